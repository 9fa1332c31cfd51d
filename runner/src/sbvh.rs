//! A binary BVH built top down with spatial splits (SBVH; Stich, Friedrich & Dietrich
//! 2009, "Spatial Splits in Bounding Volume Hierarchies"). Each node takes the cheaper by
//! the surface area heuristic of two kinds of split: an object split (binned over the
//! references' centres, as a plain SAH builder; an exact sweep in small nodes) and, where
//! the object split's children overlap, a spatial split: a plane that cuts the triangles
//! straddling it, each side keeping the box of its own part. A long triangle then sits in several leaves, each with
//! a tight box, instead of one box overlapping everything along it. Unlike pre-splitting
//! (`presplit`), the builder splits only where the heuristic says the split pays, and a
//! straddling reference goes whole to one side where that costs less ("unsplitting").
//!
//! References hold their triangle once per part: traversal and hits are unchanged, as with
//! pre-splitting (a leaf holds the triangle once per part).
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::{Vec3, Vec3A};
use kernels::types::Triangle;
use obvhs::aabb::Aabb;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::bvh2::Bvh2;
use rayon::prelude::*;

use crate::presplit::Polygon;

/// Bins per axis of object splits: binning costs the same whatever their number.
const OBJECT_BINS: usize = 128;
/// Bins per axis of spatial splits: each bin a reference spans costs a clip.
const SPATIAL_BINS: usize = 32;
/// Spatial splits are tried only where the best object split's children overlap by more
/// than this share of the root's surface area (Stich et al.'s α): below it, the overlap
/// costs too little for splitting to pay back its references.
const OVERLAP_SHARE: f32 = 1e-5;
/// Triangles whose box has at least this share of the scene box's surface area are never
/// split. Splitting a ground plane put a piece of it in every cluster of objects above,
/// and every cluster's box then reached down to the ground: rocks-1m's AO rays visited
/// 16% more nodes (4.19 per ray against 3.61 without splits; 3.53 with the ground whole).
const UNSPLIT_SHARE: f32 = 0.01;
/// At most this many references per triangle in all: each one costs memory (a triangle
/// slot, 48 B) like a triangle.
const MAX_REFS_PER_TRIANGLE: f32 = 2.0;
/// Nodes of fewer references than this find their object split by an exact sweep over
/// their sorted centres, and get no spatial split: wide nodes gather such subtrees anyway
/// (8 children of up to 3 triangles), and splitting down there only duplicated triangles.
/// Measured (nodes per AO ray, triangle slots; splits allowed at every size → only from
/// 64 references): FlightHelmet 7.06 → 6.68, 2.0× → 1.16× the triangles; grass-1m 10.10 →
/// 9.99, 1.15× → 1.005×; the 1M suite's other scenes the same.
const SMALL_NODE: usize = 64;
/// Below this depth the heuristic chooses the splits; from it on, median splits, so that
/// no input (thousands of nested slivers, which the heuristic peels one by one) makes
/// the tree, or the build's recursion, deeper than this plus log₂ of the references.
const MAX_SAH_DEPTH: usize = 64;
/// Subtrees of more references than this are built in parallel, and their nodes binned in
/// parallel chunks of this many.
const PARALLEL_REFS: usize = 4096;

/// A box as two corners (empty: lo > hi).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Bounds {
    lo: Vec3,
    hi: Vec3,
}

impl Bounds {
    const EMPTY: Self = Self {
        lo: Vec3::splat(f32::INFINITY),
        hi: Vec3::splat(f32::NEG_INFINITY),
    };

    fn union(self, o: Self) -> Self {
        Self {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
        }
    }

    fn intersection(self, o: Self) -> Self {
        Self {
            lo: self.lo.max(o.lo),
            hi: self.hi.min(o.hi),
        }
    }

    /// Half the surface area (0 when empty): what the heuristic weighs.
    fn half_area(self) -> f32 {
        let d = (self.hi - self.lo).max(Vec3::ZERO);
        d.x * d.y + d.y * d.z + d.z * d.x
    }

    fn centre(self) -> Vec3 {
        0.5 * (self.lo + self.hi)
    }

    fn aabb(self) -> Aabb {
        Aabb::new(Vec3A::from(self.lo), Vec3A::from(self.hi))
    }
}

/// A reference: (a part of) triangle `tri` inside box `b`.
#[derive(Clone, Copy, Debug)]
struct Ref {
    b: Bounds,
    tri: u32,
}

