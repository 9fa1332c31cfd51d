//! Textures that change the material point by point: glTF's metallic-roughness texture
//! (roughness in green, metalness in blue, each times its factor), base colour textures on
//! metals, and emission textures (glTF `emissiveTexture`, MTL `map_Ke`) seen directly and
//! as light for next-event estimation, RIS and ReSTIR. Each is checked against the same
//! scene written without the texture, with the factors the texel stands for.
mod common;

use common::{floor_view, gltf_floor, render_cpu, strs, tmp_dir as dir, FLOOR};
use glam::Vec3;

/// The floor seen from above under a sun 45° up and a dim sky.
fn floor_lit() -> Vec<String> {
    floor_view(
        24,
        64,
        &[
            "--integrator",
            "mis",
            "--sky",
            "0.1,0.1,0.1",
            "--sun",
            "1,1,0",
            "--max-depth",
            "2",
            "--seed",
            "3",
        ],
    )
}

/// Mean radiance of the image.
fn mean(image: &runner::output::Image) -> Vec3 {
    image.mean()
}

fn png(d: &std::path::Path, name: &str, texel: [u8; 4]) {
    image::RgbaImage::from_pixel(2, 2, image::Rgba(texel))
        .save(d.join(name))
        .unwrap();
}

/// The mean radiance of a glTF floor with texture coordinates whose material is
/// `material` (JSON) and whose images are the PNG files `images`, seen from above.
fn textured_floor(d: &std::path::Path, material: &str, images: &[&str]) -> Vec3 {
    let uvs = common::floor_uvs();
    let scene = gltf_floor(d, FLOOR, &[("TEXCOORD_0", "VEC2", uvs)], material, images);
    let (image, stderr) = render_cpu(&scene, &d.join("floor.exr"), &strs(&floor_lit()));
    assert!(!stderr.contains("not supported"), "{stderr}");
    mean(&image)
}

fn close(got: Vec3, expected: Vec3, what: &str) {
    let scale = expected.max_element().max(1e-3);
    assert!(
        (got - expected).abs().max_element() < 0.01 * scale,
        "{what}: {got} vs {expected}"
    );
}

#[test]
fn metallic_roughness_textures_set_metalness_and_roughness_per_point() {
    let d = dir("textured_materials_mr");
    let base = r#""baseColorFactor":[0.9,0.6,0.3,1]"#;
    let with_texture = |texel: [u8; 4], metallic: f32, roughness: f32| {
        png(&d, "mr.png", texel);
        textured_floor(
            &d,
            &format!(
                r#"{{"pbrMetallicRoughness":{{{base},"metallicFactor":{metallic},"roughnessFactor":{roughness},"metallicRoughnessTexture":{{"index":0}}}}}}"#
            ),
            &["mr.png"],
        )
    };
    let plain = |metallic: f32, roughness: f32| {
        textured_floor(
            &d,
            &format!(
                r#"{{"pbrMetallicRoughness":{{{base},"metallicFactor":{metallic},"roughnessFactor":{roughness}}}}}"#
            ),
            &[],
        )
    };
    // Metal where blue × metallicFactor ≥ ½, at roughness green × roughnessFactor.
    let rough_metal = plain(1.0, 0.6);
    close(
        with_texture([0, 255, 255, 255], 1.0, 0.6),
        rough_metal,
        "rough metal",
    );
    close(
        with_texture([0, 128, 255, 255], 1.0, 1.0),
        plain(1.0, 128.0 / 255.0),
        "green is roughness",
    );
    // Not metal: blue 0, or blue 1 × a factor under ½.
    let dielectric = plain(0.0, 0.6);
    close(
        with_texture([0, 255, 0, 255], 1.0, 0.6),
        dielectric,
        "blue 0",
    );
    close(
        with_texture([0, 255, 255, 255], 0.4, 0.6),
        dielectric,
        "factor 0.4",
    );
    // The two are far apart, so the comparisons above can tell them.
    assert!((rough_metal - dielectric).abs().max_element() > 0.1 * dielectric.max_element());
}

#[test]
fn base_colour_textures_tint_metals() {
    let d = dir("textured_materials_metal_colour");
    png(&d, "red.png", [255, 0, 0, 255]);
    let textured = textured_floor(
        &d,
        r#"{"pbrMetallicRoughness":{"baseColorFactor":[0.8,0.8,0.8,1],"metallicFactor":1,"roughnessFactor":0.5,"baseColorTexture":{"index":0}}}"#,
        &["red.png"],
    );
    let red = textured_floor(
        &d,
        r#"{"pbrMetallicRoughness":{"baseColorFactor":[0.8,0,0,1],"metallicFactor":1,"roughnessFactor":0.5}}"#,
        &[],
    );
    close(textured, red, "red metal");
    assert!(red.x > 0.01 && red.x > 2.0 * red.y, "{red}");
}

/// A floor under a square emitter at y = 1 facing down, as OBJ; the emitter's material is
/// `light` (MTL lines).
fn lit_floor(d: &std::path::Path, light: &str) -> std::path::PathBuf {
    std::fs::write(
        d.join("s.obj"),
        "mtllib s.mtl\nv -1 0 -1\nv -1 0 1\nv 1 0 1\nv 1 0 -1\n\
         v -0.3 1 -0.3\nv 0.3 1 -0.3\nv 0.3 1 0.3\nv -0.3 1 0.3\n\
         vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
         usemtl floor\nf 1 2 3 4\nusemtl light\nf 5/1 6/2 7/3 8/4\n",
    )
    .unwrap();
    std::fs::write(
        d.join("s.mtl"),
        format!("newmtl floor\nKd 0.7 0.7 0.7\nnewmtl light\nKd 0 0 0\n{light}\n"),
    )
    .unwrap();
    d.join("s.obj")
}

