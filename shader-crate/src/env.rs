//! What a ray that leaves the scene sees: the environment map (equirectangular, linear
//! HDR, turned about the up axis) scaled by `params.sky`, or `params.sky` itself; and the
//! map's importance sampling for next-event estimation: a piecewise-constant density over
//! texels in proportion to luminance × sin θ (marginal CDF over rows, a conditional CDF per
//! row), built on the host. Layout of `env_distribution` for a W × H map: the marginal CDF
//! (H + 1 values, 0 to 1), then each row's conditional CDF (W + 1 values), rows from the top.
#[cfg(target_arch = "spirv")]
use spirv_std::num_traits::Float;

use crate::bvh::SceneBuffers;
use crate::glam::{Vec2, Vec3};
use crate::math::{vec3, PI};
use crate::texture::sample_texture;
use crate::types::{load, FrameParams, ENV_UP_Z, INVALID};

/// Texture coordinates of direction `dir` (unit) in an equirectangular map whose up axis is
/// +y (or +z) and whose centre column faces -z (or +y), turned by `rotation` radians about
/// up: u = longitude / 2π + ½, and v = 1 at the zenith (the top row).
pub fn equirect_uv(dir: Vec3, up_z: bool, rotation: f32) -> Vec2 {
    // Into the y-up frame: z-up files' (x, y, z) is y-up's (x, z, -y).
    let d = if up_z {
        Vec3::new(dir.x, dir.z, -dir.y)
    } else {
        dir
    };
    let longitude = d.x.atan2(-d.z) + rotation;
    let colatitude = d.y.clamp(-1.0, 1.0).acos();
    Vec2::new(longitude / (2.0 * PI) + 0.5, 1.0 - colatitude / PI)
}

/// The unit direction of equirectangular coordinates (u, row from the top in [0, 1]): the
/// inverse of `equirect_uv`; also sin θ (θ from the map's zenith).
pub fn equirect_direction(u: f32, top: f32, up_z: bool, rotation: f32) -> (Vec3, f32) {
    let colatitude = top * PI;
    let longitude = (u - 0.5) * 2.0 * PI - rotation;
    let (sin_t, cos_t) = (colatitude.sin(), colatitude.cos());
    let d = Vec3::new(sin_t * longitude.sin(), cos_t, -sin_t * longitude.cos());
    let dir = if up_z { Vec3::new(d.x, -d.z, d.y) } else { d };
    (dir, sin_t)
}

