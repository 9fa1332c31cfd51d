//! Path tracing, NEE and MIS: an analytic furnace, and agreement with each other.
mod common;

use glam::Vec3;
use kernels::camera::look_at;
use kernels::types::{
    FrameParams, Material, Triangle, LIGHT_SAMPLING_POWER, LIGHT_SAMPLING_UNIFORM,
};
use runner::cpu::CpuBackend;
use runner::integrator::Integrator;
use runner::output::Image;
use runner::render::render;
use runner::scene::Scene;

fn params(scene: &Scene, w: u32, h: u32, seed: u32, light_sampling: u32) -> FrameParams {
    let c = scene.camera.expect("scene camera");
    FrameParams {
        camera: look_at(
            c.eye.as_vec3(),
            c.target.as_vec3(),
            c.up,
            c.fov,
            w as f32 / h as f32,
        ),
        width: w,
        height: h,
        seed,
        max_depth: 64,
        rr_depth: 3,
        light_sampling,
        ..Default::default()
    }
}

fn render_cpu(scene: &Scene, integrator: Integrator, p: &FrameParams, spp: u32) -> Image {
    let mut cpu = CpuBackend::new(scene, p.width, p.height);
    render(&mut cpu, integrator, p, spp, spp, false).unwrap().0
}

/// Mean and standard error of the mean over pixels (each pixel is an independent estimate).
fn pixel_stats(img: &Image) -> (f64, f64) {
    let v: Vec<f64> = img.pixels.iter().map(|p| p.x as f64).collect();
    common::mean_and_standard_error(&v)
}

/// A closed sphere whose inside emits Le and reflects with albedo ρ: radiance everywhere
/// inside is Le + ρ L, so L = Le / (1 − ρ) exactly, for any closed shape.
fn furnace(albedo: f32, le: f32) -> Scene {
    let tris: Vec<Triangle> = common::icosphere(Vec3::ZERO, 3.0, 2, 0)
        .into_iter()
        .map(|t| {
            let (a, b, c) = t.vertices();
            Triangle::new(a, c, b, 0) // flip: the front (emitting) side faces inwards
        })
        .collect();
    let mut scene = Scene::new(
        tris,
        vec![Material::new(Vec3::splat(albedo), Vec3::splat(le))],
    )
    .unwrap();
    scene.camera = Some(runner::scene::CameraHint {
        eye: glam::DVec3::new(0.3, -0.2, 0.1),
        target: glam::DVec3::new(1.0, 0.5, -2.0),
        up: Vec3::Y,
        fov: 90.0,
    });
    scene
}

#[test]
fn furnace_gives_le_over_one_minus_albedo() {
    for (albedo, le) in [(0.5f32, 1.0f32), (0.8, 0.25)] {
        let scene = furnace(albedo, le);
        let want = le as f64 / (1.0 - albedo as f64);
        for integrator in [Integrator::Pt, Integrator::Nee, Integrator::Mis] {
            for ls in [LIGHT_SAMPLING_POWER, LIGHT_SAMPLING_UNIFORM] {
                let p = params(&scene, 24, 24, 3, ls);
                let img = render_cpu(&scene, integrator, &p, 16);
                let (mean, se) = pixel_stats(&img);
                assert!(
                    (mean - want).abs() < 4.0 * se + 1e-4,
                    "{integrator:?} ρ={albedo}: {mean} ± {se}, expected {want}"
                );
            }
        }
    }
}

/// Image mean of several independent renders (different seeds): mean and standard error.
fn seeded_means(scene: &Scene, integrator: Integrator, seeds: u32, spp: u32) -> (f64, f64) {
    let means: Vec<f64> = (0..seeds)
        .map(|s| {
            let img = render_cpu(
                scene,
                integrator,
                &params(scene, 24, 24, 100 + s, LIGHT_SAMPLING_POWER),
                spp,
            );
            assert!(
                img.pixels.iter().all(|p| p.is_finite()),
                "{integrator:?}: non-finite pixel"
            );
            img.mean().dot(Vec3::splat(1.0 / 3.0)) as f64
        })
        .collect();
    common::mean_and_standard_error(&means)
}

fn integrators_agree(scene: &Scene, seeds: u32, spp: u32) {
    let results: Vec<(Integrator, (f64, f64))> = [Integrator::Pt, Integrator::Nee, Integrator::Mis]
        .into_iter()
        .map(|i| (i, seeded_means(scene, i, seeds, spp)))
        .collect();
    for (a, (ma, sa)) in &results {
        for (b, (mb, sb)) in &results {
            let se = (sa * sa + sb * sb).sqrt();
            assert!(
                (ma - mb).abs() < 4.5 * se,
                "{a:?} {ma}±{sa} vs {b:?} {mb}±{sb}"
            );
        }
        assert!(*ma > 0.0, "{a:?}: black image");
    }
}

#[test]
fn pt_nee_mis_agree_on_the_cornell_box() {
    let scene = runner::scene::load_obj(&runner::scene::default_scene_path()).unwrap();
    integrators_agree(&scene, 8, 8);
}

#[test]
fn pt_nee_mis_agree_on_the_many_lights_scene() {
    let scene = runner::generate::many_lights().into_scene().unwrap();
    assert!(
        scene.lights.len() >= 200,
        "128 quads = 256 emissive triangles"
    );
    integrators_agree(&scene, 8, 16);
}

#[test]
fn the_all_lambertian_kernels_render_what_the_general_ones_do() {
    // The specialised variant is the general kernel with the BSDF known at compile time:
    // on a Lambertian scene both must give the very same numbers.
    let scene = runner::scene::load_obj(&runner::scene::default_scene_path()).unwrap();
    assert!(scene.all_diffuse());
    let p = FrameParams {
        samples: 2,
        ..params(&scene, 24, 24, 5, LIGHT_SAMPLING_POWER)
    };
    let buffers = scene.kernel();
    for integrator in [
        Integrator::Pt,
        Integrator::Nee,
        Integrator::Mis,
        Integrator::Ris,
    ] {
        let [general, diffuse] = integrator.kernels();
        let (
            runner::integrator::Kernel::Image {
                pixel: g,
                entry_point: ge,
            },
            runner::integrator::Kernel::Image {
                pixel: d,
                entry_point: de,
            },
        ) = (general, diffuse)
        else {
            panic!("{integrator:?} is an image kernel");
        };
        assert_ne!(ge, de, "{integrator:?}: two entry points");
        for y in 0..24 {
            for x in 0..24 {
                let (a, b) = (g(&buffers, &p, x, y), d(&buffers, &p, x, y));
                assert_eq!(
                    (a.sum, a.rays),
                    (b.sum, b.rays),
                    "{integrator:?} at ({x}, {y})"
                );
            }
        }
    }
}
