//! Occlusion of a bundle of rays from one point, traced together (the CPU backend's
//! ambient occlusion). A point's AO rays all start where the point is, so they visit the
//! same nodes around it (half or more of their node visits, docs/PERFORMANCE.md "Benchmark
//! suite") and part of the way out. Walked one at a time, each ray's node test waits on the load of
//! the node it chose before; walked together, a node is read once for all the rays of the
//! bundle that enter it, while the next one is fetched, and those rays' tests of it are
//! independent of each other, which the CPU runs side by side. Once only one ray of the
//! bundle is left in a subtree (the rays have spread out: most node reads far from the
//! point), it walks that subtree alone (`Bundle::lone_walk`), without the masks. The GPU
//! keeps one ray per thread (`SceneBuffers::trace_pool`).
//!
//! The answer is the same as each ray's own any-hit walk: whether a ray meets a solid
//! triangle before its end does not depend on the order the triangles are tried in. Only
//! the number of node visits differs (an occluded ray may be carried into nodes a
//! front-to-back walk would have stopped before).
use crate::bvh::{count, cwbvh_octant_inv, cwbvh_traverse, safe_recip, Cutouts, CWBVH_STACK};
use crate::glam::{UVec4, Vec3};
use crate::intersect::{Ray, TriangleTester};
use crate::skip::Skip;
use crate::types::cwbvh_meta;
use crate::types::{CwBvhPlanes, Triangle};

/// Rays in one bundle: one bit each of a `u64` mask.
pub const BUNDLE_RAYS: usize = 64;

/// Nodes waiting in a bundle walk: every child entered is pushed (with the rays that
/// entered it), at most 7 waiting siblings per level of a tree of at most `CWBVH_STACK`
/// levels, and the root.
const BUNDLE_STACK: usize = 7 * CWBVH_STACK + 1;

/// The bits of the first `n` rays.
fn first_rays(n: usize) -> u64 {
    if n >= BUNDLE_RAYS {
        u64::MAX
    } else {
        (1u64 << n) - 1
    }
}

/// Which of `rays` (at most `BUNDLE_RAYS`, all from one origin) meet a solid triangle
/// before `t_max`, as bit k for ray k, over a CWBVH of decoded nodes (the CPU's
/// `TraversalNode`). The triangles of `skip` (which the rays cannot meet) are never
/// tested, as in `CwbvhWalk`.
pub fn cwbvh_occluded<const PLAIN: bool>(
    triangles: &[UVec4],
    cutouts: &Cutouts,
    nodes: &[UVec4],
    rays: &[Ray],
    skip: Skip,
    t_max: f32,
) -> u64 {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx") && std::is_x86_feature_detected!("popcnt") {
        // SAFETY: the CPU has both (checked just now).
        return unsafe { occluded_avx::<PLAIN>(triangles, cutouts, nodes, rays, skip, t_max) };
    }
    walk::<PLAIN, false>(triangles, cutouts, nodes, rays, skip, t_max)
}

/// `cwbvh_occluded` as a CPU without AVX runs it, whatever this one has (for the tests,
/// which hold both walks to brute force).
pub fn cwbvh_occluded_without_avx<const PLAIN: bool>(
    triangles: &[UVec4],
    cutouts: &Cutouts,
    nodes: &[UVec4],
    rays: &[Ray],
    skip: Skip,
    t_max: f32,
) -> u64 {
    walk::<PLAIN, false>(triangles, cutouts, nodes, rays, skip, t_max)
}

/// `walk` compiled for CPUs with AVX and popcount, with `RayLanes`' AVX tests: its bit
/// counts are one instruction each (a dozen without popcount) and the edge pre-filter
/// inlines into it. (The slot tests stay calls: a function with a target feature cannot
/// be always inlined, and without one the intrinsics in it became calls: 4× slower.)
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,popcnt")]
unsafe fn occluded_avx<const PLAIN: bool>(
    triangles: &[UVec4],
    cutouts: &Cutouts,
    nodes: &[UVec4],
    rays: &[Ray],
    skip: Skip,
    t_max: f32,
) -> u64 {
    walk::<PLAIN, true>(triangles, cutouts, nodes, rays, skip, t_max)
}

