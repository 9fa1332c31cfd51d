//! Scenes: triangles with materials, the list of emitters, bounds and an optional default
//! camera. Loaded from OBJ + MTL with tobj (triangulated); `Kd` is the Lambertian albedo,
//! `Ke` the radiance emitted from the front (counter-clockwise) side.
use std::path::{Path, PathBuf};

use glam::{DVec3, Vec3};
use kernels::bvh::BvhNode;
use kernels::types::{Light, Material, TextureInfo, Triangle, TriangleShading};

use crate::bail;
use crate::error::{Error, Result};
use crate::options::SceneOptions;
use crate::scene_frame::SceneFrame;

/// Albedo of surfaces with no material (missing MTL or no `usemtl`).
pub const DEFAULT_ALBEDO: f32 = 0.8;

/// A camera stored in the scene file as a comment line:
/// `# camera: eye=X,Y,Z target=X,Y,Z up=X,Y,Z fov=DEG`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraHint {
    /// Positions in f64, as the file or the flags give them (see `scene_frame`).
    pub eye: DVec3,
    pub target: DVec3,
    pub up: Vec3,
    pub fov: f32,
}

#[derive(Clone, Debug, Default)]
pub struct Scene {
    /// Triangles in BVH leaf order; a pre-split triangle (`presplit`) once per slot.
    pub triangles: Vec<Triangle>,
    /// How many distinct triangles the scene has.
    pub triangle_count: usize,
    /// The BVH of the traversal compiled into the kernels.
    pub nodes: Vec<BvhNode>,
    /// `nodes` as the CPU's traversal reads them (`accel::host_nodes`), made on first use.
    pub(crate) host_nodes: std::sync::OnceLock<Vec<glam::UVec4>>,
    pub bvh_build_time: std::time::Duration,
    /// Reading, checking and building it all (`load`); zero for scenes made in code.
    pub load_time: std::time::Duration,
    pub materials: Vec<Material>,
    /// The emissive triangles, with the alias table for power sampling.
    pub lights: Vec<Light>,
    /// The file's camera, in the file's coordinates (`camera::camera_pose` maps it).
    pub camera: Option<CameraHint>,
    /// The file's coordinates to the kernels' (moved and scaled where the file's would
    /// cost precision; see `scene_frame`).
    pub frame: SceneFrame,
    /// A sun the file itself has (a glTF directional light); `--sun` overrides it.
    pub sun: Option<crate::gltf_lights::SceneSun>,
    pub warnings: Vec<String>,
    /// Vertex normals, texture coordinates and textures (see `SurfaceAttributes`).
    pub attributes: SurfaceAttributes,
}

/// What a surface has beyond its flat triangle and material: per-triangle shading
/// attributes (indexed by `Triangle::shading`) and the textures materials refer to.
#[derive(Clone, Debug, Default)]
pub struct SurfaceAttributes {
    pub shading: Vec<TriangleShading>,
    pub textures: Vec<TextureInfo>,
    /// All textures' texels, RGBA8 (see `kernels::texture`).
    pub texels: Vec<u32>,
    /// The environment map's importance distribution (see `kernels::env`).
    pub env_distribution: Vec<f32>,
    /// The opacity textures that hold coverage fractions (glTF BLEND), not cut-outs:
    /// traversal finds their surfaces solid with probability alpha (`ALPHA_BLENDED`).
    pub coverage_masks: Vec<u32>,
    /// The entries `textures::with_sampler` made: (texture, sampler bits) to entry.
    pub sampled: std::collections::HashMap<(u32, u32), u32>,
}

impl SurfaceAttributes {
    /// Give `triangle` its corners' normals, texture coordinates and/or linear colours (all
    /// three corners each, or none); nothing is stored when it has none of them. Every
    /// loader goes through here.
    pub fn attach(
        &mut self,
        triangle: &mut Triangle,
        normals: Option<[Vec3; 3]>,
        uvs: Option<[glam::Vec2; 3]>,
        colours: Option<[Vec3; 3]>,
    ) {
        if normals.is_none() && uvs.is_none() && colours.is_none() {
            return;
        }
        let mut shading = TriangleShading::default();
        if let Some(n) = normals {
            for (k, v) in n.iter().enumerate() {
                shading.normals[3 * k..3 * k + 3].copy_from_slice(&v.to_array());
            }
            shading.flags |= kernels::types::SHADING_NORMALS;
        }
        if let Some(uv) = uvs {
            for (k, v) in uv.iter().enumerate() {
                shading.uvs[2 * k..2 * k + 2].copy_from_slice(&v.to_array());
            }
            shading.flags |= kernels::types::SHADING_UVS;
        }
        if let Some(c) = colours {
            // An albedo factor: non-negative and finite (RGBE keeps 8 bits of the largest
            // channel, plenty for a colour).
            shading.colours = c.map(|v| {
                let v = if v.is_finite() {
                    v.max(Vec3::ZERO)
                } else {
                    Vec3::ZERO
                };
                crate::environment::linear_to_rgbe(v)
            });
            shading.flags |= kernels::types::SHADING_COLOURS;
        }
        triangle.shading = self.shading.len() as u32;
        self.shading.push(shading);
    }

    /// Give `triangle` (already given its attributes by `attach`) its corners' tangents
    /// (xyz along +u; w = ±1, the bitangent's side as glTF defines it), which then orient
    /// its normal map instead of its own dp/du. Tangents that are not finite unit-ish
    /// directions are not stored.
    pub fn attach_tangents(&mut self, triangle: &Triangle, tangents: [glam::Vec4; 3]) {
        let Some(shading) = self.shading.get_mut(triangle.shading as usize) else {
            return;
        };
        let directions = tangents.map(|t| t.truncate().normalize_or_zero());
        if directions
            .iter()
            .any(|d| *d == Vec3::ZERO || !d.is_finite())
        {
            return;
        }
        shading.tangents = directions.map(kernels::types::encode_unit);
        shading.flags |= kernels::types::SHADING_TANGENTS;
        if tangents[0].w < 0.0 {
            shading.flags |= kernels::types::SHADING_BITANGENT_FLIPPED;
        }
    }

    /// Whether `texture` is a single texel (the same value at every texture coordinate,
    /// so faces without coordinates can read it).
    pub fn is_constant(&self, texture: u32) -> bool {
        self.textures
            .get(texture as usize)
            .is_some_and(|t| t.width == 1 && t.height == 1)
    }

    /// Flag the triangles whose material has a cut-out mask for the traversal's test
    /// (`kernels::types::ALPHA_TESTED`), for every loader alike. A mask needs the hit's
    /// texture coordinates: a triangle without them stays opaque. Call after `check`.
    fn mark_cutouts(&self, triangles: &mut [Triangle], materials: &[Material]) {
        let invalid = kernels::types::INVALID;
        for t in triangles {
            t.shading = t.shading_index(); // the flags are derived here, never taken as given
            let mask = materials[t.material as usize].opacity_texture;
            let has_uvs = t.shading != invalid
                && self.shading[t.shading as usize].flags & kernels::types::SHADING_UVS != 0;
            if mask != invalid && has_uvs {
                t.shading |= kernels::types::ALPHA_TESTED;
                if self.coverage_masks.contains(&mask) {
                    t.shading |= kernels::types::ALPHA_BLENDED;
                }
            }
        }
    }

