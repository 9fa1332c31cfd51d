//! Scene queries: closest hit and any hit (shadow/AO rays) by brute force, over a binary
//! BVH, or over a compressed 8-wide BVH (CWBVH). `SceneBuffers` uses the traversal picked by cargo
//! feature; every variant answers the same question, and the tests hold them to it.
use crate::bits::{first_bit_high, shl};
use crate::bsdf::{Bsdf, BSDF_CONDUCTOR, BSDF_DIELECTRIC};
use crate::glam::{UVec2, UVec4, Vec2, Vec3, Vec4};
use crate::intersect::{intersect_aabb, Hit, Ray, TriangleTester};
use crate::math::{max, min, vec3};
use crate::rng::pcg_hash;
use crate::sampling::orthonormal_basis;
use crate::skip::Skip;
use crate::texture::{sample_texture, sample_texture_footprint};
use crate::types::cwbvh_meta::{FIRST_INTERIOR_BIT, INTERIOR_HITS, TRIANGLE_HITS};
use crate::types::{
    at, load, set_at, Bvh2Node, CwBvhNode, CwBvhPlanes, CwBvhSlotNode, GBufferTexel, Light,
    Material, TextureInfo, Triangle, TriangleShading, AO_NEAR_FIRST, INVALID, METAL_THRESHOLD,
    NORMAL_MAP_HEIGHT, SHADING_BITANGENT_FLIPPED, SHADING_COLOURS, SHADING_NORMALS,
    SHADING_TANGENTS, SHADING_UVS,
};
use core::mem::MaybeUninit;

/// Rays to trace for `SceneBuffers::trace_pool`, handed out one at a time by index.
pub trait RayPool {
    /// The index of the next ray to trace, `INVALID` when there are no more.
    fn take(&mut self) -> u32;
    /// Ray `index`, a pure function of the index so that any thread may trace it, and the
    /// triangles it cannot meet, which the walk does not test (`Skip`: the one it leaves,
    /// its origin off the side it points to, and those below that side's plane).
    fn ray(&self, index: u32) -> (Ray, Skip);
    /// Ray `index` met nothing before its end.
    fn escaped(&mut self, index: u32);
    /// Whether every ray has been taken.
    fn exhausted(&self) -> bool;
}

/// The node type of the traversal compiled in.
#[cfg(any(feature = "traversal-bvh2", feature = "traversal-brute-force"))]
pub type BvhNode = Bvh2Node;
#[cfg(not(any(feature = "traversal-bvh2", feature = "traversal-brute-force")))]
pub type BvhNode = CwBvhNode;

/// Name of the traversal compiled in, for reports.
pub const TRAVERSAL: &str = if cfg!(feature = "traversal-brute-force") {
    "brute-force"
} else if cfg!(feature = "traversal-bvh2") {
    "bvh2"
} else {
    "cwbvh"
};

/// Traversal stack depth. A BVH2 from PLOC over a few million triangles is well under 64
/// levels; an ordered traversal pushes at most one node per level.
pub const BVH2_STACK: usize = 64;
/// CWBVH stack of node groups, at most one per level: 8-wide trees are shallow (the 1M-
/// triangle suite scenes have 10–17 levels), and the host builds a balanced tree for a
/// scene deeper than this (`accel::build_cwbvh`). The size cost time only while every
/// traversal zero-initialised its stack (24 entries instead of 32: a ReSTIR frame 2.40 →
/// 2.34 ms on the H100); since `CwbvhWalk` leaves it uninitialised, it costs local memory.
pub const CWBVH_STACK: usize = 24;

/// A GPU thread whose pooled ray has ended (`SceneBuffers::trace_pool`) waits for this many
/// threads of its warp (of 32) to be done before they all start their next rays together.
/// A ray's start (taking it from the pool, making its direction, the walk's set-up) costs
/// the warp as much whether one lane or twelve run it, the others waiting: started one lane
/// at a time, nearly every step of the walk paid for one. Aila & Laine 2009's dynamic fetch;
/// 8, 10, 12, 14 and 16 measured (docs/PERFORMANCE.md, "Benchmark suite"). On the CPU a
/// thread is its own warp.
pub const START_TOGETHER: u32 = 12;

/// The pooled AO walk tests one triangle a step, alongside that step's node (`CwbvhWalk::
/// step`'s `ONE`): a lane's triangles wait while it goes on with nodes, instead of the warp
/// testing one lane's several triangles while the others idle. Nsight Compute on a CUDA
/// port of this walk (shell-1m, H100) found the triangle loop running with 2.6 of 32 lanes
/// on average and issuing 35% of the warp instructions; one a step: shell-1m −10.2%,
/// spheres-1m −7.4%, grass-1m −3.9%, rocks-1m −3.6%, city-1m +1.7% (H100, one round;
/// docs/PERFORMANCE.md, "Benchmark suite").
/// Closest-hit and shadow walks keep a node's triangles in its step (there, one a step
/// was slower: docs/PERFORMANCE.md, "A leaf's triangles spread over the walk's steps").
const AO_ONE_TRIANGLE: bool = true;

/// Shadow rays stop this fraction of the way to the light's (offset) point, so that the
/// light's own triangle never counts as an occluder.
const SHADOW_RAY_END: f32 = 0.9999;

/// The shadow ray between surface point (p, n) and light point (q, nq), and where it
/// ends: from and to the offset end points, off the surface on the side the light is on
/// (it can be below: transmission).
pub fn shadow_ray(p: Vec3, n: Vec3, q: Vec3, nq: Vec3) -> (Ray, f32) {
    let n = if (q - p).dot(n) >= 0.0 { n } else { -n };
    let origin = offset_ray_origin(p, n);
    let target = offset_ray_origin(q, nq);
    let d = target - origin;
    let dist = d.length();
    (Ray::new(origin, d / dist), dist * SHADOW_RAY_END)
}

/// The shadow ray from surface point (p, n) in direction `dir` (to the sky: unbounded).
pub fn shadow_ray_towards(p: Vec3, n: Vec3, dir: Vec3) -> Ray {
    let n = if dir.dot(n) >= 0.0 { n } else { -n };
    Ray::new(offset_ray_origin(p, n), dir)
}

/// The scene buffers a kernel reads, bundled so integrators take one argument.
#[derive(Copy, Clone)]
pub struct SceneBuffers<'a> {
    /// The triangles as 16-byte words (`Triangle::WORDS` each), read with `triangle`.
    pub triangles: &'a [UVec4],
    pub materials: &'a [Material],
    /// The BVH's nodes as 16-byte words (the `BvhNode`s built, back to back; over a CWBVH
    /// on the CPU, those nodes decoded to `TraversalNode`s): read a word at a time, every
    /// node load is 128-bit wide whatever the driver makes of a struct's fields.
    pub nodes: &'a [UVec4],
    pub lights: &'a [Light],
    /// Vertex normals and texture coordinates, indexed by `Triangle::shading`.
    pub shading: &'a [TriangleShading],
    /// The texture table and the texels it points into (see `texture.rs`).
    pub textures: &'a [TextureInfo],
    pub texels: &'a [u32],
    /// The environment map's sampling distribution (see `env.rs`); empty without one.
    pub env_distribution: &'a [f32],
}

/// What traversal needs to test cut-outs (alpha masks): a hit on a triangle flagged
/// `ALPHA_TESTED` counts only where its material's mask is at least ½ at the hit's texture
/// coordinates, so leaves are holes for camera, bounce and shadow rays alike; with
/// `ALPHA_BLENDED` the mask is a coverage fraction (`coverage_threshold`).
#[derive(Copy, Clone)]
pub struct Cutouts<'a> {
    pub materials: &'a [Material],
    pub shading: &'a [TriangleShading],
    pub textures: &'a [TextureInfo],
    pub texels: &'a [u32],
}

/// A mask value below this makes a hole.
const ALPHA_CUTOFF: f32 = 0.5;

impl Cutouts<'_> {
    /// No masks (every triangle opaque): for traversal of bare triangle lists.
    pub const NONE: Cutouts<'static> = Cutouts {
        materials: &[],
        shading: &[],
        textures: &[],
        texels: &[],
    };

    /// Where `tester`'s ray meets `tri` before `t_max` on its surface, not in a hole: (t,
    /// b1, b2). `PLAIN` promises a scene without cut-outs (no mask is read).
    #[inline(always)]
    pub(crate) fn solid_hit<const PLAIN: bool>(
        &self,
        tester: &TriangleTester,
        tri: &Triangle,
        t_max: f32,
    ) -> Option<(f32, f32, f32)> {
        let (t, b1, b2) = tester.intersect(tri, 0.0, t_max)?;
        if PLAIN || self.solid(tri, b1, b2) {
            Some((t, b1, b2))
        } else {
            None
        }
    }

    /// Whether a hit at barycentrics (b1, b2) of `tri` is on the surface, not in a hole.
    fn solid(&self, tri: &Triangle, b1: f32, b2: f32) -> bool {
        if !tri.alpha_tested() {
            return true;
        }
        let mask = load(self.materials, tri.material as usize).opacity_texture;
        let a = load(self.shading, tri.shading_index() as usize);
        let alpha = sample_texture(self.textures, self.texels, mask, a.uv_at(b1, b2)).w;
        if tri.alpha_blended() {
            alpha > coverage_threshold(tri, b1, b2)
        } else {
            alpha >= ALPHA_CUTOFF
        }
    }
}

/// A number in [0, 1) that a coverage mask must exceed at barycentrics (b1, b2) of `tri`:
/// a hash of the hit point on the triangle, so the rays that meet a surface of alpha a
/// find it solid a share a of the time, each ray deciding independently of its order in
/// traversal (the same point always decides the same way).
fn coverage_threshold(tri: &Triangle, b1: f32, b2: f32) -> f32 {
    let h = pcg_hash(b1.to_bits() ^ pcg_hash(b2.to_bits() ^ pcg_hash(tri.shading)));
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}

