//! Texture lookup: all texels of a scene live in one buffer with a table of textures
//! (`TextureInfo`), and the lookup and filtering are these functions, so the CPU backend
//! reads a texture exactly as the GPU does.
#[cfg(target_arch = "spirv")]
use spirv_std::num_traits::Float;

use crate::glam::{Vec2, Vec4};
use crate::types::{
    load, TextureInfo, TEXTURE_FORMAT, TEXTURE_LEVELS, TEXTURE_LEVELS_MASK, TEXTURE_LINEAR8,
    TEXTURE_NEAREST, TEXTURE_RGBE, TEXTURE_WRAP_U, TEXTURE_WRAP_V, WRAP_CLAMP, WRAP_MIRROR,
    WRAP_REPEAT,
};

/// sRGB transfer function → linear (IEC 61966-2-1).
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// An RGBE word decoded (Radiance's convention: (m + 0.5) · 2^(e − 136); e = 0 is black).
pub fn rgbe_to_linear(w: u32) -> Vec4 {
    let e = w >> 24;
    if e == 0 {
        return Vec4::new(0.0, 0.0, 0.0, 1.0);
    }
    // 2^(e − 136) built as a float: e − 136 + 127 = e − 9 is a valid biased exponent for
    // every e in 10..=255; smaller ones are below what an RGBE map stores (2^-126).
    let scale = if e > 9 {
        f32::from_bits((e - 9) << 23)
    } else {
        0.0
    };
    let m = |shift: u32| (((w >> shift) & 0xff) as f32 + 0.5) * scale;
    Vec4::new(m(0), m(8), m(16), 1.0)
}

/// Texel (x, y) of a texture, decoded: linear RGB and alpha.
fn texel(texels: &[u32], info: &TextureInfo, x: u32, y: u32) -> Vec4 {
    let w = load(texels, (info.offset + y * info.width + x) as usize);
    let format = info.format & TEXTURE_FORMAT;
    if format == TEXTURE_RGBE {
        return rgbe_to_linear(w);
    }
    let byte = |shift: u32| ((w >> shift) & 0xff) as f32 / 255.0;
    if format == TEXTURE_LINEAR8 {
        return Vec4::new(byte(0), byte(8), byte(16), byte(24));
    }
    Vec4::new(
        srgb_to_linear(byte(0)),
        srgb_to_linear(byte(8)),
        srgb_to_linear(byte(16)),
        byte(24),
    )
}

/// `i` wrapped into 0..n (texture repeat), for any integer `i`.
fn repeat(i: i32, n: u32) -> u32 {
    let n = n as i32;
    // `%` without its panic (as `math::div_rem`, for a signed i): n > 0 here.
    let r = i.checked_rem(n).unwrap_or(0);
    (if r < 0 { r + n } else { r }) as u32
}

/// A texture coordinate along one axis of `n` texels under wrap mode `wrap` (`flip`: the
/// axis runs the other way in the image, as v does): the two texels to blend and the
/// second's weight, or with `nearest` the texel the coordinate falls in (twice, weight 0).
fn axis(t: f32, n: u32, wrap: u32, flip: bool, nearest: bool) -> (u32, u32, f32) {
    // Into [0, 1] first, so that huge coordinates keep their fraction in f32.
    let t = if wrap == WRAP_CLAMP {
        t.clamp(0.0, 1.0)
    } else if wrap == WRAP_MIRROR {
        let r = t - 2.0 * (0.5 * t).floor();
        if r > 1.0 {
            2.0 - r
        } else {
            r
        }
    } else {
        t - t.floor()
    };
    let t = if flip { 1.0 - t } else { t };
    let last = n as i32 - 1;
    if nearest {
        let i = ((t * n as f32) as i32).max(0).min(last) as u32;
        return (i, i, 0.0);
    }
    // Texel centres at half integers.
    let x = t * n as f32 - 0.5;
    let x0 = x.floor();
    let (f, x0) = (x - x0, x0 as i32);
    if wrap == WRAP_REPEAT {
        (repeat(x0, n), repeat(x0 + 1, n), f)
    } else {
        // Clamped, and mirrored at the edge (where the mirror image's next texel is the
        // edge texel itself).
        (
            x0.max(0).min(last) as u32,
            (x0 + 1).max(0).min(last) as u32,
            f,
        )
    }
}

