//! Image output: PNG (sRGB-encoded, clamped to [0, 1]) or OpenEXR (linear float RGB).
use std::path::Path;

use glam::Vec3;
use image::{ImageFormat, Rgb32FImage, RgbImage};

use crate::bail;
use crate::error::{Context, Result};

/// A linear-radiance image, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Vec3>,
}

impl Image {
    /// Mean of each pixel from an accumulation buffer (rgb = sum, a = sample count).
    pub fn from_accumulation(width: u32, height: u32, accum: &[[f32; 4]]) -> Self {
        let pixels = accum
            .iter()
            .map(|a| Vec3::new(a[0], a[1], a[2]) / a[3].max(1.0))
            .collect();
        Self {
            width,
            height,
            pixels,
        }
    }

    pub fn mean(&self) -> Vec3 {
        self.pixels.iter().copied().sum::<Vec3>() / self.pixels.len().max(1) as f32
    }
}

#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum OutputFormat {
    Png,
    Exr,
}

/// The format named by the file extension; checked before rendering starts.
pub fn output_format(path: &Path) -> Result<OutputFormat> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("png") => Ok(OutputFormat::Png),
        Some("exr") => Ok(OutputFormat::Exr),
        _ => bail!(
            "output '{}': unknown image format (use .png or .exr)",
            path.display()
        ),
    }
}

/// Fail early, before a long render, if the output cannot be written.
pub fn check_writable(path: &Path) -> Result<OutputFormat> {
    let format = output_format(path)?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        bail!("output '{}': directory '{}' does not exist", path.display(), dir.display());
    }
    let md = std::fs::metadata(dir).context(|| format!("output '{}'", path.display()))?;
    if md.permissions().readonly() {
        bail!("output '{}': directory '{}' is not writable", path.display(), dir.display());
    }
    Ok(format)
}

pub fn linear_to_srgb(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

pub fn write_image(path: &Path, image: &Image) -> Result<()> {
    let what = || format!("cannot write '{}'", path.display());
    match output_format(path)? {
        OutputFormat::Png => {
            let mut buf = RgbImage::new(image.width, image.height);
            for (dst, src) in buf.pixels_mut().zip(&image.pixels) {
                let c = src.to_array().map(|x| (linear_to_srgb(x) * 255.0 + 0.5) as u8);
                *dst = image::Rgb(c);
            }
            buf.save_with_format(path, ImageFormat::Png).context(what)
        }
        OutputFormat::Exr => {
            let mut buf = Rgb32FImage::new(image.width, image.height);
            for (dst, src) in buf.pixels_mut().zip(&image.pixels) {
                *dst = image::Rgb(src.to_array());
            }
            buf.save_with_format(path, ImageFormat::OpenExr).context(what)
        }
    }
}
