//! ReSTIR DI (Bitterli et al. 2020), one function per pass; each pass is its own GPU
//! dispatch, and the CPU backend runs the same functions pass by pass over all pixels.
//! 1. `primary_hit`: the G-buffer (position, normal, albedo, depth) from the camera.
//! 2. `initial_pass`: RIS over `candidates` light samples into a reservoir.
//! 3. `temporal_pass`: reproject into the previous frame, reject on depth/normal
//!    mismatch (disocclusion), cap the history's M, merge.
//! 4. `spatial_pass`: merge k neighbours within a radius that pass the same test.
//! 5. `shade_pass`: f · Le · G · W, plus emission seen directly and, with max_depth > 2
//!    (or a sky), the light of a bounce continued by NEE path tracing.
//!
//! Every reservoir a pass writes holds a sample its owner *sees*, or none (W = 0): the
//! initial pick is tested with a shadow ray; the temporal pass resamples the history's
//! light with visibility in the target (a shadow ray from here), so an occluded history
//! sample is simply not chosen; a spatial pass tests the neighbour's sample it picked. So
//! visibility is reused along with the sample, and the shade pass needs no shadow ray.
//! The temporal result is the next frame's history (see runner/src/restir.rs).
//!
//! Reuse is generalised RIS (Lin et al. 2022): each merged reservoir's sample is weighed
//! by an MIS weight saying how likely each reservoir was to produce it (confidence M times
//! its target): the balance heuristic between this frame and the history in the temporal
//! pass, defensive pairwise MIS between this pixel and each neighbour in the spatial pass.
//! Every pass is generic over `PLAIN`, the promise of a plain scene (all Lambertian,
//! untextured, no cut-outs, no map or sun; see `path::trace_path`): its variant carries
//! none of the other BSDFs', textures' or infinite lights' code.
//!
//! By default the GPU and the CPU run passes 1–2 as one dispatch (`primary_initial_pass`)
//! and the last spatial pass with 5 (`spatial_shade_pass`): each of those passes reads only
//! its own pixel of what the one before wrote, so fusing them changes no value; it saves
//! the G-buffer texel's and the reservoir's round trip through memory and a dispatch's ramp
//! (many-lights, 1080p, H100: 2.20 → 2.04 ms a frame). The temporal pass could join the
//! first dispatch too, but that kernel was slower than the two apart (1.82 against 1.41 ms,
//! unbiased). The split schedule (one dispatch per pass) times each pass.
//!
//! The two modes, chosen at run time (`RESTIR_UNBIASED`), differ only in those weights'
//! targets at other pixels: with visibility there (a shadow ray each: unbiased) or without
//! (biased: slightly dark where neighbours do not see what this pixel sees).
use crate::bsdf::{Bsdf, BSDF_DIFFUSE};
use crate::bvh::{surface_hit, SceneBuffers, SurfaceHit};
use crate::camera::jittered_ray;
use crate::env::{escaped_radiance, unsampled_radiance};
use crate::glam::Vec3;
use crate::integrators::path::{infinite_probability, trace_path, PathState, NEE};
use crate::integrators::ris::{
    initial_candidates, sample_visible, shade_reservoir, target_pdf_of, unshadowed_reservoir,
    ShadingPoint,
};
use crate::math::{div_rem, sin_cos, sqrt, vec3, PI};
use crate::reservoir::Reservoir;
use crate::rng::{pcg_hash, Rng};
use crate::types::{
    at, load, set_at, Camera, FrameParams, GBufferTexel, INVALID, RESTIR_HISTORY_VALID,
    RESTIR_TEMPORAL, RESTIR_UNBIASED, RESTIR_VISIBILITY_REUSE,
};

/// Most neighbours a spatial pass takes (the unbiased weights remember each one).
pub const MAX_SPATIAL_NEIGHBOURS: u32 = 16;
/// A pixel whose reservoir holds less than this many frames' candidates (disoccluded, the
/// first frames, or no temporal reuse) takes `disocclusion_neighbours` in a spatial pass.
const YOUNG_HISTORY_FRAMES: f32 = 4.0;
/// Neighbours are similar enough to reuse when normals are within ~25° and depths
/// within 10% (Bitterli et al.).
const NORMAL_THRESHOLD: f32 = 0.906;
const DEPTH_THRESHOLD: f32 = 0.1;