impl<'a> SceneBuffers<'a> {
    pub fn cutouts(&self) -> Cutouts<'a> {
        Cutouts {
            materials: self.materials,
            shading: self.shading,
            textures: self.textures,
            texels: self.texels,
        }
    }

    /// The nearest hit along `ray` before `t_max`. `PLAIN` promises a scene without
    /// cut-outs (the plain-scene kernels, see `path::trace_path`): traversal then carries
    /// no mask test, whose registers cost plain scenes 2–14% (H100).
    pub fn closest_hit<const PLAIN: bool>(&self, ray: &Ray, t_max: f32) -> Hit {
        self.trace::<PLAIN>(ray, t_max, false)
    }

    /// Whether anything blocks `ray` before `t_max` (`PLAIN` as for `closest_hit`).
    pub fn any_hit<const PLAIN: bool>(&self, ray: &Ray, t_max: f32) -> bool {
        self.trace::<PLAIN>(ray, t_max, true).is_hit()
    }

    /// `closest_hit`, or with `any` the first hit found (`any_hit`): one traversal for
    /// both, so that a kernel tracing both kinds of ray in turn can do so from one call
    /// site (`path::trace_path`), holding one inlined traversal and its stack.
    pub fn trace<const PLAIN: bool>(&self, ray: &Ray, t_max: f32, any: bool) -> Hit {
        let cut = self.cutouts();
        #[cfg(feature = "traversal-brute-force")]
        return if any {
            // Only whether it hit counts for `any`: any triangle stands for the blocker.
            let blocked = brute_force_any_hit(self.triangles, &cut, ray, t_max);
            Hit {
                prim: if blocked { 0 } else { INVALID },
                ..Hit::none(t_max)
            }
        } else {
            brute_force_closest_hit(self.triangles, &cut, ray, t_max)
        };
        #[cfg(all(feature = "traversal-bvh2", not(feature = "traversal-brute-force")))]
        return bvh2_traverse::<PLAIN>(self.triangles, &cut, self.nodes, ray, t_max, any);
        #[cfg(not(any(feature = "traversal-bvh2", feature = "traversal-brute-force")))]
        return cwbvh_traverse::<PLAIN, TraversalNode>(
            self.triangles,
            &cut,
            self.nodes,
            ray,
            t_max,
            any,
        );
    }

    /// Trace every ray of `pool` to `t_max`, telling the pool which ones meet nothing
    /// (ambient occlusion). Over a CWBVH the rays run back to back in one traversal loop:
    /// a GPU thread whose ray ends starts its next one soon (with [`START_TOGETHER`] of its
    /// warp) instead of idling until the slowest ray of its warp is done (the idea of Aila
    /// & Laine 2009's persistent threads), so a warp takes about the longest *sum* of its
    /// threads' rays, not the sum of each ray's longest; and where the pool is shared by a
    /// workgroup, a thread takes rays of other pixels once its own are spoken for, so the
    /// sums even out too.
    ///
    /// `order` (`AO_NEAR_FIRST` or `AO_FAR_FIRST`): the order the walk visits a node's
    /// children in (`runner::ao_order` chooses it per scene).
    pub fn trace_pool<const PLAIN: bool, P: RayPool>(&self, pool: &mut P, t_max: f32, order: u32) {
        #[cfg(not(any(feature = "traversal-bvh2", feature = "traversal-brute-force")))]
        if !self.nodes.is_empty() {
            let cut = self.cutouts();
            let mut index = pool.take();
            if index == INVALID {
                return;
            }
            let (ray, skip) = pool.ray(index);
            let mut walk = CwbvhWalk::new(&ray, t_max, skip, order);
            let mut done = false;
            // A warp with fewer threads in the loop than that (lavapipe's subgroups of 8, or
            // a warp of which fewer threads found a first ray) waits for all of them.
            let wanted = START_TOGETHER.min(crate::subgroup::count(true));
            loop {
                if !done {
                    done = walk.step::<PLAIN, true, AO_ONE_TRIANGLE, TraversalNode>(
                        self.triangles,
                        &cut,
                        self.nodes,
                        true,
                    );
                    if done && !walk.hit.is_hit() {
                        pool.escaped(index);
                    }
                }
                // Threads that have exited found the pool empty: then no thread waits.
                let finished = crate::subgroup::count(done);
                if done && (finished >= wanted || pool.exhausted()) {
                    index = pool.take();
                    if index == INVALID {
                        break;
                    }
                    let (ray, skip) = pool.ray(index);
                    walk.restart(&ray, t_max, skip, order);
                    done = false;
                }
            }
            return;
        }
        let _ = order;
        loop {
            let index = pool.take();
            if index == INVALID {
                break;
            }
            // A CWBVH without nodes has no triangles: nothing blocks. (Tracing anyway put a
            // third inlined traversal and its stack, never run, into the AO kernels.)
            #[cfg(any(feature = "traversal-bvh2", feature = "traversal-brute-force"))]
            if self.any_hit::<PLAIN>(&pool.ray(index).0, t_max) {
                continue;
            }
            pool.escaped(index);
        }
    }

    /// Which of `rays` (at most `bundle::BUNDLE_RAYS`, all from one point, which cannot meet
    /// the triangles of `skip`) meet something before `t_max`: bit k for ray k. The CPU's
    /// ambient occlusion (see `bundle`); each bit is `any_hit` of its ray.
    #[cfg(not(target_arch = "spirv"))]
    pub fn occluded_bundle<const PLAIN: bool>(&self, rays: &[Ray], skip: Skip, t_max: f32) -> u64 {
        #[cfg(not(any(feature = "traversal-bvh2", feature = "traversal-brute-force")))]
        return crate::bundle::cwbvh_occluded::<PLAIN>(
            self.triangles,
            &self.cutouts(),
            self.nodes,
            rays,
            skip,
            t_max,
        );
        #[cfg(any(feature = "traversal-bvh2", feature = "traversal-brute-force"))]
        {
            let _ = skip;
            let mut occluded = 0;
            for (k, ray) in rays.iter().take(crate::bundle::BUNDLE_RAYS).enumerate() {
                if self.any_hit::<PLAIN>(ray, t_max) {
                    occluded |= 1 << k;
                }
            }
            occluded
        }
    }

    /// Whether the light point (q, nq) is visible from the surface point (p, n): one
    /// shadow ray between the offset end points.
    pub fn visible<const PLAIN: bool>(&self, p: Vec3, n: Vec3, q: Vec3, nq: Vec3) -> bool {
        let (ray, t_max) = shadow_ray(p, n, q, nq);
        !self.any_hit::<PLAIN>(&ray, t_max)
    }

    /// Whether surface point p (normal n) sees outside the scene in direction `dir`.
    pub fn visible_towards<const PLAIN: bool>(&self, p: Vec3, n: Vec3, dir: Vec3) -> bool {
        !self.any_hit::<PLAIN>(&shadow_ray_towards(p, n, dir), f32::INFINITY)
    }

    /// The triangles that rays from `origin`, off triangle `prim`'s surface, into the
    /// hemisphere about `n` cannot meet (`Skip::below`).
    pub fn skip_below(&self, origin: Vec3, n: Vec3, prim: u32) -> Skip {
        let count = (self.triangles.len() / Triangle::WORDS) as u32;
        Skip::below(origin, n, prim, count, |i| self.triangle(i))
    }

    /// Triangle `i`.
    pub fn triangle(&self, i: u32) -> Triangle {
        Triangle::read(self.triangles, i)
    }

    pub fn material_of(&self, prim: u32) -> Material {
        load(self.materials, self.triangle(prim).material as usize)
    }

    /// The BSDF at a surface point.
    pub fn bsdf(&self, s: &SurfaceHit) -> Bsdf {
        self.surface_bsdf(&self.material_of(s.prim), s)
    }

    /// The BSDF of material `m` at surface point `s`, its textures applied: colours times
    /// the vertex colour and the base colour texture; a metallic-roughness texture's
    /// roughness and metalness (a metal texel is a conductor of the base colour). A
    /// dielectric's relative index depends on the side the ray arrived on: the material's
    /// index entering through the front, its inverse leaving.
    pub fn surface_bsdf(&self, m: &Material, s: &SurfaceHit) -> Bsdf {
        let read = |texture: u32| {
            sample_texture_footprint(self.textures, self.texels, texture, s.uv, s.uv_footprint)
        };
        let texture = if m.albedo_texture == INVALID {
            s.colour
        } else {
            s.colour * read(m.albedo_texture).truncate()
        };
        let mut kind = m.kind;
        let mut alpha = m.alpha;
        if m.metal_rough_texture != INVALID {
            let t = read(m.metal_rough_texture);
            alpha *= t.y * t.y;
            if m.metallic * t.z >= METAL_THRESHOLD {
                kind = BSDF_CONDUCTOR;
            }
        }
        let colour = if kind == BSDF_CONDUCTOR {
            m.specular
        } else {
            m.albedo
        };
        Bsdf::with_colour(kind, vec3(colour) * texture, alpha, eta_of(m, s.front_face))
    }

    /// The BSDF a G-buffer texel keeps (see `GBufferTexel`).
    pub fn gbuffer_bsdf(&self, g: &GBufferTexel) -> Bsdf {
        let m = self.material_of(g.prim);
        Bsdf::with_colour(g.kind(), vec3(g.colour), g.alpha(), eta_of(&m, g.front()))
    }

    /// Emitted radiance of triangle `tri` at barycentrics (b1, b2), towards its front: its
    /// material's emission, times its emission texture where it has one and texture
    /// coordinates.
    pub fn emission_at(&self, tri: &Triangle, b1: f32, b2: f32) -> Vec3 {
        let m = load(self.materials, tri.material as usize);
        if m.emission_texture == INVALID || tri.shading_index() == INVALID {
            return m.emission();
        }
        let uv = load(self.shading, tri.shading_index() as usize).uv_at(b1, b2);
        m.emission() * sample_texture(self.textures, self.texels, m.emission_texture, uv).truncate()
    }
}

