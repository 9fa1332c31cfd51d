//! BVH construction on the host with obvhs (PLOC + reinsertion), flattened into the arrays
//! the kernels traverse: a binary BVH or obvhs's compressed 8-wide BVH (CWBVH, uploaded
//! byte for byte). Either way the triangles are reordered to leaf order, so leaves read
//! contiguous memory and a node's `first` indexes the triangle array directly.
use std::time::{Duration, Instant};

use glam::Vec3A;
use kernels::types::{Bvh2Node, CwBvhNode, Triangle};
use obvhs::aabb::Aabb;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::ploc::{PlocBuilder, PlocSearchDistance, SortPrecision};
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

/// The padded box of each triangle, or of each part of a triangle where pre-splitting
/// (`presplit`) gave it several, and the triangle each box holds (part of).
fn padded_boxes(
    triangles: &[Triangle],
    splits: f32,
    splittable: &(dyn Fn(&Triangle) -> bool + Sync),
) -> (Vec<PaddedBox>, Vec<u32>) {
    let split = crate::presplit::split_boxes(triangles, splits, splittable);
    let boxes = split
        .boxes
        .iter()
        .map(|&(lo, hi)| {
            let (lo, hi) = pad(lo, hi);
            PaddedBox(Aabb::new(Vec3A::from(lo), Vec3A::from(hi)))
        })
        .collect();
    (boxes, split.refs)
}

/// Box `lo..hi` grown by a few ulps of its coordinates (see `PaddedBox`).
fn pad(lo: Vec3, hi: Vec3) -> (Vec3, Vec3) {
    let pad = lo.abs().max(hi.abs()).max_element() * 1e-6 + 1e-30;
    (lo - Vec3::splat(pad), hi + Vec3::splat(pad))
}

use glam::Vec3;

/// How much of the build goes into the tree's quality (`--bvh-quality`): PLOC (or, at
/// `high`, a top-down SBVH), then reinsertion (Meister & Bittner 2018), which moves
/// subtrees to where they cost the traversal least. On one core here, 1M triangles take
/// 0.35 s of PLOC, 0.4 s of conversion to CWBVH and 0.1 s (none) to 5 s (every node) of
/// reinsertion; the SBVH 3.2–5.2 s on two cores.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum BvhQuality {
    /// Up to `AUTO_FULL_TRIANGLES` triangles what `high` builds; above, PLOC with a share
    /// of nodes considered for reinsertion that keeps the reinsertion work constant:
    /// loading stays ~1 s per million triangles on one core
    #[default]
    Auto,
    /// No reinsertion: the quickest build (interactive edits, huge scenes, short renders)
    Fast,
    /// A top-down build with spatial splits (SBVH) and every node considered for
    /// reinsertion: rays visit up to 8–12% fewer nodes where triangles are long or thin
    /// (AO on the H100 up to 13% faster), for 1–3× the build time of PLOC with full
    /// reinsertion and 1.5× its memory; for long renders of large scenes
    // (Against PLOC with full reinsertion, `high` before it: docs/PERFORMANCE.md, "SBVH". The BVH2
    // traversal feature builds PLOC at every quality.)
    High,
}

/// Scenes up to this size get `high`'s build (the SBVH) under `auto`; above it PLOC, with
/// a share of nodes considered for reinsertion that shrinks as 1/n. Measured on the H100
/// (AO 64 rays/px, 1080p, 1M triangles), full reinsertion against a 10% share: city-1m and
/// grass-1m ~13–16% faster traversal, rocks-1m and spheres-1m ~1%; the build on one core
/// 5 s against ~1 s. The SBVH against PLOC with full reinsertion, up to this size (H100,
/// AO): light-hall 11%, FlightHelmet 11%, grass-100k 9%, city-100k 7% faster, rocks-50k
/// and the Cornell box the same; its build 0.27 → 0.81 s for FlightHelmet's 95k triangles
/// on two cores.
const AUTO_FULL_TRIANGLES: usize = 100_000;

