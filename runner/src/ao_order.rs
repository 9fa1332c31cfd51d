//! The order in which the GPU's AO walk visits a node's children (`FrameParams::ao_order`):
//! front to back along each ray, or back to front. An AO ray that meets nothing visits
//! every box it crosses in either order; one that meets something stops at its first hit,
//! and which order finds that hit sooner depends on the scene. Rays from inside a closed
//! shell are blocked by the far wall, while the boxes around their origins hardly ever
//! hold a blocker: back to front saves them 13% of their nodes. Rays between grass blades
//! are blocked by the nearest blade: back to front costs them 5%.
//!
//! The GPU's time follows the nodes it visits (docs/PERFORMANCE.md, "Benchmark suite": with
//! the order reversed for every scene, H200, shell-1m 96.0 → 83.0 ms and grass-1m 44.6 → 47.4, the
//! CPU's node counts −13% and +5%), so `auto` (the default) counts them: a pilot traces a
//! grid of camera rays and some of each hit's AO rays on the host, with the kernels' own
//! walk over the GPU's own nodes, in both orders, and takes the one that visits fewer
//! nodes by a clear margin. The CPU backend traces a point's AO rays in bundles
//! (`kernels::bundle`), whose order is its own; the image is the same in either order.
// Only the CWBVH walk has an order to choose: the other traversals leave the pilot unused.
#![cfg_attr(
    any(feature = "traversal-bvh2", feature = "traversal-brute-force"),
    allow(dead_code)
)]
use clap::ValueEnum;
use kernels::types::{FrameParams, AO_FAR_FIRST, AO_NEAR_FIRST};

use crate::scene::Scene;

#[derive(Copy, Clone, Debug, PartialEq, Eq, ValueEnum)]
pub enum AoOrder {
    /// Measured by a pilot: the order in which the scene's AO rays visit fewer nodes
    Auto,
    /// Each node's children front to back along the ray
    Near,
    /// Each node's children back to front
    Far,
}

/// Pilot grid of camera rays (columns × rows, spread over the image).
const PILOT_COLUMNS: u32 = 48;
const PILOT_ROWS: u32 = 27;
/// AO rays traced at each pilot hit (or all of them, if fewer), spread over its strata.
const PILOT_RAYS: u32 = 16;
/// Back to front is taken only where it saves at least this share of the nodes: the
/// pilot's rays are a sample, and the GPU follows the counts only roughly.
const MARGIN: f64 = 0.05;

/// What the pilot counted: AO rays traced, and the nodes they visited front to back and
/// back to front.
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct PilotCounts {
    pub rays: u64,
    pub near: u64,
    pub far: u64,
}

impl PilotCounts {
    fn add(self, o: Self) -> Self {
        Self {
            rays: self.rays + o.rays,
            near: self.near + o.near,
            far: self.far + o.far,
        }
    }

    /// The order that visits fewer nodes, back to front only by more than `MARGIN`.
    pub fn order(&self) -> u32 {
        if (self.far as f64) < (1.0 - MARGIN) * self.near as f64 {
            AO_FAR_FIRST
        } else {
            AO_NEAR_FIRST
        }
    }
}

/// The kernels' `ao_order` for `params`' AO frame of `scene`.
pub fn choose(order: AoOrder, scene: &Scene, params: &FrameParams) -> u32 {
    match order {
        AoOrder::Near => AO_NEAR_FIRST,
        AoOrder::Far => AO_FAR_FIRST,
        AoOrder::Auto => {
            let start = std::time::Instant::now();
            let counts = pilot(scene, params);
            let per_ray = |n: u64| n as f64 / counts.rays.max(1) as f64;
            log::info!(
                "AO walk order: {} (pilot: {} rays in {:.1} ms, {:.2} nodes per ray front to \
                 back, {:.2} back to front)",
                if counts.order() == AO_FAR_FIRST {
                    "back to front"
                } else {
                    "front to back"
                },
                counts.rays,
                start.elapsed().as_secs_f64() * 1e3,
                per_ray(counts.near),
                per_ray(counts.far)
            );
            counts.order()
        }
    }
}

