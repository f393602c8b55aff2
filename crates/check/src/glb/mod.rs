//! `world.glb` read as an engine reads it, through the `gltf` crate: the default scene's
//! nodes, the `crowd_loop` clip (or the only one) and its LINEAR translation and rotation
//! samplers. Each animated node is a walker slot whose keyed path is played over the clip
//! (held at its first and last keys outside them); a node with a mesh and no track is a
//! stander. Then the figures of [`ProductFigures`]: collisions between every pair of nodes at
//! every clip time (exact closest approach of their straight pieces, a spatial grid), speeds
//! and key jumps, the fastest turn between rotation keys, and each node's handover at the
//! clip's end to the node that starts where it ends (itself, for a one-lap slot).
//!
//! Nodes are read as roots of the scene, each with its own transform: `world.glb`'s are
//! (children are not composed with their parents).

use crate::products::{OPEN_GAP_M, ProductFigures, Seams, Tally, end_velocities};
use crate::world::{Repeat, Scene};
use glam::{DQuat, DVec2};
use gltf::animation::{Interpolation, Property, util::ReadOutputs};
use std::collections::HashMap;

/// Keys closer in time than this (an f32 step near 20 s) count as this far apart, seconds.
const MIN_DT: f64 = 2e-6;

/// Why `world.glb` cannot be checked.
#[derive(Debug, Clone, PartialEq)]
pub struct GlbError(pub String);

impl std::fmt::Display for GlbError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for GlbError {}

/// What the glTF check needs besides the file.
#[derive(Debug, Clone)]
pub struct Inputs<'a> {
    pub radius_m: f64,
    /// Obstacle boxes in world metres (the build's graph; the glTF holds none).
    pub walls: &'a [crate::Wall],
    /// `match.max_speed` x 1.05, m/s.
    pub speed_limit_m_s: f64,
    /// The world's patches cover `(0, 0)` to this corner, m: no character of ours is
    /// anywhere else.
    pub world_m: DVec2,
}

/// One animated node: its translation keys (world metres, clip seconds) and rotation keys.
#[derive(Debug, Clone, Default)]
pub struct Track {
    pub path: Vec<(DVec2, f64)>,
    pub turns: Vec<(DQuat, f64)>,
    /// Scale keys (x), STEP: a node scaled to 0 is hidden (export hides a slot outside
    /// `export.gltf_region`). None: always shown.
    pub scale: Vec<(f64, f64)>,
}

impl Track {
    /// Whether the node is shown at clip time `t` (at a key, the key's own value).
    pub fn shown_at(&self, t: f64) -> bool {
        let k = self.scale.partition_point(|k| k.1 <= t);
        k == 0 || self.scale[k - 1].0 > 0.0
    }
}

/// The nodes of a glTF world: animated ones in node order, standers, and the clip's length.
#[derive(Debug, Clone)]
pub struct Nodes {
    pub tracks: Vec<Track>,
    pub standers: Vec<DVec2>,
    pub clip_s: f64,
}

/// World (x, y) of a glTF point: glTF is Y-up with world y along -Z (DESIGN.md).
fn world(p: [f32; 3]) -> DVec2 {
    DVec2::new(f64::from(p[0]), -f64::from(p[2]))
}

