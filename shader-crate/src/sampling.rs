//! Sample warps: cosine-weighted hemisphere, uniform triangle, orthonormal basis; the
//! octahedral encoding of directions (two numbers per direction, for reservoirs); the
//! stratified pattern of a pixel's AO rays.
use crate::glam::Vec3;
use crate::math::{div_rem, sin_cos, sqrt, Divisor, PI};

/// Tangent `t` and bitangent `b` such that (t, b, n) is right-handed and orthonormal
/// (Duff et al. 2017, "Building an Orthonormal Basis, Revisited": no branch on |n.z|).
pub fn orthonormal_basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = if n.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let t = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let bt = Vec3::new(b, sign + n.y * n.y * a, -n.y);
    (t, bt)
}

/// Local frame (z = n) to world.
pub fn local_to_world(local: Vec3, n: Vec3) -> Vec3 {
    let (t, b) = orthonormal_basis(n);
    in_frame(local, [t, b, n])
}

/// `local` (x along t, y along b, z along n) in world space, for a frame made once and
/// kept (`orthonormal_basis`'s tangents with n).
pub fn in_frame(local: Vec3, [t, b, n]: [Vec3; 3]) -> Vec3 {
    t * local.x + b * local.y + n * local.z
}

/// A unit direction as two numbers in [−1, 1] (octahedral map, Meyer et al. 2010): the
/// unit octahedron unfolded onto a square. Exact to ~1e-7 in f32, and cheap both ways.
pub fn octahedral_encode(d: Vec3) -> (f32, f32) {
    let l1 = d.x.abs() + d.y.abs() + d.z.abs();
    let (x, y) = (d.x / l1, d.y / l1);
    if d.z >= 0.0 {
        (x, y)
    } else {
        let sign = |v: f32| if v >= 0.0 { 1.0 } else { -1.0 };
        ((1.0 - y.abs()) * sign(x), (1.0 - x.abs()) * sign(y))
    }
}

/// The unit direction of `octahedral_encode`'s two numbers.
pub fn octahedral_decode(u: f32, v: f32) -> Vec3 {
    let z = 1.0 - u.abs() - v.abs();
    let t = (-z).max(0.0);
    let x = if u >= 0.0 { u - t } else { u + t };
    let y = if v >= 0.0 { v - t } else { v + t };
    Vec3::new(x, y, z).normalize()
}

/// Cosine-weighted direction about +z; pdf = cos θ / π. The projection onto the xy plane
/// is uniform on the unit disk (Malley's method).
pub fn cosine_hemisphere(u1: f32, u2: f32) -> Vec3 {
    let r = sqrt(u1);
    let (s, c) = sin_cos(2.0 * PI * u2);
    Vec3::new(r * c, r * s, sqrt((1.0 - u1).max(0.0)))
}

/// The largest f32 below 1: where a stratum's jittered point would round up to 1.
const ONE_MINUS_EPSILON: f32 = 1.0 - 1.0 / 16_777_216.0;

/// A pixel's AO rays as jittered strata of the unit square that `cosine_hemisphere` maps
/// to directions: `rows` bands of u1 (the radius, so the elevation) × `columns` of u2 (the
/// azimuth), one ray per cell, each placed in its cell by random numbers of its own; rays
/// beyond rows · columns (a count that is no product of two near roots) are drawn from the
/// whole square. The mean is unbiased as before and its variance lower (visibility is a
/// step function: ~N^-1.5 instead of N^-1). The cells are visited in a serpentine order
/// and every pixel visits them in the same order, so the k-th rays of neighbouring
/// pixels, which a GPU warp traces side by side, leave in similar directions.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Strata {
    rows: u32,
    columns: u32,
    /// Division by `columns`, for the cell of a ray.
    by_columns: Divisor,
    /// 1/rows and 1/columns: a cell's extent.
    row_size: f32,
    column_size: f32,
}

impl Strata {
    /// No strata: every ray drawn from the whole square (independent samples).
    pub const NONE: Strata = Strata {
        rows: 0,
        columns: 0,
        by_columns: Divisor::ONE,
        row_size: 1.0,
        column_size: 1.0,
    };

