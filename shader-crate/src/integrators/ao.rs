//! Ambient occlusion, the course's first integrator: the fraction of cosine-weighted
//! directions around a visible point that escape within `ao_distance`.
//!
//! The CPU backend runs a pixel at a time (`render_pixel`), its point's rays traced
//! together in bundles (`bundle`). The GPU runs a workgroup at a time
//! (`render_group_pixel`): its threads trace their camera rays, put the AO rays of every
//! hit into one pool in workgroup memory, and all take rays from that pool until it is
//! empty. A thread whose pixel saw the sky, or whose rays were short, then traces rays of
//! its neighbours instead of idling while its warp finishes theirs. Each ray is a pure
//! function of (pixel, sample, ray index) and each one's answer does not depend on how it
//! is traced, so both give the same pixels.
use crate::bits::{shl, shr};
#[cfg(not(target_arch = "spirv"))]
use crate::bundle::BUNDLE_RAYS;
use crate::bvh::{offset_ray_origin, surface_hit, RayPool, SceneBuffers};
use crate::glam::Vec3;
#[cfg(not(target_arch = "spirv"))]
use crate::integrators::accumulate_samples;
use crate::integrators::{camera_sample, PixelResult};
use crate::intersect::Ray;
use crate::math::Divisor;
use crate::rng::{keyed_pair, Rng};
use crate::sampling::{cosine_hemisphere, in_frame, orthonormal_basis, Strata};
use crate::skip::Skip;
use crate::types::{decode_unit, encode_unit, FrameParams, AO_INDEPENDENT, INVALID};

/// The AO rays of one surface point: where they start, the triangles they cannot meet,
/// the frame about its normal that their directions are drawn in, and the key of their
/// random numbers. Ray k's numbers are a function of (key, k) alone (`keyed_pair`), so any thread
/// can make any point's ray k.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct AoRays {
    pub origin: Vec3,
    /// The triangle the point is on, which the rays leave on the side of its normal, and
    /// its neighbours in leaf order below that side's plane (`Skip::below`; nothing where
    /// the triangle is not given, `INVALID`): the rays cannot meet them, and traversal does
    /// not test them (`RayPool::ray`). Every AO ray's walk passes its own triangle's leaf,
    /// where those neighbours are.
    pub skip: Skip,
    /// The normal in one word (`encode_unit`), as the GPU's workgroup pool keeps it.
    pub normal: u32,
    /// Tangent, bitangent and normal (`orthonormal_basis`) of `normal`'s vector.
    pub frame: [Vec3; 3],
    pub key: u32,
}

impl AoRays {
    /// The rays of point `p` on triangle `prim` of `scene` with normal `n`; their key is
    /// the next number of `rng`.
    pub fn new(scene: &SceneBuffers, p: Vec3, prim: u32, n: Vec3, rng: &mut Rng) -> Self {
        let origin = offset_ray_origin(p, n);
        // Below the plane of the surface's own normal: the directions, drawn about its
        // 16-bit encoding, stay above it too (`skip`).
        let skip = scene.skip_below(origin, n, prim);
        Self::at(origin, skip, encode_unit(n), rng.next_u32())
    }

    /// The rays from `origin` (already off its surface) about the normal of word `normal`
    /// (`encode_unit`), of key `key`, which skip the triangles of `skip`.
    pub fn at(origin: Vec3, skip: Skip, normal: u32, key: u32) -> Self {
        let n = decode_unit(normal);
        let (t, b) = orthonormal_basis(n);
        Self {
            origin,
            skip,
            normal,
            frame: [t, b, n],
            key,
        }
    }

    /// Ray `k`, in cell k of `strata` (see `Strata::point`).
    pub fn ray(&self, k: u32, strata: Strata) -> Ray {
        let (j1, j2) = keyed_pair(self.key, k);
        let (u1, u2) = strata.point(k, j1, j2);
        Ray::new(self.origin, in_frame(cosine_hemisphere(u1, u2), self.frame))
    }
}

