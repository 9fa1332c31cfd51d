//! ReSTIR DI (Bitterli et al. 2020), one function per pass; each pass is its own GPU
//! dispatch, and the CPU backend runs the same functions pass by pass over all pixels.
//! 1. `primary_hit`: the G-buffer (position, normal, albedo, depth) from the camera.
//! 2. `initial_pass`: RIS over `candidates` light samples into a reservoir; optionally the
//!    pick's visibility is tested before anyone reuses it.
//! 3. `temporal_pass`: reproject into the previous frame, reject on depth/normal
//!    mismatch (disocclusion), cap the history's M, merge.
//! 4. `spatial_pass`: merge k neighbours within a radius that pass the same test.
//! 5. `shade_pass`: f · Le · G · V · W with one shadow ray, plus emission seen directly
//!    and, with max_depth > 2, the indirect light by NEE path tracing.
//! W is normalised by 1/M (biased) or, with `RESTIR_UNBIASED` (the `restir-unbiased`
//! feature's default), by 1/Z where Z counts only the M of reservoirs whose owners could
//! hold the sample (non-zero target there); unbiased mode does no visibility reuse.
use crate::bvh::{surface_hit, Scene, SurfaceHit};
use crate::camera::primary_ray;
use crate::glam::Vec3;
use crate::integrators::path::{trace_path, PathState, NEE};
use crate::integrators::ris::{initial_candidates, light_point, shade_reservoir, target_pdf_of};
use crate::math::{sin_cos, sqrt, vec3, PI};
use crate::reservoir::Reservoir;
use crate::rng::{pcg_hash, Rng};
use crate::types::{
    Camera, FrameParams, GBufferTexel, INVALID, RESTIR_HISTORY_VALID, RESTIR_TEMPORAL,
    RESTIR_UNBIASED, RESTIR_VISIBILITY_REUSE,
};

/// Most neighbours a spatial pass takes (the unbiased weights remember each one).
pub const MAX_SPATIAL_NEIGHBOURS: u32 = 16;
/// Neighbours are similar enough to reuse when normals are within ~25° and depths
/// within 10% (Bitterli et al.).
const NORMAL_THRESHOLD: f32 = 0.906;
const DEPTH_THRESHOLD: f32 = 0.1;

/// The weighting the `restir-unbiased` cargo feature selects by default.
pub const UNBIASED_BY_DEFAULT: bool = cfg!(feature = "restir-unbiased");

fn unbiased(params: &FrameParams) -> bool {
    params.restir_flags & RESTIR_UNBIASED != 0
}

/// The random stream of pass `pass` at a pixel in this frame.
fn pass_rng(params: &FrameParams, pixel: u32, pass: u32) -> Rng {
    Rng::new(pixel, params.frame, params.sample_offset, params.seed ^ pcg_hash(pass + 0x9e37))
}

fn has_hit(g: &GBufferTexel) -> bool {
    g.prim != INVALID
}

/// Pass 1: the camera ray of this pixel (jittered per frame) and what it hits.
pub fn primary_hit(scene: &Scene, params: &FrameParams, x: u32, y: u32, rays: &mut u32) -> GBufferTexel {
    let pixel = y * params.width + x;
    let mut rng = pass_rng(params, pixel, 0);
    let jx = rng.next_f32();
    let jy = rng.next_f32();
    let ray = primary_ray(&params.camera, params.width, params.height, x as f32 + jx, y as f32 + jy);
    let hit = scene.closest_hit(&ray, f32::INFINITY);
    *rays += 1;
    if !hit.is_hit() {
        return GBufferTexel { prim: INVALID, ..Default::default() };
    }
    let s = surface_hit(scene.triangles, &ray, &hit);
    GBufferTexel {
        p: s.p.to_array(),
        depth: hit.t,
        n: s.n.to_array(),
        prim: hit.prim,
        albedo: scene.material_of(hit.prim).albedo().to_array(),
        front: s.front_face as u32,
    }
}

