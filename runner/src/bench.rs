//! `runner bench`: time a render workload. Each frame is a full render of `--spp` samples
//! per pixel; its time is the sum of its passes' device times (GPU timestamp queries, or
//! wall clock on the CPU backend). Rays counts camera, bounce, shadow and AO rays, as
//! traced by the kernels themselves. ReSTIR's frames form one sequence across warm-up and
//! runs (`--spp` frames a run), as in the viewer.
use clap::Args;

use crate::backend::DeviceOptions;
use crate::options::{KernelOptions, SceneOptions};
use std::fmt::Write as _;

use indicatif::ProgressBar;
use kernels::types::FrameParams;

use crate::accel::BvhQuality;
use crate::backend::Backend;
use crate::error::Result;
use crate::integrator::Integrator;
use crate::options::frame_params;
use crate::render::{accumulate, RenderStats};
use crate::restir::continue_history;
use crate::scene::{load as load_scene, Scene};

#[derive(Clone, Debug)]
pub struct BenchReport {
    pub scene: String,
    pub triangles: usize,
    /// Triangle slots in the BVH's leaves: more than `triangles` where large ones were
    /// pre-split (`--bvh-splits`).
    pub bvh_slots: usize,
    /// Nodes of the BVH (how the tree was priced shows here: `collapse`).
    pub bvh_nodes: usize,
    pub bvh_build_ms: f64,
    /// `--bvh-quality` of the build.
    pub bvh_quality: String,
    /// Reading the file, checking it and building everything (0 for scenes made in code
    /// before `bench`).
    pub load_ms: f64,
    pub traversal: &'static str,
    pub backend: String,
    pub integrator: String,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub rays_per_frame: u64,
    pub frame_ms: Vec<f64>,
    pub pass_ms: Vec<f64>,
    /// ReSTIR: median ms of each pass kind per frame.
    pub breakdown: Vec<(&'static str, f64)>,
    /// Nodes visited and triangles tested per traversal (ray), counted by the CPU backend
    /// under the `traversal-stats` feature.
    pub per_ray: Option<(f64, f64)>,
}

fn min(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::INFINITY, f64::min)
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(|a, b| a.total_cmp(b));
    let n = s.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

/// A number with the SI prefix that leaves three significant digits
/// ("3.36 G", "42.1 M", "812 k", "12.0").
pub fn with_unit(x: f64) -> String {
    let (value, prefix) = [(1e9, "G"), (1e6, "M"), (1e3, "k")]
        .iter()
        .find(|(scale, _)| x.abs() >= *scale)
        .map_or((x, ""), |&(scale, prefix)| (x / scale, prefix));
    let decimals = if value.abs() >= 100.0 {
        0
    } else if value.abs() >= 10.0 {
        1
    } else {
        2
    };
    format!("{value:.decimals$} {prefix}")
        .trim_end()
        .to_string()
}

impl BenchReport {
    pub fn rays_per_second(&self) -> f64 {
        self.rays_per_frame as f64 / (median(&self.frame_ms) * 1e-3)
    }

    pub fn table(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "scene          {}", self.scene);
        let _ = writeln!(s, "triangles      {}", self.triangles);
        let _ = writeln!(
            s,
            "BVH            {} (build {:.1} ms, quality {}, {} triangle slots, {} nodes)",
            self.traversal, self.bvh_build_ms, self.bvh_quality, self.bvh_slots, self.bvh_nodes
        );
        let _ = writeln!(
            s,
            "load           {:.1} ms (file, checks and BVH)",
            self.load_ms
        );
        let _ = writeln!(s, "backend        {}", self.backend);
        let _ = writeln!(
            s,
            "workload       {} at {}x{}, {} spp",
            self.integrator, self.width, self.height, self.spp
        );
        let _ = writeln!(s, "rays/frame     {}", self.rays_per_frame);
        let _ = writeln!(
            s,
            "ms/frame       min {:.3}  median {:.3}  ({} runs)",
            min(&self.frame_ms),
            median(&self.frame_ms),
            self.frame_ms.len()
        );
        let _ = writeln!(
            s,
            "ms/pass        min {:.3}  median {:.3}",
            min(&self.pass_ms),
            median(&self.pass_ms)
        );
        for (name, ms) in &self.breakdown {
            let _ = writeln!(s, "  {name:<12} {ms:.3} ms (median per frame)");
        }
        let _ = writeln!(s, "rays/s         {}", with_unit(self.rays_per_second()));
        if let Some((nodes, triangles)) = self.per_ray {
            let _ = writeln!(
                s,
                "per ray        {nodes:.1} nodes visited, {triangles:.1} triangles tested"
            );
        }
        s
    }

