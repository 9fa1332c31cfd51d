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
use crate::bvh::{shadow_ray, surface_hit, SceneBuffers, SurfaceHit};
use crate::camera::pixel_spread;
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
    /// The length of the path from the camera to `ray`'s origin: with the pixel's spread
    /// it widens the footprint that chooses texture levels (`surface_hit`'s `cone_width`;
    /// the widening by curved or rough surfaces on the way is left out, so that textures
    /// are read sharper rather than blurrier than the footprint asks).
    pub travelled: f32,
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
            travelled: 0.0,
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

/// A light sample's shadow test still to be traced: what the sample adds if `ray` meets
/// nothing before `t_max`. `trace` is false where no ray is needed (the sample adds
/// nothing whatever it meets).
#[derive(Copy, Clone)]
pub struct ShadowTest {
    pub ray: Ray,
    pub t_max: f32,
    pub radiance: Vec3,
    pub trace: bool,
}

impl ShadowTest {
    const NONE: Self = Self {
        ray: Ray {
            origin: Vec3::ZERO,
            dir: Vec3::ZERO,
        },
        t_max: 0.0,
        radiance: Vec3::ZERO,
        trace: false,
    };
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
    let test = nee_sample::<PLAIN>(scene, params, s, bsdf, wo, mis, rng);
    if !test.trace {
        return Vec3::ZERO;
    }
    *rays += 1;
    if scene.any_hit::<PLAIN>(&test.ray, test.t_max) {
        return Vec3::ZERO;
    }
    test.radiance
}

/// `direct_nee`'s light sample and its shadow test, untraced.
pub fn nee_sample<const PLAIN: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    s: &SurfaceHit,
    bsdf: &Bsdf,
    wo: Vec3,
    mis: bool,
    rng: &mut Rng,
) -> ShadowTest {
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
            return ShadowTest::NONE;
        }
        let (f, bsdf_pdf) = bsdf_toward(s, bsdf, wo, dir);
        if f == Vec3::ZERO {
            return ShadowTest::NONE;
        }
        let weight = if mis {
            power_heuristic(light_pdf, bsdf_pdf)
        } else {
            1.0
        };
        return ShadowTest {
            ray: Ray::new(s.origin_towards(dir), dir),
            t_max: f32::INFINITY,
            radiance: f * escaped_radiance(scene, params, dir) * (weight / light_pdf),
            trace: true,
        };
    }
    let ls = sample_light(scene, params.light_sampling, rng);
    let to_light = ls.p - s.p;
    let dist2 = to_light.length_squared();
    let dir = to_light / crate::math::sqrt(dist2);
    let cos_light = -ls.n.dot(dir);
    if cos_light <= 0.0 || dist2 == 0.0 || !s.leaves(dir) {
        return ShadowTest::NONE;
    }
    let (f, bsdf_pdf) = bsdf_toward(s, bsdf, wo, dir);
    if f == Vec3::ZERO {
        return ShadowTest::NONE;
    }
    let pdf_area = ls.pdf_area * (1.0 - p_infinite);
    let mut weight = 1.0;
    if mis {
        let light_pdf = pdf_area * dist2 / cos_light;
        weight = power_heuristic(light_pdf, bsdf_pdf);
    }
    let (ray, t_max) = shadow_ray(s.p, s.n, ls.p, ls.n);
    ShadowTest {
        ray,
        t_max,
        radiance: f * ls.emission * (cos_light / dist2 / pdf_area * weight),
        trace: true,
    }
}

