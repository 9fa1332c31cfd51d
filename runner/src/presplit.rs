//! Splitting the boxes of large triangles before the BVH build (pre-splitting, Karras &
//! Aila 2013, "Fast Parallel Construction of High-Quality Bounding Volume Hierarchies",
//! §5). A triangle whose box is mostly empty or spans much of the scene — a sliver
//! across a sphere's pole, a long diagonal wall, a huge ground under small objects —
//! overlaps the boxes of everything near it, so every ray that passes near it tests it,
//! and the builder cannot put it with its neighbours. Split, it gets several boxes, each
//! around the part of it in one cell of a grid of the scene's bounds; each box refers back
//! to its triangle, and a leaf holds the triangle once per box, so traversal and hits are
//! unchanged.
//!
//! The budget (a share of the triangle count) goes to triangles by priority
//! (X^i · (A_box − A_ideal))^Y: the surface area their box has beyond what infinitely fine
//! splitting would leave, weighted by how coarse the coarsest grid plane through the box
//! is (a box across the scene's middle matters more than one across a fine cell). Karras &
//! Aila's X = 2, Y = 1/3. Each split cuts at that coarsest plane, clipping the triangle
//! to each side, and the remaining splits go to the sides in proportion to their excess.
//!
//! Measured, it does not pay on most scenes here (`accel::DEFAULT_SPLITS` is 0): fewer
//! triangle tests per ray, but more node visits.
use glam::Vec3;
use kernels::types::Triangle;
use rayon::prelude::*;

/// Grid levels the split planes may come from: planes at multiples of 2^−GRID_LEVELS of
/// the scene's extent on each axis are the finest.
const GRID_LEVELS: u32 = 20;
/// Karras & Aila's weights: priority = (PLANE_WEIGHT^−level · excess)^PRIORITY_EXPONENT.
const PLANE_WEIGHT: f32 = 2.0;
const PRIORITY_EXPONENT: f32 = 1.0 / 3.0;
/// A triangle clipped to a box has at most 3 + 6 corners (one more per box plane).
const MAX_CORNERS: usize = 9;
/// Bisection steps for the priorities' scale (`split_scale`): the budget to ~2^−30.
const SCALE_BISECTIONS: u32 = 30;

/// A box per part of each triangle (`boxes[i]` around part of `triangles[refs[i]]`).
pub struct SplitBoxes {
    pub boxes: Vec<(Vec3, Vec3)>,
    pub refs: Vec<u32>,
}

/// A convex polygon: a triangle, or what is left of it inside a box.
#[derive(Clone, Copy)]
pub(crate) struct Polygon {
    corners: [Vec3; MAX_CORNERS],
    len: usize,
}

impl Polygon {
    pub(crate) fn triangle(t: &Triangle) -> Self {
        let (p0, p1, p2) = t.vertices();
        let mut corners = [Vec3::ZERO; MAX_CORNERS];
        corners[..3].copy_from_slice(&[p0, p1, p2]);
        Self { corners, len: 3 }
    }

    fn corners(&self) -> &[Vec3] {
        &self.corners[..self.len]
    }

    /// Whether nothing is left (fewer than 3 corners: clipped away, or only touching).
    pub(crate) fn is_empty(&self) -> bool {
        self.len < 3
    }

    pub(crate) fn bounds(&self) -> (Vec3, Vec3) {
        crate::scene::bounds_of(self.corners().iter().copied())
    }

    /// Surface area of the boxes that infinitely fine splitting would leave around the
    /// polygon: twice the sum of its projections' areas.
    fn ideal_area(&self) -> f32 {
        let c = self.corners();
        let mut vector_area = Vec3::ZERO;
        for i in 1..c.len().saturating_sub(1) {
            vector_area += (c[i] - c[0]).cross(c[i + 1] - c[0]);
        }
        vector_area.abs().element_sum() // 2 · ½ |cross| summed over the axes
    }