    /// The grid for `count` rays: rows = ⌊√count⌋, columns = ⌊count / rows⌋, so fewer than
    /// `rows` rays are left over (64: 8 × 8; 32: 5 × 6 and 2 left).
    pub fn new(count: u32) -> Self {
        if count == 0 {
            return Self::NONE;
        }
        // The float root is exact for perfect squares up to 2^24; the loops make it exact
        // for any count.
        let mut rows = (sqrt(count as f32) as u32).max(1);
        while rows > 1 && rows * rows > count {
            rows -= 1;
        }
        while (rows + 1) * (rows + 1) <= count {
            rows += 1;
        }
        let (columns, _) = div_rem(count, rows); // rows ≥ 1
        Self {
            rows,
            columns,
            by_columns: Divisor::new(columns),
            row_size: 1.0 / rows as f32,
            column_size: 1.0 / columns as f32,
        }
    }

    /// The square's point for ray `k`: in its cell, at (j1, j2) ∈ [0, 1)² within it.
    pub fn point(&self, k: u32, j1: f32, j2: f32) -> (f32, f32) {
        if k >= self.rows * self.columns {
            return (j1, j2);
        }
        let (row, step) = self.by_columns.div_rem(k);
        // Serpentine: odd rows run backwards, so that cell k + 1 borders cell k.
        let column = if row & 1 == 1 {
            self.columns - 1 - step
        } else {
            step
        };
        (
            ((row as f32 + j1) * self.row_size).min(ONE_MINUS_EPSILON),
            ((column as f32 + j2) * self.column_size).min(ONE_MINUS_EPSILON),
        )
    }
}

