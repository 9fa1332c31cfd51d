//! The binary BVH collapsed into the CWBVH's 8-wide nodes, priced at what the GPU pays.
//!
//! Ylitie et al. 2017's dynamic programme chooses, subtree by subtree, whether a binary
//! subtree becomes a leaf of up to 3 triangles, a wide node, or shares a parent's slots
//! with its sibling, minimising the surface area heuristic: a node visit costs 1 and a
//! triangle test `TRIANGLE_COST`, each weighed by its box's half area. obvhs's conversion
//! runs the same programme with a triangle at 0.3 of a node visit. On the H100 a triangle
//! test costs about 2.2 node visits (the AO walk ran its node visits at ~40 G/s with its
//! triangle tests left out and ~23 G/s with them; docs/PERFORMANCE.md, "The GPU's time"), so at 0.3
//! the leaves hold too many triangles: leaves of one triangle forced everywhere made the
//! 1M suite's AO 1–9% faster, but the Cornell box's 38% slower. At 2.2 the programme
//! keeps leaves of up to 3 where they pay (the Cornell box gets obvhs's tree) and single
//! triangles where they do not, and fills nodes better than leaves of one everywhere
//! would (docs/PERFORMANCE.md, "The wide nodes at the GPU's costs"). obvhs's encoder (child order,
//! quantised boxes, meta bytes) builds the nodes from these decisions. The CPU backend
//! has prices of its own (`CPU_TRIANGLE_COST`).
use obvhs::bvh2::Bvh2;
use obvhs::cwbvh::bvh2_to_cwbvh::{Bvh2Converter, Decision, DecisionKind};
use obvhs::cwbvh::CwBvh;
use std::sync::atomic::{AtomicU32, Ordering};

/// A triangle test's cost in node visits on the GPU (H100, AO; module comment).
pub const GPU_TRIANGLE_COST: f32 = 2.2;
/// ... on the CPU backend, whose bundles test a triangle against up to 64 rays at once:
/// obvhs's 0.3 (leaves of up to 3 almost everywhere) made its AO 4–10% faster than 2.2
/// on rocks-1m, shell-1m and spheres-1m (docs/PERFORMANCE.md, "The CPU backend against Embree").
pub const CPU_TRIANGLE_COST: f32 = 0.3;

/// The price the trees this process builds use (`set_for_cpu`), as f32 bits: like the
/// BVH quality, a setting of the process, chosen before a scene loads.
static TRIANGLE_COST: AtomicU32 = AtomicU32::new(GPU_TRIANGLE_COST.to_bits());

/// Price the trees built from now on for the CPU backend or the GPU's: for the CPU where
/// the kernels will run there (`backend::expects_cpu`: `--backend cpu`, or `auto` without
/// a hardware GPU), the GPU's otherwise.
pub fn set_for_cpu(cpu: bool) {
    let cost = if cpu {
        CPU_TRIANGLE_COST
    } else {
        GPU_TRIANGLE_COST
    };
    TRIANGLE_COST.store(cost.to_bits(), Ordering::Relaxed);
}

/// The most triangles a CWBVH leaf holds (its meta byte's three bits).
const MAX_LEAF: u32 = 3;
/// Slot counts a binary subtree may be given in obvhs's decision table: 1 to 7 (a wide
/// node's 8 slots go to its two halves).
const SLOTS: usize = 7;

/// The CWBVH of `bvh2` (one triangle or triangle reference per leaf), priced for the
/// backend chosen with `set_for_cpu`.
pub fn convert(bvh2: &Bvh2) -> CwBvh {
    convert_at(bvh2, f32::from_bits(TRIANGLE_COST.load(Ordering::Relaxed)))
}

/// [`convert`] with a triangle test priced at `triangle_cost` node visits.
fn convert_at(bvh2: &Bvh2, triangle_cost: f32) -> CwBvh {
    if bvh2.nodes.is_empty() {
        return CwBvh::default();
    }
    let mut converter = Bvh2Converter::new(bvh2, true, false);
    decide(bvh2, &mut converter.decisions, triangle_cost);
    converter.convert_to_cwbvh();
    CwBvh {
        nodes: converter.nodes,
        primitive_indices: converter.primitive_indices,
        total_aabb: *bvh2.nodes[0].aabb(),
        exact_node_aabbs: None,
        uses_spatial_splits: bvh2.uses_spatial_splits,
    }
}

