//! glTF 2.0 scenes: the same scene as OBJ + MTL and as glTF gives the same image; node
//! transforms, cameras and embedded textures are read.
mod common;

use common::{render_cpu as render, run_render_cpu, tmp_dir as dir};

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::Vec3;

/// One mesh of a test scene: its name, material index, positions and triangle indices.
type Object = (String, usize, Vec<[f32; 3]>, Vec<u32>);

fn base64(bytes: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                s.push(T[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// A glTF scene from objects (name, material, positions, triangle indices), one mesh and
/// node per object under a root node with `root_translation`, materials given as JSON.
fn write_gltf(
    path: &Path,
    objects: &[Object],
    materials: &[String],
    root_translation: [f32; 3],
    extra_nodes: &str,
) {
    let mut buffer: Vec<u8> = Vec::new();
    let (mut views, mut accessors, mut meshes, mut nodes) = (vec![], vec![], vec![], vec![]);
    for (i, (name, material, positions, indices)) in objects.iter().enumerate() {
        let lo = positions.iter().fold([f32::MAX; 3], |a, p| {
            [a[0].min(p[0]), a[1].min(p[1]), a[2].min(p[2])]
        });
        let hi = positions.iter().fold([f32::MIN; 3], |a, p| {
            [a[0].max(p[0]), a[1].max(p[1]), a[2].max(p[2])]
        });
        let start = buffer.len();
        buffer.extend(positions.iter().flatten().flat_map(|x| x.to_le_bytes()));
        views.push(format!(
            r#"{{"buffer":0,"byteOffset":{start},"byteLength":{}}}"#,
            buffer.len() - start
        ));
        accessors.push(format!(
            r#"{{"bufferView":{},"componentType":5126,"count":{},"type":"VEC3","min":{lo:?},"max":{hi:?}}}"#,
            views.len() - 1,
            positions.len()
        ));
        let start = buffer.len();
        buffer.extend(indices.iter().flat_map(|x| x.to_le_bytes()));
        views.push(format!(
            r#"{{"buffer":0,"byteOffset":{start},"byteLength":{}}}"#,
            buffer.len() - start
        ));
        accessors.push(format!(
            r#"{{"bufferView":{},"componentType":5125,"count":{},"type":"SCALAR"}}"#,
            views.len() - 1,
            indices.len()
        ));
        meshes.push(format!(
            r#"{{"name":"{name}","primitives":[{{"attributes":{{"POSITION":{}}},"indices":{},"material":{material}}}]}}"#,
            accessors.len() - 2,
            accessors.len() - 1
        ));
        nodes.push(format!(r#"{{"mesh":{i}}}"#));
    }
    let children: Vec<String> = (1..=objects.len()).map(|i| i.to_string()).collect();
    let root = format!(
        r#"{{"children":[{}],"translation":{root_translation:?}}}"#,
        children.join(",")
    );
    let mut all_nodes = vec![root];
    all_nodes.extend(nodes);
    let mut scene_nodes = vec!["0".to_string()];
    if !extra_nodes.is_empty() {
        all_nodes.push(extra_nodes.to_string());
        scene_nodes.push((all_nodes.len() - 1).to_string());
    }
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"extensionsUsed":["KHR_materials_specular","KHR_materials_emissive_strength"],
"scene":0,"scenes":[{{"nodes":[{}]}}],"nodes":[{}],"meshes":[{}],"materials":[{}],
"accessors":[{}],"bufferViews":[{}],
"buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{}"}}],
"cameras":[{{"type":"perspective","perspective":{{"yfov":0.6859,"znear":1}}}}]}}"#,
        scene_nodes.join(","),
        all_nodes.join(","),
        meshes.join(","),
        materials.join(","),
        accessors.join(","),
        views.join(","),
        buffer.len(),
        base64(&buffer)
    );
    std::fs::write(path, json).unwrap();
}

/// The Cornell box of assets/ as glTF objects: the OBJ's faces fan-triangulated as tobj
/// does, Lambertian materials (KHR_materials_specular 0) with the MTL's Kd and Ke.
fn cornell_gltf_objects() -> (Vec<Object>, Vec<String>) {
    let names = ["white", "red", "green", "light"];
    let kd = [
        [0.725, 0.71, 0.68],
        [0.63, 0.065, 0.05],
        [0.14, 0.45, 0.091],
        [0.78, 0.78, 0.78],
    ];
    let materials = names
        .iter()
        .zip(kd)
        .map(|(n, c)| {
            let emissive = if *n == "light" {
                r#","emissiveFactor":[1.0,0.7058824,0.23529412],"extensions":{"KHR_materials_specular":{"specularFactor":0},"KHR_materials_emissive_strength":{"emissiveStrength":17}}"#
            } else {
                r#","extensions":{"KHR_materials_specular":{"specularFactor":0}}"#
            };
            format!(
                r#"{{"name":"{n}","pbrMetallicRoughness":{{"baseColorFactor":[{},{},{},1],"metallicFactor":0,"roughnessFactor":1}}{emissive}}}"#,
                c[0], c[1], c[2]
            )
        })
        .collect();
    let mut objects = Vec::new();
    let mut v: Vec<[f32; 3]> = Vec::new();
    let (mut name, mut material) = (String::new(), 0);
    for line in runner::scene::CORNELL_BOX_OBJ.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.first() {
            Some(&"o") => name = w[1].to_string(),
            Some(&"usemtl") => material = names.iter().position(|n| *n == w[1]).unwrap(),
            Some(&"v") => v.push([
                w[1].parse().unwrap(),
                w[2].parse().unwrap(),
                w[3].parse().unwrap(),
            ]),
            Some(&"f") => {
                let corners: Vec<usize> = w[1..]
                    .iter()
                    .map(|c| c.parse::<usize>().unwrap() - 1)
                    .collect();
                let positions: Vec<[f32; 3]> = corners.iter().map(|&i| v[i]).collect();
                let mut indices = Vec::new();
                for k in 1..corners.len() as u32 - 1 {
                    indices.extend([0, k, k + 1]);
                }
                objects.push((name.clone(), material, positions, indices));
            }
            _ => {}
        }
    }
    (objects, materials)
}

#[test]
fn the_cornell_box_as_gltf_renders_as_the_obj_does() {
    let d = dir("gltf_cornell");
    let (objects, materials) = cornell_gltf_objects();
    // A camera node (yfov 0.6859 rad = 39.3°) at the OBJ camera's eye, looking down +z:
    // a 180° turn about y (glTF cameras look down their -z).
    let camera = r#"{"camera":0,"translation":[278,273,-800],"rotation":[0,1,0,0]}"#;
    write_gltf(
        &d.join("cornell.gltf"),
        &objects,
        &materials,
        [0.0; 3],
        camera,
    );
    let scene = runner::scene::load(&runner::options::SceneOptions {
        scene: Some(d.join("cornell.gltf")),
        width: 1,
        height: 1,
        eye: None,
        target: None,
        up: None,
        up_axis: runner::options::UpAxis::Y,
        fov: None,
        bvh_quality: None,
        bvh_splits: None,
    })
    .unwrap();
    let cam = scene.camera.expect("the glTF camera is the default view");
    assert!(
        (cam.eye.as_vec3() - Vec3::new(278.0, 273.0, -800.0)).length() < 1e-3,
        "{cam:?}"
    );
    assert!(
        ((cam.target - cam.eye).as_vec3().normalize() - Vec3::Z).length() < 1e-5,
        "{cam:?}"
    );
    assert!((cam.fov - 39.3).abs() < 0.01, "{cam:?}");
    assert!(scene.all_diffuse(), "specularFactor 0: Lambertian");
    // Same camera flags for both: the geometry, materials and light must match exactly.
    let flags = [
        "--eye",
        "278,273,-800",
        "--target",
        "278,273,0",
        "--fov",
        "39.3",
        "--width",
        "48",
        "--height",
        "48",
        "--spp",
        "8",
        "--integrator",
        "mis",
    ];
    let (from_obj, _) = render(
        &runner::scene::default_scene_path(),
        &d.join("obj.exr"),
        &flags,
    );
    let (from_gltf, stderr) = render(&d.join("cornell.gltf"), &d.join("gltf.exr"), &flags);
    assert!(!stderr.contains("warning"), "{stderr}");
    // Identical triangles in the same order; only the light's Ke = factor × strength may
    // round differently in its last bit.
    let close = from_obj
        .pixels
        .iter()
        .zip(&from_gltf.pixels)
        .filter(|(a, b)| (**a - **b).abs().max_element() <= 1e-5 * a.max_element().max(1.0))
        .count();
    assert_eq!(close, from_obj.pixels.len(), "OBJ and glTF images differ");
}