/// Unoccluded fraction at the point of `point`'s rays, from `rays` of them, of length
/// `distance`, spread over the hemisphere by `strata`. Cosine weighting makes this the
/// cosine-weighted visibility integral (1/π) ∫ V(ω) cos θ dω estimated with equal weights.
/// The CPU's: the rays go through the BVH in bundles of 64 from the point
/// (`bundle::cwbvh_occluded`); the GPU traces the same rays one per thread from its
/// workgroup's pool (`render_group_pixel`), with the same answer for each.
#[cfg(not(target_arch = "spirv"))]
pub fn ambient_occlusion<const PLAIN: bool>(
    scene: &SceneBuffers,
    point: AoRays,
    rays: u32,
    strata: Strata,
    distance: f32,
) -> f32 {
    let mut bundle = [Ray::new(point.origin, point.frame[2]); BUNDLE_RAYS];
    let mut open = 0;
    let mut first = 0;
    while first < rays {
        let n = (rays - first).min(BUNDLE_RAYS as u32);
        for (k, ray) in bundle[..n as usize].iter_mut().enumerate() {
            *ray = point.ray(first + k as u32, strata);
        }
        let occluded = scene.occluded_bundle::<PLAIN>(&bundle[..n as usize], point.skip, distance);
        open += n - occluded.count_ones();
        first += n;
    }
    open as f32 / rays.max(1) as f32
}

/// The strata of `params`' AO rays.
pub fn strata(params: &FrameParams) -> Strata {
    if params.ao_sampling == AO_INDEPENDENT {
        Strata::NONE
    } else {
        Strata::new(params.ao_rays)
    }
}

/// The visible point of a camera ray (position, triangle, normal), or None where it
/// leaves the scene.
pub fn camera_hit<const PLAIN: bool>(scene: &SceneBuffers, ray: &Ray) -> Option<(Vec3, u32, Vec3)> {
    let hit = scene.closest_hit::<PLAIN>(ray, f32::INFINITY);
    if !hit.is_hit() {
        return None;
    }
    let s = surface_hit(scene, ray, &hit, 0.0);
    Some((s.p, s.prim, s.n))
}

/// One AO sample for a camera ray: 0 where the ray leaves the scene (no surface, no
/// occlusion to speak of), the unoccluded fraction (grey) where it hits.
#[cfg(not(target_arch = "spirv"))]
pub fn ao_sample<const PLAIN: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    ray: Ray,
    rng: &mut Rng,
    rays: &mut u32,
) -> Vec3 {
    *rays += 1;
    let Some((p, prim, n)) = camera_hit::<PLAIN>(scene, &ray) else {
        return Vec3::ZERO;
    };
    *rays += params.ao_rays;
    Vec3::splat(ambient_occlusion::<PLAIN>(
        scene,
        AoRays::new(scene, p, prim, n, rng),
        params.ao_rays,
        strata(params),
        params.ao_distance,
    ))
}

/// `PLAIN`: the scene has no cut-outs (the plain-scene variant; see `bvh::closest_hit`).
#[cfg(not(target_arch = "spirv"))]
pub fn render_pixel<const PLAIN: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    x: u32,
    y: u32,
) -> PixelResult {
    accumulate_samples(params, x, y, |ray, rng, rays| {
        ao_sample::<PLAIN>(scene, params, ray, rng, rays)
    })
}

/// AO workgroups are rows of this many threads (`runner::gpu::pipelines::ao_workgroup`).
pub const GROUP_WIDTH: usize = 16;
/// Threads of an AO workgroup, all sharing one pool: 16×8, or 16×56 on NVIDIA adapters,
/// where the larger workgroup caps the kernels at 72 registers instead of the driver's 80
/// and its pool evens out more rays (2–5% faster on the H100; docs/PERFORMANCE.md,
/// "Occupancy measured"). Not everywhere: lavapipe runs a workgroup's subgroups one after
/// another, so its first subgroup traces the whole pool, and 7 times the rays run past its
/// loop limit.
pub const SMALL_GROUP: usize = 128;
pub const WIDE_GROUP: usize = 896;
/// A pool's layout in workgroup memory, in 32-bit words, for a group of `g` threads: the
/// next ray's index, the number of points with rays, those points' threads in the order
/// they came (`thread_bits` each), each thread's count of escaped rays, and each thread's
/// `AoRays` (origin, normal word, key, skipped triangles' start and mask). Kept small: the
/// workgroup's memory comes out of the SM's L1, which the walk's node reads live on
/// (docs/PERFORMANCE.md, "Benchmark suite").
const NEXT: usize = 0;
const POINTS: usize = 1;
const POINT_THREADS: usize = 2;
const RAYS_WORDS: usize = 7;
/// Bits of a point's thread in the point list: a byte while the group has at most 256.
const fn thread_bits(g: usize) -> usize {
    if g <= 256 {
        8
    } else {
        16
    }
}
const fn escaped_word(g: usize) -> usize {
    POINT_THREADS + g * thread_bits(g) / 32
}
const fn rays_word(g: usize) -> usize {
    escaped_word(g) + g
}
/// Words of workgroup memory an AO workgroup of `g` threads needs.
pub const fn group_words(g: usize) -> usize {
    rays_word(g) + RAYS_WORDS * g
}
const _: () = assert!(
    WIDE_GROUP < 1 << 16,
    "a point's thread must fit in its bits"
);
/// Where point `slot`'s thread is kept in the point list of a group of `G`: the word and
/// the shift of its bits.
fn point_thread_bits<const G: usize>(slot: usize) -> (usize, u32) {
    let per_word = 32 / thread_bits(G);
    (
        POINT_THREADS + slot / per_word,
        (slot % per_word * thread_bits(G)) as u32,
    )
}