/// Whether a build of `quality` over `triangles` triangles is the SBVH (else PLOC).
pub fn builds_sbvh(quality: BvhQuality, triangles: usize) -> bool {
    match quality {
        BvhQuality::Fast => false,
        BvhQuality::High => true,
        BvhQuality::Auto => triangles <= AUTO_FULL_TRIANGLES,
    }
}

/// The quality every build of this process uses (`set_quality`): one setting for the five
/// loaders and the built-in scenes alike, the way a thread count is.
static QUALITY: std::sync::atomic::AtomicU8 = std::sync::atomic::AtomicU8::new(0);

/// Choose the BVH quality for the scenes this process builds from now on.
pub fn set_quality(quality: BvhQuality) {
    QUALITY.store(quality as u8, std::sync::atomic::Ordering::Relaxed);
}

/// The quality chosen with `set_quality` (`Auto` unless told).
pub fn quality() -> BvhQuality {
    match QUALITY.load(std::sync::atomic::Ordering::Relaxed) {
        1 => BvhQuality::Fast,
        2 => BvhQuality::High,
        _ => BvhQuality::Auto,
    }
}

/// Extra boxes pre-splitting may add, as a share of the triangles (`--bvh-splits`;
/// `presplit`), unless told otherwise: none. Measured on the H200 (docs/PERFORMANCE.md, "Benchmark
/// suite"), Karras & Aila's 0.3 made AO on four of the five suite scenes 1–17% slower and
/// Cornell MIS 21% (fewer triangle tests, more node visits), rocks-1m AO and city-1m pt
/// 3–4% faster: a lever for scenes of large triangles, not a default.
pub const DEFAULT_SPLITS: f32 = 0.0;
/// The most `--bvh-splits` accepts: each split box costs memory (a triangle slot, 48 B)
/// and build time like a triangle.
pub const MAX_SPLITS: f32 = 4.0;

/// The pre-splitting share every build of this process uses (`set_splits`), as f32 bits.
static SPLITS: std::sync::atomic::AtomicU32 =
    std::sync::atomic::AtomicU32::new(DEFAULT_SPLITS.to_bits());

/// Choose the pre-splitting share for the scenes this process builds from now on (`None`:
/// `DEFAULT_SPLITS`).
pub fn set_splits(share: Option<f32>) {
    let share = share.unwrap_or(DEFAULT_SPLITS);
    SPLITS.store(share.to_bits(), std::sync::atomic::Ordering::Relaxed);
}

/// The share chosen with `set_splits` (`DEFAULT_SPLITS` unless told).
pub fn splits() -> f32 {
    f32::from_bits(SPLITS.load(std::sync::atomic::Ordering::Relaxed))
}

/// The share of nodes considered for reinsertion for `triangles` triangles.
pub fn reinsertion_share(quality: BvhQuality, triangles: usize) -> f32 {
    match quality {
        BvhQuality::Fast => 0.0,
        BvhQuality::High => 1.0,
        BvhQuality::Auto => (AUTO_FULL_TRIANGLES as f32 / triangles.max(1) as f32).min(1.0),
    }
}

/// obvhs's "very slow" preset (PLOC with a medium search radius, 128-bit Morton codes)
/// with the reinsertion share of `quality`. With every node considered, against obvhs's
/// "medium" preset (5%) on the H100, AO 64 rays/px at 1080p: city-1m 64.1 → 50.5 ms,
/// grass-1m 149.5 → 114.4 ms, rocks-1m, spheres-1m and shell-1m 0.5–3% faster. (Its
/// `pre_split` applies only to obvhs's triangle builder, and our flat grounds are never
/// split by its area criterion anyway.)
fn params(quality: BvhQuality, triangles: usize) -> BvhBuildParams {
    BvhBuildParams {
        ploc_search_distance: PlocSearchDistance::Medium,
        sort_precision: SortPrecision::U128,
        reinsertion_batch_ratio: reinsertion_share(quality, triangles),
        ..BvhBuildParams::very_slow_build()
    }
}

