//! Sample warps: cosine-weighted hemisphere, uniform triangle, orthonormal basis; the
//! octahedral encoding of directions (two numbers per direction, for reservoirs).
use crate::glam::Vec3;
use crate::math::{sin_cos, sqrt, PI};

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
}
