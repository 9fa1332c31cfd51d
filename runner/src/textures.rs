//! Texture files on the host: found next to the scene, decoded with `image` (PNG, JPEG,
//! TGA, BMP, HDR/EXR), and packed into the one texel buffer the kernels read
//! (`kernels::texture`).
use std::path::{Path, PathBuf};

use kernels::types::TextureInfo;

use crate::scene::{read_input_file, SurfaceAttributes};

/// Largest texture file read, and largest decoded texture: what real scenes carry (8k
/// textures are 256 MiB of RGBA8) with room, and a bound on a hostile header.
pub const MAX_TEXTURE_FILE_BYTES: u64 = 512 << 20;
pub const MAX_TEXTURE_TEXELS: u64 = 1 << 26;

/// An MTL map statement (`map_Kd -s 4 4 -clamp on wood floor.png`): its options, then its
/// file name, which may hold spaces (Blender writes names as they are).
#[derive(Clone, Debug, PartialEq)]
pub struct MapStatement {
    /// With Windows separators made portable.
    pub file: String,
    /// `-s` and `-o`: texture coordinates are read at `scale × uv + offset`.
    pub scale: glam::Vec2,
    pub offset: glam::Vec2,
    /// `-clamp on`: coordinates outside [0, 1] read the edge instead of repeating.
    pub clamp: bool,
    /// `-bm`: a bump map's multiplier.
    pub bump_multiplier: Option<f32>,
}

impl MapStatement {
    /// Where a point with texture coordinates `uv` reads the map (`-s`, `-o`).
    pub fn uv_map(&self) -> glam::Affine2 {
        glam::Affine2::from_scale_angle_translation(self.scale, 0.0, self.offset)
    }
}

/// Parse an MTL map statement: the options of the MTL specification, each with the values
/// it takes (`-o`, `-s`, `-t` one to three numbers), and the rest of the line as the file
/// name. Options not read here are skipped with their values.
pub fn parse_map_statement(statement: &str) -> MapStatement {
    let mut map = MapStatement {
        file: String::new(),
        scale: glam::Vec2::ONE,
        offset: glam::Vec2::ZERO,
        clamp: false,
        bump_multiplier: None,
    };
    let mut rest = statement.trim_start();
    let number = |word: &str| word.parse::<f32>().ok().filter(|v| v.is_finite());
    while let Some(option) = rest.strip_prefix('-').and(rest.split_whitespace().next()) {
        let mut words = rest.split_whitespace();
        words.next();
        let mut values: Vec<&str> = Vec::new();
        let takes = match option {
            "-blendu" | "-blendv" | "-cc" | "-clamp" | "-imfchan" | "-type" | "-bm" | "-boost"
            | "-texres" => 1..=1,
            "-mm" => 2..=2,
            // -o, -s, -t and any other: the numbers that follow, up to three.
            _ => 0..=3,
        };
        for word in words.by_ref() {
            if values.len() == *takes.end()
                || (values.len() >= *takes.start() && number(word).is_none())
            {
                break;
            }
            values.push(word);
        }
        let floats: Vec<f32> = values.iter().filter_map(|w| number(w)).collect();
        match option {
            "-s" if !floats.is_empty() => {
                map.scale = glam::Vec2::new(floats[0], *floats.get(1).unwrap_or(&1.0))
            }
            "-o" if !floats.is_empty() => {
                map.offset = glam::Vec2::new(floats[0], *floats.get(1).unwrap_or(&0.0))
            }
            "-clamp" => map.clamp = values.first() == Some(&"on"),
            "-bm" => map.bump_multiplier = floats.first().copied(),
            _ => {}
        }
        // Past the option and its values, to the next word.
        for word in std::iter::once(option).chain(values.iter().copied()) {
            rest = rest.strip_prefix(word).unwrap_or(rest).trim_start();
        }
    }
    map.file = rest.trim_end().replace('\\', "/");
    map
}

/// The paths a texture named `name` in an MTL beside `dir` may be at: as written, relative
/// to the scene's folder, then by base name in that folder (as Blender looks them up).
pub fn candidate_paths(dir: &Path, name: &str) -> Vec<PathBuf> {
    let mut paths = vec![dir.join(name)];
    if let Some(base) = Path::new(name).file_name() {
        let by_base = dir.join(base);
        if by_base != paths[0] {
            paths.push(by_base);
        }
    }
    paths
}

/// Why an image file could not be had.
pub enum ImageFileError {
    /// Reading it (missing, not a regular file, over the size limit, unknown format).
    Read(String),
    /// Decoding it.
    Decode(String),
}

