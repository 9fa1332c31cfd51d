//! glTF 2.0 scenes (`.gltf` with external or embedded buffers and images, `.glb`) through
//! the `gltf` crate: the default scene's nodes with their transforms, triangle primitives
//! with normals and texture coordinates (floats, or `KHR_mesh_quantization`'s integers:
//! `gltf_attributes`), any buffer view compressed by `EXT_meshopt_compression` decoded
//! first (`gltf_meshopt`), materials mapped onto our BSDF family, base
//! colour, normal, metallic-roughness and emissive textures (with `KHR_texture_transform`,
//! one per material, baked into the texture coordinates), `KHR_lights_punctual` lights
//! (see `gltf_lights`), skinned meshes in the pose their joints' nodes give (`gltf_skin`),
//! and the first camera as the default view.
//!
//! Material mapping (the metallic-roughness model; α = roughness²):
//! - `KHR_materials_transmission` > 0: a dielectric of index `KHR_materials_ior` (1.5);
//! - metallic ≥ 0.5: a conductor of reflectance baseColor (a binary choice: no blend);
//!   with a metallic-roughness texture the choice is made per point (metallic × blue),
//!   and roughness is roughnessFactor × green there;
//! - `KHR_materials_specular` with specularFactor 0: Lambertian baseColor;
//! - otherwise: baseColor under a GGX dielectric coat of index ior (Lambert + GGX specular
//!   weighted by Fresnel, as the specification's dielectric BRDF).
//!
//! baseColor is baseColorFactor × its texture × COLOR_0, for conductors too. Emission =
//! emissiveFactor × its texture × `KHR_materials_emissive_strength`, from the front side,
//! and from both sides when the material is `doubleSided` (the triangle is added flipped).
use std::path::Path;

use glam::{Affine2, Mat3, Mat4, Vec2, Vec3, Vec4};
use gltf::Semantic;
use kernels::types::{Material, Triangle, DEFAULT_IOR};

use crate::bail;
use crate::error::{Error, Result};
use crate::gltf_attributes as vertex;
use crate::gltf_lights::{radiometric, PointLight, SceneSun};
use crate::scene::{CameraHint, Scene, SurfaceAttributes};

/// Largest `.gltf`/`.glb` file read (its buffers and images are read by the importer).
pub const MAX_GLTF_BYTES: u64 = 2 << 30;

/// The extensions the loader reads (see the module documentation); a file that uses
/// another gets one warning naming it (one it *requires* is refused by the importer).
/// `KHR_materials_volume` is how glTF says a transmissive mesh is solid, which is what our
/// dielectric always is.
const READ_EXTENSIONS: [&str; 10] = [
    "KHR_mesh_quantization",
    crate::gltf_meshopt::EXTENSION,
    "KHR_lights_punctual",
    "KHR_materials_pbrSpecularGlossiness",
    "KHR_materials_emissive_strength",
    "KHR_texture_transform",
    "KHR_materials_transmission",
    "KHR_materials_ior",
    "KHR_materials_specular",
    "KHR_materials_volume",
];

/// The extensions of READ_EXTENSIONS that gltf refuses where a file requires them.
const READ_BEYOND_GLTF: [&str; 2] = ["KHR_mesh_quantization", crate::gltf_meshopt::EXTENSION];

/// A glTF texture sampler as the sampler bits of `TextureInfo::format`: its wrap modes,
/// and nearest filtering where magnification asks for it (pixel art and voxel models do;
/// minification is left to the many samples a pixel takes).
fn sampler_bits(sampler: &gltf::texture::Sampler) -> u32 {
    use gltf::texture::{MagFilter, WrappingMode};
    use kernels::types::{WRAP_CLAMP, WRAP_MIRROR, WRAP_REPEAT};
    let wrap = |mode: WrappingMode| match mode {
        WrappingMode::Repeat => WRAP_REPEAT,
        WrappingMode::ClampToEdge => WRAP_CLAMP,
        WrappingMode::MirroredRepeat => WRAP_MIRROR,
    };
    let nearest = sampler.mag_filter() == Some(MagFilter::Nearest);
    kernels::types::sampler(wrap(sampler.wrap_s()), wrap(sampler.wrap_t()), nearest)
}

/// A texture's `KHR_texture_transform` as the map of glTF texture coordinates it
/// specifies: scale, then rotation, then offset. The rotation turns u towards −v, as the
/// Khronos sample viewer, three.js and bevy read it (the extension's GLSL snippet is
/// ambiguous about the sign; its TextureTransformTest model decides).
fn uv_transform(t: &gltf::texture::TextureTransform) -> Affine2 {
    Affine2::from_scale_angle_translation(t.scale().into(), -t.rotation(), t.offset().into())
}