    /// Every index the kernels will follow stays inside its buffer.
    fn check(&self, triangles: &[Triangle], materials: &[Material]) -> Result<()> {
        let invalid = kernels::types::INVALID;
        if let Some(t) = triangles
            .iter()
            .find(|t| t.shading != invalid && t.shading_index() as usize >= self.shading.len())
        {
            bail!(
                "triangle refers to shading attributes {} of {}",
                t.shading_index(),
                self.shading.len()
            );
        }
        let texture_ok = |k: u32| k == invalid || (k as usize) < self.textures.len();
        if let Some(m) = materials
            .iter()
            .find(|m| m.textures().iter().any(|&k| !texture_ok(k)))
        {
            bail!(
                "material refers to textures {:?} of {}",
                m.textures(),
                self.textures.len()
            );
        }
        for t in &self.textures {
            let end = t.offset as u64 + kernels::texture::texel_count(t);
            if t.width == 0 || t.height == 0 || end > self.texels.len() as u64 {
                bail!(
                    "texture of {}x{} texels at {} is outside the texel buffer",
                    t.width,
                    t.height,
                    t.offset
                );
            }
        }
        Ok(())
    }
}

impl Scene {
    /// Build from triangles and materials: drop degenerate triangles (zero area or
    /// non-finite) with a warning, build the BVH, put the triangles in its leaf order, and
    /// collect the emitters.
    pub fn new(triangles: Vec<Triangle>, materials: Vec<Material>) -> Result<Self> {
        Self::with_attributes(triangles, materials, SurfaceAttributes::default())
    }

    /// `new`, for triangles and materials that refer to shading attributes and textures.
    pub fn with_attributes(
        mut triangles: Vec<Triangle>,
        mut materials: Vec<Material>,
        attributes: SurfaceAttributes,
    ) -> Result<Self> {
        let total = triangles.len();
        let frame = SceneFrame::fitting(corners(&triangles));
        if !frame.is_identity() {
            to_frame(&frame, &mut triangles, &mut materials);
        }
        let triangles: Vec<Triangle> = triangles.into_iter().filter(is_proper).collect();
        if let Some(far) = triangles
            .iter()
            .flat_map(|t| [t.p0, t.p1, t.p2])
            .flatten()
            .map(f32::abs)
            .find(|x| *x > MAX_COORDINATE)
        {
            bail!(
                "a triangle reaches coordinate {far:e}; at most {MAX_COORDINATE:e} is supported \
                 (the BVH build's f32 surface areas overflow beyond it): scale the scene down"
            );
        }
        let mut warnings = Vec::new();
        if triangles.len() < total {
            warnings.push(format!(
                "dropped {} degenerate triangle(s) (zero area)",
                total - triangles.len()
            ));
        }
        if triangles.is_empty() {
            bail!("the scene has no triangles (no faces, or only points and lines)");
        }
        let (triangles, duplicates) = without_duplicates(triangles, &materials);
        if duplicates > 0 {
            warnings.push(format!(
                "dropped {duplicates} duplicate triangle(s) (the same three vertices and material as another)"
            ));
        }
        // The watertight test reads a material index's top bit as its zero
        // (`kernels::intersect::edge_function`); no file can hold this many materials.
        if materials.len() > kernels::types::MATERIALS_MAX {
            bail!(
                "the scene has {} materials, more than 2^31",
                materials.len()
            );
        }
        if let Some(t) = triangles
            .iter()
            .find(|t| t.material as usize >= materials.len())
        {
            bail!(
                "triangle refers to material {} of {}",
                t.material,
                materials.len()
            );
        }
        attributes.check(&triangles, &materials)?;
        let mut triangles = triangles;
        attributes.mark_cutouts(&mut triangles, &materials);
        // Emitters keep one slot each: the light table holds every slot's emitter once.
        let bvh = crate::accel::build(&triangles, &|t| {
            !materials[t.material as usize].is_emissive()
        });
        crate::accel::check_depth(&bvh.nodes)?;
        if bvh.balanced {
            warnings.push(
                "the triangles overlap so much (slivers or stacks nested in one another) that \
                 the usual BVH would be too deep for the traversal or too slow to build; built \
                 a balanced one instead (traversal may be slower)"
                    .to_string(),
            );
        }
        let triangle_count = triangles.len();
        let mut triangles = crate::accel::reorder(&triangles, &bvh.order);
        let lights =
            crate::lights::build_light_table(&mut triangles, &bvh.order, &materials, &attributes);
        Ok(Self {
            triangles,
            triangle_count,
            nodes: bvh.nodes,
            host_nodes: Default::default(),
            bvh_build_time: bvh.build_time,
            load_time: std::time::Duration::ZERO,
            materials,
            lights,
            camera: None,
            frame,
            sun: None,
            warnings,
            attributes,
        })
    }

    /// The buffers as the kernels see them.
    pub fn kernel(&self) -> kernels::bvh::SceneBuffers<'_> {
        self.buffers(
            self.host_nodes
                .get_or_init(|| crate::accel::host_nodes(&self.nodes)),
        )
    }

    /// The buffers without the traversal's nodes, for host code that traces no ray: the
    /// CPU's nodes are decoded on first use (`kernel`), which a GPU run then never pays
    /// for (time, and 2.8× the nodes' memory). A ray traced in them meets nothing.
    pub fn untraced(&self) -> kernels::bvh::SceneBuffers<'_> {
        self.buffers(&[])
    }

    fn buffers<'a>(&'a self, nodes: &'a [glam::UVec4]) -> kernels::bvh::SceneBuffers<'a> {
        kernels::bvh::SceneBuffers {
            triangles: bytemuck::cast_slice(&self.triangles),
            materials: &self.materials,
            nodes,
            lights: &self.lights,
            shading: &self.attributes.shading,
            textures: &self.attributes.textures,
            texels: &self.attributes.texels,
            env_distribution: &self.attributes.env_distribution,
        }
    }

    /// Each distinct triangle once, in leaf order: a pre-split triangle's slots are copies
    /// of it, and no two distinct triangles are equal (`without_duplicates`).
    pub fn distinct_triangles(&self) -> Vec<Triangle> {
        let mut seen = rustc_hash::FxHashSet::default();
        self.triangles
            .iter()
            .filter(|t| seen.insert(bytemuck::bytes_of(*t)))
            .copied()
            .collect()
    }

    pub fn bounds(&self) -> (Vec3, Vec3) {
        bounds_of(corners(&self.triangles))
    }

    /// Whether every material is Lambertian and untextured and no vertex has a colour (the
    /// kernels have a faster variant for that).
    pub fn all_diffuse(&self) -> bool {
        let invalid = kernels::types::INVALID;
        self.materials.iter().all(|m| {
            m.kind == kernels::bsdf::BSDF_DIFFUSE && m.textures().iter().all(|&t| t == invalid)
        }) && self
            .attributes
            .shading
            .iter()
            .all(|a| a.flags & kernels::types::SHADING_COLOURS == 0)
    }

    /// Length of the bounding-box diagonal: the scene's natural length scale.
    pub fn extent(&self) -> f32 {
        let (lo, hi) = self.bounds();
        (hi - lo).length()
    }
}

/// Move `triangles` into `frame` (from the file's coordinates), and the bump maps'
/// displacements, which are in scene units, with them.
fn to_frame(frame: &SceneFrame, triangles: &mut [Triangle], materials: &mut [Material]) {
    let point = |p: [f32; 3]| frame.point(Vec3::from(p)).to_array();
    for t in triangles {
        (t.p0, t.p1, t.p2) = (point(t.p0), point(t.p1), point(t.p2));
    }
    for m in materials {
        if m.normal_map_kind == kernels::types::NORMAL_MAP_HEIGHT {
            m.normal_scale = frame.length(m.normal_scale);
        }
    }
}

