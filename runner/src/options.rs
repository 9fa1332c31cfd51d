//! The scene, camera and integrator options that `render`, `bench` and `view` share, and
//! the one place they are validated and turned into the kernels' `FrameParams`.
use std::path::PathBuf;

use clap::{Args, ValueEnum};
use glam::{DVec3, Vec3};
use kernels::types::FrameParams;

use crate::ao_order::AoOrder;
use crate::bail;
use crate::error::Result;
use crate::integrator::{AoSampling, Integrator, LightSampling, RestirBias};
use crate::light_shares::LightShares;
use crate::scene::Scene;

/// Largest image side and size: 16 bytes of accumulation per pixel must fit in memory and
/// in one GPU buffer.
pub const MAX_IMAGE_SIDE: u32 = 32_768;
pub const MAX_IMAGE_PIXELS: u64 = 1 << 27;
/// Most samples per pixel: keeps sample indices far from overflow.
pub const MAX_SPP: u32 = 1 << 24;
/// Most AO rays per camera sample: a GPU workgroup's pool counts its points' rays in 32
/// bits (and one failed take a thread), for up to `kernels::integrators::ao::WIDE_GROUP`
/// (896) points.
pub const MAX_AO_RAYS: u32 = 1 << 22;
const _: () = assert!(
    kernels::integrators::ao::WIDE_GROUP as u64 * (MAX_AO_RAYS as u64 + 1) <= u32::MAX as u64
);
/// Most RIS candidates per pixel: 65,536 is already ~100× past where more stop helping,
/// and every one costs a light sample in every pixel of every frame.
pub const MAX_CANDIDATES: u32 = 1 << 16;
/// ReSTIR's spatial neighbours by default: one for a pixel with a history, five for one
/// without (see `restir::neighbour_count`).
pub const DEFAULT_SPATIAL_NEIGHBOURS: u32 = 1;
pub const DEFAULT_DISOCCLUSION_NEIGHBOURS: u32 = 5;
/// Most ReSTIR spatial passes per frame: past two or three, more add time and blur, not
/// quality (Bitterli et al. 2020 use 2).
pub const MAX_SPATIAL_PASSES: u32 = 8;
/// Russian roulette starts after this many path segments (pbrt's default depth is 3 too):
/// the first bounces, which carry most of the light, are never cut short.
pub const RUSSIAN_ROULETTE_DEPTH: u32 = 3;

/// Scene, camera and image options shared by `render`, `bench` and `view`.
#[derive(Args, Debug, Clone)]
pub struct SceneOptions {
    /// OBJ scene file (MTL files next to it), glTF 2.0 (.gltf, .glb), PLY, or a built-in scene: cornell-box,
    /// many-lights, light-hall, rocks-<N> (N triangles, e.g. rocks-1m), shell-<N> (a closed
    /// sphere seen from inside) [default: cornell-box]
    #[arg(long, value_name = "FILE|NAME")]
    pub scene: Option<PathBuf>,
    /// Image width in pixels
    #[arg(long, default_value_t = 512, value_name = "W")]
    pub width: u32,
    /// Image height in pixels
    #[arg(long, default_value_t = 512, value_name = "H")]
    pub height: u32,
    /// Camera position [default: the scene's `# camera:` line, else framed from the bounds]
    #[arg(long, value_parser = parse_position, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub eye: Option<DVec3>,
    /// Point the camera looks at
    #[arg(long, value_parser = parse_position, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub target: Option<DVec3>,
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
    /// How much of the BVH build goes into the tree's quality [default: auto; high for
    /// `bench --suite`]
    #[arg(long, value_enum, value_name = "QUALITY")]
    pub bvh_quality: Option<crate::accel::BvhQuality>,
    /// Extra BVH boxes for large triangles, as a share of the triangle count: pre-splitting
    /// (Karras & Aila 2013; their budget is 0.3). Fewer triangle tests per ray but more
    /// node visits: faster only on some scenes of large triangles [default: 0, none]
    #[arg(long, value_name = "SHARE", value_parser = split_share)]
    pub bvh_splits: Option<f32>,
}

/// `--bvh-splits`: a share in [0, MAX_SPLITS].
fn split_share(s: &str) -> std::result::Result<f32, String> {
    let share: f32 = s.parse().map_err(|_| format!("'{s}' is not a number"))?;
    if (0.0..=crate::accel::MAX_SPLITS).contains(&share) {
        Ok(share)
    } else {
        Err(format!(
            "must be between 0 and {} (extra boxes per triangle)",
            crate::accel::MAX_SPLITS
        ))
    }
}

