//! `#[repr(C)]` data shared by the host and the kernels. Only 4-byte scalars and arrays of
//! them (no `Vec3`), so Rust's layout, std430 and rust-gpu's offsets agree; the host checks
//! sizes with `const` asserts at the bottom.
#[cfg(not(target_arch = "spirv"))]
use bytemuck::{Pod, Zeroable};

use crate::glam::{UVec4, Vec3, Vec4};
use crate::math::vec3;
#[cfg(target_arch = "spirv")]
use spirv_std::arch::IndexUnchecked;

/// Marks "no triangle": a miss, or an empty slot.
pub const INVALID: u32 = u32::MAX;

/// One triangle: three vertices, the index of its material, its index in the light table
/// (`INVALID` unless its material emits) and of its shading attributes (`INVALID` when it
/// has no vertex normals or texture coordinates: flat, untextured).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable))]
pub struct Triangle {
    pub p0: [f32; 3],
    /// Below 2^31: the watertight test reads its top bit as a 0 (`intersect::edge_function`).
    pub material: u32,
    pub p1: [f32; 3],
    pub light: u32,
    pub p2: [f32; 3],
    pub shading: u32,
}

/// The top bit of `Triangle::shading`: the triangle's material has a cut-out mask, which
/// traversal tests at every hit (the rest of the field indexes its shading attributes,
/// which then exist: the mask is read at the hit's texture coordinates).
pub const ALPHA_TESTED: u32 = 1 << 31;
/// Materials a scene may have: `Triangle::material` stays below 2^31.
pub const MATERIALS_MAX: usize = 1 << 31;
/// The next bit: the mask is a coverage fraction (glTF alphaMode BLEND), not a cut-out. A
/// hit is solid with probability alpha: where alpha exceeds a hash of the hit's
/// barycentrics (hashed alpha testing, Wyman & McGuire 2017), so on average a surface of
/// alpha 0.3 passes 70% of the rays that meet it, camera, bounce and shadow rays alike.
pub const ALPHA_BLENDED: u32 = 1 << 30;

/// Where a read of `n` words from word `k` of a buffer the host built (a node's, a
/// triangle's) starts. On the GPU, without a bounds check: rust-gpu writes a slice index as
/// a compare and a branch out of the traversal loop, five of them per CWBVH node and three
/// per triangle; instead `k` is clamped so that all n words lie inside the buffer, one
/// instruction for the whole read (a clamp per word before 2026-12-05), and the words are
/// read with [`buffer_word`]. The CPU indexes as usual.
#[inline(always)]
pub fn buffer_read(words: &[UVec4], k: usize, n: usize) -> usize {
    #[cfg(target_arch = "spirv")]
    return k.min(words.len().max(n) - n);
    #[cfg(not(target_arch = "spirv"))]
    {
        let _ = (words, n);
        k
    }
}

/// Item `i` of a buffer the host built, at an index that the scene's own data gives (a
/// triangle's material or shading record, a light's triangle, a texel, a ReSTIR
/// neighbour). On the GPU, clamped into the buffer and read without a bounds check: a
/// checked index is a panic, which rust-gpu writes as a return from the kernel, and
/// spirv-opt as a flag tested on the way out of every loop around it — 1–6% of a kernel
/// (docs/PERFORMANCE.md, "Panics in the walk's loop"). The loaders keep every such index
/// inside its buffer, so the clamp never acts on a scene the host built, and the host
/// binds no buffer empty (one zeroed element at least). The CPU indexes as usual, and
/// panics on an index out of range.
#[inline(always)]
pub fn load<T: Copy>(items: &[T], i: usize) -> T {
    // SAFETY: the index is clamped below the buffer's length, which is at least 1.
    #[cfg(target_arch = "spirv")]
    return unsafe { *items.get_unchecked(i.min(items.len().max(1) - 1)) };
    #[cfg(not(target_arch = "spirv"))]
    items[i]
}

/// Item `i` of a fixed-size array in a kernel's own memory (a traversal stack, a list of
/// neighbours). On the GPU without a bounds check, for the reason [`load`] gives; the CPU
/// checks.
///
/// # Safety
/// `i < N`: the caller keeps its index below the length by construction.
#[inline(always)]
pub unsafe fn at<T: Copy, const N: usize>(items: &[T; N], i: usize) -> T {
    debug_assert!(i < N);
    #[cfg(target_arch = "spirv")]
    return unsafe { *items.index_unchecked(i) };
    #[cfg(not(target_arch = "spirv"))]
    items[i]
}

/// Item `i` of a fixed-size array set to `value`, as [`at`] reads one.
///
/// # Safety
/// `i < N`, as for [`at`].
#[inline(always)]
pub unsafe fn set_at<T, const N: usize>(items: &mut [T; N], i: usize, value: T) {
    debug_assert!(i < N);
    #[cfg(target_arch = "spirv")]
    unsafe {
        *items.index_unchecked_mut(i) = value;
    }
    #[cfg(not(target_arch = "spirv"))]
    {
        items[i] = value;
    }
}

/// Word `k` of a read that [`buffer_read`] placed.
#[inline(always)]
pub fn buffer_word(words: &[UVec4], k: usize) -> UVec4 {
    // SAFETY: `buffer_read` kept the read inside the buffer; the kernels never read a
    // buffer shorter than one node or triangle (the traversals return before reading an
    // empty scene's).
    #[cfg(target_arch = "spirv")]
    return unsafe { *words.get_unchecked(k) };
    #[cfg(not(target_arch = "spirv"))]
    words[k]
}

