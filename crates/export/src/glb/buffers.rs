//! The binary chunk of `world.glb`: little-endian bytes of f32 arrays, buffer views appended
//! at 4-byte boundaries, and the f32 accessors over them.

use gltf_json as json;
use json::validation::Checked::Valid;
use json::validation::USize64;

pub(super) fn bytes_of(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

pub(super) fn bytes_of_3(v: &[[f32; 3]]) -> Vec<u8> {
    v.iter().flatten().flat_map(|x| x.to_le_bytes()).collect()
}

pub(super) fn bytes_of_4(v: &[[f32; 4]]) -> Vec<u8> {
    v.iter().flatten().flat_map(|x| x.to_le_bytes()).collect()
}

/// A buffer view over `bytes`, appended to `bin` at a 4-byte boundary.
pub(super) fn view(
    root: &mut json::Root,
    bin: &mut Vec<u8>,
    bytes: Vec<u8>,
    target: Option<json::buffer::Target>,
) -> json::Index<json::buffer::View> {
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let offset = bin.len();
    bin.extend_from_slice(&bytes);
    root.push(json::buffer::View {
        buffer: json::Index::new(0),
        byte_length: USize64::from(bytes.len()),
        byte_offset: Some(USize64::from(offset)),
        byte_stride: None,
        name: None,
        target: target.map(Valid),
        extensions: None,
        extras: None,
    })
}

pub(super) fn accessor(
    view: json::Index<json::buffer::View>,
    offset: usize,
    count: usize,
    type_: json::accessor::Type,
    bounds: Option<(Vec<f32>, Vec<f32>)>,
) -> json::Accessor {
    let (min, max) = match bounds {
        Some((min, max)) => (Some(json::Value::from(min)), Some(json::Value::from(max))),
        None => (None, None),
    };
    json::Accessor {
        buffer_view: Some(view),
        byte_offset: Some(USize64::from(offset)),
        count: USize64::from(count),
        component_type: Valid(json::accessor::GenericComponentType(
            json::accessor::ComponentType::F32,
        )),
        extensions: None,
        extras: None,
        type_: Valid(type_),
        min,
        max,
        name: None,
        normalized: false,
        sparse: None,
    }
}
