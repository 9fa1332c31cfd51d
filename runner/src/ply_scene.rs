//! PLY meshes (ASCII and binary, as scanners write them) through the `ply-rs-bw` crate:
//! `vertex` elements with x, y, z (and nx, ny, nz as vertex normals when present), `face`
//! elements with a `vertex_indices` (or `vertex_index`) list, polygons split as OBJ's are
//! (`scene::triangulate_polygon`).
//! A PLY carries no material: surfaces are Lambertian grey (`scene::DEFAULT_ALBEDO`).
use std::path::Path;

use glam::{DVec3, Vec3};
use kernels::types::{Material, Triangle};
use ply_rs_bw::ply::Property;

use crate::bail;
use crate::error::{Error, Result};
use crate::scene::{read_input_file, Scene, SurfaceAttributes, DEFAULT_ALBEDO};

/// Largest PLY file read.
pub const MAX_PLY_BYTES: u64 = 2 << 30;
/// Bytes of memory per byte of PLY file while it is parsed (the parser keeps a map of
/// properties per element: about 16x a binary file, measured loosely; text is smaller).
const BYTES_PER_PLY_BYTE: f64 = 16.0;

pub fn is_ply(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("ply"))
}

/// A scalar property as f64 (every kind converts exactly): positions stay in f64 until
/// they are moved near the origin (`scene_frame`), normals are rounded to f32 at once.
fn scalar(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => v as f64,
        Property::UChar(v) => v as f64,
        Property::Short(v) => v as f64,
        Property::UShort(v) => v as f64,
        Property::Int(v) => v as f64,
        Property::UInt(v) => v as f64,
        Property::Float(v) => v as f64,
        Property::Double(v) => v,
        _ => return None,
    })
}

/// A list property as indices (negative entries are refused by the caller as out of range).
fn indices(p: &Property) -> Option<Vec<i64>> {
    Some(match p {
        Property::ListChar(v) => v.iter().map(|&x| x as i64).collect(),
        Property::ListUChar(v) => v.iter().map(|&x| x as i64).collect(),
        Property::ListShort(v) => v.iter().map(|&x| x as i64).collect(),
        Property::ListUShort(v) => v.iter().map(|&x| x as i64).collect(),
        Property::ListInt(v) => v.iter().map(|&x| x as i64).collect(),
        Property::ListUInt(v) => v.iter().map(|&x| x as i64).collect(),
        _ => return None,
    })
}

/// A vertex's colour as a linear albedo factor: `red`/`green`/`blue` (or `diffuse_*`), as
/// 0..255 integers or 0..1 floats of display (sRGB) values, as scanners write them.
fn vertex_colour(v: &ply_rs_bw::ply::DefaultElement) -> Option<Vec3> {
    let channel = |name: &str| {
        let p = v.get(name).or_else(|| v.get(&format!("diffuse_{name}")))?;
        Some(match p {
            Property::UChar(x) => *x as f32 / 255.0,
            Property::UShort(x) => *x as f32 / 65535.0,
            Property::Float(x) => *x,
            Property::Double(x) => *x as f32,
            _ => return None,
        })
    };
    let rgb = [channel("red")?, channel("green")?, channel("blue")?];
    Some(crate::scene::srgb_colour(&rgb))
}

pub fn load(path: &Path) -> Result<Scene> {
    let name = path.display().to_string();
    if let Ok(md) = std::fs::metadata(path) {
        crate::memory::check_scene(
            &format!("scene '{name}'"),
            md.len() as f64 * BYTES_PER_PLY_BYTE,
        )?;
    }
    let bytes = match read_input_file(path, MAX_PLY_BYTES) {
        Ok(b) => b,
        Err(e) => bail!("cannot read scene '{name}': {e}"),
    };
    parse_ply_bytes(&name, bytes)
}

