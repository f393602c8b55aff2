//! `world.glb`: the crowd as a glTF 2.0 scene an engine or a DCC tool loads (Y-up, metres,
//! world (x, y) -> glTF (x, 0, -y), DESIGN.md).
//!
//! One shared capsule mesh; one node per character slot (the runtime's ids, `walker_<id>`,
//! and `stander_<i>`); one animation, `crowd_loop`, that lasts exactly one period, with
//! translation keys at the trajectory points inside it and at 0 and the period, and rotation
//! keys at their own times, where the heading model of `crowd_runtime::turn` starts and ends a
//! turn (at most `export.turn_rate_deg_s`).
//! A slot of a one-period loop has equal keys at 0 and at the period, so a looping player shows
//! no jump. A loop of k periods has k slots: slot j is the walker a runtime calls lap j, one
//! period behind slot j - 1, so at the clip's end it stands where slot j - 1 starts, facing the
//! same way: the set of positions is continuous at every time while each node, looping, hands
//! its walker over to the next. Each walker node names that successor in its `extras`
//! (`{"crowd_next": "walker_<id>", "crowd_loop": l, "crowd_lap": j}`; itself for a one-period
//! loop), so that a player that plays nodes one by one can chain them and pass a character's
//! look on (FORMAT.md).
//!
//! `keys.rs` makes each slot's keys, `region.rs` shows only what is inside
//! `export.gltf_region`, `mesh.rs` the capsule, `buffers.rs` the binary chunk's views and
//! accessors; this file assembles the document.

mod buffers;
mod keys;
mod mesh;
mod plan;
mod region;

use crate::characters::Links;
use crate::motion::{Held, Motion, Summaries};
use buffers::{accessor, bytes_of, bytes_of_3, bytes_of_4, view};
use crowd_core::PatchGraph;
use crowd_runtime::turn::LoopPoints;
use glam::DVec2;
use gltf_json as json;
use json::validation::Checked::Valid;
use json::validation::USize64;
use keys::{Keys, gltf_point, slot_keys};
use mesh::capsule;
use rayon::prelude::*;

/// What `world.glb` is made from.
pub struct World<'a> {
    pub graph: &'a PatchGraph,
    /// Every trajectory's summary, and the final motion, whose patches are read only where
    /// the slots shown walk (`plan.rs`).
    pub summaries: &'a Summaries,
    pub motion: &'a dyn Motion,
    pub links: &'a Links,
    pub period_s: f64,
    pub seed: u64,
    pub input_hash: String,
    /// Characters only while inside `(x0, y0, x1, y1)` (`region.rs`).
    pub region: Option<(f64, f64, f64, f64)>,
    /// The library made from the same keyframes: headings come from its points
    /// (`crowd_runtime::turn::library_headings`), and its turn rate.
    pub library: LibraryRef<'a>,
}

/// The library `world.glb` is faced by: held whole, or its records with its points in stage
/// 8's scratch file, a loop's read back at a time.
#[derive(Clone, Copy)]
pub enum LibraryRef<'a> {
    Held(&'a crowd_runtime::Library),
    Spilled(&'a crowd_runtime::Library, &'a crate::spill::Spilled),
}

impl LibraryRef<'_> {
    /// Every record (the points only when held).
    pub fn records(&self) -> &crowd_runtime::Library {
        match self {
            LibraryRef::Held(lib) | LibraryRef::Spilled(lib, _) => lib,
        }
    }

    /// The first read of the scratch file that failed, if one did ([`LoopPoints`] cannot).
    fn failure(&self) -> crowd_core::Result<()> {
        match self {
            LibraryRef::Held(_) => Ok(()),
            LibraryRef::Spilled(_, spilled) => spilled.failure().map_err(|e| {
                let scratch = std::path::Path::new("(the library's points, a scratch file)");
                crowd_core::Error::io(scratch, "read", e)
            }),
        }
    }
}

/// The library's points where they are: its own list, or the scratch file.
impl LoopPoints for LibraryRef<'_> {
    fn with<R>(&self, first: u32, n: u32, read: impl FnOnce(&[crowd_runtime::Point]) -> R) -> R {
        match self {
            LibraryRef::Held(lib) => lib.points[..].with(first, n, read),
            LibraryRef::Spilled(_, spilled) => spilled.with(first, n, read),
        }
    }

    fn prefetch(&self, first: u32) {
        match self {
            LibraryRef::Held(lib) => lib.points[..].prefetch(first),
            LibraryRef::Spilled(_, spilled) => spilled.prefetch(first),
        }
    }

    fn stream_keys(&self) -> usize {
        match self {
            LibraryRef::Held(lib) => lib.points[..].stream_keys(),
            LibraryRef::Spilled(_, spilled) => spilled.stream_keys(),
        }
    }
}

/// The patches whose keyframes [`world_glb`] reads: those its shown slots walk through (all that
/// hold a trajectory, without a region).
pub fn patches_read(w: &World) -> Vec<bool> {
    plan::patches(&plans(w, &laps(w)), w.links, w.graph.patches.len())
}