/// What every node's build reads: the triangles, which of them may be split, the padding
/// of boxes, and the references still allowed beyond one per triangle.
struct Context<'a> {
    triangles: &'a [Triangle],
    splittable: Vec<bool>,
    pad: &'a (dyn Fn(Vec3, Vec3) -> (Vec3, Vec3) + Sync),
    root_area: f32,
    /// `MAX_SAH_DEPTH` (tests choose less).
    max_sah_depth: usize,
    spare_refs: AtomicUsize,
}

impl Context<'_> {
    fn polygon(&self, r: &Ref) -> Polygon {
        Polygon::triangle(&self.triangles[r.tri as usize])
    }

    /// The box of part `p` of `r`'s triangle within `r`'s box, padded as every box is;
    /// None where nothing of it is there.
    fn part(&self, r: &Ref, p: &Polygon) -> Option<Bounds> {
        if p.is_empty() {
            return None;
        }
        // A cut puts the part's corners on the plane exactly; padded, its box reaches a
        // few ulps across it, as every box reaches past its triangle.
        let (plo, phi) = p.bounds();
        let (plo, phi) = (self.pad)(plo, phi);
        let b = Bounds { lo: plo, hi: phi }.intersection(r.b);
        (b.lo.cmple(b.hi).all()).then_some(b)
    }
}

/// Spatial bins along one axis of a node's box: bin i spans planes i and i + 1.
struct Planes {
    lo: f32,
    step: f32,
}

impl Planes {
    fn new(b: Bounds, axis: usize) -> Option<Self> {
        let extent = b.hi[axis] - b.lo[axis];
        (extent > 0.0 && extent.is_finite()).then(|| Self {
            lo: b.lo[axis],
            step: extent / SPATIAL_BINS as f32,
        })
    }

    fn at(&self, i: usize) -> f32 {
        self.lo + self.step * i as f32
    }

    fn bin(&self, x: f32) -> usize {
        (((x - self.lo) / self.step).floor().max(0.0) as usize).min(SPATIAL_BINS - 1)
    }

    /// The bins reference `r` spans (one bin, that of its centre, for a reference that may
    /// not be split).
    fn span(&self, ctx: &Context, r: &Ref, axis: usize) -> (usize, usize) {
        if !ctx.splittable[r.tri as usize] {
            let c = self.bin(r.b.centre()[axis]);
            return (c, c);
        }
        (self.bin(r.b.lo[axis]), self.bin(r.b.hi[axis]))
    }
}

/// Object bins on three axes: each bin's box and count.
type ObjectBins = [[(Bounds, u32); OBJECT_BINS]; 3];
/// Spatial bins on three axes: each bin's box and the references entering and leaving.
type SpatialBins = [[(Bounds, u32, u32); SPATIAL_BINS]; 3];

/// A node's best split of either kind.
#[derive(Clone, Copy, Debug)]
enum Split {
    /// The first `count` references in the order of their centres on `axis` go left (a
    /// small node's exact sweep).
    Sorted {
        axis: usize,
        count: usize,
        cost: f32,
    },
    /// References whose centre falls in bins ≤ `last` (of `bins` on `axis`) go left.
    Object {
        axis: usize,
        bins: CentreBins,
        last: usize,
        cost: f32,
        left: Bounds,
        right: Bounds,
    },
    /// The plane between bins `plane - 1` and `plane` on `axis`.
    Spatial {
        axis: usize,
        plane: usize,
        cost: f32,
        left: Bounds,
        right: Bounds,
        counts: (usize, usize),
    },
}

/// The bins of a node's references: chunks in parallel where there are many. The chunks'
/// bins (12 KB of object bins) are merged on the heap: rayon's reduce holds each level's
/// two results on its stack, and a worker that waits in a join runs other nodes' binning
/// on top of its own, so bins by value overflowed the 2 MiB stacks of the device
/// machine's 16 workers (grass-1m at `high`; 512 KiB stacks overflow every time).
fn bin_in_chunks<B: Send>(
    refs: &[Ref],
    bin: impl Fn(&[Ref]) -> B + Sync,
    merge: impl Fn(&mut B, &B) + Sync + Send,
) -> B {
    if refs.len() <= PARALLEL_REFS {
        return bin(refs);
    }
    let merged = refs
        .par_chunks(PARALLEL_REFS)
        .map(|chunk| Box::new(bin(chunk)))
        .reduce_with(|mut a, b| {
            merge(&mut a, &b);
            a
        });
    *merged.expect("more than PARALLEL_REFS references make at least one chunk")
}