impl Triangle {
    /// 16-byte words a triangle takes in the triangle buffer, which the kernels read a word
    /// at a time (like the nodes: one 128-bit load per word whatever the driver makes of a
    /// struct's fields).
    pub const WORDS: usize = 3;

    /// Triangle `i` of a triangle buffer, in place (the CPU's AO bundles: one bounds check
    /// and no copy).
    #[cfg(not(target_arch = "spirv"))]
    #[inline(always)]
    pub fn get(words: &[UVec4], i: u32) -> &Self {
        let w = Self::WORDS * i as usize;
        bytemuck::from_bytes(bytemuck::cast_slice(&words[w..w + Self::WORDS]))
    }

    /// Triangle `i` of a triangle buffer read as words.
    pub fn read(words: &[UVec4], i: u32) -> Self {
        let w = buffer_read(words, Self::WORDS * i as usize, Self::WORDS);
        Self::from_words([
            buffer_word(words, w),
            buffer_word(words, w + 1),
            buffer_word(words, w + 2),
        ])
    }

    /// The triangle from its three 16-byte words.
    pub fn from_words(w: [UVec4; Self::WORDS]) -> Self {
        let xyz = |w: UVec4| {
            [
                f32::from_bits(w.x),
                f32::from_bits(w.y),
                f32::from_bits(w.z),
            ]
        };
        Self {
            p0: xyz(w[0]),
            material: w[0].w,
            p1: xyz(w[1]),
            light: w[1].w,
            p2: xyz(w[2]),
            shading: w[2].w,
        }
    }

    /// Index of the triangle's shading attributes (INVALID: none).
    pub fn shading_index(&self) -> u32 {
        if self.shading == INVALID {
            INVALID
        } else {
            self.shading & !(ALPHA_TESTED | ALPHA_BLENDED)
        }
    }

    /// Whether the mask traversal tests is a coverage fraction (`ALPHA_BLENDED`).
    pub fn alpha_blended(&self) -> bool {
        self.shading != INVALID && self.shading & ALPHA_BLENDED != 0
    }

    /// Whether traversal must test the material's cut-out mask at hits on this triangle.
    pub fn alpha_tested(&self) -> bool {
        self.shading != INVALID && self.shading & ALPHA_TESTED != 0
    }

    pub fn new(p0: Vec3, p1: Vec3, p2: Vec3, material: u32) -> Self {
        Self {
            p0: p0.to_array(),
            material,
            p1: p1.to_array(),
            light: INVALID,
            p2: p2.to_array(),
            shading: INVALID,
        }
    }
    pub fn vertices(&self) -> (Vec3, Vec3, Vec3) {
        (vec3(self.p0), vec3(self.p1), vec3(self.p2))
    }
    /// Unnormalised normal of the counter-clockwise winding; its length is twice the area.
    pub fn cross(&self) -> Vec3 {
        let (p0, p1, p2) = self.vertices();
        (p1 - p0).cross(p2 - p0)
    }
    /// Area and unit normal scale the cross product by its largest component first: its
    /// squared length overflows f32 for edges past ~1e9 and underflows for areas below
    /// ~1e-19, both of which real scenes have (a 2e10 ground, a 1e-15 fillet).
    pub fn area(&self) -> f32 {
        let c = self.cross();
        let s = c.abs().max_element();
        if s > 0.0 {
            0.5 * s * (c / s).length()
        } else {
            0.0
        }
    }
    pub fn normal(&self) -> Vec3 {
        let c = self.cross();
        (c / c.abs().max_element()).normalize()
    }
    /// Point at barycentrics (b1, b2): (1 - b1 - b2) p0 + b1 p1 + b2 p2.
    pub fn point(&self, b1: f32, b2: f32) -> Vec3 {
        let (p0, p1, p2) = self.vertices();
        p0 * (1.0 - b1 - b2) + p1 * b1 + p2 * b2
    }
    /// Barycentrics (b1, b2) of a point `p` on the triangle (the inverse of `point`).
    pub fn barycentrics(&self, p: Vec3) -> (f32, f32) {
        let (p0, p1, p2) = self.vertices();
        let (e1, e2, d) = (p1 - p0, p2 - p0, p - p0);
        let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
        let (d1, d2) = (d.dot(e1), d.dot(e2));
        let det = d11 * d22 - d12 * d12;
        if det == 0.0 || !det.is_finite() {
            return (0.0, 0.0);
        }
        ((d22 * d1 - d12 * d2) / det, (d11 * d2 - d12 * d1) / det)
    }
}

