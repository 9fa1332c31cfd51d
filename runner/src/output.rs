//! Image output: PNG (sRGB-encoded, clamped to [0, 1]) or OpenEXR (linear float RGB).
use std::path::PathBuf;

use clap::Args;
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
    if path.is_dir() {
        bail!("output '{}' is a directory", path.display());
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        bail!(
            "output '{}': directory '{}' does not exist",
            path.display(),
            dir.display()
        );
    }
    let md = std::fs::metadata(dir).context(|| format!("output '{}'", path.display()))?;
    if md.permissions().readonly() {
        bail!(
            "output '{}': directory '{}' is not writable",
            path.display(),
            dir.display()
        );
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
    let mut bytes = std::io::Cursor::new(Vec::new());
    match output_format(path)? {
        OutputFormat::Png => {
            let mut buf = RgbImage::new(image.width, image.height);
            for (dst, src) in buf.pixels_mut().zip(&image.pixels) {
                let c = src
                    .to_array()
                    .map(|x| (linear_to_srgb(x) * 255.0 + 0.5) as u8);
                *dst = image::Rgb(c);
            }
            buf.write_to(&mut bytes, ImageFormat::Png).context(what)?;
        }
        OutputFormat::Exr => {
            let mut buf = Rgb32FImage::new(image.width, image.height);
            for (dst, src) in buf.pixels_mut().zip(&image.pixels) {
                *dst = image::Rgb(src.to_array());
            }
            buf.write_to(&mut bytes, ImageFormat::OpenExr)
                .context(what)?;
        }
    }
    write_file(path, bytes.get_ref())
}

/// Write `bytes` to `path` so that it is either the whole new file or untouched: into a
/// temporary file beside it, flushed to disk, then renamed over it. Every failure is
/// reported (a full disk, a file-size limit, a write error that a dropped buffer would have
/// swallowed). A symbolic link is written through to what it names; something that is not a
/// regular file (a device such as /dev/null, a FIFO) is written to directly.
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::Write;
    let what = || format!("cannot write '{}'", path.display());
    let target = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
    if target.exists() && !target.is_file() {
        let mut f = std::fs::OpenOptions::new()
            .write(true)
            .open(&target)
            .context(what)?;
        return f.write_all(bytes).and_then(|()| f.flush()).context(what);
    }
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = target.with_file_name(format!(".{name}.partial-{}", std::process::id()));
    let written = std::fs::File::create(&tmp).and_then(|mut f| {
        f.write_all(bytes)?;
        f.sync_all()
    });
    match written.and_then(|()| std::fs::rename(&tmp, &target)) {
        Ok(()) => Ok(()),
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(crate::error::Error(format!("{}: {e}", what())))
        }
    }
}

/// Read a PNG (sRGB-decoded) or EXR (linear) image.
pub fn read_image(path: &Path) -> Result<Image> {
    let format = output_format(path)?;
    let img = image::open(path).context(|| format!("cannot read image '{}'", path.display()))?;
    let rgb = img.to_rgb32f();
    let decode = |x: f32| match format {
        // `image` converts 8-bit PNG to float without undoing the sRGB curve.
        OutputFormat::Png => kernels::texture::srgb_to_linear(x),
        OutputFormat::Exr => x,
    };
    Ok(Image {
        width: rgb.width(),
        height: rgb.height(),
        pixels: rgb
            .pixels()
            .map(|p| Vec3::new(decode(p[0]), decode(p[1]), decode(p[2])))
            .collect(),
    })
}

/// Error of an image against a reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageError {
    pub rmse: f64,
    /// Mean over pixels and channels of (x − ref)² / (ref² + 0.01): the relative MSE used
    /// in rendering papers, stable where the reference is dark.
    pub rel_mse: f64,
    pub max_abs: f64,
    /// Fraction of pixels equal to the reference within 1e-4 relative.
    pub identical: f64,
}

pub fn compare(image: &Image, reference: &Image) -> Result<ImageError> {
    if (image.width, image.height) != (reference.width, reference.height) {
        bail!(
            "images differ in size: {}x{} vs {}x{}",
            image.width,
            image.height,
            reference.width,
            reference.height
        );
    }
    for (img, which) in [(image, "the image"), (reference, "the reference")] {
        if let Some(i) = img.pixels.iter().position(|p| !p.is_finite()) {
            bail!(
                "{which} has a non-finite pixel at ({}, {}): {}; errors cannot be measured",
                i % img.width.max(1) as usize,
                i / img.width.max(1) as usize,
                img.pixels[i]
            );
        }
    }
    let (mut se, mut rel, mut max_abs, mut same) = (0.0f64, 0.0f64, 0.0f64, 0usize);
    for (a, b) in image.pixels.iter().zip(&reference.pixels) {
        let d = (*a - *b).abs();
        if d.max_element() <= 1e-4 * b.abs().max_element().max(1.0) {
            same += 1;
        }
        for c in 0..3 {
            let (x, r) = (a[c] as f64, b[c] as f64);
            se += (x - r).powi(2);
            rel += (x - r).powi(2) / (r * r + 0.01);
            max_abs = max_abs.max((x - r).abs());
        }
    }
    let n = image.pixels.len().max(1) as f64;
    Ok(ImageError {
        rmse: (se / (3.0 * n)).sqrt(),
        rel_mse: rel / (3.0 * n),
        max_abs,
        identical: same as f64 / n,
    })
}

#[derive(Args, Debug, Clone)]
pub struct CompareArgs {
    /// The image to judge (.exr keeps linear values; .png is decoded from sRGB)
    pub image: PathBuf,
    /// The reference image, same size
    pub reference: PathBuf,
}

/// `runner compare`: the one line of error measures it prints.
pub fn compare_report(args: &CompareArgs) -> Result<String> {
    let image = read_image(&args.image)?;
    let reference = read_image(&args.reference)?;
    let e = compare(&image, &reference)?;
    Ok(format!(
        "rmse {:.6}  relmse {:.6}  max_abs {:.6}  identical {:.2}%  (mean {:.5} vs {:.5})",
        e.rmse,
        e.rel_mse,
        e.max_abs,
        100.0 * e.identical,
        image.mean().dot(glam::Vec3::splat(1.0 / 3.0)),
        reference.mean().dot(glam::Vec3::splat(1.0 / 3.0)),
    ))
}