/// Integrator options shared by `render`, `bench` and `view`.
#[derive(Args, Debug, Clone)]
pub struct KernelOptions {
    /// Which integrator (kernel) to run
    #[arg(long, value_enum, default_value_t = Integrator::Mis)]
    pub integrator: Integrator,
    /// Samples per pixel (camera rays, each jittered in its pixel; the pixel is their mean)
    #[arg(long, default_value_t = 64, value_name = "N")]
    pub spp: u32,
    /// Path segments (Mitsuba's max_depth): 1 = emitters seen directly, 2 = + direct light
    #[arg(long, default_value_t = 8, value_name = "N")]
    pub max_depth: u32,
    /// Radiance of rays that leave the scene, the same in every direction [default: black;
    /// for scenes without emitters or --sun, the built-in sky: a soft white dome over a grey
    /// floor]
    #[arg(long, value_parser = parse_vec3, value_name = "R,G,B")]
    pub sky: Option<Vec3>,
    /// Environment map that rays leaving the scene see: an equirectangular (latitude-
    /// longitude) Radiance .hdr or OpenEXR file, linear, +y up (the scene's --up-axis)
    #[arg(long, value_name = "FILE.hdr|FILE.exr")]
    pub env: Option<PathBuf>,
    /// Turn the environment map about the up axis by this many degrees
    #[arg(
        long,
        default_value_t = 0.0,
        value_name = "DEG",
        allow_hyphen_values = true
    )]
    pub env_rotate: f32,
    /// Multiply the environment map (or the built-in sky) by this
    #[arg(long, default_value_t = 1.0, value_name = "S")]
    pub env_scale: f32,
    /// A sun: the direction towards it (world coordinates); a distant disk light that
    /// next-event estimation samples by its cone [default: the scene's own directional
    /// light (glTF), if it has one]
    #[arg(long, value_parser = parse_vec3, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub sun: Option<Vec3>,
    /// The sun disk's radiance
    #[arg(long, value_parser = parse_vec3, default_value = "10000,9000,8000", value_name = "R,G,B")]
    pub sun_radiance: Vec3,
    /// The sun's angular diameter in degrees (the real sun: 0.53)
    #[arg(long, default_value_t = 0.53, value_name = "DEG")]
    pub sun_angle: f32,
    /// How NEE and MIS pick a light triangle
    #[arg(long, value_enum, default_value_t = LightSampling::Power)]
    pub light_sampling: LightSampling,
    /// How NEE and RIS split light samples between emissive triangles, the environment map
    /// and the sun
    #[arg(long, value_enum, default_value_t = LightShares::Seen)]
    pub light_shares: LightShares,
    /// RIS/ReSTIR: light candidates per pixel
    #[arg(long, default_value_t = 32, value_name = "M")]
    pub candidates: u32,
    /// ReSTIR: cap on the temporal history, in multiples of --candidates
    #[arg(long, default_value_t = 20.0, value_name = "X")]
    pub temporal_cap: f32,
    /// ReSTIR: neighbours merged per spatial pass by a pixel with a history (at most 16)
    #[arg(long, default_value_t = DEFAULT_SPATIAL_NEIGHBOURS, value_name = "K")]
    pub spatial_neighbours: u32,
    /// ReSTIR: neighbours merged per spatial pass by a pixel whose history is shorter than 4
    /// frames (disoccluded, the first frames, or --no-temporal; at most 16)
    #[arg(long, default_value_t = DEFAULT_DISOCCLUSION_NEIGHBOURS, value_name = "K")]
    pub disocclusion_neighbours: u32,
    /// ReSTIR: radius of the spatial neighbourhood in pixels [default: 30 px at 1080 lines,
    /// in proportion to the image's smaller side, at least 3]
    #[arg(long, value_name = "PX")]
    pub spatial_radius: Option<f32>,
    /// ReSTIR: how reused samples are weighted: unbiased (MIS weights with visibility at
    /// the other pixels, a shadow ray each) or biased (the same weights without those rays:
    /// ~40% cheaper reuse, a little dark at shadow edges) [default: unbiased; biased when
    /// built without the `restir-unbiased` feature]
    #[arg(long, value_enum)]
    pub restir_bias: Option<RestirBias>,
    /// ReSTIR: spatial reuse passes per frame (0 = none, at most 8)
    #[arg(long, default_value_t = 1, value_name = "N")]
    pub spatial_passes: u32,
    /// ReSTIR: no temporal reuse
    #[arg(long)]
    pub no_temporal: bool,
    /// ReSTIR: do not test each pixel's pick for visibility before reusing it
    #[arg(long)]
    pub no_visibility_reuse: bool,
    /// ReSTIR: run each pass as its own dispatch, so that bench times every pass (by default
    /// primary runs with initial and the last spatial pass with shade: three dispatches, the
    /// same image, faster)
    #[arg(long)]
    pub split_passes: bool,
    /// AO: occlusion rays per camera sample
    #[arg(long, default_value_t = 4, value_name = "N")]
    pub ao_rays: u32,
    /// AO: occlusion ray length [default: 1/4 of the scene's bounding-box diagonal]
    #[arg(long, value_name = "D")]
    pub ao_distance: Option<f32>,
    /// AO: how each pixel's occlusion rays are spread over the hemisphere
    #[arg(long, value_enum, default_value_t = AoSampling::Stratified)]
    pub ao_sampling: AoSampling,
    /// AO: the order the GPU's walk visits a node's children in (the CPU backend's bundles
    /// have their own; the image is the same)
    #[arg(long, value_enum, default_value_t = AoOrder::Auto)]
    pub ao_order: AoOrder,
    /// Random seed: the same command and seed give the same image
    #[arg(long, default_value_t = 0)]
    pub seed: u32,
}

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum UpAxis {
    /// +y is up, the model faces +z
    Y,
    /// +z is up, the model faces -y
    Z,
}