/// Relative index of refraction of material `m` for a ray arriving on its front or back.
fn eta_of(m: &Material, front_face: bool) -> f32 {
    if m.kind == BSDF_DIELECTRIC && !front_face {
        1.0 / m.ior
    } else {
        m.ior
    }
}

/// Test every triangle, keep the nearest: the course's first version.
pub fn brute_force_closest_hit(
    triangles: &[UVec4],
    cutouts: &Cutouts,
    ray: &Ray,
    t_max: f32,
) -> Hit {
    let tester = TriangleTester::new(ray);
    let mut hit = Hit::none(t_max);
    let mut i = 0;
    while i < triangles.len() / Triangle::WORDS {
        let tri = Triangle::read(triangles, i as u32);
        if let Some((t, b1, b2)) = cutouts.solid_hit::<false>(&tester, &tri, hit.t) {
            hit = Hit {
                t,
                b1,
                b2,
                prim: i as u32,
            };
        }
        i += 1;
    }
    hit
}

/// Stop at the first occluder closer than `t_max`.
pub fn brute_force_any_hit(triangles: &[UVec4], cutouts: &Cutouts, ray: &Ray, t_max: f32) -> bool {
    let tester = TriangleTester::new(ray);
    let mut i = 0;
    while i < triangles.len() / Triangle::WORDS {
        let tri = Triangle::read(triangles, i as u32);
        if cutouts.solid_hit::<false>(&tester, &tri, t_max).is_some() {
            return true;
        }
        i += 1;
    }
    false
}

/// What the traversal did, counted on the host under the `traversal-stats` feature (never
/// in SPIR-V: kernels read no globals). The CPU backend runs the GPU's traversal over the
/// same BVH, so its counts per ray describe the GPU's work too; its AO bundles (`bundle`)
/// count each ray's node tests, as the ray's own walk would visit those nodes.
#[cfg(all(feature = "traversal-stats", not(target_arch = "spirv")))]
pub mod stats {
    use core::sync::atomic::{AtomicU64, Ordering::Relaxed};
    pub static TRAVERSALS: AtomicU64 = AtomicU64::new(0);
    pub static NODES: AtomicU64 = AtomicU64::new(0);
    pub static TRIANGLES: AtomicU64 = AtomicU64::new(0);

    /// (traversals, nodes visited, triangles tested) since the last call.
    pub fn take() -> (u64, u64, u64) {
        (
            TRAVERSALS.swap(0, Relaxed),
            NODES.swap(0, Relaxed),
            TRIANGLES.swap(0, Relaxed),
        )
    }
}

/// Add one to a `stats` counter (nothing without the feature, and never on the GPU).
macro_rules! count {
    ($counter:ident) => {
        #[cfg(all(feature = "traversal-stats", not(target_arch = "spirv")))]
        crate::bvh::stats::$counter.fetch_add(1, core::sync::atomic::Ordering::Relaxed);
    };
}
#[cfg(not(target_arch = "spirv"))]
pub(crate) use count;

/// Test triangles `first .. first + count` against the ray, shrinking `hit.t`.
/// Returns true when `any` is set and something was hit (the caller stops).
fn test_leaf<const PLAIN: bool>(
    triangles: &[UVec4],
    cutouts: &Cutouts,
    tester: &TriangleTester,
    first: u32,
    count: u32,
    hit: &mut Hit,
    any: bool,
) -> bool {
    let mut i = first;
    while i < first + count {
        count!(TRIANGLES);
        let tri = Triangle::read(triangles, i);
        // Written out rather than through `Cutouts::solid_hit`: that call changes the
        // SPIR-V of every traversal, which no device was lent to measure.
        if let Some((t, b1, b2)) = tester.intersect(&tri, 0.0, hit.t) {
            if PLAIN || cutouts.solid(&tri, b1, b2) {
                *hit = Hit { t, b1, b2, prim: i };
                if any {
                    return true;
                }
            }
        }
        i += 1;
    }
    false
}

/// Ordered stack traversal of a binary BVH: visit the nearer child first, push the other.
/// With `any`, return at the first hit (any hit is enough for shadow and AO rays).
pub fn bvh2_traverse<const PLAIN: bool>(
    triangles: &[UVec4],
    cutouts: &Cutouts,
    nodes: &[UVec4],
    ray: &Ray,
    t_max: f32,
    any: bool,
) -> Hit {
    let tester = TriangleTester::new(ray);
    let inv_dir = ray.dir.recip();
    let mut hit = Hit::none(t_max);
    if nodes.is_empty() {
        return hit;
    }
    let root = Bvh2Node::read(nodes, 0);
    if intersect_aabb(ray.origin, inv_dir, vec3(root.lo), vec3(root.hi), hit.t) == f32::INFINITY {
        return hit;
    }
    let mut stack = [0u32; BVH2_STACK];
    let mut sp = 0usize;
    let mut current = 0u32;
    loop {
        let node = Bvh2Node::read(nodes, current);
        let mut next_valid = false;
        if node.count > 0 {
            if test_leaf::<PLAIN>(
                triangles, cutouts, &tester, node.first, node.count, &mut hit, any,
            ) {
                return hit;
            }
        } else {
            let (l, r) = (
                Bvh2Node::read(nodes, node.first),
                Bvh2Node::read(nodes, node.first + 1),
            );
            let tl = intersect_aabb(ray.origin, inv_dir, vec3(l.lo), vec3(l.hi), hit.t);
            let tr = intersect_aabb(ray.origin, inv_dir, vec3(r.lo), vec3(r.hi), hit.t);
            let (near, far, t_near, t_far) = if tl <= tr {
                (node.first, node.first + 1, tl, tr)
            } else {
                (node.first + 1, node.first, tr, tl)
            };
            if t_near != f32::INFINITY {
                current = near;
                next_valid = true;
                if t_far != f32::INFINITY && sp < BVH2_STACK {
                    stack[sp] = far;
                    sp += 1;
                }
            }
        }
        if !next_valid {
            if sp == 0 {
                break;
            }
            sp -= 1;
            current = stack[sp];
        }
    }
    hit
}

/// 7 − the ray's octant, in the bit order obvhs assigns child slots by (x: bit 2, y: bit 1,
/// z: bit 0). Slot XOR this is the child's traversal priority: popping the highest first
/// visits the children front to back.
pub fn cwbvh_octant_inv(dir: Vec3) -> u32 {
    let oct = (((dir.x < 0.0) as u32) << 2) | (((dir.y < 0.0) as u32) << 1) | (dir.z < 0.0) as u32;
    7 - oct
}

/// 1/d per component, with ±2^63 where d is too small to invert: finite slopes keep the
/// quantised slab test free of 0·∞ = NaN for axis-parallel rays.
pub fn safe_recip(d: Vec3) -> Vec3 {
    let r = |x: f32| {
        if x > 1e-18 || x < -1e-18 {
            1.0 / x
        } else if x.to_bits() >> 31 != 0 {
            -9.223372e18
        } else {
            9.223372e18
        }
    };
    Vec3::new(r(d.x), r(d.y), r(d.z))
}

/// (near, far) planes of one axis: where the ray runs towards -axis, the box's max plane is
/// the one it enters by.
fn near_far<T>(min: T, max: T, negative: bool) -> (T, T) {
    if negative {
        (max, min)
    } else {
        (min, max)
    }
}

/// Ray relative to a CWBVH node: t = plane · slope + offset per axis.
struct NodeRay {
    slope: Vec3,
    offset: Vec3,
    negative: [bool; 3],
    oct_inv: u32,
    t_max: f32,
}

impl NodeRay {
    /// The ray against child planes `p + scale · plane` (`scale` 1 for decoded planes).
    #[inline(always)]
    fn new(
        p: [f32; 3],
        scale: Vec3,
        origin: Vec3,
        inv_dir: Vec3,
        oct_inv: u32,
        t_max: f32,
    ) -> Self {
        Self {
            slope: scale * inv_dir,
            offset: (vec3(p) - origin) * inv_dir,
            negative: [inv_dir.x < 0.0, inv_dir.y < 0.0, inv_dir.z < 0.0],
            oct_inv,
            t_max,
        }
    }
}

/// Whether the ray enters a child slot's box (near and far planes) before its end. The
/// caller selects the slot's hit bits (see [`WideNode::hits`]) with it, without a branch:
/// every slot is tested, an empty one (meta 0) adding no bits. Branching on empty slots
/// and on the slab test's outcome (as before 858c4e3) left the CPU two unpredictable
/// branches per child:
/// this made the CPU backend's AO 10–30% faster and the GPU's 1.5–2.4% (the 1M suite
/// scenes; Cornell box AO 2% slower, its MIS the same). The four children's slab tests side
/// by side in `Vec4`s with a branch-free mask (2c44636) made the CPU backend's AO 17–19%
/// faster but the GPU's kernels 3–28% slower (H200, same device run: Cornell MIS 2.09 →
/// 2.67 ms, many-lights NEE 0.95 → 1.15, city-1m AO 33.6 → 35.6), and the GPU comes first:
/// the CPU, which reads decoded planes, tests four children at a time there instead
/// ([`cwbvh_half_hits_decoded`]).
#[inline(always)]
fn slab_hit(ray: &NodeRay, near: Vec3, far: Vec3) -> bool {
    let near = near * ray.slope + ray.offset;
    let far = far * ray.slope + ray.offset;
    let t_near = max(max(max(near.x, near.y), near.z), 0.0);
    let t_far = min(min(min(far.x, far.y), far.z), ray.t_max);
    t_near <= t_far
}

