//! SPIR-V entry points: fetch the invocation id, bounds-check, call the kernel function,
//! store. No logic lives here; the CPU backend calls the same kernel functions.
//!
//! The bindings are those of `bindings.rs` (set 0: `bindings::SCENE`, set 1 of the ReSTIR
//! passes: `bindings::RESTIR`), written out as literals because SPIR-V attributes take no
//! constants; tests/bindings.rs checks the compiled module against the tables.
use crate::bvh::SceneBuffers;
use crate::glam::{UVec3, UVec4, Vec4};
use crate::integrators::{ao, path, restir, PixelResult};
use crate::present::{display_colour, fullscreen_triangle, PresentParams};
use crate::reservoir::Reservoir;
use crate::types::{
    at, set_at, FrameParams, GBufferTexel, Light, Material, TextureInfo, TriangleShading,
};
use spirv_std::arch::{atomic_i_add, workgroup_memory_barrier_with_group_sync, IndexUnchecked};
use spirv_std::memory::{Scope, Semantics};
use spirv_std::spirv;

/// ReSTIR's set 1 (`bindings::RESTIR`) as one value: this frame's G-buffer (written by the
/// primary pass) and the previous frame's, the reservoirs a pass reads, writes, and reads
/// as history (see `runner/src/restir.rs` for which buffer is which in each pass).
struct RestirBuffers<'a> {
    g_cur: &'a mut [GBufferTexel],
    g_prev: &'a [GBufferTexel],
    res_in: &'a [Reservoir],
    res_out: &'a mut [Reservoir],
    res_prev: &'a [Reservoir],
}

/// Declares one compute kernel over the image, in workgroups of `$wx`×`$wy` invocations (the
/// host's `gpu::pipelines::workgroup` says the same). The scene buffers (set 0) are bound as a
/// `SceneBuffers` named `$scene`, the accumulation as `$accum`; `$body` runs for pixel
/// (`$x`, `$y`) with index `$i` and adds the rays it traces to `$rays`. `restir: $b` also
/// binds ReSTIR's set 1, as a `RestirBuffers` named `$b`.
macro_rules! kernel {
    (threads($wx:literal, $wy:literal), $name:ident, |$scene:ident, $params:ident, $x:ident, $y:ident, $i:ident, $rays:ident, $accum:ident| $body:block) => {
        kernel!(@fn ($wx, $wy), $name, $scene, $params, $x, $y, $i, $rays, $accum, inside, { if !inside { return; } }, [], {}, $body);
    };
    (threads($wx:literal, $wy:literal), $name:ident, |$scene:ident, $params:ident, $x:ident, $y:ident, $i:ident, $rays:ident, $accum:ident, group: $memory:ident, $thread:ident, $inside:ident| $body:block) => {
        kernel!(@fn ($wx, $wy), $name, $scene, $params, $x, $y, $i, $rays, $accum, $inside, {}, [
            #[spirv(workgroup)] shared: &mut [u32; ao::group_words($wx * $wy)],
            #[spirv(local_invocation_index)] local: u32,
        ], {
            let $memory = shared;
            let $thread = local as usize;
        }, $body);
    };
    (threads($wx:literal, $wy:literal), $name:ident, |$scene:ident, $params:ident, $x:ident, $y:ident, $i:ident, $rays:ident, $accum:ident, restir: $restir:ident| $body:block) => {
        kernel!(@fn ($wx, $wy), $name, $scene, $params, $x, $y, $i, $rays, $accum, inside, { if !inside { return; } }, [
            #[spirv(storage_buffer, descriptor_set = 1, binding = 0)] g_cur: &mut [GBufferTexel],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 1)] g_prev: &[GBufferTexel],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 2)] res_in: &[Reservoir],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 3)] res_out: &mut [Reservoir],
            #[spirv(storage_buffer, descriptor_set = 1, binding = 4)] res_prev: &[Reservoir],
        ], {
            let mut $restir = RestirBuffers { g_cur, g_prev, res_in, res_out, res_prev };
        }, $body);
    };
    (@fn ($wx:literal, $wy:literal), $name:ident, $scene:ident, $params:ident, $x:ident, $y:ident, $i:ident, $rays:ident, $accum:ident, $inside:ident, {$($guard:tt)*}, [$($set1:tt)*], {$($bind_set1:tt)*}, $body:block) => {
        #[spirv(compute(threads($wx, $wy)))]
        #[allow(unused_variables, unused_mut)]
        pub fn $name(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] $params: &FrameParams,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] triangles: &[UVec4],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] materials: &[Material],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] nodes: &[UVec4],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] lights: &[Light],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] $accum: &mut [Vec4],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] ray_counts: &mut [u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] shading: &[TriangleShading],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] textures: &[TextureInfo],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 9)] texels: &[u32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 10)] env_distribution: &[f32],
            $($set1)*
        ) {
            let $inside = id.x < $params.width && id.y < $params.height;
            $($guard)*
            let $scene = SceneBuffers {
                triangles, materials, nodes, lights, shading, textures, texels, env_distribution,
            };
            $($bind_set1)*
            let ($x, $y) = (id.x, id.y);
            let $i = (id.y * $params.width + id.x) as usize;
            let mut $rays = 0u32;
            $body
            if $inside {
                ray_counts[$i] = ray_counts[$i].wrapping_add($rays);
            }
        }
    };
}