/// A BVH over a triangle list: nodes plus the leaf order of the triangles
/// (`order[i]` = index in the input of the triangle that goes to slot i; a pre-split
/// triangle goes to several slots).
pub struct Built<N> {
    pub nodes: Vec<N>,
    pub order: Vec<u32>,
    pub build_time: Duration,
    /// Whether a balanced tree replaced PLOC's (too deep for the traversal, or the boxes
    /// overlap beyond `MAX_OVERLAP`).
    pub balanced: bool,
}

/// How many times the scene's bounding box the triangles' boxes may cover in all (sum of
/// their surface areas) before PLOC is not even tried. A mesh's boxes tile its surface:
/// measured 1.7 (rocks-1m, the bunny) to 4.5 (Cornell box, light-hall), 32 for an
/// 800-triangle fan of slivers from one corner. Thousands of triangles spanning one box
/// (50,000: ~50,000; PLOC took 40-100 s on them, quadratic in the stack) go straight to
/// the balanced build.
const MAX_OVERLAP: f64 = 1000.0;

/// Sum of the boxes' surface areas over the surface area of their union.
fn overlap(boxes: &[PaddedBox]) -> f64 {
    let mut all = Aabb::empty();
    let mut sum = 0.0f64;
    for b in boxes {
        all = all.union(&b.0);
        sum += b.0.half_area() as f64;
    }
    let total = all.half_area() as f64;
    if total > 0.0 {
        sum / total
    } else {
        0.0
    }
}

/// A binary BVH of one triangle per leaf, each node split at the median centroid along
/// its widest centroid extent: ⌈log₂ n⌉ + 1 levels whatever the geometry. The fallback
/// where PLOC's tree is deeper than the traversal's stack: slivers nested in one another
/// (a fan of hundreds of triangles sharing a corner) make PLOC pair them one by one.
/// Slower to traverse than PLOC's where both exist, never wrong.
fn balanced_bvh2(boxes: &[PaddedBox]) -> obvhs::bvh2::Bvh2 {
    use obvhs::bvh2::node::Bvh2Node as Node;
    let n = boxes.len();
    let mut indices: Vec<u32> = (0..n as u32).collect();
    let mut nodes = vec![Node::default(); (2 * n).saturating_sub(1).max(1)];
    let centre = |i: u32| boxes[i as usize].0.center();
    let mut next = 1;
    // (node, first index, end) of the subtrees still to build.
    let mut work = vec![(0usize, 0usize, n)];
    while let Some((node, start, end)) = work.pop() {
        let range = &mut indices[start..end];
        let mut aabb = Aabb::empty();
        let mut centres = Aabb::empty();
        for &i in range.iter() {
            aabb = aabb.union(&boxes[i as usize].0);
            centres.extend(centre(i));
        }
        nodes[node].aabb = aabb;
        if range.len() <= 1 {
            nodes[node].prim_count = range.len() as u32;
            nodes[node].first_index = start as u32;
            continue;
        }
        let axis = (centres.max - centres.min).max_position();
        let half = range.len() / 2;
        range.select_nth_unstable_by(half, |&a, &b| centre(a)[axis].total_cmp(&centre(b)[axis]));
        nodes[node].prim_count = 0;
        nodes[node].first_index = next as u32;
        work.push((next, start, start + half));
        work.push((next + 1, start + half, end));
        next += 2;
    }
    obvhs::bvh2::Bvh2 {
        nodes,
        primitive_indices: indices,
        ..Default::default()
    }
}