impl UpAxis {
    /// The world's up vector.
    pub fn up(self) -> Vec3 {
        match self {
            UpAxis::Y => Vec3::Y,
            UpAxis::Z => Vec3::Z,
        }
    }
    /// The direction a model's front faces: +z for Y-up files (OBJ, glTF), -y for Z-up
    /// files (Blender's and most CAD tools' front view looks along +y).
    pub fn front(self) -> Vec3 {
        match self {
            UpAxis::Y => Vec3::Z,
            UpAxis::Z => -Vec3::Y,
        }
    }
}

/// Check the image size against what one accumulation buffer can hold.
pub fn check_image_size(width: u32, height: u32) -> Result<()> {
    if width == 0 || height == 0 {
        bail!("image size must be at least 1x1, got {width}x{height}");
    }
    if width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
        bail!("image size {width}x{height} is too large (at most {MAX_IMAGE_SIDE} per side)");
    }
    let pixels = width as u64 * height as u64;
    if pixels > MAX_IMAGE_PIXELS {
        bail!("image size {width}x{height} is too large ({pixels} pixels; at most {MAX_IMAGE_PIXELS})");
    }
    Ok(())
}

/// Validate the options and build the kernels' parameters for the first frame.
/// The environment map (`--env`, or the built-in sky for a scene that has no emitters and
/// none of `--sky`, `--env`, `--sun`) is added to the scene's textures here.
pub fn frame_params(
    args: &SceneOptions,
    kernel: &KernelOptions,
    scene: &mut Scene,
) -> Result<FrameParams> {
    if kernel.spp == 0 || kernel.spp > MAX_SPP {
        bail!("--spp must be between 1 and {MAX_SPP}, got {}", kernel.spp);
    }
    if kernel.ao_rays > MAX_AO_RAYS {
        bail!("--ao-rays must be at most {MAX_AO_RAYS}");
    }
    if kernel.ao_rays == 0 {
        bail!("--ao-rays must be at least 1");
    }
    if kernel.max_depth == 0 {
        bail!("--max-depth must be at least 1");
    }
    if let Some(sky) = kernel.sky {
        if sky.min_element() < 0.0 || sky.max_element() > crate::scene::MAX_RADIANCE {
            bail!(
                "--sky must be between 0 and {:e} per channel",
                crate::scene::MAX_RADIANCE
            );
        }
    }
    if !(kernel.env_scale > 0.0 && kernel.env_scale <= crate::scene::MAX_RADIANCE) {
        bail!(
            "--env-scale must be a positive number up to {:e}",
            crate::scene::MAX_RADIANCE
        );
    }
    if !kernel.env_rotate.is_finite() {
        bail!("--env-rotate must be a finite number of degrees");
    }
    if let Some(sun) = kernel.sun {
        if sun.length() == 0.0 {
            bail!("--sun must be a direction, not zero");
        }
        if kernel.sun_radiance.min_element() < 0.0
            || kernel.sun_radiance.max_element() > crate::scene::MAX_RADIANCE
        {
            bail!(
                "--sun-radiance must be between 0 and {:e} per channel",
                crate::scene::MAX_RADIANCE
            );
        }
    }
    if !(kernel.sun_angle > 0.0 && kernel.sun_angle < 90.0) {
        bail!(
            "--sun-angle must be in (0, 90) degrees, got {}",
            kernel.sun_angle
        );
    }
    let sun_cos_max = (0.5 * kernel.sun_angle).to_radians().cos();
    // The sun: --sun, else the file's own (a glTF directional light, its irradiance spread
    // over a disk of --sun-angle): (direction towards it, the disk's radiance).
    let sun = match (kernel.sun, scene.sun) {
        (Some(direction), _) => Some((direction.normalize(), kernel.sun_radiance)),
        (None, Some(own)) => {
            let solid_angle = std::f32::consts::TAU * (1.0 - sun_cos_max);
            let radiance = own.irradiance / solid_angle;
            if !(radiance.is_finite() && radiance.max_element() <= crate::scene::MAX_RADIANCE) {
                bail!(
                    "the scene's directional light ({} W/m²) over a {}° disk is brighter than \
                     {:e}: widen --sun-angle",
                    own.irradiance,
                    kernel.sun_angle,
                    crate::scene::MAX_RADIANCE
                );
            }
            Some((own.direction, radiance))
        }
        (None, None) => None,
    };
    let needs_lights = kernel.integrator != Integrator::Ao;
    let unlit = needs_lights && scene.lights.is_empty() && sun.is_none();
    let (sky, env_texture) = match (&kernel.env, kernel.sky) {
        (Some(_), Some(_)) => bail!("give --sky or --env, not both"),
        (Some(path), None) => (
            Vec3::splat(kernel.env_scale),
            crate::environment::load(&mut scene.attributes, path)?,
        ),
        (None, Some(sky)) => (sky, kernels::types::INVALID),
        (None, None) if unlit => {
            eprintln!(
                "note: the scene has no emitters; lighting it with the built-in sky \
                 (--env FILE.hdr or --sky R,G,B to choose)"
            );
            (
                Vec3::splat(kernel.env_scale),
                crate::environment::default_sky(&mut scene.attributes),
            )
        }
        (None, None) => (Vec3::ZERO, kernels::types::INVALID),
    };
    if unlit {
        if sky == Vec3::ZERO {
            bail!(
                "the scene has no emitters (no material with Ke > 0) and --sky is black: \
                 the {} image would be black; light it with --sky R,G,B or render --integrator ao",
                kernel.integrator.name()
            );
        }
        if kernel.sky.is_some() {
            eprintln!("warning: the scene has no emitters; only --sky lights it");
        }
    }
    if kernel.candidates == 0 || kernel.candidates > MAX_CANDIDATES {
        bail!(
            "--candidates must be between 1 and {MAX_CANDIDATES}, got {}",
            kernel.candidates
        );
    }
    if !(kernel.temporal_cap > 0.0 && kernel.temporal_cap.is_finite()) {
        bail!("--temporal-cap must be a positive number");
    }
    let most = kernels::integrators::restir::MAX_SPATIAL_NEIGHBOURS;
    if kernel.spatial_neighbours > most {
        bail!("--spatial-neighbours is at most {most}");
    }
    if kernel.disocclusion_neighbours > most {
        bail!("--disocclusion-neighbours is at most {most}");
    }
    let spatial_radius = kernel
        .spatial_radius
        .unwrap_or_else(|| default_spatial_radius(args.width, args.height));
    if !(spatial_radius >= 1.0 && spatial_radius.is_finite()) {
        bail!("--spatial-radius must be at least 1 pixel");
    }
    if kernel.spatial_passes > MAX_SPATIAL_PASSES {
        bail!("--spatial-passes is at most {MAX_SPATIAL_PASSES}");
    }
    // The scene's diagonal walks every triangle: once here for both its uses.
    let extent = scene.extent();
    if let Some(d) = kernel.ao_distance {
        if !(d > 0.0 && d.is_finite()) {
            bail!("--ao-distance must be a positive number, got {d}");
        }
    }
    // --ao-distance is in the file's units (`Scene::frame`).
    let ao_distance = kernel
        .ao_distance
        .map(|d| scene.frame.length(d))
        .unwrap_or(0.25 * extent);
    if !ao_distance.is_finite() {
        bail!(
            "--ao-distance overflows f32 once scaled with this small scene (×{})",
            scene.frame.scale
        );
    }
    let camera = crate::camera::camera(args, scene)?;
    let params = FrameParams {
        camera,
        prev_camera: camera,
        width: args.width,
        height: args.height,
        seed: kernel.seed,
        ao_rays: kernel.ao_rays,
        ao_distance,
        ao_sampling: kernel.ao_sampling.kernel_value(),
        sky: sky.to_array(),
        env_texture,
        env_rotation: kernel.env_rotate.to_radians(),
        sun_cos_max,
        sun_direction: sun.map_or(Vec3::Y, |(d, _)| d).to_array(),
        sun_radiance: sun.map_or(Vec3::ZERO, |(_, r)| r).to_array(),
        env_up: match args.up_axis {
            UpAxis::Y => kernels::types::ENV_UP_Y,
            UpAxis::Z => kernels::types::ENV_UP_Z,
        },
        max_depth: kernel.max_depth,
        light_sampling: kernel.light_sampling.kernel_value(),
        rr_depth: RUSSIAN_ROULETTE_DEPTH,
        candidates: kernel.candidates,
        restir_flags: restir_flags(kernel),
        temporal_cap: kernel.temporal_cap,
        spatial_neighbours: kernel.spatial_neighbours,
        disocclusion_neighbours: kernel.disocclusion_neighbours,
        spatial_radius,
        spatial_passes: kernel.spatial_passes,
        ..Default::default()
    };
    let [_, env_share, sun_share] =
        crate::light_shares::shares(kernel.light_shares, scene, &params, 0.5 * extent);
    let ao_order = if kernel.integrator == Integrator::Ao {
        crate::ao_order::choose(kernel.ao_order, scene, &params)
    } else {
        kernels::types::AO_NEAR_FIRST
    };
    Ok(FrameParams {
        env_light_probability: env_share,
        sun_light_probability: sun_share,
        ao_order,
        ..params
    })
}