    pub fn json(&self) -> String {
        format!(
            "{{\"scene\":{:?},\"triangles\":{},\"bvh_slots\":{},\"bvh_nodes\":{},\"traversal\":{:?},\"bvh_build_ms\":{:.3},\"bvh_quality\":{:?},\"load_ms\":{:.3},\"backend\":{:?},\
             \"integrator\":{:?},\"width\":{},\"height\":{},\"spp\":{},\"rays_per_frame\":{},\
             \"frame_ms_min\":{:.4},\"frame_ms_median\":{:.4},\"pass_ms_min\":{:.4},\"pass_ms_median\":{:.4},\
             \"rays_per_second\":{:.1},\"breakdown_ms\":{{{}}}}}",
            self.scene,
            self.triangles,
            self.bvh_slots,
            self.bvh_nodes,
            self.traversal,
            self.bvh_build_ms,
            self.bvh_quality,
            self.load_ms,
            self.backend,
            self.integrator,
            self.width,
            self.height,
            self.spp,
            self.rays_per_frame,
            min(&self.frame_ms),
            median(&self.frame_ms),
            min(&self.pass_ms),
            median(&self.pass_ms),
            self.rays_per_second(),
            self.breakdown
                .iter()
                .map(|(n, ms)| format!("\"{n}\":{ms:.4}"))
                .collect::<Vec<_>>()
                .join(",")
        )
    }
}

/// One timed frame: the GPU work of `render` without reading anything back. Reading the
/// image back after every frame left the GPU idle most of the time, and an H100 then lowers
/// its clocks within seconds (seen: 1980 → 420 MHz, timestamps up to 5x longer).
/// ReSTIR's frames then move `params` on: as in the viewer, each continues the history of
/// the one before, so the steady state is measured, not a fresh history per run (whose
/// first frames have no temporal pass and take `--disocclusion-neighbours`).
fn frame(
    backend: &mut dyn Backend,
    k: &KernelOptions,
    params: &mut FrameParams,
) -> Result<RenderStats> {
    backend.clear()?;
    let mut stats = RenderStats::default();
    accumulate(
        backend,
        k.integrator,
        params,
        k.spp,
        1,
        &ProgressBar::hidden(),
        &mut stats,
    )?;
    if k.integrator == Integrator::Restir {
        let camera = params.camera;
        continue_history(params, camera);
        params.frame += k.spp;
    }
    Ok(stats)
}

/// Most timed runs of one bench: a median needs far fewer, and each run is a whole render.
const MAX_RUNS: u32 = 10_000;

pub fn bench(args: &BenchArgs) -> Result<BenchReport> {
    if args.runs == 0 || args.runs > MAX_RUNS {
        crate::bail!("--runs must be between 1 and {MAX_RUNS}");
    }
    if !(args.warmup >= 0.0 && args.warmup <= 600.0) {
        crate::bail!("--warmup must be between 0 and 600 seconds");
    }
    bench_scene(args, &load_scene(&args.scene)?)
}

/// The scene of `args` and its first frame's parameters, as `bench` renders them: for the
/// diagnostics in `runner/examples`, which walk the same scene on the CPU.
pub fn scene_and_params(args: &BenchArgs) -> Result<(Scene, FrameParams)> {
    let mut scene = load_scene(&args.scene)?;
    let params = frame_params(&args.scene, &args.kernel, &mut scene)?;
    Ok((scene, params))
}