/// Follow a path from `state` to its end; `rays` counts traced rays (segments and shadow
/// rays). `ALL_DIFFUSE` is a promise of a plain scene: every material Lambertian and
/// untextured, and no environment map or sun (a constant sky at most). The kernel then
/// carries none of the other lobes', the texture lookup's or the map's and sun's sampling
/// code, whose registers cost plain scenes 5–40% (measured on the H100). `STRATEGY` (`BSDF`,
/// `NEE`, `MIS`, `RIS`) is a constant for the same reason: `pt`'s kernel carries no light
/// sampling and no any-hit traversal.
pub fn trace_path<const ALL_DIFFUSE: bool, const STRATEGY: u32>(
    scene: &SceneBuffers,
    params: &FrameParams,
    state: PathState,
    rng: &mut Rng,
    rays: &mut u32,
) -> Vec3 {
    let mut radiance = Vec3::ZERO;
    let mut st = state;
    let p_infinite = infinite_probability::<ALL_DIFFUSE>(params);
    let has_lights = !scene.lights.is_empty() || p_infinite > 0.0;
    let spread = pixel_spread(&params.camera, params.height);
    // A vertex's NEE shadow ray is traced by the next turn of the loop, before the path's
    // next segment: one traversal call site for both kinds of ray, so the kernel holds one
    // inlined traversal and its stack, and a warp's threads with a shadow ray and those
    // without one (no light sample to test) run the same traversal loop together. The
    // radiance is summed in the same order as tracing each where it arises would.
    let mut shadow = ShadowTest::NONE;
    let mut ended = false;
    loop {
        // (Never for `pt`: its kernel keeps the closest-hit traversal alone.)
        let any = STRATEGY != BSDF && shadow.trace;
        if !any && (ended || st.depth > params.max_depth) {
            break;
        }
        let (ray, t_max) = if any {
            (shadow.ray, shadow.t_max)
        } else {
            (st.ray, f32::INFINITY)
        };
        let hit = scene.trace::<ALL_DIFFUSE>(&ray, t_max, any);
        *rays += 1;
        if any {
            if !hit.is_hit() {
                radiance += shadow.radiance;
            }
            shadow.trace = false;
            continue;
        }
        if !hit.is_hit() {
            if ALL_DIFFUSE {
                radiance += st.throughput * vec3(params.sky); // a constant sky: never sampled
                break;
            }
            // The map's and the sun's light, weighed against their sampling at the vertex
            // the ray left; a constant sky is never sampled and counts in full.
            let weight = if st.depth == 1 || STRATEGY == BSDF || st.delta || !st.env_sampled {
                1.0
            } else if STRATEGY == MIS {
                power_heuristic(st.bsdf_pdf, infinite_pdf(scene, params, st.ray.dir))
            } else {
                0.0 // NEE sampled the map there already
            };
            let unsampled = unsampled_radiance(params);
            let sampled = escaped_radiance(scene, params, st.ray.dir) - unsampled;
            radiance += st.throughput * (unsampled + sampled * weight);
            break;
        }
        st.travelled += hit.t;
        let s = surface_hit(scene, &st.ray, &hit, spread * st.travelled);
        let material = scene.material_of(hit.prim);

        // Emission reached by this segment.
        if s.front_face && material.is_emissive() {
            let weight = if st.depth == 1 || STRATEGY == BSDF || st.delta {
                1.0
            } else if STRATEGY == MIS {
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
                scene.emission_at(&scene.triangle(hit.prim), hit.b1, hit.b2)
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
        let sample_lights = STRATEGY != BSDF && has_lights && !bsdf.is_delta();
        // RIS at the first vertex (emissive triangles, the map and the sun), NEE elsewhere.
        let ris_here = STRATEGY == RIS && st.depth == 1;
        st.env_sampled = sample_lights && p_infinite > 0.0;
        if sample_lights && ris_here {
            let direct = ris::direct_ris::<ALL_DIFFUSE>(
                scene,
                params,
                &ShadingPoint::new(&s, wo, bsdf),
                rng,
                rays,
            );
            radiance += st.throughput * direct;
        } else if sample_lights {
            shadow = nee_sample::<ALL_DIFFUSE>(scene, params, &s, &bsdf, wo, STRATEGY == MIS, rng);
            shadow.radiance *= st.throughput;
        }
        if !st.bounce(&s, &bsdf, params, rng) {
            if STRATEGY == BSDF {
                break;
            }
            ended = true; // after its last shadow ray, if it has one
        }
    }
    radiance
}

pub fn render_pixel<const ALL_DIFFUSE: bool, const STRATEGY: u32>(
    scene: &SceneBuffers,
    params: &FrameParams,
    x: u32,
    y: u32,
) -> PixelResult {
    crate::integrators::accumulate_samples(params, x, y, |ray, rng, rays| {
        trace_path::<ALL_DIFFUSE, STRATEGY>(scene, params, PathState::camera(ray), rng, rays)
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
    render_pixel::<ALL_DIFFUSE, BSDF>(scene, params, x, y)
}
pub fn nee_pixel<const ALL_DIFFUSE: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    x: u32,
    y: u32,
) -> PixelResult {
    render_pixel::<ALL_DIFFUSE, NEE>(scene, params, x, y)
}
pub fn mis_pixel<const ALL_DIFFUSE: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    x: u32,
    y: u32,
) -> PixelResult {
    render_pixel::<ALL_DIFFUSE, MIS>(scene, params, x, y)
}
pub fn ris_pixel<const ALL_DIFFUSE: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    x: u32,
    y: u32,
) -> PixelResult {
    render_pixel::<ALL_DIFFUSE, RIS>(scene, params, x, y)
}
