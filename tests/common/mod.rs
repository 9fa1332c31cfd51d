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
    let o = run_render_cpu(scene, out, args);
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{stderr}");
    (runner::output::read_image(out).unwrap(), stderr)
}

/// `runner render --backend cpu --scene SCENE --out OUT ARGS...`, whatever its outcome.
pub fn run_render_cpu(
    scene: &std::path::Path,
    out: &std::path::Path,
    args: &[&str],
) -> std::process::Output {
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
    runner(&all)
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

/// Render arguments for a 2x2 floor at y = 0 seen from straight above (eye 3 up, 30°
/// field of view, image up = −z, so the floor's x runs left to right): a square image of
/// `pixels`, `spp` samples, then `rest`.
pub fn floor_view(pixels: u32, spp: u32, rest: &[&str]) -> Vec<String> {
    let mut args: Vec<String> = [
        "--eye", "0,3,0", "--target", "0,0,0", "--up", "0,0,-1", "--fov", "30",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    args.extend([
        "--width".to_string(),
        pixels.to_string(),
        "--height".to_string(),
        pixels.to_string(),
        "--spp".to_string(),
        spp.to_string(),
    ]);
    args.extend(rest.iter().map(|s| s.to_string()));
    args
}

/// `args` as the `&str`s `render_cpu` takes.
pub fn strs(args: &[String]) -> Vec<&str> {
    args.iter().map(String::as_str).collect()
}

/// The 2 × 2 floor at y = 0 (normal +y) that `floor_view` looks down on, as `gltf_floor`
/// takes it (triangles 0-1-2 and 0-2-3, counter-clockwise seen from above).
pub const FLOOR: [[f32; 3]; 4] = [
    [-1.0, 0.0, -1.0],
    [-1.0, 0.0, 1.0],
    [1.0, 0.0, 1.0],
    [1.0, 0.0, -1.0],
];

/// `FLOOR`'s texture coordinates as glTF has them: u along +x, v along +z, so `floor_view`
/// shows v = 0 at the top of the image.
pub fn floor_uvs() -> Vec<f32> {
    FLOOR
        .iter()
        .flat_map(|c| [(c[0] + 1.0) / 2.0, (c[2] + 1.0) / 2.0])
        .collect()
}

/// Write `dir/floor.gltf` (and `floor.bin`): one quad on `corners` (two triangles, 0-1-2
/// and 0-2-3) with float vertex attributes `attributes` (glTF name, accessor type, the four
/// corners' values), material `material` (JSON) and external images `images` (file names,
/// texture i = image i). Returns its path.
pub fn gltf_floor(
    dir: &std::path::Path,
    corners: [[f32; 3]; 4],
    attributes: &[(&str, &str, Vec<f32>)],
    material: &str,
    images: &[&str],
) -> std::path::PathBuf {
    let mut buffer: Vec<u8> = corners
        .iter()
        .flatten()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    let mut views = vec![(0, 48)];
    let mut accessors = vec![
        r#"{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-1,0,-1],"max":[1,0,1]}"#
            .to_string(),
    ];
    let mut names = vec![r#""POSITION":0"#.to_string()];
    for (name, kind, values) in attributes {
        let start = buffer.len();
        buffer.extend(values.iter().flat_map(|x| x.to_le_bytes()));
        views.push((start, buffer.len() - start));
        names.push(format!(r#""{name}":{}"#, accessors.len()));
        accessors.push(format!(
            r#"{{"bufferView":{},"componentType":5126,"count":4,"type":"{kind}"}}"#,
            views.len() - 1
        ));
    }
    let start = buffer.len();
    buffer.extend([0u32, 1, 2, 0, 2, 3].iter().flat_map(|x| x.to_le_bytes()));
    views.push((start, 24));
    let indices = accessors.len();
    accessors.push(format!(
        r#"{{"bufferView":{},"componentType":5125,"count":6,"type":"SCALAR"}}"#,
        views.len() - 1
    ));
    std::fs::write(dir.join("floor.bin"), &buffer).unwrap();
    let views: Vec<String> = views
        .iter()
        .map(|(o, l)| format!(r#"{{"buffer":0,"byteOffset":{o},"byteLength":{l}}}"#))
        .collect();
    let textures: Vec<String> = (0..images.len())
        .map(|i| format!(r#"{{"source":{i}}}"#))
        .collect();
    let images: Vec<String> = images
        .iter()
        .map(|f| format!(r#"{{"uri":"{f}"}}"#))
        .collect();
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"extensionsUsed":["KHR_materials_specular"],"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
"meshes":[{{"primitives":[{{"attributes":{{{}}},"indices":{indices},"material":0}}]}}],
"materials":[{material}],"textures":[{}],"images":[{}],"accessors":[{}],"bufferViews":[{}],
"buffers":[{{"byteLength":{},"uri":"floor.bin"}}]}}"#,
        names.join(","),
        textures.join(","),
        images.join(","),
        accessors.join(","),
        views.join(","),
        buffer.len()
    );
    let path = dir.join("floor.gltf");
    std::fs::write(&path, json).unwrap();
    path
}
