//! The render loop: pick a backend, run the kernel pass by pass with a progress bar,
//! and turn the accumulation into an image.
use indicatif::{ProgressBar, ProgressStyle};
use kernels::types::FrameParams;

use crate::backend::Backend;
use crate::bail;
use crate::cli::{BackendChoice, Integrator};
use crate::cpu::CpuBackend;
use crate::error::Result;
use crate::gpu::{adapters, is_software, GpuBackend, GpuContext};
use crate::output::Image;
use crate::scene::Scene;

/// Open the backend the user asked for. `auto` takes a hardware GPU, else a software
/// Vulkan driver, else the CPU; it says which on stderr.
pub fn open_backend(
    choice: BackendChoice,
    scene: &Scene,
    width: u32,
    height: u32,
) -> Result<Box<dyn Backend>> {
    if choice == BackendChoice::Cpu {
        return Ok(Box::new(CpuBackend::new(scene, width, height)));
    }
    let list = adapters();
    match (list.first(), choice) {
        (Some(adapter), _) => {
            if is_software(adapter) && choice == BackendChoice::Auto {
                eprintln!("note: no hardware GPU found; using the software Vulkan driver");
            }
            let ctx = GpuContext::new(adapter)?;
            Ok(Box::new(GpuBackend::new(ctx, scene, width, height)?))
        }
        (None, BackendChoice::Gpu) => bail!(
            "no Vulkan adapter with SPIR-V passthrough found (install a Vulkan driver, \
             e.g. mesa-vulkan-drivers, or use --backend cpu)"
        ),
        (None, _) => {
            eprintln!("note: no Vulkan adapter found; using the CPU backend");
            Ok(Box::new(CpuBackend::new(scene, width, height)))
        }
    }
}

/// Timing of a finished render.
#[derive(Clone, Debug, Default)]
pub struct RenderStats {
    /// Device time of each pass in ms (GPU timestamps, or wall clock on the CPU backend).
    pub pass_ms: Vec<f64>,
    /// Rays traced in the whole render.
    pub rays: u64,
}

/// Render `spp` samples per pixel in passes of `samples_per_pass`, then read the mean.
/// Sample `s` always draws the same random stream, so the split into passes does not
/// change the image.
pub fn render(
    backend: &mut dyn Backend,
    integrator: Integrator,
    params: &FrameParams,
    spp: u32,
    samples_per_pass: u32,
    show_progress: bool,
) -> Result<(Image, RenderStats)> {
    let bar = if show_progress {
        let bar = ProgressBar::new(spp as u64);
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} spp (eta {eta})",
            )
            .expect("static template"),
        );
        bar
    } else {
        ProgressBar::hidden()
    };
    backend.clear()?;
    let mut stats = RenderStats::default();
    let mut done = 0;
    while done < spp {
        let samples = samples_per_pass.min(spp - done);
        let pass = FrameParams {
            sample_offset: params.sample_offset + done,
            samples,
            ..*params
        };
        stats.pass_ms.push(backend.pass(integrator, &pass)?);
        done += samples;
        bar.set_position(done as u64);
    }
    bar.finish_and_clear();
    let accum = backend.read_accumulation()?;
    stats.rays = backend.rays_traced()?;
    Ok((Image::from_accumulation(params.width, params.height, &accum), stats))
}
