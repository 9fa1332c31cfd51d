//! The triangles an AO ray cannot meet, which its walk drops from every node's hits so
//! that they take neither a test nor a step: the triangle it leaves, and the triangles near
//! it in leaf order that lie wholly below the plane it leaves.
//!
//! An AO ray starts at `origin`, off its surface on the side of the surface's normal `n`,
//! and runs into the hemisphere about `n`'s 16-bit encoding (`encode_unit`, within 1e-4
//! of `n`), never closer than 2^-12 to that hemisphere's plane (`cosine_hemisphere`'s
//! `1 - u1` is at least 2^-24): so never closer than 1e-4 to the plane through `origin`
//! normal to `n`, and every point it reaches lies above that plane. A triangle whose three
//! corners lie below the plane cannot block it. On a curved or flat surface that is most
//! of the triangles beside the point's own, which share its leaf or its node and were
//! tested by nearly every one of its rays: per AO ray (1080p × 64 rays, the GPU's walk on
//! the CPU, `runner/examples/ao_walk_floor.rs` with `--features traversal-stats`), the
//! walk's triangle tests fall from 1.23 to 0.29 on rocks-1m, 1.97 to 0.83 on spheres-1m,
//! 1.52 to 1.08 on city-1m, 2.48 to 1.86 on grass-1m and 2.26 to 1.51 on shell-1m, with
//! the same answers (docs/PERFORMANCE.md, "Triangles below the plane a ray leaves").
//!
//! The window is the `WINDOW` (32) triangle slots around the point's own (`BEFORE` before it): a
//! node's triangles are consecutive slots of up to 24 (`cwbvh_meta`), so the window holds
//! the point's own node's, where the neighbours are, wherever its triangle sits in it.
use crate::bits::{shl, shr};
use crate::glam::Vec3;
use crate::types::{Triangle, INVALID};

/// Slots of the window: one bit each of `Skip::mask`.
const WINDOW: u32 = 32;
/// Slots of the window before the point's own triangle.
const BEFORE: u32 = 16;
/// A corner lies below the plane when its height above it, computed in f32, is below
/// minus this share of Σ |n_i| |corner_i − origin_i|: the height's rounding error (that of
/// the subtraction and of the dot product, under 4 ulps of that sum) with room to spare, so
/// that a corner counted below is below in exact arithmetic.
const HEIGHT_ERROR: f32 = 1e-6;

/// Which triangle slots a ray skips: bit k of `mask` for slot `start + k`.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct Skip {
    pub start: u32,
    pub mask: u32,
}

impl Skip {
    /// Nothing skipped.
    pub const NONE: Skip = Skip { start: 0, mask: 0 };

    /// Only triangle `prim` (nothing for `INVALID`).
    pub fn only(prim: u32) -> Self {
        if prim == INVALID {
            return Self::NONE;
        }
        Self {
            start: prim.wrapping_sub(BEFORE),
            mask: 1 << BEFORE,
        }
    }

    /// The triangle the rays leave, of a skip made by `only` or `below` with a triangle.
    pub fn own(self) -> u32 {
        self.start.wrapping_add(BEFORE)
    }

    /// The skips of AO rays from `origin` (off triangle `prim`'s surface) into the
    /// hemisphere about `n`: `prim` and the slots of the window wholly below the plane,
    /// among the `count` triangles of `triangle(i)`.
    pub fn below(
        origin: Vec3,
        n: Vec3,
        prim: u32,
        count: u32,
        triangle: impl Fn(u32) -> Triangle,
    ) -> Self {
        if prim == INVALID {
            return Self::NONE;
        }
        let mut skip = Self::only(prim);
        let below = |p: [f32; 3]| {
            let d = Vec3::from(p) - origin;
            d.dot(n) < -HEIGHT_ERROR * (d.abs().dot(n.abs()))
        };
        let mut k = 0;
        while k < WINDOW {
            let i = skip.start.wrapping_add(k);
            if i < count {
                let t = triangle(i);
                if below(t.p0) && below(t.p1) && below(t.p2) {
                    skip.mask |= 1 << k;
                }
            }
            k += 1;
        }
        skip
    }

    /// Whether slot `i` is skipped.
    pub fn holds(&self, i: u32) -> bool {
        let k = i.wrapping_sub(self.start);
        k < WINDOW && (self.mask >> k) & 1 != 0
    }

    /// The skipped slots among a node's triangle bits (bit j: slot `base + j`, j < 24).
    #[inline(always)]
    pub fn node_bits(&self, base: u32) -> u32 {
        let after = base.wrapping_sub(self.start);
        let before = self.start.wrapping_sub(base);
        if after < WINDOW {
            shr(self.mask, after)
        } else if before < WINDOW {
            shl(self.mask, before)
        } else {
            0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn node_bits_are_the_slots_held() {
        let skip = Skip {
            start: 100,
            mask: 0x8001_2345,
        };
        for base in 60..160u32 {
            let bits = skip.node_bits(base);
            for j in 0..24 {
                assert_eq!(
                    (bits >> j) & 1 != 0,
                    skip.holds(base + j),
                    "base {base} bit {j}"
                );
            }
        }
        assert_eq!(Skip::NONE.node_bits(0), 0);
        assert!(Skip::only(5).holds(5) && !Skip::only(5).holds(4) && !Skip::only(5).holds(6));
        assert_eq!(Skip::only(INVALID), Skip::NONE);
    }

    fn tri(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> Triangle {
        Triangle {
            p0: a,
            p1: b,
            p2: c,
            ..Default::default()
        }
    }

    /// A fan about the origin's point: the own triangle, a coplanar neighbour (below the
    /// offset origin), one folded down, one folded up, one standing across the plane.
    #[test]
    fn below_holds_the_triangles_under_the_plane_and_no_other() {
        let tris = [
            tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]), // own
            tri([0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]), // coplanar
            tri([0.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, -1.0, -0.5]), // folded down
            tri([0.0, 0.0, 0.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.5]), // folded up
            tri([2.0, 2.0, -1.0], [2.0, 3.0, -1.0], [2.0, 2.0, 1.0]), // across
            tri([5.0, 5.0, -1e-3], [6.0, 5.0, -1e-3], [5.0, 6.0, -1e-3]), // just below
        ];
        let origin = Vec3::new(0.2, 0.2, 1e-5);
        let n = Vec3::Z;
        let skip = Skip::below(origin, n, 0, tris.len() as u32, |i| tris[i as usize]);
        let held: [bool; 6] = core::array::from_fn(|i| skip.holds(i as u32));
        assert_eq!(held, [true, true, true, false, false, true]);
        // From the other side, only the own triangle and the one folded up lie below.
        let under = Vec3::new(0.2, 0.2, -1e-5);
        let skip = Skip::below(under, -n, 0, tris.len() as u32, |i| tris[i as usize]);
        let held: [bool; 6] = core::array::from_fn(|i| skip.holds(i as u32));
        assert_eq!(held, [true, true, false, true, false, false]);
    }

    /// Slots past the triangle count, and before slot 0, are never read.
    #[test]
    fn the_window_stays_inside_the_triangles() {
        let t = tri([0.0, 0.0, -1.0], [1.0, 0.0, -1.0], [0.0, 1.0, -1.0]);
        let skip = Skip::below(Vec3::ZERO, Vec3::Z, 2, 4, |i| {
            assert!(i < 4, "slot {i} read");
            t
        });
        assert_eq!(skip.mask.count_ones(), 4);
    }
}