/// Binary BVH, leaves of up to 4 triangles after obvhs's SAH-driven collapse.
pub fn build_bvh2(
    triangles: &[Triangle],
    quality: BvhQuality,
    splits: f32,
    splittable: &(dyn Fn(&Triangle) -> bool + Sync),
) -> Built<Bvh2Node> {
    let start = Instant::now();
    let (boxes, refs) = padded_boxes(triangles, splits, splittable);
    let config = BvhBuildParams {
        max_prims_per_leaf: 4,
        ..params(quality, boxes.len())
    };
    let flatten = |bvh: &obvhs::bvh2::Bvh2| -> Vec<Bvh2Node> {
        bvh.nodes
            .iter()
            .map(|n| Bvh2Node {
                lo: n.aabb.min.to_array(),
                first: n.first_index,
                hi: n.aabb.max.to_array(),
                count: n.prim_count,
            })
            .collect()
    };
    let crowded = overlap(&boxes) > MAX_OVERLAP;
    let mut bvh = if crowded {
        balanced_bvh2(&boxes)
    } else {
        obvhs::bvh2::builder::build_bvh2(&boxes, config, &mut Duration::default())
    };
    let mut nodes = flatten(&bvh);
    let balanced = crowded || bvh2_depth(&nodes) > kernels::bvh::BVH2_STACK;
    if balanced && !crowded {
        bvh = balanced_bvh2(&boxes);
        nodes = flatten(&bvh);
    }
    Built {
        nodes,
        order: triangle_order(&bvh.primitive_indices, &refs),
        build_time: start.elapsed(),
        balanced,
    }
}

/// CWBVH: a binary BVH with one triangle per leaf (PLOC, or the SBVH), collapsed into
/// 8-wide compressed nodes with children ordered for traversal, leaf children of 1 to 3
/// triangles where the GPU's costs favour them (`collapse`).
pub fn build_cwbvh(
    triangles: &[Triangle],
    quality: BvhQuality,
    splits: f32,
    splittable: &(dyn Fn(&Triangle) -> bool + Sync),
) -> Built<CwBvhNode> {
    let start = Instant::now();
    let (boxes, refs) = padded_boxes(triangles, splits, splittable);
    // Same 80 bytes, read as words on our side.
    let flatten = |bvh: &obvhs::cwbvh::CwBvh| {
        bytemuck::cast_slice::<obvhs::cwbvh::node::CwBvhNode, CwBvhNode>(&bvh.nodes).to_vec()
    };
    let crowded = overlap(&boxes) > MAX_OVERLAP;
    // A binary tree collapsed into wide nodes, and the triangle in each of their primitive
    // slots: the binary leaves hold triangle indices (the SBVH's) or box indices.
    let collapse = |bvh2: &obvhs::bvh2::Bvh2, of_triangles: bool| {
        let bvh = crate::collapse::convert(bvh2);
        let order = if of_triangles {
            bvh.primitive_indices.clone()
        } else {
            triangle_order(&bvh.primitive_indices, &refs)
        };
        (bvh, order)
    };
    let balanced_tree = || collapse(&balanced_bvh2(&boxes), false);
    let (bvh, mut order) = if crowded {
        balanced_tree()
    } else {
        let (bvh2, of_triangles) = if builds_sbvh(quality, triangles.len()) {
            let corners: Vec<(Vec3, Vec3)> = boxes
                .iter()
                .map(|b| (Vec3::from(b.0.min), Vec3::from(b.0.max)))
                .collect();
            let mut bvh2 = crate::sbvh::build(triangles, &corners, &refs, &pad, splittable);
            // Every node considered, as at `high`: `auto` builds the SBVH only up to
            // `AUTO_FULL_TRIANGLES` triangles (whose references may be more).
            ReinsertionOptimizer::default().run(&mut bvh2, 1.0, None);
            (bvh2, true)
        } else {
            // obvhs's `build_cwbvh` up to its conversion, which `collapse` makes.
            let config = params(quality, boxes.len());
            let mut bvh2 = PlocBuilder::with_capacity(boxes.len()).build(
                config.ploc_search_distance,
                &boxes,
                (0..boxes.len() as u32).collect(),
                config.sort_precision,
                config.search_depth_threshold,
            );
            ReinsertionOptimizer::default().run(&mut bvh2, config.reinsertion_batch_ratio, None);
            (bvh2, false)
        };
        collapse(&bvh2, of_triangles)
    };
    let mut nodes = flatten(&bvh);
    let balanced = crowded || cwbvh_depth(&nodes) > kernels::bvh::CWBVH_STACK;
    if balanced && !crowded {
        let (bvh, balanced_order) = balanced_tree();
        nodes = flatten(&bvh);
        order = balanced_order;
    }
    Built {
        nodes,
        order,
        build_time: start.elapsed(),
        balanced,
    }
}