/// A surface's BSDF (`kind`: one of `bsdf::BSDF_*`) and its one-sided emitted radiance
/// (`Ke`). `albedo` is the diffuse colour (`Kd`; times the texture `albedo_texture` unless
/// that is `INVALID`), `specular` a conductor's reflectance at normal
/// incidence, `alpha` the GGX roughness α and `ior` the index of refraction of a
/// dielectric or of a coat.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable))]
pub struct Material {
    pub albedo: [f32; 3],
    pub albedo_texture: u32,
    pub emission: [f32; 3],
    pub kind: u32,
    pub specular: [f32; 3],
    pub alpha: f32,
    pub ior: f32,
    /// A cut-out mask (MTL `map_d`): texture whose alpha below ½ makes the surface a hole
    /// for every ray (tested during traversal); INVALID: opaque.
    pub opacity_texture: u32,
    /// A tangent-space normal map (glTF `normalTexture`, MTL `norm`; stored linear, see
    /// `TEXTURE_LINEAR8`) bending the shading normal; INVALID: none.
    pub normal_texture: u32,
    /// The normal map's strength: its x and y are scaled by this (glTF's `scale`); for a
    /// height map, the displacement of a texel of value 1 in scene units (MTL's `-bm`).
    pub normal_scale: f32,
    /// glTF's metallic-roughness texture (linear; green: roughness, blue: metalness, each
    /// times its factor: α = `alpha` × green², metalness = `metallic` × blue); INVALID: none.
    pub metal_rough_texture: u32,
    /// glTF's metallic factor, read with `metal_rough_texture`: where metalness ≥ ½ the
    /// surface is a conductor of reflectance `specular` (the base colour) × textures.
    pub metallic: f32,
    /// Emitted radiance is `emission` × this texture (glTF `emissiveTexture`, MTL `map_Ke`;
    /// sRGB colour); INVALID: `emission` alone.
    pub emission_texture: u32,
    /// What `normal_texture` holds: `NORMAL_MAP_TANGENT` or `NORMAL_MAP_HEIGHT`.
    pub normal_map_kind: u32,
}

/// `normal_texture` is a tangent-space normal map (x, y, z encoded in r, g, b).
pub const NORMAL_MAP_TANGENT: u32 = 0;
/// `normal_texture` is a height (bump) map: its red channel × `normal_scale` displaces the
/// surface along its normal, and the shading normal is the displaced surface's.
pub const NORMAL_MAP_HEIGHT: u32 = 1;

/// Metalness from which a texel of a metallic-roughness texture is a conductor.
pub const METAL_THRESHOLD: f32 = 0.5;

/// Index of refraction of glass, and of coats, when a file gives none.
pub const DEFAULT_IOR: f32 = 1.5;

impl Material {
    /// Lambertian diffuse `albedo`, emitting `emission` from its front side.
    pub fn new(albedo: Vec3, emission: Vec3) -> Self {
        Self {
            albedo: albedo.to_array(),
            albedo_texture: INVALID,
            emission: emission.to_array(),
            kind: crate::bsdf::BSDF_DIFFUSE,
            specular: [0.0; 3],
            alpha: 1.0,
            ior: DEFAULT_IOR,
            opacity_texture: INVALID,
            normal_texture: INVALID,
            normal_scale: 1.0,
            metal_rough_texture: INVALID,
            metallic: 0.0,
            emission_texture: INVALID,
            normal_map_kind: NORMAL_MAP_TANGENT,
        }
    }
    /// A metal: reflectance `specular` at normal incidence, GGX roughness `alpha` (0: mirror).
    pub fn conductor(specular: Vec3, alpha: f32) -> Self {
        Self {
            kind: crate::bsdf::BSDF_CONDUCTOR,
            specular: specular.to_array(),
            alpha,
            ..Self::new(Vec3::ZERO, Vec3::ZERO)
        }
    }
    /// Glass, water: a dielectric interface of index `ior`, GGX roughness `alpha`.
    pub fn dielectric(ior: f32, alpha: f32) -> Self {
        Self {
            kind: crate::bsdf::BSDF_DIELECTRIC,
            ior,
            alpha,
            ..Self::new(Vec3::ZERO, Vec3::ZERO)
        }
    }
    /// Plastic, varnish: diffuse `albedo` under a clear coat of index `ior`, roughness `alpha`.
    pub fn coated(albedo: Vec3, ior: f32, alpha: f32) -> Self {
        Self {
            kind: crate::bsdf::BSDF_COATED,
            ior,
            alpha,
            ..Self::new(albedo, Vec3::ZERO)
        }
    }
    pub fn albedo(&self) -> Vec3 {
        vec3(self.albedo)
    }
    /// Every texture the material refers to (INVALID where it has none of that kind).
    pub fn textures(&self) -> [u32; 5] {
        [
            self.albedo_texture,
            self.opacity_texture,
            self.normal_texture,
            self.metal_rough_texture,
            self.emission_texture,
        ]
    }
    pub fn emission(&self) -> Vec3 {
        vec3(self.emission)
    }
    pub fn is_emissive(&self) -> bool {
        self.emission[0] > 0.0 || self.emission[1] > 0.0 || self.emission[2] > 0.0
    }
}

/// Per-vertex shading attributes of a triangle (OBJ `vn`/`vt`, vertex colours): vertex k's
/// normal is `normals[3k..3k+3]`, its texture coordinates `uvs[2k..2k+2]` and its colour
/// `colours[k]` (linear RGB as an RGBE word, see `texture::rgbe_to_linear`); `flags` says
/// which of them the file gave (`SHADING_NORMALS`, `SHADING_UVS`, `SHADING_COLOURS`).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable))]
pub struct TriangleShading {
    pub normals: [f32; 9],
    pub uvs: [f32; 6],
    pub colours: [u32; 3],
    /// The corners' tangents (along +u), octahedron-encoded (`encode_unit`); with
    /// `SHADING_TANGENTS` they, not the triangle's dp/du, orient its normal map.
    pub tangents: [u32; 3],
    pub flags: u32,
}

pub const SHADING_NORMALS: u32 = 1;
pub const SHADING_UVS: u32 = 2;
pub const SHADING_COLOURS: u32 = 4;
/// The file gave tangents (glTF `TANGENT`).
pub const SHADING_TANGENTS: u32 = 8;
/// The bitangent is −(normal × tangent) (glTF's tangent w = −1: a mirrored mapping).
pub const SHADING_BITANGENT_FLIPPED: u32 = 16;