/// Random stream ids of the passes (see `pass_rng`); spatial pass i draws stream
/// `STREAM_SPATIAL + i`.
const STREAM_PRIMARY: u32 = 0;
const STREAM_INITIAL: u32 = 1;
const STREAM_TEMPORAL: u32 = 2;
const STREAM_SPATIAL: u32 = 3;
const STREAM_SHADE: u32 = 64;
const STREAM_LIGHT_CHOICE: u32 = 65;

/// The pixels that share the initial pass's light choices: one warp of ReSTIR's 16×8
/// workgroups (`entry::restir_kernel!`; a warp is 32 consecutive invocations, two rows of
/// 16), so that a warp's loads of its candidates' light, triangle and material each touch
/// one cache line instead of 32 (see `light_choice_rng`).
pub const LIGHT_TILE: (u32, u32) = (16, 2);
/// Mixed into the seed with a pass's stream id, so pass streams differ from the streams
/// of the other integrators.
const PASS_STREAM_SALT: u32 = 0x9e37;

/// The weighting the `restir-unbiased` cargo feature selects by default.
pub const UNBIASED_BY_DEFAULT: bool = cfg!(feature = "restir-unbiased");

fn unbiased(params: &FrameParams) -> bool {
    params.restir_flags & RESTIR_UNBIASED != 0
}

/// The random stream of pass `pass` at a pixel in this frame.
fn pass_rng(params: &FrameParams, pixel: u32, pass: u32) -> Rng {
    Rng::new(
        pixel,
        params.frame,
        params.sample_offset,
        params.seed ^ pcg_hash(pass + PASS_STREAM_SALT),
    )
}

fn has_hit(g: &GBufferTexel) -> bool {
    g.prim != INVALID
}

/// Pass 1: the camera ray of this pixel (jittered per frame) and what it hits.
pub fn primary_hit<const PLAIN: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    x: u32,
    y: u32,
    rays: &mut u32,
) -> GBufferTexel {
    let pixel = y * params.width + x;
    let mut rng = pass_rng(params, pixel, STREAM_PRIMARY);
    let ray = jittered_ray(&params.camera, params.width, params.height, x, y, &mut rng);
    let hit = scene.closest_hit::<PLAIN>(&ray, f32::INFINITY);
    *rays += 1;
    if !hit.is_hit() {
        return GBufferTexel {
            prim: INVALID,
            n: ray.dir.to_array(),
            ..Default::default()
        };
    }
    let cone_width = crate::camera::pixel_spread(&params.camera, params.height) * hit.t;
    let s = surface_hit(scene, &ray, &hit, cone_width);
    let bsdf = if PLAIN {
        Bsdf::diffuse(scene.material_of(hit.prim).albedo())
    } else {
        scene.bsdf(&s)
    };
    GBufferTexel {
        p: s.p.to_array(),
        depth: hit.t,
        n: s.ns.to_array(),
        prim: hit.prim,
        colour: bsdf.colour().to_array(),
        surface: GBufferTexel::pack_surface(s.front_face, bsdf.kind, bsdf.alpha),
    }
}

/// Whether the surface point (p, n) sees the light sample of reservoir `r` (one shadow ray).
fn sees<const PLAIN: bool>(
    scene: &SceneBuffers,
    p: Vec3,
    n: Vec3,
    r: &Reservoir,
    rays: &mut u32,
) -> bool {
    *rays += 1;
    sample_visible::<PLAIN>(scene, r, p, n)
}

/// Keep reservoir `r` (owned by the surface point p, n) only if its owner sees the sample;
/// else it keeps its M but no sample.
fn keep_if_visible<const PLAIN: bool>(
    scene: &SceneBuffers,
    r: &mut Reservoir,
    p: Vec3,
    n: Vec3,
    rays: &mut u32,
) {
    if r.has_sample() && r.w > 0.0 && !sees::<PLAIN>(scene, p, n, r, rays) {
        let m = r.m;
        *r = Reservoir::empty();
        r.m = m;
    }
}

