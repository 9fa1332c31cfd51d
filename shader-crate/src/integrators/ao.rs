//! Ambient occlusion, the course's first integrator: the fraction of cosine-weighted
//! directions around a visible point that escape within `ao_distance`.
use crate::bvh::{offset_ray_origin, surface_hit, SceneBuffers};
use crate::glam::Vec3;
use crate::integrators::{accumulate_samples, PixelResult};
use crate::intersect::Ray;
use crate::rng::Rng;
use crate::sampling::{cosine_hemisphere, local_to_world, Strata};
use crate::types::{FrameParams, AO_INDEPENDENT};

/// Unoccluded fraction at `p` with normal `n`, from `rays` cosine-weighted rays of length
/// `distance`, spread over the hemisphere by `strata`. Cosine weighting makes this the
/// cosine-weighted visibility integral (1/π) ∫ V(ω) cos θ dω estimated with equal weights.
pub fn ambient_occlusion<const PLAIN: bool>(
    scene: &SceneBuffers,
    p: Vec3,
    n: Vec3,
    rays: u32,
    strata: Strata,
    distance: f32,
    rng: &mut Rng,
) -> f32 {
    let origin = offset_ray_origin(p, n);
    let open = scene.count_unoccluded::<PLAIN, _>(rays, distance, rng, |k, rng| {
        let (u1, u2) = strata.point(k, rng.next_f32(), rng.next_f32());
        Ray::new(origin, local_to_world(cosine_hemisphere(u1, u2), n))
    });
    open as f32 / rays.max(1) as f32
}

/// One AO sample for a camera ray: 0 where the ray leaves the scene (no surface, no
/// occlusion to speak of), the unoccluded fraction (grey) where it hits.
pub fn ao_sample<const PLAIN: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    ray: Ray,
    rng: &mut Rng,
    rays: &mut u32,
) -> Vec3 {
    let hit = scene.closest_hit::<PLAIN>(&ray, f32::INFINITY);
    *rays += 1;
    if !hit.is_hit() {
        return Vec3::ZERO;
    }
    let s = surface_hit(scene, &ray, &hit);
    *rays += params.ao_rays;
    let strata = if params.ao_sampling == AO_INDEPENDENT {
        Strata::NONE
    } else {
        Strata::new(params.ao_rays)
    };
    Vec3::splat(ambient_occlusion::<PLAIN>(
        scene,
        s.p,
        s.n,
        params.ao_rays,
        strata,
        params.ao_distance,
        rng,
    ))
}

/// `PLAIN`: the scene has no cut-outs (the plain-scene variant; see `bvh::closest_hit`).
pub fn render_pixel<const PLAIN: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    x: u32,
    y: u32,
) -> PixelResult {
    accumulate_samples(params, x, y, |ray, rng, rays| {
        ao_sample::<PLAIN>(scene, params, ray, rng, rays)
    })
}