/// A unit vector in one word: its octahedral map (`sampling::octahedral_encode`) with 16
/// bits per coordinate; `decode_unit` gives it back to within ~1e-4.
pub fn encode_unit(v: Vec3) -> u32 {
    let (x, y) = crate::sampling::octahedral_encode(v);
    let q = |c: f32| ((c.clamp(-1.0, 1.0) * 0.5 + 0.5) * 65535.0 + 0.5) as u32;
    q(x) | (q(y) << 16)
}

/// The unit vector of `encode_unit`'s word.
pub fn decode_unit(w: u32) -> Vec3 {
    let c = |bits: u32| bits as f32 / 65535.0 * 2.0 - 1.0;
    crate::sampling::octahedral_decode(c(w & 0xffff), c(w >> 16))
}

impl TriangleShading {
    pub fn normal(&self, k: usize) -> Vec3 {
        Vec3::new(
            self.normals[3 * k],
            self.normals[3 * k + 1],
            self.normals[3 * k + 2],
        )
    }
    pub fn uv(&self, k: usize) -> crate::glam::Vec2 {
        crate::glam::Vec2::new(self.uvs[2 * k], self.uvs[2 * k + 1])
    }
    /// Texture coordinates at barycentrics (b1, b2), interpolated across the corners.
    pub fn uv_at(&self, b1: f32, b2: f32) -> crate::glam::Vec2 {
        self.uv(0) * (1.0 - b1 - b2) + self.uv(1) * b1 + self.uv(2) * b2
    }
    pub fn colour(&self, k: usize) -> Vec3 {
        crate::texture::rgbe_to_linear(self.colours[k]).truncate()
    }
    pub fn tangent(&self, k: usize) -> Vec3 {
        decode_unit(self.tangents[k])
    }
}

/// One texture in the texel buffer: `width × height` texels from `offset` on, row by row
/// from the top, one 32-bit word each in `format`'s low byte (`TEXTURE_FORMAT`); its
/// higher bits are the sampler (`TEXTURE_WRAP_U`, `TEXTURE_WRAP_V`, `TEXTURE_NEAREST`) and
/// the number of mip levels (`TEXTURE_LEVELS`), stored one after the other from `offset`
/// (`texture::level`). Textures of one image with different samplers share its texels.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable))]
pub struct TextureInfo {
    pub offset: u32,
    pub width: u32,
    pub height: u32,
    pub format: u32,
}

/// RGBA8, red in the low byte; colour sRGB-encoded, alpha linear.
pub const TEXTURE_SRGB8: u32 = 0;
/// Radiance's shared-exponent RGBE (red in the low byte, the exponent in the high one):
/// linear HDR colour in 32 bits, for environment maps.
pub const TEXTURE_RGBE: u32 = 1;
/// RGBA, 8 bits each, read as stored (data, not colour: normal maps).
pub const TEXTURE_LINEAR8: u32 = 2;
/// The bits of `TextureInfo::format` that are the texel format.
pub const TEXTURE_FORMAT: u32 = 0xff;
/// Where the wrap mode along u and along v is in `TextureInfo::format` (two bits each):
/// how a coordinate outside [0, 1] reads the texture (glTF's sampler `wrapS`, `wrapT`).
pub const TEXTURE_WRAP_U: u32 = 8;
pub const TEXTURE_WRAP_V: u32 = 10;
/// Wrap modes: the texture repeats (the default), its edge texels go on, or it repeats
/// mirrored every other time.
pub const WRAP_REPEAT: u32 = 0;
pub const WRAP_CLAMP: u32 = 1;
pub const WRAP_MIRROR: u32 = 2;
/// The texel a point falls in, unfiltered (glTF's `magFilter` NEAREST: pixel art, voxels).
pub const TEXTURE_NEAREST: u32 = 1 << 12;

/// Where the number of mip levels is in `TextureInfo::format` (5 bits; 0 and 1 both mean
/// the full-size image alone): each level half the one before (rounded down, at least 1),
/// box-filtered, so that a surface seen from afar reads its texture's average over the
/// pixel's footprint (`texture::sample_texture_footprint`).
pub const TEXTURE_LEVELS: u32 = 16;
pub const TEXTURE_LEVELS_MASK: u32 = 0x1f << TEXTURE_LEVELS;

/// The sampler bits of `TextureInfo::format`: wrap modes along u and v, and whether to read
/// the nearest texel instead of filtering.
pub const fn sampler(wrap_u: u32, wrap_v: u32, nearest: bool) -> u32 {
    let filter = if nearest { TEXTURE_NEAREST } else { 0 };
    wrap_u << TEXTURE_WRAP_U | wrap_v << TEXTURE_WRAP_V | filter
}

/// One emissive triangle in the light table, with its entry of the alias table that picks
/// lights in proportion to their power (Walker/Vose): slot `i` keeps itself with
/// probability `threshold`, else goes to `alias`. `pdf` is the probability that power
/// sampling selects this light.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable))]
pub struct Light {
    pub triangle: u32,
    pub pdf: f32,
    pub alias: u32,
    pub threshold: f32,
}

/// How next-event estimation picks a light triangle.
pub const LIGHT_SAMPLING_UNIFORM: u32 = 0;
pub const LIGHT_SAMPLING_POWER: u32 = 1;

/// Pinhole camera. `right` and `up` are pre-scaled by the half extent of the image plane
/// at distance 1 (tan(fov/2) · aspect and tan(fov/2)), `forward` is unit length.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable))]
pub struct Camera {
    pub eye: [f32; 3],
    pub _pad0: f32,
    pub forward: [f32; 3],
    pub _pad1: f32,
    pub right: [f32; 3],
    pub _pad2: f32,
    pub up: [f32; 3],
    pub _pad3: f32,
}