/// ReSTIR's spatial radius: 30 px at 1080 lines (what RTXDI and Bitterli et al. use at
/// that size), scaled with the image's smaller side, so that a small image does not reach
/// across a quarter of itself for neighbours.
pub fn default_spatial_radius(width: u32, height: u32) -> f32 {
    const RADIUS_AT_1080: f32 = 30.0;
    const MIN_RADIUS: f32 = 3.0;
    (RADIUS_AT_1080 * width.min(height) as f32 / 1080.0).max(MIN_RADIUS)
}

fn restir_flags(kernel: &KernelOptions) -> u32 {
    use kernels::types::{
        RESTIR_SPLIT_PASSES, RESTIR_TEMPORAL, RESTIR_UNBIASED, RESTIR_VISIBILITY_REUSE,
    };
    let mut flags = 0;
    if kernel.restir_bias.unwrap_or(RestirBias::COMPILED_DEFAULT) == RestirBias::Unbiased {
        flags |= RESTIR_UNBIASED;
    }
    if !kernel.no_temporal {
        flags |= RESTIR_TEMPORAL;
    }
    if !kernel.no_visibility_reuse {
        flags |= RESTIR_VISIBILITY_REUSE;
    }
    if kernel.split_passes {
        flags |= RESTIR_SPLIT_PASSES;
    }
    flags
}