/// Pass 2: RIS over the light candidates; with visibility reuse, an occluded pick keeps
/// its M but loses its weight, so neighbours do not inherit a shadowed light. Unbiased
/// mode skips it: it removes samples from a reservoir's support in a way that Z cannot
/// account for (neighbours would count candidates that could not have survived).
pub fn initial_pass(scene: &Scene, params: &FrameParams, g: &GBufferTexel, pixel: u32, rays: &mut u32) -> Reservoir {
    if !has_hit(g) {
        return Reservoir::empty();
    }
    let (p, n, albedo) = (vec3(g.p), vec3(g.n), vec3(g.albedo));
    let mut rng = pass_rng(params, pixel, 1);
    let mut r = initial_candidates(scene, params, p, n, albedo, &mut rng);
    if params.restir_flags & RESTIR_VISIBILITY_REUSE != 0 && !unbiased(params) && r.has_sample() {
        let (q, nq, _) = light_point(scene, r.triangle, r.b1, r.b2);
        *rays += 1;
        if !scene.visible(p, n, q, nq) {
            let m = r.m;
            r = Reservoir::empty();
            r.m = m;
        }
    }
    r.finalize(r.m);
    r
}

/// Whether the surface seen in `other` is close enough to `g`'s to share light samples.
pub fn similar(g: &GBufferTexel, other: &GBufferTexel) -> bool {
    has_hit(g)
        && has_hit(other)
        && vec3(g.n).dot(vec3(other.n)) >= NORMAL_THRESHOLD
        && (g.depth - other.depth).abs() <= DEPTH_THRESHOLD * g.depth
}

/// Pixel of `camera` (of a width × height image) that sees world point `p`, if any.
pub fn project(camera: &Camera, width: u32, height: u32, p: Vec3) -> Option<(u32, u32)> {
    let d = p - vec3(camera.eye);
    let z = d.dot(vec3(camera.forward));
    if z <= 0.0 {
        return None;
    }
    let (r, u) = (vec3(camera.right), vec3(camera.up));
    let ndc_x = d.dot(r) / (r.length_squared() * z);
    let ndc_y = d.dot(u) / (u.length_squared() * z);
    let fx = (ndc_x + 1.0) * 0.5 * width as f32;
    let fy = (1.0 - ndc_y) * 0.5 * height as f32;
    if fx < 0.0 || fy < 0.0 || fx >= width as f32 || fy >= height as f32 {
        return None;
    }
    Some((fx as u32, fy as u32))
}

/// Could the reservoir owned by texel `g` hold reservoir `r`'s sample? Every merge into a
/// reservoir weighs samples by its owner's target, so exactly when that target is
/// non-zero there. Only such owners' M count in Z. (Visibility is not part of it: samples
/// arriving by reuse are not re-tested at their new owner, so a reservoir can hold samples
/// its owner cannot see.)
fn could_produce(scene: &Scene, g: &GBufferTexel, r: &Reservoir) -> bool {
    has_hit(g) && target_pdf_of(scene, r, vec3(g.p), vec3(g.n), vec3(g.albedo)) > 0.0
}

/// Pass 3: merge the reservoir of this surface point in the previous frame.
pub fn temporal_pass(
    scene: &Scene,
    params: &FrameParams,
    g_cur: &[GBufferTexel],
    g_prev: &[GBufferTexel],
    current: &[Reservoir],
    previous: &[Reservoir],
    x: u32,
    y: u32,
) -> Reservoir {
    let pixel = (y * params.width + x) as usize;
    let cur = current[pixel];
    let g = g_cur[pixel];
    let wanted = RESTIR_TEMPORAL | RESTIR_HISTORY_VALID;
    if params.restir_flags & wanted != wanted || !has_hit(&g) {
        return cur;
    }
    let Some((px, py)) = project(&params.prev_camera, params.width, params.height, vec3(g.p)) else {
        return cur;
    };
    let prev_pixel = (py * params.width + px) as usize;
    let gp = g_prev[prev_pixel];
    if !similar(&g, &gp) {
        return cur; // disocclusion: the surface was not visible there
    }
    let mut prev = previous[prev_pixel];
    prev.m = prev.m.min(params.temporal_cap * params.candidates as f32);

    let mut rng = pass_rng(params, pixel as u32, 2);
    let (p, n, albedo) = (vec3(g.p), vec3(g.n), vec3(g.albedo));
    let mut out = Reservoir::empty();
    out.merge(&cur, cur.target_pdf, rng.next_f32());
    out.merge(&prev, target_pdf_of(scene, &prev, p, n, albedo), rng.next_f32());
    let mut z = out.m;
    if unbiased(params) && out.has_sample() {
        z = cur.m; // the pixel itself produced the sample's target: p̂ > 0 here
        if could_produce(scene, &gp, &out) {
            z += prev.m;
        }
    }
    out.finalize(z);
    out
}