/// A PLY file's bytes (named `name` in messages) as a scene.
pub fn parse_ply_bytes(name: &str, bytes: Vec<u8>) -> Result<Scene> {
    let parser = ply_rs_bw::parser::Parser::<ply_rs_bw::ply::DefaultElement>::new();
    let ply = parser
        .read_ply(&mut std::io::Cursor::new(bytes))
        // The parser's messages span lines; ours are one.
        .map_err(|e| {
            let e = e.to_string();
            let e = e.split_whitespace().collect::<Vec<_>>().join(" ");
            Error(format!("cannot load scene '{name}': {e}"))
        })?;
    let no_vertices = Vec::new();
    let vertices = ply.payload.get("vertex").unwrap_or(&no_vertices);
    let mut positions = Vec::with_capacity(vertices.len());
    let mut normals = Vec::with_capacity(vertices.len());
    let mut colours = Vec::with_capacity(vertices.len());
    for (i, v) in vertices.iter().enumerate() {
        let get = |k: &str| v.get(k).and_then(scalar);
        let (Some(x), Some(y), Some(z)) = (get("x"), get("y"), get("z")) else {
            bail!("scene '{name}': vertex {i} has no x, y, z");
        };
        let p = DVec3::new(x, y, z);
        if !p.as_vec3().is_finite() {
            bail!("scene '{name}': vertex {i} is not finite in f32 ({p})");
        }
        positions.push(p);
        if let (Some(nx), Some(ny), Some(nz)) = (get("nx"), get("ny"), get("nz")) {
            normals.push(DVec3::new(nx, ny, nz).as_vec3());
        }
        if let Some(c) = vertex_colour(v) {
            colours.push(c);
        }
    }
    // Far from the origin (georeferenced scans in f64): moved there before the rounding.
    // The box only decides whether to move (f32 precision, as for OBJ's `check_lines`).
    let (lo, hi) = crate::scene::bounds_of(positions.iter().map(|p| p.as_vec3()));
    let centre = crate::scene_frame::far_centre(lo.as_dvec3(), hi.as_dvec3());
    let positions: Vec<Vec3> = positions.iter().map(|&p| (p - centre).as_vec3()).collect();
    let has_normals = !normals.is_empty() && normals.len() == positions.len();
    let has_colours = !colours.is_empty() && colours.len() == positions.len();
    let mut warnings = Vec::new();
    let mut triangles = Vec::new();
    let mut corners = Vec::new();
    let mut attributes = SurfaceAttributes::default();
    let no_faces = Vec::new();
    for (f, face) in ply
        .payload
        .get("face")
        .unwrap_or(&no_faces)
        .iter()
        .enumerate()
    {
        let Some(list) = face
            .get("vertex_indices")
            .or_else(|| face.get("vertex_index"))
            .and_then(indices)
        else {
            bail!("scene '{name}': face {f} has no vertex_indices list");
        };
        if let Some(&bad) = list
            .iter()
            .find(|&&k| k < 0 || k as usize >= positions.len())
        {
            bail!(
                "scene '{name}': face {f} refers to vertex {bad} of {}",
                positions.len()
            );
        }
        corners.clear();
        crate::scene::triangulate_polygon(list.len(), &mut corners);
        for local in &corners {
            let c = local.map(|k| list[k] as usize);
            let mut t = Triangle::new(positions[c[0]], positions[c[1]], positions[c[2]], 0);
            let corner_normals = has_normals.then(|| c.map(|i| normals[i]));
            let corner_colours = has_colours.then(|| c.map(|i| colours[i]));
            attributes.attach(&mut t, corner_normals, None, corner_colours);
            triangles.push(t);
        }
    }
    let materials = vec![Material::new(Vec3::splat(DEFAULT_ALBEDO), Vec3::ZERO)];
    let mut scene = Scene::with_attributes(triangles, materials, attributes)
        .map_err(|e| Error(format!("scene '{name}': {e}")))?;
    warnings.append(&mut scene.warnings);
    scene.warnings = warnings;
    // The file's coordinates are the centred ones plus `centre`.
    scene.frame.centre += centre;
    Ok(scene)
}