/// The box of the references' centres.
fn centres_of(refs: &[Ref]) -> Bounds {
    refs.iter().fold(Bounds::EMPTY, |b, r| {
        let c = r.b.centre();
        b.union(Bounds { lo: c, hi: c })
    })
}

/// Object bins over a node's centres: the same bin for a reference when binning and when
/// partitioning.
#[derive(Clone, Copy, Debug)]
struct CentreBins {
    lo: Vec3,
    scale: Vec3,
}

impl CentreBins {
    fn new(centres: Bounds) -> Self {
        let extent = centres.hi - centres.lo;
        Self {
            lo: centres.lo,
            scale: Vec3::select(
                extent.cmpgt(Vec3::ZERO),
                OBJECT_BINS as f32 / extent,
                Vec3::ZERO,
            ),
        }
    }

    fn bin(&self, r: &Ref, axis: usize) -> usize {
        let k = (r.b.centre()[axis] - self.lo[axis]) * self.scale[axis];
        (k.max(0.0) as usize).min(OBJECT_BINS - 1)
    }
}

fn object_bins(refs: &[Ref], centres: CentreBins) -> ObjectBins {
    let empty = [[(Bounds::EMPTY, 0u32); OBJECT_BINS]; 3];
    bin_in_chunks(
        refs,
        |chunk| {
            let mut bins = empty;
            for r in chunk {
                for (axis, axis_bins) in bins.iter_mut().enumerate() {
                    let bin = &mut axis_bins[centres.bin(r, axis)];
                    bin.0 = bin.0.union(r.b);
                    bin.1 += 1;
                }
            }
            bins
        },
        |a, b| {
            for (axis_a, axis_b) in a.iter_mut().zip(b) {
                for (x, y) in axis_a.iter_mut().zip(axis_b) {
                    *x = (x.0.union(y.0), x.1 + y.1);
                }
            }
        },
    )
}

fn spatial_bins(ctx: &Context, refs: &[Ref], node: Bounds) -> SpatialBins {
    let empty = [[(Bounds::EMPTY, 0u32, 0u32); SPATIAL_BINS]; 3];
    let planes: [Option<Planes>; 3] = std::array::from_fn(|axis| Planes::new(node, axis));
    bin_in_chunks(
        refs,
        |chunk| {
            let mut bins = empty;
            for (axis, planes) in planes.iter().enumerate() {
                let Some(planes) = planes else { continue };
                for r in chunk {
                    let (first, last) = planes.span(ctx, r, axis);
                    if first == last {
                        bins[axis][first].0 = bins[axis][first].0.union(r.b);
                    } else {
                        // Chopped bin by bin: each plane cuts what is left above the
                        // last.
                        let mut rest = ctx.polygon(r);
                        let spanned = bins[axis].iter_mut().enumerate();
                        for (b, bin) in spanned.take(last + 1).skip(first) {
                            let part = if b == last {
                                rest
                            } else {
                                let (below, above) = rest.cut(axis, planes.at(b + 1));
                                rest = above;
                                below
                            };
                            if let Some(part) = ctx.part(r, &part) {
                                bin.0 = bin.0.union(part);
                            }
                        }
                    }
                    bins[axis][first].1 += 1;
                    bins[axis][last].2 += 1;
                }
            }
            bins
        },
        |a, b| {
            for (axis_a, axis_b) in a.iter_mut().zip(b) {
                for (x, y) in axis_a.iter_mut().zip(axis_b) {
                    *x = (x.0.union(y.0), x.1 + y.1, x.2 + y.2);
                }
            }
        },
    )
}

/// The cheapest plane through bins of (box, references entering, references leaving):
/// (plane, cost, left box, right box, left count, right count). Object bins enter and
/// leave in the same bin.
fn sweep<const N: usize>(
    bins: &[(Bounds, u32, u32); N],
) -> Option<(usize, f32, Bounds, Bounds, usize, usize)> {
    let mut right = [(Bounds::EMPTY, 0usize); N];
    let mut acc = (Bounds::EMPTY, 0usize);
    for i in (1..N).rev() {
        acc = (acc.0.union(bins[i].0), acc.1 + bins[i].2 as usize);
        right[i] = acc;
    }
    let mut best: Option<(usize, f32, Bounds, Bounds, usize, usize)> = None;
    let mut left = (Bounds::EMPTY, 0usize);
    for plane in 1..N {
        let bin = &bins[plane - 1];
        left = (left.0.union(bin.0), left.1 + bin.1 as usize);
        let (rb, rn) = right[plane];
        if left.1 == 0 || rn == 0 {
            continue;
        }
        let cost = left.0.half_area() * left.1 as f32 + rb.half_area() * rn as f32;
        if best.is_none_or(|(_, c, ..)| cost < c) {
            best = Some((plane, cost, left.0, rb, left.1, rn));
        }
    }
    best
}

