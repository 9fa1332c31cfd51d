//! Turn command-line options and a scene into kernel parameters, validating on the way.
use std::path::{Path, PathBuf};

use glam::Vec3;
use kernels::camera::look_at;
use kernels::types::{Camera, FrameParams};

use crate::bail;
use crate::cli::{Integrator, KernelArgs, LightSampling, RestirBias, SceneArgs, UpAxis};
use crate::error::Result;
use crate::scene::{load_obj, Scene};

/// Largest image side and size: 16 bytes of accumulation per pixel must fit in memory and
/// in one GPU buffer.
pub const MAX_IMAGE_SIDE: u32 = 32_768;
pub const MAX_IMAGE_PIXELS: u64 = 1 << 27;
/// Most samples per pixel (and AO rays per sample): keeps sample indices far from overflow.
pub const MAX_SPP: u32 = 1 << 24;
/// Most RIS candidates per pixel: 65,536 is already ~100× past where more stop helping,
/// and every one costs a light sample in every pixel of every frame.
pub const MAX_CANDIDATES: u32 = 1 << 16;

/// The Cornell box in the source tree (tests load it as a file; the binary embeds it).
pub fn default_scene_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/cornell_box.obj")
}

/// Load the scene named on the command line: an OBJ file, or a built-in scene's name
/// (see `generate`); the Cornell box by default. Prints the scene's warnings.
pub fn load_scene(args: &SceneArgs) -> Result<Scene> {
    let path = args
        .scene
        .clone()
        .unwrap_or_else(|| PathBuf::from("cornell-box"));
    let name = path.to_string_lossy();
    let scene = if path.is_file()
        || path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("obj"))
    {
        load_obj(&path)?
    } else if name == "cornell-box" {
        crate::scene::cornell_box()?
    } else {
        match crate::generate::builtin(&name) {
            Some(generated) => generated?.into_scene()?,
            None => crate::generate::unknown_scene(&name)?.into_scene()?,
        }
    };
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    log::debug!(
        "scene '{name}': {} triangles, {} emissive, {} materials; {} BVH: {} nodes in {:.1} ms",
        scene.triangles.len(),
        scene.lights.len(),
        scene.materials.len(),
        kernels::bvh::TRAVERSAL,
        scene.nodes.len(),
        scene.bvh_build_time.as_secs_f64() * 1e3
    );
    Ok(scene)
}

/// Where the camera stands, before the image's aspect is known.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraPose {
    pub eye: Vec3,
    pub target: Vec3,
    /// The world's up direction (the top of the image, and the axis `--orbit` turns about).
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub fov: f32,
}

/// Default vertical field of view, degrees.
pub const DEFAULT_FOV: f32 = 45.0;
/// The default view of a scene without a camera: from the front, turned this far to the
/// right and raised this far above the horizon (a three-quarter view that shows a model's
/// front, side and top at once, as product shots and DCC tools' default views do).
const THREE_QUARTER_AZIMUTH_DEG: f32 = 35.0;
const THREE_QUARTER_ELEVATION_DEG: f32 = 25.0;

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