/// A workgroup's shared memory: loads and stores of words, an atomic add, and a barrier
/// that every thread of the group must reach (workgroup memory on the GPU; in tests,
/// plain words with the phases run in order). Every `word` lies in the pool's layout
/// (`group_words`): the GPU's memory does not check it.
pub trait GroupMemory {
    fn load(&self, word: usize) -> u32;
    fn store(&mut self, word: usize, value: u32);
    /// Add `value` to `word` atomically; the value before.
    fn fetch_add(&mut self, word: usize, value: u32) -> u32;
    /// Wait for every thread of the group, their writes visible to all.
    fn barrier(&mut self);
}

/// The AO rays of a workgroup's points. Ray g is ray ⌊g / points⌋ of point g mod points:
/// the threads tracing side by side take the same ray k of neighbouring points, which
/// the strata's shared order sends in similar directions.
struct GroupPool<'a, M: GroupMemory, const G: usize> {
    memory: &'a mut M,
    points: Divisor,
    total: u32,
    strata: Strata,
}

impl<M: GroupMemory, const G: usize> GroupPool<'_, M, G> {
    /// Ray `index` as (which ray of its point, the thread of its point).
    fn point_of(&self, index: u32) -> (u32, usize) {
        let (k, slot) = self.points.div_rem(index);
        let (word, shift) = point_thread_bits::<G>(slot as usize);
        let mask = (1u32 << thread_bits(G)) - 1;
        (k, (shr(self.memory.load(word), shift) & mask) as usize)
    }
}

impl<M: GroupMemory, const G: usize> RayPool for GroupPool<'_, M, G> {
    fn take(&mut self) -> u32 {
        let index = self.memory.fetch_add(NEXT, 1);
        if index >= self.total {
            INVALID
        } else {
            index
        }
    }

    fn ray(&self, index: u32) -> (Ray, Skip) {
        let (k, thread) = self.point_of(index);
        let base = rays_word(G) + RAYS_WORDS * thread;
        let f = |i: usize| f32::from_bits(self.memory.load(base + i));
        // The point's frame is made again per ray rather than kept in workgroup memory:
        // six more words a point made AO 0.3–1% slower (H200; docs/PERFORMANCE.md,
        // "Benchmark suite").
        let origin = Vec3::new(f(0), f(1), f(2));
        let (normal, key) = (self.memory.load(base + 3), self.memory.load(base + 4));
        let skip = Skip {
            start: self.memory.load(base + 5),
            mask: self.memory.load(base + 6),
        };
        let rays = AoRays::at(origin, skip, normal, key);
        (rays.ray(k, self.strata), skip)
    }

    fn escaped(&mut self, index: u32) {
        let (_, thread) = self.point_of(index);
        self.memory.fetch_add(escaped_word(G) + thread, 1);
    }

    fn exhausted(&self) -> bool {
        self.memory.load(NEXT) >= self.total
    }
}