/// Everything a kernel needs besides the scene buffers, for one pass over the image.
/// (`Default` is all zeros but `env_texture`, which is `INVALID`: no environment map.)
#[repr(C)]
#[derive(Copy, Clone, Debug, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable))]
pub struct FrameParams {
    pub camera: Camera,
    /// Radiance returned by rays that leave the scene.
    pub sky: [f32; 3],
    pub width: u32,
    pub height: u32,
    /// Index of the frame in a sequence (ReSTIR); 0 for still renders.
    pub frame: u32,
    /// Global index of this pass's first sample: sample `s` of the pass draws the random
    /// stream of sample `sample_offset + s`, so any split into passes gives the same image.
    pub sample_offset: u32,
    /// Samples per pixel taken in this pass.
    pub samples: u32,
    pub seed: u32,
    pub ao_rays: u32,
    pub ao_distance: f32,
    /// Path segments, counted like Mitsuba's `max_depth`: 1 = emitters seen directly,
    /// 2 = plus direct lighting, ...
    pub max_depth: u32,
    /// `LIGHT_SAMPLING_UNIFORM` (the course) or `LIGHT_SAMPLING_POWER`.
    pub light_sampling: u32,
    /// Russian roulette starts after this many segments.
    pub rr_depth: u32,
    /// RIS / ReSTIR: light candidates per pixel.
    pub candidates: u32,
    /// ReSTIR: `RESTIR_*` flags.
    pub restir_flags: u32,
    /// ReSTIR: the previous frame's camera, for temporal reprojection.
    pub prev_camera: Camera,
    /// ReSTIR: cap of the temporal history, in multiples of `candidates`.
    pub temporal_cap: f32,
    /// ReSTIR: neighbours per spatial pass and their radius in pixels.
    pub spatial_neighbours: u32,
    pub spatial_radius: f32,
    /// ReSTIR: index of the current spatial pass (decorrelates their random streams).
    pub spatial_pass: u32,
    /// ReSTIR: number of spatial passes per frame.
    pub spatial_passes: u32,
    /// Environment map (an RGBE texture, equirectangular) that rays leaving the scene see,
    /// scaled by `sky`; `INVALID`: they see `sky` itself.
    pub env_texture: u32,
    /// Turn of the environment about the up axis, radians.
    pub env_rotation: f32,
    /// The environment's up axis: `ENV_UP_Y` or `ENV_UP_Z`.
    pub env_up: u32,
    /// Probability that next-event estimation samples the environment map (by its
    /// importance distribution) rather than an emissive triangle; 0 without a map.
    pub env_light_probability: f32,
    /// Probability that next-event estimation samples the sun; 0 without one.
    pub sun_light_probability: f32,
    /// Cosine of the sun's angular radius (its disk: directions within that of
    /// `sun_direction`).
    pub sun_cos_max: f32,
    /// ReSTIR: neighbours of a spatial pass for pixels with a short history (at least
    /// `spatial_neighbours`; see `restir::neighbour_count`).
    pub disocclusion_neighbours: u32,
    /// Unit direction towards the sun's centre.
    pub sun_direction: [f32; 3],
    /// AO: how a pixel's rays are spread, `AO_STRATIFIED` (the default) or
    /// `AO_INDEPENDENT` (here, where `sun_direction`'s padding was).
    pub ao_sampling: u32,
    /// Radiance of the sun's disk (zero: no sun).
    pub sun_radiance: [f32; 3],
    /// AO: the order the GPU's walk visits a node's children in, `AO_NEAR_FIRST` or
    /// `AO_FAR_FIRST` (here, where `sun_radiance`'s padding was).
    pub ao_order: u32,
}

#[cfg(not(target_arch = "spirv"))]
impl Default for FrameParams {
    fn default() -> Self {
        Self {
            env_texture: INVALID,
            ..Zeroable::zeroed()
        }
    }
}

/// AO rays in jittered strata, the same cell order in every pixel (`sampling::Strata`).
pub const AO_STRATIFIED: u32 = 0;
/// AO rays drawn independently from the whole hemisphere (incoherent: for measuring
/// traversal on rays that share nothing).
pub const AO_INDEPENDENT: u32 = 1;
/// AO walk order (`FrameParams::ao_order`), XORed into the ray's octant: a node's children
/// front to back along the ray (each ray's nearest boxes first), or back to front. Over
/// the rays' own walks, which visits fewer nodes depends on the scene: back to front saves
/// rays from inside a closed shell 13% of their nodes (the far wall blocks them, the
/// boxes around their origins hardly ever), but costs rays between grass blades 5%.
pub const AO_NEAR_FIRST: u32 = 0;
pub const AO_FAR_FIRST: u32 = 7;

pub const ENV_UP_Y: u32 = 0;
pub const ENV_UP_Z: u32 = 1;

/// ReSTIR: reuse the previous frame's reservoirs (needs `prev_camera` and history).
pub const RESTIR_TEMPORAL: u32 = 1;
/// ReSTIR: test the visibility of each pixel's initial pick before it is reused.
pub const RESTIR_VISIBILITY_REUSE: u32 = 2;
/// ReSTIR: the previous frame's buffers hold valid history (false on the first frame).
pub const RESTIR_HISTORY_VALID: u32 = 4;
/// ReSTIR: reuse's MIS weights include visibility at the other pixels (unbiased) instead
/// of skipping those shadow rays (biased). The runner sets it by `--restir-bias` (default:
/// the `restir-unbiased` feature); tests set it directly to check both.
pub const RESTIR_UNBIASED: u32 = 8;
/// ReSTIR: run each pass as its own dispatch (to time each) instead of the fused default.
/// Read by the host's schedule only (`runner/src/restir.rs`); the passes compute the same.
pub const RESTIR_SPLIT_PASSES: u32 = 16;

