//! How many triangles a leaf of the CWBVH may hold, chosen per scene. obvhs's conversion
//! of a binary BVH to 8-wide nodes (Ylitie et al. 2017's dynamic programme) puts up to 3
//! triangles in a leaf, pricing a triangle test at 0.3 of a node visit. On the H100 a
//! triangle test costs about 2.2 node visits: the AO walk ran its node visits at ~40 G/s
//! with its triangle tests left out and ~23 G/s with them, so they took 40–45% of its
//! time at 1.4–3.4 tests against 3.6–10.6 nodes per ray (README, "Where the time goes").
//! Leaves of one triangle test fewer of them, as each leaf box culls its own triangle, at
//! the price of more nodes where a node's 8 slots run out: forced everywhere, the
//! 1M-triangle suite's AO got 1–9% faster (grass-1m 32.0 → 29.2 ms), but the Cornell box's
//! 3.8 → 5.3 ms and its MIS 1.67 → 1.99 ms. So both trees are made from the same binary
//! BVH, and a pilot of AO-like rays from points on the surfaces, walked by the kernels'
//! own code over the GPU's nodes, keeps the 1-triangle one where it is cheaper by `MARGIN`
//! at `TRIANGLE_COST` (README, "Leaves of one triangle").
use kernels::bvh::{cwbvh_ao_walk_nodes, Cutouts, TriangleSlots};
use kernels::glam::UVec4;
use kernels::integrators::ao::AoRays;
use kernels::rng::Rng;
use kernels::sampling::{uniform_triangle, Strata};
use kernels::types::{CwBvhNode, Triangle, AO_NEAR_FIRST};
use obvhs::bvh2::Bvh2;
use obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh;
use obvhs::cwbvh::CwBvh;
use rayon::prelude::*;

/// obvhs's largest leaf (3 triangles, what a CWBVH meta byte holds) and ours.
const LEAF_SIZES: [u32; 2] = [3, 1];
/// A triangle test's cost in node visits (H100, AO; module comment).
const TRIANGLE_COST: f64 = 2.2;
/// 1-triangle leaves are kept only where the pilot finds them at least this much
/// cheaper: its rays are a sample, and the GPU follows the cost only roughly.
const MARGIN: f64 = 0.03;
/// Pilot rays: from points on the surfaces, each sending one cosine-distributed ray.
const PILOT_RAYS: u32 = 8192;
/// Bytes of working tables per binary node that one conversion takes (measured: rocks-1m,
/// 2M nodes, ~115 MB).
const CONVERSION_BYTES_PER_NODE: u64 = 64;
/// The pilot's rays are as long as AO's by default: a quarter of the scene's diagonal.
const PILOT_LENGTH: f32 = 0.25;

/// A CWBVH of `bvh2`'s leaves with the leaf size the pilot chose, the triangle in each of
/// its primitive slots, and that leaf size. `leaf_triangles(bvh)` gives the triangle in
/// each of `bvh`'s primitive slots (`triangles`' indices).
pub fn convert(
    bvh2: &Bvh2,
    triangles: &[Triangle],
    leaf_triangles: impl Fn(&CwBvh) -> Vec<u32> + Sync,
) -> (CwBvh, Vec<u32>, u32) {
    let start = std::time::Instant::now();
    let rays = pilot_rays(triangles);
    // Side by side where memory allows (each conversion runs on one thread), else one
    // after the other: a conversion's working tables (obvhs keeps 7 decisions per binary
    // node) take ~`CONVERSION_BYTES_PER_NODE`, and two at once raised the load's peak by
    // a third (rocks-1m, `fast`: 336 → 451 MB, against 359 MB one after the other, and
    // 1.0 s against 1.7 s to build on the 2-core box).
    let both = bvh2.nodes.len() as u64 * CONVERSION_BYTES_PER_NODE * LEAF_SIZES.len() as u64;
    let side_by_side = crate::memory::available_bytes().is_some_and(|a| a > 4 * both);
    let convert_and_price = |&leaf: &u32| {
        let bvh = bvh2_to_cwbvh(bvh2, leaf, true, false);
        let order = leaf_triangles(&bvh);
        let cost = pilot_cost(triangles, &bvh, &order, &rays);
        log::debug!("CWBVH leaves of {leaf}: pilot cost {cost:.3} node visits per ray");
        (cost, bvh, order, leaf)
    };
    let trees: Vec<(f64, CwBvh, Vec<u32>, u32)> = if side_by_side {
        LEAF_SIZES.par_iter().map(convert_and_price).collect()
    } else {
        LEAF_SIZES.iter().map(convert_and_price).collect()
    };
    let mut best: Option<(f64, CwBvh, Vec<u32>, u32)> = None;
    for tree in trees {
        if best
            .as_ref()
            .is_none_or(|(c, ..)| tree.0 < (1.0 - MARGIN) * c)
        {
            best = Some(tree);
        }
    }
    let (_, bvh, order, leaf) = best.expect("at least one leaf size");
    log::debug!(
        "CWBVH leaves of {leaf} chosen in {:.1} ms",
        start.elapsed().as_secs_f64() * 1e3
    );
    (bvh, order, leaf)
}

/// A pilot ray: from a point on triangle `triangle`, to `t_max`.
struct PilotRay {
    ray: kernels::intersect::Ray,
    triangle: u32,
    t_max: f32,
}

