//! Deterministic built-in scenes: no downloads needed for tests and benchmarks.
//! - `many-lights`: 128 small emitters of different colours and strengths, near and far,
//!   over a floor with occluders (the course's case where plain NEE struggles).
//! - `rocks-N`: N triangles (e.g. rocks-1m) of displaced icospheres scattered over a
//!   ground, with real depth complexity, lit by one large area light.
//! - `shell-N`: the inside of a closed black UV sphere of N triangles (pole fans of
//!   slivers included), camera at its centre: under `--sky` any lit pixel is a ray that
//!   slipped between triangles (the watertightness test and measurement).
//! - `spheres-N`, `city-N`, `grass-N`: with `rocks-N` and `shell-N`, the benchmark suite
//!   (`runner bench --suite`): UV spheres with pole slivers, long thin boxes, thin grass
//!   blades, each on a huge two-triangle ground under a row of area lights.
use std::path::PathBuf;

use clap::Args;
use std::collections::HashMap;
use std::fmt::Write as _;

use glam::Vec3;
use kernels::rng::pcg_hash;
use kernels::types::{Material, Triangle};

/// The generator's own random stream (PCG with a fixed increment): the built-in scenes
/// must stay the same scenes when the kernels' sampling streams change, or every measured
/// number and reference image of them would silently refer to another scene.
struct SceneRng {
    state: u32,
}

impl SceneRng {
    fn new(seed: u32) -> Self {
        Self {
            state: pcg_hash(seed),
        }
    }

    /// Uniform in [0, 1) with 24 bits.
    fn next_f32(&mut self) -> f32 {
        self.state = self
            .state
            .wrapping_mul(747_796_405)
            .wrapping_add(2_891_336_453);
        let s = self.state;
        let word = ((s >> ((s >> 28) + 4)) ^ s).wrapping_mul(277_803_737);
        (((word >> 22) ^ word) >> 8) as f32 * (1.0 / 16_777_216.0)
    }
}

use crate::bail;
use crate::error::Result;
use crate::scene::{CameraHint, Scene};

/// Names accepted by `--scene` besides OBJ paths.
pub const BUILTIN_NAMES: &str = "cornell-box, many-lights, light-hall, and of N triangles (e.g. \
     rocks-1m, rocks-100k): rocks-<N>, spheres-<N>, city-<N>, grass-<N>, shell-<N> (a closed \
     sphere seen from inside)";

/// A generated scene before BVH construction.
pub struct Generated {
    pub triangles: Vec<Triangle>,
    pub materials: Vec<Material>,
    pub camera: CameraHint,
}

impl Generated {
    /// A scene whose camera looks from `eye` at `target`, +y up, `fov` degrees vertically.
    fn upright(
        triangles: Vec<Triangle>,
        materials: Vec<Material>,
        eye: Vec3,
        target: Vec3,
        fov: f32,
    ) -> Self {
        Self {
            triangles,
            materials,
            camera: CameraHint {
                eye: eye.as_dvec3(),
                target: target.as_dvec3(),
                up: Vec3::Y,
                fov,
            },
        }
    }

    pub fn into_scene(self) -> Result<Scene> {
        let mut scene = Scene::new(self.triangles, self.materials)?;
        scene.camera = Some(self.camera);
        Ok(scene)
    }
}

/// Parse "100k", "1m", "2500" into a count.
fn parse_count(s: &str) -> Option<usize> {
    let s = s.to_ascii_lowercase();
    let (num, mult) = match s.chars().last()? {
        'k' => (&s[..s.len() - 1], 1_000),
        'm' => (&s[..s.len() - 1], 1_000_000),
        _ => (&s[..], 1),
    };
    let x: f64 = num.parse().ok()?;
    let count = x * mult as f64;
    // A whole number of triangles, at least one: "rocks-0.5" and "rocks-1e-300" are typos.
    ((1.0..=50e6).contains(&count) && count.fract() == 0.0).then_some(count as usize)
}