    /// The parts below and above `at` on `axis` (Sutherland–Hodgman against one plane).
    pub(crate) fn cut(&self, axis: usize, at: f32) -> (Self, Self) {
        let empty = Self {
            corners: [Vec3::ZERO; MAX_CORNERS],
            len: 0,
        };
        let (mut below, mut above) = (empty, empty);
        let push = |p: &mut Self, v: Vec3| {
            if p.len < MAX_CORNERS {
                p.corners[p.len] = v;
                p.len += 1;
            }
        };
        let c = self.corners();
        for (i, &a) in c.iter().enumerate() {
            let b = c[(i + 1) % c.len()];
            let (da, db) = (a[axis] - at, b[axis] - at);
            if da <= 0.0 {
                push(&mut below, a);
            }
            if da >= 0.0 {
                push(&mut above, a);
            }
            if (da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0) {
                let mut x = a + (b - a) * (da / (da - db));
                x[axis] = at; // on the plane exactly, whatever the rounding
                push(&mut below, x);
                push(&mut above, x);
            }
        }
        (below, above)
    }
}

/// The scene's bounds and the grid the split planes lie on.
struct Grid {
    lo: Vec3,
    extent: Vec3,
}

impl Grid {
    /// The grid cells at the ends of `lo..hi` on `axis`: the last is the last the interval
    /// enters, so an end on a plane does not count the cell beyond it (a part cut at the
    /// middle plane must still find the planes inside it).
    fn cells(&self, lo: f32, hi: f32, axis: usize) -> (u32, u32) {
        let cells = (1u32 << GRID_LEVELS) as f32;
        let u = |x: f32| (x - self.lo[axis]) / self.extent[axis] * cells;
        let first = u(lo).floor().clamp(0.0, cells - 1.0) as u32;
        let last = (u(hi).ceil() - 1.0).clamp(0.0, cells - 1.0) as u32;
        (first, last.max(first))
    }

    /// The coarsest grid plane strictly inside `(lo, hi)`: (level, axis, position), level 0
    /// the middle of the scene. Ties go to the longest side of the box.
    fn coarsest_plane(&self, lo: Vec3, hi: Vec3) -> Option<(u32, usize, f32)> {
        let mut best: Option<(u32, usize, f32)> = None;
        for axis in 0..3 {
            if self.extent[axis] <= 0.0 {
                continue;
            }
            let (a, b) = self.cells(lo[axis], hi[axis], axis);
            if a == b {
                continue;
            }
            // Cells a and b first differ in this bit: a plane of that level lies between.
            let bit = 31 - (a ^ b).leading_zeros();
            let level = GRID_LEVELS - 1 - bit;
            let cell = (b >> bit) << bit;
            let at =
                self.lo[axis] + self.extent[axis] * (cell as f32 / (1u32 << GRID_LEVELS) as f32);
            if at <= lo[axis] || at >= hi[axis] {
                continue; // rounding put the plane on the box's side
            }
            let longer = |o: &(u32, usize, f32)| hi[axis] - lo[axis] > hi[o.1] - lo[o.1];
            if best.is_none_or(|o| level < o.0 || (level == o.0 && longer(&o))) {
                best = Some((level, axis, at));
            }
        }
        best
    }
}

fn surface_area((lo, hi): (Vec3, Vec3)) -> f32 {
    let d = (hi - lo).max(Vec3::ZERO);
    2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
}

/// Surface area the box of `p` has beyond its ideal.
fn excess(p: &Polygon) -> f32 {
    (surface_area(p.bounds()) - p.ideal_area()).max(0.0)
}