/// Declares the image kernel of one integrator: `$pixel(&scene, params, x, y)` returns the
/// sum of the pixel's samples, added to the accumulation with their count.
macro_rules! image_kernel {
    ($name:ident, $pixel:path) => {
        kernel!(threads(8, 8), $name, |scene,
                                       params,
                                       x,
                                       y,
                                       i,
                                       rays,
                                       accum| {
            let r: PixelResult = $pixel(&scene, params, x, y);
            accum[i] += r.sum.extend(params.samples as f32);
            rays += r.rays;
        });
    };
}

/// An AO workgroup's pool (`ao::GroupMemory`) in workgroup memory. (Implemented for the
/// array itself: a struct holding the pointer would be a variable of pointer type, which
/// SPIR-V's logical addressing forbids.)
///
/// Without bounds checks: the pool's words are computed from its layout, inside it by
/// construction (`ao::group_words`; `tests/gpu_cpu.rs` runs the same indices on the CPU,
/// checked), and a failed check is a return from the kernel inside the AO walk's loop
/// (see `CwbvhWalk::top` in `bvh`).
impl<const N: usize> ao::GroupMemory for [u32; N] {
    fn load(&self, word: usize) -> u32 {
        // SAFETY: word < N (above).
        unsafe { at(self, word) }
    }

    fn store(&mut self, word: usize, value: u32) {
        // SAFETY: word < N (above).
        unsafe { set_at(self, word, value) }
    }

    fn fetch_add(&mut self, word: usize, value: u32) -> u32 {
        // Relaxed: what a thread reads of the others' words it reads after a barrier.
        // SAFETY: word < N (above).
        unsafe {
            atomic_i_add::<u32, { Scope::Workgroup as u32 }, { Semantics::NONE.bits() }>(
                self.index_unchecked_mut(word),
                value,
            )
        }
    }

    fn barrier(&mut self) {
        workgroup_memory_barrier_with_group_sync();
    }
}

const _: () = assert!(
    ao::GROUP_WIDTH == 16 && ao::SMALL_GROUP == 16 * 8 && ao::WIDE_GROUP == 16 * 56,
    "the AO kernels' workgroups"
);

/// Declares an AO kernel: every thread of the `$wx`×`$wy` workgroup (the host's
/// `gpu::pipelines::ao_workgroup`), inside the image or not,
/// runs `ao::render_group_pixel`, as they share one pool of rays.
macro_rules! ao_kernel {
    ($name:ident, $plain:literal, $wx:literal, $wy:literal) => {
        kernel!(
            threads($wx, $wy),
            $name,
            |scene, params, x, y, i, rays, accum, group: memory, thread, inside| {
                let r = ao::render_group_pixel::<$plain, { $wx * $wy }, _>(
                    &scene, params, memory, thread, x, y, inside,
                );
                if inside {
                    accum[i] += r.sum.extend(params.samples as f32);
                    rays += r.rays;
                }
            }
        );
    };
}

