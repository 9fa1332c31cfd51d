//! Scene builders and statistics helpers shared by the integration tests.
#![allow(dead_code)]
use glam::Vec3;
use kernels::types::Material;

#[allow(unused_imports)]
pub use runner::generate::{closed_box, icosphere, quad};

/// Run the real `runner` binary with `args` (no display needed: XDG_RUNTIME_DIR is set).
pub fn runner(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_runner"))
        .args(args)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .expect("runner binary runs")
}

/// `runner render --backend cpu --scene SCENE --out OUT ARGS…`, which must succeed: the
/// image it wrote and its stderr.
pub fn render_cpu(
    scene: &std::path::Path,
    out: &std::path::Path,
    args: &[&str],
) -> (runner::output::Image, String) {
    let mut all = vec![
        "render",
        "--backend",
        "cpu",
        "--scene",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    all.extend_from_slice(args);
    let o = runner(&all);
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{stderr}");
    (runner::output::read_image(out).unwrap(), stderr)
}

/// A folder of the test's own under cargo's temporary directory.
pub fn tmp_dir(name: &str) -> std::path::PathBuf {
    let d = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::create_dir_all(&d).unwrap();
    d
}

pub fn grey(albedo: f32) -> Material {
    Material::new(Vec3::splat(albedo), Vec3::ZERO)
}

/// Mean of independent estimates and the standard error of that mean.
pub fn mean_and_standard_error(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// Number of standard errors between an estimate and its expectation.
pub fn z_score(estimate: f64, expected: f64, std_error: f64) -> f64 {
    (estimate - expected).abs() / std_error
}

/// Pearson's χ² statistic of observed counts against expected counts.
pub fn chi_square(observed: &[u64], expected: &[f64]) -> f64 {
    observed
        .iter()
        .zip(expected)
        .map(|(&o, &e)| (o as f64 - e).powi(2) / e)
        .sum()
}

/// Upper critical value of χ² with `dof` degrees of freedom at significance 1e-4
/// (Wilson–Hilferty approximation; z = 3.719).
pub fn chi_square_critical(dof: usize) -> f64 {
    let k = dof as f64;
    let z = 3.719;
    k * (1.0 - 2.0 / (9.0 * k) + z * (2.0 / (9.0 * k)).sqrt()).powi(3)
}

/// An image against a reference (same size): (mean / reference mean − 1, RMS of the
/// differences of `block`×`block`-pixel averages, relative to the reference's mean), both
/// over RGB. How the Mitsuba comparisons judge a render: the mean for bias, the blocks for
/// where the light goes, with the per-pixel noise averaged out.
pub fn mean_and_block_rms(
    image: &runner::output::Image,
    reference: &runner::output::Image,
    block: usize,
) -> (f64, f64) {
    let (w, h) = (reference.width as usize, reference.height as usize);
    let average = |img: &runner::output::Image, bx: usize, by: usize| {
        let mut s = Vec3::ZERO;
        for y in by * block..(by + 1) * block {
            for x in bx * block..(bx + 1) * block {
                s += img.pixels[y * w + x];
            }
        }
        s / (block * block) as f32
    };
    let (nx, ny) = (w / block, h / block);
    let mut sq = 0.0;
    for by in 0..ny {
        for bx in 0..nx {
            let d = average(image, bx, by) - average(reference, bx, by);
            sq += d.length_squared() as f64 / 3.0;
        }
    }
    let (ours, theirs) = (image.mean().element_sum(), reference.mean().element_sum());
    let rms = (sq / (nx * ny) as f64).sqrt() / theirs as f64 * 3.0;
    (ours as f64 / theirs as f64 - 1.0, rms)
}