#[test]
fn node_transforms_place_the_meshes() {
    let d = dir("gltf_transform");
    let (objects, materials) = cornell_gltf_objects();
    write_gltf(
        &d.join("moved.gltf"),
        &objects,
        &materials,
        [1000.0, -50.0, 0.0],
        "",
    );
    let opts = |p: PathBuf| runner::options::SceneOptions {
        scene: Some(p),
        width: 1,
        height: 1,
        eye: None,
        target: None,
        up: None,
        up_axis: runner::options::UpAxis::Y,
        fov: None,
        bvh_quality: None,
        bvh_splits: None,
    };
    let moved = runner::scene::load(&opts(d.join("moved.gltf"))).unwrap();
    let original = runner::scene::cornell_box().unwrap();
    let (lo, hi) = moved.bounds();
    let (olo, ohi) = original.bounds();
    assert!(
        (lo - olo - Vec3::new(1000.0, -50.0, 0.0)).length() < 1e-2,
        "{lo} vs {olo}"
    );
    assert!(
        (hi - ohi - Vec3::new(1000.0, -50.0, 0.0)).length() < 1e-2,
        "{hi} vs {ohi}"
    );
    assert!(
        moved.camera.is_none(),
        "no camera node: the default view frames the bounds"
    );
}

#[test]
fn a_broken_gltf_is_one_error_line() {
    // Cut short; and one whose POSITION names an accessor it does not define (gltf-json
    // 1.4 panicked validating it: found by the fuzzer).
    let missing_accessor = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/fuzz/regressions/gltf_missing_accessor.gltf");
    for text in [
        "{\"asset\": {\"version\": \"2.0\"}, \"meshes\": [".to_string(),
        std::fs::read_to_string(missing_accessor).unwrap(),
    ] {
        a_broken_gltf_is_refused(&text);
    }
}

/// An accessor that reaches past its buffer view is refused by name: the reader cannot read
/// it, and reading on without it drew other triangles (indices read as absent: the
/// vertices taken three at a time) or none ("no triangles"), as if the file said so. And
/// an attribute of the application's own loads (it was refused as invalid).
#[test]
fn an_accessor_past_its_buffer_view_is_one_error_line_naming_it() {
    let d = dir("gltf_accessor_bounds");
    let quad: Object = (
        "quad".into(),
        0,
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ],
        vec![0, 1, 2, 0, 2, 3],
    );
    let material = r#"{"pbrMetallicRoughness":{"baseColorFactor":[1,1,1,1]}}"#.to_string();
    let good = d.join("good.gltf");
    write_gltf(&good, &[quad], &[material], [0.0; 3], "");
    let json = std::fs::read_to_string(&good).unwrap();
    let positions = r#""componentType":5126,"count":4,"type":"VEC3""#;
    let indices = r#""componentType":5125,"count":6,"type":"SCALAR""#;
    assert!(json.contains(positions) && json.contains(indices));
    let small = ["--width", "8", "--height", "8", "--spp", "1"];
    let render = |path: &Path| run_render_cpu(path, &d.join("x.png"), &small);
    let o = render(&good);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // An application-specific attribute (a leading underscore: glTF 2.0, 3.7.2.1; bevy's
    // barycentric.gltf has `__BARYCENTRIC`) is valid, and ignored.
    let custom = d.join("custom.gltf");
    let attributes = r#""attributes":{"POSITION":0}"#;
    assert!(json.contains(attributes));
    let with_custom = r#""attributes":{"POSITION":0,"_BATCHID":0}"#;
    std::fs::write(&custom, json.replace(attributes, with_custom)).unwrap();
    let o = render(&custom);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for (what, from, to) in [
        (
            "indices accessor 1",
            indices,
            r#""componentType":5125,"count":9,"type":"SCALAR""#,
        ),
        (
            "POSITION accessor 0",
            positions,
            r#""byteOffset":40,"componentType":5126,"count":4,"type":"VEC3""#,
        ),
        (
            "POSITION accessor 0 holds VEC2 values",
            positions,
            r#""componentType":5126,"count":4,"type":"VEC2""#,
        ),
        (
            "POSITION accessor 0 holds 32-bit integers",
            positions,
            r#""componentType":5125,"count":4,"type":"VEC3""#,
        ),
    ] {
        let broken = d.join("broken.gltf");
        std::fs::write(&broken, json.replace(from, to)).unwrap();
        let o = render(&broken);
        let stderr = String::from_utf8_lossy(&o.stderr);
        let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
        assert_eq!(o.status.code(), Some(1), "{stderr}");
        assert!(
            errors.len() == 1
                && errors[0].contains(what)
                && errors[0].contains("mesh 0 primitive 0"),
            "{stderr}"
        );
    }
}

/// One triangle with normals, texture coordinates and tangents, under a node that scales by
/// ¼, its vertex attributes as `f32` or as the integers of `KHR_mesh_quantization`
/// (positions i16 as whole numbers, normals i8, texture coordinates u8 and tangents i16
/// normalized; strides padded to 4 bytes as glTF asks), with the same values either way.
fn quantized_triangle(quantized: bool) -> String {
    let mut buffer: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    // Each attribute: its values, its glTF type and, quantized, its component type, the
    // scale it is stored at (an f32 value v as the integer v × scale) and its stride.
    struct Stored {
        values: Vec<Vec<i32>>,
        kind: &'static str,
        quantized: (u32, i32, usize),
    }
    let attributes = [
        Stored {
            values: vec![vec![0, 0, 0], vec![4, 0, 0], vec![0, -2, 4]],
            kind: "VEC3",
            quantized: (5122, 1, 8),
        },
        Stored {
            values: vec![vec![0, 1, 0], vec![1, 0, 0], vec![0, 0, -1]],
            kind: "VEC3",
            quantized: (5120, 127, 4),
        },
        Stored {
            values: vec![vec![0, 0], vec![1, 0], vec![0, 1]],
            kind: "VEC2",
            quantized: (5121, 255, 4),
        },
        Stored {
            values: vec![vec![1, 0, 0, 1], vec![0, 0, 1, -1], vec![0, 1, 0, 1]],
            kind: "VEC4",
            quantized: (5122, 32767, 8),
        },
    ];
    for Stored {
        values,
        kind,
        quantized: (component, scale, stride),
    } in attributes
    {
        let start = buffer.len();
        for v in &values {
            let item_start = buffer.len();
            for &x in v {
                match (quantized, component) {
                    (false, _) => buffer.extend((x as f32).to_le_bytes()),
                    (true, 5120 | 5121) => buffer.push((x * scale) as u8),
                    (true, _) => buffer.extend(((x * scale) as i16).to_le_bytes()),
                }
            }
            let stride = if quantized { stride } else { 4 * v.len() };
            buffer.resize(item_start + stride, 0);
        }
        let (component, normalized, stride) = if quantized {
            (component, scale != 1, stride)
        } else {
            (5126, false, 4 * values[0].len())
        };
        views.push(format!(
            r#"{{"buffer":0,"byteOffset":{start},"byteLength":{},"byteStride":{stride}}}"#,
            buffer.len() - start
        ));
        // POSITION (the first) must state its bounds.
        let bounds = if views.len() == 1 {
            r#","min":[0,-2,0],"max":[4,0,4]"#
        } else {
            ""
        };
        accessors.push(format!(
            r#"{{"bufferView":{},"componentType":{component},"normalized":{normalized},"count":3,"type":"{kind}"{bounds}}}"#,
            views.len() - 1
        ));
    }
    let extensions = if quantized {
        r#""extensionsUsed":["KHR_mesh_quantization"],"extensionsRequired":["KHR_mesh_quantization"],"#
    } else {
        ""
    };
    format!(
        r#"{{"asset":{{"version":"2.0"}},{extensions}"scene":0,"scenes":[{{"nodes":[0]}}],
"nodes":[{{"mesh":0,"scale":[0.25,0.25,0.25]}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"NORMAL":1,"TEXCOORD_0":2,"TANGENT":3}}}}]}}],
"accessors":[{}],"bufferViews":[{}],
"buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{}"}}]}}"#,
        accessors.join(","),
        views.join(","),
        buffer.len(),
        base64(&buffer)
    )
}