/// The best split of a node of `refs` in box `node`.
fn best_split(ctx: &Context, refs: &[Ref], node: Bounds) -> Option<Split> {
    if refs.len() < SMALL_NODE {
        return Some(sorted_split(refs));
    }
    let centres = centres_of(refs);
    let centre_bins = CentreBins::new(centres);
    let bins = object_bins(refs, centre_bins);
    let mut best: Option<Split> = None;
    for (axis, axis_bins) in bins.iter().enumerate() {
        if centres.hi[axis] <= centres.lo[axis] {
            continue;
        }
        let as_spatial: [(Bounds, u32, u32); OBJECT_BINS] =
            std::array::from_fn(|i| (axis_bins[i].0, axis_bins[i].1, axis_bins[i].1));
        if let Some((plane, cost, left, right, ..)) = sweep(&as_spatial) {
            if best.is_none_or(|b| cost < b.cost()) {
                best = Some(Split::Object {
                    axis,
                    bins: centre_bins,
                    last: plane - 1,
                    cost,
                    left,
                    right,
                });
            }
        }
    }
    let overlap = match best {
        Some(Split::Object { left, right, .. }) => left.intersection(right).half_area(),
        _ => f32::INFINITY,
    };
    if overlap <= OVERLAP_SHARE * ctx.root_area || ctx.spare_refs.load(Ordering::Relaxed) == 0 {
        return best;
    }
    let bins = spatial_bins(ctx, refs, node);
    for (axis, axis_bins) in bins.iter().enumerate() {
        if let Some((plane, cost, left, right, nl, nr)) = sweep(axis_bins) {
            if best.is_none_or(|b| cost < b.cost()) {
                best = Some(Split::Spatial {
                    axis,
                    plane,
                    cost,
                    left,
                    right,
                    counts: (nl, nr),
                });
            }
        }
    }
    best
}

impl Split {
    fn cost(&self) -> f32 {
        match *self {
            Split::Sorted { cost, .. }
            | Split::Object { cost, .. }
            | Split::Spatial { cost, .. } => cost,
        }
    }
}

/// `refs` sorted by their centres on `axis` (stable: the same order each time).
fn sort_on(refs: &mut [Ref], axis: usize) {
    refs.sort_by(|a, b| a.b.centre()[axis].total_cmp(&b.b.centre()[axis]));
}

/// The cheapest object split of a small node (at least 2 references): every place in
/// the order of the centres on each axis between two different centres (a median split
/// where all are the same). Splitting between equal centres — the two triangles of an
/// axis-aligned quad — cost many-lights' AO rays 7% more nodes (3.04 per ray against
/// 2.83).
fn sorted_split(refs: &[Ref]) -> Split {
    let n = refs.len();
    let mut order = refs.to_vec();
    let mut right_area = vec![0.0f32; n];
    let mut best = Split::Sorted {
        axis: 0,
        count: n / 2,
        cost: f32::INFINITY,
    };
    for axis in 0..3 {
        order.copy_from_slice(refs);
        sort_on(&mut order, axis);
        let mut right = Bounds::EMPTY;
        for i in (1..n).rev() {
            right = right.union(order[i].b);
            right_area[i] = right.half_area();
        }
        let mut left = Bounds::EMPTY;
        for count in 1..n {
            left = left.union(order[count - 1].b);
            let centre = |i: usize| order[i].b.centre()[axis];
            if centre(count - 1) == centre(count) {
                continue; // as bins would, equal centres stay together
            }
            let cost = left.half_area() * count as f32 + right_area[count] * (n - count) as f32;
            if cost < best.cost() {
                best = Split::Sorted { axis, count, cost };
            }
        }
    }
    best
}