/// `cwbvh_occluded`'s walk; `AVX`: with `RayLanes`' AVX tests, only where the CPU has AVX
/// (`occluded_avx`).
#[inline(always)]
fn walk<const PLAIN: bool, const AVX: bool>(
    triangles: &[UVec4],
    cutouts: &Cutouts,
    nodes: &[UVec4],
    rays: &[Ray],
    skip: Skip,
    t_max: f32,
) -> u64 {
    let n = rays.len().min(BUNDLE_RAYS);
    let all = first_rays(n);
    if nodes.is_empty() || n == 0 {
        return 0;
    }
    let origin = rays[0].origin;
    debug_assert!(rays[..n].iter().all(|r| r.origin == origin), "one origin");
    let mut inv_dir = [Vec3::ZERO; BUNDLE_RAYS];
    let mut testers = [TriangleTester::new(&rays[0]); BUNDLE_RAYS];
    for (k, ray) in rays[..n].iter().enumerate() {
        count!(TRAVERSALS);
        inv_dir[k] = safe_recip(ray.dir);
        testers[k] = TriangleTester::new(ray);
    }
    let lanes = RayLanes::<AVX>::new(&inv_dir, &testers[..n]);
    let bundle = Bundle {
        triangles,
        cutouts,
        nodes,
        lanes: &lanes,
        testers: &testers,
        inv_dir: &inv_dir,
        origin,
        skip,
        t_max,
    };
    let mut occluded = 0u64;
    let mut stack = [(0u32, 0u64); BUNDLE_STACK];
    // The lone walks' stack, one for the bundle.
    let mut lone_stack = [0u32; BUNDLE_STACK];
    stack[0] = (0, all);
    let mut sp = 1;
    while sp > 0 {
        sp -= 1;
        let (index, entered) = stack[sp];
        let mut open = entered & !occluded;
        if open == 0 {
            continue;
        }
        // The next node's load starts now, behind this node's tests of every ray.
        if sp > 0 {
            prefetch(
                nodes,
                stack[sp - 1].0 as usize * CwBvhPlanes::WORDS,
                CwBvhPlanes::WORDS,
            );
        }
        if open & (open - 1) == 0 {
            // One ray left in this subtree (most node reads where the rays have spread
            // out: 76% on shell-1m): it walks the subtree alone, without the bundle's
            // masks and their transpose.
            let k = open.trailing_zeros() as usize;
            let blocked = bundle
                .lone_walk::<PLAIN>(k, rays[k].dir, index, &mut lone_stack)
                .unwrap_or_else(|| {
                    one_at_a_time::<PLAIN>(triangles, cutouts, nodes, rays, open, t_max) != 0
                });
            if blocked {
                occluded |= open;
                if occluded & all == all {
                    return all;
                }
            }
            continue;
        }
        let node = CwBvhPlanes::get(nodes, index);
        // Each ray's slab tests, turned around into the rays that enter each slot.
        let filled = filled_slots(node);
        let slot_rays = if let Some(rays) = lanes.slot_rays(node, origin, open, filled, t_max) {
            rays
        } else if let Some(ray_slots) = lanes.ray_slots(node, origin, open, filled, t_max) {
            transpose(&ray_slots)
        } else {
            let mut ray_slots = [0u8; BUNDLE_RAYS];
            while open != 0 {
                let k = open.trailing_zeros() as usize;
                open &= open - 1;
                // Counted per ray, as its own walk (and the GPU's) visits the node.
                count!(NODES);
                ray_slots[k] = (node.slot_hits(origin, inv_dir[k], t_max) & filled) as u8;
            }
            transpose(&ray_slots)
        };
        // The slots some ray entered, as bits: walked bit by bit, where a loop over all 8
        // slots mispredicted a branch on each.
        let entered_slots = (0..8).fold(0u32, |m, s| m | ((slot_rays[s] != 0) as u32) << s);
        // Leaves first: a ray found blocked there enters none of the nodes below.
        let mut leaf_slots = entered_slots & !node.imask;
        while leaf_slots != 0 {
            let slot = leaf_slots.trailing_zeros() as usize;
            leaf_slots &= leaf_slots - 1;
            for prim in leaf_triangles(node, slot) {
                let open = slot_rays[slot] & !occluded;
                if open != 0 && !skip.holds(prim) {
                    occluded |= bundle.blocked::<PLAIN>(prim, open);
                }
            }
        }
        if occluded & all == all {
            return all;
        }
        let mut inner_slots = entered_slots & node.imask;
        while inner_slots != 0 {
            let slot = inner_slots.trailing_zeros() as usize;
            inner_slots &= inner_slots - 1;
            if sp == BUNDLE_STACK {
                // Deeper than the host ever builds (`CWBVH_STACK` levels): the rays not yet
                // decided walk one at a time instead.
                let rest = all & !occluded;
                return occluded
                    | one_at_a_time::<PLAIN>(triangles, cutouts, nodes, rays, rest, t_max);
            }
            stack[sp] = (interior_child(node, slot as u32), slot_rays[slot]);
            sp += 1;
        }
    }
    occluded
}

