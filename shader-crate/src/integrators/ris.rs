//! Resampled importance sampling of direct light (the course's RIS): draw M candidate
//! light points from the light-source pdf, keep one with weighted reservoir sampling in
//! proportion to w = p̂ / p, with target p̂ = BRDF · Le · G (visibility taken as 1), and
//! shade it with one shadow ray: contribution = f · Le · G · V · W, W = w_sum / (M p̂).
use crate::bvh::{SceneBuffers, SurfaceHit};
use crate::glam::Vec3;
use crate::lights::{geometry_term, sample_light};
use crate::math::{luminance, PI};
use crate::reservoir::Reservoir;
use crate::rng::Rng;
use crate::types::FrameParams;

/// A light point given by triangle and barycentrics: position, front normal, radiance.
pub fn light_point(scene: &SceneBuffers, triangle: u32, b1: f32, b2: f32) -> (Vec3, Vec3, Vec3) {
    let tri = scene.triangles[triangle as usize];
    (
        tri.point(b1, b2),
        tri.normal(),
        scene.materials[tri.material as usize].emission(),
    )
}

/// The unshadowed contribution f · Le · G of a light point at a surface point (RGB).
pub fn unshadowed(p: Vec3, n: Vec3, albedo: Vec3, q: Vec3, nq: Vec3, le: Vec3) -> Vec3 {
    (albedo / PI) * le * geometry_term(p, n, q, nq)
}

/// The scalar target function p̂: luminance of the unshadowed contribution.
pub fn target_pdf(p: Vec3, n: Vec3, albedo: Vec3, q: Vec3, nq: Vec3, le: Vec3) -> f32 {
    luminance(unshadowed(p, n, albedo, q, nq, le))
}

/// p̂ of a reservoir's sample at another surface point (reuse re-evaluates it there).
pub fn target_pdf_of(scene: &SceneBuffers, r: &Reservoir, p: Vec3, n: Vec3, albedo: Vec3) -> f32 {
    if !r.has_sample() {
        return 0.0;
    }
    let (q, nq, le) = light_point(scene, r.triangle, r.b1, r.b2);
    target_pdf(p, n, albedo, q, nq, le)
}

/// Stream `params.candidates` light samples through a reservoir (not yet finalised).
pub fn initial_candidates(
    scene: &SceneBuffers,
    params: &FrameParams,
    p: Vec3,
    n: Vec3,
    albedo: Vec3,
    rng: &mut Rng,
) -> Reservoir {
    let mut r = Reservoir::empty();
    if scene.lights.is_empty() {
        return r;
    }
    let mut i = 0;
    while i < params.candidates {
        let ls = sample_light(scene, params.light_sampling, rng);
        let p_hat = target_pdf(p, n, albedo, ls.p, ls.n, ls.emission);
        r.update(
            ls.triangle,
            ls.b1,
            ls.b2,
            p_hat / ls.pdf_area,
            p_hat,
            rng.next_f32(),
        );
        i += 1;
    }
    r
}

/// The light point of a finalised reservoir that contributes (a sample and W > 0).
fn contributing_light(scene: &SceneBuffers, r: &Reservoir) -> Option<(Vec3, Vec3, Vec3)> {
    if !r.has_sample() || r.w <= 0.0 {
        return None;
    }
    Some(light_point(scene, r.triangle, r.b1, r.b2))
}

/// A finalised reservoir's contribution without visibility: f · Le · G · W.
pub fn unshadowed_reservoir(
    scene: &SceneBuffers,
    r: &Reservoir,
    p: Vec3,
    n: Vec3,
    albedo: Vec3,
) -> Vec3 {
    match contributing_light(scene, r) {
        Some((q, nq, le)) => unshadowed(p, n, albedo, q, nq, le) * r.w,
        None => Vec3::ZERO,
    }
}

/// Shade a finalised reservoir: f · Le · G · V · W, one shadow ray.
pub fn shade_reservoir(
    scene: &SceneBuffers,
    r: &Reservoir,
    p: Vec3,
    n: Vec3,
    albedo: Vec3,
    rays: &mut u32,
) -> Vec3 {
    let Some((q, nq, le)) = contributing_light(scene, r) else {
        return Vec3::ZERO;
    };
    let contribution = unshadowed(p, n, albedo, q, nq, le) * r.w;
    if contribution == Vec3::ZERO {
        return Vec3::ZERO;
    }
    *rays += 1;
    if !scene.visible(p, n, q, nq) {
        return Vec3::ZERO;
    }
    contribution
}

/// Direct light at `s` by RIS (the `ris` integrator's first vertex).
pub fn direct_ris(
    scene: &SceneBuffers,
    params: &FrameParams,
    s: &SurfaceHit,
    albedo: Vec3,
    rng: &mut Rng,
    rays: &mut u32,
) -> Vec3 {
    // The shading normal throughout: RIS's target and shadow ray see the surface as the
    // G-buffer of ReSTIR does.
    let mut r = initial_candidates(scene, params, s.p, s.ns, albedo, rng);
    r.finalize(r.m);
    shade_reservoir(scene, &r, s.p, s.ns, albedo, rays)
}
