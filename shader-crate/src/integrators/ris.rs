//! Resampled importance sampling of direct light (the course's RIS): draw M candidate
//! light points from the light-source pdf, keep one with weighted reservoir sampling in
//! proportion to w = p̂ / p, with target p̂ = BRDF · Le · G (visibility taken as 1), and
//! shade it with one shadow ray: contribution = f · Le · G · V · W, W = w_sum / (M p̂).
use crate::bsdf::{Bsdf, BSDF_DIFFUSE};
use crate::bvh::{SceneBuffers, SurfaceHit};
use crate::glam::Vec3;
use crate::lights::{geometry_term, sample_light};
use crate::math::{luminance, PI};
use crate::reservoir::Reservoir;
use crate::rng::Rng;
use crate::sampling::orthonormal_basis;
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

/// A surface point as the direct-light estimators see it: position, shading normal, the
/// unit direction towards the viewer, and its BSDF.
#[derive(Copy, Clone, Debug)]
pub struct ShadingPoint {
    pub p: Vec3,
    pub n: Vec3,
    pub wo: Vec3,
    pub bsdf: Bsdf,
}

impl ShadingPoint {
    pub fn new(s: &SurfaceHit, wo: Vec3, bsdf: Bsdf) -> Self {
        Self {
            p: s.p,
            n: s.ns,
            wo,
            bsdf,
        }
    }
}

/// The unshadowed contribution f · Le · G of a light point at a surface point (RGB).
/// `ALL_DIFFUSE` (here and below) promises a Lambertian BSDF, so that the kernels of
/// all-Lambertian scenes carry no other BSDF's code (see `path::trace_path`).
pub fn unshadowed<const ALL_DIFFUSE: bool>(sp: &ShadingPoint, q: Vec3, nq: Vec3, le: Vec3) -> Vec3 {
    if ALL_DIFFUSE || sp.bsdf.kind == BSDF_DIFFUSE {
        // The course's formula; the general one below gives the same, slower.
        return (sp.bsdf.albedo / PI) * le * geometry_term(sp.p, sp.n, q, nq);
    }
    let d = q - sp.p;
    let dist2 = d.length_squared();
    let wi = d / crate::math::sqrt(dist2);
    let cos_q = -nq.dot(wi);
    if cos_q <= 0.0 || dist2 == 0.0 {
        return Vec3::ZERO;
    }
    let (t, b) = orthonormal_basis(sp.n);
    let local = |w: Vec3| Vec3::new(w.dot(t), w.dot(b), w.dot(sp.n));
    sp.bsdf.eval(local(sp.wo), local(wi)) * le * (cos_q / dist2)
}

/// The scalar target function p̂: luminance of the unshadowed contribution.
pub fn target_pdf<const ALL_DIFFUSE: bool>(sp: &ShadingPoint, q: Vec3, nq: Vec3, le: Vec3) -> f32 {
    luminance(unshadowed::<ALL_DIFFUSE>(sp, q, nq, le))
}

/// p̂ of a reservoir's sample at another surface point (reuse re-evaluates it there).
pub fn target_pdf_of<const ALL_DIFFUSE: bool>(
    scene: &SceneBuffers,
    r: &Reservoir,
    sp: &ShadingPoint,
) -> f32 {
    if !r.has_sample() {
        return 0.0;
    }
    let (q, nq, le) = light_point(scene, r.triangle, r.b1, r.b2);
    target_pdf::<ALL_DIFFUSE>(sp, q, nq, le)
}

/// Stream `params.candidates` light samples through a reservoir (not yet finalised).
pub fn initial_candidates<const ALL_DIFFUSE: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    sp: &ShadingPoint,
    rng: &mut Rng,
) -> Reservoir {
    let mut r = Reservoir::empty();
    if scene.lights.is_empty() {
        return r;
    }
    let mut i = 0;
    while i < params.candidates {
        let ls = sample_light(scene, params.light_sampling, rng);
        let p_hat = target_pdf::<ALL_DIFFUSE>(sp, ls.p, ls.n, ls.emission);
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
pub fn unshadowed_reservoir<const ALL_DIFFUSE: bool>(
    scene: &SceneBuffers,
    r: &Reservoir,
    sp: &ShadingPoint,
) -> Vec3 {
    match contributing_light(scene, r) {
        Some((q, nq, le)) => unshadowed::<ALL_DIFFUSE>(sp, q, nq, le) * r.w,
        None => Vec3::ZERO,
    }
}

/// Shade a finalised reservoir: f · Le · G · V · W, one shadow ray.
pub fn shade_reservoir<const ALL_DIFFUSE: bool>(
    scene: &SceneBuffers,
    r: &Reservoir,
    sp: &ShadingPoint,
    rays: &mut u32,
) -> Vec3 {
    let Some((q, nq, le)) = contributing_light(scene, r) else {
        return Vec3::ZERO;
    };
    let contribution = unshadowed::<ALL_DIFFUSE>(sp, q, nq, le) * r.w;
    if contribution == Vec3::ZERO {
        return Vec3::ZERO;
    }
    *rays += 1;
    if !scene.visible(sp.p, sp.n, q, nq) {
        return Vec3::ZERO;
    }
    contribution
}

/// Direct light at a surface point by RIS (the `ris` integrator's first vertex). The
/// shading normal throughout: RIS's target and shadow ray see the surface as the G-buffer
/// of ReSTIR does.
pub fn direct_ris<const ALL_DIFFUSE: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    sp: &ShadingPoint,
    rng: &mut Rng,
    rays: &mut u32,
) -> Vec3 {
    let mut r = initial_candidates::<ALL_DIFFUSE>(scene, params, sp, rng);
    r.finalize(r.m);
    shade_reservoir::<ALL_DIFFUSE>(scene, &r, sp, rays)
}