/// Meta byte of a node's slot (`cwbvh_meta`; 0: empty).
#[inline(always)]
fn slot_meta(node: &CwBvhPlanes, slot: usize) -> u32 {
    (node.child_meta[slot / 4] >> (8 * (slot % 4))) & 0xff
}

/// The slots of `node` that hold a child, as bits.
#[inline(always)]
fn filled_slots(node: &CwBvhPlanes) -> u32 {
    (0..8).fold(0u32, |f, slot| {
        f | ((slot_meta(node, slot) != 0) as u32) << slot
    })
}

/// The triangles of leaf slot `slot`.
#[inline(always)]
fn leaf_triangles(node: &CwBvhPlanes, slot: usize) -> core::ops::Range<u32> {
    let m = slot_meta(node, slot);
    let first = node.primitive_base_idx + cwbvh_meta::index(m);
    first..first + cwbvh_meta::triangle_bits(m).count_ones()
}

/// The node index of interior slot `slot`: interior children are stored in slot order
/// from the child base.
#[inline(always)]
fn interior_child(node: &CwBvhPlanes, slot: u32) -> u32 {
    node.child_base_idx + (node.imask & ((1u32 << slot) - 1)).count_ones()
}

/// What a bundle's walk reads: the scene and its rays' set-up.
struct Bundle<'a, const AVX: bool> {
    triangles: &'a [UVec4],
    cutouts: &'a Cutouts<'a>,
    nodes: &'a [UVec4],
    lanes: &'a RayLanes<AVX>,
    testers: &'a [TriangleTester; BUNDLE_RAYS],
    /// Each ray's reciprocal direction (the slab tests without `RayLanes`).
    inv_dir: &'a [Vec3; BUNDLE_RAYS],
    origin: Vec3,
    /// Triangles the rays cannot meet, never tested.
    skip: Skip,
    t_max: f32,
}

impl<const AVX: bool> Bundle<'_, AVX> {
    /// The rays of `open` that triangle `prim` blocks (a solid hit before the rays' end).
    #[inline(always)]
    fn blocked<const PLAIN: bool>(&self, prim: u32, open: u64) -> u64 {
        let tri = Triangle::get(self.triangles, prim);
        for _ in 0..open.count_ones() {
            count!(TRIANGLES);
        }
        let mut candidates = self.lanes.edge_candidates(tri, self.origin, open);
        let mut blocked = 0u64;
        while candidates != 0 {
            let k = candidates.trailing_zeros() as usize;
            candidates &= candidates - 1;
            let hit = self
                .cutouts
                .solid_hit::<PLAIN>(&self.testers[k], tri, self.t_max);
            blocked |= (hit.is_some() as u64) << k;
        }
        blocked
    }

    /// Whether ray `k` (direction `dir`) meets a solid triangle in the subtree at node
    /// `root`: its own any-hit walk, a node index per stack entry, leaves first and then
    /// the children front to back (by `cwbvh_octant_inv`). None where the subtree is deeper
    /// than `stack` holds.
    #[inline(always)]
    fn lone_walk<const PLAIN: bool>(
        &self,
        k: usize,
        dir: Vec3,
        root: u32,
        stack: &mut [u32; BUNDLE_STACK],
    ) -> Option<bool> {
        let ray = 1u64 << k;
        let oct_inv = cwbvh_octant_inv(dir);
        stack[0] = root;
        let mut sp = 1;
        while sp > 0 {
            sp -= 1;
            let node = CwBvhPlanes::get(self.nodes, stack[sp]);
            if sp > 0 {
                let next = stack[sp - 1] as usize * CwBvhPlanes::WORDS;
                prefetch(self.nodes, next, CwBvhPlanes::WORDS);
            }
            let filled = filled_slots(node);
            let slots = match self
                .lanes
                .ray_slots(node, self.origin, ray, filled, self.t_max)
            {
                Some(ray_slots) => ray_slots[k] as u32,
                None => {
                    count!(NODES);
                    node.slot_hits(self.origin, self.inv_dir[k], self.t_max) & filled
                }
            };
            let mut leaf_slots = slots & !node.imask;
            while leaf_slots != 0 {
                let slot = leaf_slots.trailing_zeros() as usize;
                leaf_slots &= leaf_slots - 1;
                for prim in leaf_triangles(node, slot) {
                    if !self.skip.holds(prim) && self.blocked::<PLAIN>(prim, ray) != 0 {
                        return Some(true);
                    }
                }
            }
            // The entered children by priority (slot XOR octant), pushed lowest first so
            // that the nearest is popped next.
            let mut rest = slots & node.imask;
            let mut by_priority = 0u32;
            while rest != 0 {
                by_priority |= 1 << (rest.trailing_zeros() ^ oct_inv);
                rest &= rest - 1;
            }
            while by_priority != 0 {
                let slot = by_priority.trailing_zeros() ^ oct_inv;
                by_priority &= by_priority - 1;
                if sp == BUNDLE_STACK {
                    return None;
                }
                stack[sp] = interior_child(node, slot);
                sp += 1;
            }
        }
        Some(false)
    }
}