/// Split `refs` by the spatial plane `plane` on `axis`: references on one side go there;
/// a straddling one is split in two, or goes whole to one side where the heuristic says
/// that costs less (Stich et al. §4.4). The references back (`Err`) where a side would be
/// empty or the spare references run out.
#[allow(clippy::too_many_arguments)]
fn spatial_partition(
    ctx: &Context,
    refs: Vec<Ref>,
    node: Bounds,
    axis: usize,
    plane: usize,
    (mut left_box, mut right_box): (Bounds, Bounds),
    (mut nl, mut nr): (usize, usize),
) -> Result<(Vec<Ref>, Vec<Ref>), Vec<Ref>> {
    let planes = Planes::new(node, axis).expect("a spatial split has bins");
    let at = planes.at(plane);
    let mut left = Vec::with_capacity(nl);
    let mut right = Vec::with_capacity(nr);
    let mut straddling = Vec::new();
    for r in &refs {
        let (first, last) = planes.span(ctx, r, axis);
        if last < plane {
            left.push(*r);
        } else if first >= plane {
            right.push(*r);
        } else {
            straddling.push(*r);
        }
    }
    let mut added = 0;
    for r in straddling {
        let (below, above) = ctx.polygon(&r).cut(axis, at);
        let parts = (ctx.part(&r, &below), ctx.part(&r, &above));
        let (lp, rp) = match parts {
            (Some(lp), Some(rp)) => (lp, rp),
            // The triangle's box crosses the plane, the triangle does not.
            (Some(lp), None) => {
                nr -= 1;
                left.push(Ref { b: lp, tri: r.tri });
                continue;
            }
            (None, Some(rp)) => {
                nl -= 1;
                right.push(Ref { b: rp, tri: r.tri });
                continue;
            }
            (None, None) => {
                left.push(r); // rounding: keep it somewhere
                nr -= 1;
                continue;
            }
        };
        let split = left_box.half_area() * nl as f32 + right_box.half_area() * nr as f32;
        let to_left =
            left_box.union(r.b).half_area() * nl as f32 + right_box.half_area() * (nr - 1) as f32;
        let to_right =
            left_box.half_area() * (nl - 1) as f32 + right_box.union(r.b).half_area() * nr as f32;
        if to_left <= split && to_left <= to_right {
            left_box = left_box.union(r.b);
            nr -= 1;
            left.push(r);
        } else if to_right <= split {
            right_box = right_box.union(r.b);
            nl -= 1;
            right.push(r);
        } else {
            added += 1;
            left.push(Ref { b: lp, tri: r.tri });
            right.push(Ref { b: rp, tri: r.tri });
        }
    }
    let reserved = ctx
        .spare_refs
        .try_update(Ordering::Relaxed, Ordering::Relaxed, |spare| {
            spare.checked_sub(added)
        })
        .is_ok();
    if left.is_empty() || right.is_empty() || !reserved {
        if reserved {
            ctx.spare_refs.fetch_add(added, Ordering::Relaxed);
        }
        return Err(refs);
    }
    Ok((left, right))
}

/// Split `refs` in two halves by their centres along the longest extent of the centres:
/// the split when no other separates them (all centres in one bin).
fn median_partition(mut refs: Vec<Ref>) -> (Vec<Ref>, Vec<Ref>) {
    let centres = centres_of(&refs);
    let axis = (centres.hi - centres.lo).max_position();
    let half = refs.len() / 2;
    refs.select_nth_unstable_by(half, |a, b| {
        a.b.centre()[axis].total_cmp(&b.b.centre()[axis])
    });
    let right = refs.split_off(half);
    (refs, right)
}

fn bounds_of(refs: &[Ref]) -> Bounds {
    refs.iter().fold(Bounds::EMPTY, |b, r| b.union(r.b))
}

/// Nodes and leaf references of a subtree under construction: node 0 its root.
struct Out {
    nodes: Vec<Bvh2Node>,
    prims: Vec<u32>,
}

impl Out {
    fn with_root() -> Self {
        Self {
            nodes: vec![Bvh2Node::default()],
            prims: Vec::new(),
        }
    }

    /// Put subtree `sub` in place of node `slot` (its root there, its other nodes at the
    /// end, their indices moved along).
    fn attach(&mut self, slot: usize, sub: Out) {
        let node_offset = self.nodes.len() as u32 - 1;
        let prim_offset = self.prims.len() as u32;
        let moved = |mut n: Bvh2Node| {
            n.first_index += if n.is_leaf() {
                prim_offset
            } else {
                node_offset
            };
            n
        };
        self.nodes[slot] = moved(sub.nodes[0]);
        self.nodes.extend(sub.nodes[1..].iter().map(|&n| moved(n)));
        self.prims.extend(sub.prims);
    }
}