/// Every corner of `triangles`.
pub fn corners(triangles: &[Triangle]) -> impl Iterator<Item = Vec3> + '_ {
    triangles
        .iter()
        .flat_map(|t| [t.p0, t.p1, t.p2].map(Vec3::from))
}

/// The box (lowest, highest corner) around `points`; inverted (+∞, −∞) when there are none.
pub fn bounds_of(points: impl Iterator<Item = Vec3>) -> (Vec3, Vec3) {
    points.fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(p), hi.max(p)),
    )
}

/// The triangles without exact duplicates: the same three vertices (in any order) and the
/// same non-emissive material as an earlier one. Stacks of coincident triangles (exporters
/// write them, and 20,000 of them made the BVH build take 16 s and 2,857 levels) add
/// nothing to the image; emissive duplicates are kept, since each one emits. Also returns
/// how many were dropped.
fn without_duplicates(triangles: Vec<Triangle>, materials: &[Material]) -> (Vec<Triangle>, usize) {
    let mut seen = rustc_hash::FxHashSet::default();
    seen.reserve(triangles.len());
    let total = triangles.len();
    let kept: Vec<Triangle> = triangles
        .into_iter()
        .filter(|t| {
            if materials
                .get(t.material as usize)
                .is_some_and(Material::is_emissive)
            {
                return true;
            }
            // The corners in sorted order (three compare-swaps: the generic sort was a
            // third of this loop's time on 1M triangles).
            let [mut a, mut b, mut c] = [t.p0, t.p1, t.p2].map(|p| p.map(f32::to_bits));
            if a > b {
                std::mem::swap(&mut a, &mut b);
            }
            if b > c {
                std::mem::swap(&mut b, &mut c);
            }
            if a > b {
                std::mem::swap(&mut a, &mut b);
            }
            seen.insert(([a, b, c], t.material))
        })
        .collect();
    let dropped = total - kept.len();
    (kept, dropped)
}

/// Whether a triangle spans an area, tested free of scale: its edges are divided by their
/// largest component first, so a ground of edge 2e10 (whose area overflows f32) and a
/// triangle of area 1e-30 (whose area underflows) are kept, and only collinear or
/// coincident vertices are dropped.
fn is_proper(t: &Triangle) -> bool {
    let (p0, p1, p2) = t.vertices();
    let (e1, e2) = (p1 - p0, p2 - p0);
    let scale = e1.abs().max(e2.abs()).max_element();
    if !(scale > 0.0 && scale.is_finite()) {
        return false;
    }
    let n = (e1 / scale).cross(e2 / scale);
    // The kernels take the normal from the unscaled cross product: it must be finite and
    // not flush to zero (edges up to ~1e19, areas down to ~1e-38).
    let c = t.cross();
    n != Vec3::ZERO && n.is_finite() && c != Vec3::ZERO && c.is_finite()
}

/// The default scene, built into the binary so it works wherever the binary runs.
pub const CORNELL_BOX_OBJ: &str = include_str!("../../assets/cornell_box.obj");
const CORNELL_BOX_MTL: &str = include_str!("../../assets/cornell_box.mtl");

/// The built-in Cornell box (assets/cornell_box.obj).
pub fn cornell_box() -> Result<Scene> {
    parse_obj(
        "cornell-box",
        CORNELL_BOX_OBJ,
        |_| load_mtl_text("cornell_box.mtl", CORNELL_BOX_MTL),
        |_| Err("the built-in Cornell box has no textures".into()),
    )
}

/// Largest radiance a material or the sky may have: 2²⁴ samples of it still sum to a
/// finite f32 (a Ke of 1e39 was read as infinity and gave an all-black image).
pub const MAX_RADIANCE: f32 = 1e20;

/// Largest vertex coordinate a scene may have: box surface areas (∝ extent²) and their
/// sums in the BVH builder stay finite in f32 below it (at 2e34 they overflowed and
/// obvhs built a corrupt tree, found by the fuzzer). The solar system in metres fits.
pub const MAX_COORDINATE: f32 = 1e15;

/// What people's OBJ and MTL files have that tobj does not read: a UTF-8 byte-order mark,
/// tabs between words (`usemtl<TAB>name`) and comments after data (`v 0 0 0 # top`).
/// Lines keep their numbers; whole-line comments (and the `# camera:` line) stay.
fn normalise(text: &str) -> String {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut out = String::with_capacity(text.len());
    for line in text.lines() {
        // Most lines have no tab: copy them as they are.
        let line = if line.contains('\t') {
            std::borrow::Cow::Owned(line.replace('\t', " "))
        } else {
            std::borrow::Cow::Borrowed(line)
        };
        let data = if line.trim_start().starts_with('#') {
            &line[..]
        } else {
            // A comment starts at a '#' after a space (names such as "m#2" keep theirs).
            match line.find(" #") {
                Some(i) => &line[..i],
                None => &line[..],
            }
        };
        out.push_str(data.trim_end());
        out.push('\n');
    }
    out
}

/// Whether `normalise` would change what tobj reads: a byte-order mark, a tab, or a
/// comment after data (a `#` after a space). Line endings and trailing blanks tobj reads
/// either way.
fn needs_normalising(text: &str) -> bool {
    text.starts_with('\u{feff}') || text.contains('\t') || text.contains(" #")
}

/// Parse MTL text (named `name` in messages) with tobj, after checking what tobj would
/// panic on or silently misread: colour lines (Ka, Kd, Ks, Ke, Tf) need three numbers, and
/// every number must be finite and radiances at most `MAX_RADIANCE`. Those are errors with
/// the line number (`Err`); a file tobj cannot read is `Ok(Err(..))`, a warning.
fn load_mtl_text(name: &str, text: &str) -> Result<tobj::MTLLoadResult> {
    let text = normalise(text);
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let key = words.next().unwrap_or("");
        let count = match key {
            "Ka" | "Kd" | "Ks" | "Ke" | "Tf" => 3,
            "Ns" | "Ni" | "d" | "Tr" | "Pr" | "Pm" => 1,
            _ => continue,
        };
        let values: Vec<&str> = words.take(count).collect();
        if values.len() < count || values.iter().any(|w| w.parse::<f32>().is_err()) {
            if count == 3 {
                return Ok(Err(tobj::LoadError::MaterialParseError));
            }
            continue;
        }
        for w in values {
            let x: f32 = w.parse().unwrap_or(f32::NAN);
            if !x.is_finite() || x.abs() > MAX_RADIANCE {
                bail!("{name}:{}: {key} value '{w}' is not a finite number of at most {MAX_RADIANCE:e}", i + 1);
            }
        }
    }
    Ok(tobj::load_mtl_buf(&mut text.as_bytes()))
}

/// Largest OBJ file read (~30M triangles) and largest MTL file: past these a file is not a
/// scene someone made but a device, a runaway export or an attack on our memory.
pub const MAX_OBJ_BYTES: u64 = 2 << 30;
pub const MAX_MTL_BYTES: u64 = 64 << 20;

