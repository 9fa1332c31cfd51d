//! glTF vertex attributes read as floats whatever their components hold: `f32`, or the
//! integers of `KHR_mesh_quantization` (positions, normals, tangents, texture coordinates)
//! and of core glTF (normalized texture coordinates). gltf's own readers take every
//! POSITION, NORMAL and TANGENT as `f32`, and would read a quantized one's bytes as floats.

use gltf::accessor::{DataType, Dimensions, Item, Iter};
use gltf::Semantic;

use crate::error::Error;

/// Why an accessor that reaches outside its data cannot be read.
pub const OUTSIDE: &str = "reaches past the end of its buffer view or buffer";

/// The error for `primitive`'s accessor of `what` ("POSITION", "indices") that cannot be
/// read, and `why`; `primitive` as "scene 'x.gltf': mesh 0 primitive 1".
pub fn unreadable(primitive: &str, what: &str, accessor: &gltf::Accessor, why: &str) -> Error {
    Error(format!(
        "{primitive}: its {what} accessor {} {why}",
        accessor.index()
    ))
}

/// The primitive's `semantic` attribute as `N` floats a vertex (`None`: it has none); an
/// accessor that cannot be read is an error naming it (see `unreadable`). Normalized
/// integers map to [0, 1] (unsigned) or [−1, 1] (signed) as glTF specifies; the others
/// keep their whole numbers, which the node's transform (positions) or the texture
/// transform (texture coordinates) scales back.
pub fn vectors<const N: usize>(
    prim: &gltf::Primitive,
    semantic: Semantic,
    buffers: &[gltf::buffer::Data],
    primitive: &str,
) -> crate::error::Result<Option<Vec<[f32; N]>>>
where
    [f32; N]: Item,
    [i8; N]: Item,
    [u8; N]: Item,
    [i16; N]: Item,
    [u16; N]: Item,
{
    let Some(accessor) = prim.get(&semantic) else {
        return Ok(None);
    };
    let refuse = |why: &str| unreadable(primitive, &semantic.to_string(), &accessor, why);
    let dimensions = accessor.dimensions();
    if dimensions.multiplicity() != N || !is_vector(dimensions) {
        let why = format!(
            "holds {} values where VEC{N} ones belong",
            type_name(dimensions)
        );
        return Err(refuse(&why));
    }
    let accessor = &accessor;
    let normalized = accessor.normalized();
    let values = match accessor.data_type() {
        DataType::F32 => dequantized(accessor, buffers, |x: f32| x),
        DataType::I8 if normalized => dequantized(accessor, buffers, |x: i8| {
            (f32::from(x) / f32::from(i8::MAX)).max(-1.0)
        }),
        DataType::U8 if normalized => {
            dequantized(accessor, buffers, |x: u8| f32::from(x) / f32::from(u8::MAX))
        }
        DataType::I16 if normalized => dequantized(accessor, buffers, |x: i16| {
            (f32::from(x) / f32::from(i16::MAX)).max(-1.0)
        }),
        DataType::U16 if normalized => dequantized(accessor, buffers, |x: u16| {
            f32::from(x) / f32::from(u16::MAX)
        }),
        DataType::I8 => dequantized(accessor, buffers, |x: i8| f32::from(x)),
        DataType::U8 => dequantized(accessor, buffers, |x: u8| f32::from(x)),
        DataType::I16 => dequantized(accessor, buffers, |x: i16| f32::from(x)),
        DataType::U16 => dequantized(accessor, buffers, |x: u16| f32::from(x)),
        DataType::U32 => {
            return Err(refuse(
                "holds 32-bit integers, which glTF allows only for indices",
            ));
        }
    };
    values.map(Some).ok_or_else(|| refuse(OUTSIDE))
}

/// The accessor's items of `T`, each component through `to_f32`; `None` where they do
/// not fit in its buffer view (or it has neither a view nor sparse values).
fn dequantized<T: Copy, const N: usize>(
    accessor: &gltf::Accessor,
    buffers: &[gltf::buffer::Data],
    to_f32: impl Fn(T) -> f32,
) -> Option<Vec<[f32; N]>>
where
    [T; N]: Item,
{
    // An empty accessor: gltf's reader would work out its end as `count - 1` items.
    if accessor.count() == 0 {
        return Some(Vec::new());
    }
    let data = |b: gltf::Buffer| buffers.get(b.index()).map(|d| &d.0[..]);
    let items = Iter::<[T; N]>::new(accessor.clone(), data)?;
    Some(items.map(|item| item.map(&to_f32)).collect())
}

fn is_vector(dimensions: Dimensions) -> bool {
    matches!(
        dimensions,
        Dimensions::Vec2 | Dimensions::Vec3 | Dimensions::Vec4
    )
}

/// The accessor type as glTF spells it.
fn type_name(dimensions: Dimensions) -> &'static str {
    match dimensions {
        Dimensions::Scalar => "SCALAR",
        Dimensions::Vec2 => "VEC2",
        Dimensions::Vec3 => "VEC3",
        Dimensions::Vec4 => "VEC4",
        Dimensions::Mat2 => "MAT2",
        Dimensions::Mat3 => "MAT3",
        Dimensions::Mat4 => "MAT4",
    }
}
