//! Ray–triangle tests (watertight and Möller–Trumbore) and the ray–box slab test.
use crate::glam::Vec3;
use crate::math::{component, max_dimension};
use crate::types::{Triangle, INVALID};

#[derive(Copy, Clone, Debug)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
}

impl Ray {
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Self { origin, dir }
    }
}

/// Closest hit so far: `prim == INVALID` means no hit, and then `t` is the search limit.
/// Barycentrics (b1, b2) weight p1 and p2; p0 gets 1 - b1 - b2.
#[derive(Copy, Clone, Debug)]
pub struct Hit {
    pub t: f32,
    pub b1: f32,
    pub b2: f32,
    pub prim: u32,
}

impl Hit {
    pub fn none(t_max: f32) -> Self {
        Self {
            t: t_max,
            b1: 0.0,
            b2: 0.0,
            prim: INVALID,
        }
    }
    pub fn is_hit(&self) -> bool {
        self.prim != INVALID
    }
}

/// Per-ray set-up of the watertight test (Woop, Benthin, Wald 2013, "Watertight
/// Ray/Triangle Intersection"): permute axes so z is the ray's dominant axis and shear so
/// the ray becomes +z. Done once per ray, reused for every triangle.
#[derive(Copy, Clone, Debug)]
pub struct WatertightRay {
    pub origin: Vec3,
    pub kx: u32,
    pub ky: u32,
    pub kz: u32,
    pub shear: Vec3,
}

impl WatertightRay {
    pub fn new(ray: &Ray) -> Self {
        let kz = max_dimension(ray.dir.abs());
        let mut kx = if kz == 2 { 0 } else { kz + 1 };
        let mut ky = if kx == 2 { 0 } else { kx + 1 };
        // Keep the winding: swap kx and ky when the dominant component is negative.
        if component(ray.dir, kz) < 0.0 {
            core::mem::swap(&mut kx, &mut ky);
        }
        let dz = component(ray.dir, kz);
        // One division, not three: every AO ray pays for this set-up, and a ray tests
        // 0.8–2.3 triangles (AO 0.4–0.5% faster, H100; docs/PERFORMANCE.md, "Cheaper
        // triangle tests"). The shear is a per-ray constant, so watertightness is untouched.
        let inv_dz = 1.0 / dz;
        let shear = Vec3::new(
            component(ray.dir, kx) * inv_dz,
            component(ray.dir, ky) * inv_dz,
            inv_dz,
        );
        Self {
            origin: ray.origin,
            kx,
            ky,
            kz,
            shear,
        }
    }

    fn permute(&self, v: Vec3) -> Vec3 {
        Vec3::new(
            component(v, self.kx),
            component(v, self.ky),
            component(v, self.kz),
        )
    }
}