/// Range of the rocks' noise phases (about 2π, as first written).
#[allow(clippy::approx_constant)]
const ROCK_PHASE_RANGE: f32 = 6.283;

/// A generator of a built-in scene of about N triangles.
type SizedGenerator = fn(usize) -> Generated;

/// Built-in scenes of any size: "<prefix>N" (N triangles, e.g. 1m).
const SIZED: [(&str, SizedGenerator); 5] = [
    ("rocks-", rocks),
    ("shell-", shell),
    ("spheres-", spheres),
    ("city-", city),
    ("grass-", grass),
];

/// The suite `runner bench --suite` runs: structurally different scenes of ~1M triangles.
pub const SUITE: [&str; 5] = ["rocks-1m", "spheres-1m", "city-1m", "grass-1m", "shell-1m"];

/// The built-in scene called `name`, or None if there is none by that name.
pub fn builtin(name: &str) -> Option<Result<Generated>> {
    match name {
        "many-lights" => Some(Ok(many_lights())),
        "light-hall" => Some(Ok(light_hall())),
        _ => {
            let (kind, n) = SIZED
                .iter()
                .find_map(|(prefix, f)| Some((name.strip_prefix(prefix)?, *f)))?;
            Some(match parse_count(kind) {
                Some(count) => crate::memory::check_scene(
                    name,
                    count as f64 * crate::memory::BYTES_PER_SCENE_TRIANGLE as f64,
                )
                .map(|()| n(count)),
                None => Err(crate::error::Error(format!(
                    "bad triangle count in '{name}' (use e.g. rocks-100k, rocks-1m, shell-1m)"
                ))),
            })
        }
    }
}

/// Closed icosphere of radius `r` around `c`, subdivided `subdiv` times; shared vertices
/// are bit-identical in every triangle that uses them.
pub fn icosphere(c: Vec3, r: f32, subdiv: u32, material: u32) -> Vec<Triangle> {
    let (verts, faces) = icosphere_mesh(subdiv);
    faces
        .iter()
        .map(|f| {
            Triangle::new(
                c + verts[f[0]] * r,
                c + verts[f[1]] * r,
                c + verts[f[2]] * r,
                material,
            )
        })
        .collect()
}

/// Unit icosphere as shared vertices and counter-clockwise (outward) faces.
pub fn icosphere_mesh(subdiv: u32) -> (Vec<Vec3>, Vec<[usize; 3]>) {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut verts: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut faces: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdiv {
        let mut mid: HashMap<(usize, usize), usize> = HashMap::new();
        let mut midpoint = |a: usize, b: usize, verts: &mut Vec<Vec3>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                verts.push(((verts[a] + verts[b]) * 0.5).normalize());
                verts.len() - 1
            })
        };
        faces = faces
            .iter()
            .flat_map(|&[a, b, c]| {
                let ab = midpoint(a, b, &mut verts);
                let bc = midpoint(b, c, &mut verts);
                let ca = midpoint(c, a, &mut verts);
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
    }
    (verts, faces)
}

/// Two triangles of the quad a-b-c-d (counter-clockwise = front).
pub fn quad(q: [Vec3; 4], material: u32) -> [Triangle; 2] {
    [
        Triangle::new(q[0], q[1], q[2], material),
        Triangle::new(q[0], q[2], q[3], material),
    ]
}