/// Read a whole input file of at most `limit` bytes. Only regular files: a FIFO would block
/// forever and /dev/zero would never end.
pub fn read_input_file(path: &Path, limit: u64) -> std::io::Result<Vec<u8>> {
    use std::io::{Error, ErrorKind, Read};
    let md = std::fs::metadata(path)?;
    if !md.is_file() {
        return Err(Error::new(ErrorKind::InvalidInput, "not a regular file"));
    }
    let too_large = || {
        Error::new(
            ErrorKind::InvalidData,
            format!("larger than the limit of {limit} bytes"),
        )
    };
    if md.len() > limit {
        return Err(too_large());
    }
    let mut bytes = Vec::with_capacity(md.len() as usize);
    std::fs::File::open(path)?
        .take(limit + 1)
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_large()); // it grew while we read
    }
    Ok(bytes)
}

fn load_mtl_file(path: &Path) -> Result<tobj::MTLLoadResult> {
    match read_input_file(path, MAX_MTL_BYTES) {
        Ok(bytes) => load_mtl_text(
            &path.display().to_string(),
            &String::from_utf8_lossy(&bytes),
        ),
        Err(_) => Ok(Err(tobj::LoadError::OpenFileFailed)),
    }
}

/// Load an OBJ file (and the MTL files it names, relative to it).
pub fn load_obj(path: &Path) -> Result<Scene> {
    if let Ok(md) = std::fs::metadata(path) {
        let needed = md.len() as f64 * crate::memory::BYTES_PER_OBJ_BYTE;
        crate::memory::check_scene(&format!("scene '{}'", path.display()), needed)?;
    }
    let bytes = match read_input_file(path, MAX_OBJ_BYTES) {
        Ok(bytes) => bytes,
        Err(e) => bail!("cannot read scene '{}': {e}", path.display()),
    };
    let text = String::from_utf8_lossy(&bytes);
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let name = path.display().to_string();
    let notes = std::cell::RefCell::new(Vec::new());
    let load_texture = |map: &str| {
        let tried = crate::textures::candidate_paths(&dir, map);
        match tried.iter().find(|p| p.is_file()) {
            Some(path) => crate::textures::decode(path)
                .map_err(|e| format!("cannot read '{}': {e}", path.display())),
            None => Err(format!(
                "not found; tried {}",
                tried
                    .iter()
                    .map(|p| format!("'{}'", p.display()))
                    .collect::<Vec<_>>()
                    .join(", ")
            )),
        }
    };
    let mut scene = parse_obj(
        &name,
        &text,
        |mtllib| load_mtl_files(&name, &dir, mtllib, &mut notes.borrow_mut()),
        load_texture,
    )?;
    scene.warnings.extend(notes.into_inner());
    Ok(scene)
}

/// The materials of an `mtllib` line, which may name several files (`mtllib a.mtl b.mtl`;
/// a single name with spaces is tried first). Each file is looked up relative to the OBJ and
/// then, as Blender does, by its base name next to it; one that is found nowhere is a note
/// naming the paths tried. The materials of all files found are merged.
fn load_mtl_files(
    obj: &str,
    dir: &Path,
    mtllib: &Path,
    notes: &mut Vec<String>,
) -> Result<tobj::MTLLoadResult> {
    let names: Vec<std::path::PathBuf> = if dir.join(mtllib).is_file() {
        vec![mtllib.to_path_buf()]
    } else {
        mtllib
            .to_string_lossy()
            .split_whitespace()
            .map(std::path::PathBuf::from)
            .collect()
    };
    // An empty table of tobj's own map type, to merge into.
    let Ok((mut materials, mut index)) = tobj::load_mtl_buf(&mut "".as_bytes()) else {
        return Ok(Err(tobj::LoadError::MaterialParseError));
    };
    let mut found = false;
    for name in &names {
        // The base name after a slash or a backslash (Windows exports name their MTL so).
        let text = name.to_string_lossy();
        let base = text.rsplit(['/', '\\']).next().filter(|b| !b.is_empty());
        let tried = [Some(dir.join(name)), base.map(|b| dir.join(b))];
        let Some(file) = tried.iter().flatten().find(|p| p.is_file()) else {
            let paths: Vec<String> = tried
                .iter()
                .flatten()
                .map(|p| format!("'{}'", p.display()))
                .collect();
            notes.push(format!(
                "{obj}: mtllib '{}' not found (tried {})",
                name.display(),
                paths.join(" and ")
            ));
            continue;
        };
        match load_mtl_file(file)? {
            Ok((more, more_index)) => {
                let offset = materials.len();
                index.extend(more_index.into_iter().map(|(k, v)| (k, v + offset)));
                materials.extend(more);
                found = true;
            }
            Err(e) => return Ok(Err(e)),
        }
    }
    Ok(if found {
        Ok((materials, index))
    } else {
        Err(tobj::LoadError::OpenFileFailed)
    })
}

/// Parse OBJ text with, optionally, the text of the MTL file it refers to (whatever name
/// it gives): the loader without a file system, for fuzzing and tests.
pub fn parse_obj_text(name: &str, obj: &str, mtl: Option<&str>) -> Result<Scene> {
    parse_obj(
        name,
        obj,
        |_| match mtl {
            Some(text) => load_mtl_text("fuzz.mtl", text),
            None => Ok(Err(tobj::LoadError::OpenFileFailed)),
        },
        |_| Err("no texture files when parsing text".into()),
    )
}

