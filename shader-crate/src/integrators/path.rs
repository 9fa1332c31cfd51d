//! Path tracing with several strategies in one loop, so each term is written once:
//! - `BSDF` (`--integrator pt`): the course's loop; emission counts when a path hits it.
//! - `NEE`: at every vertex a light point is sampled and joined with a shadow ray; emission
//!   hit by a bounce is then not counted again (only what the camera sees directly).
//! - `MIS`: both, weighted by the power heuristic, so small and large lights are both
//!   handled well.
//! - `RIS`: like NEE, but the direct light at the first vertex comes from resampled
//!   importance sampling (`ris.rs`).
//!
//! Surfaces are two-sided with the BSDFs of `bsdf.rs`, lights one-sided, the sky a
//! constant radiance.
use crate::bsdf::{Bsdf, BSDF_DIFFUSE};
use crate::bvh::{surface_hit, SceneBuffers, SurfaceHit};
use crate::env::{escaped_radiance, infinite_pdf, sample_infinite, unsampled_radiance};
use crate::glam::Vec3;
use crate::integrators::ris::{self, ShadingPoint};
use crate::integrators::PixelResult;
use crate::intersect::Ray;
use crate::lights::{light_pdf_area, power_heuristic, sample_light};
use crate::math::{vec3, PI};
use crate::rng::Rng;
use crate::sampling::local_to_world;
use crate::types::{FrameParams, INVALID};

pub const BSDF: u32 = 0;
pub const NEE: u32 = 1;
pub const MIS: u32 = 2;
pub const RIS: u32 = 3;

/// Russian roulette never keeps a path with probability above this: even a white surface
/// ends its paths eventually (and the survivors' weight 1/q stays bounded).
const MAX_SURVIVAL: f32 = 0.95;

/// Where a path stands: the ray it continues along, the product of BSDF · cos / pdf so
/// far, the number of the segment `ray` is, the solid-angle density of the BSDF sample
/// that produced `ray` (MIS weights the emission it reaches), and whether that sample came
/// from a delta lobe (a mirror or smooth glass: no light sample could have found what it
/// reaches, so emission counts in full).
#[derive(Copy, Clone, Debug)]
pub struct PathState {
    pub ray: Ray,
    pub throughput: Vec3,
    pub depth: u32,
    pub bsdf_pdf: f32,
    pub delta: bool,
    /// The vertex `ray` left sampled the environment map and sun by NEE (so what of them the
    /// ray finds is weighted against that, by MIS or not at all).
    pub env_sampled: bool,
}

impl PathState {
    pub fn camera(ray: Ray) -> Self {
        Self {
            ray,
            throughput: Vec3::ONE,
            depth: 1,
            bsdf_pdf: 0.0,
            delta: false,
            env_sampled: false,
        }
    }

    /// Continue from surface `s` by sampling its BSDF: throughput *= f · cos / pdf (for a
    /// Lambertian surface, cosine sampling leaves the albedo: the course's update). Draws
    /// two numbers, a third only for BSDFs that choose between lobes. Returns false when
    /// the sample fails or Russian roulette ends the path.
    pub fn bounce(
        &mut self,
        s: &SurfaceHit,
        bsdf: &Bsdf,
        params: &FrameParams,
        rng: &mut Rng,
    ) -> bool {
        let (u1, u2) = (rng.next_f32(), rng.next_f32());
        let u3 = if bsdf.chooses_lobes() {
            rng.next_f32()
        } else {
            0.0
        };
        // A Lambertian lobe ignores where the path came from: skip the frame change.
        let wo = if bsdf.kind == BSDF_DIFFUSE {
            Vec3::Z
        } else {
            s.to_local(-self.ray.dir)
        };
        let sample = bsdf.sample(wo, u1, u2, u3);
        let dir = local_to_world(sample.wi, s.ns);
        if !sample.is_valid() || !s.leaves(dir) {
            return false;
        }
        self.bsdf_pdf = sample.pdf;
        self.delta = sample.delta;
        self.throughput *= sample.weight;
        if self.depth >= params.rr_depth {
            let q = self.throughput.max_element().min(MAX_SURVIVAL);
            if rng.next_f32() >= q {
                return false;
            }
            self.throughput /= q;
        }
        self.ray = Ray::new(s.origin_towards(dir), dir);
        self.depth += 1;
        true
    }
}

/// Probability that NEE samples the map or the sun; 0 in the kernels for plain scenes
/// (see `trace_path`), which then carry none of their code.
pub fn infinite_probability<const PLAIN: bool>(params: &FrameParams) -> f32 {
    if PLAIN {
        0.0
    } else {
        params.env_light_probability + params.sun_light_probability
    }
}