/// `KHR_mesh_quantization` (gltfpack's output, and a required extension there) loads as its
/// float twin: the integers dequantized (normalized ones to [−1, 1] or [0, 1]) and scaled by
/// the node. gltf read every POSITION, NORMAL and TANGENT as f32 and refused the extension.
#[test]
fn quantized_attributes_load_as_their_float_twins() {
    let load = |quantized| {
        let text = quantized_triangle(quantized);
        runner::gltf_scene::parse_gltf_bytes("triangle.gltf", text.as_bytes())
            .unwrap_or_else(|e| panic!("{e}"))
    };
    let (float, quantized) = (load(false), load(true));
    let corners = |s: &runner::scene::Scene| {
        let t = s.triangles[0];
        [t.p0, t.p1, t.p2]
    };
    assert_eq!(float.triangles.len(), 1);
    assert_eq!(
        corners(&float),
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -0.5, 1.0]]
    );
    assert_eq!(corners(&quantized), corners(&float));
    let shading = |s: &runner::scene::Scene| s.attributes.shading[0];
    let all = kernels::types::SHADING_NORMALS
        | kernels::types::SHADING_UVS
        | kernels::types::SHADING_TANGENTS;
    assert_eq!(shading(&float).flags & all, all);
    assert_eq!(
        bytemuck::bytes_of(&shading(&quantized)),
        bytemuck::bytes_of(&shading(&float))
    );
    assert!(quantized.warnings.is_empty(), "{:?}", quantized.warnings);
}

/// The quad that `meshopt_quad` stores: corners, normals (two of them below z = 0, where
/// the octahedral encoding folds), texture coordinates and two triangles.
const QUAD_POSITIONS: [[f32; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [1.0, 0.0, 1.0],
    [0.0, 0.0, 1.0],
];
const QUAD_NORMALS: [[f32; 3]; 4] = [
    [0.0, 1.0, 0.0],
    [0.6, 0.8, 0.0],
    [0.0, 0.6, -0.8],
    [-0.48, 0.6, -0.64],
];
const QUAD_UVS: [[f32; 2]; 4] = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
const QUAD_INDICES: [u32; 6] = [0, 2, 1, 0, 3, 2];

/// A unit vector in the extension's 8-bit octahedral encoding (x, y, then 1.0 = 127).
fn octahedral_bytes(n: [f32; 3]) -> [u8; 4] {
    let l1 = n[0].abs() + n[1].abs() + n[2].abs();
    let (x, y) = (n[0] / l1, n[1] / l1);
    let (x, y) = if n[2] >= 0.0 {
        (x, y)
    } else {
        ((1.0 - y.abs()) * x.signum(), (1.0 - x.abs()) * y.signum())
    };
    let [x, y, one] = [x, y, 1.0].map(|c| (c * 127.0).round() as i8 as u8);
    [x, y, one, 0]
}

/// Indices in the extension's mode 2 bitstream ("INDICES"): header, each index as a
/// LEB128 delta from the previous one (baseline 0, zigzag in bits 1.., sign in bit 1), tail.
fn index_sequence_bytes(indices: &[u32]) -> Vec<u8> {
    let mut out = vec![0xd1];
    let mut last = 0i64;
    for &i in indices {
        let delta = i as i64 - last;
        last = i as i64;
        let mut v = if delta >= 0 {
            (delta as u64) << 2
        } else {
            ((!delta) as u64) << 2 | 2
        };
        loop {
            let byte = (v & 0x7f) as u8;
            v >>= 7;
            if v == 0 {
                out.push(byte);
                break;
            }
            out.push(byte | 0x80);
        }
    }
    out.extend([0; 4]);
    out
}

/// The quad as a glTF, plain (`mode` None: f32 positions and normals, u16 indices) or with
/// every view compressed by EXT_meshopt_compression (gltfpack's `-c`): positions through
/// the exponential filter, normals as octahedral bytes, indices in `mode` ("TRIANGLES" or
/// "INDICES"), decoding into a placeholder buffer that has no data (marked `fallback`, or
/// with `fallback` false, only dataless). `placeholder_length` overrides its length.
fn meshopt_quad(mode: Option<&str>, fallback: bool, placeholder_length: Option<u64>) -> String {
    let f32s = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let flat = |rows: &[[f32; 3]]| rows.iter().flatten().copied().collect::<Vec<f32>>();
    let positions = f32s(&flat(&QUAD_POSITIONS));
    let normals = match mode {
        None => f32s(&flat(&QUAD_NORMALS)),
        Some(_) => QUAD_NORMALS
            .iter()
            .flat_map(|&n| octahedral_bytes(n))
            .collect(),
    };
    let uvs = f32s(&QUAD_UVS.concat());
    let indices: Vec<u8> = QUAD_INDICES
        .iter()
        .flat_map(|&i| (i as u16).to_le_bytes())
        .collect();
    // (bytes, stride, count, filter) per view: positions, normals, uvs, indices.
    let views = [
        (positions, 12, 4, "EXPONENTIAL"),
        (
            normals,
            if mode.is_some() { 4 } else { 12 },
            4,
            "OCTAHEDRAL",
        ),
        (uvs, 8, 4, "NONE"),
        (indices, 2, 6, "NONE"),
    ];
    let (mut plain, mut packed, mut json_views) = (Vec::new(), Vec::new(), Vec::new());
    for (k, (bytes, stride, count, filter)) in views.iter().enumerate() {
        let offset = plain.len();
        plain.extend(bytes);
        plain.resize(plain.len().next_multiple_of(4), 0);
        let stride_json = if k < 3 {
            format!(r#","byteStride":{stride}"#)
        } else {
            String::new()
        };
        let ext = match mode {
            None => String::new(),
            Some(mode) => {
                let (data, mode, filter) = if k == 3 {
                    let data = match mode {
                        "TRIANGLES" => meshopt::encode_index_buffer(&QUAD_INDICES, 4).unwrap(),
                        _ => index_sequence_bytes(&QUAD_INDICES),
                    };
                    (data, mode, "NONE")
                } else {
                    let mut bytes = bytes.clone();
                    if *filter == "EXPONENTIAL" {
                        // Each position component v as 2^-3 · (8 v).
                        bytes = flat(&QUAD_POSITIONS)
                            .iter()
                            .flat_map(|v| {
                                ((-3i32 << 24) | ((v * 8.0) as i32 & 0xff_ffff)).to_le_bytes()
                            })
                            .collect();
                    }
                    let elements: Vec<[u8; 4]> =
                        bytes.chunks(4).map(|c| c.try_into().unwrap()).collect();
                    let data = match stride {
                        4 => meshopt::encode_vertex_buffer(&elements).unwrap(),
                        8 => meshopt::encode_vertex_buffer(
                            &elements.chunks(2).map(|c| [c[0], c[1]]).collect::<Vec<_>>(),
                        )
                        .unwrap(),
                        _ => meshopt::encode_vertex_buffer(
                            &elements
                                .chunks(3)
                                .map(|c| [c[0], c[1], c[2]])
                                .collect::<Vec<_>>(),
                        )
                        .unwrap(),
                    };
                    (data, "ATTRIBUTES", *filter)
                };
                let at = packed.len();
                packed.extend(&data);
                packed.resize(packed.len().next_multiple_of(4), 0);
                format!(
                    r#","extensions":{{"EXT_meshopt_compression":{{"buffer":1,"byteOffset":{at},"byteLength":{},"byteStride":{stride},"count":{count},"mode":"{mode}","filter":"{filter}"}}}}"#,
                    data.len()
                )
            }
        };
        json_views.push(format!(
            r#"{{"buffer":0,"byteOffset":{offset},"byteLength":{}{stride_json}{ext}}}"#,
            bytes.len()
        ));
    }
    let data_uri = |b: &[u8]| format!("data:application/octet-stream;base64,{}", base64(b));
    let (normal_type, extensions, buffers) = match mode {
        None => (
            "5126,\"normalized\":false",
            "",
            format!(
                r#"{{"byteLength":{},"uri":"{}"}}"#,
                plain.len(),
                data_uri(&plain)
            ),
        ),
        Some(_) => {
            let marked = if fallback {
                r#","extensions":{"EXT_meshopt_compression":{"fallback":true}}"#
            } else {
                ""
            };
            let length = placeholder_length.unwrap_or(plain.len() as u64);
            (
                "5120,\"normalized\":true",
                r#""extensionsUsed":["EXT_meshopt_compression","KHR_mesh_quantization"],"extensionsRequired":["EXT_meshopt_compression","KHR_mesh_quantization"],"#,
                format!(
                    r#"{{"byteLength":{length}{marked}}},{{"byteLength":{},"uri":"{}"}}"#,
                    packed.len(),
                    data_uri(&packed)
                ),
            )
        }
    };
    format!(
        r#"{{"asset":{{"version":"2.0"}},{extensions}"scene":0,"scenes":[{{"nodes":[0]}}],
"nodes":[{{"mesh":0}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"NORMAL":1,"TEXCOORD_0":2}},"indices":3}}]}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[0,0,0],"max":[1,0,1]}},
{{"bufferView":1,"componentType":{normal_type},"count":4,"type":"VEC3"}},
{{"bufferView":2,"componentType":5126,"count":4,"type":"VEC2"}},
{{"bufferView":3,"componentType":5123,"count":6,"type":"SCALAR"}}],
"bufferViews":[{}],"buffers":[{buffers}]}}"#,
        json_views.join(",")
    )
}