/// `bench` on a scene already loaded (the suite loads each of its scenes once for all its
/// workloads); `frame_params` may add the built-in sky to the scene, so it works on a copy.
fn bench_scene(args: &BenchArgs, loaded: &Scene) -> Result<BenchReport> {
    let mut scene = loaded.clone();
    let mut params = frame_params(&args.scene, &args.kernel, &mut scene)?;
    let mut backend =
        crate::backend::open(args.device.backend, &scene, params.width, params.height)?;
    let k = &args.kernel;
    let mut frame_ms = Vec::new();
    let mut pass_ms = Vec::new();
    let mut per_pass: Vec<(&'static str, Vec<f64>)> = Vec::new();
    // Warm up for a time, not a fixed count: an idle GPU takes a while to raise its clocks,
    // and short workloads otherwise measure the ramp (seen: 4x on an H100).
    let warm_start = std::time::Instant::now();
    loop {
        frame(backend.as_mut(), k, &mut params)?;
        if warm_start.elapsed().as_secs_f64() >= args.warmup {
            break;
        }
    }
    #[cfg(feature = "traversal-stats")]
    kernels::bvh::stats::take();
    for _ in 0..args.runs {
        let stats = frame(backend.as_mut(), k, &mut params)?;
        frame_ms.push(stats.pass_ms.iter().sum());
        pass_ms.extend(stats.pass_ms);
        // ReSTIR: this run's time per frame in each pass kind (spatial may run several times).
        for (name, ms) in stats.breakdown {
            let per_frame = ms / k.spp.max(1) as f64;
            match per_pass.iter_mut().find(|(n, _)| *n == name) {
                Some((_, runs)) if runs.len() == frame_ms.len() => {
                    *runs.last_mut().unwrap() += per_frame
                }
                Some((_, runs)) => runs.push(per_frame),
                None => per_pass.push((name, vec![per_frame])),
            }
        }
    }
    #[cfg(feature = "traversal-stats")]
    let per_ray = {
        let (rays, nodes, triangles) = kernels::bvh::stats::take();
        (rays > 0).then(|| (nodes as f64 / rays as f64, triangles as f64 / rays as f64))
    };
    #[cfg(not(feature = "traversal-stats"))]
    let per_ray = None;
    // The last run's image is whole (read after the timed runs): a driver that cut the
    // kernels short would otherwise report their times as ours.
    crate::render::read_complete(backend.as_mut(), k.spp)?;
    // Rays of the last run (the count restarts with each run's clear).
    let rays_per_frame = backend.rays_traced()?;
    let breakdown = per_pass
        .into_iter()
        .map(|(name, runs)| (name, median(&runs)))
        .collect();
    Ok(BenchReport {
        scene: args
            .scene
            .scene
            .as_ref()
            .map(|p| p.display().to_string())
            .unwrap_or_else(|| "cornell-box".into()),
        triangles: scene.triangle_count,
        bvh_slots: scene.triangles.len(),
        bvh_nodes: scene.nodes.len(),
        bvh_build_ms: scene.bvh_build_time.as_secs_f64() * 1e3,
        bvh_quality: format!("{:?}", args.scene.bvh_quality.unwrap_or_default()).to_lowercase(),
        load_ms: scene.load_time.as_secs_f64() * 1e3,
        traversal: kernels::bvh::TRAVERSAL,
        backend: backend.describe(),
        integrator: k.integrator.name().to_string(),
        width: params.width,
        height: params.height,
        spp: k.spp,
        rays_per_frame,
        frame_ms,
        pass_ms,
        breakdown,
        per_ray,
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn rates_carry_their_unit() {
        use super::with_unit;
        assert_eq!(with_unit(3.3625e9), "3.36 G");
        assert_eq!(with_unit(42.13e6), "42.1 M");
        assert_eq!(with_unit(812.4e3), "812 k");
        assert_eq!(with_unit(1000.0), "1.00 k");
        assert_eq!(with_unit(12.0), "12.0");
        assert_eq!(with_unit(0.5), "0.50");
    }
}

#[derive(Args, Debug, Clone)]
pub struct BenchArgs {
    #[command(flatten)]
    pub scene: SceneOptions,
    #[command(flatten)]
    pub kernel: KernelOptions,
    #[command(flatten)]
    pub device: DeviceOptions,
    /// Timed renders (after the warm-up)
    #[arg(long, default_value_t = 5, value_name = "N")]
    pub runs: u32,
    /// Untimed rendering before the timed runs, in seconds (at least one render): an idle
    /// GPU needs a while to raise its clocks
    #[arg(long, default_value_t = 1.0, value_name = "SECONDS")]
    pub warmup: f64,
    /// Print one JSON object instead of the table (with --suite: one per line)
    #[arg(long)]
    pub json: bool,
    /// Run the benchmark suite instead of one workload: AO (1 spp x 64 AO rays), NEE (direct
    /// light, 1 spp) and pt (8 segments, 1 spp) on each built-in suite scene (rocks-1m,
    /// spheres-1m, city-1m, grass-1m, shell-1m), one table; --scene, --integrator, --spp,
    /// --ao-rays and --max-depth are set by the suite, --bvh-quality is high unless given,
    /// and each workload warms up for at least 5 s
    #[arg(long)]
    pub suite: bool,
}

/// The suite's workloads: (integrator, spp, AO rays per sample, max depth).
const SUITE_WORKLOADS: [(Integrator, u32, u32, u32); 3] = [
    (Integrator::Ao, 1, 64, 1),
    (Integrator::Nee, 1, 4, 2),
    (Integrator::Pt, 1, 4, 8),
];

/// Least warm-up of each suite workload, in seconds. Right after a scene's AO workload
/// (110 ms frames on shell-1m) its 1 ms NEE and pt frames read 4–6× slow for a few seconds,
/// every timed run included: with 1 s of warm-up the suite gave shell-1m NEE 5.6–6.2 ms and
/// pt 0.81–4.2, with 5 s 1.08 and 0.81, as each alone (H100).
const SUITE_MIN_WARMUP: f64 = 5.0;

/// `runner bench --suite`: every workload on every suite scene; a table of ms per frame
/// and rays per second (or one JSON object per run).
pub fn suite(args: &BenchArgs) -> Result<String> {
    let mut out = String::new();
    if !args.json {
        let _ = writeln!(
            out,
            "{:<12} {:>9} {:>9}  {:>20}  {:>20}  {:>20}",
            "scene", "triangles", "BVH ms", "AO 64 rays/px", "NEE direct 1 spp", "pt depth 8 1 spp"
        );
    }
    for name in crate::generate::SUITE {
        let mut row = String::new();
        let mut at_scene = args.scene.clone();
        at_scene.scene = Some(name.into());
        // The suite measures traversal: the best tree unless told otherwise.
        at_scene.bvh_quality = Some(args.scene.bvh_quality.unwrap_or(BvhQuality::High));
        let scene = load_scene(&at_scene)?;
        for (integrator, spp, ao_rays, max_depth) in SUITE_WORKLOADS {
            let mut run = args.clone();
            run.suite = false;
            run.warmup = args.warmup.max(SUITE_MIN_WARMUP);
            run.scene = at_scene.clone();
            run.kernel.integrator = integrator;
            run.kernel.spp = spp;
            run.kernel.ao_rays = ao_rays;
            run.kernel.max_depth = max_depth;
            let r = bench_scene(&run, &scene)?;
            if args.json {
                let _ = writeln!(out, "{}", r.json());
                continue;
            }
            if row.is_empty() {
                let _ = write!(
                    row,
                    "{:<12} {:>9} {:>9.0}",
                    name, r.triangles, r.bvh_build_ms
                );
            }
            let cell = format!(
                "{:.2} ms {}rays/s",
                median(&r.frame_ms),
                with_unit(r.rays_per_second())
            );
            let _ = write!(row, "  {cell:>20}");
        }
        if !row.is_empty() {
            let _ = writeln!(out, "{row}");
        }
    }
    Ok(out)
}
