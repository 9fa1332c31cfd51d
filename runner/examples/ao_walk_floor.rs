//! Diagnostic (not part of the product): how many of the nodes an AO ray visits on the GPU
//! are forced by where it starts. Every node whose box holds a ray's origin is visited
//! whatever the ray's direction and length, so those visits are a floor under the walk that
//! no child order, triangle test or node test can lower; only a shallower tree around the
//! origins, or a cheaper visit, can. On the CPU, with the GPU's walk over the GPU's nodes
//! (`cwbvh_ao_walk_nodes`, as the `--ao-order` pilot), for a grid of camera rays and every
//! fourth of each hit's AO rays, it prints per AO ray:
//! - the nodes visited (the GPU's AO time follows them: docs/PERFORMANCE.md, "The floor
//!   under the AO walk"), and with `--features traversal-stats` the triangles tested;
//! - the nodes whose boxes hold the origin (the walk to a length of 10^-6 of the AO
//!   distance), over all rays and over the rays that escape: an escaping ray visits every
//!   box its segment crosses, these among them, while a blocked one may stop first;
//! - the nodes visited once the first share s of each ray is skipped (the walk from
//!   origin + s·distance), for each s in `--skip`: what a per-point list of the triangles
//!   near the origin, tested apart, could save at most;
//! - the nodes visited and the boxes holding the origin of the points on large triangles
//!   (a suite scene's ground) and of the rest, apart.
//!
//! `cargo run --release --example ao_walk_floor -- --scene shell-1m --width 1920 --height
//! 1080 --bvh-quality high --integrator ao --spp 1 --ao-rays 64`
use clap::Parser;
use kernels::bvh::{cwbvh_ao_walk_nodes, cwbvh_traverse};
use kernels::glam::UVec4;
use kernels::integrators::ao::strata;
use kernels::intersect::Ray;
use kernels::skip::Skip;
use kernels::types::CwBvhNode;
use rayon::prelude::*;
use runner::ao_order::grid_point;

/// Camera rays of the grid (columns × rows over the image), and which of a hit's AO rays
/// are traced (every `EVERY`-th).
const COLUMNS: u32 = 96;
const ROWS: u32 = 54;
const EVERY: usize = 4;
/// The walk to this share of the AO distance visits the boxes that hold the origin.
const AT_ORIGIN: f32 = 1e-6;
/// A triangle of more than this share of the AO distance squared is large: the suite
/// scenes' ground (two triangles under everything), whose points the counts give apart.
const LARGE: f32 = 1e-3;

#[derive(Parser)]
struct Cli {
    /// Shares of the AO distance skipped at each ray's start
    #[arg(long, value_delimiter = ',', default_value = "0.001,0.01,0.1")]
    skip: Vec<f32>,
    #[command(flatten)]
    bench: runner::bench::BenchArgs,
}

