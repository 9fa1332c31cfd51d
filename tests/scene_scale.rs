//! A scene renders the same whatever its units and wherever it stands: the loader moves
//! small and far scenes into the range where ray offsets are precise
//! (`runner::scene_frame`; OBJ and PLY positions are moved in f64, before they are rounded
//! to f32), and the camera and AO distance given in the file's units follow.
//! Through the real binary, as a user's OBJ would go.
use std::path::PathBuf;
use std::process::Command;

fn dir() -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("scene_scale");
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A unit box on a 4 × 4 floor under the built-in sky, its coordinates times `scale` plus
/// `offset`, with its camera line in the same units.
fn box_on_floor(scale: f64, offset: [f64; 3]) -> String {
    let at = |p: [f64; 3]| {
        let q: Vec<String> = (0..3)
            .map(|i| format!("{:e}", p[i] * scale + offset[i]))
            .collect();
        q.join(" ")
    };
    let mut obj = format!(
        "# camera: eye={} target={} up=0,1,0 fov=40\n",
        at([2.5, 2.0, 3.0]).replace(' ', ","),
        at([0.0, 0.4, 0.0]).replace(' ', ",")
    );
    for p in [
        [-2.0, 0.0, -2.0],
        [2.0, 0.0, -2.0],
        [2.0, 0.0, 2.0],
        [-2.0, 0.0, 2.0],
    ] {
        obj += &format!("v {}\n", at(p));
    }
    obj += "f 1 4 3 2\n";
    for i in 0..8 {
        let c = |bit: usize| if i >> bit & 1 == 1 { 0.5 } else { -0.5 };
        obj += &format!("v {}\n", at([c(0), c(1) + 0.5, c(2)]));
    }
    // The box's faces (vertices 5..12: bit 0 = +x, bit 1 = +y, bit 2 = +z), outwards.
    for f in [
        "5 7 8 6",
        "9 10 12 11",
        "5 6 10 9",
        "7 11 12 8",
        "5 9 11 7",
        "6 8 12 10",
    ] {
        obj += &format!("f {f}\n");
    }
    obj
}

/// An OBJ's vertices and faces (no camera line) as an ASCII PLY with f64 positions.
fn obj_as_ply(obj: &str) -> String {
    let lines = |key: &str| -> Vec<String> {
        obj.lines()
            .filter_map(|l| l.strip_prefix(key))
            .map(str::to_string)
            .collect()
    };
    let (vertices, faces) = (lines("v "), lines("f "));
    let mut ply = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty double x\nproperty double y\n\
         property double z\nelement face {}\nproperty list uchar int vertex_indices\n\
         end_header\n",
        vertices.len(),
        faces.len()
    );
    for v in vertices {
        ply += &format!("{v}\n");
    }
    for f in faces {
        let corners: Vec<String> = f
            .split_whitespace()
            .map(|k| (k.parse::<usize>().unwrap() - 1).to_string())
            .collect();
        ply += &format!("{} {}\n", corners.len(), corners.join(" "));
    }
    ply
}

/// The image of PLY text `ply` with `flags`, as linear RGB floats.
fn render_ply(name: &str, ply: &str, flags: &[&str]) -> Vec<f32> {
    render_file(&format!("{name}.ply"), ply, flags)
}

/// The image of `obj` with `flags`, as linear RGB floats.
fn render(name: &str, obj: &str, flags: &[&str]) -> Vec<f32> {
    render_file(&format!("{name}.obj"), obj, flags)
}

/// The image of scene file `file_name` holding `text`, rendered with `flags`.
fn render_file(file_name: &str, text: &str, flags: &[&str]) -> Vec<f32> {
    let name = file_name.rsplit_once('.').unwrap().0;
    let scene = dir().join(file_name);
    std::fs::write(&scene, text).unwrap();
    let out = dir().join(format!("{name}.exr"));
    let mut args = vec![
        "render",
        "--backend",
        "cpu",
        "--width",
        "48",
        "--height",
        "36",
    ];
    args.extend(["--seed", "7", "--scene", scene.to_str().unwrap()]);
    args.extend(["--out", out.to_str().unwrap()]);
    args.extend(flags);
    let o = Command::new(env!("CARGO_BIN_EXE_runner"))
        .args(&args)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    image::open(&out).unwrap().to_rgb32f().into_raw()
}