/// f · |cos| toward `dir` and the BSDF's density for it; a Lambertian surface needs no
/// shading frame for them.
fn bsdf_toward(s: &SurfaceHit, bsdf: &Bsdf, wo: Vec3, dir: Vec3) -> (Vec3, f32) {
    if bsdf.kind == BSDF_DIFFUSE {
        let cos = s.ns.dot(dir).max(0.0);
        (bsdf.albedo * (cos / PI), cos / PI)
    } else {
        let (wo, wi) = (s.to_local(wo), s.to_local(dir));
        (bsdf.eval(wo, wi), bsdf.pdf(wo, wi))
    }
}

/// Direct light at surface `s` (viewed from `wo`) by next-event estimation: one light
/// sample — a point on an emissive triangle, or (with the probabilities in `params`) a
/// direction of the environment map or of the sun — and one shadow ray.
/// With `mis`, weighted against BSDF sampling by the power heuristic.
#[allow(clippy::too_many_arguments)] // the estimator's inputs, each used once
pub fn direct_nee<const PLAIN: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    s: &SurfaceHit,
    bsdf: &Bsdf,
    wo: Vec3,
    mis: bool,
    rng: &mut Rng,
    rays: &mut u32,
) -> Vec3 {
    // The map and the sun are one light here (their mixture); a number for the choice only
    // when there is one to make: scenes without them keep their random streams.
    let p_infinite = infinite_probability::<PLAIN>(params);
    let u_choice = if p_infinite > 0.0 {
        rng.next_f32()
    } else {
        1.0
    };
    if u_choice < p_infinite {
        let (dir, light_pdf) =
            sample_infinite(scene, params, u_choice, rng.next_f32(), rng.next_f32());
        if light_pdf <= 0.0 || !s.leaves(dir) {
            return Vec3::ZERO;
        }
        let (f, bsdf_pdf) = bsdf_toward(s, bsdf, wo, dir);
        if f == Vec3::ZERO {
            return Vec3::ZERO;
        }
        *rays += 1;
        if scene.any_hit::<PLAIN>(&Ray::new(s.origin_towards(dir), dir), f32::INFINITY) {
            return Vec3::ZERO;
        }
        let weight = if mis {
            power_heuristic(light_pdf, bsdf_pdf)
        } else {
            1.0
        };
        return f * escaped_radiance(scene, params, dir) * (weight / light_pdf);
    }
    let ls = sample_light(scene, params.light_sampling, rng);
    let to_light = ls.p - s.p;
    let dist2 = to_light.length_squared();
    let dir = to_light / crate::math::sqrt(dist2);
    let cos_light = -ls.n.dot(dir);
    if cos_light <= 0.0 || dist2 == 0.0 || !s.leaves(dir) {
        return Vec3::ZERO;
    }
    let (f, bsdf_pdf) = bsdf_toward(s, bsdf, wo, dir);
    if f == Vec3::ZERO {
        return Vec3::ZERO;
    }
    *rays += 1;
    if !scene.visible::<PLAIN>(s.p, s.n, ls.p, ls.n) {
        return Vec3::ZERO;
    }
    let pdf_area = ls.pdf_area * (1.0 - p_infinite);
    let mut weight = 1.0;
    if mis {
        let light_pdf = pdf_area * dist2 / cos_light;
        weight = power_heuristic(light_pdf, bsdf_pdf);
    }
    f * ls.emission * (cos_light / dist2 / pdf_area * weight)
}

