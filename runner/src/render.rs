//! The render loop: pick a backend, run the kernel pass by pass with a progress bar,
//! and turn the accumulation into an image.
use std::path::PathBuf;

use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use kernels::types::FrameParams;

use crate::backend::{Backend, DeviceOptions};
use crate::bail;
use crate::error::{Context, Result};
use crate::integrator::Integrator;
use crate::options::{KernelOptions, SceneOptions};
use crate::output::{check_writable, write_image, Image};
use crate::restir::continue_history;

/// `runner render`: load, render the frames, write `--out` (and `--out-dir`), report.
pub fn run(args: &RenderArgs) -> Result<()> {
    let started = std::time::Instant::now();
    let format = check_writable(&args.out)?;
    if args.frames == 0 {
        crate::bail!("--frames must be at least 1");
    }
    if !args.orbit.is_finite() {
        crate::bail!("--orbit must be a finite number of degrees");
    }
    if let Some(scene_file) = args.scene.scene.as_ref().filter(|p| p.is_file()) {
        if std::fs::canonicalize(scene_file).ok() == std::fs::canonicalize(&args.out).ok() {
            crate::bail!(
                "--out '{}' is the scene file itself; it would be overwritten",
                args.out.display()
            );
        }
    }
    if let Some(dir) = args.out_dir.as_ref().filter(|d| d.exists() && !d.is_dir()) {
        crate::bail!(
            "--out-dir '{}' exists and is not a directory",
            dir.display()
        );
    }
    let mut scene = crate::scene::load(&args.scene)?;
    let mut params = crate::options::frame_params(&args.scene, &args.kernel, &mut scene)?;
    // Frame F of a sequence draws the random numbers of samples F·spp onwards.
    let samples_end = (args.first_frame as u64 + args.frames as u64) * args.kernel.spp as u64;
    if samples_end > u32::MAX as u64 {
        crate::bail!("--first-frame, --frames and --spp together exceed 2^32 samples");
    }
    params.frame = args.first_frame * args.kernel.spp;
    params.sample_offset = args.first_frame * args.kernel.spp;
    // Created only once the scene has loaded: a run that fails on its input leaves nothing.
    if let Some(dir) = &args.out_dir {
        std::fs::create_dir_all(dir)
            .context(|| format!("cannot create --out-dir '{}'", dir.display()))?;
    }
    let mut backend =
        crate::backend::open(args.device.backend, &scene, params.width, params.height)?;
    let k = &args.kernel;
    eprintln!(
        "{} triangles ({} emissive), {}x{}, {} spp x {} frame(s), integrator {}{}, BVH {}, backend {}",
        scene.triangle_count,
        scene.lights.len(),
        params.width,
        params.height,
        k.spp,
        args.frames,
        k.integrator.name(),
        if k.integrator == Integrator::Restir {
            if params.restir_flags & kernels::types::RESTIR_UNBIASED != 0 {
                " (unbiased)"
            } else {
                " (biased)"
            }
        } else {
            ""
        },
        kernels::bvh::TRAVERSAL,
        backend.describe()
    );
    let ext = match format {
        crate::output::OutputFormat::Png => "png",
        crate::output::OutputFormat::Exr => "exr",
    };
    let (image, stats) = render_sequence(
        backend.as_mut(),
        k.integrator,
        &params,
        k.spp,
        args.frames,
        args.accumulate,
        |f| {
            crate::camera::orbit_camera(
                &args.scene,
                &scene,
                args.orbit * (args.first_frame as u64 + f as u64) as f32,
            )
        },
        |f, image| match &args.out_dir {
            Some(dir) => write_image(&dir.join(format!("frame_{f:04}.{ext}")), image),
            None => Ok(()),
        },
    )?;
    write_image(&args.out, &image)?;
    let kernel_s = stats.pass_ms.iter().sum::<f64>() * 1e-3;
    eprintln!(
        "wrote {} in {:.2} s: {}x{}, {} spp x {} frame(s), {} rays ({} rays/s over {kernel_s:.2} s of kernel time)",
        args.out.display(),
        started.elapsed().as_secs_f64(),
        params.width,
        params.height,
        k.spp,
        args.frames,
        crate::bench::with_unit(stats.rays as f64),
        crate::bench::with_unit(stats.rays as f64 / kernel_s.max(1e-9)),
    );
    Ok(())
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
            let camera = p.camera;
            continue_history(&mut p, camera);
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
    let accum = read_complete(backend, spp)?;
    stats.rays = backend.rays_traced()?;
    Ok((
        Image::from_accumulation(params.width, params.height, &accum),
        stats,
    ))
}