/// What the primary-hit pass leaves for the later ReSTIR passes. `prim == INVALID` marks a
/// pixel whose camera ray left the scene (`n` then holds the ray's direction, for the
/// environment).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable))]
pub struct GBufferTexel {
    pub p: [f32; 3],
    pub depth: f32,
    /// Shading normal (the G-buffer keeps no geometric one).
    pub n: [f32; 3],
    pub prim: u32,
    /// The BSDF's colour, textures applied (`Bsdf::colour`).
    pub colour: [f32; 3],
    /// Whether the ray hit the front side (bit 0), the BSDF's kind (bits 1–2) and its α as
    /// a 16-bit fraction (bits 16–31): what textures may change per point.
    pub surface: u32,
}

impl GBufferTexel {
    pub fn front(&self) -> bool {
        self.surface & 1 != 0
    }
    pub fn kind(&self) -> u32 {
        (self.surface >> 1) & 3
    }
    pub fn alpha(&self) -> f32 {
        (self.surface >> 16) as f32 / 65535.0
    }
    /// Pack `surface` (α is in [0, 1]: roughness²).
    pub fn pack_surface(front: bool, kind: u32, alpha: f32) -> u32 {
        let a = (alpha.clamp(0.0, 1.0) * 65535.0 + 0.5) as u32;
        front as u32 | (kind & 3) << 1 | a << 16
    }
}

#[cfg(not(target_arch = "spirv"))]
const _: () = {
    assert!(core::mem::size_of::<Triangle>() == 48);
    assert!(core::mem::size_of::<Material>() == 80);
    assert!(core::mem::size_of::<Camera>() == 64);
    assert!(core::mem::size_of::<FrameParams>() == 272);
    assert!(core::mem::size_of::<GBufferTexel>() == 48);
    assert!(core::mem::size_of::<Light>() == 16);
    assert!(core::mem::size_of::<TriangleShading>() == 88);
    assert!(core::mem::size_of::<TextureInfo>() == 16);
    assert!(core::mem::size_of::<FrameParams>().is_multiple_of(16));
};

/// Binary BVH node, 32 bytes. Interior: `count == 0` and the children are nodes `first` and
/// `first + 1`. Leaf: triangles `first .. first + count` (triangles are stored in leaf order).
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable))]
pub struct Bvh2Node {
    pub lo: [f32; 3],
    pub first: u32,
    pub hi: [f32; 3],
    pub count: u32,
}

/// obvhs's compressed 8-wide node (Ylitie et al. 2017), 80 bytes, byte-identical to
/// `obvhs::cwbvh::node::CwBvhNode` but read as 32-bit words so SPIR-V needs no 8-bit types.
/// Each `[u32; 2]` holds one byte per child slot: slots 0–3 in word 0, 4–7 in word 1, slot
/// k in bits 8·(k mod 4) .. 8·(k mod 4) + 8 (little-endian, as obvhs stores `[u8; 8]`).
/// Child k's box is `p + scale() · (min, max)` per axis, with the quantised bytes below.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable))]
pub struct CwBvhNode {
    /// Origin of the node's quantisation grid (its box's minimum corner).
    pub p: [f32; 3],
    /// Bits 0–7, 8–15, 16–23: the biased exponents e_x, e_y, e_z of the grid's cell size
    /// 2^(e − 127); bits 24–31: `imask`, bit k set when slot k holds an interior child.
    pub e_imask: u32,
    /// Index of the first interior child; they are stored contiguously in slot order.
    pub child_base_idx: u32,
    /// Index of the first triangle of the leaf children, also contiguous.
    pub primitive_base_idx: u32,
    /// One meta byte per slot; 0 = empty slot. Interior child: `0b001_11sss` = 24 + slot.
    /// Leaf child: bits 5–7 = triangle count in unary (`0b001`, `0b011`, `0b111`), bits 0–4 =
    /// its first triangle's offset from `primitive_base_idx` (0–23). See [`cwbvh_meta`].
    pub child_meta: [u32; 2],
    pub child_min_x: [u32; 2],
    pub child_max_x: [u32; 2],
    pub child_min_y: [u32; 2],
    pub child_max_y: [u32; 2],
    pub child_min_z: [u32; 2],
    pub child_max_z: [u32; 2],
}

impl Bvh2Node {
    /// 16-byte words a node takes in the node buffer, which the kernels read a word at a time.
    pub const WORDS: usize = 2;

    /// Node `i` of a node buffer read as words.
    pub fn read(nodes: &[UVec4], i: u32) -> Self {
        let w = Self::WORDS * i as usize;
        Self::from_words(nodes[w], nodes[w + 1])
    }

    /// The node from its two 16-byte words.
    pub fn from_words(a: UVec4, b: UVec4) -> Self {
        Self {
            lo: [
                f32::from_bits(a.x),
                f32::from_bits(a.y),
                f32::from_bits(a.z),
            ],
            first: a.w,
            hi: [
                f32::from_bits(b.x),
                f32::from_bits(b.y),
                f32::from_bits(b.z),
            ],
            count: b.w,
        }
    }
}