/// Reads the scene's nodes and their tracks.
pub fn read(bytes: &[u8]) -> Result<Nodes, GlbError> {
    let err = |e: String| GlbError(e);
    let gltf = gltf::Gltf::from_slice(bytes).map_err(|e| err(format!("not a glTF: {e}")))?;
    let blob = gltf.blob.as_deref();
    let data = |b: gltf::Buffer| match b.source() {
        gltf::buffer::Source::Bin => blob,
        gltf::buffer::Source::Uri(_) => None,
    };
    let clip = gltf
        .animations()
        .find(|a| a.name() == Some("crowd_loop"))
        .or_else(|| gltf.animations().next());
    let mut tracks: HashMap<usize, Track> = HashMap::new();
    let mut clip_s = 0.0f64;
    for channel in clip.iter().flat_map(|a| a.channels()) {
        let property = usable(gltf.as_json(), channel.animation().index(), channel.index())
            .map_err(|e| err(format!("channel {}: {e}", channel.index())))?;
        let sampler = channel.sampler();
        for accessor in [sampler.input(), sampler.output()] {
            fits(&accessor, blob.map_or(0, <[u8]>::len)).map_err(err)?;
        }
        if property == Property::Scale {
            let reader = channel.reader(data);
            let (Some(times), Some(ReadOutputs::Scales(scales))) =
                (reader.read_inputs(), reader.read_outputs())
            else {
                return Err(err(format!("channel {}: keys missing", channel.index())));
            };
            let track = tracks.entry(channel.target().node().index()).or_default();
            track.scale = scales
                .map(|s| f64::from(s[0]))
                .zip(times.map(f64::from))
                .collect();
            continue;
        }
        if !matches!(property, Property::Translation | Property::Rotation) {
            continue;
        }
        if channel.sampler().interpolation() != Interpolation::Linear {
            return Err(err(format!(
                "animation sampler {}: expected LINEAR interpolation",
                channel.sampler().index()
            )));
        }
        let reader = channel.reader(data);
        let missing = || err(format!("channel {}: keys missing", channel.index()));
        let times: Vec<f64> = reader
            .read_inputs()
            .ok_or_else(missing)?
            .map(f64::from)
            .collect();
        clip_s = clip_s.max(times.last().copied().unwrap_or(0.0));
        let track = tracks.entry(channel.target().node().index()).or_default();
        match reader.read_outputs().ok_or_else(missing)? {
            ReadOutputs::Translations(p) => track.path = p.map(world).zip(times).collect(),
            ReadOutputs::Rotations(q) => {
                let q = q.into_f32().map(|q| DQuat::from_array(q.map(f64::from)));
                track.turns = q.zip(times).collect();
            }
            _ => {}
        }
    }
    let scene = gltf.default_scene().or_else(|| gltf.scenes().next());
    let mut nodes = Nodes {
        tracks: Vec::new(),
        standers: Vec::new(),
        clip_s,
    };
    for node in scene.iter().flat_map(|s| s.nodes()) {
        match tracks.remove(&node.index()) {
            Some(t) if !t.path.is_empty() => nodes.tracks.push(t),
            _ if node.mesh().is_some() => {
                nodes.standers.push(world(node.transform().decomposed().0));
            }
            _ => {}
        }
    }
    for t in &mut nodes.tracks {
        hold_ends(&mut t.path, clip_s);
        hold_ends(&mut t.turns, clip_s);
    }
    Ok(nodes)
}

/// A track held at its first key before it and at its last after it, over [0, clip].
fn hold_ends<T: Copy>(keys: &mut Vec<(T, f64)>, clip: f64) {
    if let (Some(&first), Some(&last)) = (keys.first(), keys.last()) {
        if first.1 > 0.0 {
            keys.insert(0, (first.0, 0.0));
        }
        if last.1 < clip || keys.len() == 1 {
            keys.push((last.0, clip));
        }
    }
}

/// The property channel `channel` of animation `animation` animates, once every value of its
/// JSON that the `gltf` crate's accessors unwrap is known to be one glTF defines: its target
/// path, its sampler's interpolation, its accessors' component and element types (the crate's
/// validation lets a damaged path through, and `property()` then panics).
fn usable(root: &gltf::json::Root, animation: usize, channel: usize) -> Result<Property, String> {
    use gltf::json::validation::Checked::Valid;
    let anim = root.animations.get(animation).ok_or("no such animation")?;
    let ch = anim.channels.get(channel).ok_or("no such channel")?;
    let Valid(property) = ch.target.path else {
        return Err("its target path is not one glTF knows".into());
    };
    let sampler = anim
        .samplers
        .get(ch.sampler.value())
        .ok_or("its sampler is not in the animation")?;
    if !matches!(sampler.interpolation, Valid(_)) {
        return Err("its sampler's interpolation is not one glTF knows".into());
    }
    for index in [sampler.input, sampler.output] {
        let accessor = root
            .accessors
            .get(index.value())
            .ok_or("its sampler's accessor is not in the file")?;
        if !matches!(
            (&accessor.component_type, &accessor.type_),
            (Valid(_), Valid(_))
        ) {
            return Err(format!(
                "accessor {}: its component or element type is not one glTF knows",
                index.value()
            ));
        }
    }
    Ok(property)
}

