//! PLY meshes, ASCII and binary: the same geometry as an OBJ renders the same image, vertex
//! normals are read, and broken files are one error line.
mod common;

use common::{render_cpu, tmp_dir as dir};

use std::process::Command;

/// The Cornell box's vertices and polygons (its materials left out).
fn cornell_geometry() -> (Vec<[f32; 3]>, Vec<Vec<u32>>) {
    let (mut v, mut f) = (Vec::new(), Vec::new());
    for line in runner::scene::CORNELL_BOX_OBJ.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.first() {
            Some(&"v") => v.push([
                w[1].parse().unwrap(),
                w[2].parse().unwrap(),
                w[3].parse().unwrap(),
            ]),
            Some(&"f") => f.push(
                w[1..]
                    .iter()
                    .map(|c| c.parse::<u32>().unwrap() - 1)
                    .collect(),
            ),
            _ => {}
        }
    }
    (v, f)
}

fn header(format: &str, v: usize, f: usize) -> String {
    format!(
        "ply\nformat {format} 1.0\ncomment the Cornell box\nelement vertex {v}\nproperty float x\n\
         property float y\nproperty float z\nelement face {f}\nproperty list uchar int vertex_indices\nend_header\n"
    )
}

fn render(scene: &std::path::Path, out: &std::path::Path) -> (runner::output::Image, String) {
    render_cpu(
        scene,
        out,
        &[
            "--width",
            "32",
            "--height",
            "32",
            "--spp",
            "4",
            "--eye",
            "278,273,-800",
            "--target",
            "278,273,0",
            "--fov",
            "39.3",
            "--integrator",
            "mis",
        ],
    )
}

#[test]
fn ascii_and_binary_ply_render_what_the_obj_does() {
    let d = dir("ply_cornell");
    let (v, f) = cornell_geometry();
    let mut obj = String::new();
    for p in &v {
        obj += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for face in &f {
        obj += "f";
        for i in face {
            obj += &format!(" {}", i + 1);
        }
        obj += "\n";
    }
    std::fs::write(d.join("box.obj"), obj).unwrap();
    let mut ascii = header("ascii", v.len(), f.len());
    for p in &v {
        ascii += &format!("{} {} {}\n", p[0], p[1], p[2]);
    }
    for face in &f {
        ascii += &format!("{}", face.len());
        for i in face {
            ascii += &format!(" {i}");
        }
        ascii += "\n";
    }
    std::fs::write(d.join("box_ascii.ply"), ascii).unwrap();
    let mut binary = header("binary_little_endian", v.len(), f.len()).into_bytes();
    for p in &v {
        for c in p {
            binary.extend(c.to_le_bytes());
        }
    }
    for face in &f {
        binary.push(face.len() as u8);
        for &i in face {
            binary.extend((i as i32).to_le_bytes());
        }
    }
    std::fs::write(d.join("box_binary.ply"), &binary).unwrap();
    // No emitters and no materials in any of the three: grey under the built-in sky.
    let (obj_image, _) = render(&d.join("box.obj"), &d.join("obj.exr"));
    for ply in ["box_ascii.ply", "box_binary.ply"] {
        let (image, stderr) = render(&d.join(ply), &d.join("ply.exr"));
        assert!(stderr.contains("32 triangles"), "{stderr}");
        assert_eq!(image.pixels, obj_image.pixels, "{ply}");
    }
    // A truncated binary file and an index out of range are errors, each one line.
    std::fs::write(d.join("truncated.ply"), &binary[..binary.len() - 7]).unwrap();
    let mut bad = header("ascii", 3, 1);
    bad += "0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n";
    std::fs::write(d.join("bad_index.ply"), bad).unwrap();
    for (file, message) in [
        ("truncated.ply", "cannot load scene"),
        ("bad_index.ply", "refers to vertex 7 of 3"),
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_runner"))
            .args([
                "render",
                "--backend",
                "cpu",
                "--scene",
                d.join(file).to_str().unwrap(),
                "--out",
                d.join("x.png").to_str().unwrap(),
            ])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{file}");
        assert!(
            stderr.starts_with("error: ")
                && stderr.contains(message)
                && stderr.lines().count() == 1,
            "{file}: {stderr}"
        );
    }
}