/// Fill obvhs's decision table (`SLOTS` per binary node: its subtree given 1..=7 slots)
/// bottom up, as its `calculate_cost` does, at our costs. Iterative: the SBVH's binary
/// trees can be deeper than a thread's stack likes.
fn decide(bvh2: &Bvh2, decisions: &mut [Decision], triangle_cost: f32) {
    let cost = |d: &[Decision], node: usize, slots: usize| d[node * SLOTS + slots].cost;
    let mut triangles = vec![0u32; bvh2.nodes.len()];
    let mut stack = vec![(0usize, false)];
    while let Some((n, halves_done)) = stack.pop() {
        let node = &bvh2.nodes[n];
        let area = node.aabb().half_area();
        let at = n * SLOTS;
        if node.is_leaf() {
            triangles[n] = node.prim_count;
            let leaf = Decision {
                cost: area * node.prim_count as f32 * triangle_cost,
                kind: DecisionKind::LEAF,
                ..Decision::default()
            };
            decisions[at..at + SLOTS].fill(leaf);
            continue;
        }
        let (l, r) = (node.first_index as usize, node.first_index as usize + 1);
        if !halves_done {
            stack.extend([(n, true), (l, false), (r, false)]);
            continue;
        }
        triangles[n] = triangles[l] + triangles[r];
        // One slot: a leaf, or a wide node whose 8 slots its halves share.
        let (split, shared) = (0..SLOTS)
            .map(|k| (k, cost(decisions, l, k) + cost(decisions, r, SLOTS - 1 - k)))
            .fold((0, f32::INFINITY), |a, b| if b.1 < a.1 { b } else { a });
        let internal = area + shared;
        let leaf = if triangles[n] <= MAX_LEAF {
            triangles[n] as f32 * area * triangle_cost
        } else {
            f32::INFINITY
        };
        decisions[at] = Decision {
            cost: leaf.min(internal),
            kind: if leaf < internal {
                DecisionKind::LEAF
            } else {
                DecisionKind::INTERNAL
            },
            distribute_left: split as u8,
            distribute_right: (SLOTS - 1 - split) as u8,
        };
        // i + 1 slots: as with i, or shared between the halves.
        for i in 1..SLOTS {
            let mut best = decisions[at + i - 1];
            for k in 0..i {
                let c = cost(decisions, l, k) + cost(decisions, r, i - k - 1);
                if c < best.cost {
                    best = Decision {
                        cost: c,
                        kind: DecisionKind::DISTRIBUTE,
                        distribute_left: k as u8,
                        distribute_right: (i - k - 1) as u8,
                    };
                }
            }
            decisions[at + i] = best;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kernels::types::Triangle;
    use obvhs::aabb::Aabb;
    use obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh;
    use obvhs::cwbvh::node::CwBvhNode;
    use obvhs::ploc::{PlocBuilder, PlocSearchDistance, SortPrecision};

    fn ploc(triangles: &[Triangle]) -> Bvh2 {
        let boxes: Vec<Aabb> = triangles
            .iter()
            .map(|t| {
                let (a, b, c) = t.vertices();
                let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
                Aabb::new(lo.to_array().into(), hi.to_array().into())
            })
            .collect();
        PlocBuilder::with_capacity(boxes.len()).build(
            PlocSearchDistance::Medium,
            &boxes,
            (0..boxes.len() as u32).collect(),
            SortPrecision::U64,
            1,
        )
    }

    fn same_tree(a: &CwBvh, b: &CwBvh) -> bool {
        let bytes = |n: &[CwBvhNode]| bytemuck::cast_slice::<CwBvhNode, u8>(n).to_vec();
        bytes(&a.nodes) == bytes(&b.nodes) && a.primitive_indices == b.primitive_indices
    }

    /// Triangles in each leaf child of `bvh`'s nodes: how many leaves hold 1, 2 and 3.
    fn leaf_sizes(bvh: &CwBvh) -> [usize; 3] {
        let mut sizes = [0; 3];
        for node in &bvh.nodes {
            for (slot, &meta) in node.child_meta.iter().enumerate() {
                if meta != 0 && node.imask & (1 << slot) == 0 {
                    sizes[(meta >> 5).count_ones() as usize - 1] += 1;
                }
            }
        }
        sizes
    }

    /// Our programme is obvhs's: at its triangle cost it makes its tree, to the byte.
    #[test]
    fn at_obvhs_triangle_cost_it_is_obvhs_conversion() {
        let cornell = crate::scene::cornell_box()
            .expect("built-in scene")
            .triangles;
        for triangles in [cornell, crate::generate::rocks(20_000).triangles] {
            let bvh2 = ploc(&triangles);
            assert!(same_tree(
                &convert_at(&bvh2, 0.3),
                &bvh2_to_cwbvh(&bvh2, 3, true, false)
            ));
        }
    }

    /// What the H100 measured (AO 1080p): the Cornell box with leaves of up to 3
    /// triangles 3.8 ms, of one 5.3 ms; rocks-1m 11.96 and 11.41 ms. At the GPU's triangle
    /// cost the Cornell box keeps obvhs's tree and rocks gets leaves of one triangle
    /// almost everywhere (obvhs's conversion puts most of its triangles in leaves of 2
    /// or 3: rocks-20k 6462 / 3599 / 568 leaves of 1 / 2 / 3, ours 15336 / 14 / 0).
    #[test]
    fn at_the_gpus_triangle_cost_leaves_follow_what_the_gpu_measured() {
        let cornell = ploc(
            &crate::scene::cornell_box()
                .expect("built-in scene")
                .triangles,
        );
        assert!(same_tree(
            &convert_at(&cornell, GPU_TRIANGLE_COST),
            &bvh2_to_cwbvh(&cornell, 3, true, false)
        ));
        let rocks = ploc(&crate::generate::rocks(20_000).triangles);
        let [ones, twos, threes] = leaf_sizes(&convert_at(&rocks, GPU_TRIANGLE_COST));
        assert!(
            ones > 20 * (twos + threes),
            "leaves of 1, 2, 3: {ones} {twos} {threes}"
        );
        let [ones, twos, threes] = leaf_sizes(&bvh2_to_cwbvh(&rocks, 3, true, false));
        assert!(
            2 * twos + 3 * threes > ones,
            "obvhs's leaves of 1, 2, 3: {ones} {twos} {threes}"
        );
    }

    #[test]
    fn an_empty_tree_converts_to_an_empty_one() {
        assert!(convert(&Bvh2::default()).nodes.is_empty());
    }
}