/// Whether `accessor`'s elements lie inside its buffer view and the view inside the binary
/// chunk of `blob_len` bytes: a reader takes the count at its word and makes room for that
/// many (a damaged count asked 5.5 GB of a 30 kB file).
fn fits(accessor: &gltf::Accessor, blob_len: usize) -> Result<(), String> {
    let place = || format!("accessor {}", accessor.index());
    let Some(view) = accessor.view() else {
        return Err(format!(
            "{}: no buffer view (sparse accessors are not read)",
            place()
        ));
    };
    let size = accessor.size();
    let stride = view.stride().unwrap_or(size).max(size);
    let count = accessor.count();
    let need = match count {
        0 => Some(0),
        n => (n - 1)
            .checked_mul(stride)
            .and_then(|b| b.checked_add(size))
            .and_then(|b| b.checked_add(accessor.offset())),
    };
    let view_end = view.offset().checked_add(view.length());
    match (need, view_end) {
        (Some(need), Some(end)) if need <= view.length() && end <= blob_len => Ok(()),
        _ => Err(format!(
            "{}: {count} elements of {size} bytes do not fit its buffer view {} ({} bytes at \
             {} of a {blob_len}-byte binary chunk)",
            place(),
            view.index(),
            view.length(),
            view.offset()
        )),
    }
}

/// Refuses a node whose keys lie outside the world (or are not numbers, or a clip time that
/// is not): the world check files every piece in the grid cells its box touches, and one
/// piece a damaged key throws across a million kilometres would fill memory with cells.
fn in_world(nodes: &Nodes, world: DVec2) -> Result<(), GlbError> {
    let slack = DVec2::splat(1.0);
    let inside = |p: DVec2| p.is_finite() && p.cmpge(-slack).all() && p.cmple(world + slack).all();
    let tracks = nodes.tracks.iter().enumerate();
    let keys = tracks.flat_map(|(n, t)| t.path.iter().map(move |&(p, t)| (n, p, t)));
    if let Some((n, p, t)) = keys.clone().find(|&(_, p, t)| !inside(p) || !t.is_finite()) {
        return Err(GlbError(format!(
            "animated node {n}: a key at ({}, {}) m, {t} s, outside the world (0, 0)-({}, {}) m",
            p.x, p.y, world.x, world.y
        )));
    }
    if let Some(p) = nodes.standers.iter().find(|p| !inside(**p)) {
        return Err(GlbError(format!(
            "a standing node at ({}, {}) m, outside the world (0, 0)-({}, {}) m",
            p.x, p.y, world.x, world.y
        )));
    }
    Ok(())
}

/// The figures of the glTF world in `bytes`.
pub fn figures(bytes: &[u8], inputs: &Inputs) -> Result<ProductFigures, GlbError> {
    let nodes = read(bytes)?;
    in_world(&nodes, inputs.world_m)?;
    let clip = nodes.clip_s;
    let paths: Vec<Vec<(DVec2, f64)>> = nodes.tracks.iter().map(|t| t.path.clone()).collect();
    let tally = Tally::of_float32(&paths, inputs.speed_limit_m_s, MIN_DT, clip);
    let mut scene = Scene {
        radius: inputs.radius_m,
        repeat: Repeat::Clip(clip),
        pieces: Vec::new(),
        ends: Vec::new(),
        standers: nodes.standers.clone(),
        walls: inputs.walls.to_vec(),
        owned: crate::world::Owned::Every,
    };
    scene
        .pieces
        .reserve_exact(paths.iter().map(|p| p.len().saturating_sub(1)).sum());
    for (i, path) in paths.iter().enumerate() {
        scene.push_path(i as u32, 0, path.iter().copied());
    }
    let clearance = scene.clearance();
    let seams = handovers(&nodes.tracks, clip);
    let counts = (
        nodes.tracks.len() as u64,
        nodes.standers.len() as u64,
        scene.pieces.len() as u64,
        nodes.tracks.len() as u64,
    );
    Ok(ProductFigures {
        max_turn_rate_rad_s: Some(max_turn_rate(&nodes.tracks)),
        ..ProductFigures::measured(
            "world.glb",
            counts,
            &clearance,
            &tally,
            &seams,
            inputs.speed_limit_m_s,
        )
    })
}

