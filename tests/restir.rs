//! Weighted reservoirs, RIS and ReSTIR DI: selection statistics, unbiasedness against NEE,
//! and temporal reprojection that does not smear reservoirs across disocclusions.
mod common;

use common::{chi_square, chi_square_critical};
use glam::Vec3;
use kernels::camera::look_at;
use kernels::integrators::restir;
use kernels::reservoir::Reservoir;
use kernels::rng::Rng;
use kernels::types::{
    FrameParams, Material, INVALID, LIGHT_SAMPLING_POWER, RESTIR_HISTORY_VALID,
    RESTIR_SPLIT_PASSES, RESTIR_TEMPORAL, RESTIR_UNBIASED, RESTIR_VISIBILITY_REUSE,
};
use runner::cpu::CpuBackend;
use runner::integrator::Integrator;
use runner::render::render;
use runner::scene::Scene;

fn weights(n: usize, seed: u32) -> Vec<f32> {
    let mut rng = Rng::from_seed(seed);
    (0..n)
        .map(|_| 0.05 + rng.next_f32().powi(2) * 3.0)
        .collect()
}

fn chi2_against_weights(counts: &[u64], w: &[f32], trials: u64) {
    let total: f64 = w.iter().map(|&x| x as f64).sum();
    let expected: Vec<f64> = w
        .iter()
        .map(|&x| trials as f64 * x as f64 / total)
        .collect();
    let chi2 = chi_square(counts, &expected);
    let crit = chi_square_critical(w.len() - 1);
    assert!(chi2 < crit, "χ² = {chi2:.1} ≥ {crit:.1}");
}

#[test]
fn wrs_selects_each_candidate_in_proportion_to_its_weight() {
    let w = weights(20, 1);
    let trials = 400_000u64;
    let mut counts = vec![0u64; w.len()];
    let mut rng = Rng::from_seed(2);
    for _ in 0..trials {
        let mut r = Reservoir::empty();
        for (i, &wi) in w.iter().enumerate() {
            r.update(i as u32, 0.0, 0.0, wi, 1.0, rng.next_f32());
        }
        assert_eq!(r.m, w.len() as f32);
        counts[r.triangle as usize] += 1;
    }
    chi2_against_weights(&counts, &w, trials);
}

#[test]
fn merging_two_reservoirs_selects_like_one_over_the_union() {
    // Candidates i have weight w_i = p̂_i / p_i with p = 1: p̂_i = w_i, so W = w_sum / (M p̂).
    let w = weights(24, 3);
    let (a, b) = w.split_at(9);
    let trials = 400_000u64;
    let mut counts = vec![0u64; w.len()];
    let mut rng = Rng::from_seed(4);
    for _ in 0..trials {
        let mut build = |set: &[f32], offset: usize| {
            let mut r = Reservoir::empty();
            for (i, &wi) in set.iter().enumerate() {
                r.update((offset + i) as u32, 0.0, 0.0, wi, wi, rng.next_f32());
            }
            r.finalize(r.m);
            r
        };
        let (ra, rb) = (build(a, 0), build(b, a.len()));
        let mut merged = Reservoir::empty();
        // At the same pixel, p̂ of each reservoir's sample is its own target_pdf, and
        // the MIS weights of two reservoirs with one target are their shares of M.
        let m = ra.m + rb.m;
        merged.resample(&ra, ra.target_pdf, ra.m / m, rng.next_f32());
        merged.resample(&rb, rb.target_pdf, rb.m / m, rng.next_f32());
        assert_eq!(merged.m, w.len() as f32);
        let total: f32 = w.iter().sum();
        assert!((merged.w_sum * m - total).abs() < 1e-4 * total);
        counts[merged.triangle as usize] += 1;
    }
    chi2_against_weights(&counts, &w, trials);
}

fn params(scene: &Scene, w: u32, h: u32, seed: u32, max_depth: u32, flags: u32) -> FrameParams {
    let c = scene.camera.expect("scene camera");
    let (eye, target) = (c.eye.as_vec3(), c.target.as_vec3());
    let cam = look_at(eye, target, c.up, c.fov, w as f32 / h as f32);
    FrameParams {
        camera: cam,
        prev_camera: cam,
        width: w,
        height: h,
        seed,
        max_depth,
        rr_depth: 3,
        light_sampling: LIGHT_SAMPLING_POWER,
        candidates: 8,
        restir_flags: flags,
        temporal_cap: 20.0,
        spatial_neighbours: runner::options::DEFAULT_SPATIAL_NEIGHBOURS,
        disocclusion_neighbours: runner::options::DEFAULT_DISOCCLUSION_NEIGHBOURS,
        spatial_radius: 10.0,
        spatial_passes: 1,
        ..Default::default()
    }
}