/// Pass 2: RIS over the light candidates; the pick is tested for visibility (unless
/// `RESTIR_VISIBILITY_REUSE` is off), so that neither this pixel's later frames nor its
/// neighbours inherit a light it cannot see.
pub fn initial_pass<const PLAIN: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    g: &GBufferTexel,
    pixel: u32,
    rays: &mut u32,
) -> Reservoir {
    if !has_hit(g) {
        return Reservoir::empty();
    }
    let sp = shading_point::<PLAIN>(scene, g, vec3(params.camera.eye));
    let mut rng = pass_rng(params, pixel, STREAM_INITIAL);
    let mut choice = light_choice_rng(params, pixel);
    let mut r = initial_candidates::<PLAIN>(scene, params, &sp, &mut rng, &mut choice);
    r.finalize(r.m);
    if visibility_reuse(params) {
        keep_if_visible::<PLAIN>(scene, &mut r, sp.p, sp.n, rays);
    }
    r
}

/// The stream that chooses the initial candidates' lights at a pixel: the same for every
/// pixel of its `LIGHT_TILE`, so a warp's k-th candidates are all on one light (each at a
/// point of its own, weighed and kept by numbers of its own). Each pixel's candidates are
/// still independent draws from the light pdf, so its reservoir is what it was in
/// distribution; only pixels of one tile now share their 32 lights in a frame, which
/// reuse barely sees (a spatial neighbour lies in the tile ~1% of the time, history is of
/// other frames). Random lights per pixel made the candidate loop a gather of 32 cache
/// lines per load, its cost with many lights (many-lights, 1080p, H100: 0.35 ms of a
/// 0.75 ms pass for 31 candidates, against 0.28 ms on the Cornell box's two lights).
pub fn light_choice_rng(params: &FrameParams, pixel: u32) -> Rng {
    let (y, x) = div_rem(pixel, params.width); // width ≥ 1
    let tiles_x = params.width.div_ceil(LIGHT_TILE.0);
    let tile = (y / LIGHT_TILE.1) * tiles_x + x / LIGHT_TILE.0;
    pass_rng(params, tile, STREAM_LIGHT_CHOICE)
}

/// The surface of a G-buffer texel as the estimators see it, viewed from `eye` (the
/// camera that made that G-buffer).
fn shading_point<const PLAIN: bool>(
    scene: &SceneBuffers,
    g: &GBufferTexel,
    eye: Vec3,
) -> ShadingPoint {
    let p = vec3(g.p);
    ShadingPoint {
        p,
        n: vec3(g.n),
        wo: (eye - p).normalize(),
        bsdf: if PLAIN {
            Bsdf::diffuse(vec3(g.colour))
        } else {
            scene.gbuffer_bsdf(g)
        },
    }
}

fn visibility_reuse(params: &FrameParams) -> bool {
    params.restir_flags & RESTIR_VISIBILITY_REUSE != 0
}

/// Whether a surface of normal `n` at distance `depth` from an eye is close enough to
/// the surface `other` saw from the same eye to share light samples.
fn similar_surface(n: Vec3, depth: f32, other: &GBufferTexel) -> bool {
    has_hit(other)
        && n.dot(vec3(other.n)) >= NORMAL_THRESHOLD
        && (depth - other.depth).abs() <= DEPTH_THRESHOLD * depth
}

/// Whether the surface seen in `other` is close enough to `g`'s (same camera) to share
/// light samples.
pub fn similar(g: &GBufferTexel, other: &GBufferTexel) -> bool {
    has_hit(g) && similar_surface(vec3(g.n), g.depth, other)
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

/// The target of the reservoir owned by texel `g` for the sample of `r`, visibility
/// included: every merge weighs samples by its owner's target and (with visibility reuse)
/// every reservoir keeps only samples its owner sees, so this is zero exactly where that
/// reservoir could not have produced the sample. `seen` skips the shadow ray when the
/// sample is known (or, biased, assumed) to be visible there.
#[allow(clippy::too_many_arguments)] // the texel, its eye and the sample, each needed
fn target_with_visibility<const PLAIN: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    g: &GBufferTexel,
    eye: Vec3,
    r: &Reservoir,
    seen: bool,
    rays: &mut u32,
) -> f32 {
    if !has_hit(g) {
        return 0.0;
    }
    let sp = shading_point::<PLAIN>(scene, g, eye);
    let target = target_pdf_of::<PLAIN>(scene, params, r, &sp);
    if target <= 0.0
        || seen
        || !visibility_reuse(params)
        || sees::<PLAIN>(scene, sp.p, sp.n, r, rays)
    {
        target
    } else {
        0.0
    }
}