/// The number of mip levels of a texture (at least 1: the image itself).
pub fn levels(info: &TextureInfo) -> u32 {
    ((info.format & TEXTURE_LEVELS_MASK) >> TEXTURE_LEVELS).max(1)
}

/// Mip level `level` of a texture as a texture of its own: each level is half the one
/// before (rounded down, at least 1 texel) and follows it in the texel buffer.
pub fn level(info: &TextureInfo, level: u32) -> TextureInfo {
    let mut l = *info;
    let mut i = 0;
    while i < level {
        l.offset += l.width * l.height;
        l.width = (l.width / 2).max(1);
        l.height = (l.height / 2).max(1);
        i += 1;
    }
    l
}

/// Texels a texture holds, all its levels together.
pub fn texel_count(info: &TextureInfo) -> u64 {
    let last = level(info, levels(info) - 1);
    (last.offset - info.offset) as u64 + last.width as u64 * last.height as u64
}

/// Lookup of texture `index` at `uv` through its sampler (`TextureInfo::format`): bilinear
/// unless it asks for the nearest texel, repeating outside [0, 1] unless it asks to clamp
/// or mirror. v = 0 is the bottom row of the image (the OBJ and OpenGL convention).
/// Filtering happens on linear values. The full-size image is read (no footprint).
pub fn sample_texture(textures: &[TextureInfo], texels: &[u32], index: u32, uv: Vec2) -> Vec4 {
    sample_texture_footprint(textures, texels, index, uv, 0.0)
}

/// `sample_texture` for a pixel whose footprint on the surface spans `footprint` in texture
/// coordinates (`SurfaceHit::uv_footprint`): read from the mip levels whose texels are
/// about that size, blended between the two nearest (trilinear), so that a texture seen
/// from afar gives each pixel its average there instead of one point of it (less noise
/// per sample, and the same image when converged). A nearest-texel sampler reads the
/// full-size image.
pub fn sample_texture_footprint(
    textures: &[TextureInfo],
    texels: &[u32],
    index: u32,
    uv: Vec2,
    footprint: f32,
) -> Vec4 {
    let info = load(textures, index as usize);
    if info.width == 0 || info.height == 0 {
        return Vec4::ONE;
    }
    let uv = if uv.is_finite() { uv } else { Vec2::ZERO };
    let size = ((info.width * info.height) as f32).sqrt();
    let lod = (footprint * size).log2();
    let top = (levels(&info) - 1) as f32;
    // Magnified (or no footprint, or a NaN: `is_nan` first), the image itself.
    if lod.is_nan() || lod <= 0.0 || top == 0.0 || info.format & TEXTURE_NEAREST != 0 {
        return sample_level(texels, &info, uv);
    }
    let lod = lod.min(top);
    let fine = lod.floor();
    let coarse_weight = lod - fine;
    let near = sample_level(texels, &level(&info, fine as u32), uv);
    if coarse_weight <= 0.0 {
        return near;
    }
    let far = sample_level(texels, &level(&info, fine as u32 + 1), uv);
    near * (1.0 - coarse_weight) + far * coarse_weight
}

