//! Environment light on the host: an equirectangular HDR or EXR file (`--env`), or the
//! built-in sky that lights scenes without emitters, stored as an RGBE texture in the
//! scene's texel buffer (see `kernels::env`).
use std::path::Path;

use glam::Vec3;
use kernels::types::{TextureInfo, TEXTURE_RGBE};

use crate::bail;
use crate::error::Result;
use crate::scene::{read_input_file, SurfaceAttributes};

/// Largest environment file read and largest map decoded (a 16k × 8k map is 2^27).
pub const MAX_ENV_FILE_BYTES: u64 = 2 << 30;
pub const MAX_ENV_TEXELS: u64 = 1 << 27;

/// Linear RGB to Radiance's RGBE word (red in the low byte): the largest component sets
/// the shared exponent; mantissas are rounded down as Radiance writes them.
pub fn linear_to_rgbe(c: Vec3) -> u32 {
    let c = c.max(Vec3::ZERO);
    let m = c.max_element();
    if m.is_nan() || m <= 1e-32 || !m.is_finite() {
        return 0;
    }
    // m = f · 2^e with f in [0.5, 1): mantissa = c · 256 / 2^e.
    let e = m.log2().floor() as i32 + 1;
    let scale = 256.0 / 2f32.powi(e);
    let byte = |x: f32| (x * scale).clamp(0.0, 255.0) as u32;
    byte(c.x) | byte(c.y) << 8 | byte(c.z) << 16 | ((e + 128).clamp(0, 255) as u32) << 24
}

/// Append an equirectangular map of `width × height` linear texels (rows from the top).
pub fn add_map(
    attributes: &mut SurfaceAttributes,
    width: u32,
    height: u32,
    texels: &[Vec3],
) -> u32 {
    let offset = attributes.texels.len() as u32;
    attributes
        .texels
        .extend(texels.iter().map(|&c| linear_to_rgbe(c)));
    attributes.textures.push(TextureInfo {
        offset,
        width,
        height,
        format: TEXTURE_RGBE,
    });
    attributes.textures.len() as u32 - 1
}

/// Read an equirectangular environment (Radiance .hdr or OpenEXR, linear) into the texel
/// buffer; its texture index.
pub fn load(attributes: &mut SurfaceAttributes, path: &Path) -> Result<u32> {
    let name = path.display();
    let bytes = match read_input_file(path, MAX_ENV_FILE_BYTES) {
        Ok(b) => b,
        Err(e) => bail!("cannot read --env '{name}': {e}"),
    };
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| crate::error::Error(format!("cannot read --env '{name}': {e}")))?;
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(MAX_ENV_TEXELS * 16);
    reader.limits(limits);
    let image = match reader.decode() {
        Ok(i) => i.to_rgb32f(),
        Err(e) => bail!("cannot decode --env '{name}': {e}"),
    };
    let (w, h) = image.dimensions();
    if w < 2 || h < 1 || w as u64 * h as u64 > MAX_ENV_TEXELS {
        bail!("--env '{name}' is {w}x{h} texels; an equirectangular map needs 2x1 to {MAX_ENV_TEXELS} texels");
    }
    let texels: Vec<Vec3> = image.pixels().map(|p| Vec3::from(p.0)).collect();
    if let Some(bad) = texels
        .iter()
        .find(|c| !c.is_finite() || c.min_element() < 0.0)
    {
        bail!("--env '{name}' has a texel that is negative or not finite ({bad})");
    }
    if texels.iter().all(|c| c.max_element() <= 0.0) {
        bail!("--env '{name}' is black: it would light nothing");
    }
    Ok(add_map(attributes, w, h, &texels))
}

/// The built-in sky for scenes with neither emitters nor `--sky`/`--env`: a soft studio
/// dome, white overhead (1.0), 0.6 at the horizon, and a grey floor below (0.2), so that
/// shapes are lit from above with soft shading and readable contact shadows. Smooth enough
/// that BSDF sampling finds it with little noise. Up is the map's +y (the `--up-axis` turns
/// it).
pub fn default_sky(attributes: &mut SurfaceAttributes) -> u32 {
    const W: u32 = 64;
    const H: u32 = 32;
    let texels: Vec<Vec3> = (0..H)
        .flat_map(|y| {
            // Row centre's elevation: +90° at the top row, -90° at the bottom.
            let elevation = (0.5 - (y as f32 + 0.5) / H as f32) * std::f32::consts::PI;
            let s = elevation.sin();
            let value = if s >= 0.0 { 0.6 + 0.4 * s.sqrt() } else { 0.2 };
            (0..W).map(move |_| Vec3::splat(value))
        })
        .collect();
    add_map(attributes, W, H, &texels)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rgbe_keeps_three_significant_digits() {
        for c in [
            Vec3::new(1.0, 0.5, 0.25),
            Vec3::new(1e4, 3.0, 0.0),
            Vec3::splat(1e-3),
        ] {
            let back = kernels::texture::rgbe_to_linear(linear_to_rgbe(c)).truncate();
            let err = (back - c).abs().max_element() / c.max_element();
            assert!(err < 1.0 / 128.0, "{c} -> {back}");
        }
        assert_eq!(linear_to_rgbe(Vec3::ZERO), 0);
        assert_eq!(
            kernels::texture::rgbe_to_linear(linear_to_rgbe(Vec3::ZERO)).x,
            0.0
        );
    }
}