/// The target of another pixel's reservoir (texel `g`, seen from `eye`) for the sample of
/// `r`, as the MIS weights of a merge need it: with that pixel's visibility (one shadow ray)
/// when unbiased; the biased mode skips the ray and so credits that pixel with samples it
/// may not see (its one source of bias, slightly dark at shadow edges).
fn target_elsewhere<const PLAIN: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    g: &GBufferTexel,
    eye: Vec3,
    r: &Reservoir,
    rays: &mut u32,
) -> f32 {
    target_with_visibility::<PLAIN>(scene, params, g, eye, r, !unbiased(params), rays)
}

/// The share a/(a + b) of the first of two confidence-weighted targets a = Mᵢ p̂ᵢ(y) and
/// b = Mⱼ p̂ⱼ(y): the balance heuristic between two reservoirs (0 when neither has y).
fn balance(a: f32, b: f32) -> f32 {
    if a > 0.0 {
        a / (a + b)
    } else {
        0.0
    }
}

/// Pass 3: merge the reservoir of this surface point in the previous frame. The history's
/// light is a candidate only if this point sees it (visibility is part of the target here),
/// so a hidden history sample never displaces this frame's own.
/// `g` and `cur` are this pixel's texel and initial reservoir.
#[allow(clippy::too_many_arguments)]
pub fn temporal_pass<const PLAIN: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    g: &GBufferTexel,
    cur: Reservoir,
    g_prev: &[GBufferTexel],
    previous: &[Reservoir],
    pixel: u32,
    rays: &mut u32,
) -> Reservoir {
    let g = *g;
    let wanted = RESTIR_TEMPORAL | RESTIR_HISTORY_VALID;
    if params.restir_flags & wanted != wanted || !has_hit(&g) {
        return cur;
    }
    let Some((px, py)) = project(&params.prev_camera, params.width, params.height, vec3(g.p))
    else {
        return cur;
    };
    let prev_pixel = (py * params.width + px) as usize;
    let gp = load(g_prev, prev_pixel);
    // The previous G-buffer's depths are distances from the previous eye.
    let prev_depth = (vec3(g.p) - vec3(params.prev_camera.eye)).length();
    if !similar_surface(vec3(g.n), prev_depth, &gp) {
        return cur; // disocclusion: the surface was not visible there
    }
    let mut prev = load(previous, prev_pixel);
    prev.m = prev.m.min(params.temporal_cap * params.candidates as f32);

    let mut rng = pass_rng(params, pixel, STREAM_TEMPORAL);
    let eye = vec3(params.camera.eye);
    let target_prev = target_with_visibility::<PLAIN>(scene, params, &g, eye, &prev, false, rays);
    // Generalised RIS with the balance heuristic over the two reservoirs: each sample
    // weighed by how likely each reservoir was to produce it (Mᵢ p̂ᵢ, targets with
    // visibility: a reservoir never holds a sample its owner does not see).
    let cur_there = if cur.has_sample() && cur.w > 0.0 {
        let prev_eye = vec3(params.prev_camera.eye);
        target_elsewhere::<PLAIN>(scene, params, &gp, prev_eye, &cur, rays)
    } else {
        0.0
    };
    let m_cur = balance(cur.m * cur.target_pdf, prev.m * cur_there);
    let m_prev = balance(prev.m * prev.target_pdf, cur.m * target_prev);
    let mut out = Reservoir::empty();
    out.resample(&cur, cur.target_pdf, m_cur, rng.next_f32());
    out.resample(&prev, target_prev, m_prev, rng.next_f32());
    out.finalize(1.0);
    out
}

/// Pass 4: merge up to `spatial_neighbours` similar neighbours within `spatial_radius`.
/// Its result is shown (and read by a further spatial pass), never kept as history.
#[allow(clippy::too_many_arguments)]
pub fn spatial_pass<const PLAIN: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    gbuffer: &[GBufferTexel],
    input: &[Reservoir],
    x: u32,
    y: u32,
    rays: &mut u32,
) -> Reservoir {
    let pixel = y * params.width + x;
    spatial_reuse::<PLAIN>(
        scene,
        params,
        gbuffer,
        &load(gbuffer, pixel as usize),
        input,
        x,
        y,
        rays,
    )
}