/// A lookup in one level of a texture (`sample_texture`'s filtering and wrapping).
fn sample_level(texels: &[u32], info: &TextureInfo, uv: Vec2) -> Vec4 {
    let nearest = info.format & TEXTURE_NEAREST != 0;
    let wrap = |shift: u32| (info.format >> shift) & 3;
    let (xa, xb, fx) = axis(uv.x, info.width, wrap(TEXTURE_WRAP_U), false, nearest);
    let (ya, yb, fy) = axis(uv.y, info.height, wrap(TEXTURE_WRAP_V), true, nearest);
    if nearest {
        return texel(texels, info, xa, ya);
    }
    let top = texel(texels, info, xa, ya) * (1.0 - fx) + texel(texels, info, xb, ya) * fx;
    let bottom = texel(texels, info, xa, yb) * (1.0 - fx) + texel(texels, info, xb, yb) * fx;
    top * (1.0 - fy) + bottom * fy
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rgba(r: u8, g: u8, b: u8) -> u32 {
        r as u32 | (g as u32) << 8 | (b as u32) << 16 | 0xff << 24
    }

    #[test]
    fn srgb_decoding_matches_the_standard() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        // sRGB 128/255 is 0.2158605 linear.
        assert!((srgb_to_linear(128.0 / 255.0) - 0.215_860_5).abs() < 1e-6);
    }

    #[test]
    fn texel_centres_return_texels_and_between_them_filters_linearly() {
        // 2x1 texture: left black, right white.
        let info = [TextureInfo {
            offset: 0,
            width: 2,
            height: 1,
            format: 0,
        }];
        let texels = [rgba(0, 0, 0), rgba(255, 255, 255)];
        let at = |u: f32| sample_texture(&info, &texels, 0, Vec2::new(u, 0.5)).x;
        assert!(at(0.25).abs() < 1e-6, "left texel centre");
        assert!((at(0.75) - 1.0).abs() < 1e-6, "right texel centre");
        assert!((at(0.5) - 0.5).abs() < 1e-6, "half way, in linear values");
        // Repeat: u = 1.25 is u = 0.25, u = -0.25 is u = 0.75.
        assert!(at(1.25).abs() < 1e-6);
        assert!((at(-0.25) - 1.0).abs() < 1e-6);
        // The seam at u = 0 blends the last and the first texel.
        assert!((at(0.0) - 0.5).abs() < 1e-6);
        assert_eq!(
            sample_texture(&info, &texels, 0, Vec2::new(f32::NAN, 0.0)).x,
            at(0.0)
        );
    }

    /// A 2×1 texture, left black and right white, under `sampler` (`TextureInfo::format`'s
    /// sampler bits), read at u along its middle row.
    fn black_white(sampler: u32, u: f32) -> f32 {
        let info = [TextureInfo {
            offset: 0,
            width: 2,
            height: 1,
            format: sampler,
        }];
        let texels = [rgba(0, 0, 0), rgba(255, 255, 255)];
        sample_texture(&info, &texels, 0, Vec2::new(u, 0.5)).x
    }

    #[test]
    fn clamped_textures_keep_their_edge_texels_outside() {
        let clamp = WRAP_CLAMP << TEXTURE_WRAP_U;
        let at = |u: f32| black_white(clamp, u);
        // Beyond either edge the edge texel, with no blend across the seam at u = 0 / 1.
        for (u, want) in [(-3.0, 0.0), (0.0, 0.0), (1.0, 1.0), (7.5, 1.0), (0.5, 0.5)] {
            assert!((at(u) - want).abs() < 1e-6, "u {u}: {} not {want}", at(u));
        }
    }

    #[test]
    fn mirrored_textures_reverse_every_other_repeat() {
        let mirror = WRAP_MIRROR << TEXTURE_WRAP_U;
        let at = |u: f32| black_white(mirror, u);
        // In [0, 1] as repeat; in [1, 2] reversed (1.25 reads 0.75); [2, 3] as [0, 1].
        for (u, want) in [
            (0.25, 0.0),
            (0.75, 1.0),
            (1.25, 1.0),
            (1.75, 0.0),
            (2.25, 0.0),
        ] {
            assert!((at(u) - want).abs() < 1e-6, "u {u}: {} not {want}", at(u));
        }
        // Negative coordinates mirror too (-0.25 reads 0.25); the edges meet their own
        // texel, not the opposite one.
        assert!(at(-0.25).abs() < 1e-6);
        assert!((at(1.0) - 1.0).abs() < 1e-6 && at(0.0).abs() < 1e-6);
    }

    #[test]
    fn nearest_filtering_reads_one_texel() {
        let at = |u: f32| black_white(TEXTURE_NEAREST, u);
        // Either side of the texels' border at u = 0.5, no blend; repeat as before.
        assert_eq!(at(0.49), 0.0);
        assert_eq!(at(0.51), 1.0);
        assert_eq!(at(1.2), 0.0);
        assert_eq!(at(-0.2), 1.0);
        assert_eq!(
            black_white(TEXTURE_NEAREST | WRAP_CLAMP << TEXTURE_WRAP_U, 1.0),
            1.0
        );
    }

    #[test]
    fn v_zero_is_the_bottom_row() {
        // 1x2 texture: top row red, bottom row blue.
        let info = [TextureInfo {
            offset: 0,
            width: 1,
            height: 2,
            format: 0,
        }];
        let texels = [rgba(255, 0, 0), rgba(0, 0, 255)];
        let bottom = sample_texture(&info, &texels, 0, Vec2::new(0.5, 0.25));
        let top = sample_texture(&info, &texels, 0, Vec2::new(0.5, 0.75));
        assert!(bottom.z > 0.99 && bottom.x < 0.01, "{bottom}");
        assert!(top.x > 0.99 && top.z < 0.01, "{top}");
    }

    #[test]
    fn mip_levels_follow_the_image_and_the_footprint_chooses_and_blends_them() {
        use crate::types::{TEXTURE_LEVELS, TEXTURE_LINEAR8};
        // 5 × 3, then 2 × 1, then 1 × 1; after some other texture's 7 texels.
        let info = TextureInfo {
            offset: 7,
            width: 5,
            height: 3,
            format: TEXTURE_LINEAR8 | 3 << TEXTURE_LEVELS,
        };
        assert_eq!(levels(&info), 3);
        let l1 = level(&info, 1);
        assert_eq!((l1.offset, l1.width, l1.height), (7 + 15, 2, 1));
        let l2 = level(&info, 2);
        assert_eq!((l2.offset, l2.width, l2.height), (7 + 15 + 2, 1, 1));
        assert_eq!(texel_count(&info), 18);
        // Without the levels' bits: the image alone.
        let alone = TextureInfo {
            format: TEXTURE_LINEAR8,
            ..info
        };
        assert_eq!((levels(&alone), texel_count(&alone)), (1, 15));

        // A grey level of 0 (the image), 100 (level 1), 200 (level 2), linear bytes.
        let mut texels = [0u32; 25];
        texels[22] = rgba(100, 100, 100);
        texels[23] = rgba(100, 100, 100);
        texels[24] = rgba(200, 200, 200);
        let table = [info];
        let at = |footprint: f32| {
            sample_texture_footprint(&table, &texels, 0, Vec2::new(0.3, 0.6), footprint).x * 255.0
        };
        // lod = log2(footprint · √(5 · 3)): below 0 the image; 1 and 2 those levels;
        // past the last level, the last; half way, the average of the two.
        let size = 15f32.sqrt();
        for (footprint, expect) in [
            (0.0, 0.0),
            (0.5 / size, 0.0),
            (2.0 / size, 100.0),
            (4.0 / size, 200.0),
            (64.0 / size, 200.0),
            (2f32.powf(1.5) / size, 150.0),
            (f32::NAN, 0.0),
        ] {
            assert!(
                (at(footprint) - expect).abs() < 1e-3,
                "footprint {footprint}: {}",
                at(footprint)
            );
        }
        // A nearest-texel sampler reads the image.
        let nearest = [TextureInfo {
            format: info.format | TEXTURE_NEAREST,
            ..info
        }];
        let x = sample_texture_footprint(&nearest, &texels, 0, Vec2::new(0.3, 0.6), 1.0).x;
        assert_eq!(x, 0.0);
    }
}
