//! Environment light on the host: an equirectangular HDR or EXR file (`--env`), or the
//! built-in sky that lights scenes without emitters, stored as an RGBE texture in the
//! scene's texel buffer (see `kernels::env`).
use std::path::Path;

use glam::Vec3;
use kernels::types::{sampler, TextureInfo, TEXTURE_RGBE, WRAP_CLAMP, WRAP_REPEAT};

use crate::bail;
use crate::error::Result;
use crate::scene::SurfaceAttributes;
use crate::textures::{read_image_file, ImageFileError};

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

/// The importance distribution of an equirectangular map (layout in `kernels::env`):
/// texel weights luminance × sin θ (θ of the row's centre), so that sampling follows the
/// radiance per solid angle. Each texel takes the largest luminance of its 3 × 3
/// neighbourhood: bilinear filtering spreads a texel's radiance into its neighbours, and
/// every direction with radiance must have a density (else NEE, which alone accounts for
/// the map where it samples, would miss it). A black map has no distribution (empty).
pub fn distribution(width: u32, height: u32, texels: &[Vec3]) -> Vec<f32> {
    let (w, h) = (width as usize, height as usize);
    let lum = |x: usize, y: usize| kernels::math::luminance(texels[y * w + x]).max(0.0) as f64;
    let mut rows: Vec<Vec<f64>> = Vec::with_capacity(h);
    for y in 0..h {
        let sin_theta = ((y as f64 + 0.5) / h as f64 * std::f64::consts::PI).sin();
        let mut cdf = Vec::with_capacity(w + 1);
        let mut sum = 0.0f64;
        cdf.push(0.0);
        for x in 0..w {
            let mut m = 0.0f64;
            for ny in y.saturating_sub(1)..(y + 2).min(h) {
                for dx in [w - 1, 0, 1] {
                    m = m.max(lum((x + dx) % w, ny));
                }
            }
            sum += m * sin_theta;
            cdf.push(sum);
        }
        rows.push(cdf);
    }
    let total: f64 = rows.iter().map(|r| r[w]).sum();
    if total.is_nan() || total <= 0.0 || !total.is_finite() {
        return Vec::new();
    }
    let mut out = Vec::with_capacity(h + 1 + h * (w + 1));
    let mut acc = 0.0f64;
    out.push(0.0);
    for r in &rows {
        acc += r[w];
        out.push((acc / total) as f32);
    }
    *out.last_mut().expect("h >= 1") = 1.0;
    for r in &rows {
        let row_sum = r[w];
        for (x, v) in r.iter().enumerate() {
            // A black row is never chosen; keep its CDF uniform so that it stays valid.
            let value = if row_sum > 0.0 {
                v / row_sum
            } else {
                x as f64 / w as f64
            };
            out.push(value as f32);
        }
        *out.last_mut().expect("w >= 1") = 1.0;
    }
    out
}

/// Append an equirectangular map of `width × height` linear texels (rows from the top),
/// with its importance distribution (one map per scene).
pub fn add_map(
    attributes: &mut SurfaceAttributes,
    width: u32,
    height: u32,
    texels: &[Vec3],
) -> u32 {
    attributes.env_distribution = distribution(width, height, texels);
    let offset = attributes.texels.len() as u32;
    attributes
        .texels
        .extend(texels.iter().map(|&c| linear_to_rgbe(c)));
    attributes.textures.push(TextureInfo {
        offset,
        width,
        height,
        // Around in longitude; the poles' rows stay theirs (a repeating v blended the
        // zenith with the nadir's row within half a row of either pole).
        format: TEXTURE_RGBE | sampler(WRAP_REPEAT, WRAP_CLAMP, false),
    });
    attributes.textures.len() as u32 - 1
}

