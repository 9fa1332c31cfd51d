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

/// Relative luminance of linear Rec. 709 / sRGB primaries (ITU-R BT.709 weights): the
/// scalar that light power, RIS targets and tone mapping use.
pub fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

pub fn tan(x: f32) -> f32 {
    x.tan()
}

/// The high 32 bits of the 64-bit product `a · b`, in 32-bit arithmetic (SPIR-V without
/// the Int64 capability): maps a uniform 32-bit number onto `0..b` without modulo bias.
pub fn mul_hi(a: u32, b: u32) -> u32 {
    let (a_lo, a_hi) = (a & 0xffff, a >> 16);
    let (b_lo, b_hi) = (b & 0xffff, b >> 16);
    let lo_lo = a_lo * b_lo;
    let hi_lo = a_hi * b_lo;
    let lo_hi = a_lo * b_hi;
    // Cannot overflow: lo_hi ≤ (2¹⁶−1)², the other two terms < 2¹⁶ each.
    let middle = (lo_lo >> 16) + (hi_lo & 0xffff) + lo_hi;
    a_hi * b_hi + (hi_lo >> 16) + (middle >> 16)
}

#[cfg(test)]
mod tests {
    #[test]
    fn mul_hi_is_the_high_word_of_the_product() {
        let mut x = 0x1234_5678u32;
        for _ in 0..100_000 {
            x = crate::rng::pcg_hash(x);
            let y = crate::rng::pcg_hash(x ^ 0x5bd1_e995);
            assert_eq!(
                super::mul_hi(x, y),
                ((x as u64 * y as u64) >> 32) as u32,
                "{x} {y}"
            );
        }
        assert_eq!(super::mul_hi(u32::MAX, u32::MAX), u32::MAX - 1);
        assert_eq!(super::mul_hi(u32::MAX, 7), 6);
    }
}