/// Uniform barycentrics (b1, b2) on a triangle (the square-root warp).
pub fn uniform_triangle(u1: f32, u2: f32) -> (f32, f32) {
    let su = sqrt(u1);
    (su * (1.0 - u2), su * u2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn octahedral_encoding_round_trips_every_direction() {
        let mut rng = crate::rng::Rng::from_seed(9);
        for i in 0..100_000 {
            // Uniform directions, and the axes and octant borders exactly.
            let d = if i < 6 {
                [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z][i]
            } else {
                let z = 1.0 - 2.0 * rng.next_f32();
                let r = sqrt((1.0 - z * z).max(0.0));
                let (s, c) = sin_cos(2.0 * PI * rng.next_f32());
                Vec3::new(r * c, r * s, z)
            };
            let (u, v) = octahedral_encode(d);
            assert!(u.abs() <= 1.0 && v.abs() <= 1.0);
            let back = octahedral_decode(u, v);
            assert!((back - d).length() < 1e-6, "{d} -> ({u}, {v}) -> {back}");
        }
    }

    #[test]
    fn basis_is_orthonormal_for_many_normals() {
        let mut rng = crate::rng::Rng::from_seed(5);
        for i in 0..10_000 {
            let n = if i < 2 {
                Vec3::new(0.0, 0.0, if i == 0 { 1.0 } else { -1.0 })
            } else {
                let d = cosine_hemisphere(rng.next_f32(), rng.next_f32());
                if rng.next_f32() < 0.5 {
                    d
                } else {
                    -d
                }
            }
            .normalize();
            let (t, b) = orthonormal_basis(n);
            for (x, y) in [(t, b), (t, n), (b, n)] {
                assert!(x.dot(y).abs() < 1e-5);
            }
            assert!((t.length() - 1.0).abs() < 1e-5 && (b.length() - 1.0).abs() < 1e-5);
            assert!((t.cross(b) - n).length() < 1e-4, "right-handed");
        }
    }

    #[test]
    fn cosine_samples_are_unit_and_in_upper_hemisphere() {
        let mut rng = crate::rng::Rng::from_seed(9);
        for _ in 0..10_000 {
            let d = cosine_hemisphere(rng.next_f32(), rng.next_f32());
            assert!((d.length() - 1.0).abs() < 1e-5 && d.z >= 0.0);
        }
    }

    #[test]
    fn triangle_samples_are_inside() {
        let mut rng = crate::rng::Rng::from_seed(3);
        for _ in 0..10_000 {
            let (b1, b2) = uniform_triangle(rng.next_f32(), rng.next_f32());
            assert!(b1 >= 0.0 && b2 >= 0.0 && b1 + b2 <= 1.0);
        }
    }

    #[test]
    fn strata_visit_every_cell_once_each_next_to_the_last() {
        for count in 1..=300u32 {
            let strata = Strata::new(count);
            let cells = strata.rows * strata.columns;
            assert!(
                cells <= count && count - cells < strata.rows,
                "{count}: {strata:?}"
            );
            let mut seen = std::vec![false; cells as usize];
            let mut last: Option<(i64, i64)> = None;
            for k in 0..cells {
                let (u1, u2) = strata.point(k, 0.5, 0.5);
                let cell = (
                    (u1 * strata.rows as f32) as i64,
                    (u2 * strata.columns as f32) as i64,
                );
                let index = (cell.0 * strata.columns as i64 + cell.1) as usize;
                assert!(!seen[index], "{count}: cell {cell:?} twice");
                seen[index] = true;
                if let Some(l) = last {
                    assert_eq!((cell.0 - l.0).abs() + (cell.1 - l.1).abs(), 1, "{count}");
                }
                last = Some(cell);
            }
            // Jitter at the cell's far edge stays inside the square.
            let (u1, u2) = strata.point(cells.max(1) - 1, ONE_MINUS_EPSILON, ONE_MINUS_EPSILON);
            assert!(u1 < 1.0 && u2 < 1.0);
        }
        let s = Strata::new(64);
        assert_eq!((s.rows, s.columns), (8, 8));
        assert_eq!(Strata::new(0), Strata::NONE);
        assert_eq!(Strata::NONE.point(3, 0.25, 0.75), (0.25, 0.75));
    }

    /// AO of a wall: the cosine-weighted share of directions with x > A, which is the
    /// share of the unit disk beyond the chord x = A (Malley). Both patterns estimate it
    /// without bias; the strata with a fraction of the variance.
    #[test]
    fn stratified_rays_estimate_without_bias_and_with_less_variance() {
        const A: f64 = 0.3;
        const RAYS: u32 = 64;
        const TRIALS: usize = 4000;
        let exact = (A.acos() - A * (1.0 - A * A).sqrt()) / core::f64::consts::PI;
        let mut rng = crate::rng::Rng::from_seed(17);
        let mut estimate = |strata: Strata| {
            let (mut sum, mut sum2) = (0.0f64, 0.0f64);
            for _ in 0..TRIALS {
                let mut open = 0u32;
                for k in 0..RAYS {
                    let (u1, u2) = strata.point(k, rng.next_f32(), rng.next_f32());
                    open += (cosine_hemisphere(u1, u2).x as f64 > A) as u32;
                }
                let f = open as f64 / RAYS as f64;
                sum += f;
                sum2 += f * f;
            }
            let mean = sum / TRIALS as f64;
            (mean, sum2 / TRIALS as f64 - mean * mean)
        };
        let (independent, var_independent) = estimate(Strata::NONE);
        let (stratified, var_stratified) = estimate(Strata::new(RAYS));
        // The independent variance is known: p (1 - p) / N.
        let var_exact = exact * (1.0 - exact) / RAYS as f64;
        assert!(
            (var_independent / var_exact - 1.0).abs() < 0.1,
            "{var_independent} {var_exact}"
        );
        for (mean, var) in [(independent, var_independent), (stratified, var_stratified)] {
            let sigma = (var / TRIALS as f64).sqrt();
            assert!(
                (mean - exact).abs() < 5.0 * sigma,
                "{mean} vs {exact} (σ {sigma})"
            );
        }
        assert!(
            var_stratified < var_independent / 4.0,
            "{var_stratified} {var_independent}"
        );
    }
}