impl CwBvhNode {
    /// 16-byte words a node takes in the node buffer, which the kernels read a word at a time.
    pub const WORDS: usize = 5;

    /// Node `i` of a node buffer read as words.
    pub fn read(nodes: &[UVec4], i: u32) -> Self {
        let w = buffer_read(nodes, Self::WORDS * i as usize, Self::WORDS);
        Self::from_words([
            buffer_word(nodes, w),
            buffer_word(nodes, w + 1),
            buffer_word(nodes, w + 2),
            buffer_word(nodes, w + 3),
            buffer_word(nodes, w + 4),
        ])
    }

    /// The node from its five 16-byte words.
    pub fn from_words(w: [UVec4; Self::WORDS]) -> Self {
        Self {
            p: [
                f32::from_bits(w[0].x),
                f32::from_bits(w[0].y),
                f32::from_bits(w[0].z),
            ],
            e_imask: w[0].w,
            child_base_idx: w[1].x,
            primitive_base_idx: w[1].y,
            child_meta: [w[1].z, w[1].w],
            child_min_x: [w[2].x, w[2].y],
            child_max_x: [w[2].z, w[2].w],
            child_min_y: [w[3].x, w[3].y],
            child_max_y: [w[3].z, w[3].w],
            child_min_z: [w[4].x, w[4].y],
            child_max_z: [w[4].z, w[4].w],
        }
    }
    /// Cell size of the node's grid per axis, 2^(e − 127): the exponent byte moved into an
    /// f32's exponent field.
    pub fn scale(&self) -> Vec3 {
        let e = self.e_imask;
        Vec3::new(
            f32::from_bits((e & 0xff) << 23),
            f32::from_bits(((e >> 8) & 0xff) << 23),
            f32::from_bits(((e >> 16) & 0xff) << 23),
        )
    }
    /// Bit k set: slot k holds an interior child.
    pub fn imask(&self) -> u32 {
        self.e_imask >> 24
    }
}

/// A [`CwBvhNode`] as the GPU reads it: obvhs's five words, then each slot's hit-mask bits
/// (`slot_bits`: a leaf's triangles at their offsets, an interior child's bit 24 + slot,
/// 0 for an empty slot), so that a hit child costs the slab test one OR instead of the
/// bit decoding of its meta byte. `CwBvhSlotNode::of` (in `bvh`, beside the decoder it
/// uses) makes one from a [`CwBvhNode`].
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable))]
pub struct CwBvhSlotNode {
    pub node: CwBvhNode,
    pub slot_bits: [u32; 8],
}

impl CwBvhSlotNode {
    /// 16-byte words a node takes in the node buffer.
    pub const WORDS: usize = 7;

    /// Node `i` of a node buffer read as words.
    pub fn read(nodes: &[UVec4], i: u32) -> Self {
        let w = buffer_read(nodes, Self::WORDS * i as usize, Self::WORDS);
        let s = [buffer_word(nodes, w + 5), buffer_word(nodes, w + 6)];
        Self {
            node: CwBvhNode::from_words([
                buffer_word(nodes, w),
                buffer_word(nodes, w + 1),
                buffer_word(nodes, w + 2),
                buffer_word(nodes, w + 3),
                buffer_word(nodes, w + 4),
            ]),
            slot_bits: [
                s[0].x, s[0].y, s[0].z, s[0].w, s[1].x, s[1].y, s[1].z, s[1].w,
            ],
        }
    }
}

/// A [`CwBvhNode`] with its child planes decoded from bytes to the f32 offsets from `p`
/// they stand for (224 bytes instead of 80): the layout the CPU backend traverses (see
/// `bvh::TraversalNode`). A byte q of axis exponent e stands for q · 2^(e − 127), 8
/// significant bits times a power of two, so the f32 holds it exactly and the slab test
/// computes the same t from it as from the byte (images the same to the bit), without a
/// byte extract and conversion per plane. Child k's box is `p + (min, max)` per axis: the
/// planes of slots 0–3 in the first `Vec4` of each pair, 4–7 in the second.
#[repr(C)]
#[derive(Copy, Clone, Debug, Default, PartialEq)]
#[cfg_attr(not(target_arch = "spirv"), derive(Pod, Zeroable))]
pub struct CwBvhPlanes {
    /// The node's `p`.
    pub p: [f32; 3],
    /// Bit k set when slot k holds an interior child.
    pub imask: u32,
    pub child_base_idx: u32,
    pub primitive_base_idx: u32,
    /// The node's meta bytes, as in [`CwBvhNode::child_meta`].
    pub child_meta: [u32; 2],
    pub child_min_x: [Vec4; 2],
    pub child_max_x: [Vec4; 2],
    pub child_min_y: [Vec4; 2],
    pub child_max_y: [Vec4; 2],
    pub child_min_z: [Vec4; 2],
    pub child_max_z: [Vec4; 2],
}

impl CwBvhPlanes {
    /// 16-byte words a node takes in the node buffer.
    pub const WORDS: usize = 14;

    /// Node `i` of a node buffer, in place (the CPU's AO bundles: one bounds check and no
    /// copy, where `read` checks and copies each of the 14 words).
    #[cfg(not(target_arch = "spirv"))]
    #[inline(always)]
    pub fn get(nodes: &[UVec4], i: u32) -> &Self {
        let w = Self::WORDS * i as usize;
        bytemuck::from_bytes(bytemuck::cast_slice(&nodes[w..w + Self::WORDS]))
    }