/// Parse OBJ text named `name` (for messages); `load_mtl` resolves `mtllib` names and
/// `load_texture` the file names of `map_Kd` statements.
fn parse_obj(
    name: &str,
    text: &str,
    load_mtl: impl Fn(&Path) -> Result<tobj::MTLLoadResult>,
    load_texture: impl Fn(&str) -> std::result::Result<image::RgbaImage, String>,
) -> Result<Scene> {
    let camera = parse_camera_hint(name, text)?;
    // Most files need none of `normalise`'s repairs: no second copy of a large text then.
    let repaired = needs_normalising(text).then(|| normalise(text));
    let text = repaired.as_deref().unwrap_or(text);
    let (lo, hi) = check_lines(name, text)?;
    // Far from the origin: moved there in f64, before tobj rounds the positions to f32.
    let centre = crate::scene_frame::far_centre(lo.as_dvec3(), hi.as_dvec3());
    let centred = (centre != DVec3::ZERO).then(|| centre_obj_vertices(text, centre));
    let text = centred.as_deref().unwrap_or(text);
    // An MTL error that must stop the load (it names its line) travels past tobj here.
    let mtl_error = std::cell::RefCell::new(None);
    let load_mtl = |path: &Path| match load_mtl(path) {
        Ok(result) => result,
        Err(e) => {
            mtl_error.borrow_mut().get_or_insert(e);
            Err(tobj::LoadError::MaterialParseError)
        }
    };

    // Polygons come back whole and are split by `triangulate_polygon` (tobj's fan from the
    // first corner turns a many-sided cap into slivers that nest a BVH 40 levels deep).
    let options = tobj::LoadOptions {
        triangulate: false,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let hoisted = hoist_mtllib(text);
    let (models, mtl_result) = tobj::load_obj_buf(&mut hoisted.as_bytes(), &options, load_mtl)
        .map_err(|e| Error(format!("cannot load scene '{name}': {e}")))?;
    if let Some(e) = mtl_error.into_inner() {
        return Err(e);
    }
    let mut warnings = Vec::new();
    let mut attributes = SurfaceAttributes::default();
    // Each material's texture coordinate map (`-s`, `-o`): its maps', when they agree.
    let mut uv_maps: Vec<glam::Affine2> = Vec::new();
    let mut materials: Vec<Material> = match mtl_result {
        Ok(mtls) => {
            warnings.extend(unknown_material_warnings(name, text, &mtls));
            // What no material kind here reads: one warning per key, with a count.
            let mut ignored: Vec<(String, usize)> = Vec::new();
            for key in mtls.iter().flat_map(ignored_mtl_keys) {
                match ignored.iter_mut().find(|(k, _)| *k == key) {
                    Some((_, n)) => *n += 1,
                    None => ignored.push((key, 1)),
                }
            }
            for (key, n) in ignored {
                warnings.push(format!(
                    "materials of '{name}': {key} in {n} material(s) is not supported yet; ignored"
                ));
            }
            // Textures by file name and use: one decode however many materials share one;
            // each with whether it is a height (bump) map rather than a normal map.
            let mut loaded: std::collections::HashMap<String, Option<(u32, bool)>> =
                Default::default();
            // A map statement's texture, read through its sampler, and whether it is a
            // height map.
            let mut map = |statement: Option<&crate::textures::MapStatement>,
                           use_: MapUse,
                           key: &str,
                           material: &str,
                           otherwise: &str| {
                let statement = statement.filter(|s| !s.file.is_empty())?;
                let file = &statement.file;
                let tag = match use_ {
                    MapUse::Colour => "",
                    MapUse::Mask => "\0mask",
                    MapUse::Normal | MapUse::MaybeNormal => "\0normal",
                };
                let (texture, is_height) = (*loaded.entry(format!("{file}{tag}")).or_insert_with(|| match load_texture(file) {
                    Ok(image) => Some(match use_ {
                        MapUse::Colour => (crate::textures::add(&mut attributes, &image), false),
                        MapUse::Mask => (
                            crate::textures::add(&mut attributes, &crate::textures::cutout_mask(image)),
                            false,
                        ),
                        // A height map: its red channel, read linear.
                        MapUse::MaybeNormal if !crate::textures::is_normal_map(&image) => {
                            (crate::textures::add_linear(&mut attributes, &image), true)
                        }
                        MapUse::Normal | MapUse::MaybeNormal => {
                            (crate::textures::add_linear(&mut attributes, &image), false)
                        }
                    }),
                    Err(why) => {
                        warnings.push(format!(
                            "texture '{file}' ({key} of material '{material}') not loaded: {why}; {otherwise}"
                        ));
                        None
                    }
                }))?;
                // `-clamp on`: the texture's edges go on outside [0, 1].
                let wrap = if statement.clamp {
                    kernels::types::WRAP_CLAMP
                } else {
                    kernels::types::WRAP_REPEAT
                };
                let sampler = kernels::types::sampler(wrap, wrap, false);
                let read = crate::textures::with_sampler(&mut attributes, texture, sampler);
                Some((read, is_height))
            };
            let mut disagreeing = 0;
            let mut materials: Vec<Material> = mtls
                .iter()
                .map(|m| {
                    let mut material = material_from_mtl(m);
                    let name = m.name.as_str();
                    let parse = |s: Option<&str>| s.map(crate::textures::parse_map_statement);
                    // The texture is the albedo (exporters often write Kd 0 beside it).
                    let diffuse = parse(m.diffuse_texture.as_deref());
                    if let Some((index, _)) = map(
                        diffuse.as_ref(),
                        MapUse::Colour,
                        "map_Kd",
                        name,
                        "using its Kd",
                    ) {
                        material.albedo_texture = index;
                        material.albedo = [1.0; 3];
                    }
                    let mask = parse(m.dissolve_texture.as_deref());
                    if let Some((index, _)) = map(
                        mask.as_ref(),
                        MapUse::Mask,
                        "map_d",
                        name,
                        "the surface stays opaque",
                    ) {
                        material.opacity_texture = index;
                    }
                    // `norm` (the PBR extension) is a normal map; `map_Bump`/`bump` one too
                    // when its texels say so (Blender writes normal maps there), else a
                    // height map displacing by `-bm` scene units at its brightest.
                    let (bump, use_, key) = match m.unknown_param.get("norm") {
                        Some(norm) => (parse(Some(norm)), MapUse::Normal, "norm"),
                        None => (
                            parse(m.normal_texture.as_deref()),
                            MapUse::MaybeNormal,
                            "map_Bump",
                        ),
                    };
                    if let Some((index, is_height)) =
                        map(bump.as_ref(), use_, key, name, "its normals stay unbent")
                    {
                        material.normal_texture = index;
                        material.normal_scale =
                            bump.as_ref().and_then(|s| s.bump_multiplier).unwrap_or(1.0);
                        if is_height {
                            material.normal_map_kind = kernels::types::NORMAL_MAP_HEIGHT;
                        }
                    }
                    // map_Ke: emission = Ke (1 when not given) × the texture.
                    let glow = parse(m.unknown_param.get("map_Ke").map(String::as_str));
                    if let Some((index, _)) = map(
                        glow.as_ref(),
                        MapUse::Colour,
                        "map_Ke",
                        name,
                        "using its Ke",
                    ) {
                        material.emission_texture = index;
                        if m.emissive.is_none() {
                            material.emission = [1.0; 3];
                        }
                    }
                    let maps: Vec<glam::Affine2> = [diffuse, mask, bump, glow]
                        .iter()
                        .flatten()
                        .map(crate::textures::MapStatement::uv_map)
                        .collect();
                    let uv_map = maps.first().copied().unwrap_or(glam::Affine2::IDENTITY);
                    disagreeing += usize::from(maps.iter().any(|t| *t != uv_map));
                    uv_maps.push(uv_map);
                    material
                })
                .collect();
            if disagreeing > 0 {
                warnings.push(format!(
                    "materials of '{name}': maps of one material with different -s or -o in \
                     {disagreeing} material(s) are read with the first map's; not supported yet"
                ));
            }
            // `d` < 1 without a map: the same share covered everywhere (one texel).
            for (material, m) in materials.iter_mut().zip(&mtls) {
                if let Some(d) = dissolve_coverage(m).filter(|_| m.dissolve_texture.is_none()) {
                    let alpha = (d * 255.0).round() as u8;
                    let texel =
                        image::RgbaImage::from_pixel(1, 1, image::Rgba([255, 255, 255, alpha]));
                    material.opacity_texture = crate::textures::add(&mut attributes, &texel);
                    attributes.coverage_masks.push(material.opacity_texture);
                }
            }
            materials
        }
        Err(e) => {
            if models.iter().any(|m| m.mesh.material_id.is_some()) || text.contains("mtllib") {
                warnings.push(format!(
                    "materials of '{name}' could not be loaded ({e}); using a grey default"
                ));
            }
            Vec::new()
        }
    };
    let default_material = materials.len() as u32;
    materials.push(Material::new(Vec3::splat(DEFAULT_ALBEDO), Vec3::ZERO));
    let constant_mask: Vec<bool> = materials
        .iter()
        .map(|m| attributes.is_constant(m.opacity_texture))
        .collect();

    let mut triangles = Vec::new();
    for model in &models {
        let mesh = &model.mesh;
        let material = mesh
            .material_id
            .map(|m| m as u32)
            .filter(|&m| m < default_material)
            .unwrap_or(default_material);
        let uv_map = uv_maps
            .get(material as usize)
            .copied()
            .unwrap_or(glam::Affine2::IDENTITY);
        let vertex = |i: u32| -> Result<Vec3> {
            let i = i as usize;
            match mesh.positions.get(3 * i..3 * i + 3) {
                Some(p) => Ok(Vec3::new(p[0], p[1], p[2])),
                None => bail!(
                    "scene '{name}': face index {} is out of range ({} vertices)",
                    i + 1,
                    mesh.positions.len() / 3
                ),
            }
        };
        // Per-corner normal and texture indices, when every face of the mesh has them.
        let normal_indices = (!mesh.normals.is_empty()
            && mesh.normal_indices.len() == mesh.indices.len())
        .then_some(&mesh.normal_indices);
        let uv_indices = (!mesh.texcoords.is_empty()
            && mesh.texcoord_indices.len() == mesh.indices.len())
        .then_some(&mesh.texcoord_indices);
        // Corners of each polygon: `face_arities` is empty when every face is a triangle.
        let polygons = mesh.indices.len() / 3;
        let arity = |p: usize| mesh.face_arities.get(p).map_or(3, |&n| n as usize);
        let count = if mesh.face_arities.is_empty() {
            polygons
        } else {
            mesh.face_arities.len()
        };
        let mut first = 0;
        let mut corners = Vec::new();
        for p in 0..count {
            let n = arity(p);
            corners.clear();
            triangulate_polygon(n, &mut corners);
            for local in &corners {
                let c = local.map(|k| first + k);
                let mut triangle = Triangle::new(
                    vertex(mesh.indices[c[0]])?,
                    vertex(mesh.indices[c[1]])?,
                    vertex(mesh.indices[c[2]])?,
                    material,
                );
                // Each corner's attribute, if the file has it for all three.
                let normals = normal_indices.and_then(|ix| {
                    let n = |c: usize| {
                        let k = 3 * ix[c] as usize;
                        mesh.normals.get(k..k + 3).map(Vec3::from_slice)
                    };
                    Some([n(c[0])?, n(c[1])?, n(c[2])?])
                });
                let uvs = uv_indices.and_then(|ix| {
                    let uv = |c: usize| {
                        let k = 2 * ix[c] as usize;
                        let uv = mesh.texcoords.get(k..k + 2).map(glam::Vec2::from_slice)?;
                        Some(uv_map.transform_point2(uv))
                    };
                    Some([uv(c[0])?, uv(c[1])?, uv(c[2])?])
                });
                // A mask is read at texture coordinates: faces without them can still read a
                // constant one (`d` < 1).
                let uvs = uvs
                    .or_else(|| constant_mask[material as usize].then_some([glam::Vec2::ZERO; 3]));
                // `v x y z r g b`: colours as 0..1 display (sRGB) values, as MeshLab and
                // others write them.
                let colours = (mesh.vertex_color.len() == mesh.positions.len()).then(|| {
                    c.map(|corner| {
                        let k = 3 * mesh.indices[corner] as usize;
                        srgb_colour(&mesh.vertex_color[k..k + 3])
                    })
                });
                attributes.attach(&mut triangle, normals, uvs, colours);
                triangles.push(triangle);
            }
            first += n;
        }
    }
    let mut scene = Scene::with_attributes(triangles, materials, attributes)
        .map_err(|e| Error(format!("scene '{name}': {e}")))?;
    warnings.append(&mut scene.warnings);
    scene.warnings = warnings;
    scene.camera = camera;
    // The file's coordinates are the centred ones plus `centre`.
    scene.frame.centre += centre;
    Ok(scene)
}

/// Split a polygon of `n` corners (0..n in order) into n − 2 triangles, appended to `out`
/// as corner triples in the polygon's winding. Quads keep the fan (0 1 2, 0 2 3) every tool
/// uses; larger polygons are halved recursively (triangle a, mid, b over each chord a–b),
/// so a convex n-gon becomes triangles whose bounding boxes nest only log₂ n deep instead
/// of n − 2 slivers sharing one corner. (Concave polygons are split the same way, as the
/// fan split them before.)
pub fn triangulate_polygon(n: usize, out: &mut Vec<[usize; 3]>) {
    if n <= 4 {
        out.extend((1..n.saturating_sub(1)).map(|i| [0, i, i + 1]));
        return;
    }
    // Chords still to fill: the polygon's chain from corner a to corner b, closed by a–b.
    let mut chords = vec![(0, n - 1)];
    while let Some((a, b)) = chords.pop() {
        if b - a < 2 {
            continue;
        }
        let mid = (a + b) / 2;
        out.push([a, mid, b]);
        chords.push((a, mid));
        chords.push((mid, b));
    }
}

/// The text tobj parses: `mtllib` statements moved before everything else when one comes
/// after a `usemtl`. tobj resolves material names as it reads, so faces whose `usemtl`
/// preceded the `mtllib` that defines it came out grey; the format itself does not order
/// the two. (Our own line checks and messages read the original text.)
fn hoist_mtllib(text: &str) -> std::borrow::Cow<'_, str> {
    let first_usemtl = text.lines().position(|l| l.starts_with("usemtl"));
    let last_mtllib = text
        .lines()
        .enumerate()
        .filter(|(_, l)| l.starts_with("mtllib"))
        .map(|(i, _)| i)
        .last();
    match (first_usemtl, last_mtllib) {
        (Some(u), Some(m)) if m > u => {
            let (libs, rest): (Vec<&str>, Vec<&str>) =
                text.lines().partition(|l| l.starts_with("mtllib"));
            std::borrow::Cow::Owned(libs.into_iter().chain(rest).collect::<Vec<_>>().join("\n"))
        }
        _ => std::borrow::Cow::Borrowed(text),
    }
}