fn main() {
    let cli = Cli::parse();
    let args = &cli.bench;
    let (scene, params) = runner::bench::scene_and_params(args).unwrap_or_else(|e| {
        eprintln!("error: {e}");
        std::process::exit(1)
    });
    let buffers = scene.untraced();
    let nodes: &[UVec4] = bytemuck::cast_slice(&scene.nodes);
    let cut = buffers.cutouts();
    let triangles = buffers.triangles;
    let rays_strata = strata(&params);
    let distance = params.ao_distance;
    let walk = |ray: &Ray, skip: Skip, length: f32| {
        let end = (skip, length);
        cwbvh_ao_walk_nodes::<false, CwBvhNode>(triangles, &cut, nodes, ray, end, params.ao_order)
            as u64
    };
    // The AO rays of the grid's hits, with the triangles each skips and whether their point
    // lies on a large triangle (`LARGE`: a suite scene's ground).
    let large = |skip: Skip| buffers.triangle(skip.own()).area() > LARGE * distance * distance;
    let ao_rays: Vec<(Ray, Skip, bool)> = (0..ROWS)
        .into_par_iter()
        .flat_map_iter(|row| {
            let mut out = Vec::new();
            for column in 0..COLUMNS {
                let cell = (column, row);
                let grid = (COLUMNS, ROWS);
                if let Some(point) = grid_point::<false>(&buffers, nodes, &cut, &params, cell, grid)
                {
                    for k in (0..params.ao_rays).step_by(EVERY) {
                        out.push((point.ray(k, rays_strata), point.skip, large(point.skip)));
                    }
                }
            }
            out
        })
        .collect();
    let rays = ao_rays.len() as u64;
    let sum = |f: &(dyn Fn(&Ray, Skip) -> u64 + Sync)| -> u64 {
        ao_rays.par_iter().map(|(ray, skip, _)| f(ray, *skip)).sum()
    };
    // The walks as the GPU runs them, alone, so that the triangle counter sees only them.
    #[cfg(feature = "traversal-stats")]
    let _ = kernels::bvh::stats::take();
    let visits: Vec<u64> = ao_rays
        .par_iter()
        .map(|(ray, skip, _)| walk(ray, *skip, distance))
        .collect();
    let visited: u64 = visits.iter().sum();
    #[cfg(feature = "traversal-stats")]
    let tested = Some(kernels::bvh::stats::take().2);
    #[cfg(not(feature = "traversal-stats"))]
    let tested: Option<u64> = None;
    // Per ray, once: the boxes holding its origin, and whether it escapes.
    let origins: Vec<(u64, bool)> = ao_rays
        .par_iter()
        .map(|(ray, skip, _)| {
            let blocked =
                cwbvh_traverse::<false, CwBvhNode>(triangles, &cut, nodes, ray, distance, true)
                    .is_hit();
            (walk(ray, *skip, AT_ORIGIN * distance), !blocked)
        })
        .collect();
    let in_origin_boxes: u64 = origins.iter().map(|&(n, _)| n).sum();
    let escaping = origins.iter().filter(|&&(_, escapes)| escapes).count() as u64;
    let forced: u64 = origins
        .iter()
        .filter(|&&(_, escapes)| escapes)
        .map(|&(n, _)| n)
        .sum();
    let skipped: Vec<u64> = cli
        .skip
        .iter()
        .map(|&share| {
            sum(&|ray, skip| {
                let start = Ray::new(ray.origin + ray.dir * (share * distance), ray.dir);
                walk(&start, skip, (1.0 - share) * distance)
            })
        })
        .collect();
    let per_ray = |n: u64| n as f64 / rays.max(1) as f64;
    let name = args
        .scene
        .scene
        .as_ref()
        .map(|p| p.display().to_string())
        .unwrap_or_default();
    print!(
        "{name}: {rays} AO rays ({:.1}% escape), nodes per ray {:.2}, in boxes holding the \
         origin {:.2} (escaping rays: {:.2}, forced: {:.2} per ray)",
        100.0 * per_ray(escaping),
        per_ray(visited),
        per_ray(in_origin_boxes),
        forced as f64 / escaping.max(1) as f64,
        per_ray(forced)
    );
    if let Some(tested) = tested {
        print!(", triangles per ray {:.2}", per_ray(tested));
    }
    for (share, n) in cli.skip.iter().zip(&skipped) {
        print!(", first {share} skipped {:.2}", per_ray(*n));
    }
    println!();
    for (on_large, surface) in [(true, "large triangles"), (false, "the rest")] {
        let (mut n, mut nodes, mut boxes) = (0u64, 0u64, 0u64);
        for ((_, _, l), (v, (o, _))) in ao_rays.iter().zip(visits.iter().zip(&origins)) {
            if *l == on_large {
                (n, nodes, boxes) = (n + 1, nodes + v, boxes + o);
            }
        }
        let per = |x: u64| x as f64 / n.max(1) as f64;
        println!(
            "  points on {surface}: {:.1}% of the rays, nodes per ray {:.2}, in boxes holding \
             the origin {:.2}",
            100.0 * per_ray(n),
            per(nodes),
            per(boxes)
        );
    }
}