/// Read an image file of at most `max_bytes` and decode it, allocating for at most
/// `max_texels` texels (a hostile header cannot ask for more); texture and environment
/// files both come in here.
pub fn read_image_file(
    path: &Path,
    max_bytes: u64,
    max_texels: u64,
) -> Result<image::DynamicImage, ImageFileError> {
    let read = |e: &dyn std::fmt::Display| ImageFileError::Read(e.to_string());
    let bytes = read_input_file(path, max_bytes).map_err(|e| read(&e))?;
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| read(&e))?;
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(max_texels * 16);
    reader.limits(limits);
    reader
        .decode()
        .map_err(|e| ImageFileError::Decode(e.to_string()))
}

/// Read and decode one texture file to RGBA8 (sRGB colour, as 8-bit textures are stored),
/// or say why not.
pub fn decode(path: &Path) -> Result<image::RgbaImage, String> {
    let image =
        read_image_file(path, MAX_TEXTURE_FILE_BYTES, MAX_TEXTURE_TEXELS).map_err(|e| match e {
            ImageFileError::Read(e) | ImageFileError::Decode(e) => e,
        })?;
    if image.width() as u64 * image.height() as u64 > MAX_TEXTURE_TEXELS {
        return Err(format!(
            "{}x{} texels, over the limit of {MAX_TEXTURE_TEXELS}",
            image.width(),
            image.height()
        ));
    }
    Ok(image.to_rgba8())
}

/// A cut-out mask (MTL `map_d`) as the kernels read it, in the alpha channel: the image's
/// own alpha where it has one (a PNG with transparency), else its grey level (a black and
/// white mask; the format stores d in [0, 1], not an sRGB colour).
pub fn cutout_mask(mut image: image::RgbaImage) -> image::RgbaImage {
    let has_alpha = image.pixels().any(|p| p[3] != u8::MAX);
    for p in image.pixels_mut() {
        let mask = if has_alpha { p[3] } else { p[0] };
        *p = image::Rgba([u8::MAX, u8::MAX, u8::MAX, mask]);
    }
    image
}

/// Append a decoded colour texture to the texel buffer; its index in the texture table.
pub fn add(attributes: &mut SurfaceAttributes, image: &image::RgbaImage) -> u32 {
    add_as(attributes, image, kernels::types::TEXTURE_SRGB8)
}

/// Append a data texture (normal or metallic-roughness map: its bytes are read as they
/// are, without sRGB decoding).
pub fn add_linear(attributes: &mut SurfaceAttributes, image: &image::RgbaImage) -> u32 {
    add_as(attributes, image, kernels::types::TEXTURE_LINEAR8)
}

/// Texture `texture` read through `sampler` (`TextureInfo::format`'s sampler bits: wrap
/// modes, nearest filtering): the same texels under one more table entry, made once however
/// many materials read them so, or `texture` itself for the default sampler (bilinear,
/// repeating).
pub fn with_sampler(attributes: &mut SurfaceAttributes, texture: u32, sampler: u32) -> u32 {
    if sampler == 0 {
        return texture;
    }
    if let Some(&entry) = attributes.sampled.get(&(texture, sampler)) {
        return entry;
    }
    let mut info = attributes.textures[texture as usize];
    let kept = kernels::types::TEXTURE_FORMAT | kernels::types::TEXTURE_LEVELS_MASK;
    info.format = (info.format & kept) | sampler;
    attributes.textures.push(info);
    let entry = attributes.textures.len() as u32 - 1;
    attributes.sampled.insert((texture, sampler), entry);
    entry
}

/// Whether an image is a tangent-space normal map rather than a height (bump) map: MTL's
/// `map_Bump` names either (Blender writes its normal maps there). A normal map's texels
/// decode (2c − 1) to unit vectors whose z leads (they lean less than 45° from the
/// surface's normal); a height map is grey, where no component leads.
pub fn is_normal_map(image: &image::RgbaImage) -> bool {
    /// Share of texels that must look like normals, and how far from unit length they may be.
    const SHARE: f64 = 0.9;
    const LENGTH_TOLERANCE: f32 = 0.15;
    let normal_like = image
        .pixels()
        .filter(|p| {
            let m = [p[0], p[1], p[2]].map(|c| c as f32 / 255.0 * 2.0 - 1.0);
            let length = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
            (length - 1.0).abs() < LENGTH_TOLERANCE && m[2] > m[0].abs().max(m[1].abs())
        })
        .count();
    normal_like as f64 >= SHARE * (image.width() as f64 * image.height() as f64).max(1.0)
}

