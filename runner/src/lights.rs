//! The light table: every emissive triangle, with an alias table (Vose 1991) that picks
//! lights in proportion to their emitted power in O(1).
use glam::Vec3;
use kernels::bvh::SceneBuffers;
use kernels::math::luminance;
use kernels::types::{Light, Material, Triangle, INVALID};

use crate::scene::SurfaceAttributes;

/// Points per side of the grid on which a textured emitter's radiance is averaged.
const POWER_GRID: usize = 4;
/// A textured emitter's power is at least this share of its factor's: a bright spot
/// between the grid's points must still be sampled (a selection probability of 0 would
/// lose its light).
const MIN_TEXTURED_POWER: f32 = 0.01;

/// Power of emissive triangle `triangle` up to a constant: the luminance of its emitted
/// radiance averaged over the triangle, times its area (a Lambertian emitter radiates
/// π · Le · area). Textured emission is averaged on a grid of points.
pub fn power(scene: &SceneBuffers, triangle: u32) -> f32 {
    let tri = &scene.triangle(triangle);
    let m = &scene.materials[tri.material as usize];
    let factor = luminance(Vec3::from(m.emission));
    if m.emission_texture == INVALID {
        return factor * tri.area();
    }
    let mut sum = 0.0;
    for i in 0..POWER_GRID {
        for j in 0..POWER_GRID {
            let (u, v) = (
                (i as f32 + 0.5) / POWER_GRID as f32,
                (j as f32 + 0.5) / POWER_GRID as f32,
            );
            let (b1, b2) = if u + v > 1.0 {
                (1.0 - u, 1.0 - v)
            } else {
                (u, v)
            };
            sum += luminance(scene.emission_at(tri, b1, b2));
        }
    }
    let mean = sum / (POWER_GRID * POWER_GRID) as f32;
    mean.max(MIN_TEXTURED_POWER * factor) * tri.area()
}

/// Build the light table for `triangles` (in leaf order: slot i holds input triangle
/// `order[i]`) and write each emitter's table index into its `light` field (INVALID
/// elsewhere). The table lists the emitters in input order, so that the same random
/// numbers pick the same emitter whatever BVH put the triangles in their slots: NEE's
/// images do not depend on the tree.
pub fn build_light_table(
    triangles: &mut [Triangle],
    order: &[u32],
    materials: &[Material],
    attributes: &SurfaceAttributes,
) -> Vec<Light> {
    let mut emitters: Vec<u32> = Vec::new();
    for (i, t) in triangles.iter_mut().enumerate() {
        t.light = INVALID;
        if materials[t.material as usize].is_emissive() {
            emitters.push(i as u32);
        }
    }
    // Emitters are never split (`accel::build`'s `splittable`): one slot each.
    emitters.sort_unstable_by_key(|&slot| order[slot as usize]);
    let mut lights: Vec<Light> = Vec::with_capacity(emitters.len());
    for slot in emitters {
        triangles[slot as usize].light = lights.len() as u32;
        lights.push(Light {
            triangle: slot,
            ..Default::default()
        });
    }
    let view = SceneBuffers {
        triangles: bytemuck::cast_slice(triangles),
        materials,
        nodes: &[],
        lights: &[],
        shading: &attributes.shading,
        textures: &attributes.textures,
        texels: &attributes.texels,
        env_distribution: &[],
    };
    let powers: Vec<f64> = lights
        .iter()
        .map(|l| power(&view, l.triangle) as f64)
        .collect();
    let n = lights.len();
    if n == 0 {
        return lights;
    }
    let total: f64 = powers.iter().sum();
    let pdfs: Vec<f64> = if total > 0.0 && total.is_finite() {
        powers.iter().map(|p| p / total).collect()
    } else {
        vec![1.0 / n as f64; n]
    };
    // Vose: split slots into under- and over-full, let each under-full slot borrow from an
    // over-full one.
    let mut scaled: Vec<f64> = pdfs.iter().map(|p| p * n as f64).collect();
    let (mut small, mut large): (Vec<usize>, Vec<usize>) = (0..n).partition(|&i| scaled[i] < 1.0);
    while let (Some(&s), Some(&l)) = (small.last(), large.last()) {
        small.pop();
        lights[s].threshold = scaled[s] as f32;
        lights[s].alias = l as u32;
        scaled[l] -= 1.0 - scaled[s];
        if scaled[l] < 1.0 {
            large.pop();
            small.push(l);
        }
    }
    // Whatever is left is full up to rounding.
    for i in small.into_iter().chain(large) {
        lights[i].threshold = 1.0;
        lights[i].alias = i as u32;
    }
    for (l, p) in lights.iter_mut().zip(&pdfs) {
        l.pdf = *p as f32;
    }
    lights
}