/// Read an equirectangular environment (Radiance .hdr or OpenEXR, linear) into the texel
/// buffer; its texture index.
pub fn load(attributes: &mut SurfaceAttributes, path: &Path) -> Result<u32> {
    let name = path.display();
    let image = match read_image_file(path, MAX_ENV_FILE_BYTES, MAX_ENV_TEXELS) {
        Ok(i) => i.to_rgb32f(),
        Err(ImageFileError::Read(e)) => bail!("cannot read --env '{name}': {e}"),
        Err(ImageFileError::Decode(e)) => bail!("cannot decode --env '{name}': {e}"),
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

    /// A map with a small, very bright sun over a dim sky: the hard case.
    fn sun_map() -> (u32, u32, Vec<Vec3>) {
        let (w, h) = (64u32, 32u32);
        let texels = (0..h)
            .flat_map(|y| {
                (0..w).map(move |x| {
                    if (x as i32 - 40).abs() <= 1 && (y as i32 - 9).abs() <= 1 {
                        Vec3::new(5000.0, 4500.0, 4000.0)
                    } else if y < h / 2 {
                        Vec3::new(0.3, 0.4, 0.6)
                    } else {
                        Vec3::splat(0.05)
                    }
                })
            })
            .collect();
        (w, h, texels)
    }

    #[test]
    fn the_sampler_follows_its_pdf() {
        // χ² of directions drawn by `kernels::env::sample_env` against `env_pdf` integrated
        // over solid angle per texel, for both up axes and a turned map.
        let (w, h, texels) = sun_map();
        let mut attributes = SurfaceAttributes::default();
        let texture = add_map(&mut attributes, w, h, &texels);
        let scene = crate::scene::Scene {
            attributes,
            ..Default::default()
        };
        let buffers = scene.kernel();
        for (up, rotation) in [
            (kernels::types::ENV_UP_Y, 0.0),
            (kernels::types::ENV_UP_Y, 1.0),
            (kernels::types::ENV_UP_Z, 0.0),
            (kernels::types::ENV_UP_Z, 1.0),
        ] {
            let params = kernels::types::FrameParams {
                env_texture: texture,
                env_rotation: rotation,
                env_up: up,
                ..Default::default()
            };
            // Cells: the map's texels (rows from the top, columns), found through the map's
            // own mapping, so that the integration below never straddles a texel edge.
            const CZ: usize = 32;
            const CP: usize = 64;
            const N: u32 = 400_000;
            let up_z = up == kernels::types::ENV_UP_Z;
            let cell = |d: Vec3| {
                let uv = kernels::env::equirect_uv(d, up_z, rotation);
                let u = uv.x - uv.x.floor();
                let iz = (((1.0 - uv.y) * CZ as f32) as usize).min(CZ - 1);
                let ip = ((u * CP as f32) as usize).min(CP - 1);
                iz * CP + ip
            };
            let mut rng = kernels::rng::Rng::from_seed(5);
            let mut observed = vec![0u64; CZ * CP];
            let mut mismatched = 0u32;
            for _ in 0..N {
                let (dir, pdf) =
                    kernels::env::sample_env(&buffers, &params, rng.next_f32(), rng.next_f32());
                assert!(pdf > 0.0);
                // The density `env_pdf` gives a drawn direction is the one it was drawn
                // with, but for directions on a texel edge (rounding puts them next door).
                let back = kernels::env::env_pdf(&buffers, &params, dir);
                if (back - pdf).abs() > 1e-2 * pdf {
                    mismatched += 1;
                }
                observed[cell(dir)] += 1;
            }
            assert!(
                mismatched * 1000 < N,
                "{mismatched} of {N} draws disagree with env_pdf"
            );
            // Expected counts: ∫ pdf dω over each cell by a midpoint rule in the map's
            // (u, θ), dω = sin θ dθ dφ.
            const SUB: usize = 8;
            let mut expected = vec![0f64; CZ * CP];
            let pi = std::f64::consts::PI;
            for iz in 0..CZ * SUB {
                let top = (iz as f32 + 0.5) / (CZ * SUB) as f32;
                for ip in 0..CP * SUB {
                    let u = (ip as f32 + 0.5) / (CP * SUB) as f32;
                    let (dir, sin_t) = kernels::env::equirect_direction(u, top, up_z, rotation);
                    let area =
                        sin_t as f64 * (pi / (CZ * SUB) as f64) * (2.0 * pi / (CP * SUB) as f64);
                    expected[cell(dir)] +=
                        kernels::env::env_pdf(&buffers, &params, dir) as f64 * area * N as f64;
                }
            }
            let total: f64 = expected.iter().sum();
            assert!(
                (total / N as f64 - 1.0).abs() < 0.01,
                "the pdf integrates to {}",
                total / N as f64
            );
            let (mut chi2, mut dof, mut po, mut pe) = (0.0, 0usize, 0.0, 0.0);
            for (o, e) in observed.iter().zip(&expected) {
                if *e < 5.0 {
                    po += *o as f64;
                    pe += e;
                } else {
                    chi2 += (*o as f64 - e).powi(2) / e;
                    dof += 1;
                }
            }
            if pe >= 5.0 {
                chi2 += (po - pe).powi(2) / pe;
                dof += 1;
            }
            let k = (dof - 1) as f64;
            let critical = k * (1.0 - 2.0 / (9.0 * k) + 3.719 * (2.0 / (9.0 * k)).sqrt()).powi(3);
            assert!(
                chi2 <= critical,
                "up {up}, rotation {rotation}: χ² {chi2:.1} > {critical:.1} ({dof} cells)"
            );
        }
    }
}