/// Whether `path` names a glTF file by its extension.
pub fn is_gltf(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"))
}

/// The base colour texture of an image, as RGBA8 (8-bit formats only; others are skipped
/// with a warning by the caller).
fn rgba8(image: &gltf::image::Data) -> Option<image::RgbaImage> {
    use gltf::image::Format;
    let px = &image.pixels;
    let rgba: Vec<u8> = match image.format {
        Format::R8G8B8A8 => px.clone(),
        Format::R8G8B8 => px
            .as_chunks::<3>()
            .0
            .iter()
            .flat_map(|c| [c[0], c[1], c[2], 255])
            .collect(),
        Format::R8G8 => px
            .as_chunks::<2>()
            .0
            .iter()
            .flat_map(|c| [c[0], c[0], c[0], c[1]])
            .collect(),
        Format::R8 => px.iter().flat_map(|&c| [c, c, c, 255]).collect(),
        _ => return None,
    };
    image::RgbaImage::from_raw(image.width, image.height, rgba)
}

/// One glTF material on our BSDF family (see the module documentation).
fn material(m: &gltf::Material) -> Material {
    let mut material = match m.pbr_specular_glossiness() {
        Some(sg) => specular_glossiness(&sg),
        None => metallic_roughness(m),
    };
    let strength = m.emissive_strength().unwrap_or(1.0);
    let emission = Vec3::from(m.emissive_factor()) * strength;
    if emission.is_finite() {
        material.emission = emission.max(Vec3::ZERO).to_array();
    }
    material
}

/// A metallic-roughness material (the module documentation's mapping), without emission.
fn metallic_roughness(m: &gltf::Material) -> Material {
    let pbr = m.pbr_metallic_roughness();
    let [r, g, b, _] = pbr.base_color_factor();
    let base = Vec3::new(r, g, b).clamp(Vec3::ZERO, Vec3::ONE);
    let alpha = pbr.roughness_factor().clamp(0.0, 1.0).powi(2);
    let ior = m
        .ior()
        .filter(|n| n.is_finite() && (1.0..=4.0).contains(n))
        .unwrap_or(DEFAULT_IOR);
    let transmission = m.transmission().map_or(0.0, |t| t.transmission_factor());
    let specular = m.specular().map_or(1.0, |s| s.specular_factor());
    // A metallic-roughness texture decides metal or not per point (`surface_bsdf`): the
    // material is then its dielectric self, with the base colour kept as reflectance too.
    let metal_per_point = pbr.metallic_roughness_texture().is_some();
    let mut material = if transmission > 0.0 {
        Material::dielectric(ior, alpha)
    } else if pbr.metallic_factor() >= 0.5 && !metal_per_point {
        Material::conductor(base, alpha)
    } else if specular <= 0.0 {
        Material::new(base, Vec3::ZERO)
    } else {
        Material::coated(base, ior, alpha)
    };
    if transmission <= 0.0 {
        material.specular = base.to_array();
        material.metallic = pbr.metallic_factor().clamp(0.0, 1.0);
    }
    material
}

/// A `KHR_materials_pbrSpecularGlossiness` material (older exporters, Sketchfab), which the
/// specification prefers to the metallic-roughness fallback beside it: α = (1 − glossiness)²;
/// black diffuse with a bright specular (≥ ½) is a conductor of that specular colour;
/// otherwise diffuse under a dielectric coat whose index gives the specular's (luminance)
/// reflectance at normal incidence, F0 = ((n − 1)/(n + 1))², and Lambertian diffuse where
/// the specular is black. The specular-glossiness texture is not read (one warning).
/// Without emission (`material` adds it).
fn specular_glossiness(sg: &gltf::material::PbrSpecularGlossiness) -> Material {
    let [r, g, b, _] = sg.diffuse_factor();
    let diffuse = Vec3::new(r, g, b).clamp(Vec3::ZERO, Vec3::ONE);
    let specular = Vec3::from(sg.specular_factor()).clamp(Vec3::ZERO, Vec3::ONE);
    let alpha = (1.0 - sg.glossiness_factor().clamp(0.0, 1.0)).powi(2);
    let f0 = specular.dot(Vec3::new(0.2126, 0.7152, 0.0722));
    if diffuse.max_element() <= 0.0 && f0 >= 0.5 {
        Material::conductor(specular, alpha)
    } else if f0 <= 0.0 {
        Material::new(diffuse, Vec3::ZERO)
    } else {
        let root = f0.min(0.36).sqrt(); // n ≤ 4, the coat's range
        Material::coated(diffuse, (1.0 + root) / (1.0 - root), alpha)
    }
}