/// Trace the pilot: the GPU's traversal code over the GPU's nodes (undecoded: a GPU run
/// never decodes the CPU's, `Scene::untraced`), so the counts are the GPU's.
pub fn pilot(scene: &Scene, params: &FrameParams) -> PilotCounts {
    #[cfg(any(feature = "traversal-bvh2", feature = "traversal-brute-force"))]
    {
        let _ = (scene, params);
        PilotCounts::default()
    }
    #[cfg(not(any(feature = "traversal-bvh2", feature = "traversal-brute-force")))]
    {
        use kernels::glam::UVec4;
        use rayon::prelude::*;
        let buffers = scene.untraced();
        let nodes: &[UVec4] = bytemuck::cast_slice(&scene.nodes);
        let cut = buffers.cutouts();
        let plain = crate::integrator::plain_scene(scene.all_diffuse(), params);
        (0..PILOT_ROWS)
            .into_par_iter()
            .map(|row| {
                let mut counts = PilotCounts::default();
                for column in 0..PILOT_COLUMNS {
                    counts = counts.add(if plain {
                        pilot_point::<true>(&buffers, nodes, &cut, params, column, row)
                    } else {
                        pilot_point::<false>(&buffers, nodes, &cut, params, column, row)
                    });
                }
                counts
            })
            .reduce(PilotCounts::default, PilotCounts::add)
    }
}

/// The pilot's AO rays of grid point (column, row), counted in both orders: traced through
/// `nodes` (the GPU's), the rest of the scene from `buffers`.
#[cfg(not(any(feature = "traversal-bvh2", feature = "traversal-brute-force")))]
fn pilot_point<const PLAIN: bool>(
    buffers: &kernels::bvh::SceneBuffers,
    nodes: &[kernels::glam::UVec4],
    cut: &kernels::bvh::Cutouts,
    params: &FrameParams,
    column: u32,
    row: u32,
) -> PilotCounts {
    use kernels::bvh::cwbvh_ao_walk_nodes;
    use kernels::integrators::ao::strata;
    use kernels::types::CwBvhNode;
    let grid = (PILOT_COLUMNS, PILOT_ROWS);
    let mut counts = PilotCounts::default();
    let Some(point) = grid_point::<PLAIN>(buffers, nodes, cut, params, (column, row), grid) else {
        return counts;
    };
    let strata = strata(params);
    let every = (params.ao_rays / PILOT_RAYS).max(1);
    for k in (0..params.ao_rays).step_by(every as usize) {
        let ao = point.ray(k, strata);
        let end = (point.skip, params.ao_distance);
        let walk = |order| {
            cwbvh_ao_walk_nodes::<PLAIN, CwBvhNode>(buffers.triangles, cut, nodes, &ao, end, order)
        };
        counts.rays += 1;
        counts.near += walk(AO_NEAR_FIRST) as u64;
        counts.far += walk(AO_FAR_FIRST) as u64;
    }
    counts
}

/// The AO rays of what the camera ray through cell (column, row) of a `grid` (columns ×
/// rows) over the image sees, or None where it sees nothing: the closest hit through
/// `nodes` (the GPU's CWBVH), the rest of the scene from `buffers`, and the rays' key from
/// the cell's own random numbers. The pilots' (and `examples/ao_walk_floor.rs`'s) sample
/// of a frame's AO rays.
pub fn grid_point<const PLAIN: bool>(
    buffers: &kernels::bvh::SceneBuffers,
    nodes: &[kernels::glam::UVec4],
    cut: &kernels::bvh::Cutouts,
    params: &FrameParams,
    (column, row): (u32, u32),
    grid: (u32, u32),
) -> Option<kernels::integrators::ao::AoRays> {
    use kernels::bvh::{cwbvh_traverse, surface_hit};
    use kernels::types::CwBvhNode;
    let ray = crate::camera::pilot_ray(params, (column, row), grid);
    let triangles = buffers.triangles;
    let hit = cwbvh_traverse::<PLAIN, CwBvhNode>(triangles, cut, nodes, &ray, f32::INFINITY, false);
    if !hit.is_hit() {
        return None;
    }
    let s = surface_hit(buffers, &ray, &hit, 0.0);
    let mut rng = kernels::rng::Rng::new(row * grid.0 + column, 0, 0, params.seed);
    Some(kernels::integrators::ao::AoRays::new(
        buffers, s.p, s.prim, s.n, &mut rng,
    ))
}
