//! Where the camera stands: from the flags, the scene's `# camera:` line, or a default view
//! that frames the scene. `render`, `--orbit` and the viewer all start here.
use glam::Vec3;
use kernels::camera::look_at;
use kernels::types::Camera;

use crate::bail;
use crate::error::Result;
use crate::options::{check_image_size, SceneOptions};
use crate::scene::Scene;

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

/// The camera pose from the flags, else the scene's `# camera:` line, else a three-quarter
/// view from the front that frames the scene's bounding sphere, upright for `--up-axis`;
/// in the kernels' coordinates (the flags and the file's camera are in the file's:
/// `Scene::frame` maps them).
pub fn camera_pose(args: &SceneOptions, scene: &Scene) -> Result<CameraPose> {
    let (lo, hi) = scene.bounds();
    let hint = scene.camera;
    let frame = scene.frame;
    let fov = args.fov.or(hint.map(|h| h.fov)).unwrap_or(DEFAULT_FOV);
    if !(fov > 0.0 && fov < 180.0) {
        bail!("--fov must be in (0, 180) degrees, got {fov}");
    }
    let target = args
        .target
        .or(hint.map(|h| h.target))
        .map(|p| frame.position(p))
        .unwrap_or(0.5 * (lo + hi));
    let up = args.up.or(hint.map(|h| h.up)).unwrap_or(args.up_axis.up());
    let eye = args.eye.or(hint.map(|h| h.eye)).map(|p| frame.position(p));
    let eye = eye.unwrap_or_else(|| {
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
    // The same point to f32 precision: relative to the coordinates, as a scene of any size
    // may be framed (a floor of 1 here refused every scene under ~1e-7 across).
    if forward.length() <= f32::EPSILON * eye.abs().max_element().max(target.abs().max_element()) {
        bail!("--eye and --target are the same point");
    }
    // |forward|² overflows f32 beyond ~1.8e19: the view direction would normalise to zero.
    if !forward.length().is_finite() {
        bail!(
            "--eye and --target are too far apart for f32 arithmetic (eye {eye}, target {target})"
        );
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

/// The kernels' camera for the flags and the scene (see `camera_pose`).
pub fn camera(args: &SceneOptions, scene: &Scene) -> Result<Camera> {
    check_image_size(args.width, args.height)?;
    let pose = camera_pose(args, scene)?;
    let aspect = args.width as f32 / args.height as f32;
    Ok(look_at(pose.eye, pose.target, pose.up, pose.fov, aspect))
}

/// The camera of an orbit's frame: the eye turned by `degrees` about the world's up
/// direction (`--up`, the scene's camera line or `--up-axis`) through the target.
pub fn orbit_camera(args: &SceneOptions, scene: &Scene, degrees: f32) -> Result<Camera> {
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

/// The camera ray through the centre of cell (column, row) of a `columns` × `rows` grid
/// spread over `params`' image: the host's pilots (`light_shares`, `ao_order`) look at
/// the scene through it.
pub fn pilot_ray(
    params: &kernels::types::FrameParams,
    (column, row): (u32, u32),
    (columns, rows): (u32, u32),
) -> kernels::intersect::Ray {
    let x = (column as f32 + 0.5) / columns as f32 * params.width as f32;
    let y = (row as f32 + 0.5) / rows as f32 * params.height as f32;
    kernels::camera::primary_ray(&params.camera, params.width, params.height, x, y)
}