/// Load a glTF 2.0 file.
pub fn load(path: &Path) -> Result<Scene> {
    let name = path.display().to_string();
    let md =
        std::fs::metadata(path).map_err(|e| Error(format!("cannot read scene '{name}': {e}")))?;
    if !md.is_file() {
        bail!("cannot read scene '{name}': not a regular file");
    }
    if md.len() > MAX_GLTF_BYTES {
        bail!(
            "scene '{name}' is {} bytes, over the limit of {MAX_GLTF_BYTES}",
            md.len()
        );
    }
    crate::memory::check_scene(
        &format!("scene '{name}'"),
        md.len() as f64 * crate::memory::BYTES_PER_OBJ_BYTE,
    )?;
    // Relative URIs are beside the file (gltf's `import` takes "./" for a bare name).
    let base = path.parent().unwrap_or(Path::new("./"));
    guarded(&name, || {
        let file = std::io::BufReader::new(
            std::fs::File::open(path)
                .map_err(|e| Error(format!("cannot read scene '{name}': {e}")))?,
        );
        let gltf = gltf::Gltf::from_reader_without_validation(file)
            .and_then(validated)
            .map_err(|e| Error(format!("cannot load scene '{name}': {e}")))?;
        from_import(&name, import(&name, gltf, Some(base))?)
    })
}

/// gltf's validation, less its refusal of the required extensions that this loader reads
/// though gltf does not (`KHR_mesh_quantization`: `gltf_attributes` reads its integers;
/// `EXT_meshopt_compression`: `import` decodes its views).
fn validated(gltf: gltf::Gltf) -> gltf::Result<gltf::Gltf> {
    let gltf::Gltf { document, blob } = gltf;
    let mut json = document.into_json();
    json.extensions_required
        .retain(|e| !READ_BEYOND_GLTF.contains(&e.as_str()));
    let document = gltf::Document::from_json(json)?;
    Ok(gltf::Gltf { document, blob })
}

/// gltf's `import`, but an image that cannot be read (a file that is not there, an
/// encoding it does not decode) is one warning and its textures are left out, as an OBJ's
/// `map_Kd` that cannot be read, instead of the whole scene refused.
/// A buffer that cannot be read is one error naming it ("its buffer 0 'scene.bin'"), where
/// the importer said only "No such file or directory".
fn import(name: &str, gltf: gltf::Gltf, base: Option<&Path>) -> Result<Imported> {
    let gltf::Gltf { document, mut blob } = gltf;
    let buffers = document
        .buffers()
        .map(|buffer| {
            let file = match buffer.source() {
                gltf::buffer::Source::Uri(uri) if !uri.starts_with("data:") => format!(" '{uri}'"),
                _ => String::new(),
            };
            let its = format!(
                "cannot load scene '{name}': its buffer {}{file}",
                buffer.index()
            );
            if crate::gltf_meshopt::is_placeholder(&document, &buffer, blob.is_some()) {
                // Room for the views decoded into it (below), checked first: its length is
                // the file's word alone.
                crate::memory::check(&its, buffer.length() as u64)?;
                return Ok(gltf::buffer::Data(vec![0; buffer.length()]));
            }
            let data = gltf::buffer::Data::from_source_and_blob(buffer.source(), base, &mut blob)
                .map_err(|e| Error(format!("{its}: {e}")))?;
            // The check of gltf's `import_buffers`: accessors trust the stated length.
            if data.len() < buffer.length() {
                bail!(
                    "{its} holds {} bytes, fewer than the {} it states",
                    data.len(),
                    buffer.length()
                );
            }
            Ok(data)
        })
        .collect::<Result<Vec<_>>>()?;
    let mut buffers = buffers;
    crate::gltf_meshopt::decode_views(&document, &mut buffers)
        .map_err(|e| Error(format!("cannot load scene '{name}': {e}")))?;
    let mut warnings = Vec::new();
    let images = document
        .images()
        .map(|image| {
            let source = image.source();
            let file = match source {
                gltf::image::Source::Uri { uri, .. } if !uri.starts_with("data:") => {
                    format!(" ('{uri}')")
                }
                _ => String::new(),
            };
            gltf::image::Data::from_source(source, base, &buffers)
                .map_err(|e| {
                    warnings.push(format!(
                        "'{name}': image {}{file} not loaded: {e}; its textures are left out",
                        image.index()
                    ))
                })
                .ok()
        })
        .collect();
    Ok((document, buffers, images, warnings))
}

