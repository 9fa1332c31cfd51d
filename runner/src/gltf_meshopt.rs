//! `EXT_meshopt_compression` (gltfpack's `-c`, three.js and Babylon assets): buffer views
//! stored compressed, each decoded into the buffer the file's accessors read, before any
//! of them is read. The codecs are meshoptimizer's own decoders (`meshopt`, which it
//! documents as safe on untrusted input); the filters that follow them are the
//! extension's Appendix B, written here (the crate does not build meshoptimizer's).
//! The buffer a compressed view decodes into is usually a placeholder that has a length
//! and no data (`is_placeholder`): it starts zeroed.
use gltf::json::Value;

use crate::bail;
use crate::error::Result;

pub const EXTENSION: &str = "EXT_meshopt_compression";

/// Whether `buffer` only reserves room for decoded views: marked `fallback` by the
/// extension, or without data of its own (no URI and, `blob_left` false, no GLB chunk
/// left for it) in a file that uses the extension.
pub fn is_placeholder(document: &gltf::Document, buffer: &gltf::Buffer, blob_left: bool) -> bool {
    let marked = buffer
        .extension_value(EXTENSION)
        .and_then(|e| e.get("fallback"))
        .and_then(Value::as_bool)
        == Some(true);
    let dataless = matches!(buffer.source(), gltf::buffer::Source::Bin) && !blob_left;
    marked || (dataless && document.extensions_used().any(|e| e == EXTENSION))
}

/// Decode every compressed buffer view of `document` into `buffers`; an error says which
/// view and why.
pub fn decode_views(document: &gltf::Document, buffers: &mut [gltf::buffer::Data]) -> Result<()> {
    for view in document.views() {
        let Some(ext) = view.extension_value(EXTENSION) else {
            continue;
        };
        decode_view(&view, ext, buffers)
            .map_err(|e| crate::error::Error(format!("its buffer view {}: {e}", view.index())))?;
    }
    Ok(())
}

fn decode_view(
    view: &gltf::buffer::View,
    ext: &Value,
    buffers: &mut [gltf::buffer::Data],
) -> Result<()> {
    let number = |key: &str| ext.get(key).and_then(Value::as_u64).map(|n| n as usize);
    let (Some(source), Some(length), Some(stride), Some(count)) = (
        number("buffer"),
        number("byteLength"),
        number("byteStride"),
        number("count"),
    ) else {
        bail!("its {EXTENSION} lacks buffer, byteLength, byteStride or count");
    };
    let offset = number("byteOffset").unwrap_or(0);
    let mode = ext.get("mode").and_then(Value::as_str).unwrap_or("");
    let filter = ext.get("filter").and_then(Value::as_str).unwrap_or("NONE");
    let decoded_length = stride.checked_mul(count).filter(|&n| n == view.length());
    if decoded_length.is_none() || view.stride().is_some_and(|s| s != stride) {
        bail!(
            "{count} elements of {stride} bytes do not fill its {} bytes (stride {:?})",
            view.length(),
            view.stride()
        );
    }
    let valid_stride = match (mode, filter) {
        ("ATTRIBUTES", "NONE") => stride % 4 == 0 && stride <= 256,
        ("ATTRIBUTES", "OCTAHEDRAL") => stride == 4 || stride == 8,
        ("ATTRIBUTES", "QUATERNION") => stride == 8,
        ("ATTRIBUTES", "EXPONENTIAL") => stride % 4 == 0 && stride <= 256,
        ("TRIANGLES", "NONE") => (stride == 2 || stride == 4) && count % 3 == 0,
        ("INDICES", "NONE") => stride == 2 || stride == 4,
        _ => bail!("mode '{mode}' with filter '{filter}' is not one the extension defines"),
    };
    if !valid_stride {
        bail!("a byte stride of {stride} ({count} elements) is not allowed for mode '{mode}' with filter '{filter}'");
    }
    let compressed = buffers
        .get(source)
        .and_then(|b| b.get(offset..offset.checked_add(length)?))
        .ok_or_else(|| {
            crate::error::Error(format!(
                "its compressed bytes {offset}..+{length} lie outside buffer {source}"
            ))
        })?;
    // The decoded view's place, checked before anything the size of `count` is made.
    let target = view.buffer().index();
    let start = view.offset();
    if buffers[target].len() < start + view.length() {
        bail!("it lies outside buffer {target}");
    }
    let mut decoded = vec![0u8; view.length()];
    // SAFETY: each decoder writes `count` elements of `stride` bytes, which is `decoded`'s
    // length, and reads at most `compressed.len()` bytes from it.
    let status = unsafe {
        let out = decoded.as_mut_ptr().cast();
        let (data, size) = (compressed.as_ptr(), compressed.len());
        match mode {
            "ATTRIBUTES" => {
                meshopt::ffi::meshopt_decodeVertexBuffer(out, count, stride, data, size)
            }
            "TRIANGLES" => meshopt::ffi::meshopt_decodeIndexBuffer(out, count, stride, data, size),
            _ => meshopt::ffi::meshopt_decodeIndexSequence(out, count, stride, data, size),
        }
    };
    if status != 0 {
        bail!("its {mode} data cannot be decoded (meshoptimizer's error {status})");
    }
    match filter {
        "OCTAHEDRAL" if stride == 4 => each::<4>(&mut decoded, octahedral::<1>),
        "OCTAHEDRAL" => each::<8>(&mut decoded, octahedral::<2>),
        "QUATERNION" => each::<8>(&mut decoded, quaternion),
        "EXPONENTIAL" => each::<4>(&mut decoded, exponential),
        _ => {}
    }
    buffers[target].0[start..start + view.length()].copy_from_slice(&decoded);
    Ok(())
}