/// Closed axis-aligned box as 12 triangles, counter-clockwise seen from outside.
pub fn closed_box(lo: Vec3, hi: Vec3, material: u32) -> Vec<Triangle> {
    let p =
        |x: usize, y: usize, z: usize| Vec3::new([lo.x, hi.x][x], [lo.y, hi.y][y], [lo.z, hi.z][z]);
    let quads = [
        [p(0, 0, 0), p(0, 1, 0), p(1, 1, 0), p(1, 0, 0)], // -z
        [p(0, 0, 1), p(1, 0, 1), p(1, 1, 1), p(0, 1, 1)], // +z
        [p(0, 0, 0), p(1, 0, 0), p(1, 0, 1), p(0, 0, 1)], // -y
        [p(0, 1, 0), p(0, 1, 1), p(1, 1, 1), p(1, 1, 0)], // +y
        [p(0, 0, 0), p(0, 0, 1), p(0, 1, 1), p(0, 1, 0)], // -x
        [p(1, 0, 0), p(1, 1, 0), p(1, 1, 1), p(1, 0, 1)], // +x
    ];
    quads.iter().flat_map(|q| quad(*q, material)).collect()
}

/// Fully saturated colour of hue h ∈ [0, 1).
fn hue(h: f32) -> Vec3 {
    let k = |n: f32| {
        let k = (n + h * 6.0) % 6.0;
        1.0 - k.min(4.0 - k).clamp(0.0, 1.0)
    };
    Vec3::new(k(5.0), k(3.0), k(1.0))
}

/// A second many-lights scene, built differently from `many_lights` (which was tuned on):
/// an enclosed hall (floor, ceiling, walls) with two rows of pillars, lit by 192 small
/// emitters on the side walls facing inward — vertical lights, heavy occlusion by the
/// pillars, and a camera looking down the hall.
pub fn light_hall() -> Generated {
    let mut rng = SceneRng::new(4242);
    let mut u = move || rng.next_f32();
    let mut materials = vec![
        Material::new(Vec3::splat(0.55), Vec3::ZERO), // floor, ceiling, walls
        Material::new(Vec3::new(0.6, 0.55, 0.5), Vec3::ZERO), // pillars
    ];
    let (w, h, len) = (8.0, 6.0, 60.0);
    let corner = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    let mut tris: Vec<Triangle> = Vec::new();
    for q in [
        [
            corner(-w, 0.0, 0.0),
            corner(w, 0.0, 0.0),
            corner(w, 0.0, -len),
            corner(-w, 0.0, -len),
        ],
        [
            corner(-w, h, 0.0),
            corner(-w, h, -len),
            corner(w, h, -len),
            corner(w, h, 0.0),
        ],
        [
            corner(-w, 0.0, 0.0),
            corner(-w, 0.0, -len),
            corner(-w, h, -len),
            corner(-w, h, 0.0),
        ],
        [
            corner(w, 0.0, 0.0),
            corner(w, h, 0.0),
            corner(w, h, -len),
            corner(w, 0.0, -len),
        ],
        [
            corner(-w, 0.0, -len),
            corner(w, 0.0, -len),
            corner(w, h, -len),
            corner(-w, h, -len),
        ],
    ] {
        tris.extend(quad(q, 0));
    }
    for i in 0..9 {
        let z = -6.0 - 6.0 * i as f32;
        for x in [-4.0, 4.0] {
            tris.extend(closed_box(
                Vec3::new(x - 0.4, 0.0, z - 0.4),
                Vec3::new(x + 0.4, h, z + 0.4),
                1,
            ));
        }
    }
    // 192 emitters on the side walls, a hair off them, facing into the hall.
    for i in 0..192 {
        let side = if i % 2 == 0 { -1.0 } else { 1.0 };
        let (y, z) = (0.5 + (h - 1.0) * u(), -2.0 - (len - 4.0) * u());
        let s = 0.1 + 0.3 * u();
        let strength = 10f32.powf(3.0 * u() - 1.0);
        materials.push(Material::new(
            Vec3::splat(0.5),
            (hue(u()) * 0.7 + Vec3::splat(0.3)) * strength,
        ));
        let m = materials.len() as u32 - 1;
        let x = side * (w - 0.01);
        // Counter-clockwise seen from inside the hall (front = -side along x).
        let (a, b) = (Vec3::new(x, y - s, z - s), Vec3::new(x, y + s, z + s));
        let q = if side < 0.0 {
            [a, Vec3::new(x, y + s, z - s), b, Vec3::new(x, y - s, z + s)]
        } else {
            [a, Vec3::new(x, y - s, z + s), b, Vec3::new(x, y + s, z - s)]
        };
        tris.extend(quad(q, m));
    }
    Generated::upright(
        tris,
        materials,
        Vec3::new(0.0, 3.0, -1.0),
        Vec3::new(0.0, 2.0, -40.0),
        60.0,
    )
}