/// [`child_bits`] of the 4 slots whose meta bytes are `meta4`, a byte per slot in two
/// words: the bits (1 for an interior child, a leaf's 1, 3 or 7, none for an empty slot)
/// and where they go (24 + slot XOR the octant, or a leaf's first triangle's offset).
/// Four slots' worth in a handful of word operations, where a slot at a time took as many
/// per slot: the CPU's walk over decoded planes, and the host's making of the bits the
/// GPU's nodes store ([`CwBvhSlotNode::of`]).
#[inline(always)]
fn child_bits4(meta4: u32, oct_inv: u32) -> (u32, u32) {
    // Bit 4 of each interior slot's byte: its bits 3 and 4 both set (`is_interior`); the
    // shift carries bit 7 of a byte into bit 0 of the next, which the mask drops.
    let interior4 = meta4 & (meta4 << 1) & 0x1010_1010;
    // oct_inv < 8 times a byte of 1 stays in its byte.
    let position4 = (meta4 & 0x1f1f_1f1f) ^ ((interior4 >> 4) * oct_inv);
    ((meta4 >> 5) & 0x0707_0707, position4)
}

/// The hit-mask bits of the slot whose byte in [`child_bits4`]'s two words starts at bit
/// `shift`.
#[inline(always)]
fn slot_bits(bits4: u32, position4: u32, shift: u32) -> u32 {
    ((bits4 >> shift) & 7) << ((position4 >> shift) & 0x1f)
}

impl CwBvhSlotNode {
    /// `node` with its slots' hit-mask bits: [`child_bits4`]'s at octant 0, which leaves
    /// the interior children's bits in slot order.
    pub fn of(node: &CwBvhNode) -> Self {
        let mut bits = [0; 8];
        for (k, b) in bits.iter_mut().enumerate() {
            let (bits4, position4) = child_bits4(node.child_meta[k / 4], 0);
            *b = slot_bits(bits4, position4, 8 * (k % 4) as u32);
        }
        Self {
            node: *node,
            slot_bits: bits,
        }
    }
}

/// The hit-mask bits of a child slot with meta byte `meta`, when the ray hits its box
/// (what [`child_bits4`] computes four slots at a time, and [`CwBvhSlotNode`] stores; the
/// tests hold them to each other).
/// Interior child: index = 24 + slot, XOR the ray octant, which orders the children front
/// to back when popped highest bit first. Leaf child: its triangles' bits from its first
/// offset. An empty slot (meta 0) is a leaf of no triangles: no bits.
#[cfg(test)]
fn child_bits(ray: &NodeRay, meta: u32) -> u32 {
    use crate::types::cwbvh_meta;
    if cwbvh_meta::is_interior(meta) {
        1 << (cwbvh_meta::index(meta) ^ ray.oct_inv)
    } else {
        cwbvh_meta::triangle_bits(meta) << cwbvh_meta::index(meta)
    }
}

/// [`slot_half_hits`] over decoded planes (`x`, `y`, `z`: the 4 children's min and max),
/// the four slab tests side by side in `Vec4`s (one SSE register each on the CPU, which is
/// the only target that reads decoded planes) and the hit bits selected without a branch.
/// Each lane runs the scalar test's operations on the same numbers, so the hits are the
/// same to the bit.
#[inline(always)]
fn cwbvh_half_hits_decoded(
    ray: &NodeRay,
    meta4: u32,
    x: (Vec4, Vec4),
    y: (Vec4, Vec4),
    z: (Vec4, Vec4),
) -> u32 {
    let hit = decoded_slab_hits(ray, x, y, z);
    let (bits4, position4) = child_bits4(meta4, ray.oct_inv);
    let mut mask = 0u32;
    let mut k = 0u32;
    while k < 4 {
        mask |= slot_bits(bits4, position4, 8 * k) & 0u32.wrapping_sub((hit >> k) & 1);
        k += 1;
    }
    mask
}

/// Which of the 4 children with decoded planes `x`, `y`, `z` (min, max) the ray enters
/// within its t range: bit k for child k. The four slab tests side by side in `Vec4`s.
#[inline(always)]
fn decoded_slab_hits(ray: &NodeRay, x: (Vec4, Vec4), y: (Vec4, Vec4), z: (Vec4, Vec4)) -> u32 {
    let (nx, fx) = near_far(x.0, x.1, ray.negative[0]);
    let (ny, fy) = near_far(y.0, y.1, ray.negative[1]);
    let (nz, fz) = near_far(z.0, z.1, ray.negative[2]);
    let (s, o) = (ray.slope, ray.offset);
    let t = |plane: Vec4, slope: f32, offset: f32| plane * Vec4::splat(slope) + Vec4::splat(offset);
    let t_near = t(nx, s.x, o.x)
        .max(t(ny, s.y, o.y))
        .max(t(nz, s.z, o.z))
        .max(Vec4::ZERO);
    let t_far = t(fx, s.x, o.x)
        .min(t(fy, s.y, o.y))
        .min(t(fz, s.z, o.z))
        .min(Vec4::splat(ray.t_max));
    t_near.cmple(t_far).bitmask()
}

impl CwBvhPlanes {
    /// Which of the node's 8 slots' boxes the ray enters before `t_max`: bit k for slot k
    /// (empty slots included: mask them with their meta bytes). The same slab tests as
    /// [`WideNode::hits`], without turning the hits into traversal bits.
    #[inline(always)]
    pub fn slot_hits(&self, origin: Vec3, inv_dir: Vec3, t_max: f32) -> u32 {
        let ray = NodeRay::new(self.p, Vec3::ONE, origin, inv_dir, 0, t_max);
        let (m, n) = (self.child_min_x, self.child_max_x);
        let (k, l) = (self.child_min_y, self.child_max_y);
        let (i, j) = (self.child_min_z, self.child_max_z);
        decoded_slab_hits(&ray, (m[0], n[0]), (k[0], l[0]), (i[0], j[0]))
            | decoded_slab_hits(&ray, (m[1], n[1]), (k[1], l[1]), (i[1], j[1])) << 4
    }
}

/// A CWBVH node as a traversal reads it: obvhs's 80-byte node ([`CwBvhNode`]) or the same
/// node with its planes decoded ([`CwBvhPlanes`]).
pub trait WideNode {
    /// Node `i` of a buffer of these nodes read as words.
    fn read(nodes: &[UVec4], i: u32) -> Self;
    /// The ray against the node's 8 child boxes. Returns the hit mask in the paper's
    /// layout: high byte = interior children hit (bit 24 + traversal priority), low 24 bits
    /// = triangles of the leaf children hit. The near and far planes are picked once per
    /// node from the ray's direction signs.
    fn hits(&self, origin: Vec3, inv_dir: Vec3, oct_inv: u32, t_max: f32) -> u32;
    fn child_base(&self) -> u32;
    fn primitive_base(&self) -> u32;
    /// Bit k set when slot k holds an interior child.
    fn imask(&self) -> u32;
}

impl WideNode for CwBvhNode {
    #[inline(always)]
    fn read(nodes: &[UVec4], i: u32) -> Self {
        CwBvhNode::read(nodes, i)
    }
    /// The GPU's test ([`CwBvhSlotNode`]'s), its slot bits made on the spot: the host's
    /// pilot (`runner::ao_order`) walks the built nodes themselves.
    #[inline(always)]
    fn hits(&self, origin: Vec3, inv_dir: Vec3, oct_inv: u32, t_max: f32) -> u32 {
        CwBvhSlotNode::of(self).hits(origin, inv_dir, oct_inv, t_max)
    }
    fn child_base(&self) -> u32 {
        self.child_base_idx
    }
    fn primitive_base(&self) -> u32 {
        self.primitive_base_idx
    }
    fn imask(&self) -> u32 {
        CwBvhNode::imask(self)
    }
}

impl WideNode for CwBvhPlanes {
    #[inline(always)]
    fn read(nodes: &[UVec4], i: u32) -> Self {
        CwBvhPlanes::read(nodes, i)
    }
    #[inline(always)]
    fn hits(&self, origin: Vec3, inv_dir: Vec3, oct_inv: u32, t_max: f32) -> u32 {
        let ray = NodeRay::new(self.p, Vec3::ONE, origin, inv_dir, oct_inv, t_max);
        let (m, n) = (self.child_min_x, self.child_max_x);
        let (k, l) = (self.child_min_y, self.child_max_y);
        let (i, j) = (self.child_min_z, self.child_max_z);
        let meta = self.child_meta;
        cwbvh_half_hits_decoded(&ray, meta[0], (m[0], n[0]), (k[0], l[0]), (i[0], j[0]))
            | cwbvh_half_hits_decoded(&ray, meta[1], (m[1], n[1]), (k[1], l[1]), (i[1], j[1]))
    }
    fn child_base(&self) -> u32 {
        self.child_base_idx
    }
    fn primitive_base(&self) -> u32 {
        self.primitive_base_idx
    }
    fn imask(&self) -> u32 {
        self.imask
    }
}