/// Append `image` in `format` with its mip levels (`mip_levels`); its table index.
fn add_as(attributes: &mut SurfaceAttributes, image: &image::RgbaImage, format: u32) -> u32 {
    let offset = attributes.texels.len() as u32;
    let levels = mip_levels(image, format == kernels::types::TEXTURE_SRGB8);
    attributes.textures.push(TextureInfo {
        offset,
        width: image.width(),
        height: image.height(),
        format: format | (levels.len() as u32) << kernels::types::TEXTURE_LEVELS,
    });
    for level in &levels {
        attributes.texels.extend(
            level
                .pixels()
                .map(|p| u32::from_le_bytes([p[0], p[1], p[2], p[3]])),
        );
    }
    attributes.textures.len() as u32 - 1
}

/// `image` and its mip levels down to one texel (`kernels::texture::level`'s layout):
/// each texel of a level the box average of the 2 × 2 texels it covers in the level
/// before (3 wide or high at the last column or row of an odd size, so that no texel is
/// left out). `srgb`: colour is averaged as linear light, then encoded again; alpha and
/// data textures are averaged as stored.
pub fn mip_levels(image: &image::RgbaImage, srgb: bool) -> Vec<image::RgbaImage> {
    use rayon::prelude::*;
    let decode: Vec<f32> = (0..=255u8)
        .map(|c| {
            let c = c as f32 / 255.0;
            if srgb {
                kernels::texture::srgb_to_linear(c)
            } else {
                c
            }
        })
        .collect();
    let encode = |v: f32| {
        let v = if srgb { linear_to_srgb(v) } else { v };
        (v * 255.0).round().clamp(0.0, 255.0) as u8
    };
    let mut levels = vec![image.clone()];
    while let Some(last) = levels.last().filter(|l| l.width() > 1 || l.height() > 1) {
        let (sw, sh) = (last.width(), last.height());
        let (w, h) = ((sw / 2).max(1), (sh / 2).max(1));
        // The source texels that destination texel i of n covers along an axis of size s.
        let span = |i: u32, n: u32, s: u32| {
            let end = if i + 1 == n { s } else { (2 * i + 2).min(s) };
            (2 * i).min(s - 1)..end
        };
        let mut next = image::RgbaImage::new(w, h);
        next.par_chunks_mut(4 * w as usize)
            .enumerate()
            .for_each(|(y, row)| {
                for (x, texel) in row.chunks_mut(4).enumerate() {
                    let mut sum = [0.0f32; 4];
                    let mut count = 0.0;
                    for sy in span(y as u32, h, sh) {
                        for sx in span(x as u32, w, sw) {
                            let p = last.get_pixel(sx, sy);
                            for c in 0..3 {
                                sum[c] += decode[p[c] as usize];
                            }
                            sum[3] += p[3] as f32 / 255.0;
                            count += 1.0;
                        }
                    }
                    for c in 0..3 {
                        texel[c] = encode(sum[c] / count);
                    }
                    texel[3] = (sum[3] / count * 255.0).round() as u8;
                }
            });
        levels.push(next);
    }
    levels
}