pub fn many_lights() -> Generated {
    let mut rng = SceneRng::new(2024);
    let mut u = move || rng.next_f32();
    let mut materials = vec![
        Material::new(Vec3::splat(0.6), Vec3::ZERO), // floor
        Material::new(Vec3::new(0.7, 0.6, 0.5), Vec3::ZERO), // blocks
    ];
    let half = 30.0;
    let mut tris: Vec<Triangle> = quad(
        [
            Vec3::new(-half, 0.0, -half),
            Vec3::new(-half, 0.0, half),
            Vec3::new(half, 0.0, half),
            Vec3::new(half, 0.0, -half),
        ],
        0,
    )
    .to_vec();
    for _ in 0..24 {
        let c = Vec3::new((u() - 0.5) * 40.0, 0.0, (u() - 0.5) * 40.0 - 5.0);
        let s = Vec3::new(0.5 + 1.5 * u(), 0.5 + 3.0 * u(), 0.5 + 1.5 * u());
        tris.extend(closed_box(c - Vec3::new(s.x, 0.0, s.z), c + s, 1));
    }
    // 128 emitters: small quads facing down, log-uniform strengths over 3 decades.
    for _ in 0..128 {
        let c = Vec3::new(
            (u() - 0.5) * 50.0,
            0.3 + 5.0 * u(),
            (u() - 0.5) * 50.0 - 5.0,
        );
        let s = 0.05 + 0.25 * u();
        let strength = 10f32.powf(0.5 + 3.0 * u());
        let colour = hue(u()) * 0.7 + Vec3::splat(0.3);
        materials.push(Material::new(Vec3::splat(0.5), colour * strength));
        let m = materials.len() as u32 - 1;
        tris.extend(quad(
            [
                c + Vec3::new(-s, 0.0, -s),
                c + Vec3::new(s, 0.0, -s),
                c + Vec3::new(s, 0.0, s),
                c + Vec3::new(-s, 0.0, s),
            ],
            m,
        ));
    }
    Generated::upright(
        tris,
        materials,
        Vec3::new(0.0, 4.0, 24.0),
        Vec3::new(0.0, 0.5, -2.0),
        55.0,
    )
}

/// Value noise on the unit sphere from a few random plane waves: cheap, smooth, seeded.
fn bumps(p: Vec3, waves: &[(Vec3, f32)]) -> f32 {
    waves
        .iter()
        .map(|(k, phase)| (p.dot(*k) + phase).sin())
        .sum::<f32>()
        / waves.len() as f32
}