/// Nodes entered by at least this many rays are tested a slot at a time for 8 rays at once
/// (`RayLanes`); fewer rays, each ray against the 8 slots.
const DENSE_RAYS: u32 = 32;

/// The bundle's rays laid out for AVX tests: reciprocal directions by axis (one slot against
/// 8 rays in a register) and the watertight set-up (`edge_candidates`). Without `AVX` (a
/// CPU without it) each test declines and the bundle tests a ray at a time; `AVX` is set
/// only in `occluded_avx`, which runs where the CPU has AVX.
struct RayLanes<const AVX: bool> {
    inv: [[f32; BUNDLE_RAYS]; 3],
    /// Each ray's watertight set-up for `edge_candidates`: the axes (kx, ky, kz, kz) that
    /// permute a vertex, and the shear (sx, sy, 0, 0). `edges` is false where the triangle
    /// test in use is not the watertight one.
    edges: bool,
    axes: [[u32; 4]; BUNDLE_RAYS],
    shear: [[f32; 4]; BUNDLE_RAYS],
}

impl<const AVX: bool> RayLanes<AVX> {
    fn new(inv_dir: &[Vec3; BUNDLE_RAYS], testers: &[TriangleTester]) -> Self {
        let mut inv = [[0.0; BUNDLE_RAYS]; 3];
        let mut axes = [[0; 4]; BUNDLE_RAYS];
        let mut shear = [[0.0; 4]; BUNDLE_RAYS];
        // Without AVX no test reads the lanes: the walk tests a ray at a time.
        if !AVX {
            return Self {
                inv,
                edges: false,
                axes,
                shear,
            };
        }
        for (k, d) in inv_dir.iter().enumerate() {
            inv[0][k] = d.x;
            inv[1][k] = d.y;
            inv[2][k] = d.z;
        }
        let mut edges = true;
        for (k, tester) in testers.iter().enumerate() {
            match tester.watertight() {
                Some(wr) => {
                    axes[k] = [wr.kx, wr.ky, wr.kz, wr.kz];
                    shear[k] = [wr.shear.x, wr.shear.y, 0.0, 0.0];
                }
                None => edges = false,
            }
        }
        Self {
            inv,
            edges,
            axes,
            shear,
        }
    }

