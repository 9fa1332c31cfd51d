//! The fuzzing harness (tests/fuzz), here so that the regression tests run it too.
use kernels::types::FrameParams;

use crate::bail;
use crate::error::Result;
use crate::integrator::Integrator;
use crate::options::{SceneOptions, UpAxis};

/// The fuzzing harness: bytes → a PLY file (when they begin with `ply`), a glTF file (`glTF`
/// or `{`: buffers and images embedded) or OBJ (and MTL
/// after the first 0xFF byte) → scene and BVH (either builder) → a 4×4 CPU render with NEE (or AO when there
/// are no emitters). Bad input must come back as an `Err`, never a panic, a hang or a
/// non-finite pixel.
pub fn load_and_render_bytes(data: &[u8]) -> Result<crate::output::Image> {
    // Inputs of odd length build the SBVH (what `auto` builds for scenes this small), the
    // others PLOC (`fast`; `auto`'s builder above 100k triangles).
    crate::accel::set_quality(if data.len() % 2 == 1 {
        crate::accel::BvhQuality::Auto
    } else {
        crate::accel::BvhQuality::Fast
    });
    let scene = if data.starts_with(b"ply") {
        crate::ply_scene::parse_ply_bytes("fuzz.ply", data.to_vec())?
    } else if data.starts_with(b"glTF") || data.starts_with(b"{") {
        crate::gltf_scene::parse_gltf_bytes("fuzz.gltf", data)?
    } else {
        let (obj, mtl) = match data.iter().position(|&b| b == 0xff) {
            Some(i) => (&data[..i], Some(&data[i + 1..])),
            None => (data, None),
        };
        let obj = String::from_utf8_lossy(obj);
        let mtl = mtl.map(String::from_utf8_lossy);
        crate::scene::parse_obj_text("fuzz.obj", &obj, mtl.as_deref())?
    };
    let args = SceneOptions {
        scene: None,
        width: 4,
        height: 4,
        eye: None,
        target: None,
        up: None,
        up_axis: UpAxis::Y,
        fov: None,
        bvh_quality: None,
        bvh_splits: None,
    };
    let camera = crate::camera::camera(&args, &scene)?;
    let mut params = FrameParams {
        camera,
        prev_camera: camera,
        width: 4,
        height: 4,
        samples: 1,
        max_depth: 3,
        rr_depth: 2,
        light_sampling: kernels::types::LIGHT_SAMPLING_POWER,
        ao_rays: 2,
        ao_distance: scene.extent().max(1e-6),
        ..Default::default()
    };
    let integrator = if scene.lights.is_empty() {
        // As `frame_params` does for AO: the walk order's pilot traces the scene too.
        params.ao_order = crate::ao_order::choose(crate::ao_order::AoOrder::Auto, &scene, &params);
        Integrator::Ao
    } else {
        Integrator::Nee
    };
    let mut cpu = crate::cpu::CpuBackend::new(&scene, 4, 4);
    let (image, _) = crate::render::render(&mut cpu, integrator, &params, 1, 1, false)?;
    if image.pixels.iter().any(|p| !p.is_finite()) {
        bail!("non-finite pixel");
    }
    Ok(image)
}
