//! Diagnostic (not part of the product): would a warp that walks the tree together — one
//! node for all its lanes at a time, a shared stack, each lane testing the node against
//! its own ray — beat the GPU's walk of one ray per lane on the suite's AO rays? The pool
//! hands a warp the same ray k of neighbouring points (`integrators::ao`), so their rays
//! start close together and leave in similar directions. For sampled 16×56 workgroups at
//! full resolution, each ray's segment up to its closest hit is walked alone (every node
//! whose box it crosses) and the nodes of each packet of `--lanes` consecutive points'
//! ray k are counted as a set. A packet walk costs a step of its whole packet per node of
//! that union; the lane walk a lane's step per node of its ray, its warps running about
//! 15 of 32 lanes (docs/PERFORMANCE.md, "Where the AO walk's time goes"), so it wins
//! unless the union is under about 32/15 times a ray's nodes. It prints both, and the
//! triangles whose leaf boxes the rays cross.
//!
//! `cargo run --release --example ao_packet_union -- --scene spheres-1m --width 1920
//! --height 1080 --bvh-quality high --integrator ao --spp 1 --ao-rays 64`
use clap::Parser;
use kernels::bvh::{cwbvh_traverse, safe_recip, WideNode};
use kernels::glam::UVec4;
use kernels::integrators::ao::{strata, AoRays, GROUP_WIDTH, WIDE_GROUP};
use kernels::intersect::Ray;
use kernels::types::cwbvh_meta::{FIRST_INTERIOR_BIT, TRIANGLE_HITS};
use kernels::types::CwBvhNode;
use rayon::prelude::*;
use runner::ao_order::grid_point;

/// Lanes of a warp.
const WARP: usize = 32;

#[derive(Parser)]
struct Cli {
    /// Workgroups sampled over the image
    #[arg(long, default_value_t = 60)]
    groups: u32,
    /// Walk every this-many-th of a point's rays
    #[arg(long, default_value_t = 8)]
    every: u32,
    /// Lanes of a packet
    #[arg(long, default_value_t = 32)]
    lanes: usize,
    #[command(flatten)]
    bench: runner::bench::BenchArgs,
}

/// Appends the nodes whose boxes the segment of `ray` to `t_max` crosses, from the root,
/// and the triangles of the leaf boxes it crosses: the GPU's node test (`WideNode::hits`),
/// every hit child followed.
fn crossed(nodes: &[CwBvhNode], ray: &Ray, t_max: f32, out: &mut (Vec<u32>, Vec<u32>)) {
    let inv_dir = safe_recip(ray.dir);
    let mut stack = vec![0u32];
    while let Some(i) = stack.pop() {
        out.0.push(i);
        let n = &nodes[i as usize];
        // Octant 0: the interior children's bits stay in slot order.
        let hits = n.hits(ray.origin, inv_dir, 0, t_max);
        let interior = hits >> FIRST_INTERIOR_BIT;
        for slot in (0..8).filter(|slot| interior >> slot & 1 != 0) {
            // Interior children are stored in slot order: the index counts those below.
            let below = (n.imask() & ((1 << slot) - 1)).count_ones();
            stack.push(n.child_base() + below);
        }
        let triangles = hits & TRIANGLE_HITS;
        let first = n.primitive_base();
        out.1.extend(
            (0..24)
                .filter(|k| triangles >> k & 1 != 0)
                .map(|k| first + k),
        );
    }
}

/// Sums over rays and packets.
#[derive(Default)]
struct Counts {
    rays: u64,
    packets: u64,
    ray_nodes: u64,
    union_nodes: u64,
    ray_triangles: u64,
    union_triangles: u64,
    /// Warps of 32 lanes, and the sum over them of their longest packet's nodes: the steps
    /// of a warp whose packets walk side by side.
    warps: u64,
    warp_steps: u64,
}

impl Counts {
    fn add(self, o: Self) -> Self {
        Self {
            rays: self.rays + o.rays,
            packets: self.packets + o.packets,
            ray_nodes: self.ray_nodes + o.ray_nodes,
            union_nodes: self.union_nodes + o.union_nodes,
            ray_triangles: self.ray_triangles + o.ray_triangles,
            union_triangles: self.union_triangles + o.union_triangles,
            warps: self.warps + o.warps,
            warp_steps: self.warp_steps + o.warp_steps,
        }
    }
}

