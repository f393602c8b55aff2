//! `world.glb`: the crowd as a glTF 2.0 scene an engine or a DCC tool loads (Y-up, metres,
//! world (x, y) -> glTF (x, 0, -y), DESIGN.md).
//!
//! One shared capsule mesh; one node per character slot (the runtime's ids, `walker_<id>`,
//! and `stander_<i>`); one animation, `crowd_loop`, that lasts exactly one period, with
//! translation and rotation keys at the trajectory points inside it and at 0 and the period.
//! A slot of a one-period loop has equal keys at 0 and at the period, so a looping player shows
//! no jump. A loop of k periods has k slots: slot j walks the loop's j-th period, and at the
//! clip's end stands where slot j + 1 starts, so the set of positions is continuous at every
//! time while each node, looping, hands its walker over to the next.
//!
//! `keys.rs` makes each slot's keys, `mesh.rs` the capsule, `buffers.rs` the binary chunk's
//! views and accessors; this file assembles the document.

mod buffers;
mod keys;
mod mesh;

use crate::characters::Links;
use buffers::{accessor, bytes_of, bytes_of_3, bytes_of_4, view};
use crowd_core::PatchGraph;
use crowd_core::trajectories::PatchMotion;
use glam::DVec2;
use gltf_json as json;
use json::validation::Checked::Valid;
use json::validation::USize64;
use keys::{Keys, gltf_point, loop_paths, slot_keys};
use mesh::capsule;

/// What `world.glb` is made from.
pub struct World<'a> {
    pub graph: &'a PatchGraph,
    pub motion: &'a [PatchMotion],
    pub links: &'a Links,
    pub period_s: f64,
    pub seed: u64,
    pub input_hash: String,
    /// Characters at time 0 inside `(x0, y0, x1, y1)` only.
    pub region: Option<(f64, f64, f64, f64)>,
}

/// The bytes of `world.glb`.
pub fn world_glb(w: &World) -> Vec<u8> {
    let mut root = json::Root {
        asset: json::Asset {
            version: "2.0".to_string(),
            generator: Some(format!("crowd {}", env!("CARGO_PKG_VERSION"))),
            ..Default::default()
        },
        ..Default::default()
    };
    let mut bin: Vec<u8> = Vec::new();
    let mesh = capsule(&mut root, &mut bin, w.graph.radius_m as f32);

    // Animation data goes into three views, one per kind, after the mesh.
    let (mut times, mut moves, mut turns): (Vec<f32>, Vec<[f32; 3]>, Vec<[f32; 4]>) =
        (Vec::new(), Vec::new(), Vec::new());
    struct Track {
        node: json::Index<json::Node>,
        first: usize,
        count: usize,
    }
    let mut tracks = Vec::new();
    let mut nodes = Vec::new();
    let period = w.period_s;
    let inside = |p: DVec2| {
        w.region
            .is_none_or(|(x0, y0, x1, y1)| p.x >= x0 && p.x < x1 && p.y >= y0 && p.y < y1)
    };
    let mut id = 0u32;
    for path in loop_paths(w) {
        let length = f64::from(path.laps) * period;
        for lap in 0..path.laps {
            let this = id;
            id += 1;
            // Loop time at clip time 0, as the runtime counts it.
            let tau0 = (-path.start - f64::from(lap) * period).rem_euclid(length);
            if !inside(path.at(tau0)) {
                continue;
            }
            let Keys {
                times: key_t,
                points: key_p,
                turns: q,
            } = slot_keys(&path, tau0, period);
            let node = root.push(json::Node {
                mesh: Some(mesh),
                name: Some(format!("walker_{this}")),
                translation: Some(gltf_point(key_p[0])),
                rotation: Some(json::scene::UnitQuaternion(q[0])),
                ..Default::default()
            });
            nodes.push(node);
            tracks.push(Track {
                node,
                first: times.len(),
                count: key_t.len(),
            });
            times.extend(key_t.iter().map(|&t| t as f32));
            moves.extend(key_p.iter().map(|&p| gltf_point(p)));
            turns.extend(q);
        }
    }
    let mut stander = 0;
    for (p, m) in w.motion.iter().enumerate() {
        let origin = w.graph.world_from_patch(w.graph.patches[p].cell);
        for s in &m.standers {
            let at = origin + *s;
            if inside(at) {
                nodes.push(root.push(json::Node {
                    mesh: Some(mesh),
                    name: Some(format!("stander_{stander}")),
                    translation: Some(gltf_point(at)),
                    ..Default::default()
                }));
            }
            stander += 1;
        }
    }

    if !tracks.is_empty() {
        let time_view = view(&mut root, &mut bin, bytes_of(&times), None);
        let move_view = view(&mut root, &mut bin, bytes_of_3(&moves), None);
        let turn_view = view(&mut root, &mut bin, bytes_of_4(&turns), None);
        let mut animation = json::Animation {
            name: Some("crowd_loop".to_string()),
            extras: Some(
                json::extras::RawValue::from_string(format!(
                    "{{\"loop\":true,\"period\":{}}}",
                    period
                ))
                .expect("valid JSON"),
            ),
            channels: Vec::new(),
            samplers: Vec::new(),
            extensions: None,
        };
        for tr in &tracks {
            let input = root.push(accessor(
                time_view,
                tr.first * 4,
                tr.count,
                json::accessor::Type::Scalar,
                // Every track runs over the whole clip: keys at 0 and at the period.
                Some((vec![0.0], vec![period as f32])),
            ));
            let mut channel = |output, path| {
                let sampler = json::Index::new(animation.samplers.len() as u32);
                animation.samplers.push(json::animation::Sampler {
                    input,
                    interpolation: Valid(json::animation::Interpolation::Linear),
                    output,
                    extensions: None,
                    extras: None,
                });
                animation.channels.push(json::animation::Channel {
                    sampler,
                    target: json::animation::Target {
                        node: tr.node,
                        path: Valid(path),
                        extensions: None,
                        extras: None,
                    },
                    extensions: None,
                    extras: None,
                });
            };
            for (view, size, type_, path) in [
                (
                    move_view,
                    12,
                    json::accessor::Type::Vec3,
                    json::animation::Property::Translation,
                ),
                (
                    turn_view,
                    16,
                    json::accessor::Type::Vec4,
                    json::animation::Property::Rotation,
                ),
            ] {
                let output = root.push(accessor(view, tr.first * size, tr.count, type_, None));
                channel(output, path);
            }
        }
        root.push(animation);
    }
    let world = &w.graph.world;
    let scene = root.push(json::Scene {
        name: Some("crowd".to_string()),
        nodes,
        extras: Some(
            json::extras::RawValue::from_string(format!(
                "{{\"patch_side_m\":{},\"period_s\":{},\"seed\":{},\"input_hash\":\"{}\",\"radius_m\":{}}}",
                world.patch_side_m, period, w.seed, w.input_hash, w.graph.radius_m
            ))
            .expect("valid JSON"),
        ),
        extensions: None,
    });
    root.scene = Some(scene);
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    root.push(json::Buffer {
        byte_length: USize64::from(bin.len()),
        name: None,
        uri: None,
        extensions: None,
        extras: None,
    });
    let json_bytes = root.to_vec().expect("a glTF root serialises");
    let glb = gltf::binary::Glb {
        header: gltf::binary::Header {
            magic: *b"glTF",
            version: 2,
            length: 0, // to_vec fills it in
        },
        json: std::borrow::Cow::Owned(json_bytes),
        bin: Some(std::borrow::Cow::Owned(bin)),
    };
    glb.to_vec().expect("a GLB in memory")
}
