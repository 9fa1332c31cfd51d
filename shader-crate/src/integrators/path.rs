//! Path tracing with several strategies in one loop, so each term is written once:
//! - `BSDF` (`--integrator pt`): the course's loop; emission counts when a path hits it.
//! - `NEE`: at every vertex a light point is sampled and joined with a shadow ray; emission
//!   hit by a bounce is then not counted again (only what the camera sees directly).
//! - `MIS`: both, weighted by the power heuristic, so small and large lights are both
//!   handled well.
//! - `RIS`: like NEE, but the direct light at the first vertex comes from resampled
//!   importance sampling (`ris.rs`).
//!
//! Surfaces are two-sided Lambertian, lights one-sided, the sky a constant radiance.
use crate::bvh::{offset_ray_origin, surface_hit, SceneBuffers, SurfaceHit};
use crate::glam::Vec3;
use crate::integrators::{ris, PixelResult};
use crate::intersect::Ray;
use crate::lights::{geometry_term, light_pdf_area, power_heuristic, sample_light};
use crate::math::{vec3, PI};
use crate::rng::Rng;
use crate::sampling::{cosine_hemisphere, local_to_world};
use crate::types::FrameParams;

pub const BSDF: u32 = 0;
pub const NEE: u32 = 1;
pub const MIS: u32 = 2;
pub const RIS: u32 = 3;

/// Russian roulette never keeps a path with probability above this: even a white surface
/// ends its paths eventually (and the survivors' weight 1/q stays bounded).
const MAX_SURVIVAL: f32 = 0.95;

/// Where a path stands: the ray it continues along, the product of BSDF · cos / pdf so
/// far, the number of the segment `ray` is, and the solid-angle density of the BSDF
/// sample that produced `ray` (MIS weights the emission it reaches).
#[derive(Copy, Clone, Debug)]
pub struct PathState {
    pub ray: Ray,
    pub throughput: Vec3,
    pub depth: u32,
    pub bsdf_pdf: f32,
}

impl PathState {
    pub fn camera(ray: Ray) -> Self {
        Self {
            ray,
            throughput: Vec3::ONE,
            depth: 1,
            bsdf_pdf: 0.0,
        }
    }

    /// Continue from surface `s` (albedo `albedo`) by cosine sampling: the sampling cancels
    /// cos/π against the Lambertian BRDF, leaving throughput *= albedo (the course's
    /// update). Returns false when Russian roulette ends the path.
    pub fn bounce(
        &mut self,
        s: &SurfaceHit,
        albedo: Vec3,
        params: &FrameParams,
        rng: &mut Rng,
    ) -> bool {
        let local = cosine_hemisphere(rng.next_f32(), rng.next_f32());
        let dir = local_to_world(local, s.ns);
        if !s.leaves(dir) {
            return false;
        }
        self.bsdf_pdf = local.z / PI;
        self.throughput *= albedo;
        if self.depth >= params.rr_depth {
            let q = self.throughput.max_element().min(MAX_SURVIVAL);
            if rng.next_f32() >= q {
                return false;
            }
            self.throughput /= q;
        }
        self.ray = Ray::new(offset_ray_origin(s.p, s.n), dir);
        self.depth += 1;
        true
    }
}

/// Direct light at surface `s` by next-event estimation: one light point, one shadow ray.
/// With `mis`, weighted against BSDF sampling by the power heuristic.
pub fn direct_nee(
    scene: &SceneBuffers,
    params: &FrameParams,
    s: &SurfaceHit,
    albedo: Vec3,
    mis: bool,
    rng: &mut Rng,
    rays: &mut u32,
) -> Vec3 {
    let ls = sample_light(scene, params.light_sampling, rng);
    let g = geometry_term(s.p, s.ns, ls.p, ls.n);
    if g <= 0.0 || !s.leaves(ls.p - s.p) {
        return Vec3::ZERO;
    }
    *rays += 1;
    if !scene.visible(s.p, s.n, ls.p, ls.n) {
        return Vec3::ZERO;
    }
    let mut weight = 1.0;
    if mis {
        let to_light = ls.p - s.p;
        let dir = to_light.normalize();
        let light_pdf = ls.pdf_area * to_light.length_squared() / -ls.n.dot(dir);
        weight = power_heuristic(light_pdf, s.ns.dot(dir) / PI);
    }
    (albedo / PI) * ls.emission * (g / ls.pdf_area * weight)
}

/// Follow a path from `state` to its end; `rays` counts traced rays (segments and shadow
/// rays).
pub fn trace_path(
    scene: &SceneBuffers,
    params: &FrameParams,
    state: PathState,
    rng: &mut Rng,
    strategy: u32,
    rays: &mut u32,
) -> Vec3 {
    let mut radiance = Vec3::ZERO;
    let mut st = state;
    let has_lights = !scene.lights.is_empty();
    while st.depth <= params.max_depth {
        let hit = scene.closest_hit(&st.ray, f32::INFINITY);
        *rays += 1;
        if !hit.is_hit() {
            radiance += st.throughput * vec3(params.sky);
            break;
        }
        let s = surface_hit(scene, &st.ray, &hit);
        let material = scene.material_of(hit.prim);

        // Emission reached by this segment.
        if s.front_face && material.is_emissive() {
            let weight = if st.depth == 1 || strategy == BSDF {
                1.0
            } else if strategy == MIS {
                let cos_light = -s.n.dot(st.ray.dir);
                let light_pdf =
                    light_pdf_area(scene, params.light_sampling, hit.prim) * hit.t * hit.t
                        / cos_light.max(1e-12);
                power_heuristic(st.bsdf_pdf, light_pdf)
            } else {
                0.0 // NEE and RIS already counted it as direct light
            };
            radiance += st.throughput * material.emission() * weight;
        }
        if st.depth == params.max_depth {
            break;
        }
        let albedo = scene.albedo(&s);
        if strategy != BSDF && has_lights {
            let direct = if strategy == RIS && st.depth == 1 {
                ris::direct_ris(scene, params, &s, albedo, rng, rays)
            } else {
                direct_nee(scene, params, &s, albedo, strategy == MIS, rng, rays)
            };
            radiance += st.throughput * direct;
        }
        if !st.bounce(&s, albedo, params, rng) {
            break;
        }
    }
    radiance
}

pub fn render_pixel(
    scene: &SceneBuffers,
    params: &FrameParams,
    x: u32,
    y: u32,
    strategy: u32,
) -> PixelResult {
    crate::integrators::accumulate_samples(params, x, y, |ray, rng, rays| {
        trace_path(scene, params, PathState::camera(ray), rng, strategy, rays)
    })
}

/// The per-pixel functions of the path integrators' image kernels (`--integrator pt`,
/// `nee`, `mis`, `ris`), called by their SPIR-V entry points and by the CPU backend.
pub fn pt_pixel(scene: &SceneBuffers, params: &FrameParams, x: u32, y: u32) -> PixelResult {
    render_pixel(scene, params, x, y, BSDF)
}
pub fn nee_pixel(scene: &SceneBuffers, params: &FrameParams, x: u32, y: u32) -> PixelResult {
    render_pixel(scene, params, x, y, NEE)
}
pub fn mis_pixel(scene: &SceneBuffers, params: &FrameParams, x: u32, y: u32) -> PixelResult {
    render_pixel(scene, params, x, y, MIS)
}
pub fn ris_pixel(scene: &SceneBuffers, params: &FrameParams, x: u32, y: u32) -> PixelResult {
    render_pixel(scene, params, x, y, RIS)
}