/// About `target` triangles: displaced icospheres (5,120 triangles each) of random sizes
/// scattered and stacked over a ground plane, plus a large area light overhead.
pub fn rocks(target: usize) -> Generated {
    let mut rng = SceneRng::new(7);
    let mut u = move || rng.next_f32();
    let (verts, faces) = icosphere_mesh(4);
    let per_rock = faces.len();
    let count = (target.saturating_sub(4) / per_rock).max(1);
    // Spread rocks over an area that grows with their number: constant density, so depth
    // complexity stays high whatever the size.
    let extent = 10.0 * (count as f32).sqrt();
    let materials = vec![
        Material::new(Vec3::splat(0.5), Vec3::ZERO),
        Material::new(Vec3::new(0.55, 0.45, 0.35), Vec3::ZERO),
        Material::new(Vec3::splat(0.5), Vec3::splat(5.0)),
    ];
    let mut tris = Vec::with_capacity(count * per_rock + 4);
    tris.extend(quad(
        [
            Vec3::new(-extent, 0.0, -extent),
            Vec3::new(-extent, 0.0, extent),
            Vec3::new(extent, 0.0, extent),
            Vec3::new(extent, 0.0, -extent),
        ],
        0,
    ));
    for _ in 0..count {
        let waves: Vec<(Vec3, f32)> = (0..6)
            // 6.283, not TAU: the rocks stay the scenes every measurement was made on.
            .map(|_| {
                (
                    Vec3::new(u() - 0.5, u() - 0.5, u() - 0.5) * 12.0,
                    u() * ROCK_PHASE_RANGE,
                )
            })
            .collect();
        let r = 1.0 + 4.0 * u() * u();
        let c = Vec3::new(
            (u() - 0.5) * 2.0 * extent,
            r * (0.3 + 1.5 * u()),
            (u() - 0.5) * 2.0 * extent,
        );
        let squash = Vec3::new(1.0 + 0.5 * u(), 0.5 + 0.7 * u(), 1.0 + 0.5 * u());
        let displaced: Vec<Vec3> = verts
            .iter()
            .map(|v| c + *v * squash * r * (1.0 + 0.35 * bumps(*v, &waves)))
            .collect();
        tris.extend(
            faces
                .iter()
                .map(|f| Triangle::new(displaced[f[0]], displaced[f[1]], displaced[f[2]], 1)),
        );
    }
    let h = 4.0 * extent.sqrt() + 30.0;
    let l = 0.2 * extent;
    tris.extend(quad(
        [
            Vec3::new(-l, h, -l),
            Vec3::new(l, h, -l),
            Vec3::new(l, h, l),
            Vec3::new(-l, h, l),
        ],
        2,
    ));
    Generated::upright(
        tris,
        materials,
        Vec3::new(0.0, 0.25 * extent + 8.0, extent * 1.1),
        Vec3::new(0.0, 2.0, 0.0),
        50.0,
    )
}

/// A closed UV sphere: `rings` × 2·`rings` segments, fans of slivers at the poles, each
/// vertex computed once (neighbouring triangles share bit-identical edges), scaled by
/// `radius` per axis; counter-clockwise seen from outside. 4·rings·(rings − 1) triangles.
pub fn uv_sphere(centre: Vec3, radius: Vec3, rings: usize, material: u32) -> Vec<Triangle> {
    let rings = rings.max(2);
    let segments = 2 * rings;
    let vertex = |ring: usize, segment: usize| {
        let theta = std::f32::consts::PI * ring as f32 / rings as f32;
        let phi = std::f32::consts::TAU * (segment % segments) as f32 / segments as f32;
        let unit = Vec3::new(
            theta.sin() * phi.cos(),
            theta.cos(),
            theta.sin() * phi.sin(),
        );
        centre + unit * radius
    };
    let (north, south) = (vertex(0, 0), vertex(rings, 0));
    let grid: Vec<Vec<Vec3>> = (1..rings)
        .map(|r| (0..segments).map(|s| vertex(r, s)).collect())
        .collect();
    let mut tris = Vec::with_capacity(2 * segments * (rings - 1));
    for s in 0..segments {
        let t = (s + 1) % segments;
        tris.push(Triangle::new(north, grid[0][t], grid[0][s], material));
        tris.push(Triangle::new(
            south,
            grid[rings - 2][s],
            grid[rings - 2][t],
            material,
        ));
        for r in 0..rings - 2 {
            let (a, b) = (grid[r][s], grid[r][t]);
            let (c, d) = (grid[r + 1][s], grid[r + 1][t]);
            tris.push(Triangle::new(a, b, d, material));
            tris.push(Triangle::new(a, d, c, material));
        }
    }
    tris
}