    /// Node `i` of a node buffer read as words. Inlined: as a call it copied all 224 bytes
    /// out for every node visit (8% of the CPU backend's AO samples on grass-1m).
    #[inline(always)]
    pub fn read(nodes: &[UVec4], i: u32) -> Self {
        let w = Self::WORDS * i as usize;
        let plane = |k: usize| {
            let q = nodes[w + 2 + k];
            Vec4::new(
                f32::from_bits(q.x),
                f32::from_bits(q.y),
                f32::from_bits(q.z),
                f32::from_bits(q.w),
            )
        };
        let (head, bases) = (nodes[w], nodes[w + 1]);
        Self {
            p: [
                f32::from_bits(head.x),
                f32::from_bits(head.y),
                f32::from_bits(head.z),
            ],
            imask: head.w,
            child_base_idx: bases.x,
            primitive_base_idx: bases.y,
            child_meta: [bases.z, bases.w],
            child_min_x: [plane(0), plane(1)],
            child_max_x: [plane(2), plane(3)],
            child_min_y: [plane(4), plane(5)],
            child_max_y: [plane(6), plane(7)],
            child_min_z: [plane(8), plane(9)],
            child_max_z: [plane(10), plane(11)],
        }
    }

    /// `node` with its child bytes decoded.
    pub fn decoded(node: &CwBvhNode) -> Self {
        let scale = node.scale();
        let planes = |w: [u32; 2], s: f32| {
            let d = |k: usize| ((w[k / 4] >> (8 * (k % 4))) & 0xff) as f32 * s;
            [
                Vec4::new(d(0), d(1), d(2), d(3)),
                Vec4::new(d(4), d(5), d(6), d(7)),
            ]
        };
        Self {
            p: node.p,
            imask: node.imask(),
            child_base_idx: node.child_base_idx,
            primitive_base_idx: node.primitive_base_idx,
            child_meta: node.child_meta,
            child_min_x: planes(node.child_min_x, scale.x),
            child_max_x: planes(node.child_max_x, scale.x),
            child_min_y: planes(node.child_min_y, scale.y),
            child_max_y: planes(node.child_max_y, scale.y),
            child_min_z: planes(node.child_min_z, scale.z),
            child_max_z: planes(node.child_max_z, scale.z),
        }
    }
}

/// Decoding a CWBVH child's meta byte (see [`CwBvhNode::child_meta`]) and the traversal's
/// hit masks, which use the paper's layout: bits 24–31 = interior children hit (bit
/// 24 + the child's traversal priority), bits 0–23 = triangles of the leaf children hit
/// (bit = offset from `primitive_base_idx`).
pub mod cwbvh_meta {
    /// Hit-mask bits of interior children.
    pub const INTERIOR_HITS: u32 = 0xff00_0000;
    /// Hit-mask bits of leaf triangles.
    pub const TRIANGLE_HITS: u32 = 0x00ff_ffff;
    /// First hit-mask bit of interior children.
    pub const FIRST_INTERIOR_BIT: u32 = 24;

    /// Whether a (non-zero) meta byte is an interior child: bits 3 and 4 both set, which no
    /// leaf offset (< 24) has.
    pub fn is_interior(meta: u32) -> bool {
        meta & 0x18 == 0x18
    }
    /// The low five bits: 24 + slot for an interior child, the first triangle's offset for
    /// a leaf child.
    pub fn index(meta: u32) -> u32 {
        meta & 0x1f
    }
    /// A leaf child's triangles as consecutive bits (1, 3 or 7), before shifting by `index`.
    pub fn triangle_bits(meta: u32) -> u32 {
        meta >> 5
    }
}

#[cfg(not(target_arch = "spirv"))]
const _: () = {
    assert!(core::mem::size_of::<Bvh2Node>() == 16 * Bvh2Node::WORDS);
    assert!(core::mem::size_of::<CwBvhNode>() == 16 * CwBvhNode::WORDS);
    assert!(core::mem::size_of::<CwBvhPlanes>() == 16 * CwBvhPlanes::WORDS);
    assert!(core::mem::size_of::<CwBvhSlotNode>() == 16 * CwBvhSlotNode::WORDS);
    assert!(core::mem::size_of::<Triangle>() == 16 * Triangle::WORDS);
};

#[cfg(test)]
mod tests {
    use super::*;

    /// Words with distinct values, so a field read from the wrong word shows.
    fn words<const N: usize>() -> [UVec4; N] {
        core::array::from_fn(|i| {
            let b = 4 * i as u32;
            UVec4::new(b + 1, b + 2, b + 3, b + 4) * 0x0101_0101
        })
    }

    #[test]
    fn nodes_read_as_words_are_the_nodes_stored() {
        let w = words::<5>();
        let node = CwBvhNode::from_words(w);
        assert_eq!(bytemuck::cast::<CwBvhNode, [UVec4; 5]>(node), w);
        let w = words::<{ CwBvhPlanes::WORDS }>();
        let node = CwBvhPlanes::read(&w, 0);
        assert_eq!(
            bytemuck::cast::<CwBvhPlanes, [UVec4; CwBvhPlanes::WORDS]>(node),
            w
        );
        let w = words::<2>();
        let node = Bvh2Node::from_words(w[0], w[1]);
        assert_eq!(bytemuck::cast::<Bvh2Node, [UVec4; 2]>(node), w);
        let w = words::<3>();
        let tri = Triangle::from_words(w);
        assert_eq!(bytemuck::cast::<Triangle, [UVec4; 3]>(tri), w);
        let stored = [Triangle::default(), tri];
        assert_eq!(Triangle::read(bytemuck::cast_slice(&stored), 1), tri);
    }
}
