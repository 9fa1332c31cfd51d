//! Emitters: picking a light triangle (uniformly, as in the course, or in proportion to
//! power with an alias table), a uniform point on it, and the pdfs that NEE and MIS need.
use crate::bvh::SceneBuffers;
use crate::glam::Vec3;
use crate::rng::Rng;
use crate::sampling::uniform_triangle;
use crate::types::{load, Light, LIGHT_SAMPLING_UNIFORM};

/// A point on an emitter, with everything the estimators need.
#[derive(Copy, Clone, Debug)]
pub struct LightSample {
    pub p: Vec3,
    /// Unit front-face normal (the emitting side).
    pub n: Vec3,
    pub emission: Vec3,
    /// Density of this point w.r.t. area: p(triangle) / area.
    pub pdf_area: f32,
    pub triangle: u32,
    /// Barycentrics of `p` on the triangle (reservoirs store these).
    pub b1: f32,
    pub b2: f32,
}

/// Index into `lights` by the chosen mode, from a uniform 32-bit number `u_slot` and a
/// uniform `u_coin` in [0, 1). The slot is the high word of `u_slot · n` (exact for any
/// number of lights: each slot gets ⌊2³²/n⌋ or ⌈2³²/n⌉ of the 2³² values) and the alias
/// coin is a number of its own, so that with 2¹⁶+ lights the coin keeps its full 24 bits
/// (drawing both from one f32 left it 24 − log2(n) bits, and the selection drifted far
/// from the stored pdfs).
pub fn select_light(lights: &[Light], mode: u32, u_slot: u32, u_coin: f32) -> u32 {
    let i = crate::math::mul_hi(u_slot, lights.len() as u32);
    if mode == LIGHT_SAMPLING_UNIFORM {
        return i;
    }
    // Alias method: one table lookup, O(1) whatever the number of lights.
    let entry = load(lights, i as usize);
    if u_coin < entry.threshold {
        i
    } else {
        entry.alias
    }
}

/// Probability that `select_light` picks light `index`.
pub fn selection_pdf(lights: &[Light], mode: u32, index: u32) -> f32 {
    if mode == LIGHT_SAMPLING_UNIFORM {
        1.0 / lights.len() as f32
    } else {
        load(lights, index as usize).pdf
    }
}

/// Pick a light triangle and a uniform point on it (four draws from `rng`).
pub fn sample_light(scene: &SceneBuffers, mode: u32, rng: &mut Rng) -> LightSample {
    let index = select_light(scene.lights, mode, rng.next_u32(), rng.next_f32());
    sample_on_light(scene, mode, index, rng)
}

/// A uniform point on light `index` of the table, chosen by `select_light` (two draws
/// from `rng`).
pub fn sample_on_light(scene: &SceneBuffers, mode: u32, index: u32, rng: &mut Rng) -> LightSample {
    let triangle = load(scene.lights, index as usize).triangle;
    let tri = scene.triangle(triangle);
    let (b1, b2) = uniform_triangle(rng.next_f32(), rng.next_f32());
    let cross = tri.cross();
    let area = 0.5 * cross.length();
    LightSample {
        p: tri.point(b1, b2),
        n: cross / (2.0 * area),
        emission: scene.emission_at(&tri, b1, b2),
        pdf_area: selection_pdf(scene.lights, mode, index) / area,
        triangle,
        b1,
        b2,
    }
}

/// Area density with which `sample_light` produces a point on `triangle` (an emitter).
pub fn light_pdf_area(scene: &SceneBuffers, mode: u32, triangle: u32) -> f32 {
    let tri = scene.triangle(triangle);
    selection_pdf(scene.lights, mode, tri.light) / tri.area()
}

/// The geometry term between a surface point (p, n) and a light point (q, nq):
/// cos θ_p · cos θ_q / |p − q|², zero unless each faces the other (lights are one-sided).
pub fn geometry_term(p: Vec3, n: Vec3, q: Vec3, nq: Vec3) -> f32 {
    let d = q - p;
    let dist2 = d.length_squared();
    let w = d / crate::math::sqrt(dist2);
    let cos_p = n.dot(w);
    let cos_q = -nq.dot(w);
    if cos_p <= 0.0 || cos_q <= 0.0 || dist2 == 0.0 {
        return 0.0;
    }
    cos_p * cos_q / dist2
}

/// Veach's power heuristic (β = 2) for the strategy with density `a` against `b`.
pub fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 == 0.0 {
        0.0
    } else {
        a2 / (a2 + b2)
    }
}