/// `filter` applied to each `S` bytes of `data`.
fn each<const S: usize>(data: &mut [u8], filter: fn(&mut [u8])) {
    for element in data.as_chunks_mut::<S>().0 {
        filter(element);
    }
}

/// A signed little-endian integer of `N` bytes (1 or 2) at component `i` of `element`.
fn component<const N: usize>(element: &[u8], i: usize) -> i32 {
    if N == 1 {
        element[i] as i8 as i32
    } else {
        i16::from_le_bytes([element[2 * i], element[2 * i + 1]]) as i32
    }
}

fn set_component<const N: usize>(element: &mut [u8], i: usize, value: i32) {
    if N == 1 {
        element[i] = value as i8 as u8;
    } else {
        element[2 * i..2 * i + 2].copy_from_slice(&(value as i16).to_le_bytes());
    }
}

/// Filter 1: a unit vector from its octahedral x and y, in K-bit integers whose 1.0 is the
/// third component; out as N-byte normalized integers, the fourth component kept.
fn octahedral<const N: usize>(element: &mut [u8]) {
    let max = if N == 1 { 127.0 } else { 32767.0 };
    let one = component::<N>(element, 2) as f32;
    let mut x = component::<N>(element, 0) as f32 / one;
    let mut y = component::<N>(element, 1) as f32 / one;
    let z = 1.0 - x.abs() - y.abs();
    // The lower hemisphere is folded over the diagonals.
    let t = z.min(0.0);
    x -= t.copysign(x);
    y -= t.copysign(y);
    let length = (x * x + y * y + z * z).sqrt();
    for (i, c) in [x, y, z].into_iter().enumerate() {
        set_component::<N>(element, i, (c / length * max).round() as i32);
    }
}

/// Filter 2: a unit quaternion from its three smaller components (scaled by √2) and the
/// index of the largest, in 16-bit integers.
fn quaternion(element: &mut [u8]) {
    let range = std::f32::consts::FRAC_1_SQRT_2;
    let last = component::<2>(element, 3);
    let one = (last | 3) as f32;
    let [x, y, z] = [0, 1, 2].map(|i| component::<2>(element, i) as f32 / one * range);
    let w = (1.0 - x * x - y * y - z * z).max(0.0).sqrt();
    let largest = (last & 3) as usize;
    for (k, c) in [w, x, y, z].into_iter().enumerate() {
        set_component::<2>(element, (largest + k) % 4, (c * 32767.0).round() as i32);
    }
}

/// Filter 3: a float from a signed 8-bit exponent and 24-bit mantissa (2^e · m).
fn exponential(element: &mut [u8]) {
    let input = i32::from_le_bytes([element[0], element[1], element[2], element[3]]);
    let (e, m) = (input >> 24, (input << 8) >> 8);
    let value = 2f32.powi(e) * m as f32;
    element.copy_from_slice(&value.to_le_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bytes_i16(values: [i16; 4]) -> Vec<u8> {
        values.iter().flat_map(|v| v.to_le_bytes()).collect()
    }

    #[test]
    fn filters_decode_as_the_extension_specifies() {
        // Octahedral, 8-bit, K = 8: (0, 0) is +z; (127, 0) is +x; a lower-hemisphere point.
        let mut e = [0u8, 0, 127, 9];
        octahedral::<1>(&mut e);
        assert_eq!(e, [0, 0, 127, 9]);
        let mut e = [127u8, 0, 127, 0];
        octahedral::<1>(&mut e);
        assert_eq!(e, [127, 0, 0, 0]);
        // x = y = 0.75 (16-bit, K = 16): z = 1 − 1.5 = −0.5, below the diagonals, so x and
        // y move 0.5 towards 0: (0.25, 0.25, −0.5), then normalized.
        let mut e = bytes_i16([24575, 24575, 32767, 0]);
        octahedral::<2>(&mut e);
        let x0 = 24575.0f32 / 32767.0;
        let z = 1.0 - x0 - x0;
        let x = x0 + z;
        let length = (2.0 * x * x + z * z).sqrt();
        let expect = |c: f32| (c / length * 32767.0).round() as i16;
        assert_eq!(e, bytes_i16([expect(x), expect(x), expect(z), 0]));
        // Quaternion: the identity, w largest (index 3 → w lands at (3 + 0) % 4).
        let mut e = bytes_i16([0, 0, 0, (32767 & !3) | 3]);
        quaternion(&mut e);
        assert_eq!(e, bytes_i16([0, 0, 0, 32767]));
        // Exponential: −3 · 2^−2 = −0.75.
        let mut e = ((-2i32 << 24) | (-3i32 & 0xff_ffff)).to_le_bytes();
        exponential(&mut e);
        assert_eq!(f32::from_le_bytes(e), -0.75);
    }
}