/// A glTF file's bytes (named `name` in messages; .glb, or .gltf whose buffers and images
/// are embedded as data URIs) as a scene.
pub fn parse_gltf_bytes(name: &str, bytes: &[u8]) -> Result<Scene> {
    guarded(name, || {
        let gltf = gltf::Gltf::from_slice_without_validation(bytes)
            .and_then(validated)
            .map_err(|e| Error(format!("cannot load scene '{name}': {e}")))?;
        from_import(name, import(name, gltf, None)?)
    })
}

/// Load a glTF, the gltf library's panics one `error:` for this file like its errors. gltf
/// 1.4 validates with unchecked indices (a POSITION naming an accessor the file does not
/// define panics in gltf-json) and its readers panic on accessor types the specification
/// does not allow (a COLOR_0 of bytes as scalars): both found by the fuzzer. The panic hook
/// is silenced meanwhile (the library's message is not ours to print); loading runs on
/// one thread.
fn guarded(name: &str, load: impl FnOnce() -> Result<Scene>) -> Result<Scene> {
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(load));
    std::panic::set_hook(hook);
    result.unwrap_or_else(|_| {
        Err(Error(format!(
            "cannot load scene '{name}': it is inconsistent (an item it does not define, or an \
             accessor of a type its use does not allow)"
        )))
    })
}

/// What `import` gives: the document, its buffers, its images (`None` where one could not
/// be read) and a warning for each image that could not.
type Imported = (
    gltf::Document,
    Vec<gltf::buffer::Data>,
    Vec<Option<gltf::image::Data>>,
    Vec<String>,
);