/// Image means (average of r, g, b) of `runs` independent renders: mean and standard error.
fn image_means(
    scene: &Scene,
    integrator: Integrator,
    runs: u32,
    spp: u32,
    max_depth: u32,
    flags: u32,
) -> (f64, f64) {
    let v: Vec<f64> = (0..runs)
        .map(|s| {
            let p = params(scene, 32, 24, 1000 + s, max_depth, flags);
            let mut cpu = CpuBackend::new(scene, p.width, p.height);
            let (img, _) = render(&mut cpu, integrator, &p, spp, spp, false).unwrap();
            assert!(img.pixels.iter().all(|p| p.is_finite()));
            img.mean().dot(Vec3::splat(1.0 / 3.0)) as f64
        })
        .collect();
    common::mean_and_standard_error(&v)
}

fn scenes() -> Vec<(&'static str, Scene)> {
    vec![
        ("cornell-box", runner::scene::cornell_box().unwrap()),
        (
            "many-lights",
            runner::generate::many_lights().into_scene().unwrap(),
        ),
    ]
}

#[test]
fn ris_direct_light_is_unbiased() {
    for (name, scene) in scenes() {
        let (nee, se_nee) = image_means(&scene, Integrator::Nee, 8, 16, 2, 0);
        let (ris, se_ris) = image_means(&scene, Integrator::Ris, 8, 16, 2, 0);
        let se = (se_nee * se_nee + se_ris * se_ris).sqrt();
        assert!(
            (nee - ris).abs() < 4.5 * se,
            "{name}: NEE {nee}±{se_nee} vs RIS {ris}±{se_ris}"
        );
    }
}

#[test]
fn unbiased_restir_converges_to_nee_and_biased_error_is_reported() {
    let full = RESTIR_TEMPORAL | RESTIR_VISIBILITY_REUSE;
    for (name, scene) in scenes() {
        let (nee, se_nee) = image_means(&scene, Integrator::Nee, 12, 64, 2, 0);
        let (unb, se_unb) = image_means(
            &scene,
            Integrator::Restir,
            12,
            64,
            2,
            full | RESTIR_UNBIASED,
        );
        let (bia, se_bia) = image_means(&scene, Integrator::Restir, 12, 64, 2, full);
        let se = (se_nee * se_nee + se_unb * se_unb).sqrt();
        eprintln!(
            "{name}: NEE {nee:.5}±{se_nee:.5}  ReSTIR unbiased {unb:.5}±{se_unb:.5}  biased {bia:.5}±{se_bia:.5} \
             (biased error {:+.2}%)",
            100.0 * (bia - nee) / nee
        );
        assert!(
            (nee - unb).abs() < 4.5 * se,
            "{name}: unbiased ReSTIR {unb} vs NEE {nee} (se {se})"
        );
        // The biased mode trades a small bias for less noise; it must stay small (10%, plus
        // what the noise of this measurement allows).
        let se_b = (se_nee * se_nee + se_bia * se_bia).sqrt();
        assert!(
            (bia - nee).abs() < 0.1 * nee + 4.5 * se_b,
            "{name}: biased ReSTIR {bia} vs NEE {nee}"
        );
    }
}

#[test]
fn fused_passes_render_what_split_passes_do() {
    // The fused dispatches (primary with initial, the last spatial pass with shade) read
    // only their own pixel of what they would have written, so every frame must be the
    // same to the bit, with history (8 frames), in both modes, for 0, 1 and 2 spatial passes.
    let (_, scene) = scenes().remove(1);
    for unbiased in [0, RESTIR_UNBIASED] {
        for spatial_passes in 0..3 {
            let image = |split| {
                let flags = RESTIR_TEMPORAL | RESTIR_VISIBILITY_REUSE | unbiased | split;
                let p = FrameParams {
                    spatial_passes,
                    ..params(&scene, 32, 24, 7, 2, flags)
                };
                let mut cpu = CpuBackend::new(&scene, p.width, p.height);
                render(&mut cpu, Integrator::Restir, &p, 8, 8, false)
                    .unwrap()
                    .0
            };
            let (fused, split) = (image(0), image(RESTIR_SPLIT_PASSES));
            assert!(fused.mean().max_element() > 0.0);
            assert!(
                fused.pixels == split.pixels,
                "unbiased {unbiased}, {spatial_passes} spatial passes"
            );
        }
    }
}

