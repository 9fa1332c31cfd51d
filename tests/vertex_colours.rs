//! Vertex colours (PLY `red green blue`, OBJ `v x y z r g b`, glTF `COLOR_0`) multiply the
//! albedo, interpolated across each triangle.
mod common;

use common::{floor_view, gltf_floor, render_cpu, strs, tmp_dir as dir, FLOOR};
use glam::Vec3;

/// The floor seen from above under a white sky: a Lambertian floor of albedo ρ under a
/// uniform sky of radiance 1 has radiance ρ (direct light only).
fn view() -> Vec<String> {
    floor_view(
        32,
        16,
        &["--integrator", "nee", "--sky", "1,1,1", "--max-depth", "2"],
    )
}

/// Mean of pixel column `x` over the middle rows.
fn column(image: &runner::output::Image, x: usize) -> Vec3 {
    (12..20).map(|y| image.pixels[y * 32 + x]).sum::<Vec3>() / 8.0
}

fn srgb(x: f32) -> f32 {
    kernels::texture::srgb_to_linear(x)
}

fn near(got: Vec3, expected: Vec3, what: &str) {
    assert!(
        (got - expected).abs().max_element() < 0.02,
        "{what}: {got} vs {expected}"
    );
}

#[test]
fn ply_colours_are_srgb_bytes_interpolated_across_the_floor() {
    // Left corners orange (255, 128, 0), right corners blue (0, 0, 255); default albedo 0.8.
    let d = dir("vertex_colours_ply");
    let mut ply = String::from(
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
         property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
         element face 1\nproperty list uchar int vertex_indices\nend_header\n",
    );
    for c in FLOOR {
        let rgb = if c[0] < 0.0 { "255 128 0" } else { "0 0 255" };
        ply += &format!("{} {} {} {rgb}\n", c[0], c[1], c[2]);
    }
    ply += "4 0 1 2 3\n";
    std::fs::write(d.join("floor.ply"), ply).unwrap();
    let (image, stderr) = render_cpu(&d.join("floor.ply"), &d.join("floor.exr"), &strs(&view()));
    assert!(!stderr.contains("vertex colour"), "{stderr}");
    let orange = 0.8 * Vec3::new(1.0, srgb(128.0 / 255.0), 0.0);
    let blue = 0.8 * Vec3::Z;
    // The image spans x = ±3 tan 15° = ±0.80 of the floor's ±1: at a pixel column's
    // centre the floor is this fraction of the way from the left edge to the right.
    let half_width = 3.0 * 15f32.to_radians().tan();
    for (x, what) in [(4, "left"), (16, "middle"), (27, "right")] {
        let fx = (x as f32 + 0.5) / 32.0;
        let t = 0.5 + (fx - 0.5) * half_width;
        near(column(&image, x), orange.lerp(blue, t), what);
    }
}

#[test]
fn obj_and_gltf_colours_multiply_the_albedo() {
    let d = dir("vertex_colours_obj_gltf");
    // OBJ: display values 0..1 after the position; Kd 0.5.
    let mut obj = String::from("mtllib floor.mtl\n");
    for c in FLOOR {
        obj += &format!("v {} {} {} 1 0.5 0\n", c[0], c[1], c[2]);
    }
    obj += "usemtl m\nf 1 2 3 4\n";
    std::fs::write(d.join("floor.obj"), obj).unwrap();
    std::fs::write(d.join("floor.mtl"), "newmtl m\nKd 0.5 0.5 0.5\n").unwrap();
    let (image, _) = render_cpu(&d.join("floor.obj"), &d.join("obj.exr"), &strs(&view()));
    near(
        column(&image, 16),
        0.5 * Vec3::new(1.0, srgb(0.5), 0.0),
        "OBJ",
    );

    // glTF: COLOR_0 is linear; base colour 1, no specular (Lambertian).
    let colour = [0.2f32, 0.6, 0.9];
    let scene = gltf_floor(
        &d,
        FLOOR,
        &[("COLOR_0", "VEC3", colour.repeat(4))],
        r#"{"pbrMetallicRoughness":{"metallicFactor":0},"extensions":{"KHR_materials_specular":{"specularFactor":0}}}"#,
        &[],
    );
    let (image, _) = render_cpu(&scene, &d.join("gltf.exr"), &strs(&view()));
    near(column(&image, 16), Vec3::from(colour), "glTF");
}