/// Follow a path from `state` to its end; `rays` counts traced rays (segments and shadow
/// rays). `ALL_DIFFUSE` is a promise of a plain scene: every material Lambertian and
/// untextured, and no environment map or sun (a constant sky at most). The kernel then
/// carries none of the other lobes', the texture lookup's or the map's and sun's sampling
/// code, whose registers cost plain scenes 5–40% (measured on the H100).
pub fn trace_path<const ALL_DIFFUSE: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    state: PathState,
    rng: &mut Rng,
    strategy: u32,
    rays: &mut u32,
) -> Vec3 {
    let mut radiance = Vec3::ZERO;
    let mut st = state;
    let p_infinite = infinite_probability::<ALL_DIFFUSE>(params);
    let has_lights = !scene.lights.is_empty() || p_infinite > 0.0;
    while st.depth <= params.max_depth {
        let hit = scene.closest_hit::<ALL_DIFFUSE>(&st.ray, f32::INFINITY);
        *rays += 1;
        if !hit.is_hit() {
            if ALL_DIFFUSE {
                radiance += st.throughput * vec3(params.sky); // a constant sky: never sampled
                break;
            }
            // The map's and the sun's light, weighed against their sampling at the vertex
            // the ray left; a constant sky is never sampled and counts in full.
            let weight = if st.depth == 1 || strategy == BSDF || st.delta || !st.env_sampled {
                1.0
            } else if strategy == MIS {
                power_heuristic(st.bsdf_pdf, infinite_pdf(scene, params, st.ray.dir))
            } else {
                0.0 // NEE sampled the map there already
            };
            let unsampled = unsampled_radiance(params);
            let sampled = escaped_radiance(scene, params, st.ray.dir) - unsampled;
            radiance += st.throughput * (unsampled + sampled * weight);
            break;
        }
        let s = surface_hit(scene, &st.ray, &hit);
        let material = scene.material_of(hit.prim);

        // Emission reached by this segment.
        if s.front_face && material.is_emissive() {
            let weight = if st.depth == 1 || strategy == BSDF || st.delta {
                1.0
            } else if strategy == MIS {
                let cos_light = -s.n.dot(st.ray.dir);
                let light_pdf = light_pdf_area(scene, params.light_sampling, hit.prim)
                    * (1.0 - p_infinite)
                    * hit.t
                    * hit.t
                    / cos_light.max(1e-12);
                power_heuristic(st.bsdf_pdf, light_pdf)
            } else {
                0.0 // NEE and RIS already counted it as direct light
            };
            // Untextured emission needs no second look at the triangle.
            let le = if ALL_DIFFUSE || material.emission_texture == INVALID {
                material.emission()
            } else {
                scene.emission_at(&scene.triangles[hit.prim as usize], hit.b1, hit.b2)
            };
            radiance += st.throughput * le * weight;
        }
        if st.depth == params.max_depth {
            break;
        }
        let bsdf = if ALL_DIFFUSE {
            // Untextured too (see `Scene::plain_materials`): no texture lookup's registers.
            Bsdf::diffuse(material.albedo())
        } else {
            scene.surface_bsdf(&material, &s)
        };
        let wo = -st.ray.dir;
        // A delta BSDF has nothing for a light sample to find: its bounce finds the light.
        let sample_lights = strategy != BSDF && has_lights && !bsdf.is_delta();
        // RIS at the first vertex (emissive triangles, the map and the sun), NEE elsewhere.
        let ris_here = strategy == RIS && st.depth == 1;
        st.env_sampled = sample_lights && p_infinite > 0.0;
        if sample_lights {
            let direct = if ris_here {
                ris::direct_ris::<ALL_DIFFUSE>(
                    scene,
                    params,
                    &ShadingPoint::new(&s, wo, bsdf),
                    rng,
                    rays,
                )
            } else {
                direct_nee::<ALL_DIFFUSE>(scene, params, &s, &bsdf, wo, strategy == MIS, rng, rays)
            };
            radiance += st.throughput * direct;
        }
        if !st.bounce(&s, &bsdf, params, rng) {
            break;
        }
    }
    radiance
}

pub fn render_pixel<const ALL_DIFFUSE: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    x: u32,
    y: u32,
    strategy: u32,
) -> PixelResult {
    crate::integrators::accumulate_samples(params, x, y, |ray, rng, rays| {
        trace_path::<ALL_DIFFUSE>(scene, params, PathState::camera(ray), rng, strategy, rays)
    })
}

/// The per-pixel functions of the path integrators' image kernels (`--integrator pt`,
/// `nee`, `mis`, `ris`), called by their SPIR-V entry points and by the CPU backend, each
/// in a general and an all-Lambertian variant (see `trace_path`).
pub fn pt_pixel<const ALL_DIFFUSE: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    x: u32,
    y: u32,
) -> PixelResult {
    render_pixel::<ALL_DIFFUSE>(scene, params, x, y, BSDF)
}
pub fn nee_pixel<const ALL_DIFFUSE: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    x: u32,
    y: u32,
) -> PixelResult {
    render_pixel::<ALL_DIFFUSE>(scene, params, x, y, NEE)
}
pub fn mis_pixel<const ALL_DIFFUSE: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    x: u32,
    y: u32,
) -> PixelResult {
    render_pixel::<ALL_DIFFUSE>(scene, params, x, y, MIS)
}
pub fn ris_pixel<const ALL_DIFFUSE: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    x: u32,
    y: u32,
) -> PixelResult {
    render_pixel::<ALL_DIFFUSE>(scene, params, x, y, RIS)
}