#[test]
fn emission_textures_light_the_scene_like_their_value() {
    // Ke 4 × a texture of sRGB (128, 64, 255) against Ke 4 × that colour in linear values,
    // for every estimator: the light table's power, NEE's and RIS's light samples, ReSTIR's
    // shading of a seen emitter and of its reservoirs all read the texture.
    let d = dir("textured_materials_emission");
    png(&d, "glow.png", [128, 64, 255, 255]);
    let linear = Vec3::new(128.0, 64.0, 255.0).map(|c| kernels::texture::srgb_to_linear(c / 255.0));
    let ke = 4.0 * linear;
    let textured = lit_floor(&d, "Ke 4 4 4\nmap_Ke glow.png");
    let d2 = dir("textured_materials_emission_plain");
    let plain = lit_floor(&d2, &format!("Ke {} {} {}", ke.x, ke.y, ke.z));
    // From the floor's corner, looking up at the emitter's underside and the floor.
    for integrator in ["pt", "nee", "mis", "ris", "restir"] {
        let view = [
            "--eye",
            "1.8,0.15,1.8",
            "--target",
            "0,0.6,0",
            "--width",
            "32",
            "--height",
            "32",
            "--spp",
            "16",
            "--integrator",
            integrator,
            "--max-depth",
            "3",
            "--seed",
            "5",
        ];
        let (a, stderr) = render_cpu(&textured, &d.join(format!("{integrator}.exr")), &view);
        assert!(!stderr.contains("map_Ke"), "{stderr}");
        let (b, _) = render_cpu(&plain, &d2.join(format!("{integrator}.exr")), &view);
        // Same seeds, same light table: the same image up to rounding of the emission.
        let (ma, mb) = (mean(&a), mean(&b));
        assert!(mb.max_element() > 0.05, "{integrator}: lit");
        close(ma, mb, integrator);
        let brightest = |i: &runner::output::Image| {
            i.pixels
                .iter()
                .map(|p| p.max_element())
                .fold(0.0f32, f32::max)
        };
        // The emitter seen directly is Ke × texel.
        assert!(
            (brightest(&a) - ke.z).abs() < 0.01 * ke.z,
            "{integrator}: emitter seen {} vs {}",
            brightest(&a),
            ke.z
        );
    }
}

#[test]
fn mtl_statements_nothing_reads_are_named_once_each() {
    // Unknown statements are one warning per key with the number of materials; those that
    // state the format's defaults (3ds Max writes `Tr 0` and `Tf 1 1 1` everywhere) none.
    let d = dir("textured_materials_unknown_mtl");
    let scene = lit_floor(
        &d,
        "Tr 0\nTf 1 1 1\nmap_Pr r.png\nnewmtl other\nTf 0.5 0.5 0.5\nmap_Pr r.png",
    );
    let view = ["--width", "8", "--height", "8", "--spp", "1"];
    let (_, stderr) = render_cpu(&scene, &d.join("out.exr"), &view);
    assert!(
        stderr.contains("map_Pr in 2 material(s) is not supported yet"),
        "{stderr}"
    );
    assert!(stderr.contains("Tf in 1 material(s)"), "{stderr}");
    assert!(!stderr.contains("Tr in"), "{stderr}");
}

/// KHR_materials_pbrSpecularGlossiness renders as its metallic-roughness twin: black
/// specular is Lambertian diffuse, black diffuse with a bright specular a metal of that
/// colour (roughness 1 − glossiness), specular 0.04 diffuse under a coat of index 1.5.
#[test]
fn specular_glossiness_materials_match_their_metallic_roughness_twins() {
    let d = dir("textured_materials_specular_glossiness");
    let sg = |diffuse: &str, specular: &str, glossiness: f32| {
        textured_floor(
            &d,
            &format!(
                r#"{{"extensions":{{"KHR_materials_pbrSpecularGlossiness":{{"diffuseFactor":{diffuse},"specularFactor":{specular},"glossinessFactor":{glossiness}}}}}}}"#
            ),
            &[],
        )
    };
    let mr = |json: &str| textured_floor(&d, json, &[]);
    close(
        sg("[0.6,0.4,0.2,1]", "[0,0,0]", 0.5),
        mr(
            r#"{"pbrMetallicRoughness":{"baseColorFactor":[0.6,0.4,0.2,1],"metallicFactor":0},"extensions":{"KHR_materials_specular":{"specularFactor":0}}}"#,
        ),
        "diffuse",
    );
    close(
        sg("[0,0,0,1]", "[0.9,0.7,0.5]", 0.6),
        mr(
            r#"{"pbrMetallicRoughness":{"baseColorFactor":[0.9,0.7,0.5,1],"metallicFactor":1,"roughnessFactor":0.4}}"#,
        ),
        "metal",
    );
    close(
        sg("[0.6,0.4,0.2,1]", "[0.04,0.04,0.04]", 0.5),
        mr(
            r#"{"pbrMetallicRoughness":{"baseColorFactor":[0.6,0.4,0.2,1],"metallicFactor":0,"roughnessFactor":0.5}}"#,
        ),
        "plastic",
    );
}