/// EXT_meshopt_compression (gltfpack's `-c`, a required extension there; before, gltf
/// refused such files): each view decoded (vertex codec with the exponential and
/// octahedral filters; triangle and index-sequence codecs) loads as the plain file does.
#[test]
fn meshopt_compressed_views_load_as_their_plain_twin() {
    let load = |text: String| {
        runner::gltf_scene::parse_gltf_bytes("quad.gltf", text.as_bytes())
            .unwrap_or_else(|e| panic!("{e}"))
    };
    let plain = load(meshopt_quad(None, false, None));
    assert_eq!(plain.triangles.len(), 2);
    for (mode, fallback) in [("TRIANGLES", true), ("INDICES", false)] {
        let packed = load(meshopt_quad(Some(mode), fallback, None));
        assert!(packed.warnings.is_empty(), "{mode}: {:?}", packed.warnings);
        assert_eq!(packed.triangles.len(), 2, "{mode}");
        for (a, b) in corners(&packed).iter().zip(&corners(&plain)) {
            for ((pa, na, ua), (pb, nb, ub)) in a.iter().zip(b) {
                assert_eq!((pa, ua), (pb, ub), "{mode}");
                // Octahedral bytes: within a few 127ths of each component.
                let off = (Vec3::from(*na) - Vec3::from(*nb)).abs().max_element();
                assert!(off < 0.03, "{mode}: normal {na:?} against {nb:?}");
            }
        }
    }
}

/// A corner of a loaded triangle: position, normal, texture coordinates.
type Corner = ([f32; 3], [f32; 3], [f32; 2]);

/// The triangles of `scene` as their corners, each from its least position (the triangle
/// codec may rotate a triangle's corners, keeping its winding), in order of their positions.
fn corners(scene: &runner::scene::Scene) -> Vec<Vec<Corner>> {
    let mut all: Vec<Vec<Corner>> = scene
        .triangles
        .iter()
        .map(|t| {
            let a = scene.attributes.shading[t.shading_index() as usize];
            let p = [t.p0, t.p1, t.p2];
            let mut c: Vec<Corner> = (0..3)
                .map(|k| {
                    let n = [a.normals[3 * k], a.normals[3 * k + 1], a.normals[3 * k + 2]];
                    (p[k], n, [a.uvs[2 * k], a.uvs[2 * k + 1]])
                })
                .collect();
            let least = (0..3)
                .min_by(|&i, &j| c[i].0.partial_cmp(&c[j].0).unwrap())
                .unwrap();
            c.rotate_left(least);
            c
        })
        .collect();
    let positions = |c: &[Corner]| c.iter().map(|c| c.0).collect::<Vec<_>>();
    all.sort_by(|a, b| positions(a).partial_cmp(&positions(b)).unwrap());
    all
}

/// What a compressed view or its placeholder gets wrong is one error naming it.
#[test]
fn broken_meshopt_compression_is_one_error_naming_the_view() {
    let error =
        |text: String| match runner::gltf_scene::parse_gltf_bytes("quad.gltf", text.as_bytes()) {
            Ok(_) => panic!("loaded"),
            Err(e) => e.to_string(),
        };
    let text = meshopt_quad(Some("TRIANGLES"), true, None);
    // A filter, a mode or a count the view's layout does not allow.
    let e = error(text.replacen(
        r#""mode":"ATTRIBUTES","filter":"EXPONENTIAL""#,
        r#""mode":"ATTRIBUTES","filter":"QUATERNION""#,
        1,
    ));
    assert!(
        e.contains("its buffer view 0") && e.contains("byte stride of 12"),
        "{e}"
    );
    let e = error(text.replacen(r#""mode":"TRIANGLES""#, r#""mode":"TRIANGLE""#, 1));
    assert!(
        e.contains("its buffer view 3") && e.contains("mode 'TRIANGLE'"),
        "{e}"
    );
    let e = error(text.replacen(
        r#""count":4,"mode":"ATTRIBUTES","filter":"NONE""#,
        r#""count":5,"mode":"ATTRIBUTES","filter":"NONE""#,
        1,
    ));
    assert!(
        e.contains("its buffer view 2") && e.contains("5 elements of 8 bytes"),
        "{e}"
    );
    let e = error(text.replacen(
        r#""buffer":1,"byteOffset":0,"#,
        r#""buffer":1,"byteOffset":100000,"#,
        1,
    ));
    assert!(e.contains("lie outside buffer 1"), "{e}");
    // A stream whose bytes are not the codec's (the positions' first three, header
    // included, zeroed: the compressed buffer's first four base64 digits).
    let at = text.rfind("base64,").unwrap() + "base64,".len();
    let e = error(format!("{}AAAA{}", &text[..at], &text[at + 4..]));
    assert!(
        e.contains("its buffer view 0") && e.contains("cannot be decoded"),
        "{e}"
    );
    // A placeholder of a petabyte: refused before anything that size is made.
    let e = error(meshopt_quad(Some("TRIANGLES"), true, Some(1 << 50)));
    assert!(
        e.contains("its buffer 0") && e.contains("GB of memory"),
        "{e}"
    );
}

/// A two-joint skin: a quad whose top corners hang on joint B, one fully and one half (the
/// other half on joint A, at the origin). In the file's pose joint B sits where it was bound
/// (0, 1, 0) but turned 90° about z; the mesh's own node is moved 100 along x, which the
/// specification says a skinned mesh ignores. `joint` is the top left corner's joint.
fn skinned_quad(joint: u8) -> String {
    let mut buffer: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut put = |bytes: Vec<u8>| {
        views.push(format!(
            r#"{{"buffer":0,"byteOffset":{},"byteLength":{}}}"#,
            buffer.len(),
            bytes.len()
        ));
        buffer.extend(bytes);
    };
    let f32s = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    put(f32s(&[
        0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 2.0, 0.0, 1.0, 2.0, 0.0,
    ]));
    put(f32s(&[0.0, 0.0, 1.0].repeat(4)));
    put(vec![0, 0, 0, 0, 0, 0, 0, 0, joint, 0, 0, 0, 0, 1, 0, 0]);
    put(f32s(&[
        1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.5, 0.5, 0.0, 0.0,
    ]));
    put([0u16, 1, 2, 1, 3, 2]
        .iter()
        .flat_map(|i| i.to_le_bytes())
        .collect());
    // Inverse bind matrices (column-major): A's the identity, B's a move by (0, −1, 0).
    let identity = [
        1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    ];
    let mut down = identity;
    down[13] = -1.0;
    put(f32s(&[identity, down].concat()));
    let half = std::f32::consts::FRAC_1_SQRT_2;
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],
"nodes":[{{"children":[1,2]}},{{"mesh":0,"skin":0,"translation":[100,0,0]}},{{"children":[3]}},
{{"translation":[0,1,0],"rotation":[0,0,{half},{half}]}}],
"skins":[{{"joints":[2,3],"inverseBindMatrices":5}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"NORMAL":1,"JOINTS_0":2,"WEIGHTS_0":3}},"indices":4}}]}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[0,0,0],"max":[1,2,0]}},
{{"bufferView":1,"componentType":5126,"count":4,"type":"VEC3"}},
{{"bufferView":2,"componentType":5121,"count":4,"type":"VEC4"}},
{{"bufferView":3,"componentType":5126,"count":4,"type":"VEC4"}},
{{"bufferView":4,"componentType":5123,"count":6,"type":"SCALAR"}},
{{"bufferView":5,"componentType":5126,"count":2,"type":"MAT4"}}],
"bufferViews":[{}],
"buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{}"}}]}}"#,
        views.join(","),
        buffer.len(),
        base64(&buffer)
    )
}