/// Pass 4: merge up to `spatial_neighbours` similar neighbours within `spatial_radius`.
pub fn spatial_pass(
    scene: &Scene,
    params: &FrameParams,
    gbuffer: &[GBufferTexel],
    input: &[Reservoir],
    x: u32,
    y: u32,
) -> Reservoir {
    let pixel = y * params.width + x;
    let own = input[pixel as usize];
    let g = gbuffer[pixel as usize];
    if !has_hit(&g) {
        return own;
    }
    let (p, n, albedo) = (vec3(g.p), vec3(g.n), vec3(g.albedo));
    let mut rng = pass_rng(params, pixel, 3 + params.spatial_pass);
    let mut out = Reservoir::empty();
    out.merge(&own, own.target_pdf, rng.next_f32());
    let mut used = [0u32; MAX_SPATIAL_NEIGHBOURS as usize];
    let mut n_used = 0usize;
    let k = params.spatial_neighbours.min(MAX_SPATIAL_NEIGHBOURS);
    let mut i = 0;
    while i < k {
        // Uniform in the disk of the given radius.
        let r = params.spatial_radius * sqrt(rng.next_f32());
        let (s, c) = sin_cos(2.0 * PI * rng.next_f32());
        let nx = x as f32 + r * c;
        let ny = y as f32 + r * s;
        i += 1;
        if nx < 0.0 || ny < 0.0 || nx >= params.width as f32 || ny >= params.height as f32 {
            continue;
        }
        let q = ny as u32 * params.width + nx as u32;
        if q == pixel || !similar(&g, &gbuffer[q as usize]) {
            continue;
        }
        let neighbour = input[q as usize];
        out.merge(&neighbour, target_pdf_of(scene, &neighbour, p, n, albedo), rng.next_f32());
        used[n_used] = q;
        n_used += 1;
    }
    let mut z = out.m;
    if unbiased(params) && out.has_sample() {
        z = own.m;
        let mut j = 0;
        while j < n_used {
            let q = used[j] as usize;
            if could_produce(scene, &gbuffer[q], &out) {
                z += input[q].m;
            }
            j += 1;
        }
    }
    out.finalize(z);
    out
}

/// Pass 5: the pixel's radiance for this frame.
pub fn shade_pass(scene: &Scene, params: &FrameParams, g: &GBufferTexel, r: &Reservoir, pixel: u32, rays: &mut u32) -> Vec3 {
    if !has_hit(g) {
        return vec3(params.sky);
    }
    let material = scene.material_of(g.prim);
    let mut radiance = if g.front != 0 { material.emission() } else { Vec3::ZERO };
    if params.max_depth < 2 {
        return radiance;
    }
    let (p, n, albedo) = (vec3(g.p), vec3(g.n), vec3(g.albedo));
    radiance += shade_reservoir(scene, r, p, n, albedo, rays);
    if params.max_depth > 2 {
        // Indirect light: bounce off the primary hit and continue with NEE.
        let mut rng = pass_rng(params, pixel, 64);
        let s = SurfaceHit { p, n, front_face: g.front != 0, prim: g.prim };
        let mut state = PathState::camera(crate::intersect::Ray::new(p, n));
        if state.bounce(&s, albedo, params, &mut rng) {
            radiance += trace_path(scene, params, state, &mut rng, NEE, rays);
        }
    }
    radiance
}