#[test]
fn temporal_reuse_rejects_disoccluded_pixels() {
    // A box in front of a back wall; between frames the camera slides sideways, so wall
    // pixels that the box covered in the previous frame become visible.
    let mut tris = common::quad(
        [
            Vec3::new(-20.0, -20.0, -10.0),
            Vec3::new(20.0, -20.0, -10.0),
            Vec3::new(20.0, 20.0, -10.0),
            Vec3::new(-20.0, 20.0, -10.0),
        ],
        0,
    )
    .to_vec();
    tris.extend(common::closed_box(
        Vec3::new(-1.5, -1.5, -3.0),
        Vec3::new(1.5, 1.5, 0.0),
        0,
    ));
    // A light above, facing down.
    tris.extend(common::quad(
        [
            Vec3::new(-2.0, 8.0, -6.0),
            Vec3::new(2.0, 8.0, -6.0),
            Vec3::new(2.0, 8.0, -2.0),
            Vec3::new(-2.0, 8.0, -2.0),
        ],
        1,
    ));
    let materials = vec![
        common::grey(0.6),
        Material::new(Vec3::splat(0.5), Vec3::splat(10.0)),
    ];
    // Identify the wall by position (triangles are reordered by the BVH): it lies in z = -10.
    let scene = Scene::new(tris, materials).unwrap();
    let on_wall =
        |g: &kernels::types::GBufferTexel| g.prim != INVALID && (g.p[2] + 10.0).abs() < 1e-3;

    let (w, h) = (64u32, 48u32);
    let cam = |x: f32| {
        look_at(
            Vec3::new(x, 0.0, 12.0),
            Vec3::new(x, 0.0, -10.0),
            Vec3::Y,
            40.0,
            w as f32 / h as f32,
        )
    };
    let ks = scene.kernel();
    let frame = |camera, frame: u32| FrameParams {
        camera,
        width: w,
        height: h,
        frame,
        max_depth: 2,
        candidates: 4,
        temporal_cap: 20.0,
        restir_flags: RESTIR_TEMPORAL | RESTIR_HISTORY_VALID,
        ..Default::default()
    };
    let p0 = frame(cam(0.0), 0);
    let mut p1 = frame(cam(2.0), 1);
    p1.prev_camera = p0.camera;
    let mut rays = 0;
    let gbuf = |p: &FrameParams, rays: &mut u32| -> Vec<_> {
        (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| restir::primary_hit::<false>(&ks, p, x, y, rays))
            .collect()
    };
    let (g0, g1) = (gbuf(&p0, &mut rays), gbuf(&p1, &mut rays));
    let res =
        |p: &FrameParams, g: &[kernels::types::GBufferTexel], rays: &mut u32| -> Vec<Reservoir> {
            g.iter()
                .enumerate()
                .map(|(i, t)| restir::initial_pass::<false>(&ks, p, t, i as u32, rays))
                .collect()
        };
    let (r0, r1) = (res(&p0, &g0, &mut rays), res(&p1, &g1, &mut rays));
    let (mut merged, mut rejected_disocclusions) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            let out = restir::temporal_pass::<false>(
                &ks, &p1, &g1[i], r1[i], &g0, &r0, i as u32, &mut rays,
            );
            let reprojected = restir::project(&p1.prev_camera, w, h, Vec3::from(g1[i].p));
            let took_history = out.m > r1[i].m;
            if let (true, Some((px, py))) = (on_wall(&g1[i]), reprojected) {
                let before = &g0[(py * w + px) as usize];
                if !on_wall(before) {
                    // The wall point was hidden behind the box: no history may be taken.
                    assert!(
                        !took_history,
                        "pixel ({x},{y}) took history across a disocclusion"
                    );
                    rejected_disocclusions += 1;
                } else if took_history {
                    merged += 1;
                }
            }
        }
    }
    assert!(
        rejected_disocclusions > 20,
        "the test must produce disocclusions ({rejected_disocclusions})"
    );
    assert!(
        merged > (w * h / 4) as usize,
        "visible wall pixels should reuse history ({merged})"
    );
}