/// One warning per `usemtl` name that no loaded MTL defines (its faces turn grey), with the
/// line it first appears on.
fn unknown_material_warnings(name: &str, text: &str, known: &[tobj::Material]) -> Vec<String> {
    let mut seen: Vec<&str> = Vec::new();
    let mut warnings = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        if words.next() != Some("usemtl") {
            continue;
        }
        let material = words.next().unwrap_or("");
        if !seen.contains(&material) && !known.iter().any(|m| m.name == material) {
            warnings.push(format!(
                "{name}:{}: usemtl '{material}' names no material of the MTL files; its faces are grey",
                i + 1
            ));
        }
        seen.push(material);
    }
    warnings
}

/// GGX α of a Phong exponent `Ns` (Walter et al. 2007's Beckmann–Phong correspondence,
/// α = √(2 / (Ns + 2))): Ns 10 is α 0.41, Ns 100 α 0.14, Ns 1000 α 0.045.
pub fn alpha_from_phong(ns: f32) -> f32 {
    (2.0 / (ns.max(0.0) + 2.0)).sqrt()
}

/// What an MTL texture map is read as.
#[derive(Clone, Copy)]
enum MapUse {
    /// An sRGB colour (`map_Kd`, `map_Ke`).
    Colour,
    /// A cut-out mask (`map_d`).
    Mask,
    /// A tangent-space normal map (`norm`).
    Normal,
    /// A normal map if its texels are normals, else a height map (`map_Bump`, `bump`).
    MaybeNormal,
}

/// MTL statements tobj does not know that the materials read (the PBR extension's and
/// the normal and emission maps); every other unknown statement is one warning.
const READ_MTL_PARAMS: [&str; 4] = ["Pm", "Pr", "norm", "map_Ke"];

