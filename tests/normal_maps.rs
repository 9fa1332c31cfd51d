//! Tangent-space normal maps (MTL `norm`, `map_Bump` holding a normal map, glTF
//! `normalTexture`) bend the shading normal: a floor under a small sun is as bright as the
//! cosine between the bent normal and the sun says, in the frame the formats define (x
//! along increasing u, y along increasing v: up the image).
mod common;

use common::{render_cpu, tmp_dir as dir};
use glam::Vec3;

/// A 2x2 floor at y = 0 seen from above (image up = −z), lit only by a sun (`SUN`) up
/// towards +x and a little −z: direct light only, so a Lambertian floor's radiance is
/// ∝ max(0, n_s · sun).
const VIEW: [&str; 24] = [
    "--eye",
    "0,3,0",
    "--target",
    "0,0,0",
    "--up",
    "0,0,-1",
    "--fov",
    "30",
    "--width",
    "32",
    "--height",
    "32",
    "--spp",
    "16",
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
];

/// The direction towards the sun of `VIEW`.
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
    let (flat_image, stderr) = render_cpu(&scene, &d.join("flat.exr"), &VIEW);
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
        let (image, _) = render_cpu(&scene, &d.join("n.exr"), &VIEW);
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
        &VIEW,
    );
    assert!(!stderr.contains("height map"), "{stderr}");
    write_png(&d.join("flat.png"), FLAT);
    let (flat, _) = render_cpu(&obj_floor(&d, "norm flat.png"), &d.join("f.exr"), &VIEW);
    assert!(
        middle(&normal) > 1.2 * middle(&flat),
        "the map bent nothing"
    );

    // A grey height map is not read as normals: one warning, the floor stays flat.
    write_png(&d.join("h.png"), [90, 90, 90]);
    let (height, stderr) = render_cpu(&obj_floor(&d, "bump h.png"), &d.join("h.exr"), &VIEW);
    assert!(
        stderr.contains("'h.png'") && stderr.contains("height map"),
        "{stderr}"
    );
    let (m_h, m_f) = (middle(&height), middle(&flat));
    assert!((m_h - m_f).abs() < 0.01 * m_f, "{m_h} vs {m_f}");
}

#[test]
fn gltf_normal_textures_agree_with_obj() {
    // The same floor and map as glTF (v runs down the image there: v_gltf = 1 − v_obj) with
    // a normal scale of ½; against the OBJ floor whose map leans half as far in x and y.
    let d = dir("normal_maps_gltf");
    write_png(&d.join("n.png"), TOWARDS_V);
    let mut buffer: Vec<u8> = Vec::new();
    for (p, _) in CORNERS {
        buffer.extend(p.iter().flat_map(|x| x.to_le_bytes()));
    }
    for (_, uv) in CORNERS {
        buffer.extend([uv[0], 1.0 - uv[1]].iter().flat_map(|x| x.to_le_bytes()));
    }
    buffer.extend([0u32, 1, 2, 0, 2, 3].iter().flat_map(|x| x.to_le_bytes()));
    std::fs::write(d.join("floor.bin"), &buffer).unwrap();
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"extensionsUsed":["KHR_materials_specular"],"scene":0,"scenes":[{{"nodes":[0]}}],
"nodes":[{{"mesh":0}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1}},"indices":2,"material":0}}]}}],
"materials":[{{"pbrMetallicRoughness":{{"baseColorFactor":[0.5,0.5,0.5,1],"metallicFactor":0}},
"normalTexture":{{"index":0,"scale":0.5}},
"extensions":{{"KHR_materials_specular":{{"specularFactor":0}}}}}}],
"textures":[{{"source":0}}],"images":[{{"uri":"n.png"}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-1,0,-1],"max":[1,0,1]}},
{{"bufferView":1,"componentType":5126,"count":4,"type":"VEC2"}},{{"bufferView":2,"componentType":5125,"count":6,"type":"SCALAR"}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":32}},{{"buffer":0,"byteOffset":80,"byteLength":24}}],
"buffers":[{{"byteLength":{},"uri":"floor.bin"}}]}}"#,
        buffer.len()
    );
    std::fs::write(d.join("floor.gltf"), json).unwrap();
    let (gltf, stderr) = render_cpu(&d.join("floor.gltf"), &d.join("gltf.exr"), &VIEW);
    assert!(!stderr.contains("normal textures"), "{stderr}");
    let (obj, _) = render_cpu(
        &obj_floor(&d, "norm -bm 0.5 n.png"),
        &d.join("obj.exr"),
        &VIEW,
    );
    let (g, o) = (middle(&gltf), middle(&obj));
    assert!((g - o).abs() < 0.005 * o, "glTF {g} vs OBJ {o}");
    // And that is the analytic value: x and y of the texel halved.
    write_png(&d.join("flat.png"), FLAT);
    let (flat, _) = render_cpu(&obj_floor(&d, "norm flat.png"), &d.join("f.exr"), &VIEW);
    let m = Vec3::from(TOWARDS_V.map(|c| c as f32 / 255.0 * 2.0 - 1.0)) * Vec3::new(0.5, 0.5, 1.0);
    let sun = sun();
    let expected = Vec3::new(m.x, m.z, -m.y).normalize().dot(sun) / bent_normal(FLAT).dot(sun);
    let ratio = g / middle(&flat);
    assert!((ratio - expected).abs() < 0.01, "{ratio} vs {expected}");
}