    /// The rays of `open` that may meet `tri`: all but those whose three edge functions
    /// have opposite signs, which the watertight test rejects before anything else. The
    /// same edge functions as `intersect::intersect_watertight` on the same numbers (the
    /// vertices relative to the shared origin, permuted and sheared per ray), a ray at a
    /// time in SSE registers without a branch: a ray ruled out here is one that test
    /// rejects, and the test decides the rest. Most triangles an AO ray tests it misses,
    /// most of them are ruled out here, and the scalar test's branches on the ray's axes
    /// and on the edges' order, which change from one ray of the bundle to the next,
    /// mispredicted. Without AVX, or with another triangle test, all of `open`.
    #[inline(always)]
    fn edge_candidates(&self, tri: &Triangle, origin: Vec3, open: u64) -> u64 {
        if !AVX || !self.edges {
            return open;
        }
        #[cfg(target_arch = "x86_64")]
        {
            // SAFETY: `AVX` only in `occluded_avx`, run where the CPU has AVX.
            unsafe { self.edge_candidates_avx(tri, origin, open) }
        }
        #[cfg(not(target_arch = "x86_64"))]
        open
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn edge_candidates_avx(&self, tri: &Triangle, origin: Vec3, mut open: u64) -> u64 {
        use core::arch::x86_64::*;
        // The vertices relative to the origin, as `intersect_watertight` computes them.
        let (p0, p1, p2) = tri.vertices();
        let rel = |p: Vec3| {
            let v = p - origin;
            _mm_setr_ps(v.x, v.y, v.z, 0.0)
        };
        let (a, b, c) = (rel(p0), rel(p1), rel(p2));
        let zero = _mm_setzero_ps();
        let mut candidates = 0u64;
        while open != 0 {
            let k = open.trailing_zeros() as usize;
            open &= open - 1;
            let axes = _mm_loadu_si128(self.axes[k].as_ptr() as *const __m128i);
            let shear = _mm_loadu_ps(self.shear[k].as_ptr());
            // (x − sx·z, y − sy·z, ·, ·) of a vertex permuted to (x, y, z, z).
            let sheared = |v| {
                let v = _mm_permutevar_ps(v, axes);
                _mm_sub_ps(v, _mm_mul_ps(shear, _mm_shuffle_ps::<0b1010_1010>(v, v)))
            };
            let (sa, sb, sc) = (sheared(a), sheared(b), sheared(c));
            // x = (ax, bx, cx, cx), y = (ay, by, cy, cy).
            let ab = _mm_unpacklo_ps(sa, sb);
            let x = _mm_shuffle_ps::<0b00_00_01_00>(ab, sc);
            let y = _mm_shuffle_ps::<0b01_01_11_10>(ab, sc);
            // Edges u (c → b), v (a → c), w (b → a): p = (c, a, b), q = (b, c, a).
            let (px, py) = (
                _mm_shuffle_ps::<0b11_01_00_10>(x, x),
                _mm_shuffle_ps::<0b11_01_00_10>(y, y),
            );
            let (qx, qy) = (
                _mm_shuffle_ps::<0b11_00_10_01>(x, x),
                _mm_shuffle_ps::<0b11_00_10_01>(y, y),
            );
            // `edge_function`: both products rounded (its XOR with zero is for the GPU's
            // compiler, which might fuse them), so px·qy − py·qx and −(qx·py − qy·px)
            // round the same (products commute, a − b = −(b − a)), up to the sign of a
            // zero, which the sign test ignores.
            let e = _mm_sub_ps(_mm_mul_ps(px, qy), _mm_mul_ps(py, qx));
            let negative = _mm_movemask_ps(_mm_cmplt_ps(e, zero)) & 0b111;
            let positive = _mm_movemask_ps(_mm_cmpgt_ps(e, zero)) & 0b111;
            if negative == 0 || positive == 0 {
                candidates |= 1u64 << k;
            }
        }
        candidates
    }

    /// The rays of `open` that enter each slot of `filled`, for a node that at least
    /// `DENSE_RAYS` of them entered; None where that is not this test's case.
    #[inline(always)]
    fn slot_rays(
        &self,
        node: &CwBvhPlanes,
        origin: Vec3,
        open: u64,
        filled: u32,
        t_max: f32,
    ) -> Option<[u64; 8]> {
        if !AVX || open.count_ones() < DENSE_RAYS {
            return None;
        }
        #[cfg(target_arch = "x86_64")]
        {
            for _ in 0..open.count_ones() {
                count!(NODES);
            }
            // SAFETY: `AVX` only in `occluded_avx`, run where the CPU has AVX.
            Some(unsafe { self.slot_rays_avx(node, origin, open, filled, t_max) })
        }
        #[cfg(not(target_arch = "x86_64"))]
        None
    }

    /// The slots of `filled` that each ray of `open` enters (bit s of entry k), for a node
    /// that fewer than `DENSE_RAYS` of them entered: a ray's 8 slots in one AVX register.
    /// None without AVX.
    #[inline(always)]
    fn ray_slots(
        &self,
        node: &CwBvhPlanes,
        origin: Vec3,
        open: u64,
        filled: u32,
        t_max: f32,
    ) -> Option<[u8; BUNDLE_RAYS]> {
        if !AVX {
            return None;
        }
        #[cfg(target_arch = "x86_64")]
        {
            for _ in 0..open.count_ones() {
                count!(NODES);
            }
            // SAFETY: `AVX` only in `occluded_avx`, run where the CPU has AVX.
            Some(unsafe { self.ray_slots_avx(node, origin, open, filled, t_max) })
        }
        #[cfg(not(target_arch = "x86_64"))]
        None
    }

    /// `ray_slots` with the node's 8 slots of each plane in one AVX register: the same
    /// operations on the same numbers as `CwBvhPlanes::slot_hits` (see `slot_rays_avx`).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn ray_slots_avx(
        &self,
        node: &CwBvhPlanes,
        origin: Vec3,
        mut open: u64,
        filled: u32,
        t_max: f32,
    ) -> [u8; BUNDLE_RAYS] {
        use core::arch::x86_64::*;
        let rel = crate::math::vec3(node.p) - origin;
        let planes = |p: &[crate::glam::Vec4; 2]| _mm256_loadu_ps(p.as_ptr() as *const f32);
        let (min_x, max_x) = (planes(&node.child_min_x), planes(&node.child_max_x));
        let (min_y, max_y) = (planes(&node.child_min_y), planes(&node.child_max_y));
        let (min_z, max_z) = (planes(&node.child_min_z), planes(&node.child_max_z));
        let (zero, limit) = (_mm256_setzero_ps(), _mm256_set1_ps(t_max));
        let mut ray_slots = [0u8; BUNDLE_RAYS];
        while open != 0 {
            let k = open.trailing_zeros() as usize;
            open &= open - 1;
            // One axis: the entry and exit t of the 8 slots, by the ray's direction's sign.
            // `slab_axis` and `slab_lanes` written out: used here, they left a plane to be
            // reloaded from the stack for every ray (3-4% slower on grass-1m, spheres-1m).
            let axis = |lo, hi, inv: f32, rel: f32| {
                let negative = _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_set1_ps(inv), zero);
                let (inv, offset) = (_mm256_set1_ps(inv), _mm256_set1_ps(rel * inv));
                let near = _mm256_blendv_ps(lo, hi, negative);
                let far = _mm256_blendv_ps(hi, lo, negative);
                (
                    _mm256_add_ps(_mm256_mul_ps(near, inv), offset),
                    _mm256_add_ps(_mm256_mul_ps(far, inv), offset),
                )
            };
            let (x0, x1) = axis(min_x, max_x, self.inv[0][k], rel.x);
            let (y0, y1) = axis(min_y, max_y, self.inv[1][k], rel.y);
            let (z0, z1) = axis(min_z, max_z, self.inv[2][k], rel.z);
            let t_near = _mm256_max_ps(_mm256_max_ps(_mm256_max_ps(x0, y0), z0), zero);
            let t_far = _mm256_min_ps(_mm256_min_ps(_mm256_min_ps(x1, y1), z1), limit);
            let hit = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OS>(t_near, t_far)) as u32;
            ray_slots[k] = (hit & filled) as u8;
        }
        ray_slots
    }

    /// The rays of `open` that enter each slot of `filled`, a slot at a time for 8 rays:
    /// the rays' reciprocal directions of an axis in one AVX register. `slab_axis` and
    /// `slab_lanes` compute `CwBvhPlanes::slot_hits`' t on the same numbers, so the same
    /// hits to the bit.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn slot_rays_avx(
        &self,
        node: &CwBvhPlanes,
        origin: Vec3,
        open: u64,
        filled: u32,
        t_max: f32,
    ) -> [u64; 8] {
        use core::arch::x86_64::*;
        let rel = crate::math::vec3(node.p) - origin;
        let plane = |planes: &[crate::glam::Vec4; 2], slot: usize| planes[slot / 4][slot % 4];
        let mut slot_rays = [0u64; 8];
        for group in 0..BUNDLE_RAYS / 8 {
            let active = (open >> (8 * group)) & 0xff;
            if active == 0 {
                continue;
            }
            let load = |axis: usize| _mm256_loadu_ps(self.inv[axis][8 * group..].as_ptr());
            let (ix, iy, iz) = (load(0), load(1), load(2));
            let zero = _mm256_setzero_ps();
            let (nx, ny, nz) = (
                _mm256_cmp_ps::<_CMP_LT_OQ>(ix, zero),
                _mm256_cmp_ps::<_CMP_LT_OQ>(iy, zero),
                _mm256_cmp_ps::<_CMP_LT_OQ>(iz, zero),
            );
            let (ox, oy, oz) = (
                _mm256_mul_ps(_mm256_set1_ps(rel.x), ix),
                _mm256_mul_ps(_mm256_set1_ps(rel.y), iy),
                _mm256_mul_ps(_mm256_set1_ps(rel.z), iz),
            );
            let limit = _mm256_set1_ps(t_max);
            let mut slots = filled;
            while slots != 0 {
                let slot = slots.trailing_zeros() as usize;
                slots &= slots - 1;
                // The slot's planes, in every lane.
                let planes = |min: &[crate::glam::Vec4; 2], max: &[crate::glam::Vec4; 2]| {
                    (
                        _mm256_set1_ps(plane(min, slot)),
                        _mm256_set1_ps(plane(max, slot)),
                    )
                };
                let (lo_x, hi_x) = planes(&node.child_min_x, &node.child_max_x);
                let (lo_y, hi_y) = planes(&node.child_min_y, &node.child_max_y);
                let (lo_z, hi_z) = planes(&node.child_min_z, &node.child_max_z);
                let hit = slab_lanes(
                    slab_axis(lo_x, hi_x, nx, ix, ox),
                    slab_axis(lo_y, hi_y, ny, iy, oy),
                    slab_axis(lo_z, hi_z, nz, iz, oz),
                    limit,
                ) as u64;
                slot_rays[slot] |= (hit & active) << (8 * group);
            }
        }
        slot_rays
    }
}