/// Iterations that llvmpipe (lavapipe) lets a shader's loops run in all before it ends them
/// (Mesa's `LP_MAX_TGSI_LOOP_ITERATIONS`).
const LLVMPIPE_LOOP_LIMIT: &str = "65,535";

/// That every pixel of an accumulation of `spp` samples holds all of them (its fourth
/// channel counts them), so that a kernel a driver cut short is an error, not a picture
/// with holes: lavapipe ends a shader's loops after `LLVMPIPE_LOOP_LIMIT` iterations in
/// all, which the AO workgroup pool on a deep scene exceeds (shell-100k with 64 AO rays),
/// and the invocations it stops write nothing.
pub fn check_complete(accum: &[[f32; 4]], spp: u32) -> Result<()> {
    let short = accum.iter().filter(|a| a[3] != spp as f32).count();
    if short > 0 {
        bail!(
            "the device left {short} of {} pixels without their {spp} sample(s), and nothing \
             was written (a software Vulkan driver such as lavapipe stops a kernel's loops \
             after {LLVMPIPE_LOOP_LIMIT} iterations); use --backend cpu, or fewer --ao-rays",
            accum.len()
        );
    }
    Ok(())
}

/// The backend's accumulation of `spp` samples a pixel, whole (`check_complete`).
pub fn read_complete(backend: &mut dyn Backend, spp: u32) -> Result<Vec<[f32; 4]>> {
    let accum = backend.read_accumulation()?;
    check_complete(&accum, spp)?;
    Ok(accum)
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
        p.prev_camera = p.camera;
        if let Some(prev) = prev_camera {
            continue_history(&mut p, prev);
        }
        prev_camera = Some(p.camera);
        p.frame = params.frame + f * spp;
        p.sample_offset = params.sample_offset + f * spp;
        backend.clear()?; // each frame accumulates on its own; `average` sums them below
        accumulate(backend, integrator, &p, spp, 1, &bar, &mut stats)?;
        let accum = read_complete(backend, spp)?;
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

#[derive(Args, Debug, Clone)]
pub struct RenderArgs {
    #[command(flatten)]
    pub scene: SceneOptions,
    #[command(flatten)]
    pub kernel: KernelOptions,
    #[command(flatten)]
    pub device: DeviceOptions,
    /// Output image: .png (sRGB, clamped) or .exr (linear float RGB)
    #[arg(long, default_value = "out.png", value_name = "FILE")]
    pub out: PathBuf,
    /// Frames to render in sequence (ReSTIR reuses each frame's reservoirs in the next;
    /// for ReSTIR every sample of --spp is itself a frame of the pipeline)
    #[arg(long, default_value_t = 1, value_name = "N")]
    pub frames: u32,
    /// Move the camera around --target by this many degrees per frame (about --up)
    #[arg(
        long,
        default_value_t = 0.0,
        value_name = "DEG",
        allow_hyphen_values = true
    )]
    pub orbit: f32,
    /// Start the sequence at this frame: its camera (--orbit) and random numbers are those
    /// of frame F of a longer sequence (e.g. a converged reference for one frame of an orbit)
    #[arg(long, default_value_t = 0, value_name = "F")]
    pub first_frame: u32,
    /// Average all frames into --out (default: --out is the last frame)
    #[arg(long)]
    pub accumulate: bool,
    /// Also write every frame to this directory as frame_NNNN.<ext of --out>
    #[arg(long, value_name = "DIR")]
    pub out_dir: Option<PathBuf>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_accumulation_missing_samples_is_an_error() {
        let full = vec![[0.5, 0.5, 0.5, 4.0]; 6];
        assert!(check_complete(&full, 4).is_ok());
        // A pixel no invocation wrote (lavapipe's loop limit), and one short of a pass.
        for hole in [[0.0; 4], [0.5, 0.5, 0.5, 3.0]] {
            let mut holes = full.clone();
            holes[2] = hole;
            let e = check_complete(&holes, 4).unwrap_err().to_string();
            assert!(
                e.contains("1 of 6 pixels") && e.contains("--backend cpu"),
                "{e}"
            );
        }
    }
}