/// Linear light → sRGB (IEC 61966-2-1), the inverse of `kernels::texture::srgb_to_linear`.
fn linear_to_srgb(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;

    #[test]
    fn map_statements_keep_spaces_in_file_names_and_read_their_options() {
        let plain = parse_map_statement("textures\\wood floor.png");
        assert_eq!(plain.file, "textures/wood floor.png");
        assert_eq!(
            (plain.scale, plain.offset, plain.clamp),
            (Vec2::ONE, Vec2::ZERO, false)
        );
        let m = parse_map_statement("-s 4 2 1 -o 0.5 -clamp on -bm 0.3 -imfchan l my map.png ");
        assert_eq!(m.file, "my map.png");
        assert_eq!(m.scale, Vec2::new(4.0, 2.0));
        assert_eq!(m.offset, Vec2::new(0.5, 0.0));
        assert!(m.clamp);
        assert_eq!(m.bump_multiplier, Some(0.3));
        assert_eq!(m.uv_map().transform_point2(Vec2::ONE), Vec2::new(4.5, 2.0));
        // A file name of digits after an option of up to three numbers, and options this
        // loader does not read, with their values.
        let m = parse_map_statement("-mm 0 1 -t 1 1 -s 3 2024.jpg");
        assert_eq!(
            (m.file.as_str(), m.scale),
            ("2024.jpg", Vec2::new(3.0, 1.0))
        );
        assert!(!parse_map_statement("-clamp off a.png").clamp);
        assert_eq!(parse_map_statement("n.png").bump_multiplier, None);
    }

    #[test]
    fn a_texture_read_through_a_sampler_is_one_more_entry_however_often_asked() {
        use kernels::types::{
            sampler, TEXTURE_FORMAT, TEXTURE_LEVELS_MASK, WRAP_CLAMP, WRAP_MIRROR, WRAP_REPEAT,
        };
        let mut attributes = SurfaceAttributes::default();
        let image = image::RgbaImage::from_pixel(2, 2, image::Rgba([10, 20, 30, 255]));
        let a = add(&mut attributes, &image);
        let b = add_linear(&mut attributes, &image);
        assert_eq!(
            with_sampler(&mut attributes, a, sampler(WRAP_REPEAT, WRAP_REPEAT, false)),
            a
        );
        let clamp = sampler(WRAP_CLAMP, WRAP_CLAMP, false);
        let a_clamped = with_sampler(&mut attributes, a, clamp);
        assert_eq!(with_sampler(&mut attributes, a, clamp), a_clamped);
        // Another texture or another sampler is an entry of its own.
        let b_clamped = with_sampler(&mut attributes, b, clamp);
        let a_mirrored = with_sampler(&mut attributes, a, sampler(WRAP_MIRROR, WRAP_CLAMP, true));
        let entries = [a, b, a_clamped, b_clamped, a_mirrored];
        assert_eq!(attributes.textures.len(), entries.len());
        for (i, &e) in entries.iter().enumerate() {
            assert!(!entries[..i].contains(&e), "{entries:?}");
        }
        // The same texels and texel format, its own sampler bits.
        let (t, tc) = (
            attributes.textures[b as usize],
            attributes.textures[b_clamped as usize],
        );
        assert_eq!(
            (tc.offset, tc.width, tc.height),
            (t.offset, t.width, t.height)
        );
        assert_eq!(tc.format, t.format | clamp);
        assert_eq!(t.format & !(TEXTURE_FORMAT | TEXTURE_LEVELS_MASK), 0);
    }

    #[test]
    fn mip_levels_average_the_texels_they_cover_as_linear_light() {
        // 5 × 2: one black and one white column pair, and a fifth column of grey 128.
        let mut image = image::RgbaImage::new(5, 2);
        for (x, _, p) in image.enumerate_pixels_mut() {
            let c = [0, 0, 255, 255, 128][x as usize];
            *p = image::Rgba([c, c, c, x as u8 * 50]);
        }
        let data = mip_levels(&image, false);
        let sizes: Vec<(u32, u32)> = data.iter().map(|l| l.dimensions()).collect();
        assert_eq!(sizes, [(5, 2), (2, 1), (1, 1)]);
        // Level 1: texel 0 covers columns 0..2, texel 1 (the last) columns 2..5.
        assert_eq!(data[1].get_pixel(0, 0).0, [0, 0, 0, 25]);
        let last = ((255.0 * 2.0 + 128.0) / 3.0f32).round() as u8;
        assert_eq!(data[1].get_pixel(1, 0).0, [last, last, last, 150]);
        // Colour: black and white average to half the light, sRGB 188, not 128.
        let colour = mip_levels(&image, true);
        assert_eq!(colour[1].get_pixel(0, 0)[0], 0);
        let pair = image::RgbaImage::from_fn(2, 1, |x, _| image::Rgba([x as u8 * 255; 4]));
        assert_eq!(
            mip_levels(&pair, true)[1].get_pixel(0, 0).0,
            [188, 188, 188, 128]
        );
        // One texel is its own last level; a texture keeps its levels with its sampler.
        assert_eq!(mip_levels(&image::RgbaImage::new(1, 1), true).len(), 1);
        let mut attributes = SurfaceAttributes::default();
        let t = add(&mut attributes, &image);
        assert_eq!(attributes.texels.len(), 10 + 2 + 1);
        let clamp = kernels::types::sampler(kernels::types::WRAP_CLAMP, 0, false);
        let clamped = with_sampler(&mut attributes, t, clamp);
        let clamped = attributes.textures[clamped as usize];
        assert_eq!(kernels::texture::levels(&clamped), 3);
    }

    #[test]
    fn normal_maps_are_told_from_height_maps() {
        let flat = image::RgbaImage::from_pixel(4, 4, image::Rgba([128, 128, 255, 255]));
        assert!(is_normal_map(&flat));
        let tilted = image::RgbaImage::from_pixel(4, 4, image::Rgba([191, 128, 238, 255]));
        assert!(is_normal_map(&tilted));
        // Grey at any level, even where (2c − 1)·√3 is a unit length (c ≈ 201).
        for level in [90, 128, 201, 255] {
            let grey = image::RgbaImage::from_pixel(4, 4, image::Rgba([level, level, level, 255]));
            assert!(!is_normal_map(&grey), "grey {level}");
        }
    }
}
