//! Resampled importance sampling of direct light (the course's RIS): draw M candidate
//! light samples from the light-source pdf, keep one with weighted reservoir sampling in
//! proportion to w = p̂ / p, with target p̂ = BRDF · Le · G (visibility taken as 1), and
//! shade it with one shadow ray: contribution = f · Le · G · V · W, W = w_sum / (M p̂).
//! A candidate is a point on an emissive triangle (area measure: p̂ = f · Le · cos' / d²)
//! or, with the probabilities NEE uses, a direction of the environment map or the sun
//! (solid-angle measure: p̂ = f · Le); each sample keeps its own measure in p̂, p and the
//! contribution alike, so the weights p̂ / p compare across the two.
use crate::bsdf::{Bsdf, BSDF_DIFFUSE};
use crate::bvh::{SceneBuffers, SurfaceHit};
use crate::env::{escaped_radiance, infinite_direction, infinite_pdf};
use crate::glam::Vec3;
use crate::integrators::path::infinite_probability;
use crate::lights::{geometry_term, sample_on_light, select_light};
use crate::math::{luminance, PI};
use crate::reservoir::{Reservoir, DIRECTION_SAMPLE};
use crate::rng::Rng;
use crate::sampling::{octahedral_decode, octahedral_encode, orthonormal_basis};
use crate::types::FrameParams;

/// A light point given by triangle and barycentrics: position, front normal, radiance.
pub fn light_point(scene: &SceneBuffers, triangle: u32, b1: f32, b2: f32) -> (Vec3, Vec3, Vec3) {
    let tri = scene.triangle(triangle);
    (
        tri.point(b1, b2),
        tri.normal(),
        scene.emission_at(&tri, b1, b2),
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

/// The unshadowed contribution f · Le · cos of the map and the sun toward the unit
/// direction `wi` (RGB, solid-angle measure).
pub fn unshadowed_direction(
    scene: &SceneBuffers,
    params: &FrameParams,
    sp: &ShadingPoint,
    wi: Vec3,
) -> Vec3 {
    let le = escaped_radiance(scene, params, wi);
    if sp.bsdf.kind == BSDF_DIFFUSE {
        return (sp.bsdf.albedo / PI) * le * sp.n.dot(wi).max(0.0);
    }
    let (t, b) = orthonormal_basis(sp.n);
    let local = |w: Vec3| Vec3::new(w.dot(t), w.dot(b), w.dot(sp.n));
    sp.bsdf.eval(local(sp.wo), local(wi)) * le
}

/// The scalar target function p̂: luminance of the unshadowed contribution.
pub fn target_pdf<const ALL_DIFFUSE: bool>(sp: &ShadingPoint, q: Vec3, nq: Vec3, le: Vec3) -> f32 {
    luminance(unshadowed::<ALL_DIFFUSE>(sp, q, nq, le))
}

/// What a reservoir's sample brings to a surface point, without visibility: f · Le · G for
/// a point on a triangle, f · Le · cos for a direction (each in its own measure).
pub fn unshadowed_sample<const ALL_DIFFUSE: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    r: &Reservoir,
    sp: &ShadingPoint,
) -> Vec3 {
    if !r.has_sample() {
        return Vec3::ZERO;
    }
    if !ALL_DIFFUSE && r.triangle == DIRECTION_SAMPLE {
        return unshadowed_direction(scene, params, sp, octahedral_decode(r.b1, r.b2));
    }
    let (q, nq, le) = light_point(scene, r.triangle, r.b1, r.b2);
    unshadowed::<ALL_DIFFUSE>(sp, q, nq, le)
}

/// p̂ of a reservoir's sample at another surface point (reuse re-evaluates it there).
pub fn target_pdf_of<const ALL_DIFFUSE: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    r: &Reservoir,
    sp: &ShadingPoint,
) -> f32 {
    luminance(unshadowed_sample::<ALL_DIFFUSE>(scene, params, r, sp))
}

/// Whether surface point p (normal n) sees a reservoir's sample: one shadow ray, to the
/// light point or out of the scene along the direction.
pub fn sample_visible<const ALL_DIFFUSE: bool>(
    scene: &SceneBuffers,
    r: &Reservoir,
    p: Vec3,
    n: Vec3,
) -> bool {
    if !ALL_DIFFUSE && r.triangle == DIRECTION_SAMPLE {
        return scene.visible_towards::<ALL_DIFFUSE>(p, n, octahedral_decode(r.b1, r.b2));
    }
    let (q, nq, _) = light_point(scene, r.triangle, r.b1, r.b2);
    scene.visible::<ALL_DIFFUSE>(p, n, q, nq)
}