/// One axis of a slab test in 8 AVX lanes: the entry and exit t through planes `lo` and
/// `hi`, the near one picked by the lanes' `negative` directions, t = plane · (1/d) + (p −
/// o)/d without a fused multiply-add — `decoded_slab_hits`' operations, so the same t.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
#[inline]
unsafe fn slab_axis(
    lo: core::arch::x86_64::__m256,
    hi: core::arch::x86_64::__m256,
    negative: core::arch::x86_64::__m256,
    inv: core::arch::x86_64::__m256,
    offset: core::arch::x86_64::__m256,
) -> (core::arch::x86_64::__m256, core::arch::x86_64::__m256) {
    use core::arch::x86_64::*;
    let near = _mm256_blendv_ps(lo, hi, negative);
    let far = _mm256_blendv_ps(hi, lo, negative);
    (
        _mm256_add_ps(_mm256_mul_ps(near, inv), offset),
        _mm256_add_ps(_mm256_mul_ps(far, inv), offset),
    )
}

/// The lanes whose boxes are entered before `limit`, from their three axes' (entry, exit):
/// max and min in `decoded_slab_hits`' operand order, so the same hits to the bit.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
#[inline]
unsafe fn slab_lanes(
    x: (core::arch::x86_64::__m256, core::arch::x86_64::__m256),
    y: (core::arch::x86_64::__m256, core::arch::x86_64::__m256),
    z: (core::arch::x86_64::__m256, core::arch::x86_64::__m256),
    limit: core::arch::x86_64::__m256,
) -> u32 {
    use core::arch::x86_64::*;
    let zero = _mm256_setzero_ps();
    let t_near = _mm256_max_ps(_mm256_max_ps(_mm256_max_ps(x.0, y.0), z.0), zero);
    let t_far = _mm256_min_ps(_mm256_min_ps(_mm256_min_ps(x.1, y.1), z.1), limit);
    _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OS>(t_near, t_far)) as u32
}