impl WideNode for CwBvhSlotNode {
    #[inline(always)]
    fn read(nodes: &[UVec4], i: u32) -> Self {
        CwBvhSlotNode::read(nodes, i)
    }
    #[inline(always)]
    fn hits(&self, origin: Vec3, inv_dir: Vec3, oct_inv: u32, t_max: f32) -> u32 {
        let n = &self.node;
        // Child box = p + scale · q: the ray into the node's quantised grid.
        let ray = NodeRay::new(n.p, n.scale(), origin, inv_dir, oct_inv, t_max);
        let (m, x) = (n.child_min_x, n.child_max_x);
        let (k, y) = (n.child_min_y, n.child_max_y);
        let (i, z) = (n.child_min_z, n.child_max_z);
        let s = self.slot_bits;
        let slots = slot_half_hits(
            &ray,
            [s[0], s[1], s[2], s[3]],
            (m[0], x[0]),
            (k[0], y[0]),
            (i[0], z[0]),
        ) | slot_half_hits(
            &ray,
            [s[4], s[5], s[6], s[7]],
            (m[1], x[1]),
            (k[1], y[1]),
            (i[1], z[1]),
        );
        interior_in_priority_order(slots, oct_inv)
    }
    fn child_base(&self) -> u32 {
        self.node.child_base_idx
    }
    fn primitive_base(&self) -> u32 {
        self.node.primitive_base_idx
    }
    fn imask(&self) -> u32 {
        self.node.imask()
    }
}

/// The slot bits (`bits`, [`CwBvhSlotNode::slot_bits`]) of the 4 children whose bytes are
/// in one word of each of the node's child arrays (half 0: children 0–3, half 1: children
/// 4–7) that the ray enters: a hit child costs one OR of its stored bits. Decoding them
/// from the meta bytes here instead, four slots' worth at a time (`child_bits4`, until
/// the slot bits were stored), cost every kernel 1–3.5% (H100, two rounds: AO rocks-1m
/// 10.37 → 10.05 ms, spheres-1m 22.88 → 22.12, city-1m 18.03 → 17.39, grass-1m 26.63 →
/// 25.76, shell-1m 52.77 → 51.01, Cornell 3.94 → 3.82; Cornell MIS 1.508 → 1.492,
/// many-lights NEE 0.651 → 0.640). The bytes stay int-to-float conversions: converting
/// them by OR-ing into 2^23's mantissa and subtracting 2^23 (exact, no conversion
/// instruction) made every kernel 8–14% slower on the H200 (AO city-1m 33.0 → 36.7 ms,
/// Cornell MIS 2.08 → 2.36): the driver's conversion selects the byte itself.
#[inline(always)]
fn slot_half_hits(
    ray: &NodeRay,
    bits: [u32; 4],
    x: (u32, u32),
    y: (u32, u32),
    z: (u32, u32),
) -> u32 {
    let (nx, fx) = near_far(x.0, x.1, ray.negative[0]);
    let (ny, fy) = near_far(y.0, y.1, ray.negative[1]);
    let (nz, fz) = near_far(z.0, z.1, ray.negative[2]);
    // The four children written out: rust-gpu leaves a loop over them a loop in the
    // SPIR-V, its byte shifts variables.
    let child = |shift: u32, bits: u32| {
        let q = |w: u32| ((w >> shift) & 0xff) as f32;
        let near = Vec3::new(q(nx), q(ny), q(nz));
        let far = Vec3::new(q(fx), q(fy), q(fz));
        if slab_hit(ray, near, far) {
            bits
        } else {
            0
        }
    };
    child(0, bits[0]) | child(8, bits[1]) | child(16, bits[2]) | child(24, bits[3])
}

/// A node's hit mask with its interior children's bits moved from 24 + slot (where
/// [`CwBvhSlotNode::slot_bits`] keeps them) to 24 + slot XOR `oct_inv`, their traversal
/// priority (see [`cwbvh_octant_inv`]): the high byte's bits swapped singly, in pairs and
/// by nibbles as `oct_inv`'s three bits say. As selects: the same swaps as XOR masks made
/// of the bits ("delta swaps") were 0.3–1.5% slower (H100, same runs as above).
#[inline(always)]
fn interior_in_priority_order(mask: u32, oct_inv: u32) -> u32 {
    let swap = |m: u32, by: u32, low: u32| {
        ((m >> by) & low) | ((m & low) << by) | (m & !(low | (low << by)))
    };
    let m = mask;
    let m = if oct_inv & 1 != 0 {
        swap(m, 1, 0x5500_0000)
    } else {
        m
    };
    let m = if oct_inv & 2 != 0 {
        swap(m, 2, 0x3300_0000)
    } else {
        m
    };
    if oct_inv & 4 != 0 {
        swap(m, 4, 0x0f00_0000)
    } else {
        m
    }
}

/// The node layout the traversal reads on this target. The GPU reads obvhs's 80-byte
/// nodes with each slot's hit-mask bits after them (112 bytes, [`CwBvhSlotNode`]; the
/// bits save more than their loads cost, see [`slot_half_hits`]); with planes decoded to
/// f32 (224 bytes) its kernels were 0–9% slower (H200, AO
/// 1080p: rocks-1m, spheres-1m, city-1m the same, grass-1m 45.7 → 49.1 ms, shell-1m 100.3
/// → 105.0; Cornell MIS 1.96 → 2.15, many-lights NEE 0.913 → 0.981), as it pays for the
/// loads more than for the conversions. The CPU pays for the conversions: AO on the CPU
/// backend 16–21% faster with decoded planes, 27–41% with their children tested four at a
/// time and the node read inlined (rocks-1m, spheres-1m, city-1m, grass-1m; 2-core box;
/// docs/PERFORMANCE.md, "The CPU backend against Embree"). The host
/// builds each backend's buffer (`runner::accel::host_nodes`, `runner::accel::gpu_node`);
/// the traversal is the same
/// code over either ([`WideNode`]), and both give the same t to the bit.
#[cfg(target_arch = "spirv")]
pub type TraversalNode = CwBvhSlotNode;
#[cfg(not(target_arch = "spirv"))]
pub type TraversalNode = CwBvhPlanes;

/// Stack traversal of obvhs's CWBVH (Ylitie, Karras, Laine 2017, Algorithm 1): a stack of
/// node groups (child base index, hit bits) and one triangle group at a time.
pub fn cwbvh_traverse<const PLAIN: bool, N: WideNode>(
    triangles: &[UVec4],
    cutouts: &Cutouts,
    nodes: &[UVec4],
    ray: &Ray,
    t_max: f32,
    any: bool,
) -> Hit {
    if nodes.is_empty() {
        return Hit::none(t_max);
    }
    // Front to back: a closest hit found early shortens the ray for the rest of the walk.
    let mut walk = CwbvhWalk::new(ray, t_max, Skip::NONE, AO_NEAR_FIRST);
    while !walk.step::<PLAIN, false, false, N>(triangles, cutouts, nodes, any) {}
    walk.hit
}

/// Nodes that the pooled AO walk (`SceneBuffers::trace_pool`) visits for `ray`, which
/// skips the triangles of `skip`, to `t_max` with children in `order`: what the GPU's time follows
/// (docs/PERFORMANCE.md, "Benchmark suite"); the host's pilot (`runner::ao_order`) counts it
/// over the GPU's own nodes.
pub fn cwbvh_ao_walk_nodes<const PLAIN: bool, N: WideNode>(
    triangles: &[UVec4],
    cutouts: &Cutouts,
    nodes: &[UVec4],
    ray: &Ray,
    (skip, t_max): (Skip, f32),
    order: u32,
) -> u32 {
    if nodes.is_empty() {
        return 0;
    }
    let mut walk = CwbvhWalk::new(ray, t_max, skip, order);
    let mut visited = 0;
    loop {
        // A step visits a node while its group has interior children left (`step`).
        visited += (walk.group_bits & INTERIOR_HITS != 0) as u32;
        if walk.step::<PLAIN, true, AO_ONE_TRIANGLE, N>(triangles, cutouts, nodes, true) {
            return visited;
        }
    }
}

/// A CWBVH traversal in progress, advanced one node at a time by `step`, so that a caller
/// with many rays can run them back to back in one loop (`SceneBuffers::trace_pool`).
struct CwbvhWalk {
    tester: TriangleTester,
    origin: Vec3,
    inv_dir: Vec3,
    oct_inv: u32,
    /// The nearest hit so far (t = the ray's end while none).
    hit: Hit,
    /// Triangles the ray cannot meet (`RayPool::ray`), never tested.
    skip: Skip,
    /// Node groups (child base index, hit bits), one 64-bit entry each: one local-memory
    /// access per push or pop instead of two. Entries below `sp` are written before they
    /// are read: left uninitialised, as every traversal used to spend time zeroing them in
    /// local memory.
    stack: [MaybeUninit<UVec2>; CWBVH_STACK],
    sp: usize,
    /// The node group being visited: child base index and hit bits.
    group_base: u32,
    group_bits: u32,
    /// With `step`'s `ONE`: the triangles waiting to be tested, a step testing one
    /// (base index, bits); further groups wait on the stack (their top byte 0).
    tri_base: u32,
    tri_bits: u32,
}

impl CwbvhWalk {
    fn new(ray: &Ray, t_max: f32, skip: Skip, order: u32) -> Self {
        let mut walk = Self {
            tester: TriangleTester::new(ray),
            origin: ray.origin,
            inv_dir: Vec3::ZERO,
            oct_inv: 0,
            hit: Hit::none(t_max),
            skip,
            stack: [MaybeUninit::uninit(); CWBVH_STACK],
            sp: 0,
            group_base: 0,
            group_bits: 0,
            tri_base: 0,
            tri_bits: 0,
        };
        walk.restart(ray, t_max, skip, order);
        walk
    }

    /// Begin `ray` at the root (the stack's contents are left, unread), never testing
    /// the triangles of `skip`, visiting each node's children in `order` (`AO_NEAR_FIRST` or
    /// `AO_FAR_FIRST`).
    fn restart(&mut self, ray: &Ray, t_max: f32, skip: Skip, order: u32) {
        count!(TRAVERSALS);
        self.tester = TriangleTester::new(ray);
        self.origin = ray.origin;
        self.inv_dir = safe_recip(ray.dir);
        self.oct_inv = cwbvh_octant_inv(ray.dir) ^ order;
        self.hit = Hit::none(t_max);
        self.skip = skip;
        self.sp = 0;
        // The root is the only "interior child" of a virtual group at node 0.
        self.group_base = 0;
        self.group_bits = 1u32 << 31;
        self.tri_bits = 0;
    }