/// Rings of a UV sphere of about `triangles` triangles.
fn rings_for(triangles: usize) -> usize {
    ((triangles as f64 / 4.0).sqrt().round() as usize).max(2)
}

/// The inside of a closed black UV sphere of radius 1 and about `target` triangles, seen
/// from its centre.
pub fn shell(target: usize) -> Generated {
    Generated::upright(
        uv_sphere(Vec3::ZERO, Vec3::ONE, rings_for(target), 0),
        vec![Material::new(Vec3::ZERO, Vec3::ZERO)],
        Vec3::ZERO,
        Vec3::new(0.3, 0.4, -1.0),
        100.0,
    )
}

/// The suite's ground: one huge quad (two triangles far larger than anything on them, the
/// case that defeats a BVH without splits) of half-size `half`, and `lights` emissive
/// squares of side `side` in a row at height `height`. Materials: 0 ground, 1 objects,
/// 2 lights.
fn ground_and_lights(
    half: f32,
    height: f32,
    lights: usize,
    side: f32,
) -> (Vec<Triangle>, Vec<Material>) {
    let mut tris: Vec<Triangle> = quad(
        [
            Vec3::new(-half, 0.0, -half),
            Vec3::new(-half, 0.0, half),
            Vec3::new(half, 0.0, half),
            Vec3::new(half, 0.0, -half),
        ],
        0,
    )
    .to_vec();
    for i in 0..lights {
        let x = (i as f32 + 0.5) / lights as f32 * half - 0.5 * half;
        let h = 0.5 * side;
        tris.extend(quad(
            [
                Vec3::new(x - h, height, -h),
                Vec3::new(x + h, height, -h),
                Vec3::new(x + h, height, h),
                Vec3::new(x - h, height, h),
            ],
            2,
        ));
    }
    let materials = vec![
        Material::new(Vec3::splat(0.5), Vec3::ZERO),
        Material::new(Vec3::new(0.6, 0.55, 0.5), Vec3::ZERO),
        // Bright enough that the ground below gets an irradiance of about 2π.
        Material::new(
            Vec3::splat(0.5),
            Vec3::splat(2.0 * height * height / (lights as f32 * side * side)),
        ),
    ];
    (tris, materials)
}

/// `spheres-N`: 50 UV spheres (squashed, slivers at their poles) of N/50 triangles each,
/// scattered over a huge two-triangle ground.
pub fn spheres(target: usize) -> Generated {
    const COUNT: usize = 50;
    let mut rng = SceneRng::new(11);
    let mut u = move || rng.next_f32();
    let (mut tris, materials) = ground_and_lights(200.0, 60.0, 4, 8.0);
    let rings = rings_for(target / COUNT);
    for _ in 0..COUNT {
        let r = 1.0 + 4.0 * u();
        let radius = Vec3::new(r * (0.8 + 0.4 * u()), r * (0.5 + 0.7 * u()), r);
        let c = Vec3::new((u() - 0.5) * 60.0, radius.y * 0.8, (u() - 0.5) * 60.0);
        tris.extend(uv_sphere(c, radius, rings, 1));
    }
    Generated::upright(
        tris,
        materials,
        Vec3::new(0.0, 18.0, 45.0),
        Vec3::new(0.0, 2.0, 0.0),
        50.0,
    )
}