/// The spatial pass of pixel (x, y), whose texel `g` is given (read once when shading
/// follows).
#[allow(clippy::too_many_arguments)]
fn spatial_reuse<const PLAIN: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    gbuffer: &[GBufferTexel],
    g: &GBufferTexel,
    input: &[Reservoir],
    x: u32,
    y: u32,
    rays: &mut u32,
) -> Reservoir {
    let pixel = y * params.width + x;
    let own = load(input, pixel as usize);
    let g = *g;
    if !has_hit(&g) {
        return own;
    }
    let eye = vec3(params.camera.eye);
    let sp = shading_point::<PLAIN>(scene, &g, eye);
    let mut rng = pass_rng(params, pixel, STREAM_SPATIAL + params.spatial_pass);
    // The neighbours: pixels in the disk about this pixel's centre that see a similar
    // surface (chosen by geometry alone, never by their samples).
    let mut used = [0u32; MAX_SPATIAL_NEIGHBOURS as usize];
    let mut n_used = 0usize;
    let k = neighbour_count(params, &own);
    let mut i = 0;
    while i < k {
        let r = params.spatial_radius * sqrt(rng.next_f32());
        let (s, c) = sin_cos(2.0 * PI * rng.next_f32());
        let nx = x as f32 + 0.5 + r * c;
        let ny = y as f32 + 0.5 + r * s;
        i += 1;
        if nx < 0.0 || ny < 0.0 || nx >= params.width as f32 || ny >= params.height as f32 {
            continue;
        }
        let q = ny as u32 * params.width + nx as u32;
        if q == pixel || !similar(&g, &load(gbuffer, q as usize)) {
            continue;
        }
        // SAFETY: n_used < k ≤ MAX_SPATIAL_NEIGHBOURS (`neighbour_count`), used's length.
        unsafe { set_at(&mut used, n_used, q) };
        n_used += 1;
    }
    let mut out = Reservoir::empty();
    let from_neighbour = pairwise_resample::<PLAIN>(
        scene, params, gbuffer, input, &used, n_used, &own, &sp, &mut out, &mut rng, rays,
    );
    out.finalize(1.0);
    // A neighbour's sample may be hidden from here: test it, so that what this pass writes
    // (shown now, or read by a further spatial pass) holds only samples seen from here.
    if from_neighbour && visibility_reuse(params) {
        keep_if_visible::<PLAIN>(scene, &mut out, sp.p, sp.n, rays);
    }
    out
}

/// Neighbours a spatial pass merges into reservoir `own`: `spatial_neighbours` where it
/// has a history of a few frames, more where it has not (RTXDI's disocclusion boost): each
/// unbiased neighbour costs a shadow ray, and a pixel with a long history gains little from
/// a second or third (many-lights, 1080p, H100: 0.34 ms per neighbour), while one without
/// history has only its own 32 candidates and needs its neighbours' to look like the rest.
fn neighbour_count(params: &FrameParams, own: &Reservoir) -> u32 {
    let young = own.m < YOUNG_HISTORY_FRAMES * params.candidates as f32;
    let k = if young {
        params
            .spatial_neighbours
            .max(params.disocclusion_neighbours)
    } else {
        params.spatial_neighbours
    };
    k.min(MAX_SPATIAL_NEIGHBOURS)
}