/// Boxes for `triangles`, with up to `budget` × their number of extra boxes among the
/// triangles `splittable` allows (the rest keep one box each).
pub fn split_boxes(
    triangles: &[Triangle],
    budget: f32,
    splittable: impl Fn(&Triangle) -> bool + Sync,
) -> SplitBoxes {
    let extra = (budget as f64 * triangles.len() as f64).floor() as u64;
    if extra == 0 {
        return SplitBoxes {
            boxes: triangles
                .par_iter()
                .map(|t| Polygon::triangle(t).bounds())
                .collect(),
            refs: (0..triangles.len() as u32).collect(),
        };
    }
    let (lo, hi) = crate::scene::bounds_of(crate::scene::corners(triangles));
    let grid = Grid {
        lo,
        extent: hi - lo,
    };
    let priority = |t: &Triangle| -> f64 {
        if !splittable(t) {
            return 0.0;
        }
        let p = Polygon::triangle(t);
        let (blo, bhi) = p.bounds();
        match grid.coarsest_plane(blo, bhi) {
            Some((level, _, _)) => {
                (PLANE_WEIGHT.powi(-(level as i32)) * excess(&p)).powf(PRIORITY_EXPONENT) as f64
            }
            None => 0.0,
        }
    };
    let priorities: Vec<f64> = triangles.par_iter().map(priority).collect();
    let scale = split_scale(&priorities, extra);
    let parts: Vec<Vec<(Vec3, Vec3)>> = triangles
        .par_iter()
        .zip(&priorities)
        .map(|(t, &p)| {
            let splits = (scale * p).floor().min(u32::MAX as f64) as u32;
            let polygon = Polygon::triangle(t);
            let mut boxes = Vec::with_capacity(splits as usize + 1);
            split(&grid, &polygon, polygon.bounds(), splits, &mut |b| {
                boxes.push(b)
            });
            boxes
        })
        .collect();
    let mut out = SplitBoxes {
        boxes: Vec::with_capacity(triangles.len() + extra as usize),
        refs: Vec::with_capacity(triangles.len() + extra as usize),
    };
    for (i, boxes) in parts.into_iter().enumerate() {
        out.refs.extend(std::iter::repeat_n(i as u32, boxes.len()));
        out.boxes.extend(boxes);
    }
    out
}