/// `city-N`: N/12 long thin boxes (towers, walls and beams, up to 40:1) packed over a huge
/// ground.
pub fn city(target: usize) -> Generated {
    let mut rng = SceneRng::new(12);
    let mut u = move || rng.next_f32();
    let count = (target / 12).max(1);
    let extent = 2.0 * (count as f32).sqrt();
    let (mut tris, materials) =
        ground_and_lights(4.0 * extent, 0.4 * extent + 20.0, 6, 0.05 * extent);
    for _ in 0..count {
        let long = 2.0 + 18.0 * u() * u();
        let thin = 0.1 + 0.4 * u();
        let tall = 0.2 + 12.0 * u() * u() * u();
        let size = if u() < 0.5 {
            Vec3::new(long, tall, thin)
        } else {
            Vec3::new(thin, tall, long)
        };
        let lo = Vec3::new((u() - 0.5) * 2.0 * extent, 0.0, (u() - 0.5) * 2.0 * extent);
        tris.extend(closed_box(lo, lo + size, 1));
    }
    Generated::upright(
        tris,
        materials,
        Vec3::new(0.0, 0.15 * extent, 0.9 * extent),
        Vec3::new(0.0, 0.0, 0.2 * extent),
        50.0,
    )
}

/// `grass-N`: N/3 blades (a thin tapered quad and a tip, bent by the wind) over a huge
/// ground, seen from just above them.
pub fn grass(target: usize) -> Generated {
    let mut rng = SceneRng::new(13);
    let mut u = move || rng.next_f32();
    let count = (target / 3).max(1);
    let extent = 0.05 * (count as f32).sqrt();
    let (mut tris, materials) =
        ground_and_lights(8.0 * extent, 3.0 + 0.5 * extent, 4, 0.1 * extent);
    for _ in 0..count {
        let base = Vec3::new((u() - 0.5) * 2.0 * extent, 0.0, (u() - 0.5) * 2.0 * extent);
        let angle = std::f32::consts::TAU * u();
        let side = Vec3::new(angle.cos(), 0.0, angle.sin()) * (0.004 + 0.004 * u());
        let height = 0.15 + 0.35 * u();
        let lean = Vec3::new(0.3 * (u() - 0.5), 0.0, 0.3 * (u() - 0.5)) * height;
        let mid = base + Vec3::Y * (0.6 * height) + 0.4 * lean;
        let tip = base + Vec3::Y * height + lean;
        tris.extend(quad(
            [base - side, base + side, mid + 0.7 * side, mid - 0.7 * side],
            1,
        ));
        tris.push(Triangle::new(mid - 0.7 * side, mid + 0.7 * side, tip, 1));
    }
    Generated::upright(
        tris,
        materials,
        Vec3::new(0.0, 0.7, 0.8 * extent),
        Vec3::new(0.0, 0.0, 0.4 * extent),
        60.0,
    )
}

/// OBJ + MTL text for a generated scene (what `runner generate` writes).
pub fn to_obj(g: &Generated, mtl_name: &str) -> (String, String) {
    let mut obj = String::new();
    let c = &g.camera;
    // Generated positions are f32 values: written as such (shortest digits).
    let (eye, target) = (c.eye.as_vec3(), c.target.as_vec3());
    let _ = writeln!(obj, "# Generated by `runner generate`.");
    let _ = writeln!(
        obj,
        "# camera: eye={},{},{} target={},{},{} up={},{},{} fov={}",
        eye.x, eye.y, eye.z, target.x, target.y, target.z, c.up.x, c.up.y, c.up.z, c.fov
    );
    let _ = writeln!(obj, "mtllib {mtl_name}");
    let mut current = u32::MAX;
    for (i, t) in g.triangles.iter().enumerate() {
        if t.material != current {
            current = t.material;
            let _ = writeln!(obj, "usemtl m{current}");
        }
        for p in [t.p0, t.p1, t.p2] {
            let _ = writeln!(obj, "v {} {} {}", p[0], p[1], p[2]);
        }
        let _ = writeln!(obj, "f {} {} {}", 3 * i + 1, 3 * i + 2, 3 * i + 3);
    }
    let mut mtl = String::new();
    for (i, m) in g.materials.iter().enumerate() {
        let _ = writeln!(mtl, "newmtl m{i}");
        let _ = writeln!(mtl, "Kd {} {} {}", m.albedo[0], m.albedo[1], m.albedo[2]);
        if m.is_emissive() {
            let _ = writeln!(
                mtl,
                "Ke {} {} {}",
                m.emission[0], m.emission[1], m.emission[2]
            );
        }
    }
    (obj, mtl)
}