/// Spatial reuse: generalised RIS over this pixel's reservoir (the canonical one) and its
/// neighbours' with defensive pairwise MIS weights (Bitterli 2022, §9.1.3; Wyman et al.
/// 2023, §7): each neighbour is weighed against this pixel alone, with confidence M, so the
/// cost is linear in the neighbours and this pixel keeps at least its own share M_c/ΣM of
/// every sample (a neighbour's sample this pixel would almost never pick cannot dominate
/// its estimate, as it did with 1/M weights or a 1/Z normaliser). In the unbiased mode the
/// targets include visibility at each reservoir's owner, since a reservoir never holds a
/// sample its owner does not see: this pixel's sample at each neighbour takes a shadow
/// ray. Returns whether the kept sample came from a neighbour. The neighbours are the
/// first `n_neighbours` ≤ `MAX_SPATIAL_NEIGHBOURS` of `neighbours`.
#[allow(clippy::too_many_arguments)]
fn pairwise_resample<const PLAIN: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    gbuffer: &[GBufferTexel],
    input: &[Reservoir],
    neighbours: &[u32; MAX_SPATIAL_NEIGHBOURS as usize],
    n_neighbours: usize,
    own: &Reservoir,
    sp: &ShadingPoint,
    out: &mut Reservoir,
    rng: &mut Rng,
    rays: &mut u32,
) -> bool {
    let m_c = own.m;
    let mut m_sum = m_c;
    let mut j = 0;
    while j < n_neighbours {
        // SAFETY: j < n_neighbours ≤ MAX_SPATIAL_NEIGHBOURS, the array's length (above).
        m_sum += load(input, unsafe { at(neighbours, j) } as usize).m;
        j += 1;
    }
    let m_rest = m_sum - m_c;
    if m_sum <= 0.0 {
        return false;
    }
    let own_visible = own.has_sample() && own.w > 0.0;
    let eye = vec3(params.camera.eye);
    // This pixel's MIS weight for its own sample: its defensive share plus, from each
    // pair, the part the neighbour would not have produced.
    let mut mis_own = m_c / m_sum;
    let mut from_neighbour = false;
    let mut j = 0;
    while j < n_neighbours {
        // SAFETY: as above.
        let q = unsafe { at(neighbours, j) } as usize;
        j += 1;
        let neighbour = load(input, q);
        let share = neighbour.m / m_sum;
        // The neighbour's sample: its own target (it sees it) against this pixel's.
        let target_here = target_pdf_of::<PLAIN>(scene, params, &neighbour, sp);
        let mis = share * balance(m_rest * neighbour.target_pdf, m_c * target_here);
        from_neighbour |= out.resample(&neighbour, target_here, mis, rng.next_f32());
        if own_visible {
            let g = load(gbuffer, q);
            let there = target_elsewhere::<PLAIN>(scene, params, &g, eye, own, rays);
            mis_own += share * balance(m_c * own.target_pdf, m_rest * there);
        }
    }
    if out.resample(own, own.target_pdf, mis_own, rng.next_f32()) {
        from_neighbour = false;
    }
    from_neighbour
}

/// Passes 1 and 2 in one: pixel (x, y)'s G-buffer texel and its initial reservoir.
pub fn primary_initial_pass<const PLAIN: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    x: u32,
    y: u32,
    rays: &mut u32,
) -> (GBufferTexel, Reservoir) {
    let g = primary_hit::<PLAIN>(scene, params, x, y, rays);
    let r = initial_pass::<PLAIN>(scene, params, &g, y * params.width + x, rays);
    (g, r)
}

/// A frame's last spatial pass and the shade pass in one: pixel (x, y)'s radiance.
#[allow(clippy::too_many_arguments)]
pub fn spatial_shade_pass<const PLAIN: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    gbuffer: &[GBufferTexel],
    input: &[Reservoir],
    x: u32,
    y: u32,
    rays: &mut u32,
) -> Vec3 {
    let pixel = y * params.width + x;
    let g = load(gbuffer, pixel as usize);
    let r = spatial_reuse::<PLAIN>(scene, params, gbuffer, &g, input, x, y, rays);
    shade_pass::<PLAIN>(scene, params, &g, &r, pixel, rays)
}

/// Pass 5: the pixel's radiance for this frame. A non-finite result is dropped (0), as
/// every integrator's sample loop drops non-finite samples.
pub fn shade_pass<const PLAIN: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    g: &GBufferTexel,
    r: &Reservoir,
    pixel: u32,
    rays: &mut u32,
) -> Vec3 {
    let l = shaded_radiance::<PLAIN>(scene, params, g, r, pixel, rays);
    if l.is_finite() {
        l
    } else {
        Vec3::ZERO
    }
}