/// Group phase 1, every thread `thread` after the group's memory was cleared (`clear`):
/// trace the camera ray of its pixel's sample and put the AO rays of what it sees into
/// the pool. Returns whether the ray hit something (the caller counts its rays).
pub fn group_camera<const PLAIN: bool, const G: usize, M: GroupMemory>(
    scene: &SceneBuffers,
    memory: &mut M,
    thread: usize,
    ray: &Ray,
    rng: &mut Rng,
) -> bool {
    let Some((p, prim, n)) = camera_hit::<PLAIN>(scene, ray) else {
        return false;
    };
    let rays = AoRays::new(scene, p, prim, n, rng);
    let base = rays_word(G) + RAYS_WORDS * thread;
    memory.store(base, rays.origin.x.to_bits());
    memory.store(base + 1, rays.origin.y.to_bits());
    memory.store(base + 2, rays.origin.z.to_bits());
    memory.store(base + 3, rays.normal);
    memory.store(base + 4, rays.key);
    memory.store(base + 5, rays.skip.start);
    memory.store(base + 6, rays.skip.mask);
    // The thread into byte `slot` of the (cleared) list: adding to a zero byte sets it.
    let slot = memory.fetch_add(POINTS, 1) as usize;
    let (word, shift) = point_thread_bits::<G>(slot);
    memory.fetch_add(word, shl(thread as u32, shift));
    true
}

/// Group phase 2, every thread (or, on one thread, the whole pool): trace rays from the
/// pool until it is empty.
pub fn group_trace<const PLAIN: bool, const G: usize, M: GroupMemory>(
    scene: &SceneBuffers,
    params: &FrameParams,
    memory: &mut M,
) {
    let points = memory.load(POINTS);
    // At most WIDE_GROUP × 2^22 rays (the CLI caps --ao-rays at 2^22): with each
    // thread's last, failed take, the counter stays below 2^32.
    let mut pool = GroupPool::<M, G> {
        memory,
        points: Divisor::new(points.max(1)),
        total: points * params.ao_rays,
        strata: strata(params),
    };
    scene.trace_pool::<PLAIN, _>(&mut pool, params.ao_distance, params.ao_order);
}

/// Group phase 3, every thread: the unoccluded fraction of its point's rays; and the
/// thread's words cleared for the next sample (thread 0 clears the group's).
pub fn group_result<const G: usize, M: GroupMemory>(
    params: &FrameParams,
    memory: &mut M,
    thread: usize,
) -> f32 {
    let open = memory.load(escaped_word(G) + thread);
    clear::<G, M>(memory, thread);
    open as f32 / params.ao_rays.max(1) as f32
}

/// Clear thread `thread`'s counter, a word of the point list with the first quarter of the
/// threads, and with thread 0 the pool's: before the first sample.
pub fn clear<const G: usize, M: GroupMemory>(memory: &mut M, thread: usize) {
    memory.store(escaped_word(G) + thread, 0);
    if thread < escaped_word(G) - POINT_THREADS {
        memory.store(POINT_THREADS + thread, 0);
    }
    if thread == 0 {
        memory.store(NEXT, 0);
        memory.store(POINTS, 0);
    }
}

/// Pixel (x, y)'s samples, run by thread `thread` of a workgroup of `G` threads that
/// all call this together (threads beyond the image with `inside` false: they trace no
/// camera ray, but take rays from the pool). The same sums and ray counts as
/// `render_pixel`.
pub fn render_group_pixel<const PLAIN: bool, const G: usize, M: GroupMemory>(
    scene: &SceneBuffers,
    params: &FrameParams,
    memory: &mut M,
    thread: usize,
    x: u32,
    y: u32,
    inside: bool,
) -> PixelResult {
    clear::<G, M>(memory, thread);
    let mut result = PixelResult::default();
    let mut s = 0;
    while s < params.samples {
        memory.barrier();
        let mut hit = false;
        if inside {
            let (ray, mut rng) = camera_sample(params, x, y, s);
            hit = group_camera::<PLAIN, G, M>(scene, memory, thread, &ray, &mut rng);
            result.rays += 1 + if hit { params.ao_rays } else { 0 };
        }
        memory.barrier();
        group_trace::<PLAIN, G, M>(scene, params, memory);
        memory.barrier();
        let open = group_result::<G, M>(params, memory, thread);
        if hit {
            result.sum += Vec3::splat(open);
        }
        s += 1;
    }
    result
}
