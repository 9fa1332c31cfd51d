//! Small float helpers that behave the same on the CPU and in SPIR-V.
#[cfg(target_arch = "spirv")]
use spirv_std::num_traits::Float;

use crate::glam::Vec3;

pub const PI: f32 = core::f32::consts::PI;

pub fn vec3(a: [f32; 3]) -> Vec3 {
    Vec3::new(a[0], a[1], a[2])
}

pub fn sqrt(x: f32) -> f32 {
    x.sqrt()
}

pub fn sin_cos(x: f32) -> (f32, f32) {
    (x.sin(), x.cos())
}

pub fn acos(x: f32) -> f32 {
    x.acos()
}

/// Largest component index of `|v|` (0, 1 or 2).
pub fn max_dimension(v: Vec3) -> u32 {
    if v.x >= v.y && v.x >= v.z {
        0
    } else if v.y >= v.z {
        1
    } else {
        2
    }
}

/// `v[i]` for a run-time index without dynamic vector indexing in SPIR-V.
pub fn component(v: Vec3, i: u32) -> f32 {
    if i == 0 {
        v.x
    } else if i == 1 {
        v.y
    } else {
        v.z
    }
}

/// Mean of the three channels, used for Russian roulette and light power.
pub fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

pub fn tan(x: f32) -> f32 {
    x.tan()
}