/// Skinned meshes are placed by their joints in the file's pose (each vertex by its
/// joints' world transform × inverse bind matrix, by weight), not by their node: before,
/// the quad was drawn as bound and 100 units off.
#[test]
fn skinned_meshes_take_the_pose_of_their_joints() {
    let scene = runner::gltf_scene::parse_gltf_bytes("skin.gltf", skinned_quad(1).as_bytes())
        .unwrap_or_else(|e| panic!("{e}"));
    let corners: Vec<[f32; 3]> = scene
        .triangles
        .iter()
        .flat_map(|t| [t.p0, t.p1, t.p2])
        .collect();
    // Bottom corners stay on joint A; top left (0, 2) turns about B to (−1, 1); top right
    // (1, 2) is half on A (itself) and half on B (−1, 2): (0, 2).
    let expected = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [-1.0, 1.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 2.0, 0.0],
        [-1.0, 1.0, 0.0],
    ];
    assert_eq!(corners.len(), expected.len());
    for (c, e) in corners.iter().zip(expected) {
        assert!(
            (Vec3::from(*c) - Vec3::from(e)).length() < 1e-5,
            "{corners:?}"
        );
    }
    // Normals turn with the joints (a turn about z keeps +z).
    for shading in &scene.attributes.shading {
        for n in shading.normals.chunks(3) {
            assert!((Vec3::from_slice(n) - Vec3::Z).length() < 1e-5, "{n:?}");
        }
    }
    // A joint the skin does not have is one error naming the primitive.
    match runner::gltf_scene::parse_gltf_bytes("skin.gltf", skinned_quad(7).as_bytes()) {
        Ok(_) => panic!("loaded"),
        Err(e) => assert!(
            e.to_string()
                .contains("mesh 0 primitive 0: JOINTS_0 names joint 7 of a skin with 2"),
            "{e}"
        ),
    }
}

/// A .gltf whose buffer file is not beside it is one error naming that file (the importer
/// says only "No such file or directory").
#[test]
fn a_missing_buffer_file_is_named() {
    let d = dir("gltf_missing_bin");
    let path = one_triangle_gltf(&d);
    let json = std::fs::read_to_string(&path).unwrap();
    std::fs::write(&path, with_uri(&json, "data:", "scene%20data.bin")).unwrap();
    let o = run_render_cpu(&path, &d.join("x.png"), &[]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.lines().count() == 1 && stderr.contains("its buffer 0 'scene%20data.bin'"),
        "{stderr}"
    );
}

#[test]
fn a_buffer_shorter_than_its_length_is_named() {
    let d = dir("gltf_short_buffer");
    let path = one_triangle_gltf(&d);
    let json = std::fs::read_to_string(&path).unwrap();
    // The buffer says it holds a kilobyte more than its data URI does.
    let key = r#""buffers":[{"byteLength":"#;
    let start = json.find(key).unwrap() + key.len();
    let end = start + json[start..].find(',').unwrap();
    let length: usize = json[start..end].parse().unwrap();
    let json = format!("{}{}{}", &json[..start], length + 1024, &json[end..]);
    std::fs::write(&path, json).unwrap();
    let o = run_render_cpu(&path, &d.join("x.png"), &[]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.lines().count() == 1
            && stderr.contains("its buffer 0 holds 48 bytes, fewer than the 1072"),
        "{stderr}"
    );
}

/// `scene.gltf` in `d`: one white triangle, its buffer a data URI.
fn one_triangle_gltf(d: &Path) -> PathBuf {
    let triangle: Object = (
        "triangle".into(),
        0,
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]],
        vec![0, 1, 2],
    );
    let material = r#"{"pbrMetallicRoughness":{"baseColorFactor":[1,1,1,1]}}"#.to_string();
    let path = d.join("scene.gltf");
    write_gltf(&path, &[triangle], &[material], [0.0; 3], "");
    path
}

/// `json` with the first URI that starts with `prefix` replaced by `uri`.
fn with_uri(json: &str, prefix: &str, uri: &str) -> String {
    let start = json.find(&format!(r#""uri":"{prefix}"#)).unwrap() + r#""uri":""#.len();
    let end = start + json[start..].find('"').unwrap();
    format!("{}{uri}{}", &json[..start], &json[end..])
}

fn a_broken_gltf_is_refused(text: &str) {
    let d = dir("gltf_broken");
    std::fs::write(d.join("broken.gltf"), text).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_runner"))
        .args([
            "render",
            "--backend",
            "cpu",
            "--scene",
            d.join("broken.gltf").to_str().unwrap(),
            "--out",
            d.join("x.png").to_str().unwrap(),
        ])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        stderr.starts_with("error: cannot load scene") && stderr.lines().count() == 1,
        "{stderr}"
    );
    assert!(!d.join("x.png").exists());
}

/// The view of `write_textured_floor`: from above, the floor filling the middle of a
/// 64x64 image, under a white sky.
const FLOOR_VIEW: [&str; 20] = [
    "--eye",
    "0,3,0",
    "--target",
    "0,0,0",
    "--up",
    "0,0,-1",
    "--fov",
    "30",
    "--width",
    "64",
    "--height",
    "64",
    "--spp",
    "4",
    "--integrator",
    "nee",
    "--sky",
    "1,1,1",
    "--max-depth",
    "2",
];

/// A 2x2 Lambertian floor at y = 0 textured with a 2x2 RGBA image (rows from the top),
/// texture coordinates in glTF's convention (v down the image; -z is the image's top).
/// `material_extra` is appended to the material's JSON (e.g. an alpha mode).
fn write_textured_floor(path: &Path, texels: &[[u8; 4]; 4], material_extra: &str) {
    let mut png = Vec::new();
    image::RgbaImage::from_raw(2, 2, texels.concat())
        .unwrap()
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let positions: [[f32; 3]; 4] = [
        [-1.0, 0.0, -1.0],
        [-1.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
        [1.0, 0.0, -1.0],
    ];
    // -z is the top of the image: v = 0 there in glTF.
    let uvs: [[f32; 2]; 4] = [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]];
    let indices: [u32; 6] = [0, 1, 2, 0, 2, 3];
    let mut buffer: Vec<u8> = positions
        .iter()
        .flatten()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    buffer.extend(uvs.iter().flatten().flat_map(|x| x.to_le_bytes()));
    buffer.extend(indices.iter().flat_map(|x| x.to_le_bytes()));
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"extensionsUsed":["KHR_materials_specular"],"scene":0,"scenes":[{{"nodes":[0]}}],
"nodes":[{{"mesh":0}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1}},"indices":2,"material":0}}]}}],
"materials":[{{"pbrMetallicRoughness":{{"baseColorTexture":{{"index":0}},"metallicFactor":0}},"extensions":{{"KHR_materials_specular":{{"specularFactor":0}}}}{material_extra}}}],
"textures":[{{"source":0}}],
"images":[{{"uri":"data:image/png;base64,{}"}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-1,0,-1],"max":[1,0,1]}},
{{"bufferView":1,"componentType":5126,"count":4,"type":"VEC2"}},{{"bufferView":2,"componentType":5125,"count":6,"type":"SCALAR"}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":32}},{{"buffer":0,"byteOffset":80,"byteLength":24}}],
"buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{}"}}]}}"#,
        base64(&png),
        buffer.len(),
        base64(&buffer)
    );
    std::fs::write(path, json).unwrap();
}