fn shaded_radiance<const PLAIN: bool>(
    scene: &SceneBuffers,
    params: &FrameParams,
    g: &GBufferTexel,
    r: &Reservoir,
    pixel: u32,
    rays: &mut u32,
) -> Vec3 {
    if !has_hit(g) {
        // A miss keeps its ray's direction where the normal would be.
        return escaped_radiance(scene, params, vec3(g.n));
    }
    let material = scene.material_of(g.prim);
    let mut radiance = if g.front() && material.is_emissive() {
        // The G-buffer keeps the point, not its barycentrics: found again for a texture.
        if PLAIN || material.emission_texture == INVALID {
            material.emission()
        } else {
            let tri = scene.triangle(g.prim);
            let (b1, b2) = tri.barycentrics(vec3(g.p));
            scene.emission_at(&tri, b1, b2)
        }
    } else {
        Vec3::ZERO
    };
    if params.max_depth < 2 {
        return radiance;
    }
    let eye = vec3(params.camera.eye);
    let sp = shading_point::<PLAIN>(scene, g, eye);
    radiance += if visibility_reuse(params) {
        // The passes keep only samples this pixel sees: no shadow ray needed.
        unshadowed_reservoir::<PLAIN>(scene, params, r, &sp)
    } else {
        shade_reservoir::<PLAIN>(scene, params, r, &sp, rays)
    };
    // Beyond the direct light of the emitters, the map and the sun: a bounce continued by
    // NEE path tracing gives the indirect light, at max_depth 2 a constant sky's light (as
    // NEE's bounce does), and what a glossy or specular surface reflects of the lights
    // (delta lobes are beyond light sampling; the continued path counts what they hit).
    let unsampled_sky = unsampled_radiance(params) != Vec3::ZERO;
    if params.max_depth > 2 || unsampled_sky || (!PLAIN && sp.bsdf.kind != BSDF_DIFFUSE) {
        let mut rng = pass_rng(params, pixel, STREAM_SHADE);
        let s = SurfaceHit::flat(sp.p, sp.n, g.front(), g.prim);
        let mut state = PathState::camera(crate::intersect::Ray::new(eye, -sp.wo));
        state.travelled = g.depth;
        if state.bounce(&s, &sp.bsdf, params, &mut rng) {
            // The reservoir sampled the map and the sun here: what the bounce finds of
            // them is NEE's to weigh (not counted again).
            state.env_sampled = infinite_probability::<PLAIN>(params) > 0.0;
            radiance += trace_path::<PLAIN, NEE>(scene, params, state, &mut rng, rays);
        }
    }
    radiance
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixels_of_a_warp_choose_the_same_lights_and_other_warps_others() {
        let params = FrameParams {
            width: 100,
            height: 50,
            ..Default::default()
        };
        let draws = |x: u32, y: u32| {
            let mut rng = light_choice_rng(&params, y * params.width + x);
            [rng.next_u32(), rng.next_u32(), rng.next_u32()]
        };
        // The tile at (16, 2): pixels 16..32 of rows 2 and 3.
        let tile = draws(16, 2);
        for (x, y) in [(31, 2), (16, 3), (31, 3), (20, 3)] {
            assert_eq!(draws(x, y), tile, "({x}, {y})");
        }
        for (x, y) in [(15, 2), (32, 2), (16, 1), (16, 4), (99, 49)] {
            assert_ne!(draws(x, y), tile, "({x}, {y})");
        }
        // And the pixel's own stream is another.
        let mut own = pass_rng(&params, 2 * params.width + 16, STREAM_INITIAL);
        assert_ne!([own.next_u32(), own.next_u32(), own.next_u32()], tile);
    }

    #[test]
    fn pixels_without_history_take_more_neighbours() {
        let params = FrameParams {
            candidates: 32,
            spatial_neighbours: 1,
            disocclusion_neighbours: 5,
            ..Default::default()
        };
        let with_m = |m: f32| Reservoir {
            m,
            ..Reservoir::empty()
        };
        // This frame's candidates only (disoccluded or first frame), then 3 and 4 frames.
        assert_eq!(neighbour_count(&params, &with_m(32.0)), 5);
        assert_eq!(neighbour_count(&params, &with_m(96.0)), 5);
        assert_eq!(neighbour_count(&params, &with_m(128.0)), 1);
        // More neighbours asked for every pixel are never fewer for a young one.
        let many = FrameParams {
            spatial_neighbours: 8,
            ..params
        };
        assert_eq!(neighbour_count(&many, &with_m(32.0)), 8);
        assert_eq!(neighbour_count(&many, &with_m(640.0)), 8);
    }
}