/// The leaf order of the triangles from that of their boxes (`refs[box]` = its triangle).
fn triangle_order(box_order: &[u32], refs: &[u32]) -> Vec<u32> {
    box_order.iter().map(|&b| refs[b as usize]).collect()
}

/// The BVH of the traversal compiled into the kernels (cargo feature), of the quality
/// and pre-splitting chosen with `set_quality` and `set_splits` (only of the triangles
/// `splittable` allows). Brute force needs none: it gets a single dummy node so GPU
/// bindings stay valid.
pub fn build(
    triangles: &[Triangle],
    splittable: &(dyn Fn(&Triangle) -> bool + Sync),
) -> Built<kernels::bvh::BvhNode> {
    #[cfg(feature = "traversal-brute-force")]
    let _ = splittable;
    #[cfg(feature = "traversal-brute-force")]
    return Built {
        nodes: vec![Default::default()],
        order: (0..triangles.len() as u32).collect(),
        build_time: Duration::ZERO,
        balanced: false,
    };
    #[cfg(all(feature = "traversal-bvh2", not(feature = "traversal-brute-force")))]
    return build_bvh2(triangles, quality(), splits(), splittable);
    #[cfg(not(any(feature = "traversal-bvh2", feature = "traversal-brute-force")))]
    return build_cwbvh(triangles, quality(), splits(), splittable);
}

/// The BVH's nodes as the CPU's traversal reads them: a CWBVH's decoded
/// (`kernels::bvh::TraversalNode`), other kinds as they are.
pub fn host_nodes(nodes: &[kernels::bvh::BvhNode]) -> Vec<glam::UVec4> {
    #[cfg(not(any(feature = "traversal-bvh2", feature = "traversal-brute-force")))]
    return nodes
        .iter()
        .flat_map(|n| {
            use kernels::types::CwBvhPlanes;
            bytemuck::cast::<_, [glam::UVec4; CwBvhPlanes::WORDS]>(CwBvhPlanes::decoded(n))
        })
        .collect();
    #[cfg(any(feature = "traversal-bvh2", feature = "traversal-brute-force"))]
    return bytemuck::cast_slice(nodes).to_vec();
}

/// The node layout the GPU's traversal reads (`kernels::bvh::TraversalNode` on the GPU).
#[cfg(not(any(feature = "traversal-bvh2", feature = "traversal-brute-force")))]
pub type GpuNode = kernels::types::CwBvhSlotNode;
#[cfg(any(feature = "traversal-bvh2", feature = "traversal-brute-force"))]
pub type GpuNode = kernels::bvh::BvhNode;

/// A built node as the GPU reads it: a CWBVH node with its slots' hit-mask bits, other
/// kinds as they are.
pub fn gpu_node(node: &kernels::bvh::BvhNode) -> GpuNode {
    #[cfg(not(any(feature = "traversal-bvh2", feature = "traversal-brute-force")))]
    return GpuNode::of(node);
    #[cfg(any(feature = "traversal-bvh2", feature = "traversal-brute-force"))]
    return *node;
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
/// subtrees and render a wrong image without a word. The builders fall back to a balanced
/// tree first, so this is a last guard.
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
