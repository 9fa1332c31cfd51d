//! Putting the accumulation buffer on screen (the interactive viewer): the mean of each
//! pixel, scaled by the exposure and tone-mapped, in linear RGB (an sRGB swapchain encodes).
use crate::glam::{Vec3, Vec4};

/// Parameters of the present pass.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(bytemuck::Pod, bytemuck::Zeroable))]
pub struct PresentParams {
    pub width: u32,
    pub height: u32,
    pub exposure: f32,
    /// `TONEMAP_CLAMP` or `TONEMAP_REINHARD`.
    pub tonemap: u32,
}

/// Show the exposed radiance as it is, clamped by the display (what `render` writes to PNG).
pub const TONEMAP_CLAMP: u32 = 0;
/// Reinhard on luminance: c / (1 + L).
pub const TONEMAP_REINHARD: u32 = 1;

/// Displayed colour of an accumulation texel (rgb = sum, a = sample count).
pub fn display_colour(acc: Vec4, params: &PresentParams) -> Vec3 {
    let mean = if acc.w > 0.0 {
        acc.truncate() / acc.w
    } else {
        Vec3::ZERO
    };
    let c = mean * params.exposure;
    let c = if params.tonemap == TONEMAP_REINHARD {
        let l = crate::math::luminance(c);
        c / (1.0 + l)
    } else {
        c
    };
    c.clamp(Vec3::ZERO, Vec3::ONE)
}

/// Clip-space position of vertex `i` of a triangle that covers the screen.
pub fn fullscreen_triangle(i: u32) -> Vec4 {
    let x = ((i << 1) & 2) as f32;
    let y = (i & 2) as f32;
    Vec4::new(x * 2.0 - 1.0, 1.0 - y * 2.0, 0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_exposure_and_clamp() {
        let p = PresentParams {
            width: 1,
            height: 1,
            exposure: 2.0,
            tonemap: TONEMAP_CLAMP,
        };
        let c = display_colour(Vec4::new(0.5, 1.0, 4.0, 4.0), &p);
        assert_eq!(c, Vec3::new(0.25, 0.5, 1.0));
        assert_eq!(display_colour(Vec4::ZERO, &p), Vec3::ZERO);
        let r = PresentParams {
            tonemap: TONEMAP_REINHARD,
            exposure: 1.0,
            ..p
        };
        let c = display_colour(Vec4::new(1.0, 1.0, 1.0, 1.0), &r);
        assert!((c - Vec3::splat(0.5)).length() < 1e-6);
    }

    #[test]
    fn triangle_covers_the_screen() {
        let v: [Vec4; 3] = core::array::from_fn(|i| fullscreen_triangle(i as u32));
        assert_eq!(
            v[0].truncate().truncate(),
            crate::glam::Vec2::new(-1.0, 1.0)
        );
        assert_eq!(v[1].truncate().truncate(), crate::glam::Vec2::new(3.0, 1.0));
        assert_eq!(
            v[2].truncate().truncate(),
            crate::glam::Vec2::new(-1.0, -3.0)
        );
    }
}