/// Rays from points on the surfaces, one each, cosine-distributed about the side of the
/// normal chosen at random (surfaces are two-sided). Every other point lies on a
/// triangle chosen by area, the rest on one chosen by index: a camera sees the large
/// triangles most, but a huge ground of two would leave few rays near the objects of
/// many small ones, where the leaf size matters. Deterministic: the same scene gets the
/// same rays.
fn pilot_rays(triangles: &[Triangle]) -> Vec<PilotRay> {
    if triangles.is_empty() {
        return Vec::new();
    }
    let mut cumulative = Vec::with_capacity(triangles.len());
    let mut total = 0.0;
    for t in triangles {
        total += t.area() as f64;
        cumulative.push(total);
    }
    if !(total > 0.0 && total.is_finite()) {
        return Vec::new();
    }
    let (lo, hi) = crate::scene::bounds_of(crate::scene::corners(triangles));
    let t_max = PILOT_LENGTH * (hi - lo).length();
    let mut rng = Rng::from_seed(0x1eaf);
    (0..PILOT_RAYS)
        .filter_map(|k| {
            let u = rng.next_f32();
            let i = if k % 2 == 0 {
                cumulative.partition_point(|&c| c <= u as f64 * total)
            } else {
                (u * triangles.len() as f32) as usize
            }
            .min(triangles.len() - 1);
            let tri = &triangles[i];
            let (b1, b2) = uniform_triangle(rng.next_f32(), rng.next_f32());
            let p = tri.point(b1, b2);
            let n = tri.normal();
            if !n.is_finite() {
                return None;
            }
            let n = if rng.next_f32() < 0.5 { n } else { -n };
            // The ray leaves its point as an AO ray does (offset off the surface).
            let rays = AoRays::new(p, i as u32, n, &mut rng);
            Some(PilotRay {
                ray: rays.ray(0, Strata::NONE),
                triangle: i as u32,
                t_max,
            })
        })
        .collect()
}

/// Slots of one tree read through its order from the scene's triangles.
struct Reordered<'a> {
    triangles: &'a [Triangle],
    order: &'a [u32],
}

impl TriangleSlots for Reordered<'_> {
    fn triangle(&self, slot: u32) -> Triangle {
        self.triangles[self.order[slot as usize] as usize]
    }
}

/// Mean cost per pilot ray of walking `bvh` (whose slots hold `order`'s triangles): node
/// visits plus `TRIANGLE_COST` per triangle test.
fn pilot_cost(triangles: &[Triangle], bvh: &CwBvh, order: &[u32], rays: &[PilotRay]) -> f64 {
    if rays.is_empty() {
        return 0.0;
    }
    let slots = Reordered { triangles, order };
    let nodes: &[CwBvhNode] = bytemuck::cast_slice(&bvh.nodes);
    let node_words: &[UVec4] = bytemuck::cast_slice(nodes);
    // Each triangle's first slot: the one its ray leaves (never tested).
    let mut slot_of = vec![kernels::types::INVALID; triangles.len()];
    for (slot, &t) in order.iter().enumerate().rev() {
        slot_of[t as usize] = slot as u32;
    }
    let cut = Cutouts::NONE;
    let sum: f64 = rays
        .iter()
        .map(|r| {
            let leaves = slot_of[r.triangle as usize];
            let (nodes, tests) = cwbvh_ao_walk_nodes::<true, CwBvhNode, _>(
                &slots,
                &cut,
                node_words,
                &r.ray,
                (leaves, r.t_max),
                AO_NEAR_FIRST,
            );
            nodes as f64 + TRIANGLE_COST * tests as f64
        })
        .sum();
    sum / rays.len() as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use obvhs::aabb::Aabb;
    use obvhs::ploc::{PlocBuilder, PlocSearchDistance, SortPrecision};

    fn chosen_leaf(triangles: &[Triangle]) -> u32 {
        let boxes: Vec<Aabb> = triangles
            .iter()
            .map(|t| {
                let (a, b, c) = t.vertices();
                let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
                Aabb::new(lo.to_array().into(), hi.to_array().into())
            })
            .collect();
        let bvh2 = PlocBuilder::with_capacity(boxes.len()).build(
            PlocSearchDistance::Medium,
            &boxes,
            (0..boxes.len() as u32).collect(),
            SortPrecision::U64,
            1,
        );
        let (bvh, order, leaf) = convert(&bvh2, triangles, |cw| cw.primitive_indices.clone());
        let mut seen = order.clone();
        seen.sort_unstable();
        seen.dedup();
        assert_eq!(seen.len(), triangles.len(), "every triangle in a slot");
        assert_eq!(order.len(), bvh.primitive_indices.len());
        leaf
    }

    /// The two scenes the GPU measured both ways (H100): the Cornell box's AO 3.8 → 5.3
    /// ms and its MIS 1.67 → 1.99 ms with leaves of one triangle, rocks' AO 11.96 →
    /// 11.41 ms (rocks-1m; rocks-20k's pilot picks the same way).
    #[test]
    fn the_pilot_picks_what_the_gpu_measured_faster() {
        let cornell = crate::scene::cornell_box().expect("built-in scene");
        assert_eq!(chosen_leaf(&cornell.triangles), 3);
        assert_eq!(chosen_leaf(&crate::generate::rocks(20_000).triangles), 1);
    }
}
