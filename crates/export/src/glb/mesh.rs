//! The one character mesh every node of `world.glb` shares: a capsule standing on the ground,
//! facing +Z.

use super::buffers::{accessor, bytes_of_3, view};
use gltf_json as json;
use json::validation::Checked::Valid;

/// Character height, metres.
const HEIGHT_M: f32 = 1.8;

/// A capsule of `radius` standing on the ground, `HEIGHT_M` tall (its front is +Z, the
/// direction the rotation keys turn towards the walk); returns its mesh.
pub(super) fn capsule(
    root: &mut json::Root,
    bin: &mut Vec<u8>,
    radius: f32,
) -> json::Index<json::Mesh> {
    const SEGMENTS: usize = 16;
    const RINGS: usize = 6; // per hemisphere
    let mut pos: Vec<[f32; 3]> = Vec::new();
    let mut nor: Vec<[f32; 3]> = Vec::new();
    // Rings from the bottom pole to the top pole: bottom hemisphere, then top.
    let mut rings: Vec<(f32, f32, f32)> = Vec::new(); // (y of centre, sin, cos) per ring
    for k in 0..=RINGS {
        let a =
            -std::f32::consts::FRAC_PI_2 + std::f32::consts::FRAC_PI_2 * k as f32 / RINGS as f32;
        rings.push((radius, a.sin(), a.cos()));
    }
    for k in 0..=RINGS {
        let a = std::f32::consts::FRAC_PI_2 * k as f32 / RINGS as f32;
        rings.push((HEIGHT_M - radius, a.sin(), a.cos()));
    }
    for &(cy, s, c) in &rings {
        for j in 0..=SEGMENTS {
            let phi = std::f32::consts::TAU * j as f32 / SEGMENTS as f32;
            let (nx, nz) = (c * phi.cos(), c * phi.sin());
            pos.push([radius * nx, cy + radius * s, radius * nz]);
            nor.push([nx, s, nz]);
        }
    }
    let row = SEGMENTS + 1;
    let mut idx: Vec<u16> = Vec::new();
    for k in 0..rings.len() - 1 {
        for j in 0..SEGMENTS {
            let (a, b) = ((k * row + j) as u16, ((k + 1) * row + j) as u16);
            // Counter-clockwise seen from outside.
            idx.extend_from_slice(&[a, b, a + 1, a + 1, b, b + 1]);
        }
    }
    let (mut min, mut max) = ([f32::MAX; 3], [f32::MIN; 3]);
    for p in &pos {
        for i in 0..3 {
            min[i] = min[i].min(p[i]);
            max[i] = max[i].max(p[i]);
        }
    }
    let vertices = pos.len();
    let pv = view(
        root,
        bin,
        bytes_of_3(&pos),
        Some(json::buffer::Target::ArrayBuffer),
    );
    let nv = view(
        root,
        bin,
        bytes_of_3(&nor),
        Some(json::buffer::Target::ArrayBuffer),
    );
    let iv = view(
        root,
        bin,
        idx.iter().flat_map(|i| i.to_le_bytes()).collect(),
        Some(json::buffer::Target::ElementArrayBuffer),
    );
    let positions = root.push(accessor(
        pv,
        0,
        vertices,
        json::accessor::Type::Vec3,
        Some((min.to_vec(), max.to_vec())),
    ));
    let normals = root.push(accessor(nv, 0, vertices, json::accessor::Type::Vec3, None));
    let mut indices = accessor(iv, 0, idx.len(), json::accessor::Type::Scalar, None);
    indices.component_type = Valid(json::accessor::GenericComponentType(
        json::accessor::ComponentType::U16,
    ));
    let indices = root.push(indices);
    let material = root.push(json::Material {
        name: Some("crowd".to_string()),
        ..Default::default()
    });
    root.push(json::Mesh {
        name: Some("character".to_string()),
        primitives: vec![json::mesh::Primitive {
            attributes: [
                (Valid(json::mesh::Semantic::Positions), positions),
                (Valid(json::mesh::Semantic::Normals), normals),
            ]
            .into_iter()
            .collect(),
            indices: Some(indices),
            material: Some(material),
            mode: Valid(json::mesh::Mode::Triangles),
            targets: None,
            extensions: None,
            extras: None,
        }],
        weights: None,
        extensions: None,
        extras: None,
    })
}