/// Stream `params.candidates` light samples through a reservoir (not yet finalised): each
/// a point on an emissive triangle or, with the map's and the sun's share of NEE's light
/// choice, a direction of theirs. Which triangle a candidate is on comes from `choice`
/// (two numbers a candidate, drawn whatever the candidate turns out to be), the rest from
/// `rng`: ReSTIR gives every pixel of a warp the same `choice` stream, so that their k-th
/// candidates read one light's data (see `restir::light_choice_rng`).
pub fn initial_candidates<const ALL_DIFFUSE: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    sp: &ShadingPoint,
    rng: &mut Rng,
    choice: &mut Rng,
) -> Reservoir {
    let mut r = Reservoir::empty();
    let p_infinite = infinite_probability::<ALL_DIFFUSE>(params);
    if scene.lights.is_empty() && p_infinite <= 0.0 {
        return r;
    }
    let mut i = 0;
    while i < params.candidates {
        i += 1;
        let (u_slot, u_coin) = (choice.next_u32(), choice.next_f32());
        // A number for the choice only when there is one: other scenes keep their streams.
        let u_choice = if p_infinite > 0.0 {
            rng.next_f32()
        } else {
            1.0
        };
        if u_choice < p_infinite {
            // The reservoir keeps the direction octahedrally encoded, and reuse and shading
            // see what it decodes to: p̂ and the density must be of that direction too. A
            // direction drawn from the map just outside the sun's disk can decode to just
            // inside it, and weighed by the map's density alone it was a firefly of the
            // sun's full radiance (seen: 800× the pixel's value at 16 spp).
            let drawn = infinite_direction(scene, params, u_choice, rng.next_f32(), rng.next_f32());
            let (e1, e2) = octahedral_encode(drawn);
            let dir = octahedral_decode(e1, e2);
            let pdf = infinite_pdf(scene, params, dir);
            let p_hat = luminance(unshadowed_direction(scene, params, sp, dir));
            let weight = if pdf > 0.0 { p_hat / pdf } else { 0.0 };
            r.update(DIRECTION_SAMPLE, e1, e2, weight, p_hat, rng.next_f32());
            continue;
        }
        let index = select_light(scene.lights, params.light_sampling, u_slot, u_coin);
        let ls = sample_on_light(scene, params.light_sampling, index, rng);
        let p_hat = target_pdf::<ALL_DIFFUSE>(sp, ls.p, ls.n, ls.emission);
        r.update(
            ls.triangle,
            ls.b1,
            ls.b2,
            p_hat / (ls.pdf_area * (1.0 - p_infinite)),
            p_hat,
            rng.next_f32(),
        );
    }
    r
}

/// A finalised reservoir's contribution without visibility: f · Le · G · W.
pub fn unshadowed_reservoir<const ALL_DIFFUSE: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    r: &Reservoir,
    sp: &ShadingPoint,
) -> Vec3 {
    if r.w > 0.0 {
        unshadowed_sample::<ALL_DIFFUSE>(scene, params, r, sp) * r.w
    } else {
        Vec3::ZERO
    }
}

/// Shade a finalised reservoir: f · Le · G · V · W, one shadow ray.
pub fn shade_reservoir<const ALL_DIFFUSE: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    r: &Reservoir,
    sp: &ShadingPoint,
    rays: &mut u32,
) -> Vec3 {
    let contribution = unshadowed_reservoir::<ALL_DIFFUSE>(scene, params, r, sp);
    if contribution == Vec3::ZERO {
        return Vec3::ZERO;
    }
    *rays += 1;
    if !sample_visible::<ALL_DIFFUSE>(scene, r, sp.p, sp.n) {
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
    // Each pixel chooses its candidates' lights on its own here.
    let mut choice = Rng::from_seed(rng.next_u32());
    let mut r = initial_candidates::<ALL_DIFFUSE>(scene, params, sp, rng, &mut choice);
    r.finalize(r.m);
    shade_reservoir::<ALL_DIFFUSE>(scene, params, &r, sp, rays)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::FrameParams;

    #[test]
    fn a_direction_candidate_is_weighed_as_the_reservoir_stores_it() {
        // A small sun (0.1°) alone: of many one-candidate reservoirs, each one's p̂ must be
        // the target of the direction it decodes to (what reuse and shading evaluate).
        // When p̂ was taken at the drawn direction, those drawn within rounding of the
        // disk's edge disagreed (sun vs no sun), and a map-drawn one decoding into the sun
        // was a firefly of the sun's full radiance.
        let scene = SceneBuffers {
            triangles: &[],
            materials: &[],
            nodes: &[],
            lights: &[],
            shading: &[],
            textures: &[],
            texels: &[],
            env_distribution: &[],
        };
        let params = FrameParams {
            env_texture: crate::types::INVALID,
            sun_light_probability: 1.0,
            sun_direction: [0.3, 0.9, 0.2],
            sun_cos_max: (0.05f32).to_radians().cos(),
            sun_radiance: [1e4; 3],
            candidates: 1,
            ..Default::default()
        };
        let sun = Vec3::from(params.sun_direction).normalize();
        let params = FrameParams {
            sun_direction: sun.to_array(),
            ..params
        };
        let sp = ShadingPoint {
            p: Vec3::ZERO,
            n: Vec3::Y,
            wo: Vec3::Y,
            bsdf: crate::bsdf::Bsdf::diffuse(Vec3::splat(0.5)),
        };
        let (mut mismatches, mut empty) = (0, 0);
        for i in 0..200_000 {
            let mut rng = Rng::new(i, 0, 0, 1);
            let mut choice = Rng::from_seed(rng.next_u32());
            let r = initial_candidates::<false>(&scene, &params, &sp, &mut rng, &mut choice);
            if !r.has_sample() {
                empty += 1;
                continue;
            }
            let here = target_pdf_of::<false>(&scene, &params, &r, &sp);
            if (r.target_pdf - here).abs() > 1e-3 * r.target_pdf {
                mismatches += 1;
            }
        }
        assert_eq!(mismatches, 0, "of 200,000 reservoirs");
        // Drawn inside the disk and decoded just outside it (the disk's edge is within f32
        // rounding of cos θ for so small a sun): no sample, as shading found before. 0.5%
        // here, ~0.1% for the real sun's 0.53°.
        assert!(
            empty <= 2000,
            "{empty} of 200,000 reservoirs lost their sample"
        );
    }
}