/// Build the subtree of `refs` (in box `node`) into `out`'s node `slot`.
fn build_node(
    ctx: &Context,
    refs: Vec<Ref>,
    node: Bounds,
    depth: usize,
    out: &mut Out,
    slot: usize,
) {
    if refs.len() <= 1 {
        out.nodes[slot] = Bvh2Node::new(node.aabb(), refs.len() as u32, out.prims.len() as u32);
        out.prims.extend(refs.iter().map(|r| r.tri));
        return;
    }
    let many = refs.len() > PARALLEL_REFS;
    let split = if depth < ctx.max_sah_depth {
        best_split(ctx, &refs, node)
    } else {
        None
    };
    let (left, right) = match split {
        Some(Split::Sorted { axis, count, .. }) => {
            let mut refs = refs;
            sort_on(&mut refs, axis);
            let right = refs.split_off(count);
            (refs, right)
        }
        Some(Split::Object {
            axis, bins, last, ..
        }) => {
            let (l, r): (Vec<Ref>, Vec<Ref>) =
                refs.into_iter().partition(|r| bins.bin(r, axis) <= last);
            if l.is_empty() || r.is_empty() {
                median_partition(l.into_iter().chain(r).collect())
            } else {
                (l, r)
            }
        }
        Some(Split::Spatial {
            axis,
            plane,
            left,
            right,
            counts,
            ..
        }) => match spatial_partition(ctx, refs, node, axis, plane, (left, right), counts) {
            Ok(sides) => sides,
            Err(refs) => median_partition(refs),
        },
        None => median_partition(refs),
    };
    let (lb, rb) = (bounds_of(&left), bounds_of(&right));
    let first = out.nodes.len();
    out.nodes.push(Bvh2Node::default());
    out.nodes.push(Bvh2Node::default());
    out.nodes[slot] = Bvh2Node::new(node.aabb(), 0, first as u32);
    if many {
        let sub = |refs: Vec<Ref>, b: Bounds| {
            let mut o = Out::with_root();
            build_node(ctx, refs, b, depth + 1, &mut o, 0);
            o
        };
        let (l, r) = rayon::join(|| sub(left, lb), || sub(right, rb));
        out.attach(first, l);
        out.attach(first + 1, r);
    } else {
        build_node(ctx, left, lb, depth + 1, out, first);
        build_node(ctx, right, rb, depth + 1, out, first + 1);
    }
}

/// The SBVH of `triangles`, one reference per leaf (obvhs's CWBVH conversion gathers
/// leaves). `boxes` are padded boxes, box i around (part of) triangle `refs[i]` (a part
/// where `presplit` split it first); `pad` pads a part's box the same way. Only triangles
/// `splittable` allows, and none of `UNSPLIT_SHARE`'s size, are ever split. The tree's
/// `primitive_indices` are triangle indices, a split triangle's in several leaves.
pub fn build(
    triangles: &[Triangle],
    boxes: &[(Vec3, Vec3)],
    refs: &[u32],
    pad: &(dyn Fn(Vec3, Vec3) -> (Vec3, Vec3) + Sync),
    splittable: &(dyn Fn(&Triangle) -> bool + Sync),
) -> Bvh2 {
    build_to_depth(triangles, boxes, refs, pad, splittable, MAX_SAH_DEPTH)
}

