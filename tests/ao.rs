//! Ambient occlusion against analytic values.
mod common;

use common::{grey, quad, z_score};
use glam::Vec3;
use kernels::bvh::SceneBuffers;
use kernels::integrators::ao::{ambient_occlusion, AoRays};
use kernels::intersect::Ray;
use kernels::rng::Rng;
use kernels::sampling::Strata;
use kernels::types::{Triangle, INVALID};
use runner::scene::Scene;

/// Half size of the "infinite" planes: far beyond every AO ray below (≤ 5 long, from
/// points within 3 of the origin), and large against the scene's other lengths.
const BIG: f32 = 1.0e2;
/// The open-plane test uses a far larger plane: numerically the hardest case for
/// self-intersection, since the error of t grows with the triangle's size.
const HUGE: f32 = 1.0e5;

fn floor(size: f32) -> Vec<Triangle> {
    quad(
        [
            Vec3::new(-size, -size, 0.0),
            Vec3::new(size, -size, 0.0),
            Vec3::new(size, size, 0.0),
            Vec3::new(-size, size, 0.0),
        ],
        0,
    )
    .to_vec()
}

/// The wall x = 0, facing +x, standing on the floor.
fn wall() -> Vec<Triangle> {
    quad(
        [
            Vec3::new(0.0, -BIG, 0.0),
            Vec3::new(0.0, BIG, 0.0),
            Vec3::new(0.0, BIG, BIG),
            Vec3::new(0.0, -BIG, BIG),
        ],
        0,
    )
    .to_vec()
}

/// The triangle under point p of the floor, as a camera ray from above finds it; and
/// `INVALID`: the AO rays either skip the triangles they cannot meet or test them (see
/// `AoRays::skip`), with the same result.
fn floor_prims(scene: &SceneBuffers, p: Vec3) -> [u32; 2] {
    let hit = scene.closest_hit::<false>(&Ray::new(p + Vec3::Z, -Vec3::Z), f32::INFINITY);
    assert!(hit.is_hit(), "no floor under {p}");
    [hit.prim, INVALID]
}

#[test]
fn open_plane_is_fully_unoccluded() {
    let scene = Scene::new(floor(HUGE), vec![grey(0.5)]).unwrap();
    let scene = scene.kernel();
    let mut rng = Rng::from_seed(1);
    for p in [
        Vec3::ZERO,
        Vec3::new(0.01, 0.02, 0.0),
        Vec3::new(123.0, -45.0, 0.0),
        Vec3::new(-9000.0, 9000.0, 0.0),
    ] {
        for prim in floor_prims(&scene, p) {
            for strata in [Strata::NONE, Strata::new(10_000)] {
                let rays = AoRays::new(&scene, p, prim, Vec3::Z, &mut rng);
                let v = ambient_occlusion::<false>(&scene, rays, 10_000, strata, f32::INFINITY);
                assert_eq!(v, 1.0, "at {p}, leaving {prim}");
            }
        }
    }
}

/// Point on the floor at distance d from the wall, AO rays of length D. Cosine-weighted
/// directions project uniformly onto the unit disk, and a ray hits the wall within D iff
/// its x component is below -d/D: the occluded fraction is the disk segment beyond
/// a = d/D, (acos a - a sqrt(1 - a²)) / π.
fn corner_unoccluded(d: f32, distance: f32) -> f64 {
    let a = (d / distance).min(1.0) as f64;
    1.0 - (a.acos() - a * (1.0 - a * a).sqrt()) / std::f64::consts::PI
}

#[test]
fn corner_of_two_planes_matches_the_analytic_value() {
    let mut tris = floor(BIG);
    tris.extend(wall());
    let scene = Scene::new(tris, vec![grey(0.5)]).unwrap();
    let scene = scene.kernel();
    let rays = 200_000u32;
    for (i, (d, distance)) in [
        (0.01f32, 1.0f32),
        (0.25, 1.0),
        (0.5, 1.0),
        (0.9, 1.0),
        (2.0, 5.0),
        (3.0, 1.0),
    ]
    .into_iter()
    .enumerate()
    {
        let mut rng = Rng::from_seed(100 + i as u32);
        let p = Vec3::new(d, 0.0, 0.0);
        let want = corner_unoccluded(p.x, distance);
        // Binomial standard error of a fraction over `rays` independent rays (the strata's
        // is smaller); floor it for p ∈ {0, 1}.
        let se = (want * (1.0 - want) / rays as f64).sqrt().max(1e-6);
        for prim in floor_prims(&scene, p) {
            for strata in [Strata::NONE, Strata::new(rays)] {
                let point = AoRays::new(&scene, p, prim, Vec3::Z, &mut rng);
                let got = ambient_occlusion::<false>(&scene, point, rays, strata, distance) as f64;
                assert!(
                    z_score(got, want, se) < 5.0 || (got - want).abs() < 1e-5,
                    "d = {d}, D = {distance}, {strata:?}, leaving {prim}: got {got}, \
                     expected {want} (se {se})"
                );
            }
        }
    }
}
