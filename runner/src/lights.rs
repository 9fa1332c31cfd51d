//! The light table: every emissive triangle, with an alias table (Vose 1991) that picks
//! lights in proportion to their emitted power in O(1).
use glam::Vec3;
use kernels::math::luminance;
use kernels::types::{Light, Material, Triangle, INVALID};

/// Power of an emissive triangle up to a constant: luminance of Ke times area (a
/// Lambertian emitter radiates π · Le · area).
pub fn power(tri: &Triangle, materials: &[Material]) -> f32 {
    luminance(Vec3::from(materials[tri.material as usize].emission)) * tri.area()
}

/// Build the light table for `triangles` and write each emitter's table index into its
/// `light` field (INVALID elsewhere).
pub fn build_light_table(triangles: &mut [Triangle], materials: &[Material]) -> Vec<Light> {
    let mut lights: Vec<Light> = Vec::new();
    for (i, t) in triangles.iter_mut().enumerate() {
        t.light = INVALID;
        if materials[t.material as usize].is_emissive() {
            t.light = lights.len() as u32;
            lights.push(Light {
                triangle: i as u32,
                ..Default::default()
            });
        }
    }
    let n = lights.len();
    if n == 0 {
        return lights;
    }
    let powers: Vec<f64> = lights
        .iter()
        .map(|l| power(&triangles[l.triangle as usize], materials) as f64)
        .collect();
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
