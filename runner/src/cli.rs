//! Command-line interface (clap). `render` is the contract later kernels extend.
use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};
use glam::Vec3;

#[derive(Parser, Debug)]
#[command(
    // No subcommand is an error (one `error:` line and the usage), not a help page.
    subcommand_required = true,
    arg_required_else_help = false,
    name = "runner",
    version,
    about = "GPU ray tracer in Rust: the same no_std kernels run as SPIR-V through wgpu and on the CPU",
    long_about = "GPU ray tracer in Rust. Kernels (ambient occlusion, ...) are no_std Rust compiled \
to SPIR-V by rust-gpu and run through wgpu (Vulkan); the very same functions run on the CPU \
backend. Scenes are OBJ + MTL: Kd is the diffuse albedo, Ke the emitted radiance (front side = \
counter-clockwise winding)."
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Render an image (PNG or EXR)
    Render(RenderArgs),
    /// Time a render workload: ms per frame from GPU timestamps, rays per second
    Bench(BenchArgs),
    /// Write a built-in scene (many-lights, light-hall, rocks-<N>) as OBJ + MTL
    Generate(GenerateArgs),
    /// Compare an image with a reference: RMSE, relMSE, identical pixels
    Compare(CompareArgs),
    /// Interactive viewer: WASD/QE move, drag to look, scroll = speed, R reset camera,
    /// 1-6 integrator (ao pt nee mis ris restir), T temporal, +/- spatial passes,
    /// B biased/unbiased, P save PNG+EXR, Esc quit
    View(ViewArgs),
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, ValueEnum)]
pub enum Integrator {
    /// Ambient occlusion: fraction of cosine-weighted rays that escape within --ao-distance
    Ao,
    /// Path tracing (the course's loop): emission counts when a bounce hits it
    Pt,
    /// Path tracing with next-event estimation: a light sample and shadow ray per vertex
    Nee,
    /// NEE and BSDF sampling combined by multiple importance sampling (power heuristic)
    Mis,
    /// Resampled importance sampling of direct light (--candidates per pixel, WRS)
    Ris,
    /// ReSTIR DI: RIS plus temporal and spatial reuse of reservoirs across frames/pixels
    Restir,
}

impl Integrator {
    /// The name `--integrator` takes.
    pub fn name(self) -> &'static str {
        match self {
            Integrator::Ao => "ao",
            Integrator::Pt => "pt",
            Integrator::Nee => "nee",
            Integrator::Mis => "mis",
            Integrator::Ris => "ris",
            Integrator::Restir => "restir",
        }
    }
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum RestirBias {
    /// 1/Z: converges to the right image
    Unbiased,
    /// 1/M: no extra shadow rays, a little darker where visibility varies
    Biased,
}