/// Reject names that are neither built in nor files, listing what exists.
pub fn unknown_scene(name: &str) -> Result<Generated> {
    bail!("cannot read scene '{name}': no such file, and no built-in scene of that name ({BUILTIN_NAMES})")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The built-in scenes are fixed: every number and reference image in the README and
    /// the tests refers to them. (The first emitter of many-lights and one of its vertices,
    /// as the scene has been since it was written.)
    #[test]
    fn sized_scenes_have_about_the_triangles_asked_for() {
        for (prefix, generate) in SIZED {
            for n in [50_000usize, 300_000] {
                let g = generate(n);
                let got = g.triangles.len() as f64;
                assert!(
                    (got / n as f64 - 1.0).abs() < 0.2,
                    "{prefix}{n}: {got} triangles"
                );
                assert!(g.into_scene().is_ok(), "{prefix}{n} loads");
            }
        }
        for name in SUITE {
            assert!(builtin(name).is_some(), "{name} is a built-in scene");
        }
        // The suite's timings in the README refer to these very scenes: a changed
        // generator is a new suite (re-measure, then update these).
        let middle_vertex = |g: Generated| g.triangles[g.triangles.len() / 2].p0;
        assert_eq!(
            middle_vertex(rocks(50_000)),
            [20.163225, 0.81437194, 20.32913]
        );
        assert_eq!(middle_vertex(shell(50_000)), [0.0, 1.0, 0.0]);
        assert_eq!(
            middle_vertex(spheres(50_000)),
            [-21.031097, 0.50747395, -15.870229]
        );
        assert_eq!(middle_vertex(city(50_000)), [9.460201, 0.0, -122.29478]);
        assert_eq!(middle_vertex(grass(50_000)), [2.5779943, 0.0, -4.9087815]);
    }

    #[test]
    fn built_in_scenes_do_not_change() {
        let g = many_lights();
        assert_eq!(g.triangles.len(), 546);
        assert_eq!(g.materials[2].emission, [19.7662, 8.200587, 27.33529]);
        let p = g
            .triangles
            .iter()
            .find(|t| t.material == 95)
            .map(|t| t.p0)
            .unwrap();
        assert_eq!(p, [-3.0192213, 4.6667233, -19.55682]);
        let hall = light_hall();
        assert_eq!((hall.triangles.len(), hall.materials.len()), (610, 194));
    }
}

#[derive(Args, Debug, Clone)]
pub struct GenerateArgs {
    /// Built-in scene: many-lights, light-hall or rocks-<N> (e.g. rocks-1m)
    pub name: String,
    /// Output OBJ file; the MTL file is written next to it
    #[arg(long, value_name = "FILE.obj")]
    pub out: PathBuf,
}

/// `runner generate`: write a built-in scene as OBJ + MTL.
pub fn run(args: &GenerateArgs) -> Result<()> {
    if args
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("mtl"))
    {
        crate::bail!(
            "--out '{}' names the MTL file; give the OBJ file (the MTL is written beside it)",
            args.out.display()
        );
    }
    let generated = match builtin(&args.name) {
        Some(g) => g?,
        None => crate::bail!("no built-in scene '{}' ({})", args.name, BUILTIN_NAMES),
    };
    let mtl_path = args.out.with_extension("mtl");
    let mtl_name = mtl_path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let (obj, mtl) = to_obj(&generated, &mtl_name);
    crate::output::write_file(&args.out, obj.as_bytes())?;
    crate::output::write_file(&mtl_path, mtl.as_bytes())?;
    eprintln!(
        "wrote {} and {} ({} triangles)",
        args.out.display(),
        mtl_path.display(),
        generated.triangles.len()
    );
    Ok(())
}
