//! SPIR-V entry points: fetch the invocation id, bounds-check, call the kernel function,
//! store. No logic lives here; the CPU backend calls the same kernel functions.
//!
//! Bindings (set 0) shared by every image kernel, mirrored in runner/src/gpu.rs:
//! 0 FrameParams, 1 triangles, 2 materials, 3 BVH nodes, 4 lights,
//! 5 accumulation (rgb = sum, a = sample count), 6 rays traced per pixel.
use crate::bvh::{BvhNode, Scene};
use crate::glam::{UVec3, Vec4};
use crate::integrators::{ao, path, PixelResult};
use crate::types::{FrameParams, Light, Material, Triangle};
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
            let scene = Scene { triangles, materials, nodes, lights };
            // A fn item or closure called in place: monomorphised, no indirect call.
            let r: PixelResult = ($pixel)(&scene, params, id.x, id.y);
            let i = (id.y * params.width + id.x) as usize;
            accum[i] += r.sum.extend(params.samples as f32);
            ray_counts[i] = ray_counts[i].wrapping_add(r.rays);
        }
    };
}

image_kernel!(ao_main, ao::render_pixel);
image_kernel!(pt_main, |s: &Scene, p: &FrameParams, x, y| path::render_pixel(s, p, x, y, path::BSDF));
image_kernel!(nee_main, |s: &Scene, p: &FrameParams, x, y| path::render_pixel(s, p, x, y, path::NEE));
image_kernel!(mis_main, |s: &Scene, p: &FrameParams, x, y| path::render_pixel(s, p, x, y, path::MIS));