/// The angle between two rotations, radians.
fn angle(a: DQuat, b: DQuat) -> f64 {
    // 4 atan2(|a - b|, |a + b|) (b taken on a's side: |a -+ b| = 2 sin, 2 cos of a quarter of
    // the turn), not 2 acos(a.b): near 1 the cosine
    // loses the small turns between keys a few milliseconds apart to the f32 keys' rounding
    // (0.6 % of a 0.4 degree turn).
    let b = if a.dot(b) < 0.0 { -b } else { b };
    4.0 * (a - b).length().atan2((a + b).length())
}

/// The fastest turn between consecutive rotation keys of any node, rad/s. Key times are f32:
/// each is the exact time rounded by up to half a unit in its last place, so the interval
/// between two keys is taken one unit (at the later key) longer than it reads. Near the end of
/// a 600 s clip a unit is 61 us, 3 % of a turn's 2 ms between keys (365 degrees a second
/// measured for a 360 one, without it).
fn max_turn_rate(tracks: &[Track]) -> f64 {
    let ulp = |t: f64| {
        let f = t as f32;
        f64::from(f32::from_bits(f.to_bits() + 1)) - f64::from(f)
    };
    let mut fastest = 0.0f64;
    for t in tracks {
        for w in t.turns.windows(2).filter(|w| w[1].1 > w[0].1) {
            let dt = w[1].1 - w[0].1 + ulp(w[1].1);
            fastest = fastest.max(angle(w[0].0, w[1].0) / dt);
        }
    }
    fastest
}

/// Each shown node's handover at the clip's end: to itself when its end is within 1 cm of its
/// own start, else to the node shown at the clip's start whose start is nearest its end (within
/// 1 cm; none: an open loop). A node hidden at the clip's end hands over to no one.
fn handovers(tracks: &[Track], clip: f64) -> Seams {
    let cell = |p: DVec2| {
        (
            (p.x / OPEN_GAP_M).floor() as i64,
            (p.y / OPEN_GAP_M).floor() as i64,
        )
    };
    let mut starts: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for (i, t) in tracks.iter().enumerate().filter(|(_, t)| t.shown_at(0.0)) {
        starts.entry(cell(t.path[0].0)).or_default().push(i);
    }
    let mut seams = Seams::default();
    for (i, t) in tracks.iter().enumerate() {
        if !t.shown_at(clip) {
            continue;
        }
        let end = t.path[t.path.len() - 1].0;
        let (cx, cy) = cell(end);
        let nearest = (cx - 1..=cx + 1)
            .flat_map(|x| (cy - 1..=cy + 1).map(move |y| (x, y)))
            .flat_map(|k| starts.get(&k).into_iter().flatten().copied())
            .map(|j| (tracks[j].path[0].0.distance(end), j))
            .filter(|&(d, _)| d <= OPEN_GAP_M)
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let own = t.path[0].0.distance(end) <= OPEN_GAP_M && t.shown_at(0.0);
        let Some(next) = (if own {
            Some(i)
        } else {
            nearest.map(|(_, j)| j)
        }) else {
            seams.open += 1;
            continue;
        };
        let n = &tracks[next];
        let v_in = end_velocities(&t.path, MIN_DT).1;
        let v_out = end_velocities(&n.path, MIN_DT).0;
        let heading = match (t.turns.last(), n.turns.first()) {
            (Some(a), Some(b)) => angle(a.0, b.0),
            _ => 0.0,
        };
        let gap = end.distance(n.path[0].0);
        seams.note_with_heading(gap, (v_out - v_in).length(), heading);
    }
    seams
}

#[cfg(test)]
mod tests;