/// The scene of an imported glTF document, its buffers and its images.
fn from_import(name: &str, imported: Imported) -> Result<Scene> {
    let (doc, buffers, images, mut warnings) = imported;
    warnings.extend(
        doc.extensions_used()
            .filter(|e| !READ_EXTENSIONS.contains(e))
            .map(|e| format!("'{name}': extension {e} is not supported yet; ignored")),
    );
    let mut attributes = SurfaceAttributes::default();

    // Images → textures, on first use: as colour or as data.
    let mut texture_of_image: Vec<Option<Option<u32>>> = vec![None; images.len()];
    let mut data_of_image: Vec<Option<Option<u32>>> = vec![None; images.len()];
    let mut invisible: Vec<bool> = Vec::new();
    let mut spots = 0;
    let mut materials: Vec<Material> = Vec::new();
    let mut ignored: Vec<&str> = Vec::new();
    // Each material's texture coordinate map (KHR_texture_transform).
    let mut uv_maps: Vec<Affine2> = Vec::new();
    for m in doc.materials() {
        let mut mat = material(&m);
        let pbr = m.pbr_metallic_roughness();
        // alphaMode MASK: the base colour's alpha (times its factor) against the cutoff, as
        // a cut-out mask thresholded per texel. BLEND: that alpha is the share of the
        // surface that is there (a coverage mask, solid with probability alpha), which is
        // what blending one layer over what lies behind it means, in any order.
        let cutoff = match m.alpha_mode() {
            gltf::material::AlphaMode::Opaque => None,
            gltf::material::AlphaMode::Mask => Some(m.alpha_cutoff().unwrap_or(0.5)),
            gltf::material::AlphaMode::Blend => None,
        };
        let blend = m.alpha_mode() == gltf::material::AlphaMode::Blend;
        // Each image is decoded once per way it is read: as sRGB colour (base colour,
        // emission) or as linear data (normal, metallic-roughness).
        // Each use reads it through its texture's sampler.
        let mut texture = |texture: gltf::Texture, linear: bool, what: &str| {
            let image = texture.source().index();
            let cache = if linear {
                &mut data_of_image
            } else {
                &mut texture_of_image
            };
            // An image that was not loaded has had its warning.
            let loaded = images[image].as_ref()?;
            let decoded = (*cache[image].get_or_insert_with(|| match rgba8(loaded) {
                Some(rgba) if linear => Some(crate::textures::add_linear(&mut attributes, &rgba)),
                Some(rgba) => Some(crate::textures::add(&mut attributes, &rgba)),
                None => {
                    warnings.push(format!(
                        "'{name}': image {image} is not 8-bit ({:?}); its {what} is ignored",
                        loaded.format
                    ));
                    None
                }
            }))?;
            let sampler = sampler_bits(&texture.sampler());
            Some(crate::textures::with_sampler(
                &mut attributes,
                decoded,
                sampler,
            ))
        };
        // The base colour: specular-glossiness's diffuse where the material has it.
        let sg = m.pbr_specular_glossiness();
        let base_info = match &sg {
            Some(sg) => sg.diffuse_texture(),
            None => pbr.base_color_texture(),
        };
        let base_alpha = sg
            .as_ref()
            .map_or(pbr.base_color_factor()[3], |sg| sg.diffuse_factor()[3]);
        if sg
            .as_ref()
            .is_some_and(|sg| sg.specular_glossiness_texture().is_some())
        {
            ignored.push("specular-glossiness textures");
        }
        let base_texture = base_info.as_ref().map(|i| i.texture());
        let base_image = base_texture.as_ref().map(|t| t.source().index());
        if let Some(t) = base_texture
            .clone()
            .and_then(|t| texture(t, false, "base colour texture"))
        {
            mat.albedo_texture = t;
        }
        if let Some(normal) = m.normal_texture() {
            if let Some(t) = texture(normal.texture(), true, "normal texture") {
                mat.normal_texture = t;
                mat.normal_scale = Some(normal.scale())
                    .filter(|s| s.is_finite())
                    .unwrap_or(1.0);
            }
        }
        if let Some(info) = pbr.metallic_roughness_texture() {
            if let Some(t) = texture(info.texture(), true, "metallic-roughness texture") {
                if mat.kind != kernels::bsdf::BSDF_DIELECTRIC {
                    mat.metal_rough_texture = t;
                }
            }
        }
        if let Some(info) = m.emissive_texture() {
            if let Some(t) = texture(info.texture(), false, "emissive texture") {
                mat.emission_texture = t;
            }
        }
        // The mask of MASK or BLEND, texel by texel from the base colour's alpha × factor:
        // solid or a hole against the cutoff (MASK), the share covered (BLEND). A BLEND
        // factor without a texture is one texel, wherever it is read.
        if cutoff.is_some() || blend {
            let mask_texel = |a: u8| match cutoff {
                Some(c) if a as f32 / 255.0 * base_alpha >= c => 255,
                Some(_) => 0,
                None => (a as f32 * base_alpha.clamp(0.0, 1.0)).round() as u8,
            };
            let mask = match base_image.and_then(|i| images[i].as_ref().and_then(rgba8)) {
                Some(mut rgba) => {
                    for p in rgba.pixels_mut() {
                        *p = image::Rgba([255, 255, 255, mask_texel(p[3])]);
                    }
                    Some(rgba)
                }
                None if blend && base_alpha < 1.0 => Some(image::RgbaImage::from_pixel(
                    1,
                    1,
                    image::Rgba([255, 255, 255, mask_texel(255)]),
                )),
                None => None,
            };
            if let Some(mask) = mask {
                // Read as the base colour is, through its sampler.
                let sampler = base_texture
                    .as_ref()
                    .map_or(0, |t| sampler_bits(&t.sampler()));
                let mask = crate::textures::add(&mut attributes, &mask);
                mat.opacity_texture = crate::textures::with_sampler(&mut attributes, mask, sampler);
                if blend {
                    attributes.coverage_masks.push(mat.opacity_texture);
                }
            }
        }
        // KHR_texture_transform: one map per material, baked into its primitives' texture
        // coordinates: the base colour's, else the first texture's that has one (normal
        // textures carry theirs where the gltf crate does not read it; they follow).
        let infos = [
            base_info.clone(),
            pbr.metallic_roughness_texture(),
            m.emissive_texture(),
        ];
        let transforms: Vec<Affine2> = infos
            .iter()
            .flatten()
            .filter_map(|i| i.texture_transform())
            .map(|t| uv_transform(&t))
            .collect();
        let uv_map = transforms.first().copied().unwrap_or(Affine2::IDENTITY);
        if transforms.iter().any(|t| *t != uv_map) {
            ignored.push("textures of one material with different texture transforms");
        }
        uv_maps.push(uv_map);
        // A transform may name another coordinate set.
        let set = |i: &gltf::texture::Info| {
            i.texture_transform()
                .and_then(|t| t.tex_coord())
                .unwrap_or(i.tex_coord())
        };
        let sets = [
            base_info.as_ref().map(set),
            m.normal_texture().map(|n| n.tex_coord()),
            pbr.metallic_roughness_texture().map(|i| set(&i)),
            m.emissive_texture().map(|i| set(&i)),
        ];
        let other_sets = sets.iter().flatten().filter(|&&set| set != 0).count();
        ignored.extend(std::iter::repeat_n(
            "texture coordinate sets other than 0",
            other_sets,
        ));
        // Without a texture the factor's alpha alone decides: solid, or a hole everywhere
        // (its primitives are left out).
        invisible.push(cutoff.is_some_and(|c| base_info.is_none() && base_alpha < c));
        materials.push(mat);
    }
    // The specification's default material (white, metallic 1, roughness 1), added after
    // the others if a primitive has no material.
    let default_material = materials.len() as u32;
    let mut uses_default = false;
    let double_sided: Vec<bool> = doc.materials().map(|m| m.double_sided()).collect();

    let scene = doc
        .default_scene()
        .or_else(|| doc.scenes().next())
        .ok_or_else(|| Error(format!("scene '{name}' has no scene to render")))?;
    let mut triangles = Vec::new();
    let mut camera = None;
    // KHR_lights_punctual: the first directional light is the sun; point and spot lights
    // become small emitters once the scene's size is known (`gltf_lights`).
    let mut sun: Option<SceneSun> = None;
    let mut point_lights: Vec<PointLight> = Vec::new();
    let placed = placed_nodes(name, &doc, scene)?;
    check_memory(name, &placed)?;
    // Skins' joints: every node's world transform (a joint need not be in the scene's tree).
    let worlds = match doc.skins().len() {
        0 => Vec::new(),
        _ => crate::gltf_skin::world_transforms(&doc),
    };
    for (node, world) in placed {
        if let (None, Some(cam)) = (camera, node.camera()) {
            if let gltf::camera::Projection::Perspective(p) = cam.projection() {
                let eye = world.transform_point3(Vec3::ZERO);
                let forward = world.transform_vector3(-Vec3::Z);
                let up = world.transform_vector3(Vec3::Y);
                camera = Some(CameraHint {
                    eye: eye.as_dvec3(),
                    target: (eye + forward.normalize_or_zero()).as_dvec3(),
                    up,
                    fov: p.yfov().to_degrees(),
                });
            }
        }
        if let Some(light) = node.light() {
            let value = radiometric(light.color(), light.intensity())
                .map_err(|e| Error(format!("scene '{name}': light {}: {e}", light.index())))?;
            let position = world.transform_point3(Vec3::ZERO);
            // Lights shine along their node's −z.
            let forward = world.transform_vector3(-Vec3::Z).normalize_or_zero();
            match light.kind() {
                gltf::khr_lights_punctual::Kind::Directional if sun.is_none() => {
                    if forward == Vec3::ZERO {
                        bail!("scene '{name}': light {} has no direction", light.index());
                    }
                    sun = Some(SceneSun {
                        direction: -forward,
                        irradiance: value,
                    });
                }
                gltf::khr_lights_punctual::Kind::Directional => {
                    ignored.push("directional lights after the first");
                }
                gltf::khr_lights_punctual::Kind::Point => point_lights.push(PointLight {
                    position,
                    intensity: value,
                    spot: None,
                }),
                gltf::khr_lights_punctual::Kind::Spot { .. } => {
                    spots += 1;
                    point_lights.push(PointLight {
                        position,
                        intensity: value,
                        spot: Some(forward).filter(|f| *f != Vec3::ZERO),
                    })
                }
            }
        }
        let Some(mesh) = node.mesh() else { continue };
        let normal_matrix = Mat3::from_mat4(world).inverse().transpose();
        for prim in mesh.primitives() {
            if prim.mode() != gltf::mesh::Mode::Triangles {
                ignored.push("primitives other than triangle lists");
                continue;
            }
            let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
            // An accessor the primitive names but that cannot be read (outside its buffer
            // view, or of a type its attribute does not take) is refused: reading on
            // without it would draw other triangles (indices) or other shading (normals,
            // ...) than the file's.
            let at = format!(
                "scene '{name}': mesh {} primitive {}",
                mesh.index(),
                prim.index()
            );
            let Some(positions) = vertex::vectors::<3>(&prim, Semantic::Positions, &buffers, &at)?
            else {
                ignored.push("primitives without POSITION");
                continue;
            };
            // A skinned primitive's vertices each have their own transform (`gltf_skin`).
            let skin = crate::gltf_skin::Skinning::read(
                &node,
                &prim,
                &worlds,
                &buffers,
                positions.len(),
                &at,
            )?;
            let place = |v: usize| skin.as_ref().map_or(world, |s| s.matrix(v));
            let positions: Vec<Vec3> = positions
                .into_iter()
                .enumerate()
                .map(|(v, p)| place(v).transform_point3(Vec3::from(p)))
                .collect();
            let normals: Option<Vec<Vec3>> =
                vertex::vectors::<3>(&prim, Semantic::Normals, &buffers, &at)?.map(|n| {
                    n.into_iter()
                        .enumerate()
                        .map(|(v, n)| {
                            let m = match &skin {
                                Some(s) => Mat3::from_mat4(s.matrix(v)).inverse().transpose(),
                                None => normal_matrix,
                            };
                            (m * Vec3::from(n)).normalize_or_zero()
                        })
                        .collect()
                });
            if let (Some(a), None) = (prim.get(&Semantic::Colors(0)), reader.read_colors(0)) {
                return Err(vertex::unreadable(&at, "COLOR_0", &a, vertex::OUTSIDE));
            }
            let material_index = prim.material().index();
            // glTF's v runs down the image; our textures put v = 0 at the bottom row.
            let uv_map = material_index.map_or(Affine2::IDENTITY, |i| uv_maps[i]);
            let uvs: Option<Vec<Vec2>> =
                vertex::vectors::<2>(&prim, Semantic::TexCoords(0), &buffers, &at)?.map(|t| {
                    t.into_iter()
                        .map(|uv| {
                            let t = uv_map.transform_point2(Vec2::from(uv));
                            Vec2::new(t.x, 1.0 - t.y)
                        })
                        .collect()
                });
            // A mask is read at texture coordinates: a primitive without them can still
            // read a constant one (BLEND by the factor alone).
            let constant_mask = material_index
                .is_some_and(|i| attributes.is_constant(materials[i].opacity_texture));
            let uvs = uvs.or_else(|| constant_mask.then(|| vec![Vec2::ZERO; positions.len()]));
            // TANGENT: directions like positions' (not normals'); a mirroring transform
            // turns the bitangent's side.
            let mirrors = |v: usize| Mat3::from_mat4(place(v)).determinant() < 0.0;
            let mirror = |v: usize| if mirrors(v) { -1.0 } else { 1.0 };
            let tangents: Option<Vec<Vec4>> =
                vertex::vectors::<4>(&prim, Semantic::Tangents, &buffers, &at)?.map(|t| {
                    t.into_iter()
                        .enumerate()
                        .map(|(v, [x, y, z, w])| {
                            place(v)
                                .transform_vector3(Vec3::new(x, y, z))
                                .extend(w * mirror(v))
                        })
                        .collect()
                });
            // COLOR_0 is linear (the specification), alpha ignored.
            let colours: Option<Vec<Vec3>> = reader
                .read_colors(0)
                .map(|c| c.into_rgb_f32().map(Vec3::from).collect());
            let indices: Vec<u32> = match (reader.read_indices(), prim.indices()) {
                (Some(i), _) => i.into_u32().collect(),
                (None, None) => (0..positions.len() as u32).collect(),
                (None, Some(a)) => {
                    return Err(vertex::unreadable(&at, "indices", &a, vertex::OUTSIDE))
                }
            };
            if material_index.is_some_and(|i| invisible[i]) {
                continue;
            }
            let material = material_index.map_or(default_material, |i| i as u32);
            uses_default |= material_index.is_none();
            let two_sided_emitter =
                material_index.is_some_and(|i| double_sided[i] && materials[i].is_emissive());
            for face in indices.as_chunks::<3>().0 {
                let mut corners = [face[0] as usize, face[1] as usize, face[2] as usize];
                if corners.iter().any(|&c| c >= positions.len()) {
                    bail!(
                        "scene '{name}': index {} is out of range ({} vertices)",
                        corners.iter().max().unwrap(),
                        positions.len()
                    );
                }
                // Mirrored where its first corner's transform is (a skin's vary by vertex).
                if mirrors(corners[0]) {
                    corners.swap(1, 2);
                }
                let mut sides = vec![corners];
                if two_sided_emitter {
                    sides.push([corners[0], corners[2], corners[1]]);
                }
                for c in sides {
                    let mut t =
                        Triangle::new(positions[c[0]], positions[c[1]], positions[c[2]], material);
                    let corner_normals = normals
                        .as_ref()
                        .map(|n| c.map(|i| n.get(i).copied().unwrap_or(Vec3::ZERO)));
                    let corner_uvs = uvs
                        .as_ref()
                        .map(|uv| c.map(|i| uv.get(i).copied().unwrap_or(Vec2::ZERO)));
                    let corner_colours = colours
                        .as_ref()
                        .map(|col| c.map(|i| col.get(i).copied().unwrap_or(Vec3::ONE)));
                    attributes.attach(&mut t, corner_normals, corner_uvs, corner_colours);
                    if let Some(tangents) = &tangents {
                        let corner = |i: usize| tangents.get(i).copied().unwrap_or(Vec4::ZERO);
                        attributes.attach_tangents(&t, c.map(corner));
                    }
                    triangles.push(t);
                }
            }
        }
    }
    if uses_default {
        materials.push(Material::conductor(Vec3::ONE, 1.0));
    }
    if !point_lights.is_empty() {
        let radius = crate::gltf_lights::RADIUS_SHARE * extent(&triangles, &point_lights);
        let (more, mut emitting) =
            crate::gltf_lights::emitters(&point_lights, radius, materials.len() as u32)
                .map_err(|e| Error(format!("scene '{name}': {e}")))?;
        triangles.extend(more);
        materials.append(&mut emitting);
    }
    if spots > 0 {
        warnings.push(format!(
            "'{name}': {spots} spot light(s) drawn as small discs facing along the spot: \
             the intensity on the axis is kept, the cone's angles are not (a cosine falloff)"
        ));
    }
    ignored.sort_unstable();
    let mut kinds = ignored.clone();
    kinds.dedup();
    for kind in kinds {
        let n = ignored.iter().filter(|k| **k == kind).count();
        warnings.push(format!(
            "'{name}': {kind} ({n}) are not supported yet; ignored"
        ));
    }
    let mut scene = Scene::with_attributes(triangles, materials, attributes)
        .map_err(|e| Error(format!("scene '{name}': {e}")))?;
    warnings.append(&mut scene.warnings);
    scene.warnings = warnings;
    scene.camera = camera;
    scene.sun = sun;
    Ok(scene)
}