    /// Visit one node and test the triangles of it the ray hits; true when the walk is over
    /// (`hit` final; with `any`, the first hit found ends it). Inlined, with the node
    /// test, into the traversal loops: as a call per node the CPU kept the walk's state
    /// in memory (AO on the CPU backend 10–15% slower). `SKIPS`: the walk drops the
    /// triangles its ray cannot meet (`skip`; pooled AO rays) from the node's hits, so that
    /// they take neither a test nor, with `ONE`, a step of their own (the pilot's steps per
    /// AO ray with the triangle it leaves dropped: shell-1m 12.09 → 11.62, spheres-1m 7.03 →
    /// 6.65, grass-1m 10.88 → 10.85; with those below its plane too: `skip`); without
    /// it the walk keeps every triangle, with no compare for it in the loop (the compare
    /// against `INVALID` made Cornell MIS 0.8% slower on the H200). `ONE`: the step tests
    /// at most one triangle of the walk's waiting group (`tri_bits`), the node's hit
    /// triangles joining it (or waiting on the stack, a group whose top byte is 0, where one
    /// is in hand); the walk is over when nodes and triangles are both done. The stack is
    /// full only in a tree near `CWBVH_STACK` levels deep: then the node's triangles are
    /// tested at once.
    #[inline(always)]
    fn step<const PLAIN: bool, const SKIPS: bool, const ONE: bool, N: WideNode>(
        &mut self,
        triangles: &[UVec4],
        cutouts: &Cutouts,
        nodes: &[UVec4],
        any: bool,
    ) -> bool {
        let mut tri_base = 0u32;
        let mut tri_bits = 0u32;
        if self.group_bits & INTERIOR_HITS != 0 {
            let slot_bit = first_bit_high(self.group_bits);
            self.group_bits &= !shl(1, slot_bit);
            // Interior children are stored contiguously in slot order: the node's index is
            // the number of interior siblings (imask, the group's low byte) in lower slots.
            let slot = (slot_bit - FIRST_INTERIOR_BIT) ^ self.oct_inv;
            let relative = (self.group_bits & 0xff & !shl(u32::MAX, slot)).count_ones();
            let child = self.group_base + relative;
            if self.group_bits & INTERIOR_HITS != 0 && self.sp < CWBVH_STACK {
                self.push(self.group_base, self.group_bits);
            }
            count!(NODES);
            let node = N::read(nodes, child);
            let hits = node.hits(self.origin, self.inv_dir, self.oct_inv, self.hit.t);
            self.group_base = node.child_base();
            self.group_bits = (hits & INTERIOR_HITS) | node.imask();
            tri_base = node.primitive_base();
            tri_bits = hits & TRIANGLE_HITS;
            if SKIPS {
                // Triangles the ray cannot meet take neither a test nor a step.
                tri_bits &= !self.skip.node_bits(tri_base);
            }
            if ONE && tri_bits != 0 {
                if self.tri_bits == 0 {
                    (self.tri_base, self.tri_bits) = (tri_base, tri_bits);
                    tri_bits = 0;
                } else if self.sp < CWBVH_STACK {
                    self.push(tri_base, tri_bits);
                    tri_bits = 0;
                }
                // Else the stack is full: the group is tested in this step, below.
            }
        }
        if ONE && self.tri_bits != 0 {
            let k = first_bit_high(self.tri_bits);
            self.tri_bits &= !shl(1, k);
            if self.test::<PLAIN>(triangles, cutouts, self.tri_base + k, any) {
                return true;
            }
        }
        while tri_bits != 0 {
            let k = first_bit_high(tri_bits);
            tri_bits &= !shl(1, k);
            if self.test::<PLAIN>(triangles, cutouts, tri_base + k, any) {
                return true;
            }
        }
        if self.group_bits & INTERIOR_HITS == 0 {
            if self.sp == 0 {
                return !ONE || self.tri_bits == 0;
            }
            let entry = self.top();
            if !ONE || entry.y & INTERIOR_HITS != 0 {
                self.sp -= 1;
                (self.group_base, self.group_bits) = (entry.x, entry.y);
            } else if self.tri_bits == 0 {
                // A waiting triangle group: taken once the one in hand is done.
                self.sp -= 1;
                (self.tri_base, self.tri_bits) = (entry.x, entry.y);
            }
        }
        false
    }

    /// Push a group (sp < `CWBVH_STACK`: every caller checks). In SPIR-V without the
    /// bounds check, as [`Self::top`].
    #[inline(always)]
    fn push(&mut self, base: u32, bits: u32) {
        let entry = MaybeUninit::new(UVec2::new(base, bits));
        // SAFETY: sp < CWBVH_STACK, the stack's length, where every caller pushes.
        unsafe { set_at(&mut self.stack, self.sp, entry) };
        self.sp += 1;
    }

    /// The top entry (sp > 0). rust-gpu turns a failed bounds check (any panic) into a
    /// return from the kernel, which spirv-opt's single-exit rewrite makes a flag tested
    /// throughout the loops around it; `push` keeps sp within the stack, so the GPU's walk
    /// goes without. (A build whose panics were all undefined behaviour instead, rust-gpu's
    /// unsound `--abort-strategy=unreachable`, had every AO scene 5–6% faster on the H100:
    /// docs/PERFORMANCE.md, "Panics in the walk's loop".)
    #[inline(always)]
    fn top(&self) -> UVec2 {
        // SAFETY: 0 < sp ≤ CWBVH_STACK (`push` checks), and entry `sp - 1` was pushed
        // (written) before `sp` passed it.
        unsafe { at(&self.stack, self.sp - 1).assume_init() }
    }

    /// Test triangle `i`; true when `any` and it was hit (the walk is over).
    #[inline(always)]
    fn test<const PLAIN: bool>(
        &mut self,
        triangles: &[UVec4],
        cutouts: &Cutouts,
        i: u32,
        any: bool,
    ) -> bool {
        let tester = &self.tester;
        test_leaf::<PLAIN>(triangles, cutouts, tester, i, 1, &mut self.hit, any)
    }
}

/// Shading frame at a hit: position, unit geometric normal turned towards the incoming
/// ray (surfaces are two-sided), the shading normal on the same side, texture
/// coordinates, and whether the ray hit the front (emitting) side.
#[derive(Copy, Clone, Debug)]
pub struct SurfaceHit {
    pub p: Vec3,
    /// Geometric normal: ray offsets and the test that a direction leaves the surface.
    pub n: Vec3,
    /// Shading normal: the interpolated vertex normal, or `n` without vertex normals. The
    /// BSDF's cosines and sampling use it.
    pub ns: Vec3,
    pub uv: Vec2,
    /// How far the pixel's footprint here spans in texture coordinates (0: a point, read
    /// from the full-size textures): textures are read from the mip levels of that size.
    pub uv_footprint: f32,
    /// The interpolated vertex colour (white without one): it multiplies the albedo.
    pub colour: Vec3,
    pub front_face: bool,
    pub prim: u32,
}

impl SurfaceHit {
    /// A flat, untextured surface point.
    pub fn flat(p: Vec3, n: Vec3, front_face: bool, prim: u32) -> Self {
        Self {
            p,
            n,
            ns: n,
            uv: Vec2::ZERO,
            uv_footprint: 0.0,
            colour: Vec3::ONE,
            front_face,
            prim,
        }
    }

    /// Whether the direction `dir` is on the same side of the geometric surface as of the
    /// shading one. With vertex normals a direction above the shading hemisphere can still
    /// point into the geometric surface (or one refracted below it point out); such
    /// directions carry no light, so smooth normals never leak light through a face.
    pub fn leaves(&self, dir: Vec3) -> bool {
        self.ns == self.n || (dir.dot(self.n) > 0.0) == (dir.dot(self.ns) > 0.0)
    }

    /// The shading frame's tangents (t, b) with `ns`: world ↔ local for the BSDF.
    pub fn to_local(&self, w: Vec3) -> Vec3 {
        let (t, b) = orthonormal_basis(self.ns);
        Vec3::new(w.dot(t), w.dot(b), w.dot(self.ns))
    }

    /// The ray origin for leaving the surface towards `dir`: offset to that side.
    pub fn origin_towards(&self, dir: Vec3) -> Vec3 {
        offset_ray_origin(
            self.p,
            if dir.dot(self.n) >= 0.0 {
                self.n
            } else {
                -self.n
            },
        )
    }
}

