//! SPIR-V entry points: fetch the invocation id, bounds-check, call the kernel function,
//! store. No logic lives here; the CPU backend calls the same kernel functions.
//!
//! Bindings (set 0) shared by every image kernel, mirrored in runner/src/gpu.rs:
//! 0 FrameParams, 1 triangles, 2 materials, 3 BVH nodes, 4 lights,
//! 5 accumulation (rgb = sum, a = sample count), 6 rays traced per pixel.
//! ReSTIR passes add set 1: 0 current G-buffer, 1 previous G-buffer, 2 input reservoirs,
//! 3 output reservoirs, 4 previous frame's reservoirs.
use crate::bvh::{BvhNode, Scene};
use crate::glam::{UVec3, Vec4};
use crate::integrators::{ao, path, restir, PixelResult};
use crate::present::{display_colour, fullscreen_triangle, PresentParams};
use crate::reservoir::Reservoir;
use crate::types::{FrameParams, GBufferTexel, Light, Material, Triangle};
use spirv_std::spirv;

/// Declares one image kernel: `$name` runs `$pixel(&scene, params, x, y)` for its pixel
/// and adds the sum of its samples to the accumulation buffer.
macro_rules! image_kernel {
    ($name:ident, $pixel:expr) => {
        #[spirv(compute(threads(8, 8)))]
        pub fn $name(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &FrameParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] triangles: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] materials: &[Material],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] nodes: &[BvhNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] lights: &[Light],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] accum: &mut [Vec4],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] ray_counts: &mut [u32],
        ) {
            if id.x >= params.width || id.y >= params.height {
                return;
            }
            let scene = Scene {
                triangles,
                materials,
                nodes,
                lights,
            };
            // A fn item or closure called in place: monomorphised, no indirect call.
            let r: PixelResult = ($pixel)(&scene, params, id.x, id.y);
            let i = (id.y * params.width + id.x) as usize;
            accum[i] += r.sum.extend(params.samples as f32);
            ray_counts[i] = ray_counts[i].wrapping_add(r.rays);
        }
    };
}

image_kernel!(ao_main, ao::render_pixel);
image_kernel!(pt_main, |s: &Scene, p: &FrameParams, x, y| {
    path::render_pixel(s, p, x, y, path::BSDF)
});
image_kernel!(nee_main, |s: &Scene, p: &FrameParams, x, y| {
    path::render_pixel(s, p, x, y, path::NEE)
});
image_kernel!(mis_main, |s: &Scene, p: &FrameParams, x, y| {
    path::render_pixel(s, p, x, y, path::MIS)
});
image_kernel!(ris_main, |s: &Scene, p: &FrameParams, x, y| {
    path::render_pixel(s, p, x, y, path::RIS)
});

/// Declares one ReSTIR pass: the scene bindings of set 0 and the ReSTIR buffers of set 1
/// are in scope under the names below; `$body` computes and stores the pixel's result.
macro_rules! restir_kernel {
    ($name:ident, |$scene:ident, $params:ident, $x:ident, $y:ident, $i:ident, $rays:ident, $g_cur:ident, $g_prev:ident, $res_in:ident, $res_out:ident, $res_prev:ident, $accum:ident| $body:block) => {
        #[spirv(compute(threads(8, 8)))]
        #[allow(unused_variables, unused_mut)]
        pub fn $name(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] $params: &FrameParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] triangles: &[Triangle],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] materials: &[Material],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] nodes: &[BvhNode],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] lights: &[Light],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] $accum: &mut [Vec4],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] ray_counts: &mut [u32],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 0)] $g_cur: &mut [GBufferTexel],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 1)] $g_prev: &[GBufferTexel],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 2)] $res_in: &[Reservoir],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 3)] $res_out: &mut [Reservoir],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 4)] $res_prev: &[Reservoir],
        ) {
            if id.x >= $params.width || id.y >= $params.height {
                return;
            }
            let $scene = Scene { triangles, materials, nodes, lights };
            let ($x, $y) = (id.x, id.y);
            let $i = (id.y * $params.width + id.x) as usize;
            let mut $rays = 0u32;
            $body
            ray_counts[$i] = ray_counts[$i].wrapping_add($rays);
        }
    };
}

restir_kernel!(restir_primary, |scene,
                                params,
                                x,
                                y,
                                i,
                                rays,
                                g_cur,
                                g_prev,
                                res_in,
                                res_out,
                                res_prev,
                                accum| {
    g_cur[i] = restir::primary_hit(&scene, params, x, y, &mut rays);
});
restir_kernel!(restir_initial, |scene,
                                params,
                                x,
                                y,
                                i,
                                rays,
                                g_cur,
                                g_prev,
                                res_in,
                                res_out,
                                res_prev,
                                accum| {
    res_out[i] = restir::initial_pass(&scene, params, &g_cur[i], i as u32, &mut rays);
});
restir_kernel!(restir_temporal, |scene,
                                 params,
                                 x,
                                 y,
                                 i,
                                 rays,
                                 g_cur,
                                 g_prev,
                                 res_in,
                                 res_out,
                                 res_prev,
                                 accum| {
    res_out[i] = restir::temporal_pass(
        &scene, params, g_cur, g_prev, res_in, res_prev, x, y, &mut rays,
    );
});
restir_kernel!(restir_spatial, |scene,
                                params,
                                x,
                                y,
                                i,
                                rays,
                                g_cur,
                                g_prev,
                                res_in,
                                res_out,
                                res_prev,
                                accum| {
    res_out[i] = restir::spatial_pass(&scene, params, g_cur, res_in, x, y, &mut rays);
});
restir_kernel!(restir_shade, |scene,
                              params,
                              x,
                              y,
                              i,
                              rays,
                              g_cur,
                              g_prev,
                              res_in,
                              res_out,
                              res_prev,
                              accum| {
    let l = restir::shade_pass(&scene, params, &g_cur[i], &res_in[i], i as u32, &mut rays);
    // Non-finite results are dropped, as in every integrator's sample loop.
    let l = if l.is_finite() {
        l
    } else {
        crate::glam::Vec3::ZERO
    };
    accum[i] += l.extend(1.0);
});

/// The viewer's present pass: a fullscreen triangle...
#[spirv(vertex)]
pub fn present_vs(#[spirv(vertex_index)] vertex: i32, #[spirv(position)] position: &mut Vec4) {
    *position = fullscreen_triangle(vertex as u32);
}

/// ...whose fragments show the accumulation buffer.
#[spirv(fragment)]
pub fn present_fs(
    #[spirv(frag_coord)] coord: Vec4,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] params: &PresentParams,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] accum: &[Vec4],
    colour: &mut Vec4,
) {
    let x = (coord.x as u32).min(params.width - 1);
    let y = (coord.y as u32).min(params.height - 1);
    *colour = display_colour(accum[(y * params.width + x) as usize], params).extend(1.0);
}