/// How many periods each loop lasts ([`keys::loop_laps`]), in loop order.
fn laps(w: &World) -> Vec<u32> {
    (w.links.loops.iter())
        .map(|members| keys::loop_laps(w, members))
        .collect()
}

/// Every loop's [`plan::Plan`] (in loop order, `laps` each), but those of loops no slot of
/// which may show.
fn plans(w: &World, laps: &[u32]) -> Vec<plan::Plan> {
    // With a region, a loop whose box misses it shows nothing (most of painting's, for its
    // 160 m region).
    (0..w.links.loops.len())
        .into_par_iter()
        .filter_map(|lp| {
            let members = &w.links.loops[lp];
            if w.region
                .is_some_and(|r| !region::may_show(keys::loop_box(w.summaries, members), r))
            {
                return None;
            }
            let clock = keys::clock(w, members, laps[lp]);
            plan::plan(w.summaries, w.links, lp, clock, w.region)
        })
        .collect()
}

/// A walker slot's keys, and the spans of the clip it is shown (all of it without a region).
struct Slot {
    id: u32,
    next: u32,
    /// Its loop (in the library's CHAR order) and lap.
    lp: u32,
    lap: u32,
    keys: Keys,
    shown: Vec<(f64, f64)>,
}

/// The slots of every loop that may show (`laps[lp]` each), in loop and lap order: the
/// patches they walk read from the final motion (`plan.rs`), each loop's path made and its
/// slots cut from it. A planned slot whose keys' box misses the region shows nothing: its
/// keys are never made.
fn slots(w: &World, laps: &[u32]) -> crowd_core::Result<Vec<Slot>> {
    let hidden = |b: (DVec2, DVec2)| w.region.is_some_and(|r| !region::may_show(b, r));
    let firsts: Vec<u32> = laps
        .iter()
        .scan(0u32, |id, &n| {
            let first = *id;
            *id += n;
            Some(first)
        })
        .collect();
    let plans = plans(w, laps);
    let held = Held::load(
        w.motion,
        &plan::patches(&plans, w.links, w.graph.patches.len()),
    )?;
    let loop_slots = |plan: &plan::Plan| -> crowd_core::Result<Vec<Slot>> {
        let path = keys::loop_path(w, &held, plan)?;
        let first = firsts[plan.lp];
        // A loop of 60,000 laps (painting's longest) has its slots made in parallel too.
        let slots = (plan.laps.par_iter())
            .filter(|&&lap| !hidden(keys::window_box(&path, lap)))
            .map(|&lap| {
                let keys = slot_keys(&path, lap);
                let shown = match w.region {
                    Some(r) => region::shown(&keys.times, &keys.points, r),
                    None => vec![(0.0, w.period_s)],
                };
                Slot {
                    id: first + lap,
                    next: first + path.next_lap(lap),
                    lp: plan.lp as u32,
                    lap,
                    keys,
                    shown,
                }
            })
            .collect();
        Ok(slots)
    };
    // Loops are independent: their keys are made in parallel and kept in loop order
    // (painting's 428 loops were two seconds of the export on one core), but for the longest.
    let keys_of = |plan: &plan::Plan| -> usize {
        (w.links.loops[plan.lp].iter())
            .map(|&i| w.summaries.trajectories[i].points)
            .sum()
    };
    let per_loop: Vec<Option<crowd_core::Result<Vec<Slot>>>> = (plans.par_iter())
        .map(|plan| (keys_of(plan) < LONG_LOOP_KEYS).then(|| loop_slots(plan)))
        .collect();
    let mut all = Vec::new();
    for (made, plan) in per_loop.into_iter().zip(&plans) {
        all.extend(made.unwrap_or_else(|| loop_slots(plan))?);
    }
    Ok(all)
}

/// Keys of loops from this long are made one loop at a time (each on every core): a loop's
/// keys and headings are made whole before its slots are cut from them, 80 bytes a key, and
/// the million's four longest, 8 to 36 million keys, made at once held gigabytes.
const LONG_LOOP_KEYS: usize = 1 << 23;