/// Parse "X,Y,Z" into a vector of finite numbers.
pub fn parse_vec3(s: &str) -> std::result::Result<Vec3, String> {
    parse_triple::<f32>(s).map(Vec3::from)
}

/// Parse "X,Y,Z" into a position in a scene file's coordinates: read in f64, as a
/// georeferenced scene's coordinates need more digits than f32 holds before
/// `Scene::frame` moves them near the origin; finite as f32.
pub fn parse_position(s: &str) -> std::result::Result<DVec3, String> {
    let p = DVec3::from(parse_triple::<f64>(s)?);
    if !p.as_vec3().is_finite() {
        return Err(format!("'{s}' is beyond f32's range"));
    }
    Ok(p)
}

/// Three comma-separated finite numbers.
fn parse_triple<T: std::str::FromStr + Default + Copy + Into<f64>>(
    s: &str,
) -> std::result::Result<[T; 3], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!("expected X,Y,Z, got '{s}'"));
    }
    let mut v = [T::default(); 3];
    for (x, p) in v.iter_mut().zip(&parts) {
        *x = p.parse().map_err(|_| format!("'{p}' is not a number"))?;
        if !(*x).into().is_finite() {
            return Err(format!("'{p}' is not a finite number"));
        }
    }
    Ok(v)
}
