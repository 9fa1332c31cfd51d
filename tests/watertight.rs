//! Watertightness: from inside a closed black sphere under a white sky, a lit pixel is a
//! ray that slipped between two triangles sharing an edge. The same rays on the CPU backend
//! and on the GPU (lavapipe in CI; the H100 in the measurement: 0 in 796 M rays, README).
mod common;

use common::{runner, tmp_dir};

/// Lit pixels of `shell-250k` seen from `view` on `backend` over a BVH of `quality` (256 x
/// 256, 16 spp, camera rays only: 1 M rays).
fn leaked_pixels(backend: &str, quality: &str, view: &[&str], name: &str) -> usize {
    let out = tmp_dir("watertight").join(format!("{backend}_{quality}_{name}.exr"));
    let mut args = vec![
        "render",
        "--backend",
        backend,
        "--scene",
        "shell-250k",
        "--sky",
        "1,1,1",
        "--integrator",
        "pt",
        "--max-depth",
        "1",
        "--spp",
        "16",
        "--width",
        "256",
        "--height",
        "256",
        "--bvh-quality",
        quality,
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(view);
    let o = runner(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let image = runner::output::read_image(&out).unwrap();
    image
        .pixels
        .iter()
        .filter(|p| p.max_element() > 0.0)
        .count()
}

#[test]
fn no_ray_slips_out_of_a_closed_sphere() {
    let views: [(&str, &[&str]); 3] = [
        ("centre", &[]),
        // Looking at the north pole's fan of slivers from close by.
        ("pole", &["--eye", "0,0.5,0", "--target", "0,1,0.01"]),
        // Grazing the wall: long thin projected triangles.
        (
            "grazing",
            &["--eye", "0.95,0,0", "--target", "1,0,0.01", "--fov", "150"],
        ),
    ];
    // `high`: the SBVH, whose split triangles' parts meet at the split planes.
    for backend in ["cpu", "gpu"] {
        for quality in ["auto", "high"] {
            for (name, view) in views {
                let leaked = leaked_pixels(backend, quality, view, name);
                assert_eq!(leaked, 0, "{backend}, {quality}, {name}");
            }
        }
    }
}
