//! BVH construction on the host with obvhs (PLOC + reinsertion), flattened into the arrays
//! the kernels traverse: a binary BVH or obvhs's compressed 8-wide BVH (CWBVH, uploaded
//! byte for byte). Either way the triangles are reordered to leaf order, so leaves read
//! contiguous memory and a node's `first` indexes the triangle array directly.
use std::time::{Duration, Instant};

use glam::Vec3A;
use kernels::types::{Bvh2Node, CwBvhNode, Triangle};
use obvhs::aabb::Aabb;
use obvhs::ploc::{PlocSearchDistance, SortPrecision};
use obvhs::{Boundable, BvhBuildParams};

/// A triangle's box, padded by a few ulps of its coordinates. Boxes that strictly contain
/// their triangles keep rays that run exactly in a face plane (axis-parallel rays starting
/// on a surface) from turning the slab test into 0 · ∞.
struct PaddedBox(Aabb);

impl Boundable for PaddedBox {
    fn aabb(&self) -> Aabb {
        self.0
    }
}

fn padded_boxes(triangles: &[Triangle]) -> Vec<PaddedBox> {
    triangles
        .iter()
        .map(|t| {
            let (p0, p1, p2) = t.vertices();
            let lo = p0.min(p1).min(p2);
            let hi = p0.max(p1).max(p2);
            let pad = lo.abs().max(hi.abs()).max_element() * 1e-6 + 1e-30;
            PaddedBox(Aabb::new(
                Vec3A::from(lo - Vec3::splat(pad)),
                Vec3A::from(hi + Vec3::splat(pad)),
            ))
        })
        .collect()
}

use glam::Vec3;

/// obvhs's "medium" preset: PLOC with a medium search radius and 5% reinsertion.
fn params() -> BvhBuildParams {
    BvhBuildParams {
        ploc_search_distance: PlocSearchDistance::Medium,
        sort_precision: SortPrecision::U64,
        ..BvhBuildParams::medium_build()
    }
}

/// A BVH over a triangle list: nodes plus the leaf order of the triangles
/// (`order[i]` = index in the input of the triangle that goes to slot i).
pub struct Built<N> {
    pub nodes: Vec<N>,
    pub order: Vec<u32>,
    pub build_time: Duration,
}

/// Binary BVH, leaves of up to 4 triangles after obvhs's SAH-driven collapse.
pub fn build_bvh2(triangles: &[Triangle]) -> Built<Bvh2Node> {
    let start = Instant::now();
    let boxes = padded_boxes(triangles);
    let config = BvhBuildParams {
        max_prims_per_leaf: 4,
        ..params()
    };
    let bvh = obvhs::bvh2::builder::build_bvh2(&boxes, config, &mut Duration::default());
    let nodes = bvh
        .nodes
        .iter()
        .map(|n| Bvh2Node {
            lo: n.aabb.min.to_array(),
            first: n.first_index,
            hi: n.aabb.max.to_array(),
            count: n.prim_count,
        })
        .collect();
    Built {
        nodes,
        order: bvh.primitive_indices,
        build_time: start.elapsed(),
    }
}

/// CWBVH: PLOC BVH2 with one triangle per leaf, converted by obvhs to 8-wide compressed
/// nodes with up to 3 triangles per leaf child and children ordered for traversal.
pub fn build_cwbvh(triangles: &[Triangle]) -> Built<CwBvhNode> {
    let start = Instant::now();
    let boxes = padded_boxes(triangles);
    let bvh = obvhs::cwbvh::builder::build_cwbvh(&boxes, params(), &mut Duration::default());
    // Same 80 bytes, read as words on our side.
    let nodes =
        bytemuck::cast_slice::<obvhs::cwbvh::node::CwBvhNode, CwBvhNode>(&bvh.nodes).to_vec();
    Built {
        nodes,
        order: bvh.primitive_indices,
        build_time: start.elapsed(),
    }
}

/// The BVH of the traversal compiled into the kernels (cargo feature). Brute force needs
/// none: it gets a single dummy node so GPU bindings stay valid.
pub fn build(triangles: &[Triangle]) -> Built<kernels::bvh::BvhNode> {
    #[cfg(feature = "traversal-brute-force")]
    return Built {
        nodes: vec![Default::default()],
        order: (0..triangles.len() as u32).collect(),
        build_time: Duration::ZERO,
    };
    #[cfg(all(feature = "traversal-bvh2", not(feature = "traversal-brute-force")))]
    return build_bvh2(triangles);
    #[cfg(not(any(feature = "traversal-bvh2", feature = "traversal-brute-force")))]
    return build_cwbvh(triangles);
}

/// Depth of a tree rooted at node 0 whose interior nodes' children are the nodes
/// `children(node)` (a lone root is depth 1). Indices past the end are skipped.
fn tree_depth<N>(nodes: &[N], children: impl Fn(&N) -> std::ops::Range<usize>) -> usize {
    let mut deepest = 0;
    let mut stack = vec![(0usize, 1usize)];
    while let Some((i, d)) = stack.pop() {
        let Some(n) = nodes.get(i) else { continue };
        deepest = deepest.max(d);
        stack.extend(children(n).map(|c| (c, d + 1)));
    }
    deepest
}

/// Depth of a binary BVH (a lone root is depth 1).
pub fn bvh2_depth(nodes: &[Bvh2Node]) -> usize {
    tree_depth(nodes, |n| {
        let first = n.first as usize;
        if n.count == 0 {
            first..first + 2
        } else {
            0..0
        }
    })
}

/// Depth of a CWBVH in nodes (a lone root is depth 1).
pub fn cwbvh_depth(nodes: &[CwBvhNode]) -> usize {
    tree_depth(nodes, |n| {
        let first = n.child_base_idx as usize;
        first..first + n.imask().count_ones() as usize
    })
}

/// Refuse BVHs deeper than the kernels' fixed traversal stacks, which would otherwise drop
/// subtrees and render a wrong image without a word. Only pathological geometry (thousands
/// of coincident triangles, say) gets there.
pub fn check_depth(nodes: &[kernels::bvh::BvhNode]) -> crate::error::Result<()> {
    #[cfg(feature = "traversal-brute-force")]
    let (depth, limit) = (0, 0);
    #[cfg(all(feature = "traversal-bvh2", not(feature = "traversal-brute-force")))]
    let (depth, limit) = (bvh2_depth(nodes), kernels::bvh::BVH2_STACK);
    #[cfg(not(any(feature = "traversal-bvh2", feature = "traversal-brute-force")))]
    let (depth, limit) = (cwbvh_depth(nodes), kernels::bvh::CWBVH_STACK);
    if depth > limit {
        crate::bail!(
            "the scene's BVH is {depth} levels deep, deeper than the traversal supports ({limit}): \
             the geometry is pathological (e.g. many coincident or overlapping triangles)"
        );
    }
    let _ = nodes;
    Ok(())
}

/// `items` permuted into leaf order.
pub fn reorder<T: Copy>(items: &[T], order: &[u32]) -> Vec<T> {
    order.iter().map(|&i| items[i as usize]).collect()
}