/// The camera pose from the flags, else the scene's `# camera:` line, else a three-quarter
/// view from the front that frames the scene's bounding sphere, upright for `--up-axis`.
pub fn camera_pose(args: &SceneArgs, scene: &Scene) -> Result<CameraPose> {
    let (lo, hi) = scene.bounds();
    let hint = scene.camera;
    let fov = args.fov.or(hint.map(|h| h.fov)).unwrap_or(DEFAULT_FOV);
    if !(fov > 0.0 && fov < 180.0) {
        bail!("--fov must be in (0, 180) degrees, got {fov}");
    }
    let target = args
        .target
        .or(hint.map(|h| h.target))
        .unwrap_or(0.5 * (lo + hi));
    let up = args.up.or(hint.map(|h| h.up)).unwrap_or(args.up_axis.up());
    let eye = args.eye.or(hint.map(|h| h.eye)).unwrap_or_else(|| {
        let radius = 0.5 * (hi - lo).length();
        let (az, el) = (
            THREE_QUARTER_AZIMUTH_DEG.to_radians(),
            THREE_QUARTER_ELEVATION_DEG.to_radians(),
        );
        let front = args.up_axis.front();
        let right = args.up_axis.up().cross(front);
        let dir = (front * az.cos() + right * az.sin()) * el.cos() + args.up_axis.up() * el.sin();
        target + dir * (radius / (0.5 * fov.to_radians()).sin())
    });
    let forward = target - eye;
    if !forward.is_finite() || !eye.is_finite() || !target.is_finite() {
        bail!("the camera's position or view direction is not finite (eye {eye}, target {target})");
    }
    if forward.length() <= f32::EPSILON * eye.abs().max_element().max(1.0) {
        bail!("--eye and --target are the same point");
    }
    if up.length() == 0.0 || forward.normalize().cross(up.normalize()).length() < 1e-6 {
        bail!("--up must not be zero or parallel to the view direction (target - eye)");
    }
    Ok(CameraPose {
        eye,
        target,
        up,
        fov,
    })
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

/// The kernels' camera for the flags and the scene (see `camera_pose`).
pub fn camera(args: &SceneArgs, scene: &Scene) -> Result<Camera> {
    check_image_size(args.width, args.height)?;
    let pose = camera_pose(args, scene)?;
    let aspect = args.width as f32 / args.height as f32;
    Ok(look_at(pose.eye, pose.target, pose.up, pose.fov, aspect))
}

pub fn frame_params(args: &SceneArgs, kernel: &KernelArgs, scene: &Scene) -> Result<FrameParams> {
    if kernel.spp == 0 || kernel.spp > MAX_SPP {
        bail!("--spp must be between 1 and {MAX_SPP}, got {}", kernel.spp);
    }
    if kernel.ao_rays > MAX_SPP {
        bail!("--ao-rays must be at most {MAX_SPP}");
    }
    if kernel.ao_rays == 0 {
        bail!("--ao-rays must be at least 1");
    }
    if kernel.max_depth == 0 {
        bail!("--max-depth must be at least 1");
    }
    if kernel.sky.min_element() < 0.0 || kernel.sky.max_element() > crate::scene::MAX_RADIANCE {
        bail!(
            "--sky must be between 0 and {:e} per channel",
            crate::scene::MAX_RADIANCE
        );
    }
    let needs_lights = kernel.integrator != Integrator::Ao;
    if needs_lights && scene.lights.is_empty() {
        if kernel.sky == Vec3::ZERO {
            bail!(
                "the scene has no emitters (no material with Ke > 0) and --sky is black: \
                 the {} image would be black; light it with --sky R,G,B or render --integrator ao",
                kernel.integrator.name()
            );
        }
        eprintln!("warning: the scene has no emitters; only --sky lights it");
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
    if kernel.spatial_neighbours > kernels::integrators::restir::MAX_SPATIAL_NEIGHBOURS {
        bail!(
            "--spatial-neighbours is at most {}",
            kernels::integrators::restir::MAX_SPATIAL_NEIGHBOURS
        );
    }
    let spatial_radius = kernel
        .spatial_radius
        .unwrap_or_else(|| default_spatial_radius(args.width, args.height));
    if !(spatial_radius >= 1.0 && spatial_radius.is_finite()) {
        bail!("--spatial-radius must be at least 1 pixel");
    }
    if kernel.spatial_passes > 8 {
        bail!("--spatial-passes is at most 8");
    }
    let ao_distance = kernel.ao_distance.unwrap_or(0.25 * scene.extent());
    if !(ao_distance > 0.0 && ao_distance.is_finite()) {
        bail!("--ao-distance must be a positive number, got {ao_distance}");
    }
    let camera = camera(args, scene)?;
    Ok(FrameParams {
        camera,
        prev_camera: camera,
        width: args.width,
        height: args.height,
        seed: kernel.seed,
        ao_rays: kernel.ao_rays,
        ao_distance,
        sky: kernel.sky.to_array(),
        max_depth: kernel.max_depth,
        light_sampling: match kernel.light_sampling {
            LightSampling::Uniform => kernels::types::LIGHT_SAMPLING_UNIFORM,
            LightSampling::Power => kernels::types::LIGHT_SAMPLING_POWER,
        },
        rr_depth: 3,
        candidates: kernel.candidates,
        restir_flags: restir_flags(kernel),
        temporal_cap: kernel.temporal_cap,
        spatial_neighbours: kernel.spatial_neighbours,
        spatial_radius,
        spatial_passes: kernel.spatial_passes,
        ..Default::default()
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

fn restir_flags(kernel: &KernelArgs) -> u32 {
    use kernels::types::{RESTIR_TEMPORAL, RESTIR_UNBIASED, RESTIR_VISIBILITY_REUSE};
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
    flags
}

/// The camera of an orbit's frame: the eye turned by `degrees` about the world's up
/// direction (`--up`, the scene's camera line or `--up-axis`) through the target.
pub fn orbit_camera(args: &SceneArgs, scene: &Scene, degrees: f32) -> Result<Camera> {
    check_image_size(args.width, args.height)?;
    let pose = camera_pose(args, scene)?;
    let rot = glam::Quat::from_axis_angle(pose.up.normalize(), degrees.to_radians());
    let eye = pose.target + rot * (pose.eye - pose.target);
    Ok(look_at(
        eye,
        pose.target,
        pose.up,
        pose.fov,
        args.width as f32 / args.height as f32,
    ))
}

/// The fuzzing harness: bytes → OBJ (and MTL after the first 0xFF byte) → scene and BVH →
/// a 4×4 CPU render with NEE (or AO when there are no emitters). Bad input must come back
/// as an `Err`, never a panic, a hang or a non-finite pixel.
pub fn load_and_render_bytes(data: &[u8]) -> Result<crate::output::Image> {
    let (obj, mtl) = match data.iter().position(|&b| b == 0xff) {
        Some(i) => (&data[..i], Some(&data[i + 1..])),
        None => (data, None),
    };
    let obj = String::from_utf8_lossy(obj);
    let mtl = mtl.map(String::from_utf8_lossy);
    let scene = crate::scene::parse_obj_text("fuzz.obj", &obj, mtl.as_deref())?;
    let args = SceneArgs {
        scene: None,
        width: 4,
        height: 4,
        eye: None,
        target: None,
        up: None,
        up_axis: UpAxis::Y,
        fov: None,
    };
    let camera = camera(&args, &scene)?;
    let params = FrameParams {
        camera,
        prev_camera: camera,
        width: 4,
        height: 4,
        samples: 1,
        max_depth: 3,
        rr_depth: 2,
        light_sampling: kernels::types::LIGHT_SAMPLING_POWER,
        ao_rays: 2,
        ao_distance: scene.extent().max(1e-6),
        ..Default::default()
    };
    let integrator = if scene.lights.is_empty() {
        crate::cli::Integrator::Ao
    } else {
        crate::cli::Integrator::Nee
    };
    let mut cpu = crate::cpu::CpuBackend::new(&scene, 4, 4);
    let (image, _) = crate::render::render(&mut cpu, integrator, &params, 1, 1, false)?;
    if image.pixels.iter().any(|p| !p.is_finite()) {
        bail!("non-finite pixel");
    }
    Ok(image)
}