/// Whether an MTL statement tobj does not read only states the format's default (`Tr 0`:
/// opaque, `Tf 1 1 1`: no filter; 3ds Max writes both into every material): nothing is
/// lost by not reading it, so it is no warning.
fn states_the_default(key: &str, value: &str) -> bool {
    let numbers: Vec<f32> = value
        .split_whitespace()
        .filter_map(|w| w.parse().ok())
        .collect();
    match key {
        "Tr" => numbers == [0.0],
        "Tf" => !numbers.is_empty() && numbers.iter().all(|&x| x == 1.0),
        _ => false,
    }
}

/// MTL statements the loader reads no meaning from (each one named once per scene when a
/// material uses it).
fn ignored_mtl_keys(m: &tobj::Material) -> Vec<String> {
    let mut keys: Vec<String> = m
        .unknown_param
        .iter()
        .filter(|(k, v)| !READ_MTL_PARAMS.contains(&k.as_str()) && !states_the_default(k, v))
        .map(|(k, _)| k.clone())
        .collect();
    keys.sort_unstable(); // a hash map's order would change the warnings' from run to run
    for (key, present) in [
        ("map_Ks", m.specular_texture.is_some()),
        ("map_Ns", m.shininess_texture.is_some()),
        ("map_Ka", m.ambient_texture.is_some()),
    ] {
        if present {
            keys.push(key.to_string());
        }
    }
    if dissolve_coverage(m).is_some() && m.dissolve_texture.is_some() {
        keys.push("d < 1 beside map_d (the map decides)".to_string());
    }
    keys
}

/// The share of a non-glass material's surface that is there, when its `d` (dissolve) says
/// it is partly transparent: a coverage (`SurfaceAttributes::coverage_masks`), as glTF's
/// BLEND. Glass (`illum 4, 6, 7, 9`) refracts instead and ignores `d`.
fn dissolve_coverage(m: &tobj::Material) -> Option<f32> {
    let glass = matches!(m.illumination_model, Some(4 | 6 | 7 | 9));
    m.dissolve
        .filter(|d| *d < 1.0 && !glass)
        .map(|d| d.clamp(0.0, 1.0))
}

/// An MTL material on our BSDF family (documented in the README):
/// - `illum 4, 6, 7, 9` (glass): dielectric of index `Ni` (default 1.5), smooth, or rough
///   with α = `Pr`² when the PBR extension's `Pr` is given;
/// - `illum 3, 5` (mirror reflection): a smooth conductor of reflectance `Ks` when `Kd` is
///   black, else `Kd` under a smooth clear coat;
/// - PBR extension `Pm`/`Pr`: metallic ≥ 0.5 is a conductor of reflectance `Kd`, else `Kd`
///   under a coat; α = `Pr`²;
/// - otherwise `Ks` > 0 is glossy: a conductor of reflectance `Ks` when `Kd` is black, else
///   `Kd` under a coat, α from `Ns` (`alpha_from_phong`); else Lambertian `Kd`.
///   `Ke` is the emitted radiance of any of them.
fn material_from_mtl(m: &tobj::Material) -> Material {
    let kd = m
        .diffuse
        .map(Vec3::from)
        .unwrap_or(Vec3::splat(DEFAULT_ALBEDO))
        .clamp(Vec3::ZERO, Vec3::ONE);
    let ks = m
        .specular
        .map(Vec3::from)
        .unwrap_or(Vec3::ZERO)
        .clamp(Vec3::ZERO, Vec3::ONE);
    let ke = m
        .emissive
        .map(Vec3::from)
        .unwrap_or(Vec3::ZERO)
        .max(Vec3::ZERO);
    let ior = m
        .optical_density
        .filter(|n| n.is_finite() && *n >= 1.0 && *n <= 4.0)
        .unwrap_or(kernels::types::DEFAULT_IOR);
    let param = |key: &str| {
        m.unknown_param
            .get(key)
            .and_then(|v| v.trim().parse::<f32>().ok())
            .filter(|v| v.is_finite())
            .map(|v| v.clamp(0.0, 1.0))
    };
    let black = kd.max_element() <= 0.0;
    let alpha = m.shininess.map_or(1.0, alpha_from_phong);
    let mut material = match (m.illumination_model, param("Pm"), param("Pr")) {
        (Some(4 | 6 | 7 | 9), _, roughness) => {
            Material::dielectric(ior, roughness.map_or(0.0, |r| r * r))
        }
        (Some(3 | 5), _, _) if black => Material::conductor(ks, 0.0),
        (Some(3 | 5), _, _) => Material::coated(kd, ior, 0.0),
        (_, metallic, roughness) if metallic.is_some() || roughness.is_some() => {
            let a = roughness.map_or(0.25, |r| r * r);
            if metallic.unwrap_or(0.0) >= 0.5 {
                Material::conductor(kd, a)
            } else {
                Material::coated(kd, ior, a)
            }
        }
        _ if ks.max_element() > 0.0 && black => Material::conductor(ks, alpha),
        _ if ks.max_element() > 0.0 => Material::coated(kd, ior, alpha),
        _ => Material::new(kd, Vec3::ZERO),
    };
    material.emission = ke.to_array();
    material
}

/// A vertex line's numbers after x y z: none, a weight w that tobj divides them by (not
/// zero, and leaving them finite), or a colour r g b (tobj drops a colour that does not
/// parse and gives the next vertices' colours to this one). Anything else tobj refuses
/// without a line number. Returns the weight (1 without one).
fn check_vertex_extras<'a>(
    name: &str,
    n: usize,
    xyz: [f32; 3],
    extras: impl Iterator<Item = &'a str>,
) -> Result<f32> {
    let extras: Vec<&str> = extras.collect();
    let number = |w: &str, what: &str| match w.parse::<f32>() {
        Ok(x) if x.is_finite() => Ok(x),
        _ => Err(Error(format!(
            "{name}:{n}: vertex {what} '{w}' is not a finite number"
        ))),
    };
    match extras[..] {
        [] => {}
        [word] => {
            let w = number(word, "weight")?;
            if w == 0.0 || xyz.iter().any(|x| !(x / w).is_finite()) {
                bail!("{name}:{n}: vertex weight {word} leaves no finite position (x/w, y/w, z/w)");
            }
            return Ok(w);
        }
        [r, g, b] => {
            for c in [r, g, b] {
                number(c, "colour")?;
            }
        }
        _ => bail!(
            "{name}:{n}: vertex has {} numbers; expected 3 (x y z), 4 (x y z w) or 6 (x y z r g b)",
            3 + extras.len()
        ),
    }
    Ok(1.0)
}