/// Watertight test: rays through shared edges and vertices of a closed mesh never slip
/// between triangles, because the edge functions of both neighbours see bit-identical
/// inputs. Returns (t, b1, b2) when t_min < t < t_max. (Its edges' signs and t tested in
/// one branch before the division, as `intersect_moller_trumbore` does, gained nothing:
/// AO the same, MIS and NEE 1–2% slower, H100; docs/PERFORMANCE.md, "Cheaper triangle
/// tests".)
pub fn intersect_watertight(
    wr: &WatertightRay,
    tri: &Triangle,
    t_min: f32,
    t_max: f32,
) -> Option<(f32, f32, f32)> {
    let (p0, p1, p2) = tri.vertices();
    let a = wr.permute(p0 - wr.origin);
    let b = wr.permute(p1 - wr.origin);
    let c = wr.permute(p2 - wr.origin);
    let s = wr.shear;
    let ax = a.x - s.x * a.z;
    let ay = a.y - s.y * a.z;
    let bx = b.x - s.x * b.z;
    let by = b.y - s.y * b.z;
    let cx = c.x - s.x * c.z;
    let cy = c.y - s.y * c.z;
    // Scaled barycentrics: u weights p0, v weights p1, w weights p2.
    // 0 (a material index is below 2^31), read from the triangle: see `edge_function`.
    let z = tri.material >> 31;
    let u = edge_function(cx, cy, bx, by, z);
    let v = edge_function(ax, ay, cx, cy, z);
    let w = edge_function(bx, by, ax, ay, z);
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }
    let (az, bz, cz) = (s.z * a.z, s.z * b.z, s.z * c.z);
    let t_scaled = u * az + v * bz + w * cz;
    let inv_det = 1.0 / det;
    let t = t_scaled * inv_det;
    if !(t > t_min && t < t_max) {
        return None;
    }
    // The rounding error of t grows with the triangle's extent, not with the hit point's
    // position, so a large triangle can be "hit" just behind a ray origin that was offset
    // off its surface. Reject t within its error bound (Pharr, Jakob, Humphreys, PBRT 3rd
    // ed., §3.9.6): then t > 0 is certain.
    let max_zt = az.abs().max(bz.abs()).max(cz.abs());
    let max_xt = ax.abs().max(bx.abs()).max(cx.abs());
    let max_yt = ay.abs().max(by.abs()).max(cy.abs());
    let delta_z = gamma(3) * max_zt;
    let delta_x = gamma(5) * (max_xt + max_zt);
    let delta_y = gamma(5) * (max_yt + max_zt);
    let delta_e = 2.0 * (gamma(2) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = u.abs().max(v.abs()).max(w.abs());
    let delta_t =
        3.0 * (gamma(3) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * inv_det.abs();
    if t <= delta_t {
        return None;
    }
    Some((t, v * inv_det, w * inv_det))
}

/// The edge function px·qy − py·qx of the projected edge from p to q (twice the signed
/// area of the origin, p, q), with both products rounded. Woop's test is watertight only if
/// the two triangles sharing an edge get exactly opposite values for it; they see the edge
/// in opposite directions, and a GPU driver may fuse either product into a multiply-add
/// (rust-gpu emits no NoContraction), which rounds px·qy − py·qx and −(qx·py − qy·px)
/// differently: rays slipped through shared edges on the H100 (2 in 133 M inside a closed
/// sphere) but never on the CPU. Each product's bits pass through an XOR with `zero`, 0
/// at run time but read from the triangle's words (its material index's top bit), so
/// that the shader compiler cannot fold it: no multiply-add can be formed, and both
/// products are rounded on every device, as on the CPU, where Rust never fuses. (A zero
/// computed from a buffer's length instead was folded by the NVIDIA driver: rays leaked
/// again.) Before, the endpoints were put in one canonical order, with compares and
/// selects; the XOR made every kernel 3–9% faster and leaks nothing in 796 M rays on the
/// H100 (docs/PERFORMANCE.md, "Benchmark suite"). A multiply by a run-time 1.0 (made from
/// the same bit) in place of the XOR, moving the six operations from the GPU's busy integer
/// pipe to its float pipe, was 0.4–0.8% faster on every kernel but leaked a ray on the H100
/// (docs/PERFORMANCE.md, "Cheaper triangle tests"): the driver rewrites float arithmetic,
/// and only an integer operation keeps it out.
#[inline(always)]
fn edge_function(px: f32, py: f32, qx: f32, qy: f32, zero: u32) -> f32 {
    let rounded = |p: f32| f32::from_bits(p.to_bits() ^ zero);
    rounded(px * qy) - rounded(py * qx)
}

const SIGN_BIT: u32 = 0x8000_0000;

/// Whether t = `t_scaled` / `det` (det ≥ 0, t_min ≥ 0) may lie in (t_min, t_max), without
/// the division: a filter before it, which passes every t that the exact test on the
/// quotient that follows it passes, so that the hits are those of the test on t alone. Each
/// bound is two roundings (2⁻²⁴ each at most) off t_min·det or t_max·det; widened by 2⁻²²
/// it lies beyond them. A det of 0 fails (0 · ∞ is NaN).
#[inline(always)]
fn in_range_scaled(t_scaled: f32, det: f32, t_min: f32, t_max: f32) -> bool {
    const WIDEN: f32 = 1.0 / (1 << 22) as f32;
    t_scaled > t_min * det * (1.0 - WIDEN) && t_scaled < t_max * det * (1.0 + WIDEN)
}

/// Bound on the relative error of n chained float operations: nε / (1 − nε), ε = 2⁻²⁴.
fn gamma(n: u32) -> f32 {
    let e = n as f32 * (f32::EPSILON * 0.5);
    e / (1.0 - e)
}

/// Möller & Trumbore 1997, "Fast, Minimum Storage Ray/Triangle Intersection". Faster set-up,
/// but not watertight: rays through shared edges can miss both triangles. The barycentrics
/// and t are compared scaled by det, its sign moved onto them, in one branch, and only a
/// hit divides: with a branch and a division for each, as in the paper, the Cornell box's
/// MIS took 15% longer and the many-lights NEE 8% (H100; docs/PERFORMANCE.md, "Cheaper
/// triangle tests").
pub fn intersect_moller_trumbore(
    ray: &Ray,
    tri: &Triangle,
    t_min: f32,
    t_max: f32,
) -> Option<(f32, f32, f32)> {
    let (p0, p1, p2) = tri.vertices();
    let e1 = p1 - p0;
    let e2 = p2 - p0;
    let pvec = ray.dir.cross(e2);
    let det = e1.dot(pvec);
    let tvec = ray.origin - p0;
    let qvec = tvec.cross(e1);
    let sign = det.to_bits() & SIGN_BIT;
    let flip = |x: f32| f32::from_bits(x.to_bits() ^ sign);
    let abs_det = det.abs();
    let (u, v) = (flip(tvec.dot(pvec)), flip(ray.dir.dot(qvec)));
    let ts = flip(e2.dot(qvec));
    if u < 0.0 || v < 0.0 || u + v > abs_det || !in_range_scaled(ts, abs_det, t_min, t_max) {
        return None;
    }
    let inv_det = 1.0 / abs_det;
    let t = ts * inv_det;
    if !(t > t_min && t < t_max) {
        return None;
    }
    Some((t, u * inv_det, v * inv_det))
}

/// The triangle test the traversals use, picked by cargo feature.
#[derive(Copy, Clone, Debug)]
pub struct TriangleTester {
    #[cfg(not(feature = "intersect-moller-trumbore"))]
    wr: WatertightRay,
    #[cfg(feature = "intersect-moller-trumbore")]
    ray: Ray,
}

impl TriangleTester {
    pub fn new(ray: &Ray) -> Self {
        Self {
            #[cfg(not(feature = "intersect-moller-trumbore"))]
            wr: WatertightRay::new(ray),
            #[cfg(feature = "intersect-moller-trumbore")]
            ray: *ray,
        }
    }
    /// The watertight test's per-ray set-up, where that is the test in use.
    #[cfg(not(target_arch = "spirv"))]
    pub fn watertight(&self) -> Option<&WatertightRay> {
        #[cfg(not(feature = "intersect-moller-trumbore"))]
        return Some(&self.wr);
        #[cfg(feature = "intersect-moller-trumbore")]
        return None;
    }

    pub fn intersect(&self, tri: &Triangle, t_min: f32, t_max: f32) -> Option<(f32, f32, f32)> {
        #[cfg(not(feature = "intersect-moller-trumbore"))]
        return intersect_watertight(&self.wr, tri, t_min, t_max);
        #[cfg(feature = "intersect-moller-trumbore")]
        return intersect_moller_trumbore(&self.ray, tri, t_min, t_max);
    }
}

/// Slab test against an axis-aligned box, with the reciprocal direction precomputed.
/// Returns the entry distance, or `f32::INFINITY` on a miss. Zero direction components
/// give infinite reciprocals, which the slabs handle, unless the origin lies exactly on a
/// slab plane (0 · ∞ = NaN): the BVH pads its boxes so that never decides a hit.
pub fn intersect_aabb(origin: Vec3, inv_dir: Vec3, lo: Vec3, hi: Vec3, t_max: f32) -> f32 {
    let t0 = (lo - origin) * inv_dir;
    let t1 = (hi - origin) * inv_dir;
    let t_near = t0.min(t1).max_element().max(0.0);
    let t_far = t0.max(t1).min_element().min(t_max);
    if t_near <= t_far {
        t_near
    } else {
        f32::INFINITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> Triangle {
        Triangle::new(
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            0,
        )
    }

    fn both(ray: &Ray, t: &Triangle) -> [Option<(f32, f32, f32)>; 2] {
        [
            intersect_watertight(&WatertightRay::new(ray), t, 0.0, f32::INFINITY),
            intersect_moller_trumbore(ray, t, 0.0, f32::INFINITY),
        ]
    }

    #[test]
    fn hit_with_known_t_and_barycentrics() {
        let ray = Ray::new(Vec3::new(0.25, 0.5, 2.0), Vec3::new(0.0, 0.0, -1.0));
        for h in both(&ray, &tri()) {
            let (t, b1, b2) = h.expect("hit");
            assert!((t - 2.0).abs() < 1e-6 && (b1 - 0.25).abs() < 1e-6 && (b2 - 0.5).abs() < 1e-6);
        }
        // From below and at a slant: t = |o - p| along a unit direction.
        let target = Vec3::new(0.2, 0.3, 0.0);
        let origin = Vec3::new(-1.0, 2.0, -3.0);
        let d = (target - origin).normalize();
        for h in both(&Ray::new(origin, d), &tri()) {
            let (t, b1, b2) = h.expect("hit");
            assert!((t - (target - origin).length()).abs() < 1e-5);
            assert!((b1 - 0.2).abs() < 1e-5 && (b2 - 0.3).abs() < 1e-5);
        }
    }

    #[test]
    fn misses() {
        let cases = [
            // beside the triangle
            Ray::new(Vec3::new(0.8, 0.8, 1.0), Vec3::new(0.0, 0.0, -1.0)),
            // pointing away
            Ray::new(Vec3::new(0.2, 0.2, 1.0), Vec3::new(0.0, 0.0, 1.0)),
            // parallel to the plane
            Ray::new(Vec3::new(-1.0, 0.2, 0.0), Vec3::new(1.0, 0.0, 0.0)),
        ];
        for ray in cases {
            assert_eq!(both(&ray, &tri()), [None, None], "{ray:?}");
        }
        // Outside [t_min, t_max].
        let ray = Ray::new(Vec3::new(0.2, 0.2, 1.0), Vec3::new(0.0, 0.0, -1.0));
        assert!(intersect_watertight(&WatertightRay::new(&ray), &tri(), 0.0, 0.5).is_none());
        assert!(intersect_moller_trumbore(&ray, &tri(), 1.5, 9.0).is_none());
    }

    /// The filter before the division passes every t the quotient's test passes, at the
    /// tightest bounds that test passes (t_min and t_max an ulp or two from t), over det
    /// and t of many magnitudes: products that round past t·det must not cut a hit.
    #[test]
    fn scaled_range_passes_every_t_that_the_quotient_passes() {
        let mut rng = crate::rng::Rng::from_seed(7);
        let mut near = 0;
        for _ in 0..200_000 {
            let magnitude = |rng: &mut crate::rng::Rng| {
                (0.5 + rng.next_f32()) * 2f32.powi((rng.next_u32() % 41) as i32 - 20)
            };
            let det = magnitude(&mut rng);
            let t_scaled = det * magnitude(&mut rng);
            let t = t_scaled / det;
            for ulps in 1..=2 {
                let t_max = f32::from_bits(t.to_bits() + ulps);
                let t_min = f32::from_bits(t.to_bits() - ulps);
                assert!(t_min < t && t < t_max);
                assert!(
                    in_range_scaled(t_scaled, det, t_min, t_max),
                    "t {t} = {t_scaled} / {det} cut by ({t_min}, {t_max})"
                );
                near += (t_scaled >= t_max * det || t_scaled <= t_min * det) as u32;
            }
        }
        // Unwidened bounds would have cut some of these hits: the test reaches the edge.
        assert!(near > 0);
    }

    #[test]
    fn aabb_slab() {
        let (lo, hi) = (Vec3::splat(-1.0), Vec3::splat(1.0));
        let o = Vec3::new(-5.0, 0.0, 0.0);
        let d = Vec3::new(1.0, 0.0, 0.0);
        assert_eq!(intersect_aabb(o, d.recip(), lo, hi, 100.0), 4.0);
        assert_eq!(intersect_aabb(o, d.recip(), lo, hi, 3.0), f32::INFINITY);
        let o2 = Vec3::new(-5.0, 2.0, 0.0);
        assert_eq!(intersect_aabb(o2, d.recip(), lo, hi, 100.0), f32::INFINITY);
        // Origin inside: entry distance clamps to 0.
        assert_eq!(intersect_aabb(Vec3::ZERO, d.recip(), lo, hi, 100.0), 0.0);
        // Axis-parallel ray just inside a face plane, and just outside it.
        let o3 = Vec3::new(-5.0, 0.999, 0.0);
        assert_eq!(intersect_aabb(o3, d.recip(), lo, hi, 100.0), 4.0);
        let o4 = Vec3::new(-5.0, 1.001, 0.0);
        assert_eq!(intersect_aabb(o4, d.recip(), lo, hi, 100.0), f32::INFINITY);
    }
}