/// The scene's nodes with their world transforms, each parent before its children (in the
/// order the loader has always visited them: the first camera and sun found are kept).
fn placed_nodes<'a>(
    name: &str,
    doc: &'a gltf::Document,
    scene: gltf::Scene<'a>,
) -> Result<Vec<(gltf::Node<'a>, Mat4)>> {
    let mut placed = Vec::new();
    let mut stack: Vec<(gltf::Node, Mat4)> = scene.nodes().map(|n| (n, Mat4::IDENTITY)).collect();
    while let Some((node, parent)) = stack.pop() {
        // Node graphs are trees by the specification; a file that says otherwise (a node
        // that is its own ancestor, or a child of many) must neither hang nor multiply.
        if placed.len() > doc.nodes().len() * 4 + 16 {
            bail!("scene '{name}': the node hierarchy is not a tree");
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        stack.extend(node.children().map(|c| (c, world)));
        placed.push((node, world));
    }
    Ok(placed)
}

/// Bytes a primitive's vertex arrays hold while it is read: positions, normals, tangents,
/// texture coordinates, colours, and a skin's joints and weights (12 + 12 + 16 + 8 + 12 +
/// 24).
const BYTES_PER_GLTF_VERTEX: u64 = 84;

/// Refuses, before reading any geometry, a scene whose triangles cannot fit in memory: a
/// small file can name many (a mesh placed by many nodes, or a sparse accessor without a
/// buffer view, whose count alone says how many vertices it has). Counts as the loader
/// reads: the triangle lists' indices (or vertices) over 3.
fn check_memory(name: &str, placed: &[(gltf::Node, Mat4)]) -> Result<()> {
    let mut triangles = 0u64;
    let mut largest_primitive = 0u64;
    for mesh in placed.iter().filter_map(|(node, _)| node.mesh()) {
        for prim in mesh.primitives() {
            if prim.mode() != gltf::mesh::Mode::Triangles {
                continue;
            }
            let vertices = prim.get(&Semantic::Positions).map_or(0, |a| a.count()) as u64;
            let corners = prim.indices().map_or(vertices, |a| a.count() as u64);
            triangles = triangles.saturating_add(corners / 3);
            let bytes = (vertices * BYTES_PER_GLTF_VERTEX).saturating_add(corners * 4);
            largest_primitive = largest_primitive.max(bytes);
        }
    }
    let per_triangle = crate::memory::BYTES_PER_SCENE_TRIANGLE
        + std::mem::size_of::<kernels::types::TriangleShading>() as u64;
    crate::memory::check_scene(
        &format!("scene '{name}' ({triangles} triangles)"),
        triangles as f64 * per_triangle as f64 + largest_primitive as f64,
    )
}

/// The diagonal of the box around the triangles and the lights (1 for a single light).
fn extent(triangles: &[Triangle], lights: &[PointLight]) -> f32 {
    let points = crate::scene::corners(triangles).chain(lights.iter().map(|l| l.position));
    let (lo, hi) = crate::scene::bounds_of(points);
    let diagonal = (hi - lo).length();
    if diagonal > 0.0 && diagonal.is_finite() {
        diagonal
    } else {
        1.0
    }
}
