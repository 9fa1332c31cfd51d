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