/// The rays of each slot (bit k of entry s: ray k entered slot s) from the slots of each
/// ray (bit s of entry k): an 8 × 64 bit-matrix transpose, without a branch per bit.
#[inline(always)]
fn transpose(ray_slots: &[u8; BUNDLE_RAYS]) -> [u64; 8] {
    let mut slot_rays = [0u64; 8];
    #[cfg(target_arch = "x86_64")]
    {
        use core::arch::x86_64::*;
        // 16 rays at a time: shifting each 16-bit lane left by 7 − s puts bit s of both its
        // bytes at their top bits, which movemask gathers, one bit per ray.
        for (group, rays) in ray_slots.as_chunks::<16>().0.iter().enumerate() {
            // SAFETY: SSE2 is part of x86-64; the load reads the 16 bytes of `rays`.
            unsafe {
                let v = _mm_loadu_si128(rays.as_ptr() as *const __m128i);
                for (slot, out) in slot_rays.iter_mut().enumerate() {
                    let top = _mm_sll_epi16(v, _mm_cvtsi32_si128(7 - slot as i32));
                    *out |= (_mm_movemask_epi8(top) as u32 as u64) << (16 * group);
                }
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    for (k, &slots) in ray_slots.iter().enumerate() {
        for (slot, out) in slot_rays.iter_mut().enumerate() {
            *out |= (((slots >> slot) & 1) as u64) << k;
        }
    }
    slot_rays
}

/// Ask the CPU to bring `count` words from word `first` of `words` into its cache.
#[inline(always)]
fn prefetch(words: &[UVec4], first: usize, count: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use core::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        // Four 16-byte words to a 64-byte cache line.
        let mut k = first;
        while k < (first + count).min(words.len()) {
            // SAFETY: k is inside `words`; a prefetch reads nothing the program sees.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(words.as_ptr().add(k) as *const i8) };
            k += 4;
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (words, first, count);
}

/// The rays of mask `open` walked one at a time from the root (`bvh::cwbvh_traverse`; it
/// tests the triangle they leave too, which they cannot meet).
fn one_at_a_time<const PLAIN: bool>(
    triangles: &[UVec4],
    cutouts: &Cutouts,
    nodes: &[UVec4],
    rays: &[Ray],
    mut open: u64,
    t_max: f32,
) -> u64 {
    let mut occluded = 0u64;
    while open != 0 {
        let k = open.trailing_zeros() as usize;
        open &= open - 1;
        let hit =
            cwbvh_traverse::<PLAIN, CwBvhPlanes>(triangles, cutouts, nodes, &rays[k], t_max, true);
        if hit.is_hit() {
            occluded |= 1u64 << k;
        }
    }
    occluded
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::intersect::{intersect_watertight, WatertightRay};
    use crate::rng::Rng;

    /// The rays of a bundle from `origin` that `intersect_watertight` finds meeting `tri`
    /// (anywhere in front), and those `edge_candidates` keeps.
    fn hits_and_candidates(lanes: &RayLanes<true>, rays: &[Ray], tri: &Triangle) -> (u64, u64) {
        let hits = rays.iter().enumerate().fold(0u64, |m, (k, ray)| {
            let hit = intersect_watertight(&WatertightRay::new(ray), tri, 0.0, f32::INFINITY);
            m | (hit.is_some() as u64) << k
        });
        (
            hits,
            lanes.edge_candidates(tri, rays[0].origin, first_rays(rays.len())),
        )
    }

    fn lanes(rays: &[Ray]) -> RayLanes<true> {
        let mut inv_dir = [Vec3::ZERO; BUNDLE_RAYS];
        for (k, ray) in rays.iter().enumerate() {
            inv_dir[k] = safe_recip(ray.dir);
        }
        let testers: Vec<_> = rays.iter().map(TriangleTester::new).collect();
        RayLanes::new(&inv_dir, &testers)
    }

    /// The edge pre-filter never rules out a ray the watertight test accepts: on a grid
    /// of triangles whose shared vertices and edges the rays pass through exactly (axis
    /// and diagonal directions, where projected vertices tie and an edge function is 0),
    /// and on random triangles and rays. It must also rule out most
    /// misses, or it would be no filter.
    #[test]
    fn edge_candidates_keep_every_hit() {
        #[cfg(target_arch = "x86_64")]
        let avx = std::is_x86_feature_detected!("avx");
        #[cfg(not(target_arch = "x86_64"))]
        let avx = false;
        if !avx || !lanes(&[Ray::new(Vec3::ZERO, Vec3::X)]).edges {
            return; // The filter is off: it keeps every ray.
        }
        let mut rng = Rng::from_seed(7);
        let (mut tests, mut kept, mut hits_seen) = (0u32, 0u32, 0u32);
        let mut check = |rays: &[Ray], tri: &Triangle| {
            let (hits, candidates) = hits_and_candidates(&lanes(rays), rays, tri);
            assert_eq!(hits & !candidates, 0, "a hit ruled out: {tri:?} {rays:?}");
            tests += rays.len() as u32;
            kept += candidates.count_ones();
            hits_seen += hits.count_ones();
        };
        // A unit grid in the plane z = 2, each square split along one diagonal or the
        // other; rays from the origin at its vertices, edge midpoints and square centres.
        let mut grid = Vec::new();
        for i in -3..3 {
            for j in -3..3 {
                let v = |x: i32, y: i32| Vec3::new(x as f32, y as f32, 2.0);
                let (a, b, c, d) = (v(i, j), v(i + 1, j), v(i + 1, j + 1), v(i, j + 1));
                if (i + j) % 2 == 0 {
                    grid.extend([Triangle::new(a, b, c, 0), Triangle::new(a, c, d, 0)]);
                } else {
                    grid.extend([Triangle::new(a, b, d, 0), Triangle::new(b, c, d, 0)]);
                }
            }
        }
        let targets: Vec<Vec3> = (-6..=6)
            .flat_map(|x| (-6..=6).map(move |y| Vec3::new(x as f32 * 0.5, y as f32 * 0.5, 2.0)))
            .collect();
        for origin in [
            Vec3::ZERO,
            Vec3::new(0.5, 0.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
        ] {
            let rays: Vec<Ray> = targets
                .iter()
                .map(|&t| Ray::new(origin, t - origin))
                .collect();
            for chunk in rays.chunks(BUNDLE_RAYS) {
                for tri in &grid {
                    check(chunk, tri);
                }
            }
        }
        // Random triangles (some with axis-aligned edges) and rays about them.
        for _ in 0..2000 {
            let mut point = || {
                let mut p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 4.0;
                if rng.next_f32() < 0.3 {
                    p = p.round();
                }
                p - Vec3::splat(2.0)
            };
            let tri = Triangle::new(point(), point(), point(), 0);
            let origin =
                Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 6.0 - Vec3::splat(3.0);
            let rays: Vec<Ray> = (0..BUNDLE_RAYS)
                .map(|_| {
                    let (p0, p1, p2) = tri.vertices();
                    let (u, v) = (rng.next_f32() * 1.4 - 0.2, rng.next_f32() * 1.4 - 0.2);
                    Ray::new(origin, p0 + u * (p1 - p0) + v * (p2 - p0) - origin)
                })
                .collect();
            check(&rays, &tri);
        }
        assert!(
            hits_seen > tests / 10,
            "too few hits to test: {hits_seen} of {tests}"
        );
        assert!(
            kept < (tests - hits_seen) / 2 + hits_seen,
            "the filter kept {kept} of {tests}"
        );
    }
}