/// The two images' pixel means differ by less than 4 standard errors of that difference
/// (pixels as independent samples), and at least `share` of their pixels are equal to 1e-4
/// relative: what one scene in other units gives. The offset near the origin made a box
/// 1e-6 across 13% brighter in AO, with 41% of its pixels equal.
fn assert_same_picture(got: &[f32], want: &[f32], share: f64, what: &str) {
    let stats = |v: &[f32]| {
        let n = v.len() as f64;
        let mean = v.iter().map(|&x| x as f64).sum::<f64>() / n;
        let var = v.iter().map(|&x| (x as f64 - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (mean, var / n)
    };
    let ((m1, v1), (m2, v2)) = (stats(got), stats(want));
    let se = (v1 + v2).sqrt();
    assert!(
        (m1 - m2).abs() < 4.0 * se,
        "{what}: mean {m1} vs {m2} (se {se})"
    );
    let equal = got
        .iter()
        .zip(want)
        .filter(|(a, b)| (*a - *b).abs() <= 1e-4 * b.abs().max(1e-3))
        .count();
    let equal = equal as f64 / want.len() as f64;
    assert!(
        equal >= share,
        "{what}: {:.1}% of the pixels equal",
        100.0 * equal
    );
}

#[test]
fn small_and_far_scenes_render_as_at_unit_scale() {
    let ao = ["--integrator", "ao", "--spp", "16", "--ao-rays", "4"];
    let mis = ["--integrator", "mis", "--spp", "16"];
    let unit = box_on_floor(1.0, [0.0; 3]);
    let (unit_ao, unit_mis) = (
        render("unit_ao", &unit, &ao),
        render("unit_mis", &unit, &mis),
    );
    for (name, scale, offset) in [
        ("micro", 1e-6, [0.0; 3]),
        ("far", 1.0, [3.0e4, -1.0e4, 0.0]),
        ("small_and_far", 1e-3, [40.0, 0.0, 0.0]),
    ] {
        let obj = box_on_floor(scale, offset);
        // The AO distance (the default: a quarter of the diagonal) given in the file's units.
        let d = format!("{:e}", 0.25 * 33f64.sqrt() * scale);
        let ao_in_units = [&ao[..], &["--ao-distance", &d]].concat();
        let got = render(&format!("{name}_ao"), &obj, &ao_in_units);
        assert_same_picture(&got, &unit_ao, 0.97, &format!("{name} AO"));
        // Path samples that meet the same surfaces a hair apart can part ways: fewer
        // pixels stay equal, the mean stays.
        let got = render(&format!("{name}_mis"), &obj, &mis);
        assert_same_picture(&got, &unit_mis, 0.5, &format!("{name} MIS"));
    }
    // Georeferenced (UTM-like coordinates, millions of units from the origin, where f32
    // steps are 0.5): read in f64 and moved before the rounding, under the default camera.
    let without_camera = |obj: String| obj.lines().skip(1).collect::<Vec<_>>().join("\n");
    // (A box 0.3 across: f32's 0.5 steps there would squash it flat.)
    let unit = without_camera(box_on_floor(0.3, [0.0; 3]));
    let offset = [5.0e6 + 0.37, 30.0, 4.0e6 + 0.61];
    let utm = without_camera(box_on_floor(0.3, offset));
    let want = render("unit_default_ao", &unit, &ao);
    let got = render("utm_ao", &utm, &ao);
    assert_same_picture(&got, &want, 0.97, "georeferenced AO");
    // With its camera line, read in f64 too (in f32 the eye would be up to 0.25 off).
    let framed = render("small_cam_ao", &box_on_floor(0.3, [0.0; 3]), &ao);
    let got = render("utm_cam_ao", &box_on_floor(0.3, offset), &ao);
    assert_same_picture(&got, &framed, 0.97, "georeferenced AO, the file's camera");
    // The same as a PLY of doubles, as scanners export georeferenced meshes.
    let got = render_ply("utm_ply_ao", &obj_as_ply(&utm), &ao);
    assert_same_picture(&got, &want, 0.97, "georeferenced PLY AO");
    // --eye and --target in the file's units, instead of its camera line.
    let obj = without_camera(box_on_floor(1e-6, [0.0; 3]));
    let flags = [
        "--eye",
        "2.5e-6,2e-6,3e-6",
        "--target",
        "0,4e-7,0",
        "--fov",
        "40",
    ];
    let got = render("micro_flags_ao", &obj, &[&ao[..], &flags].concat());
    assert_same_picture(&got, &unit_ao, 0.97, "micro AO, camera by flags");
}