/// The surface a ray hit. `cone_width`: the width there of the cone of directions of the
/// pixel the ray's path started from (`pixel_spread` × the distance the path has
/// travelled; 0 for a point), which chooses the mip levels its textures are read from.
pub fn surface_hit(scene: &SceneBuffers, ray: &Ray, hit: &Hit, cone_width: f32) -> SurfaceHit {
    let tri = scene.triangle(hit.prim);
    let ng = tri.normal();
    let front_face = ng.dot(ray.dir) < 0.0;
    let n = if front_face { ng } else { -ng };
    let mut s = SurfaceHit::flat(tri.point(hit.b1, hit.b2), n, front_face, hit.prim);
    if tri.shading_index() != INVALID {
        let a = load(scene.shading, tri.shading_index() as usize);
        let (b1, b2) = (hit.b1, hit.b2);
        let b0 = 1.0 - b1 - b2;
        // The file's normal at the point (interpolated, or the face's), as authored: a
        // normal map bends it in its own orientation before it is turned to the ray.
        let mut base = ng;
        if a.flags & SHADING_NORMALS != 0 {
            let m = a.normal(0) * b0 + a.normal(1) * b1 + a.normal(2) * b2;
            let len = m.length();
            if len > 0.0 && len.is_finite() {
                base = m / len;
            }
        }
        let mut shading = base;
        if a.flags & SHADING_UVS != 0 {
            s.uv = a.uv_at(b1, b2);
            if cone_width > 0.0 {
                s.uv_footprint = uv_footprint(&tri, &a, ray.dir, cone_width);
            }
            let m = load(scene.materials, tri.material as usize);
            // Normal and height maps are read from the full-size image (as pbrt-v4 does):
            // shading is not linear in the normal, so an averaged normal would shade a
            // distant bumpy surface as a flatter one, not as the average of its bumps.
            if m.normal_texture != INVALID {
                let texel = sample_texture(scene.textures, scene.texels, m.normal_texture, s.uv);
                shading = if m.normal_map_kind == NORMAL_MAP_HEIGHT {
                    let slope = height_slope(scene, m.normal_texture, s.uv, texel.x);
                    bump_mapped(&tri, &a, base, slope * m.normal_scale)
                } else {
                    normal_mapped(&tri, &a, b1, b2, base, texel.truncate(), m.normal_scale)
                };
            }
        }
        // Turned to the side the ray arrived on, like `n` (two-sided surfaces); a map that
        // bends the normal past the face's horizon is not followed there.
        let side = if base.dot(n) < 0.0 { -1.0 } else { 1.0 };
        s.ns = if (shading * side).dot(n) > MIN_SHADING_COSINE {
            shading * side
        } else {
            base * side
        };
        if a.flags & SHADING_COLOURS != 0 {
            s.colour = a.colour(0) * b0 + a.colour(1) * b1 + a.colour(2) * b2;
        }
    }
    s
}

/// A footprint seen this obliquely or more is taken as seen at this cosine: the
/// footprint of a grazing ray grows without bound, and past it the texture's average over
/// the whole surface would be read.
const MIN_FOOTPRINT_COSINE: f32 = 0.05;

/// The span in texture coordinates of a cone `cone_width` wide arriving along `dir` at
/// triangle `tri` with attributes `a` (ray cones, Akenine-Möller et al. 2019): the width,
/// stretched by the obliquity, times the triangle's texture-to-surface scale
/// √(uv area / area). 0 where the triangle has no texture area to speak of.
pub fn uv_footprint(tri: &Triangle, a: &TriangleShading, dir: Vec3, cone_width: f32) -> f32 {
    let (t1, t2) = (a.uv(1) - a.uv(0), a.uv(2) - a.uv(0));
    let uv_area = 0.5 * (t1.x * t2.y - t1.y * t2.x).abs();
    let cosine = tri.normal().dot(dir).abs().max(MIN_FOOTPRINT_COSINE);
    let footprint = cone_width / cosine * crate::math::sqrt(uv_area / tri.area());
    if footprint.is_finite() {
        footprint
    } else {
        0.0
    }
}

/// The slope (∂h/∂u, ∂h/∂v) of height map `texture` at `uv`, where its value is `here`:
/// differences one texel apart.
fn height_slope(scene: &SceneBuffers, texture: u32, uv: Vec2, here: f32) -> Vec2 {
    let info = load(scene.textures, texture as usize);
    let step = Vec2::new(1.0 / info.width as f32, 1.0 / info.height as f32);
    let height = |at: Vec2| sample_texture(scene.textures, scene.texels, texture, at).x;
    Vec2::new(
        (height(uv + Vec2::new(step.x, 0.0)) - here) / step.x,
        (height(uv + Vec2::new(0.0, step.y)) - here) / step.y,
    )
}

/// A shading normal closer than this cosine to the face's plane is not used: a normal map
/// that bends past the horizon keeps the unmapped normal there.
const MIN_SHADING_COSINE: f32 = 1e-3;

/// The normal `base` of triangle `tri` at barycentrics (b1, b2) bent by a tangent-space
/// normal map texel (each channel in [0, 1] encoding [−1, 1]; x along the tangent, y along
/// the bitangent, z along `base`; x and y scaled by `scale`), in `tangent_frame`'s frame.
/// Without a usable frame or a texel encoding no direction, `base` is kept.
#[allow(clippy::too_many_arguments)] // the hit (triangle, attributes, barycentrics) and the map
pub fn normal_mapped(
    tri: &Triangle,
    a: &TriangleShading,
    b1: f32,
    b2: f32,
    base: Vec3,
    texel: Vec3,
    scale: f32,
) -> Vec3 {
    let Some((t, b)) = tangent_frame(tri, a, b1, b2, base) else {
        return base;
    };
    let m = texel * 2.0 - Vec3::ONE;
    let bent = t * (m.x * scale) + b * (m.y * scale) + base * m.z;
    let bent = bent.normalize_or_zero();
    if bent == Vec3::ZERO || !bent.is_finite() {
        base
    } else {
        bent
    }
}

/// Squared share of a tangent that must lie across the normal for it to orient a normal
/// map (encoding error is ~1e-4; a tangent within ~0.5° of the normal orients nothing).
const MIN_TANGENT_SHARE: f32 = 1e-4;

/// The tangent and bitangent of a normal map at barycentrics (b1, b2), orthogonal to
/// `base`. The file's tangents when it has them (glTF `TANGENT`, which its normal maps were
/// baked against: interpolated, bitangent = base × tangent × w); else the triangle's own
/// frame: dp/du, and the bitangent on the side of dp/dv (the mapping's handedness, so a
/// mirrored texture keeps its bumps: x along increasing u, y along increasing v). None
/// where neither gives a direction (degenerate texture coordinates).
fn tangent_frame(
    tri: &Triangle,
    a: &TriangleShading,
    b1: f32,
    b2: f32,
    base: Vec3,
) -> Option<(Vec3, Vec3)> {
    let (along, handedness) = if a.flags & SHADING_TANGENTS != 0 {
        let t = a.tangent(0) * (1.0 - b1 - b2) + a.tangent(1) * b1 + a.tangent(2) * b2;
        let flipped = a.flags & SHADING_BITANGENT_FLIPPED != 0;
        (t, if flipped { -1.0 } else { 1.0 })
    } else {
        let (dpdu, dpdv) = uv_derivatives(tri, a)?;
        (
            dpdu,
            if base.cross(dpdu).dot(dpdv) < 0.0 {
                -1.0
            } else {
                1.0
            },
        )
    };
    // Made orthogonal to the normal; a tangent (nearly) along it orients nothing.
    let across = along - base * base.dot(along);
    let enough = across.length_squared() > MIN_TANGENT_SHARE * along.length_squared();
    if !enough {
        return None; // also where the tangent is not finite
    }
    let t = across.normalize();
    Some((t, base.cross(t) * handedness))
}

/// dp/du and dp/dv of triangle `tri` under its texture coordinates; none where the
/// coordinates do not span the triangle.
fn uv_derivatives(tri: &Triangle, a: &TriangleShading) -> Option<(Vec3, Vec3)> {
    let (p0, p1, p2) = tri.vertices();
    let (e1, e2) = (p1 - p0, p2 - p0);
    let (d1, d2) = (a.uv(1) - a.uv(0), a.uv(2) - a.uv(0));
    let det = d1.x * d2.y - d1.y * d2.x;
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    Some(((e1 * d2.y - e2 * d1.y) / det, (e2 * d1.x - e1 * d2.x) / det))
}

/// The normal `base` of triangle `tri` under a bump map whose displacement along the
/// normal changes by `slope` (∂d/∂u, ∂d/∂v, in scene units per unit of u and v): the
/// normal of the displaced surface p + d·n, whose tangents are dp/du + ∂d/∂u·n and
/// dp/dv + ∂d/∂v·n (pbrt's bump mapping without the normal's own change, which is
/// small on the faces it is used on), turned to `base`'s side.
pub fn bump_mapped(tri: &Triangle, a: &TriangleShading, base: Vec3, slope: Vec2) -> Vec3 {
    let Some((dpdu, dpdv)) = uv_derivatives(tri, a) else {
        return base;
    };
    let bent = (dpdu + base * slope.x).cross(dpdv + base * slope.y);
    let bent = bent.normalize_or_zero();
    if bent == Vec3::ZERO || !bent.is_finite() {
        base
    } else if bent.dot(base) < 0.0 {
        -bent
    } else {
        bent
    }
}

/// Move a ray origin off the surface along the normal by a few ulps of the position
/// (Wächter & Binder, "A Fast and Robust Method for Avoiding Self-Intersection", Ray
/// Tracing Gems ch. 6): no acne, and no leaks through thin walls, in scenes of about unit
/// size near the origin, where the loader keeps every scene (`runner::scene_frame`).
pub fn offset_ray_origin(p: Vec3, n: Vec3) -> Vec3 {
    Vec3::new(
        offset_component(p.x, n.x),
        offset_component(p.y, n.y),
        offset_component(p.z, n.z),
    )
}

