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

use crate::characters::Links;
use crowd_core::PatchGraph;
use crowd_core::trajectories::PatchMotion;
use glam::DVec2;
use gltf_json as json;
use json::validation::Checked::Valid;
use json::validation::USize64;

/// Character height, metres.
const HEIGHT_M: f32 = 1.8;

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

/// A walker's loop as positions at loop times (seconds from the loop's start).
struct LoopPath {
    times: Vec<f64>,
    points: Vec<DVec2>,
    /// World time at which the loop's first trajectory starts.
    start: f64,
    laps: u32,
}

impl LoopPath {
    fn at(&self, tau: f64) -> DVec2 {
        let k = self.times.partition_point(|&t| t <= tau);
        if k == 0 {
            return self.points[0];
        }
        if k >= self.times.len() {
            return self.points[self.points.len() - 1];
        }
        let (t0, t1) = (self.times[k - 1], self.times[k]);
        let s = if t1 > t0 { (tau - t0) / (t1 - t0) } else { 1.0 };
        self.points[k - 1].lerp(self.points[k], s)
    }
}

fn loop_paths(w: &World) -> Vec<LoopPath> {
    w.links
        .loops
        .iter()
        .map(|lp| {
            let (mut times, mut points) = (Vec::new(), Vec::new());
            let mut offset = 0.0;
            let first = w.links.refs[lp[0]];
            let start = w.motion[first.patch].trajectories[first.index].points[0].t;
            for &i in lp {
                let r = w.links.refs[i];
                let tr = &w.motion[r.patch].trajectories[r.index];
                let origin = w.graph.world_from_patch(w.graph.patches[r.patch].cell);
                let t0 = tr.points[0].t;
                for (k, cp) in tr.points.iter().enumerate() {
                    if k == 0 && !times.is_empty() {
                        continue; // the previous trajectory's exit, the same instant and place
                    }
                    times.push(offset + cp.t - t0);
                    points.push(origin + cp.pos);
                }
                offset += tr.duration();
            }
            let laps = (offset / w.period_s).round().max(1.0) as u32;
            LoopPath {
                times,
                points,
                start,
                laps,
            }
        })
        .collect()
}

/// glTF's frame of a world point on the ground.
fn gltf_point(p: DVec2) -> [f32; 3] {
    [p.x as f32, 0.0, -p.y as f32]
}

/// The rotation that turns the character's +Z towards world direction `d`, about +Y.
fn facing(d: DVec2) -> [f32; 4] {
    // glTF direction (d.x, 0, -d.y); yaw from +Z towards +X.
    let yaw = d.x.atan2(-d.y);
    let (s, c) = (0.5 * yaw).sin_cos();
    [0.0, s as f32, 0.0, c as f32]
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
            // Keys: 0, every point inside the clip, the period.
            let mut key_t = vec![0.0];
            let mut key_p = vec![path.at(tau0)];
            // The loop's points inside the clip's window [tau0, tau0 + period) of loop time,
            // which may wrap past the loop's end: one or two binary-searched runs.
            let (loop_times, loop_points) = (&path.times, &path.points);
            let run = |from: f64, to: f64, shift: f64| {
                let (a, b) = (
                    loop_times.partition_point(|&t| t <= from),
                    loop_times.partition_point(|&t| t < to),
                );
                (a..b.max(a)).map(move |k| (loop_times[k] - shift, loop_points[k]))
            };
            let end_tau = tau0 + period;
            let inner: Vec<(f64, DVec2)> = if end_tau <= length {
                run(tau0, end_tau, tau0).collect()
            } else {
                run(tau0, length, tau0)
                    .chain(run(-1.0, end_tau - length, tau0 - length))
                    .collect()
            };
            let inner = inner
                .into_iter()
                .filter(|&(t, _)| t > 1e-6 && t < period - 1e-6);
            // Keys strictly increasing as f32, as glTF wants them (and short of the last).
            let end = period as f32;
            for (t, p) in inner {
                let last = *key_t.last().expect("the key at 0") as f32;
                if (t as f32) > last && (t as f32) < end {
                    key_t.push(t);
                    key_p.push(p);
                }
            }
            key_t.push(period);
            key_p.push(if path.laps == 1 {
                key_p[0]
            } else {
                path.at((tau0 + period).rem_euclid(length))
            });
            // Facing: the direction walked from each key on (standing: the last one walked).
            let mut q = Vec::with_capacity(key_t.len());
            let mut dir = path.at(tau0 + 0.05) - path.at(tau0);
            if dir.length_squared() < 1e-12 {
                dir = DVec2::Y;
            }
            for k in 0..key_t.len() {
                if k + 1 < key_t.len() {
                    let d = key_p[k + 1] - key_p[k];
                    if d.length_squared() > 1e-10 {
                        dir = d;
                    }
                }
                let mut r = facing(dir);
                if let Some(prev) = q.last() {
                    let prev: &[f32; 4] = prev;
                    let dot: f32 = prev.iter().zip(&r).map(|(a, b)| a * b).sum();
                    if dot < 0.0 {
                        r = r.map(|v| -v);
                    }
                }
                q.push(r);
            }
            if path.laps == 1 {
                let last = q.len() - 1;
                q[last] = q[0];
            }
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

fn bytes_of(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn bytes_of_3(v: &[[f32; 3]]) -> Vec<u8> {
    v.iter().flatten().flat_map(|x| x.to_le_bytes()).collect()
}

fn bytes_of_4(v: &[[f32; 4]]) -> Vec<u8> {
    v.iter().flatten().flat_map(|x| x.to_le_bytes()).collect()
}

/// A buffer view over `bytes`, appended to `bin` at a 4-byte boundary.
fn view(
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

fn accessor(
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

/// A capsule of `radius` standing on the ground, `HEIGHT_M` tall (its front is +Z, the
/// direction the rotation keys turn towards the walk); returns its mesh.
fn capsule(root: &mut json::Root, bin: &mut Vec<u8>, radius: f32) -> json::Index<json::Mesh> {
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