/// Index `i` with cdf[i] ≤ u < cdf[i + 1] among the `n` intervals of the CDF starting at
/// `start` (binary search).
fn search(cdf: &[f32], start: usize, n: u32, u: f32) -> u32 {
    let (mut lo, mut hi) = (0u32, n);
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if load(cdf, start + mid as usize) <= u {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// A direction drawn by the map's importance distribution, with its solid-angle density
/// (0 where nothing can be drawn). `(0, 0)` without a map.
pub fn sample_env(scene: &SceneBuffers, params: &FrameParams, u1: f32, u2: f32) -> (Vec3, f32) {
    if params.env_texture == INVALID || scene.env_distribution.is_empty() {
        return (Vec3::Z, 0.0);
    }
    let info = load(scene.textures, params.env_texture as usize);
    let (w, h) = (info.width, info.height);
    let d = scene.env_distribution;
    let y = search(d, 0, h, u1);
    let (m0, m1) = (load(d, y as usize), load(d, y as usize + 1));
    let row = (h + 1 + y * (w + 1)) as usize;
    let x = search(d, row, w, u2);
    let (c0, c1) = (load(d, row + x as usize), load(d, row + x as usize + 1));
    let (p_row, p_col) = (m1 - m0, c1 - c0);
    if p_row <= 0.0 || p_col <= 0.0 {
        return (Vec3::Z, 0.0);
    }
    // Uniform within the texel: the numbers' remainders inside the chosen intervals.
    let fy = ((u1 - m0) / p_row).clamp(0.0, 1.0);
    let fx = ((u2 - c0) / p_col).clamp(0.0, 1.0);
    let (dir, sin_t) = equirect_direction(
        (x as f32 + fx) / w as f32,
        (y as f32 + fy) / h as f32,
        params.env_up == ENV_UP_Z,
        params.env_rotation,
    );
    if sin_t <= 0.0 {
        return (dir, 0.0);
    }
    (
        dir,
        p_row * p_col * (w * h) as f32 / (2.0 * PI * PI * sin_t),
    )
}

/// The solid-angle density with which `sample_env` draws `dir`.
pub fn env_pdf(scene: &SceneBuffers, params: &FrameParams, dir: Vec3) -> f32 {
    if params.env_texture == INVALID || scene.env_distribution.is_empty() {
        return 0.0;
    }
    let info = load(scene.textures, params.env_texture as usize);
    let (w, h) = (info.width, info.height);
    let uv = equirect_uv(dir, params.env_up == ENV_UP_Z, params.env_rotation);
    let u = uv.x - uv.x.floor();
    let x = ((u * w as f32) as u32).min(w - 1);
    let y = (((1.0 - uv.y) * h as f32) as u32).min(h - 1);
    let d = scene.env_distribution;
    let p_row = load(d, y as usize + 1) - load(d, y as usize);
    let row = (h + 1 + y * (w + 1)) as usize;
    let p_col = load(d, row + x as usize + 1) - load(d, row + x as usize);
    let up = if params.env_up == ENV_UP_Z {
        dir.z
    } else {
        dir.y
    };
    let sin_t = (1.0 - up * up).max(0.0).sqrt();
    if sin_t <= 0.0 {
        return 0.0;
    }
    p_row * p_col * (w * h) as f32 / (2.0 * PI * PI * sin_t)
}

/// Radiance arriving along `-dir` from outside the scene (a ray leaving in direction `dir`):
/// the sky or environment map, plus the sun's disk.
pub fn escaped_radiance(scene: &SceneBuffers, params: &FrameParams, dir: Vec3) -> Vec3 {
    let sky = vec3(params.sky);
    let sun = if vec3(params.sun_direction).dot(dir) >= params.sun_cos_max {
        vec3(params.sun_radiance)
    } else {
        Vec3::ZERO
    };
    if params.env_texture == INVALID {
        return sky + sun;
    }
    let uv = equirect_uv(dir, params.env_up == ENV_UP_Z, params.env_rotation);
    sky * sample_texture(scene.textures, scene.texels, params.env_texture, uv).truncate() + sun
}

/// The part of `escaped_radiance` no light sampling draws: a constant sky (a map's
/// radiance, which `sky` only scales, and the sun's are sampled).
pub fn unsampled_radiance(params: &FrameParams) -> Vec3 {
    if params.env_texture == INVALID {
        vec3(params.sky)
    } else {
        Vec3::ZERO
    }
}

/// Solid angle of the sun's disk.
pub fn sun_solid_angle(params: &FrameParams) -> f32 {
    2.0 * PI * (1.0 - params.sun_cos_max)
}

/// A direction uniform in the sun's cone, with its solid-angle density.
pub fn sample_sun(params: &FrameParams, u1: f32, u2: f32) -> (Vec3, f32) {
    let cos_t = 1.0 - u1 * (1.0 - params.sun_cos_max);
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = 2.0 * PI * u2;
    let local = Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t);
    let dir = crate::sampling::local_to_world(local, vec3(params.sun_direction));
    (dir, 1.0 / sun_solid_angle(params))
}

/// The density with which `sample_sun` draws `dir`.
pub fn sun_pdf(params: &FrameParams, dir: Vec3) -> f32 {
    if vec3(params.sun_direction).dot(dir) >= params.sun_cos_max {
        1.0 / sun_solid_angle(params)
    } else {
        0.0
    }
}

/// Everything beyond the scene as one light for next-event estimation: the map (chosen
/// with `env_light_probability`) and the sun (`sun_light_probability`). Draws a direction
/// from one of the two by `u_choice` (uniform below their sum) and returns it with the
/// mixture's density, which MIS weighs and the estimator divides by (a direction the other
/// one could have drawn counts that way too).
pub fn sample_infinite(
    scene: &SceneBuffers,
    params: &FrameParams,
    u_choice: f32,
    u1: f32,
    u2: f32,
) -> (Vec3, f32) {
    let dir = infinite_direction(scene, params, u_choice, u1, u2);
    (dir, infinite_pdf(scene, params, dir))
}

/// The direction of `sample_infinite` without its density.
pub fn infinite_direction(
    scene: &SceneBuffers,
    params: &FrameParams,
    u_choice: f32,
    u1: f32,
    u2: f32,
) -> Vec3 {
    if u_choice < params.env_light_probability {
        sample_env(scene, params, u1, u2).0
    } else {
        sample_sun(params, u1, u2).0
    }
}

/// The mixture density of `sample_infinite` (light selection included).
pub fn infinite_pdf(scene: &SceneBuffers, params: &FrameParams, dir: Vec3) -> f32 {
    let mut pdf = 0.0;
    if params.env_light_probability > 0.0 {
        pdf += params.env_light_probability * env_pdf(scene, params, dir);
    }
    if params.sun_light_probability > 0.0 {
        pdf += params.sun_light_probability * sun_pdf(params, dir);
    }
    pdf
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zenith_is_the_top_row_and_the_centre_faces_minus_z() {
        assert!((equirect_uv(Vec3::Y, false, 0.0).y - 1.0).abs() < 1e-6);
        assert!(equirect_uv(-Vec3::Y, false, 0.0).y.abs() < 1e-6);
        let front = equirect_uv(-Vec3::Z, false, 0.0);
        assert!((front - Vec2::new(0.5, 0.5)).length() < 1e-6, "{front}");
        // Z-up: +z is the zenith and +y the centre column.
        assert!((equirect_uv(Vec3::Z, true, 0.0).y - 1.0).abs() < 1e-6);
        assert!((equirect_uv(Vec3::Y, true, 0.0) - Vec2::new(0.5, 0.5)).length() < 1e-6);
        // A quarter turn moves the centre a quarter of the width.
        let turned = equirect_uv(-Vec3::Z, false, 0.5 * PI);
        assert!((turned.x - 0.75).abs() < 1e-6, "{turned}");
    }

    #[test]
    fn rgbe_round_trips_radiance() {
        // 1.0 is mantissa 128 at exponent 129: (128 + 0.5) · 2^(129 − 136) = 1.0039.
        let w = 128 | 128 << 8 | 128 << 16 | 129 << 24;
        let c = crate::texture::rgbe_to_linear(w);
        assert!((c.x - 1.0039).abs() < 1e-3, "{c}");
        assert_eq!(crate::texture::rgbe_to_linear(0).x, 0.0);
    }
}