/// What a viewer shows: one frame after `frames` frames of history (RIS: one frame), on
/// many-lights at 512×384, direct light, 32 candidates a frame, against the committed
/// reference (MIS, 65,536 spp on an H100). Single frames vary up to 2× from seed to seed,
/// so each figure is a mean over seeds. Returns (relMSE, image mean / reference mean).
fn single_frame_error(
    integrator: Integrator,
    frames: u32,
    candidates: u32,
    spatial_passes: u32,
    flags: u32,
    seeds: u32,
) -> (f64, f64) {
    let reference = runner::output::read_image(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../tests/references/many_lights_512x384_direct.exr"
    )))
    .unwrap();
    let scene = runner::generate::many_lights().into_scene().unwrap();
    let (mut rel, mut ratio) = (0.0, 0.0);
    for seed in 1..=seeds {
        let mut p = params(&scene, 512, 384, seed, 2, flags);
        p.candidates = candidates;
        p.spatial_passes = spatial_passes;
        p.spatial_radius = runner::options::default_spatial_radius(512, 384);
        let mut cpu = CpuBackend::new(&scene, p.width, p.height);
        let (img, _) = runner::render::render_sequence(
            &mut cpu,
            integrator,
            &p,
            1,
            frames,
            false,
            |_| Ok(p.camera),
            |_, _| Ok(()),
        )
        .unwrap();
        rel += runner::output::compare(&img, &reference).unwrap().rel_mse;
        ratio += (img.mean().element_sum() / reference.mean().element_sum()) as f64;
    }
    (rel / seeds as f64, ratio / seeds as f64)
}

/// ReSTIR's reason to exist: a single frame with history beats RIS with 32× the candidates,
/// each kind of reuse helps, and longer history does not hurt; in the default (unbiased)
/// mode, with the image mean right, and the biased mode's mean close.
#[test]
fn restir_single_frames_get_better_with_history() {
    let full = RESTIR_TEMPORAL | RESTIR_VISIBILITY_REUSE | RESTIR_UNBIASED;
    let (ris_1024, _) = single_frame_error(Integrator::Ris, 1, 1024, 0, 0, 3);
    let (first_no_spatial, _) = single_frame_error(Integrator::Restir, 1, 32, 0, full, 3);
    let (first, _) = single_frame_error(Integrator::Restir, 1, 32, 1, full, 3);
    let (temporal_16, _) = single_frame_error(Integrator::Restir, 16, 32, 0, full, 3);
    let (after_16, mean_16) = single_frame_error(Integrator::Restir, 16, 32, 1, full, 3);
    let (after_64, mean_64) = single_frame_error(Integrator::Restir, 64, 32, 1, full, 2);
    let biased = full & !RESTIR_UNBIASED;
    let (biased_16, biased_mean_16) = single_frame_error(Integrator::Restir, 16, 32, 1, biased, 3);
    eprintln!(
        "relMSE of one frame: RIS 1024 candidates {ris_1024:.4}; ReSTIR frame 1 {first:.4} \
         (without spatial {first_no_spatial:.4}), after 16 {after_16:.4} (temporal only {temporal_16:.4}, \
         mean x{mean_16:.4}), after 64 {after_64:.4} (mean x{mean_64:.4}); biased after 16 \
         {biased_16:.4} (mean x{biased_mean_16:.4})"
    );
    assert!(
        first < 0.75 * first_no_spatial,
        "spatial reuse must help the first frame: {first} vs {first_no_spatial}"
    );
    assert!(
        after_16 <= 0.75 * ris_1024,
        "16 frames of history: {after_16} vs RIS 1024 {ris_1024}"
    );
    assert!(
        after_16 < temporal_16,
        "spatial reuse must help after 16 frames: {after_16} vs {temporal_16}"
    );
    assert!(
        after_64 <= 1.1 * after_16,
        "64 frames must be no worse than 16: {after_64} vs {after_16}"
    );
    for m in [mean_16, mean_64] {
        assert!(
            (m - 1.0).abs() < 0.02,
            "unbiased ReSTIR's image mean x{m} of the reference"
        );
    }
    assert!(
        (biased_mean_16 - 1.0).abs() < 0.04 && biased_16 <= 0.75 * ris_1024,
        "biased ReSTIR: mean x{biased_mean_16}, relMSE {biased_16}"
    );
}