fn offset_component(p: f32, n: f32) -> f32 {
    const ORIGIN: f32 = 1.0 / 32.0;
    const FLOAT_SCALE: f32 = 1.0 / 65536.0;
    const INT_SCALE: f32 = 256.0;
    if p.abs() < ORIGIN {
        return p + FLOAT_SCALE * n;
    }
    let of_i = (INT_SCALE * n) as i32;
    let bits = p.to_bits() as i32;
    let moved = if p < 0.0 { bits - of_i } else { bits + of_i };
    f32::from_bits(moved as u32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn four_slots_bits_at_once_are_each_slots_bits() {
        // Every meta byte obvhs writes: empty, interior (24 + slot), and leaves of 1, 2 or 3
        // triangles at offsets below 24.
        let mut metas = vec![0u32];
        metas.extend((0..8).map(|slot| (1 << 5) | (24 + slot)));
        for bits in [1u32, 3, 7] {
            metas.extend((0..24).map(|offset| (bits << 5) | offset));
        }
        for oct_inv in 0..8 {
            let ray = NodeRay::new([0.0; 3], Vec3::ONE, Vec3::ZERO, Vec3::ONE, oct_inv, 1.0);
            for (i, &a) in metas.iter().enumerate() {
                // Each meta byte in each of the four positions, beside three others.
                let b = metas[(i * 7 + 1) % metas.len()];
                let c = metas[(i * 13 + 2) % metas.len()];
                let d = metas[(i * 29 + 3) % metas.len()];
                for meta4 in [
                    a | b << 8 | c << 16 | d << 24,
                    d | a << 8 | b << 16 | c << 24,
                    c | d << 8 | a << 16 | b << 24,
                    b | c << 8 | d << 16 | a << 24,
                ] {
                    let (bits4, position4) = child_bits4(meta4, oct_inv);
                    for shift in [0, 8, 16, 24] {
                        let bits = slot_bits(bits4, position4, shift);
                        assert_eq!(bits, child_bits(&ray, (meta4 >> shift) & 0xff));
                    }
                }
            }
        }
    }

    #[test]
    fn stored_slot_bits_in_priority_order_are_each_slots_bits() {
        // Every meta byte obvhs writes, in every slot, beside others, for every octant (a
        // leaf's triangles end by offset 24).
        let mut metas = vec![0u32];
        metas.extend((0..8).map(|slot| (1 << 5) | (24 + slot)));
        for (bits, count) in [(1u32, 1), (3, 2), (7, 3)] {
            metas.extend((0..=24 - count).map(|offset| (bits << 5) | offset));
        }
        for (i, _) in metas.iter().enumerate() {
            let meta = |k: usize| {
                let m = metas[(i * (2 * k + 1) + k) % metas.len()];
                // An interior child's byte names its own slot.
                if crate::types::cwbvh_meta::is_interior(m) {
                    (1 << 5) | (24 + k as u32)
                } else {
                    m
                }
            };
            let word = |h: usize| (0..4).fold(0, |w, k| w | meta(4 * h + k) << (8 * k));
            let node = CwBvhNode {
                child_meta: [word(0), word(1)],
                ..Default::default()
            };
            let slots = CwBvhSlotNode::of(&node);
            for oct_inv in 0..8 {
                let ray = NodeRay::new([0.0; 3], Vec3::ONE, Vec3::ZERO, Vec3::ONE, oct_inv, 1.0);
                // All slots' bits together, as a node whose children are all hit gives them.
                let all = slots.slot_bits.iter().fold(0, |m, b| m | b);
                let want = (0..8).fold(0, |m, k| m | child_bits(&ray, meta(k)));
                assert_eq!(
                    interior_in_priority_order(all, oct_inv),
                    want,
                    "{node:?} {oct_inv}"
                );
                for (k, &bits) in slots.slot_bits.iter().enumerate() {
                    assert_eq!(
                        interior_in_priority_order(bits, oct_inv),
                        child_bits(&ray, meta(k))
                    );
                }
            }
        }
    }

    /// A triangle in the z = 0 plane (normal +z) with texture coordinates at its corners.
    fn mapped(uvs: [f32; 6]) -> (Triangle, TriangleShading) {
        let tri = Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y, 0);
        let shading = TriangleShading {
            uvs,
            flags: crate::types::SHADING_UVS,
            ..Default::default()
        };
        (tri, shading)
    }

    /// The texel encoding direction m.
    fn texel(m: Vec3) -> Vec3 {
        m * 0.5 + Vec3::splat(0.5)
    }

    #[test]
    fn normal_maps_lean_along_the_texture_axes_mirrored_or_not() {
        // The map at a triangle's first corner, on the normal +z, at strength `scale`.
        let bend = |(tri, a): &(Triangle, TriangleShading), m: Vec3, scale: f32| {
            normal_mapped(tri, a, 0.0, 0.0, Vec3::Z, texel(m), scale)
        };
        let (lean_u, lean_v) = (Vec3::new(0.6, 0.0, 0.8), Vec3::new(0.0, 0.6, 0.8));
        // u along +x, v along +y: the map's x is +x.
        let plain = mapped([0.0, 0.0, 1.0, 0.0, 0.0, 1.0]);
        assert!((bend(&plain, lean_u, 1.0) - lean_u).length() < 1e-5);
        assert!((bend(&plain, lean_v, 1.0) - lean_v).length() < 1e-5);
        // Mirrored in u (u grows along −x): the map's x leans towards −x, its y still +y.
        let mirrored = mapped([0.0, 0.0, -1.0, 0.0, 0.0, 1.0]);
        let n = bend(&mirrored, lean_u, 1.0);
        assert!((n - Vec3::new(-0.6, 0.0, 0.8)).length() < 1e-5, "{n}");
        assert!((bend(&mirrored, lean_v, 1.0) - lean_v).length() < 1e-5);
        // Scale 0 flattens the map; degenerate texture coordinates keep the normal.
        assert!((bend(&mirrored, lean_u, 0.0) - Vec3::Z).length() < 1e-6);
        assert_eq!(bend(&mapped([0.5; 6]), lean_u, 1.0), Vec3::Z);
    }

    #[test]
    fn file_tangents_orient_the_normal_map() {
        // Texture coordinates say x is along +x; the file's tangent says +y, and wins.
        let (tri, mut a) = mapped([0.0, 0.0, 1.0, 0.0, 0.0, 1.0]);
        a.tangents = [crate::types::encode_unit(Vec3::Y); 3];
        a.flags |= SHADING_TANGENTS;
        let lean = Vec3::new(0.6, 0.0, 0.8);
        let n = normal_mapped(&tri, &a, 0.3, 0.3, Vec3::Z, texel(lean), 1.0);
        assert!((n - Vec3::new(0.0, 0.6, 0.8)).length() < 1e-4, "{n}");
        // The bitangent is base × tangent = −x; w = −1 flips it to +x.
        let up = Vec3::new(0.0, 0.6, 0.8);
        let n = normal_mapped(&tri, &a, 0.3, 0.3, Vec3::Z, texel(up), 1.0);
        assert!((n - Vec3::new(-0.6, 0.0, 0.8)).length() < 1e-4, "{n}");
        a.flags |= SHADING_BITANGENT_FLIPPED;
        let n = normal_mapped(&tri, &a, 0.3, 0.3, Vec3::Z, texel(up), 1.0);
        assert!((n - Vec3::new(0.6, 0.0, 0.8)).length() < 1e-4, "{n}");
        // A tangent along the normal gives no frame: the normal stays.
        a.tangents = [crate::types::encode_unit(Vec3::Z); 3];
        assert_eq!(
            normal_mapped(&tri, &a, 0.3, 0.3, Vec3::Z, texel(lean), 1.0),
            Vec3::Z
        );
    }

    #[test]
    fn unit_vectors_survive_their_one_word_encoding() {
        let mut rng = crate::rng::Rng::from_seed(7);
        for _ in 0..10_000 {
            let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE;
            let Some(v) = v.try_normalize() else { continue };
            let back = crate::types::decode_unit(crate::types::encode_unit(v));
            assert!((back - v).length() < 2e-4, "{v} -> {back}");
        }
        for v in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z] {
            let back = crate::types::decode_unit(crate::types::encode_unit(v));
            assert!((back - v).length() < 1e-4, "{v} -> {back}");
        }
    }

    #[test]
    fn bump_maps_tilt_away_from_the_rise_mirrored_or_not() {
        // u along +x: a height rising by ½ per unit of u is a slope of ½ along +x, whose
        // normal leans towards −x: (−½, 0, 1).
        let (tri, a) = mapped([0.0, 0.0, 1.0, 0.0, 0.0, 1.0]);
        let n = bump_mapped(&tri, &a, Vec3::Z, Vec2::new(0.5, 0.0));
        assert!(
            (n - Vec3::new(-0.5, 0.0, 1.0).normalize()).length() < 1e-5,
            "{n}"
        );
        // Rising along v (+y): leans towards −y.
        let n = bump_mapped(&tri, &a, Vec3::Z, Vec2::new(0.0, 0.5));
        assert!(
            (n - Vec3::new(0.0, -0.5, 1.0).normalize()).length() < 1e-5,
            "{n}"
        );
        // Mirrored in u (u grows along −x): the rise is along −x, the lean towards +x; the
        // normal stays on the base's side.
        let (tri, a) = mapped([0.0, 0.0, -1.0, 0.0, 0.0, 1.0]);
        let n = bump_mapped(&tri, &a, Vec3::Z, Vec2::new(0.5, 0.0));
        assert!(
            (n - Vec3::new(0.5, 0.0, 1.0).normalize()).length() < 1e-5,
            "{n}"
        );
        // No slope, or degenerate texture coordinates: the base normal.
        assert!((bump_mapped(&tri, &a, Vec3::Z, Vec2::ZERO) - Vec3::Z).length() < 1e-6);
        let (tri, a) = mapped([0.5; 6]);
        assert_eq!(bump_mapped(&tri, &a, Vec3::Z, Vec2::new(0.5, 0.0)), Vec3::Z);
    }

    #[test]
    fn offset_moves_to_the_normal_side_at_every_scale() {
        let n = Vec3::new(0.3, -0.5, 0.8).normalize();
        for scale in [1e-3f32, 1.0, 1e3, 1e5] {
            let p = Vec3::new(0.7, -0.2, 0.4) * scale;
            let q = offset_ray_origin(p, n);
            assert!((q - p).dot(n) > 0.0, "scale {scale}");
            assert!((q - p).length() < 1e-3 * scale.max(1.0), "scale {scale}");
        }
    }
}
