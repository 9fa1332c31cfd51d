//! The render loop: pick a backend, run the kernel pass by pass with a progress bar,
//! and turn the accumulation into an image.
use indicatif::{ProgressBar, ProgressStyle};
use kernels::types::FrameParams;

use crate::backend::{choose_auto, AdapterFit, AutoChoice, Backend};
use crate::bail;
use crate::cli::{BackendChoice, Integrator};
use crate::cpu::CpuBackend;
use crate::error::Result;
use crate::gpu::{adapters, check_fits, is_software, GpuBackend, GpuContext};
use crate::output::Image;
use crate::scene::Scene;

/// Open the backend the user asked for. `auto` takes the first hardware GPU that the scene
/// fits on, else the CPU backend, and says why on stderr when it is not the GPU.
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
    let adapter = match choice {
        BackendChoice::Gpu => match list.first() {
            Some(a) => a,
            None => bail!(
                "no Vulkan adapter with SPIR-V passthrough found (install a Vulkan driver, \
                 e.g. mesa-vulkan-drivers, or use --backend cpu)"
            ),
        },
        _ => {
            let fits: Vec<AdapterFit> = list
                .iter()
                .map(|a| AdapterFit {
                    name: a.get_info().name,
                    software: is_software(a),
                    fits: check_fits(&a.limits(), scene, width, height),
                })
                .collect();
            match choose_auto(&fits) {
                AutoChoice::Gpu(i) => &list[i],
                AutoChoice::Cpu(why) => {
                    eprintln!("note: {why}");
                    return Ok(Box::new(CpuBackend::new(scene, width, height)));
                }
            }
        }
    };
    let ctx = GpuContext::new(adapter)?;
    Ok(Box::new(GpuBackend::new(ctx, scene, width, height)?))
}

/// Timing of a finished render.
#[derive(Clone, Debug, Default)]
pub struct RenderStats {
    /// Device time of each pass in ms (GPU timestamps, or wall clock on the CPU backend).
    pub pass_ms: Vec<f64>,
    /// Rays traced in the whole render.
    pub rays: u64,
    /// ReSTIR: (pass name, ms) for every pass of every frame.
    pub breakdown: Vec<(&'static str, f64)>,
}

fn progress_bar(total: u64, show: bool) -> ProgressBar {
    if !show {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(total);
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} spp (eta {eta})",
        )
        .expect("static template"),
    );
    bar
}

/// The parameters of the pass that adds samples `done ..` (at most `samples` of them) to
/// an accumulation started with `params`. Sample `s` always draws stream `s`; ReSTIR takes
/// one sample per frame of its pipeline, sample `s` being frame `params.frame + s`, with
/// the frame before as history. The viewer uses this too, so a still camera converges
/// to exactly what `render` writes.
pub fn pass_params(
    integrator: Integrator,
    params: &FrameParams,
    done: u32,
    samples: u32,
) -> FrameParams {
    if integrator == Integrator::Restir {
        let mut p = FrameParams {
            frame: params.frame + done,
            samples: 1,
            ..*params
        };
        if done > 0 {
            p.restir_flags |= kernels::types::RESTIR_HISTORY_VALID;
            p.prev_camera = p.camera;
        }
        p
    } else {
        FrameParams {
            sample_offset: params.sample_offset + done,
            samples,
            ..*params
        }
    }
}

/// Add `spp` samples per pixel to the backend's accumulation, in passes of
/// `samples_per_pass`. Sample `s` always draws the same random stream, so the split into
/// passes does not change the image. ReSTIR takes one sample per frame of its pipeline:
/// sample `s` is frame `params.frame + s`, with history from the frame before.
pub fn accumulate(
    backend: &mut dyn Backend,
    integrator: Integrator,
    params: &FrameParams,
    spp: u32,
    samples_per_pass: u32,
    bar: &ProgressBar,
    stats: &mut RenderStats,
) -> Result<()> {
    let mut done = 0;
    while done < spp {
        let pass = pass_params(integrator, params, done, samples_per_pass.min(spp - done));
        stats.pass_ms.push(backend.pass(integrator, &pass)?);
        for (name, ms) in backend.pass_breakdown() {
            stats.breakdown.push((name, ms));
        }
        done += pass.samples;
        bar.inc(pass.samples as u64);
    }
    Ok(())
}

/// Render `spp` samples per pixel from a cleared accumulation and read the mean.
pub fn render(
    backend: &mut dyn Backend,
    integrator: Integrator,
    params: &FrameParams,
    spp: u32,
    samples_per_pass: u32,
    show_progress: bool,
) -> Result<(Image, RenderStats)> {
    let bar = progress_bar(spp as u64, show_progress);
    backend.clear()?;
    let mut stats = RenderStats::default();
    accumulate(
        backend,
        integrator,
        params,
        spp,
        samples_per_pass,
        &bar,
        &mut stats,
    )?;
    bar.finish_and_clear();
    let accum = backend.read_accumulation()?;
    stats.rays = backend.rays_traced()?;
    Ok((
        Image::from_accumulation(params.width, params.height, &accum),
        stats,
    ))
}

/// Render a sequence of frames whose cameras come from `camera_of(frame)`. With
/// `average`, all frames accumulate into the returned image; else it is the last frame.
/// `on_frame` sees each frame's image as it completes.
#[allow(clippy::too_many_arguments)] // each is one independent choice of the caller
pub fn render_sequence(
    backend: &mut dyn Backend,
    integrator: Integrator,
    params: &FrameParams,
    spp: u32,
    frames: u32,
    average: bool,
    camera_of: impl Fn(u32) -> Result<kernels::types::Camera>,
    mut on_frame: impl FnMut(u32, &Image) -> Result<()>,
) -> Result<(Image, RenderStats)> {
    let bar = progress_bar(spp as u64 * frames as u64, true);
    let mut stats = RenderStats::default();
    let mut sum: Vec<[f32; 4]> = Vec::new();
    let mut prev_camera = None;
    for f in 0..frames {
        let mut p = *params;
        p.camera = camera_of(f)?;
        p.prev_camera = prev_camera.unwrap_or(p.camera);
        prev_camera = Some(p.camera);
        p.frame = params.frame + f * spp;
        p.sample_offset = params.sample_offset + f * spp;
        if f > 0 {
            p.restir_flags |= kernels::types::RESTIR_HISTORY_VALID;
        }
        backend.clear()?; // each frame accumulates on its own; `average` sums them below
        accumulate(backend, integrator, &p, spp, 1, &bar, &mut stats)?;
        let accum = backend.read_accumulation()?;
        stats.rays += backend.rays_traced()?;
        on_frame(f, &Image::from_accumulation(p.width, p.height, &accum))?;
        if sum.is_empty() || !average {
            sum = accum;
        } else {
            for (s, a) in sum.iter_mut().zip(&accum) {
                for c in 0..4 {
                    s[c] += a[c];
                }
            }
        }
    }
    bar.finish_and_clear();
    Ok((
        Image::from_accumulation(params.width, params.height, &sum),
        stats,
    ))
}