ao_kernel!(ao_main, false, 16, 8);
ao_kernel!(ao_wide_main, false, 16, 56);
image_kernel!(pt_main, path::pt_pixel::<false>);
image_kernel!(nee_main, path::nee_pixel::<false>);
image_kernel!(mis_main, path::mis_pixel::<false>);
image_kernel!(ris_main, path::ris_pixel::<false>);
// For plain scenes: all Lambertian, untextured, no cut-outs (see `path::trace_path`).
ao_kernel!(ao_plain_main, true, 16, 8);
ao_kernel!(ao_plain_wide_main, true, 16, 56);
image_kernel!(pt_diffuse_main, path::pt_pixel::<true>);
image_kernel!(nee_diffuse_main, path::nee_pixel::<true>);
image_kernel!(mis_diffuse_main, path::mis_pixel::<true>);
image_kernel!(ris_diffuse_main, path::ris_pixel::<true>);

/// Declares one ReSTIR pass: `kernel!` in ReSTIR's workgroup shape (16×8, the host's
/// `gpu::pipelines::RESTIR_WORKGROUP`).
macro_rules! restir_kernel {
    ($name:ident, $($kernel:tt)*) => {
        kernel!(threads(16, 8), $name, $($kernel)*);
    };
}

/// Declares ReSTIR's five passes (`restir.rs`) and two fusions (`primary_initial_pass`,
/// `spatial_shade_pass`) under the given names, for any scene (`PLAIN` false) or for plain
/// ones (true).
#[rustfmt::skip] // one line of names per pass (rustfmt would stack the names, one a line)
macro_rules! restir_kernels {
    ($plain:literal, $primary:ident, $initial:ident, $temporal:ident, $spatial:ident, $shade:ident,
     $primary_initial:ident, $spatial_shade:ident) => {
        restir_kernel!($primary, |scene, params, x, y, i, rays, accum, restir: b| {
            b.g_cur[i] = restir::primary_hit::<$plain>(&scene, params, x, y, &mut rays);
        });
        restir_kernel!($initial, |scene, params, x, y, i, rays, accum, restir: b| {
            b.res_out[i] =
                restir::initial_pass::<$plain>(&scene, params, &b.g_cur[i], i as u32, &mut rays);
        });
        restir_kernel!($temporal, |scene, params, x, y, i, rays, accum, restir: b| {
            b.res_out[i] = restir::temporal_pass::<$plain>(
                &scene, params, &b.g_cur[i], b.res_in[i], b.g_prev, b.res_prev, i as u32, &mut rays,
            );
        });
        restir_kernel!($spatial, |scene, params, x, y, i, rays, accum, restir: b| {
            b.res_out[i] =
                restir::spatial_pass::<$plain>(&scene, params, b.g_cur, b.res_in, x, y, &mut rays);
        });
        restir_kernel!($shade, |scene, params, x, y, i, rays, accum, restir: b| {
            let (g, r) = (&b.g_cur[i], &b.res_in[i]);
            let l = restir::shade_pass::<$plain>(&scene, params, g, r, i as u32, &mut rays);
            accum[i] += l.extend(1.0);
        });
        restir_kernel!($primary_initial, |scene, params, x, y, i, rays, accum, restir: b| {
            let (g, r) = restir::primary_initial_pass::<$plain>(&scene, params, x, y, &mut rays);
            b.g_cur[i] = g;
            b.res_out[i] = r;
        });
        restir_kernel!($spatial_shade, |scene, params, x, y, i, rays, accum, restir: b| {
            let l = restir::spatial_shade_pass::<$plain>(
                &scene, params, b.g_cur, b.res_in, x, y, &mut rays,
            );
            accum[i] += l.extend(1.0);
        });
    };
}

restir_kernels!(
    false,
    restir_primary,
    restir_initial,
    restir_temporal,
    restir_spatial,
    restir_shade,
    restir_primary_initial,
    restir_spatial_shade
);
restir_kernels!(
    true,
    restir_primary_plain,
    restir_initial_plain,
    restir_temporal_plain,
    restir_spatial_plain,
    restir_shade_plain,
    restir_primary_initial_plain,
    restir_spatial_shade_plain
);

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
