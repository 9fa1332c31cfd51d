//! Tangent-space normal maps (MTL `norm`, `map_Bump` holding a normal map, glTF
//! `normalTexture`) and height maps (MTL `map_Bump`/`bump` holding grey heights) bend the
//! shading normal: a floor under a small sun is as bright as the
//! cosine between the bent normal and the sun says, in the frame the formats define (x
//! along increasing u, y along increasing v: up the image).
mod common;

use common::{floor_view, gltf_floor, render_cpu, strs, tmp_dir as dir};
use glam::Vec3;

/// The floor seen from above (image up = −z), lit only by a sun (`sun()`) up towards +x
/// and a little −z: direct light only, so a Lambertian floor's radiance is
/// ∝ max(0, n_s · sun).
fn view() -> Vec<String> {
    floor_view(
        32,
        16,
        &[
            "--integrator",
            "nee",
            "--sky",
            "0,0,0",
            "--sun",
            "1,1,-0.5",
            "--max-depth",
            "2",
            "--seed",
            "1",
        ],
    )
}

/// The direction towards the sun of `view()`.
fn sun() -> Vec3 {
    Vec3::new(1.0, 1.0, -0.5).normalize()
}

/// The floor's corners and their texture coordinates as OBJ has them (v = 0 at the image's
/// bottom): u grows along +x, v along −z (up the rendered image). Normal +y.
const CORNERS: [([f32; 3], [f32; 2]); 4] = [
    ([-1.0, 0.0, -1.0], [0.0, 1.0]),
    ([-1.0, 0.0, 1.0], [0.0, 0.0]),
    ([1.0, 0.0, 1.0], [1.0, 0.0]),
    ([1.0, 0.0, -1.0], [1.0, 1.0]),
];

/// The normal a constant normal map texel encodes on this floor (tangent +x, bitangent
/// −z, normal +y), exactly as the bytes say.
fn bent_normal(texel: [u8; 3]) -> Vec3 {
    let m = Vec3::from(texel.map(|c| c as f32 / 255.0 * 2.0 - 1.0));
    Vec3::new(m.x, m.z, -m.y).normalize()
}

/// Mean radiance of the middle of the image.
fn middle(image: &runner::output::Image) -> f32 {
    let mut sum = 0.0;
    for y in 8..24 {
        for x in 8..24 {
            sum += image.pixels[y * 32 + x].x;
        }
    }
    sum / 256.0
}

fn write_png(path: &std::path::Path, texel: [u8; 3]) {
    image::RgbaImage::from_pixel(4, 4, image::Rgba([texel[0], texel[1], texel[2], 255]))
        .save(path)
        .unwrap();
}

