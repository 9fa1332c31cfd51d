//! What a ray that leaves the scene sees: the environment map (equirectangular, linear
//! HDR, turned about the up axis) scaled by `params.sky`, or `params.sky` itself. Rays find
//! it by BSDF sampling; it is not light-sampled yet.
#[cfg(target_arch = "spirv")]
use spirv_std::num_traits::Float;

use crate::bvh::SceneBuffers;
use crate::glam::{Vec2, Vec3};
use crate::math::{vec3, PI};
use crate::texture::sample_bilinear;
use crate::types::{FrameParams, ENV_UP_Z, INVALID};

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

/// Radiance arriving along `-dir` from outside the scene (a ray leaving in direction `dir`).
pub fn escaped_radiance(scene: &SceneBuffers, params: &FrameParams, dir: Vec3) -> Vec3 {
    let sky = vec3(params.sky);
    if params.env_texture == INVALID {
        return sky;
    }
    let uv = equirect_uv(dir, params.env_up == ENV_UP_Z, params.env_rotation);
    sky * sample_bilinear(scene.textures, scene.texels, params.env_texture, uv).truncate()
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