#[test]
fn base_colour_textures_are_read_with_gltf_texture_coordinates() {
    // A 2x2 floor seen from above (as in tests/surfaces.rs), texture coordinates in glTF's
    // convention (v down the image): the image must appear upright, red at the top left.
    let d = dir("gltf_texture");
    let texels: [[u8; 4]; 4] = [
        [255, 0, 0, 255],
        [0, 255, 0, 255],
        [0, 0, 255, 255],
        [255, 255, 255, 255],
    ];
    write_textured_floor(&d.join("floor.gltf"), &texels, "");
    let (image, stderr) = render(&d.join("floor.gltf"), &d.join("floor.exr"), &FLOOR_VIEW);
    assert!(!stderr.contains("warning: '"), "{stderr}");
    let at = |fx: f32, fy: f32| image.pixels[((fy * 64.0) as usize) * 64 + (fx * 64.0) as usize];
    let (lo, hi) = (0.5 - 0.311, 0.5 + 0.311);
    for (pixel, expected, what) in [
        (at(lo, lo), Vec3::new(1.0, 0.0, 0.0), "top left: red"),
        (at(hi, lo), Vec3::new(0.0, 1.0, 0.0), "top right: green"),
        (at(lo, hi), Vec3::new(0.0, 0.0, 1.0), "bottom left: blue"),
        (at(hi, hi), Vec3::ONE, "bottom right: white"),
    ] {
        assert!(
            (pixel - expected).abs().max_element() < 0.05,
            "{what}: {pixel}"
        );
    }
}

/// A texture whose image file is not there is left out with one warning naming the file,
/// as an OBJ's missing `map_Kd` is (the whole scene was refused): the floor then has its
/// base colour factor, white, everywhere.
#[test]
fn a_missing_texture_image_is_a_warning_and_the_factor_stays() {
    let d = dir("gltf_missing_image");
    let texels: [[u8; 4]; 4] = [[255, 0, 0, 255]; 4];
    write_textured_floor(&d.join("floor.gltf"), &texels, "");
    let json = std::fs::read_to_string(d.join("floor.gltf")).unwrap();
    let external = with_uri(&json, "data:image/png", "not_here.png");
    std::fs::write(d.join("floor.gltf"), external).unwrap();
    let (image, stderr) = render(&d.join("floor.gltf"), &d.join("floor.exr"), &FLOOR_VIEW);
    // One line about the image, a warning (the other is that the sky alone lights it).
    let about_image: Vec<&str> = stderr
        .lines()
        .filter(|l| l.contains("not_here.png"))
        .collect();
    assert!(
        about_image.len() == 1
            && about_image[0].starts_with("warning:")
            && about_image[0].contains("image 0 ('not_here.png') not loaded"),
        "{stderr}"
    );
    let at = |fx: f32, fy: f32| image.pixels[((fy * 64.0) as usize) * 64 + (fx * 64.0) as usize];
    for (fx, fy) in [(0.3, 0.3), (0.7, 0.3), (0.3, 0.7), (0.7, 0.7)] {
        let pixel = at(fx, fy);
        assert!((pixel - Vec3::ONE).abs().max_element() < 0.05, "{pixel}");
    }
}

#[test]
fn alpha_mask_materials_are_cut_out() {
    // alphaMode MASK with alphaCutoff 0.3: the top left texel's alpha 0 is a hole (the white
    // sky shows through), the top right's 100/255 = 0.39 stays solid (green).
    let d = dir("gltf_mask");
    let texels: [[u8; 4]; 4] = [
        [255, 0, 0, 0],
        [0, 255, 0, 100],
        [0, 0, 255, 255],
        [255, 255, 255, 255],
    ];
    let mask = r#","alphaMode":"MASK","alphaCutoff":0.3"#;
    write_textured_floor(&d.join("floor.gltf"), &texels, mask);
    let (image, stderr) = render(&d.join("floor.gltf"), &d.join("floor.exr"), &FLOOR_VIEW);
    assert!(!stderr.contains("alpha mode"), "{stderr}");
    let at = |fx: f32, fy: f32| image.pixels[((fy * 64.0) as usize) * 64 + (fx * 64.0) as usize];
    let (lo, hi) = (0.5 - 0.311, 0.5 + 0.311);
    for (pixel, expected, what) in [
        (at(lo, lo), Vec3::ONE, "top left: a hole onto the sky"),
        (at(hi, lo), Vec3::new(0.0, 1.0, 0.0), "top right: green"),
        (at(lo, hi), Vec3::new(0.0, 0.0, 1.0), "bottom left: blue"),
    ] {
        assert!(
            (pixel - expected).abs().max_element() < 0.05,
            "{what}: {pixel}"
        );
    }
}

