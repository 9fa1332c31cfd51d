//! Path tracing with three strategies in one loop, so each term is written once:
//! - `BSDF` (`--integrator pt`): the course's loop; emission counts when a path hits it.
//! - `NEE`: at every vertex a light point is sampled and joined with a shadow ray; emission
//!   hit by a bounce is then not counted again (only what the camera sees directly).
//! - `MIS`: both, weighted by the power heuristic, so small and large lights are both
//!   handled well.
//! Surfaces are two-sided Lambertian, lights one-sided, the sky a constant radiance.
use crate::bvh::{offset_ray_origin, surface_hit, Scene};
use crate::glam::Vec3;
use crate::integrators::PixelResult;
use crate::intersect::Ray;
use crate::lights::{geometry_term, light_pdf_area, power_heuristic, sample_light};
use crate::math::PI;
use crate::rng::Rng;
use crate::sampling::{cosine_hemisphere, local_to_world};
use crate::types::FrameParams;

pub const BSDF: u32 = 0;
pub const NEE: u32 = 1;
pub const MIS: u32 = 2;

/// Radiance along `ray` estimated with the given strategy; `rays` counts traced rays
/// (path segments and shadow rays).
pub fn path_radiance(
    scene: &Scene,
    params: &FrameParams,
    ray: Ray,
    rng: &mut Rng,
    strategy: u32,
    rays: &mut u32,
) -> Vec3 {
    let mut radiance = Vec3::ZERO;
    let mut throughput = Vec3::ONE;
    let mut ray = ray;
    // Solid-angle density of the BSDF sample that produced `ray` (MIS weights emission).
    let mut bsdf_pdf = 0.0f32;
    let has_lights = !scene.lights.is_empty();
    let mut depth = 1u32;
    while depth <= params.max_depth {
        let hit = scene.closest_hit(&ray, f32::INFINITY);
        *rays += 1;
        if !hit.is_hit() {
            radiance += throughput * crate::math::vec3(params.sky);
            break;
        }
        let s = surface_hit(scene.triangles, &ray, &hit);
        let material = scene.material_of(hit.prim);

        // Emission reached by this segment.
        if s.front_face && material.is_emissive() {
            let weight = if depth == 1 || strategy == BSDF {
                1.0
            } else if strategy == NEE {
                0.0
            } else {
                let cos_light = -s.n.dot(ray.dir);
                let light_pdf = light_pdf_area(scene, params.light_sampling, hit.prim) * hit.t * hit.t
                    / cos_light.max(1e-12);
                power_heuristic(bsdf_pdf, light_pdf)
            };
            radiance += throughput * material.emission() * weight;
        }
        if depth == params.max_depth {
            break;
        }
        let albedo = material.albedo();

        // Next-event estimation: one light point, one shadow ray.
        if strategy != BSDF && has_lights {
            let ls = sample_light(scene, params.light_sampling, rng.next_f32(), rng.next_f32(), rng.next_f32());
            let g = geometry_term(s.p, s.n, ls.p, ls.n);
            if g > 0.0 {
                let origin = offset_ray_origin(s.p, s.n);
                let target = offset_ray_origin(ls.p, ls.n);
                let to_light = target - origin;
                let dist = to_light.length();
                let shadow = Ray::new(origin, to_light / dist);
                *rays += 1;
                if !scene.any_hit(&shadow, dist * 0.9999) {
                    let mut weight = 1.0;
                    if strategy == MIS {
                        let dir = (ls.p - s.p).normalize();
                        let cos_light = -ls.n.dot(dir);
                        let light_pdf = ls.pdf_area * (ls.p - s.p).length_squared() / cos_light;
                        weight = power_heuristic(light_pdf, s.n.dot(dir) / PI);
                    }
                    radiance += throughput * (albedo / PI) * ls.emission * (g / ls.pdf_area * weight);
                }
            }
        }

        // Continue the path: cosine sampling cancels cos/π against the Lambertian BRDF,
        // leaving throughput *= albedo (the course's update).
        let local = cosine_hemisphere(rng.next_f32(), rng.next_f32());
        bsdf_pdf = local.z / PI;
        throughput *= albedo;
        if depth >= params.rr_depth {
            let q = throughput.max_element().min(0.95);
            if rng.next_f32() >= q {
                break;
            }
            throughput /= q;
        }
        ray = Ray::new(offset_ray_origin(s.p, s.n), local_to_world(local, s.n));
        depth += 1;
    }
    radiance
}

pub fn render_pixel(scene: &Scene, params: &FrameParams, x: u32, y: u32, strategy: u32) -> PixelResult {
    crate::integrators::accumulate_samples(params, x, y, |ray, rng, rays| {
        path_radiance(scene, params, ray, rng, strategy, rays)
    })
}