/// The bytes of `world.glb`: of the final motion, the patches its slots walk are read.
pub fn world_glb(w: &World) -> crowd_core::Result<Vec<u8>> {
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
    let mut turn_times: Vec<f32> = Vec::new();
    // Region only: STEP scale keys that hide a character outside it.
    let (mut scale_times, mut scales): (Vec<f32>, Vec<[f32; 3]>) = (Vec::new(), Vec::new());
    struct Track {
        node: json::Index<json::Node>,
        first: usize,
        count: usize,
        /// First and count of its rotation keys.
        turns: (usize, usize),
        /// First and count of its scale keys, if it leaves the region.
        scale: Option<(usize, usize)>,
    }
    let mut tracks = Vec::new();
    let mut nodes = Vec::new();
    let period = w.period_s;
    let inside = |p: DVec2| {
        w.region
            .is_none_or(|(x0, y0, x1, y1)| p.x >= x0 && p.x < x1 && p.y >= y0 && p.y < y1)
    };
    let laps = laps(w);
    let slots = slots(w, &laps)?;
    let named: std::collections::HashSet<u32> = slots
        .iter()
        .filter(|s| !s.shown.is_empty())
        .map(|s| s.id)
        .collect();
    for slot in slots.into_iter().filter(|s| !s.shown.is_empty()) {
        let Keys {
            times: key_t,
            points: key_p,
            turn_times: key_q,
            turns: q,
        } = slot.keys;
        let scale = region::scale_keys(&slot.shown, period);
        // The successor, if it is in this file (with a region, a slot hidden at the clip's
        // end may hand over to one that stays outside all clip).
        let next = if named.contains(&slot.next) {
            format!("\"walker_{}\"", slot.next)
        } else {
            "null".to_string()
        };
        let node = root.push(json::Node {
            mesh: Some(mesh),
            name: Some(format!("walker_{}", slot.id)),
            translation: Some(gltf_point(key_p[0])),
            rotation: Some(json::scene::UnitQuaternion(q[0])),
            scale: scale
                .as_ref()
                .filter(|(_, s)| s[0] == 0.0)
                .map(|_| [0.0; 3]),
            extras: Some(
                json::extras::RawValue::from_string(format!(
                    "{{\"crowd_next\":{next},\"crowd_loop\":{},\"crowd_lap\":{}}}",
                    slot.lp, slot.lap
                ))
                .expect("valid JSON"),
            ),
            ..Default::default()
        });
        nodes.push(node);
        tracks.push(Track {
            node,
            first: times.len(),
            count: key_t.len(),
            turns: (turn_times.len(), key_q.len()),
            scale: scale.as_ref().map(|(t, _)| (scale_times.len(), t.len())),
        });
        times.extend(key_t.iter().map(|&t| t as f32));
        moves.extend(key_p.iter().map(|&p| gltf_point(p)));
        turn_times.extend(key_q.iter().map(|&t| t as f32));
        turns.extend(q);
        if let Some((t, s)) = scale {
            scale_times.extend(t.iter().map(|&t| t as f32));
            scales.extend(s.iter().map(|&s| [s; 3]));
        }
    }
    let mut stander = 0;
    for (p, standers) in w.summaries.standers.iter().enumerate() {
        let origin = w.graph.world_from_patch(w.graph.patches[p].cell);
        for s in standers {
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
        let turn_time_view = view(&mut root, &mut bin, bytes_of(&turn_times), None);
        let scale_views = (!scales.is_empty()).then(|| {
            (
                view(&mut root, &mut bin, bytes_of(&scale_times), None),
                view(&mut root, &mut bin, bytes_of_3(&scales), None),
            )
        });
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
        let mut channel = |node, input, output, path, interpolation| {
            let sampler = json::Index::new(animation.samplers.len() as u32);
            animation.samplers.push(json::animation::Sampler {
                input,
                interpolation: Valid(interpolation),
                output,
                extensions: None,
                extras: None,
            });
            animation.channels.push(json::animation::Channel {
                sampler,
                target: json::animation::Target {
                    node,
                    path: Valid(path),
                    extensions: None,
                    extras: None,
                },
                extensions: None,
                extras: None,
            });
        };
        use json::accessor::Type::{Scalar, Vec3, Vec4};
        use json::animation::Interpolation::{Linear, Step};
        use json::animation::Property::{Rotation, Scale, Translation};
        for tr in &tracks {
            let input = root.push(accessor(
                time_view,
                tr.first * 4,
                tr.count,
                Scalar,
                // Every track runs over the whole clip: keys at 0 and at the period.
                Some((vec![0.0], vec![period as f32])),
            ));
            let output = root.push(accessor(move_view, tr.first * 12, tr.count, Vec3, None));
            channel(tr.node, input, output, Translation, Linear);
            let (first, count) = tr.turns;
            let input = root.push(accessor(
                turn_time_view,
                first * 4,
                count,
                Scalar,
                Some((vec![0.0], vec![period as f32])),
            ));
            let output = root.push(accessor(turn_view, first * 16, count, Vec4, None));
            channel(tr.node, input, output, Rotation, Linear);
            if let (Some((first, count)), Some((time_view, scale_view))) = (tr.scale, scale_views) {
                let last = scale_times[first + count - 1];
                let input = root.push(accessor(
                    time_view,
                    first * 4,
                    count,
                    Scalar,
                    Some((vec![0.0], vec![last])),
                ));
                let output = root.push(accessor(scale_view, first * 12, count, Vec3, None));
                channel(tr.node, input, output, Scale, Step);
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
                "{{\"patch_side_m\":{},\"period_s\":{},\"seed\":{},\"input_hash\":\"{}\",\"radius_m\":{},\"turn_rate_deg_s\":{},\"crowd_loop_laps\":{:?}}}",
                world.patch_side_m,
                period,
                w.seed,
                w.input_hash,
                w.graph.radius_m,
                w.library.records().world.turn_rate_deg_s,
                laps
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
    Ok(glb.to_vec().expect("a GLB in memory"))
}