/// An OBJ floor whose material `m` is `Kd 0.5` plus `map_line` (e.g. `norm n.png`).
fn obj_floor(d: &std::path::Path, map_line: &str) -> std::path::PathBuf {
    let mut obj = String::from("mtllib floor.mtl\n");
    for (p, _) in CORNERS {
        obj += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for (_, uv) in CORNERS {
        obj += &format!("vt {} {}\n", uv[0], uv[1]);
    }
    obj += "usemtl m\nf 1/1 2/2 3/3 4/4\n";
    std::fs::write(d.join("floor.obj"), obj).unwrap();
    std::fs::write(
        d.join("floor.mtl"),
        format!("newmtl m\nKd 0.5 0.5 0.5\n{map_line}\n"),
    )
    .unwrap();
    d.join("floor.obj")
}

const FLAT: [u8; 3] = [128, 128, 255];
/// Tilted 30° towards +u (+x: towards the sun), −u, and +v (−z: a little towards it).
const TOWARDS_U: [u8; 3] = [191, 128, 238];
const AWAY_U: [u8; 3] = [64, 128, 238];
const TOWARDS_V: [u8; 3] = [128, 191, 238];

#[test]
fn a_normal_map_tilts_the_shading_normal_in_the_texture_frame() {
    let d = dir("normal_maps_tilt");
    let sun = sun();
    write_png(&d.join("flat.png"), FLAT);
    let scene = obj_floor(&d, "norm flat.png");
    let (flat_image, stderr) = render_cpu(&scene, &d.join("flat.exr"), &strs(&view()));
    assert!(!stderr.contains("not supported"), "{stderr}");
    let flat = middle(&flat_image);
    assert!(flat > 0.0);
    for (texel, what) in [
        (TOWARDS_U, "towards +u"),
        (AWAY_U, "towards -u"),
        (TOWARDS_V, "towards +v"),
    ] {
        write_png(&d.join("n.png"), texel);
        let scene = obj_floor(&d, "norm n.png");
        let (image, _) = render_cpu(&scene, &d.join("n.exr"), &strs(&view()));
        let expected = bent_normal(texel).dot(sun) / bent_normal(FLAT).dot(sun);
        let ratio = middle(&image) / flat;
        assert!(
            (ratio - expected).abs() < 0.01 * expected.max(0.3),
            "{what}: {ratio} vs {expected}"
        );
    }
}

#[test]
fn map_bump_is_a_normal_map_only_when_its_texels_are_normals() {
    let d = dir("normal_maps_map_bump");
    write_png(&d.join("n.png"), TOWARDS_U);
    let (normal, stderr) = render_cpu(
        &obj_floor(&d, "map_Bump -bm 1 n.png"),
        &d.join("n.exr"),
        &strs(&view()),
    );
    assert!(!stderr.contains("height map"), "{stderr}");
    write_png(&d.join("flat.png"), FLAT);
    let (flat, _) = render_cpu(
        &obj_floor(&d, "norm flat.png"),
        &d.join("f.exr"),
        &strs(&view()),
    );
    assert!(
        middle(&normal) > 1.2 * middle(&flat),
        "the map bent nothing"
    );

    // A grey map is a height map, not normals: a constant height leaves the floor flat.
    write_png(&d.join("h.png"), [90, 90, 90]);
    let (height, stderr) = render_cpu(
        &obj_floor(&d, "bump h.png"),
        &d.join("h.exr"),
        &strs(&view()),
    );
    assert!(!stderr.contains("h.png"), "{stderr}");
    let (m_h, m_f) = (middle(&height), middle(&flat));
    assert!((m_h - m_f).abs() < 0.01 * m_f, "{m_h} vs {m_f}");
}

/// A grey ramp of 64 texels (0, 4, ..., 252) along the image's `columns` (else its rows).
fn write_ramp(path: &std::path::Path, columns: bool) {
    image::RgbaImage::from_fn(64, 64, |x, y| {
        let g = (4 * if columns { x } else { y }) as u8;
        image::Rgba([g, g, g, 255])
    })
    .save(path)
    .unwrap();
}

/// A height map displaces the floor by `-bm` scene units at its brightest, and shades it
/// with the displaced surface's normal: a ramp rising along u by 4/255 a texel (1.004 per
/// unit of u; u spans the 2-unit floor) at `-bm 0.5` tilts the floor by a slope of
/// 0.251 away from the rise; a ramp down the image's rows rises along −v (towards +z).
#[test]
fn height_maps_tilt_the_floor_by_their_slope() {
    let d = dir("normal_maps_height");
    let sun = sun();
    write_png(&d.join("flat.png"), FLAT);
    let (flat, _) = render_cpu(
        &obj_floor(&d, "norm flat.png"),
        &d.join("f.exr"),
        &strs(&view()),
    );
    let slope = 0.5 * (4.0 * 64.0 / 255.0) / 2.0;
    for (columns, normal, what) in [
        (true, Vec3::new(-slope, 1.0, 0.0), "rising along +x"),
        (false, Vec3::new(0.0, 1.0, -slope), "rising along +z"),
    ] {
        write_ramp(&d.join("ramp.png"), columns);
        // Clamped or not (a clamped map is a texture of its own, still a height map).
        for map in [
            "map_Bump -bm 0.5 ramp.png",
            "map_Bump -clamp on -bm 0.5 ramp.png",
        ] {
            let (image, stderr) = render_cpu(&obj_floor(&d, map), &d.join("r.exr"), &strs(&view()));
            assert!(!stderr.contains("ramp.png"), "{stderr}");
            let expected = normal.normalize().dot(sun) / Vec3::Y.dot(sun);
            let ratio = middle(&image) / middle(&flat);
            assert!(
                (ratio - expected).abs() < 0.01 * expected,
                "{what}, {map}: {ratio} vs {expected}"
            );
        }
    }
}

#[test]
fn gltf_normal_textures_agree_with_obj() {
    // The same floor and map as glTF (v runs down the image there: v_gltf = 1 − v_obj) with
    // a normal scale of ½; against the OBJ floor whose map leans half as far in x and y.
    let d = dir("normal_maps_gltf");
    write_png(&d.join("n.png"), TOWARDS_V);
    let uvs: Vec<f32> = CORNERS
        .iter()
        .flat_map(|(_, uv)| [uv[0], 1.0 - uv[1]])
        .collect();
    let scene = gltf_floor(
        &d,
        CORNERS.map(|(p, _)| p),
        &[("TEXCOORD_0", "VEC2", uvs)],
        r#"{"pbrMetallicRoughness":{"baseColorFactor":[0.5,0.5,0.5,1],"metallicFactor":0},
"normalTexture":{"index":0,"scale":0.5},"extensions":{"KHR_materials_specular":{"specularFactor":0}}}"#,
        &["n.png"],
    );
    let (gltf, stderr) = render_cpu(&scene, &d.join("gltf.exr"), &strs(&view()));
    assert!(!stderr.contains("normal textures"), "{stderr}");
    let (obj, _) = render_cpu(
        &obj_floor(&d, "norm -bm 0.5 n.png"),
        &d.join("obj.exr"),
        &strs(&view()),
    );
    let (g, o) = (middle(&gltf), middle(&obj));
    assert!((g - o).abs() < 0.005 * o, "glTF {g} vs OBJ {o}");
    // And that is the analytic value: x and y of the texel halved.
    write_png(&d.join("flat.png"), FLAT);
    let (flat, _) = render_cpu(
        &obj_floor(&d, "norm flat.png"),
        &d.join("f.exr"),
        &strs(&view()),
    );
    let m = Vec3::from(TOWARDS_V.map(|c| c as f32 / 255.0 * 2.0 - 1.0)) * Vec3::new(0.5, 0.5, 1.0);
    let sun = sun();
    let expected = Vec3::new(m.x, m.z, -m.y).normalize().dot(sun) / bent_normal(FLAT).dot(sun);
    let ratio = g / middle(&flat);
    assert!((ratio - expected).abs() < 0.01, "{ratio} vs {expected}");
}