/// Check vertex and face lines before tobj sees them, so every error names its line:
/// tobj accepts "nan" and "inf" coordinates, silently drops faces of fewer than three
/// vertices, and reports bad indices without a line number. Returns the box of the
/// vertices' positions (to f32 precision: it only decides whether to move them).
fn check_lines(name: &str, text: &str) -> Result<(Vec3, Vec3)> {
    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    let mut vertices: i64 = 0;
    // Texture coordinates and normals so far: their indices in faces are checked too
    // (tobj overflows on indices such as -9223372036854775808).
    let (mut texcoords, mut normals): (i64, i64) = (0, 0);
    for (i, line) in text.lines().enumerate() {
        let n = i + 1;
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let mut coords = [""; 3];
                let mut count = 0;
                for w in words.by_ref().take(3) {
                    coords[count] = w;
                    count += 1;
                }
                if count < 3 {
                    bail!("{name}:{n}: vertex needs 3 coordinates, got {count}");
                }
                let mut xyz = [0.0f32; 3];
                for (x, w) in xyz.iter_mut().zip(coords) {
                    *x = match w.parse::<f32>() {
                        Ok(x) if x.is_finite() => x,
                        Ok(_) => {
                            bail!("{name}:{n}: vertex coordinate '{w}' is not a finite number")
                        }
                        Err(_) => bail!("{name}:{n}: bad vertex coordinate '{w}'"),
                    };
                }
                let w = check_vertex_extras(name, n, xyz, words)?;
                let p = Vec3::from_array(xyz) / w;
                (lo, hi) = (lo.min(p), hi.max(p));
                vertices += 1;
            }
            Some("vt") => texcoords += 1,
            Some("vn") => normals += 1,
            Some("f") => {
                let corners = words.clone().count();
                if corners < 3 {
                    bail!("{name}:{n}: face has {corners} vertices; a face needs at least 3");
                }
                for r in words {
                    let mut parts = r.split('/');
                    let index = parts.next().unwrap_or("");
                    let k: i64 = index
                        .parse()
                        .map_err(|_| Error(format!("{name}:{n}: bad face index '{r}'")))?;
                    check_index(name, n, "face index", k, vertices, "vertices")?;
                    for (what, count, kind) in [
                        ("texture coordinate index", texcoords, "texture coordinates"),
                        ("normal index", normals, "normals"),
                    ] {
                        match parts.next() {
                            None | Some("") => {}
                            Some(w) => {
                                let k: i64 = w.parse().map_err(|_| {
                                    Error(format!("{name}:{n}: bad {what} in '{r}'"))
                                })?;
                                check_index(name, n, what, k, count, kind)?;
                            }
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok((lo, hi))
}

/// The position of a checked vertex line (`check_lines`), read in f64: x y z, divided by
/// the weight w where the line has one.
fn obj_position(line: &str) -> DVec3 {
    let mut numbers = line
        .split_whitespace()
        .skip(1)
        .map(|w| w.parse().unwrap_or(f64::NAN));
    let mut xyz = [f64::NAN; 3];
    for x in &mut xyz {
        *x = numbers.next().unwrap_or(f64::NAN);
    }
    let p = DVec3::from_array(xyz);
    match (numbers.next(), numbers.next()) {
        (Some(w), None) => p / w,
        _ => p,
    }
}

/// `text` with its vertex lines moved by −`centre`, in f64, before tobj rounds them to
/// f32 (see `scene_frame`): x y z [w] becomes (x y z)/w − centre, a colour stays.
fn centre_obj_vertices(text: &str, centre: DVec3) -> String {
    let mut out = String::with_capacity(text.len() + text.len() / 8);
    for line in text.lines() {
        let mut words = line.split_whitespace();
        if words.next() == Some("v") {
            let p = obj_position(line) - centre;
            let colour: Vec<&str> = words.skip(3).collect();
            let colour = if colour.len() == 3 {
                colour.join(" ")
            } else {
                String::new()
            };
            out += &format!("v {} {} {} {colour}\n", p.x, p.y, p.z);
        } else {
            out += line;
            out.push('\n');
        }
    }
    out
}

/// An OBJ index (1-based, or negative: counted back from the last one so far) must name
/// one of the `count` elements defined before it.
fn check_index(name: &str, line: usize, what: &str, k: i64, count: i64, kind: &str) -> Result<()> {
    if k == 0 {
        bail!("{name}:{line}: {what} 0 (OBJ indices start at 1)");
    }
    let resolved = if k < 0 {
        count.saturating_add(k).saturating_add(1)
    } else {
        k
    };
    if resolved < 1 || resolved > count {
        bail!("{name}:{line}: {what} {k} is out of range ({count} {kind} so far)");
    }
    Ok(())
}

/// Parse `# camera: eye=X,Y,Z target=X,Y,Z up=X,Y,Z fov=DEG` if the file has one.
fn parse_camera_hint(name: &str, text: &str) -> Result<Option<CameraHint>> {
    let Some((n, line)) = text
        .lines()
        .enumerate()
        .find(|(_, l)| l.trim_start().starts_with("# camera:"))
    else {
        return Ok(None);
    };
    let bad = || Error(format!("{name}:{}: bad camera line '{line}'", n + 1));
    let mut hint = CameraHint {
        eye: DVec3::ZERO,
        target: DVec3::Z,
        up: Vec3::Y,
        fov: 45.0,
    };
    let (mut has_eye, mut has_target) = (false, false);
    for kv in line.trim_start()["# camera:".len()..].split_whitespace() {
        let (k, v) = kv.split_once('=').ok_or_else(bad)?;
        match k {
            "eye" => {
                (hint.eye, has_eye) = (crate::options::parse_position(v).map_err(|_| bad())?, true)
            }
            "target" => {
                (hint.target, has_target) =
                    (crate::options::parse_position(v).map_err(|_| bad())?, true)
            }
            "up" => hint.up = crate::options::parse_vec3(v).map_err(|_| bad())?,
            "fov" => hint.fov = v.parse().map_err(|_| bad())?,
            _ => return Err(bad()),
        }
    }
    if !(has_eye && has_target) {
        bail!(
            "{name}:{}: the camera line needs at least eye=X,Y,Z and target=X,Y,Z",
            n + 1
        );
    }
    Ok(Some(hint))
}

/// The Cornell box in the source tree (tests load it as a file; the binary embeds it).
pub fn default_scene_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/cornell_box.obj")
}

/// A colour given as 0..1 sRGB (display) values, as a linear albedo factor.
pub fn srgb_colour(c: &[f32]) -> Vec3 {
    Vec3::from_slice(c).map(|x| kernels::texture::srgb_to_linear(x.clamp(0.0, 1.0)))
}

/// Load the scene named on the command line: an OBJ file, or a built-in scene's name
/// (see `generate`); the Cornell box by default. Prints the scene's warnings.
pub fn load(args: &SceneOptions) -> Result<Scene> {
    let path = args
        .scene
        .clone()
        .unwrap_or_else(|| PathBuf::from("cornell-box"));
    let name = path.to_string_lossy();
    let started = std::time::Instant::now();
    crate::accel::set_quality(args.bvh_quality.unwrap_or_default());
    crate::accel::set_splits(args.bvh_splits);
    let mut scene = if crate::gltf_scene::is_gltf(&path) {
        crate::gltf_scene::load(&path)?
    } else if crate::ply_scene::is_ply(&path) {
        crate::ply_scene::load(&path)?
    } else if path.is_file()
        || path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("obj"))
    {
        load_obj(&path)?
    } else if name == "cornell-box" {
        cornell_box()?
    } else {
        match crate::generate::builtin(&name) {
            Some(generated) => generated?.into_scene()?,
            None => crate::generate::unknown_scene(&name)?.into_scene()?,
        }
    };
    scene.load_time = started.elapsed();
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    log::debug!(
        "scene '{name}': {} triangles ({} BVH slots), {} emissive, {} materials; {} BVH: {} nodes in {:.1} ms",
        scene.triangle_count,
        scene.triangles.len(),
        scene.lights.len(),
        scene.materials.len(),
        kernels::bvh::TRAVERSAL,
        scene.nodes.len(),
        scene.bvh_build_time.as_secs_f64() * 1e3
    );
    Ok(scene)
}