/// The scale β for which the triangles' splits ⌊β · priority⌋ add up to at most `extra`
/// and as close to it as bisection gets: splitting floors each triangle's share, so a
/// budget spread as `extra · p / Σp` would give most triangles of a scene of similar ones
/// no split at all (0.3 → 1% more boxes on spheres-1m).
fn split_scale(priorities: &[f64], extra: u64) -> f64 {
    let total: f64 = priorities.iter().sum();
    if total <= 0.0 {
        return 0.0;
    }
    let splits = |scale: f64| -> u64 {
        priorities
            .par_iter()
            .map(|&p| (scale * p).floor() as u64)
            .sum()
    };
    // ⌊βp⌋ > βp − 1 for each of at most n triangles with p > 0: this β spends the budget.
    let nonzero = priorities.iter().filter(|&&p| p > 0.0).count() as f64;
    let (mut lo, mut hi) = (extra as f64 / total, (extra as f64 + nonzero) / total);
    for _ in 0..SCALE_BISECTIONS {
        let mid = 0.5 * (lo + hi);
        if splits(mid) <= extra {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// Emit `splits + 1` boxes (fewer where the grid runs out of planes) that together hold
/// polygon `p`, which lies in box `b`. A work list, not recursion: the splits of one part
/// can all go down one side.
fn split(
    grid: &Grid,
    p: &Polygon,
    b: (Vec3, Vec3),
    splits: u32,
    emit: &mut impl FnMut((Vec3, Vec3)),
) {
    let mut work = vec![(*p, b, splits)];
    while let Some((p, b, splits)) = work.pop() {
        let plane = if splits == 0 {
            None
        } else {
            grid.coarsest_plane(b.0, b.1)
        };
        let Some((_, axis, at)) = plane else {
            emit(b);
            continue;
        };
        let (below, above) = p.cut(axis, at);
        if below.len < 3 || above.len < 3 {
            emit(b); // the part only touches the plane (rounding): nothing to cut
            continue;
        }
        // Each side's box: its part's bounds, within the box and on its side of the plane.
        let side_box = |part: &Polygon, lo: f32, hi: f32| {
            let (mut plo, mut phi) = part.bounds();
            plo = plo.max(b.0);
            phi = phi.min(b.1);
            plo[axis] = plo[axis].max(lo);
            phi[axis] = phi[axis].min(hi);
            (plo, phi)
        };
        let (e_below, e_above) = (excess(&below), excess(&above));
        let rest = splits - 1;
        let to_below = if e_below + e_above > 0.0 {
            ((rest as f32 * e_below / (e_below + e_above)).round() as u32).min(rest)
        } else {
            rest / 2
        };
        work.push((below, side_box(&below, f32::NEG_INFINITY, at), to_below));
        work.push((above, side_box(&above, at, f32::INFINITY), rest - to_below));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kernels::rng::Rng;
    use kernels::sampling::uniform_triangle;

    /// A huge ground triangle under small ones of random size, place and orientation,
    /// and a long sliver across it.
    fn scene() -> Vec<Triangle> {
        let mut t = vec![
            Triangle::new(
                Vec3::new(-50.0, 0.0, -50.0),
                Vec3::new(50.0, 0.0, -50.0),
                Vec3::new(-50.0, 0.0, 50.0),
                0,
            ),
            Triangle::new(
                Vec3::new(-40.0, 1.0, -40.0),
                Vec3::new(40.0, 1.5, 40.0),
                Vec3::new(40.0, 1.0, 39.5),
                0,
            ),
        ];
        let mut rng = Rng::from_seed(3);
        let mut random = |lo: f32, hi: f32| lo + (hi - lo) * rng.next_f32();
        for _ in 0..1600 {
            let p = Vec3::new(random(-40.0, 40.0), random(0.2, 3.0), random(-40.0, 40.0));
            let size = random(0.1, 0.5);
            let mut corner =
                || p + Vec3::new(random(-1.0, 1.0), random(-1.0, 1.0), random(-1.0, 1.0)) * size;
            t.push(Triangle::new(corner(), corner(), corner(), 0));
        }
        t
    }

    fn inside((lo, hi): (Vec3, Vec3), p: Vec3, tolerance: f32) -> bool {
        p.cmpge(lo - tolerance).all() && p.cmple(hi + tolerance).all()
    }

    #[test]
    fn the_parts_hold_their_triangle_within_its_box() {
        let tris = scene();
        let split = split_boxes(&tris, 0.5, |_| true);
        let mut rng = Rng::from_seed(7);
        for (i, t) in tris.iter().enumerate() {
            let boxes: Vec<_> = (0..split.refs.len())
                .filter(|&b| split.refs[b] == i as u32)
                .map(|b| split.boxes[b])
                .collect();
            let (p0, p1, p2) = t.vertices();
            let whole = Polygon::triangle(t).bounds();
            // 1e-6 of the coordinates: the BVH pads each box by that much.
            let tolerance = 1e-6 * 50.0;
            assert!(boxes
                .iter()
                .all(|&(lo, hi)| inside(whole, lo, 0.0) && inside(whole, hi, 0.0)));
            for _ in 0..2000 {
                let (u, v) = uniform_triangle(rng.next_f32(), rng.next_f32());
                let p = p0 + (p1 - p0) * u + (p2 - p0) * v;
                assert!(
                    boxes.iter().any(|&b| inside(b, p, tolerance)),
                    "triangle {i}: {p} in none of {boxes:?}"
                );
            }
        }
    }

    #[test]
    fn the_budget_goes_to_the_large_triangles() {
        let tris = scene();
        let n = tris.len();
        let split = split_boxes(&tris, 0.3, |_| true);
        // The whole budget is spent (all but what the last triangles' floors leave).
        let extra = split.boxes.len() - n;
        let budget = (0.3 * n as f32) as usize;
        assert!(
            extra <= budget && extra > budget * 9 / 10,
            "{extra} extra boxes for {n} triangles"
        );
        let parts = |i: u32| split.refs.iter().filter(|&&r| r == i).count();
        // The ground and the sliver get the most parts, and their parts' boxes hold far
        // less area than their own box.
        let most_small = (2..n as u32).map(parts).max().unwrap();
        assert!(
            parts(0).min(parts(1)) > 4 * most_small,
            "ground {}, sliver {}, small ones ≤ {most_small}",
            parts(0),
            parts(1)
        );
        for i in [0u32, 1] {
            let whole = surface_area(Polygon::triangle(&tris[i as usize]).bounds());
            let area: f32 = (0..split.refs.len())
                .filter(|&b| split.refs[b] == i)
                .map(|b| surface_area(split.boxes[b]))
                .sum();
            assert!(
                area < 0.75 * whole || i == 0 && area < whole,
                "triangle {i}: {area} vs {whole}"
            );
        }
        // Triangles it may not split keep one box each.
        let kept = split_boxes(&tris, 0.3, |t| t.p0[1] != 0.0);
        assert_eq!(kept.refs.iter().filter(|&&r| r == 0).count(), 1);
        assert_eq!(split_boxes(&tris, 0.0, |_| true).boxes.len(), n);
    }
}