/// glTF TANGENT orients the normal map as the file says, not as the texture coordinates
/// would: on the floor (normal +y) a tangent along −z takes the map's x there, and the
/// bitangent normal × tangent × w its y (w = 1: −x; w = −1: +x).
#[test]
fn gltf_tangents_orient_normal_maps() {
    let d = dir("normal_maps_gltf_tangents");
    let uvs: Vec<f32> = CORNERS
        .iter()
        .flat_map(|(_, uv)| [uv[0], 1.0 - uv[1]])
        .collect();
    let material = r#"{"pbrMetallicRoughness":{"baseColorFactor":[0.5,0.5,0.5,1],"metallicFactor":0},
"normalTexture":{"index":0},"extensions":{"KHR_materials_specular":{"specularFactor":0}}}"#;
    let render = |texel: [u8; 3], w: f32| {
        write_png(&d.join("n.png"), texel);
        let tangents: Vec<f32> = (0..4).flat_map(|_| [0.0, 0.0, -1.0, w]).collect();
        let scene = gltf_floor(
            &d,
            CORNERS.map(|(p, _)| p),
            &[
                ("TEXCOORD_0", "VEC2", uvs.clone()),
                ("TANGENT", "VEC4", tangents),
            ],
            material,
            &["n.png"],
        );
        let (image, stderr) = render_cpu(&scene, &d.join("t.exr"), &strs(&view()));
        assert!(!stderr.contains("not supported"), "{stderr}");
        middle(&image)
    };
    let flat = render(FLAT, 1.0);
    let sun = sun();
    let texel = |t: [u8; 3]| Vec3::from(t.map(|c| c as f32 / 255.0 * 2.0 - 1.0));
    for (t, w, frame, what) in [
        (
            TOWARDS_U,
            1.0,
            [Vec3::NEG_Z, Vec3::NEG_X],
            "x along the tangent",
        ),
        (
            TOWARDS_V,
            1.0,
            [Vec3::NEG_Z, Vec3::NEG_X],
            "y along normal × tangent",
        ),
        (
            TOWARDS_V,
            -1.0,
            [Vec3::NEG_Z, Vec3::X],
            "y flipped by w = −1",
        ),
    ] {
        let m = texel(t);
        let bent = (frame[0] * m.x + frame[1] * m.y + Vec3::Y * m.z).normalize();
        let expected = bent.dot(sun) / Vec3::Y.dot(sun);
        let ratio = render(t, w) / flat;
        assert!(
            (ratio - expected).abs() < 0.01 * expected,
            "{what}: {ratio} vs {expected}"
        );
    }
}