impl RestirBias {
    /// The mode the build chose (the `restir-unbiased` feature, on by default).
    pub const COMPILED_DEFAULT: RestirBias = if kernels::integrators::restir::UNBIASED_BY_DEFAULT {
        RestirBias::Unbiased
    } else {
        RestirBias::Biased
    };
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum UpAxis {
    /// +y is up, the model faces +z
    Y,
    /// +z is up, the model faces -y
    Z,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum LightSampling {
    /// Every emissive triangle equally likely (the course)
    Uniform,
    /// In proportion to emitted power (alias table)
    Power,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum BackendChoice {
    /// A hardware GPU that the scene fits on, else the CPU backend (which runs the kernels
    /// faster than a software Vulkan driver such as lavapipe)
    Auto,
    /// A Vulkan adapter (hardware preferred, else a software driver); fail if there is none
    Gpu,
    /// The CPU backend: the same kernel functions, rayon over pixels
    Cpu,
}

/// Scene, camera and image options shared by `render` and `bench`.
#[derive(Args, Debug, Clone)]
pub struct SceneArgs {
    /// OBJ scene file (MTL files next to it), or a built-in scene: cornell-box,
    /// many-lights, light-hall, rocks-<N> (N triangles, e.g. rocks-1m) [default: cornell-box]
    #[arg(long, value_name = "FILE.obj|NAME")]
    pub scene: Option<PathBuf>,
    /// Image width in pixels
    #[arg(long, default_value_t = 512, value_name = "W")]
    pub width: u32,
    /// Image height in pixels
    #[arg(long, default_value_t = 512, value_name = "H")]
    pub height: u32,
    /// Camera position [default: the scene's `# camera:` line, else framed from the bounds]
    #[arg(long, value_parser = parse_vec3, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub eye: Option<Vec3>,
    /// Point the camera looks at
    #[arg(long, value_parser = parse_vec3, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub target: Option<Vec3>,
    /// Up direction (the top of the image) [default: the scene's `# camera:` line, else
    /// --up-axis]
    #[arg(long, value_parser = parse_vec3, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub up: Option<Vec3>,
    /// Which world axis points up in the scene file: y (OBJ and glTF convention) or z
    /// (Blender, CAD and many scanned meshes); the default camera stands upright on it
    #[arg(long, value_enum, default_value_t = UpAxis::Y)]
    pub up_axis: UpAxis,
    /// Vertical field of view in degrees, in (0, 180)
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    pub fov: Option<f32>,
}

/// Integrator options shared by `render` and `bench`.
#[derive(Args, Debug, Clone)]
pub struct KernelArgs {
    /// Which integrator (kernel) to run
    #[arg(long, value_enum, default_value_t = Integrator::Mis)]
    pub integrator: Integrator,
    /// Samples per pixel (camera rays, each jittered in its pixel; the pixel is their mean)
    #[arg(long, default_value_t = 64, value_name = "N")]
    pub spp: u32,
    /// Path segments (Mitsuba's max_depth): 1 = emitters seen directly, 2 = + direct light
    #[arg(long, default_value_t = 8, value_name = "N")]
    pub max_depth: u32,
    /// Radiance of rays that leave the scene
    #[arg(long, value_parser = parse_vec3, default_value = "0,0,0", value_name = "R,G,B")]
    pub sky: Vec3,
    /// How NEE and MIS pick a light triangle
    #[arg(long, value_enum, default_value_t = LightSampling::Power)]
    pub light_sampling: LightSampling,
    /// RIS/ReSTIR: light candidates per pixel
    #[arg(long, default_value_t = 32, value_name = "M")]
    pub candidates: u32,
    /// ReSTIR: cap on the temporal history, in multiples of --candidates
    #[arg(long, default_value_t = 20.0, value_name = "X")]
    pub temporal_cap: f32,
    /// ReSTIR: neighbours merged per spatial pass (at most 16)
    #[arg(long, default_value_t = 5, value_name = "K")]
    pub spatial_neighbours: u32,
    /// ReSTIR: radius of the spatial neighbourhood in pixels [default: 30 px at 1080 lines,
    /// in proportion to the image's smaller side, at least 3]
    #[arg(long, value_name = "PX")]
    pub spatial_radius: Option<f32>,
    /// ReSTIR: how reused samples are weighted: unbiased (balance heuristic over the
    /// reservoirs that could have produced the sample, a shadow ray each) or biased (1/M:
    /// cheaper, ~1% darker on many-lights) [default: biased; unbiased when built with the
    /// `restir-unbiased` feature]
    #[arg(long, value_enum)]
    pub restir_bias: Option<RestirBias>,
    /// ReSTIR: spatial reuse passes per frame (0 = none)
    #[arg(long, default_value_t = 1, value_name = "N")]
    pub spatial_passes: u32,
    /// ReSTIR: no temporal reuse
    #[arg(long)]
    pub no_temporal: bool,
    /// ReSTIR: do not test each pixel's pick for visibility before reusing it
    #[arg(long)]
    pub no_visibility_reuse: bool,
    /// AO: occlusion rays per camera sample
    #[arg(long, default_value_t = 4, value_name = "N")]
    pub ao_rays: u32,
    /// AO: occlusion ray length [default: 1/4 of the scene's bounding-box diagonal]
    #[arg(long, value_name = "D")]
    pub ao_distance: Option<f32>,
    /// Where to run: auto, gpu or cpu
    #[arg(long, value_enum, default_value_t = BackendChoice::Auto)]
    pub backend: BackendChoice,
    /// Random seed: the same command and seed give the same image
    #[arg(long, default_value_t = 0)]
    pub seed: u32,
}

#[derive(Args, Debug, Clone)]
pub struct RenderArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub kernel: KernelArgs,
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

#[derive(Args, Debug, Clone)]
pub struct BenchArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub kernel: KernelArgs,
    /// Timed renders (after the warm-up)
    #[arg(long, default_value_t = 5, value_name = "N")]
    pub runs: u32,
    /// Untimed rendering before the timed runs, in seconds (at least one render): an idle
    /// GPU needs a while to raise its clocks
    #[arg(long, default_value_t = 1.0, value_name = "SECONDS")]
    pub warmup: f64,
    /// Print one JSON object instead of the table
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug, Clone)]
pub struct ViewArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub kernel: KernelArgs,
    /// Multiply the displayed radiance by this
    #[arg(long, default_value_t = 1.0)]
    pub exposure: f32,
    /// Close after this many frames (for scripts and tests)
    #[arg(long, value_name = "N")]
    pub exit_after: Option<u32>,
    /// With --exit-after: save the final image here (PNG also writes an EXR beside it)
    #[arg(long, value_name = "FILE")]
    pub screenshot: Option<PathBuf>,
    /// How frames reach the window
    #[arg(long, value_enum, default_value_t = PresentChoice::Auto)]
    pub present: PresentChoice,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum PresentChoice {
    /// The window's Vulkan swapchain if the GPU can present to this display (checked in a
    /// child process: some drivers crash on displays they cannot drive, such as NVIDIA's
    /// on Xvfb), else copy
    Auto,
    /// The window's Vulkan swapchain: the GPU draws straight into the window
    Swapchain,
    /// Render off-screen on the GPU and copy each frame to the window through the CPU
    /// (virtual displays and remote X, where the GPU cannot present)
    Copy,
}

#[derive(Args, Debug, Clone)]
pub struct GenerateArgs {
    /// Built-in scene: many-lights, light-hall or rocks-<N> (e.g. rocks-1m)
    pub name: String,
    /// Output OBJ file; the MTL file is written next to it
    #[arg(long, value_name = "FILE.obj")]
    pub out: PathBuf,
}

#[derive(Args, Debug, Clone)]
pub struct CompareArgs {
    /// The image to judge (.exr keeps linear values; .png is decoded from sRGB)
    pub image: PathBuf,
    /// The reference image, same size
    pub reference: PathBuf,
}

/// Parse "X,Y,Z" into a vector of finite numbers.
pub fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!("expected X,Y,Z, got '{s}'"));
    }
    let mut v = [0.0f32; 3];
    for (x, p) in v.iter_mut().zip(&parts) {
        *x = p.parse().map_err(|_| format!("'{p}' is not a number"))?;
        if !x.is_finite() {
            return Err(format!("'{p}' is not a finite number"));
        }
    }
    Ok(Vec3::from(v))
}