/// `build`, the heuristic choosing the splits down to depth `max_sah_depth`.
fn build_to_depth(
    triangles: &[Triangle],
    boxes: &[(Vec3, Vec3)],
    refs: &[u32],
    pad: &(dyn Fn(Vec3, Vec3) -> (Vec3, Vec3) + Sync),
    splittable: &(dyn Fn(&Triangle) -> bool + Sync),
    max_sah_depth: usize,
) -> Bvh2 {
    let refs: Vec<Ref> = boxes
        .iter()
        .zip(refs)
        .map(|(&(lo, hi), &tri)| Ref {
            b: Bounds { lo, hi },
            tri,
        })
        .collect();
    let root = bounds_of(&refs);
    let small = |t: &Triangle| {
        let (lo, hi) = Polygon::triangle(t).bounds();
        Bounds { lo, hi }.half_area() < UNSPLIT_SHARE * root.half_area()
    };
    let ctx = Context {
        triangles,
        splittable: triangles
            .par_iter()
            .map(|t| splittable(t) && small(t))
            .collect(),
        pad,
        root_area: root.half_area(),
        max_sah_depth,
        spare_refs: AtomicUsize::new(
            ((MAX_REFS_PER_TRIANGLE - 1.0) * triangles.len() as f32) as usize,
        ),
    };
    let mut out = Out::with_root();
    build_node(&ctx, refs, root, 0, &mut out, 0);
    Bvh2 {
        nodes: out.nodes,
        primitive_indices: out.prims,
        uses_spatial_splits: true,
        ..Default::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kernels::rng::Rng;
    use kernels::sampling::uniform_triangle;

    /// A huge ground of two triangles, long diagonal slivers over it, and
    /// small triangles of random size, place and orientation.
    fn scene() -> Vec<Triangle> {
        let v = Vec3::new;
        let mut t = vec![
            Triangle::new(
                v(-50.0, 0.0, -50.0),
                v(50.0, 0.0, -50.0),
                v(-50.0, 0.0, 50.0),
                0,
            ),
            Triangle::new(
                v(50.0, 0.0, -50.0),
                v(50.0, 0.0, 50.0),
                v(-50.0, 0.0, 50.0),
                0,
            ),
        ];
        let mut rng = Rng::from_seed(11);
        let mut random = |lo: f32, hi: f32| lo + (hi - lo) * rng.next_f32();
        // Under 1% of the scene's box each (`UNSPLIT_SHARE`), but 40 times the small ones.
        for _ in 0..40 {
            let (a, b, h) = (random(-40.0, 30.0), random(-40.0, 30.0), random(0.5, 3.0));
            let c = v(a, h, b);
            t.push(Triangle::new(
                c,
                c + v(5.0, 0.2, 8.0),
                c + v(5.0, 0.0, 7.8),
                0,
            ));
        }
        for _ in 0..2000 {
            let p = v(random(-40.0, 40.0), random(0.2, 3.0), random(-40.0, 40.0));
            let size = random(0.1, 0.5);
            let mut corner =
                || p + v(random(-1.0, 1.0), random(-1.0, 1.0), random(-1.0, 1.0)) * size;
            t.push(Triangle::new(corner(), corner(), corner(), 0));
        }
        t
    }

    fn build_of(tris: &[Triangle], splittable: &(dyn Fn(&Triangle) -> bool + Sync)) -> Bvh2 {
        build_with(tris, splittable, MAX_SAH_DEPTH)
    }

    fn build_with(
        tris: &[Triangle],
        splittable: &(dyn Fn(&Triangle) -> bool + Sync),
        max_sah_depth: usize,
    ) -> Bvh2 {
        let pad = |lo: Vec3, hi: Vec3| (lo - Vec3::splat(1e-4), hi + Vec3::splat(1e-4));
        let boxes: Vec<_> = tris
            .iter()
            .map(|t| {
                pad(
                    Polygon::triangle(t).bounds().0,
                    Polygon::triangle(t).bounds().1,
                )
            })
            .collect();
        let refs: Vec<u32> = (0..tris.len() as u32).collect();
        build_to_depth(tris, &boxes, &refs, &pad, splittable, max_sah_depth)
    }

    fn area(a: &Aabb) -> f32 {
        a.half_area()
    }

    /// The tree's surface area cost: inner nodes 1, each reference in a leaf 1, each
    /// weighted by its box's area over the root's (the chance a ray from outside hits it).
    fn sah(bvh: &Bvh2) -> f32 {
        let root = area(&bvh.nodes[0].aabb);
        bvh.nodes
            .iter()
            .map(|n| {
                area(&n.aabb) / root
                    * if n.is_leaf() {
                        n.prim_count as f32
                    } else {
                        1.0
                    }
            })
            .sum()
    }

    fn inside(a: &Aabb, p: Vec3) -> bool {
        Vec3::from(a.min).cmple(p).all() && p.cmple(Vec3::from(a.max)).all()
    }

    /// Nodes of many references bin in parallel chunks (`bin_in_chunks`) without deep
    /// stacks: with the chunks' bins held by value in rayon's reduce (12 KB a level, and a
    /// waiting worker running other nodes' binning on top), 16 workers of 512 KiB stacks
    /// overflowed on grass-1m, and the device machine's 2 MiB ones at times. A stack
    /// overflow aborts the test binary.
    #[test]
    fn builds_on_small_worker_stacks() {
        let mut rng = Rng::from_seed(5);
        let mut random = |lo: f32, hi: f32| lo + (hi - lo) * rng.next_f32();
        let tris: Vec<Triangle> = (0..200_000)
            .map(|_| {
                let p = Vec3::new(random(-50.0, 50.0), random(0.0, 5.0), random(-50.0, 50.0));
                let mut corner =
                    || p + Vec3::new(random(0.0, 0.3), random(0.0, 0.3), random(0.0, 0.3));
                Triangle::new(corner(), corner(), corner(), 0)
            })
            .collect();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(16)
            .stack_size(256 << 10)
            .build()
            .expect("a thread pool");
        let bvh = pool.install(|| build_of(&tris, &|_| true));
        let mut seen: Vec<u32> = bvh.primitive_indices.clone();
        seen.sort_unstable();
        seen.dedup();
        assert_eq!(seen.len(), tris.len(), "every triangle in a leaf");
    }

    #[test]
    fn slivers_are_split_where_it_pays_and_the_ground_never() {
        let tris = scene();
        let bvh = build_of(&tris, &|_| true);
        let whole = build_of(&tris, &|_| false);
        let parts = |i: u32| bvh.primitive_indices.iter().filter(|&&p| p == i).count();
        assert_eq!((parts(0), parts(1)), (1, 1), "the ground is never split");
        let split_slivers = (2..42).filter(|&i| parts(i) > 1).count();
        assert!(split_slivers >= 20, "{split_slivers} of 40 slivers split");
        assert!(bvh.primitive_indices.len() <= 2 * tris.len());
        assert_eq!(whole.primitive_indices.len(), tris.len());
        // The splits are there because they lower the cost.
        let (split, unsplit) = (sah(&bvh), sah(&whole));
        assert!(
            split < 0.98 * unsplit,
            "SAH {split} with splits, {unsplit} without"
        );
    }

    fn depth(bvh: &Bvh2, node: usize) -> usize {
        let n = &bvh.nodes[node];
        if n.is_leaf() {
            return 1;
        }
        let first = n.first_index as usize;
        1 + depth(bvh, first).max(depth(bvh, first + 1))
    }

    #[test]
    fn below_the_depth_limit_the_splits_are_medians() {
        let tris = scene();
        let free = build_of(&tris, &|_| true);
        let n = free.primitive_indices.len() as f32;
        // The heuristic alone goes deeper than median splits below depth 2 would.
        let limited_depth = 2 + n.log2().ceil() as usize + 1;
        assert!(depth(&free, 0) > limited_depth, "{}", depth(&free, 0));
        let limited = build_with(&tris, &|_| true, 2);
        assert!(
            depth(&limited, 0) <= limited_depth,
            "{}",
            depth(&limited, 0)
        );
        let mut seen = limited.primitive_indices.clone();
        seen.sort_unstable();
        seen.dedup();
        assert_eq!(seen.len(), tris.len(), "every triangle in a leaf");
    }

    #[test]
    fn every_point_of_every_triangle_is_in_a_leaf_of_it_inside_its_parents() {
        let tris = scene();
        let bvh = build_of(&tris, &|_| true);
        // Each node's box holds its children's.
        let mut leaves_of = vec![Vec::new(); tris.len()];
        let mut work = vec![0usize];
        while let Some(n) = work.pop() {
            let node = &bvh.nodes[n];
            if node.is_leaf() {
                let first = node.first_index as usize;
                for &t in &bvh.primitive_indices[first..first + node.prim_count as usize] {
                    leaves_of[t as usize].push(node.aabb);
                }
                continue;
            }
            for c in [node.first_index as usize, node.first_index as usize + 1] {
                let child = &bvh.nodes[c].aabb;
                assert!(
                    inside(&node.aabb, child.min.into()) && inside(&node.aabb, child.max.into())
                );
                work.push(c);
            }
        }
        let mut rng = Rng::from_seed(5);
        for (i, t) in tris.iter().enumerate() {
            let (p0, p1, p2) = t.vertices();
            for _ in 0..500 {
                let (u, v) = uniform_triangle(rng.next_f32(), rng.next_f32());
                let p = p0 + (p1 - p0) * u + (p2 - p0) * v;
                assert!(
                    leaves_of[i].iter().any(|b| inside(b, p)),
                    "triangle {i}: {p} in none of its {} leaves",
                    leaves_of[i].len()
                );
            }
        }
    }
}