/// `common::gltf_floor` of a default material whose file also names `extensions` (the
/// inside of a JSON list) as used, and as required too when `required`. Returns its path.
fn floor_naming_extensions(d: &Path, extensions: &str, required: bool) -> PathBuf {
    let path = common::gltf_floor(d, common::FLOOR, &[], r#"{"pbrMetallicRoughness":{}}"#, &[]);
    let mut named = format!(r#""extensionsUsed":["KHR_materials_specular",{extensions}]"#);
    if required {
        named += &format!(r#","extensionsRequired":[{extensions}]"#);
    }
    let json = std::fs::read_to_string(&path)
        .unwrap()
        .replace(r#""extensionsUsed":["KHR_materials_specular"]"#, &named);
    std::fs::write(&path, json).unwrap();
    path
}

#[test]
fn extensions_the_loader_does_not_read_are_named() {
    // A file that uses clearcoat and sheen (not read) besides specular and volume (read):
    // one warning for each unread extension, none for the others.
    let d = dir("gltf_unread_extensions");
    let path = floor_naming_extensions(
        &d,
        r#""KHR_materials_volume","KHR_materials_clearcoat","KHR_materials_sheen""#,
        false,
    );
    let (_, stderr) = render(
        &path,
        &d.join("out.png"),
        &["--width", "8", "--height", "8", "--spp", "1"],
    );
    for unread in ["KHR_materials_clearcoat", "KHR_materials_sheen"] {
        assert!(
            stderr.contains(&format!("extension {unread} is not supported yet")),
            "{stderr}"
        );
    }
    assert!(
        !stderr.contains("KHR_materials_specular is not"),
        "{stderr}"
    );
    assert!(!stderr.contains("KHR_materials_volume is not"), "{stderr}");
}

/// A glTF floor (u left to right, v top to bottom in the image, as glTF's texture space;
/// the view spans both from 0.1 to 0.9) textured with an `n`×`n` image of four solid
/// quadrants (red, green / blue, white) under a white sky, with `transform` as the base
/// colour texture's KHR_texture_transform and `sampler` (JSON) as its sampler: the
/// rendered 32×32 image.
fn quadrants_floor(d: &Path, n: u32, transform: &str, sampler: &str) -> runner::output::Image {
    let quadrants = image::RgbaImage::from_fn(n, n, |x, y| {
        image::Rgba(match (x < n / 2, y < n / 2) {
            (true, true) => [255, 0, 0, 255],
            (false, true) => [0, 255, 0, 255],
            (true, false) => [0, 0, 255, 255],
            (false, false) => [255, 255, 255, 255],
        })
    });
    quadrants.save(d.join("quadrants.png")).unwrap();
    let material = format!(
        r#"{{"pbrMetallicRoughness":{{"baseColorTexture":{{"index":0{transform}}},"metallicFactor":0}},"extensions":{{"KHR_materials_specular":{{"specularFactor":0}}}}}}"#
    );
    let scene = common::gltf_floor(
        d,
        common::FLOOR,
        &[("TEXCOORD_0", "VEC2", common::floor_uvs())],
        &material,
        &["quadrants.png"],
    );
    let json = std::fs::read_to_string(&scene).unwrap();
    let textures = r#""textures":[{"source":0}]"#;
    assert!(json.contains(textures));
    let with_sampler =
        format!(r#""textures":[{{"source":0,"sampler":0}}],"samplers":[{{{sampler}}}]"#);
    std::fs::write(&scene, json.replace(textures, &with_sampler)).unwrap();
    let args = common::floor_view(32, 4, &["--integrator", "mis", "--sky", "1,1,1"]);
    let (image, stderr) = render(&scene, &d.join("floor.exr"), &common::strs(&args));
    assert!(!stderr.contains("not supported"), "{stderr}");
    image
}

/// The dominant colour of each quadrant of `quadrants_floor`'s 16×16 texture, read at the
/// image's quarters (u, v ≈ ¼, ¾), row by row, as 'r', 'g', 'b' or 'w'.
fn transformed_quadrants(d: &Path, transform: &str) -> Vec<char> {
    sampled_quadrants(d, transform, "")
}

/// `transformed_quadrants` through `sampler`.
fn sampled_quadrants(d: &Path, transform: &str, sampler: &str) -> Vec<char> {
    let image = quadrants_floor(d, 16, transform, sampler);
    // The view spans u and v from 0.1 to 0.9: pixels 6 and 25 of 32 are at ≈ ¼ and ¾.
    let at = |x: u32, y: u32| image.pixels[(y * image.width + x) as usize];
    let (lo, hi) = (6, 25);
    [(lo, lo), (hi, lo), (lo, hi), (hi, hi)]
        .iter()
        .map(|&(x, y)| {
            let c = at(x, y);
            let c = c / c.max_element();
            match (c.x > 0.5, c.y > 0.5, c.z > 0.5) {
                (true, false, false) => 'r',
                (false, true, false) => 'g',
                (false, false, true) => 'b',
                (true, true, true) => 'w',
                _ => panic!("mixed colour {c} at ({x}, {y})"),
            }
        })
        .collect()
}

/// glTF samplers: wrapS and wrapT (REPEAT, CLAMP_TO_EDGE, MIRRORED_REPEAT) per axis, and
/// magFilter NEAREST (pixel art, voxel models), where every texture used to repeat and
/// blend. Scaled by 2.5, the quarters read the texture at 0.66 and 1.84: repeating 0.84,
/// clamped 1, mirrored 0.16.
#[test]
fn samplers_wrap_and_filter_as_the_file_says() {
    let d = dir("gltf_samplers");
    let scaled = r#","extensions":{"KHR_texture_transform":{"scale":[2.5,2.5]}}"#;
    let (repeat, clamp, mirror) = (10497, 33071, 33648);
    let wraps = |s: u32, t: u32| format!(r#""wrapS":{s},"wrapT":{t}"#);
    assert_eq!(
        sampled_quadrants(&d, scaled, &wraps(repeat, repeat)),
        ['w', 'w', 'w', 'w']
    );
    assert_eq!(
        sampled_quadrants(&d, scaled, &wraps(mirror, clamp)),
        ['w', 'b', 'w', 'b']
    );
    assert_eq!(
        sampled_quadrants(&d, scaled, &wraps(clamp, mirror)),
        ['w', 'w', 'g', 'g']
    );
    // A 2×2 texture over 32 pixels: bilinear blends red into green over the half of the
    // row between the texels' centres; nearest has one pixel of mixed colour, where the
    // border between the texels crosses it (antialiasing).
    let mixed_in_row = |sampler: &str| {
        let image = quadrants_floor(&d, 2, "", sampler);
        (0..image.width)
            .map(|x| image.pixels[(6 * image.width + x) as usize])
            .filter(|c| {
                let c = *c / c.max_element();
                c.x > 0.05 && c.y > 0.05
            })
            .count()
    };
    let (linear, nearest) = (mixed_in_row(""), mixed_in_row(r#""magFilter":9728"#));
    assert!(linear >= 12, "{linear} pixels blend");
    assert!(nearest <= 1, "{nearest} pixels blend");
}

/// KHR_texture_transform moves, turns and scales the texture as the Khronos sample
/// viewer shows it: offset in texture units, rotation turning u towards −v (a quarter
/// turn maps (u, v) to (v, −u)), scale before both.
#[test]
fn texture_transforms_offset_rotate_and_scale_the_texture() {
    let d = dir("gltf_texture_transform");
    let ext = |t: &str| format!(r#","extensions":{{"KHR_texture_transform":{{{t}}}}}"#);
    assert_eq!(transformed_quadrants(&d, ""), ['r', 'g', 'b', 'w']);
    // Half a texture to the right: the left of the floor shows the right of the texture.
    assert_eq!(
        transformed_quadrants(&d, &ext(r#""offset":[0.5,0]"#)),
        ['g', 'r', 'w', 'b']
    );
    // A quarter turn: (u, v) → (v, −u) (repeating), so the top left (¼, ¼) reads the
    // texture at (¼, ¾) and the top right (¾, ¼) at (¼, ¼). The opposite turn would give
    // g w r b.
    assert_eq!(
        transformed_quadrants(&d, &ext(r#""rotation":1.5707964"#)),
        ['b', 'r', 'w', 'g']
    );
    // Scale first: u halved keeps every quadrant on the texture's left half.
    assert_eq!(
        transformed_quadrants(&d, &ext(r#""scale":[0.5,1]"#)),
        ['r', 'r', 'b', 'b']
    );
    // All three, in the order scale, rotation, offset: (u, v) → (v + ½, −u/2).
    assert_eq!(
        transformed_quadrants(
            &d,
            &ext(r#""scale":[0.5,1],"rotation":1.5707964,"offset":[0.5,0]"#)
        ),
        ['w', 'w', 'b', 'b']
    );
}

/// A glTF floor of Lambertian albedo ½ (the quad of `common::gltf_floor`, 2 × 2 at y = 0)
/// with one more node carrying KHR_lights_punctual light `light` (JSON) placed by `node`
/// (JSON members such as `"translation":[..]`), rendered from above with `mis`, direct
/// light only, no sky. Returns the image and the render's stderr.
fn lit_floor(d: &Path, light: &str, node: &str) -> (runner::output::Image, String) {
    let material = r#"{"pbrMetallicRoughness":{"baseColorFactor":[0.5,0.5,0.5,1],"metallicFactor":0},"extensions":{"KHR_materials_specular":{"specularFactor":0}}}"#;
    let scene = common::gltf_floor(d, common::FLOOR, &[], material, &[]);
    let json = std::fs::read_to_string(&scene).unwrap();
    let json = json
        .replace(
            r#""extensionsUsed":["KHR_materials_specular"]"#,
            &format!(
                r#""extensionsUsed":["KHR_materials_specular","KHR_lights_punctual"],"extensions":{{"KHR_lights_punctual":{{"lights":[{light}]}}}}"#
            ),
        )
        .replace(r#""scenes":[{"nodes":[0]}]"#, r#""scenes":[{"nodes":[0,1]}]"#)
        .replace(
            r#""nodes":[{"mesh":0}]"#,
            &format!(r#""nodes":[{{"mesh":0}},{{{node},"extensions":{{"KHR_lights_punctual":{{"light":0}}}}}}]"#),
        );
    std::fs::write(&scene, json).unwrap();
    let args = common::floor_view(
        32,
        256,
        &["--integrator", "mis", "--max-depth", "2", "--seed", "5"],
    );
    render(&scene, &d.join("lit.exr"), &common::strs(&args))
}

/// A directional light is the scene's sun: straight down on the floor, 2 W/m² (1366 lux
/// over 683 lm/W) give albedo × E / π everywhere; and `--sun` would override it.
#[test]
fn a_directional_light_is_the_suns_irradiance() {
    let d = dir("gltf_directional_light");
    // The node turns the light's −z to −y (a quarter turn about x).
    let (image, stderr) = lit_floor(
        &d,
        r#"{"type":"directional","intensity":1366,"color":[1,1,1]}"#,
        r#""rotation":[-0.70710678,0,0,0.70710678]"#,
    );
    assert!(!stderr.contains("not supported"), "{stderr}");
    let expected = 0.5 * 2.0 / std::f32::consts::PI;
    let mean = image.mean();
    assert!(
        (mean - Vec3::splat(expected)).abs().max_element() < 0.01 * expected,
        "{mean} vs {expected}"
    );
}

/// A point light of 683 cd (1 W/sr) one unit above the floor gives E = I h / (h² + ρ²)^{3/2}
/// at distance ρ from the point below it: its stand-in sphere emits the same light.
#[test]
fn a_point_light_lights_like_a_point() {
    let d = dir("gltf_point_light");
    let light_at = Vec3::new(0.5, 1.0, 0.5);
    let (image, stderr) = lit_floor(
        &d,
        r#"{"type":"point","intensity":683,"color":[1,1,1]}"#,
        &format!(
            r#""translation":[{},{},{}]"#,
            light_at.x, light_at.y, light_at.z
        ),
    );
    assert!(!stderr.contains("not supported"), "{stderr}");
    // The view spans ±tan 15° × 3 around the origin; pixel (x, y) looks at the floor point
    // (x, 0, z) of its centre (x right, z down the image).
    let half = 3.0 * 15f32.to_radians().tan();
    let floor_at = |p: u32| -half + 2.0 * half * (p as f32 + 0.5) / image.width as f32;
    let (mut got, mut expected) = (0.0, 0.0);
    for py in 24..28 {
        for px in 24..28 {
            got += image.pixels[(py * image.width + px) as usize].x;
            let rho2 = (floor_at(px) - light_at.x).powi(2) + (floor_at(py) - light_at.z).powi(2);
            let e = light_at.y / (light_at.y * light_at.y + rho2).powf(1.5);
            expected += 0.5 * e / std::f32::consts::PI;
        }
    }
    assert!(
        (got - expected).abs() < 0.03 * expected,
        "{got} vs {expected}"
    );
}

/// A spot light is drawn as a disc facing along the spot, with one warning that its cone
/// is not kept; straight below it the floor gets its axis intensity.
#[test]
fn a_spot_light_is_a_disc_with_a_warning() {
    let d = dir("gltf_spot_light");
    let (image, stderr) = lit_floor(
        &d,
        r#"{"type":"spot","intensity":683,"spot":{"outerConeAngle":0.5}}"#,
        r#""translation":[0,1,0],"rotation":[-0.70710678,0,0,0.70710678]"#,
    );
    assert_eq!(
        stderr.matches("spot light(s) drawn as small discs").count(),
        1,
        "{stderr}"
    );
    // The floor straight below (the image's centre) gets E = I / h².
    let c = image.width / 2;
    let mut got = 0.0;
    for (x, y) in [(c - 1, c - 1), (c, c - 1), (c - 1, c), (c, c)] {
        got += 0.25 * image.pixels[(y * image.width + x) as usize].x;
    }
    let expected = 0.5 / std::f32::consts::PI;
    assert!(
        (got - expected).abs() < 0.05 * expected,
        "{got} vs {expected}"
    );
}

/// alphaMode BLEND is coverage: a black cover of alpha ¼ over a lit floor, with the sun
/// straight above, lets through ¾ of the sunlight and ¾ of the camera's rays, so the floor
/// looks (¾)² as bright as without it; alpha 1 hides it, alpha 0 is not there.
#[test]
fn blended_surfaces_let_through_what_they_do_not_cover() {
    let d = dir("gltf_blend");
    let quad = |y: f32, half: f32| {
        vec![
            [-half, y, -half],
            [-half, y, half],
            [half, y, half],
            [half, y, -half],
        ]
    };
    let indices = vec![0, 1, 2, 0, 2, 3];
    let mean_under = |alpha: f32| {
        let path = d.join(format!("blend_{alpha}.gltf"));
        write_gltf(
            &path,
            &[
                ("floor".into(), 0, quad(0.0, 1.0), indices.clone()),
                ("cover".into(), 1, quad(0.5, 1.5), indices.clone()),
            ],
            &[
                r#"{"pbrMetallicRoughness":{"baseColorFactor":[0.5,0.5,0.5,1],"metallicFactor":0},"extensions":{"KHR_materials_specular":{"specularFactor":0}}}"#.to_string(),
                format!(r#"{{"pbrMetallicRoughness":{{"baseColorFactor":[0,0,0,{alpha}],"metallicFactor":0}},"alphaMode":"BLEND","extensions":{{"KHR_materials_specular":{{"specularFactor":0}}}}}}"#),
            ],
            [0.0; 3],
            "",
        );
        let args = common::floor_view(
            32,
            64,
            &[
                "--integrator",
                "mis",
                "--max-depth",
                "2",
                "--sun",
                "0,1,0",
                "--seed",
                "3",
            ],
        );
        let (image, stderr) = render(&path, &d.join("blend.exr"), &common::strs(&args));
        assert!(!stderr.contains("not supported"), "{stderr}");
        image.mean().x
    };
    let open = mean_under(0.0);
    assert!(open > 0.0);
    let quarter = mean_under(0.25) / open;
    assert!((quarter - 0.5625).abs() < 0.02, "{quarter} vs 0.5625");
    assert!(mean_under(1.0) < 1e-3 * open);
}

/// A file that *requires* an extension we cannot read (mesh compression: its geometry is
/// not in the plain accessors) is refused with one `error:` naming the extension, no
/// image; one that only *uses* it loads, with one warning.
#[test]
fn required_extensions_we_cannot_read_are_refused_by_name() {
    let d = dir("gltf_required_extension");
    let draco = r#""KHR_draco_mesh_compression""#;
    let path = floor_naming_extensions(&d, draco, true);
    let out = d.join("refused.png");
    let _ = std::fs::remove_file(&out); // left by an earlier run in a kept target dir
    let tiny = ["--width", "8", "--height", "8", "--spp", "1"];
    let run = common::run_render_cpu(&path, &out, &tiny);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success(), "{stderr}");
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert!(
        errors.len() == 1 && errors[0].contains("KHR_draco_mesh_compression"),
        "{stderr}"
    );
    assert!(!out.exists());
    // Only used (not required): the file loads, with one warning naming it.
    let path = floor_naming_extensions(&d, draco, false);
    let loaded = d.join("loaded.png");
    let (_, stderr) = render(
        &path,
        &loaded,
        &["--width", "8", "--height", "8", "--spp", "1"],
    );
    assert_eq!(
        stderr.matches("KHR_draco_mesh_compression").count(),
        1,
        "{stderr}"
    );
}
