//! Ray–triangle intersection through the scene query: watertightness on closed meshes.
mod common;

use common::{closed_box, icosphere};
use glam::Vec3;
use kernels::intersect::{intersect_moller_trumbore, intersect_watertight, Ray, WatertightRay};
use kernels::rng::Rng;
use kernels::types::Triangle;

/// Closest t over all triangles with a given per-triangle test; None when every test misses.
fn closest(tris: &[Triangle], ray: &Ray, watertight: bool) -> Option<f32> {
    let wr = WatertightRay::new(ray);
    tris.iter()
        .filter_map(|t| {
            if watertight {
                intersect_watertight(&wr, t, 0.0, f32::INFINITY)
            } else {
                intersect_moller_trumbore(ray, t, 0.0, f32::INFINITY)
            }
        })
        .map(|h| h.0)
        .reduce(f32::min)
}

/// Rays from random interior points: towards random directions, towards points on shared
/// edges, and exactly at shared vertices. Returns (rays, misses).
fn shoot(
    tris: &[Triangle],
    inside: impl Fn(&mut Rng) -> Vec3,
    rays: u32,
    watertight: bool,
) -> (u32, u32) {
    let mut rng = Rng::from_seed(12345);
    let mut misses = 0;
    for i in 0..rays {
        let o = inside(&mut rng);
        let t = &tris[(rng.next_u32() % tris.len() as u32) as usize];
        let (p0, p1, p2) = t.vertices();
        let target = match i % 3 {
            // a random direction
            0 => o + common_dir(&mut rng),
            // a point on a shared edge
            1 => {
                let s = rng.next_f32();
                match rng.next_u32() % 3 {
                    0 => p0.lerp(p1, s),
                    1 => p1.lerp(p2, s),
                    _ => p2.lerp(p0, s),
                }
            }
            // a shared vertex
            _ => [p0, p1, p2][(rng.next_u32() % 3) as usize],
        };
        let ray = Ray::new(o, (target - o).normalize());
        if closest(tris, &ray, watertight).is_none() {
            misses += 1;
        }
    }
    (rays, misses)
}

fn common_dir(rng: &mut Rng) -> Vec3 {
    loop {
        let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        if v.length_squared() > 1e-4 && v.length_squared() <= 1.0 {
            return v.normalize();
        }
    }
}

#[test]
fn watertight_test_never_misses_from_inside_a_closed_sphere() {
    let tris = icosphere(Vec3::new(0.3, -0.2, 0.1), 2.0, 2, 0);
    assert_eq!(tris.len(), 320);
    let inside = |rng: &mut Rng| Vec3::new(0.3, -0.2, 0.1) + common_dir(rng) * 1.5 * rng.next_f32();
    let (rays, misses) = shoot(&tris, inside, 1_000_000, true);
    assert_eq!(
        misses, 0,
        "{misses} of {rays} rays escaped the closed sphere"
    );
}

#[test]
fn watertight_test_never_misses_from_inside_a_closed_box() {
    let (lo, hi) = (Vec3::new(-1.0, -2.0, -0.5), Vec3::new(3.0, 1.0, 0.75));
    let tris = closed_box(lo, hi, 0);
    // Strictly inside: an origin within rounding distance of a face is on that face, and a
    // ray leaving it outwards rightly hits nothing (t ≤ its error bound is rejected).
    let inside = |rng: &mut Rng| {
        let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        lo + (hi - lo) * (0.001 + 0.998 * u)
    };
    let (rays, misses) = shoot(&tris, inside, 1_000_000, true);
    assert_eq!(misses, 0, "{misses} of {rays} rays escaped the closed box");
}

#[test]
fn moller_trumbore_hits_random_directions_inside_a_sphere() {
    // Möller–Trumbore is not watertight at edges, but random directions almost never land
    // within rounding of one: allow at most 1 in 100,000.
    let tris = icosphere(Vec3::ZERO, 1.0, 2, 0);
    let mut rng = Rng::from_seed(7);
    let rays = 300_000;
    let misses = (0..rays)
        .filter(|_| {
            let o = common_dir(&mut rng) * 0.5 * rng.next_f32();
            closest(&tris, &Ray::new(o, common_dir(&mut rng)), false).is_none()
        })
        .count();
    assert!(misses * 100_000 <= rays, "{misses} of {rays} missed");
}

#[test]
fn both_variants_agree_on_t_away_from_edges() {
    let tris = icosphere(Vec3::ZERO, 1.0, 1, 0);
    let mut rng = Rng::from_seed(99);
    for _ in 0..20_000 {
        let o = common_dir(&mut rng) * 0.7 * rng.next_f32();
        let ray = Ray::new(o, common_dir(&mut rng));
        let (a, b) = (closest(&tris, &ray, true), closest(&tris, &ray, false));
        if let (Some(a), Some(b)) = (a, b) {
            assert!((a - b).abs() <= 1e-5 * a.max(1.0), "{a} vs {b}");
        }
    }
}