fn main() {
    let cli = Cli::parse();
    let args = &cli.bench;
    let (scene, params) = runner::bench::scene_and_params(args).unwrap_or_else(|e| {
        eprintln!("error: {e}");
        std::process::exit(1)
    });
    let buffers = scene.untraced();
    let words: &[UVec4] = bytemuck::cast_slice(&scene.nodes);
    let nodes: &[CwBvhNode] = &scene.nodes;
    let cut = buffers.cutouts();
    let rays_strata = strata(&params);
    let (w, h) = (params.width, params.height);
    // The wide workgroup of NVIDIA adapters.
    let (gw, gh) = (GROUP_WIDTH as u32, (WIDE_GROUP / GROUP_WIDTH) as u32);
    let tiles = w.div_ceil(gw) * h.div_ceil(gh);
    let counts = (0..cli.groups)
        .into_par_iter()
        .map(|g| {
            // Tiles spread over the image by a multiplicative hash.
            let tile = (u64::from(g) * 2_654_435_761 % u64::from(tiles)) as u32;
            let (x0, y0) = (tile % w.div_ceil(gw) * gw, tile / w.div_ceil(gw) * gh);
            let points: Vec<AoRays> = (y0..(y0 + gh).min(h))
                .flat_map(|y| (x0..(x0 + gw).min(w)).map(move |x| (x, y)))
                .filter_map(|cell| {
                    grid_point::<false>(&buffers, words, &cut, &params, cell, (w, h))
                })
                .collect();
            let mut c = Counts::default();
            let mut seen = (Vec::new(), Vec::new());
            let lanes = cli.lanes.clamp(1, WARP);
            for k in (0..params.ao_rays).step_by(cli.every.max(1) as usize) {
                for warp in points.chunks(WARP) {
                    let mut longest = 0;
                    for packet in warp.chunks(lanes) {
                        seen.0.clear();
                        seen.1.clear();
                        for point in packet {
                            let ray = point.ray(k, rays_strata);
                            let triangles = buffers.triangles;
                            let end = cwbvh_traverse::<false, CwBvhNode>(
                                triangles,
                                &cut,
                                words,
                                &ray,
                                params.ao_distance,
                                false,
                            )
                            .t;
                            crossed(nodes, &ray, end, &mut seen);
                        }
                        c.rays += packet.len() as u64;
                        c.ray_nodes += seen.0.len() as u64;
                        c.ray_triangles += seen.1.len() as u64;
                        for list in [&mut seen.0, &mut seen.1] {
                            list.sort_unstable();
                            list.dedup();
                        }
                        c.packets += 1;
                        c.union_nodes += seen.0.len() as u64;
                        c.union_triangles += seen.1.len() as u64;
                        longest = longest.max(seen.0.len() as u64);
                    }
                    c.warps += 1;
                    c.warp_steps += longest;
                }
            }
            c
        })
        .reduce(Counts::default, Counts::add);
    let per_ray = |n: u64| n as f64 / counts.rays.max(1) as f64;
    let per_packet = |n: u64| n as f64 / counts.packets.max(1) as f64;
    let name = args
        .scene
        .scene
        .as_ref()
        .map(|p| p.display().to_string())
        .unwrap_or_default();
    println!(
        "{name}: {} rays in packets of {:.1}; nodes per ray {:.2}, per packet {:.2} ({:.2}× a \
         ray's); leaf triangles per ray {:.2}, per packet {:.2}; steps per warp of {WARP} rays: \
         packets {:.1}, lane walk at 15 / 18.4 lanes {:.1} / {:.1}",
        counts.rays,
        counts.rays as f64 / counts.packets.max(1) as f64,
        per_ray(counts.ray_nodes),
        per_packet(counts.union_nodes),
        per_packet(counts.union_nodes) / per_ray(counts.ray_nodes),
        per_ray(counts.ray_triangles),
        per_packet(counts.union_triangles),
        counts.warp_steps as f64 / counts.warps.max(1) as f64,
        WARP as f64 * per_ray(counts.ray_nodes) / 15.0,
        WARP as f64 * per_ray(counts.ray_nodes) / 18.4,
    );
}
