//! Stage 6, smooth: collision-free polylines in, smooth collision-free curves out (Ramirez et
//! al. section 3.5).
//!
//! Every trajectory is sampled into tacks, a clamped cubic spline goes through them with the
//! crossing velocities of its patterns at the borders ([`curve`], [`spline`]), and the curve is
//! sampled again where it bends; what corners are left are averaged over a tenth of a second
//! ([`average`]). Then the patch is checked again exactly (stage 5's analytic closest approach,
//! `crowd_geometry`): a trajectory whose curve brings it closer to anyone or anything than it
//! may be, where its polyline did not, goes down a ladder of walks nearer its polyline (the
//! polyline averaged over shorter windows, then with its corners kept near the encounter), and
//! ships as its polyline last. Smoothing never ships a new collision.

pub mod average;
pub mod curve;
pub mod shard;
pub mod spline;

/// What the stage's unit tests build their walks from.
#[cfg(test)]
mod testing {
    use crowd_core::trajectories::{ControlPoint, PointKind};

    /// A point of a walk at (`x`, `y`) m and `t` s.
    pub fn cp(x: f64, y: f64, t: f64, kind: PointKind) -> ControlPoint {
        ControlPoint {
            pos: glam::DVec2::new(x, y),
            t,
            kind,
        }
    }
}

use crowd_core::config::SmoothSettings;
use crowd_core::patterns::Crossings;
use crowd_core::trajectories::{ControlPoint, PatchMotion, SmoothingSummary, Trajectory};
use crowd_core::{Hash, Hasher, PatchGraph};
use crowd_geometry::{Patch, Segment};
use glam::DVec2;
use rayon::prelude::*;

/// The stage name in `smoothed.ron`'s header.
pub const STAGE: &str = "smooth";
pub const VERSION: u32 = 11;

/// Everything each patch's stage 6 depends on, hashed: its stage 5 motion and its four
/// neighbours' (each in its own numbering, with its surroundings: the velocity at a crossing is
/// what both sides walk there), its surroundings and the settings. Each patch's own part is
/// hashed once, then combined with its neighbours'.
pub fn patch_keys<'a>(
    seen: &crowd_core::patch_keys::Seen,
    collided: impl Fn(usize) -> crowd_core::Result<std::borrow::Cow<'a, PatchMotion>> + Sync,
    inputs: &Inputs,
) -> crowd_core::Result<Vec<Hash>> {
    let all: Vec<usize> = (0..seen.graph.patches.len()).collect();
    patch_keys_of(seen, collided, inputs, &all)
}

/// [`patch_keys`] of `patches` alone (a shard's): `collided` is asked only for them and their
/// neighbours.
pub fn patch_keys_of<'a>(
    seen: &crowd_core::patch_keys::Seen,
    collided: impl Fn(usize) -> crowd_core::Result<std::borrow::Cow<'a, PatchMotion>> + Sync,
    inputs: &Inputs,
    patches: &[usize],
) -> crowd_core::Result<Vec<Hash>> {
    use crowd_core::patch_keys::{local_bytes, neighbours};
    let graph = seen.graph;
    let mut asked = vec![false; graph.patches.len()];
    for &p in patches {
        asked[p] = true;
        neighbours(graph, p)
            .into_iter()
            .flatten()
            .for_each(|q| asked[q] = true);
    }
    let own: Vec<crowd_core::Result<Option<Hash>>> = (0..asked.len())
        .into_par_iter()
        .map(|p| {
            if !asked[p] {
                return Ok(None);
            }
            let mut h = crowd_core::Hasher::new("smooth patch part", VERSION);
            h.binary("surroundings", &seen.surroundings(p))
                .part("motion", &local_bytes(&seen.tables[p], &*collided(p)?));
            Ok(Some(h.finish()))
        })
        .collect();
    let own = own
        .into_iter()
        .collect::<crowd_core::Result<Vec<Option<Hash>>>>()?;
    let part = |p: usize| own[p].expect("a patch asked for or a neighbour of one");
    let keys = patches
        .par_iter()
        .map(|&p| {
            let mut h = crowd_core::Hasher::new("smooth patch", VERSION);
            h.binary("world", &graph.world)
                .binary("radius", &graph.radius_m)
                .binary("inputs", inputs)
                .binary("own", &part(p));
            for q in neighbours(graph, p) {
                h.binary("neighbour", &q.map(part));
            }
            h.finish()
        })
        .collect();
    Ok(keys)
}

/// What stage 6 reads of a pipeline besides its input files.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Inputs {
    pub period_s: f64,
    pub settings: SmoothSettings,
    /// The fastest a curve may walk, m/s: `match.max_speed` plus 4 % ([`SPEED_ALLOWANCE`]; the
    /// shipped files are held to 5 %, and export's dropped keyframes take a little), or its polyline's fastest piece where that is
    /// faster already.
    pub max_speed: f64,
    /// Kept beyond every radius, m ([`crowd_core::config::Pipeline::shipping_error_m`]).
    pub margin_m: f64,
}

/// How much faster than `match.max_speed` a curve may walk: stage 5 keeps every polyline to
/// `max_speed`, and a spline through its tacks runs a little ahead or behind on a bend.
pub const SPEED_ALLOWANCE: f64 = 1.04;

/// What stage 6 reads of a pipeline.
pub fn inputs(pipeline: &crowd_core::config::PipelineFile) -> Inputs {
    let p = &pipeline.pipeline;
    Inputs {
        period_s: p.period_s,
        settings: p.smooth.clone(),
        max_speed: p.matching.max_speed * SPEED_ALLOWANCE,
        margin_m: p.shipping_error_m(),
    }
}

/// The hash of stage 6's inputs: the graph, patterns and collided files (their bytes' hashes)
/// and the settings.
pub fn input_hash(graph: &Hash, patterns: &Hash, collided: &Hash, inputs: &Inputs) -> Hash {
    Hasher::new(STAGE, VERSION)
        .file_hash("graph file", graph)
        .file_hash("patterns file", patterns)
        .file_hash("collided file", collided)
        .value("inputs", inputs)
        .finish()
}

/// Smooths every patch, in parallel; deterministic.
pub fn smooth<'a>(
    graph: &PatchGraph,
    crossings: impl Into<Crossings<'a>>,
    motion: &[PatchMotion],
    inputs: &Inputs,
    progress: &dyn crowd_core::Progress,
) -> (Vec<PatchMotion>, SmoothingSummary) {
    let all: Vec<usize> = (0..motion.len()).collect();
    let results = smooth_patches(graph, crossings.into(), motion, inputs, progress, &all);
    let summary = summary_of(results.iter().map(|r| r.1));
    (results.into_iter().map(|r| r.0).collect(), summary)
}

/// [`smooth`] of `patches` only, each with its counts (smoothed, kept straight, dropped
/// points), in the order given: a shard's part ([`shard`]). `motion` needs only those patches
/// and their neighbours (the pieces that meet at their crossings); the others may be empty.
pub fn smooth_patches<'a>(
    graph: &PatchGraph,
    crossings: impl Into<Crossings<'a>>,
    motion: &[PatchMotion],
    inputs: &Inputs,
    progress: &dyn crowd_core::Progress,
    patches: &[usize],
) -> Vec<(PatchMotion, [u64; 3])> {
    progress.begin("smooth", patches.len() as u64);
    let smoother = Smoother::new(graph, crossings.into(), motion, inputs);
    patches
        .par_iter()
        .map(|&p| {
            let out = smoother.patch(p);
            progress.advance(1);
            out
        })
        .collect()
}

/// Stage 6 of one patch at a time, for a caller that keeps each patch in its own way (a shard
/// encodes it at once and lets the curves go). `motion` needs the patches asked for and their
/// neighbours; the others may be empty.
pub struct Smoother<'a> {
    graph: &'a PatchGraph,
    motion: &'a [PatchMotion],
    inputs: &'a Inputs,
    limits: curve::Limits,
    /// Per crossing held, from the first held ([`crossing_velocities`]).
    velocities: Velocities,
}

impl<'a> Smoother<'a> {
    pub fn new(
        graph: &'a PatchGraph,
        crossings: Crossings<'_>,
        motion: &'a [PatchMotion],
        inputs: &'a Inputs,
    ) -> Smoother<'a> {
        let s = &inputs.settings;
        let limits = curve::Limits {
            side_m: graph.world.patch_side_m,
            period_s: inputs.period_s,
            tack_spacing_s: s.tack_spacing_s,
            max_displacement_m: s.max_displacement_m.unwrap_or(2.0 * graph.radius_m),
            tolerance_m: s.tolerance_m,
            blend: 1.0,
            band_m: graph.radius_m,
        };
        Smoother {
            graph,
            motion,
            inputs,
            limits,
            velocities: crossing_velocities(crossings.numbers(), motion),
        }
    }

    /// Patch `p` smoothed, with its counts (smoothed, kept straight, dropped points).
    pub fn patch(&self, p: usize) -> (PatchMotion, [u64; 3]) {
        let m = &self.motion[p];
        let obstacles = crowd_geometry::obstacles_near(self.graph, p);
        let patch = Patch {
            side_m: self.limits.side_m,
            period_s: self.limits.period_s,
            radius_m: self.graph.radius_m + self.inputs.margin_m,
            obstacles: &obstacles,
            standers: &m.standers,
        };
        smooth_patch(
            &m.trajectories,
            &self.velocities,
            &self.limits,
            self.inputs.max_speed,
            &patch,
        )
    }
}

/// The stage's summary from each patch's counts (smoothed, kept straight, dropped points).
pub fn summary_of(counts: impl Iterator<Item = [u64; 3]>) -> SmoothingSummary {
    let mut summary = SmoothingSummary {
        smoothed: 0,
        kept_straight: 0,
        dropped_points: 0,
    };
    for [smoothed, kept, dropped] in counts {
        summary.smoothed += smoothed;
        summary.kept_straight += kept;
        summary.dropped_points += dropped;
    }
    summary
}

/// The velocity of every crossing for the curves on both of its sides: the mean of the two
/// straight pieces that meet there (the walker's last piece in the patch it leaves and first
/// piece in the patch it enters). Both sides use the same vector, so the join is C1.
///
/// Where both pieces are border bands (every trajectory stage 4 draws long enough to hold
/// them), that mean is the crossing's own velocity, and the curve starts after the band. For
/// a trajectory without bands, the mean of its lines is what keeps the curve near them: held
/// to the planned velocity instead, curves ran up to half a metre ahead of or behind their
/// lines near the border (before the bands, 9,172 of 12,944 `ring` curves then broke a
/// clearance).
///
/// Only the crossings `held` (the world's numbers a shard holds: all of them in a whole
/// build) have one; a trajectory's end elsewhere (a neighbour's, beyond the shard's window)
/// adds to none.
pub fn crossing_velocities(held: std::ops::Range<u32>, motion: &[PatchMotion]) -> Velocities {
    let first = held.start;
    let mut sum = vec![DVec2::ZERO; held.len()];
    for tr in motion.iter().flat_map(|m| &m.trajectories) {
        let p = &tr.points;
        let piece = |a: &ControlPoint, b: &ControlPoint| {
            Segment {
                p0: a.pos,
                t0: a.t,
                p1: b.pos,
                t1: b.t,
            }
            .velocity()
        };
        let at = |c: u32| c.checked_sub(first).map(|k| k as usize);
        if let Some(v) = at(tr.entry).and_then(|k| sum.get_mut(k)) {
            *v += 0.5 * piece(&p[0], &p[1]);
        }
        if let Some(v) = at(tr.exit).and_then(|k| sum.get_mut(k)) {
            *v += 0.5 * piece(&p[p.len() - 2], &p[p.len() - 1]);
        }
    }
    Velocities { first, list: sum }
}

/// [`crossing_velocities`]: the velocity of each crossing held, by its world number.
pub struct Velocities {
    first: u32,
    list: Vec<DVec2>,
}

impl Velocities {
    /// Crossing `c`'s velocity; one not held is a bug (a patch smoothed outside its shard's
    /// window), which panics.
    fn of(&self, c: u32) -> DVec2 {
        let k = c.checked_sub(self.first).map(|k| k as usize);
        match k.and_then(|k| self.list.get(k)) {
            Some(&v) => v,
            None => panic!(
                "crossing {c} is not held (from {}, {} held)",
                self.first,
                self.list.len()
            ),
        }
    }
}

/// Smooths one patch's walkers: `[smoothed, kept straight, dropped points]` with the motion.
fn smooth_patch(
    trajectories: &[Trajectory],
    velocities: &Velocities,
    limits: &curve::Limits,
    max_speed: f64,
    patch: &Patch,
) -> (PatchMotion, [u64; 3]) {
    let mut dropped = 0;
    // The polyline averaged except for its corners near `held` times.
    let held_at = |tr: &Trajectory, held: &[f64], limits: &curve::Limits, allowed: f64| {
        let c = average::average(tr, AVERAGE_S[1], Some(allowed), limits.period_s, held);
        if fastest(&c) <= allowed {
            (c, 0)
        } else {
            (tr.clone(), 0)
        }
    };
    // Each trajectory's curve, made when first wanted and blended at every level after.
    let curves: Vec<std::cell::OnceCell<curve::Curve>> =
        trajectories.iter().map(|_| Default::default()).collect();
    let curve_of = |i: usize| {
        curves[i].get_or_init(|| {
            let tr = &trajectories[i];
            let v = |c: u32| velocities.of(c);
            curve::Curve::new(tr, v(tr.entry), v(tr.exit), limits)
        })
    };
    // The first candidate from `level` on that walks no faster than `max_speed` (or than the
    // polyline did); the polyline if none does.
    let curve_at = |i: usize, level: u32| {
        let tr = &trajectories[i];
        let allowed = max_speed.max(fastest(tr)) + 1e-9;
        (level..=LEVELS)
            .map(|level| candidate(tr, level, || curve_of(i), limits, allowed))
            .find(|(c, _)| fastest(c) <= allowed)
            .unwrap_or_else(|| held_at(tr, &[], limits, allowed))
    };
    let smoothed: Vec<Trajectory> = (0..trajectories.len())
        .map(|i| {
            let (s, d) = curve_at(i, 0);
            dropped += d;
            s
        })
        .collect();
    let ladder = crowd_geometry::Ladder {
        levels: LEVELS,
        halvings: CURVE_LEVELS,
        holds: HOLDS,
    };
    let chosen =
        crowd_geometry::keep_clear(trajectories, smoothed, patch, ladder, |i, level, held| {
            let tr = &trajectories[i];
            if held.is_empty() {
                curve_at(i, level).0
            } else {
                held_at(tr, held, limits, max_speed.max(fastest(tr)) + 1e-9).0
            }
        });
    let kept_straight = chosen
        .iter()
        .zip(trajectories)
        .filter(|(c, t)| c == t)
        .count() as u64;
    let motion = PatchMotion {
        standers: patch.standers.to_vec(),
        trajectories: chosen,
    };
    (
        motion,
        [
            trajectories.len() as u64 - kept_straight,
            kept_straight,
            dropped,
        ],
    )
}

/// The smoothed trajectory at `level` of departure from the polyline `tr`, and how many curve
/// points it dropped: the curve, then its halvings of the way back to the polyline
/// ([`CURVE_LEVELS`]), each with its corners averaged and eased into the band pieces; then
/// the polyline itself so averaged over shorter and shorter windows ([`AVERAGE_S`]). Each eases
/// into its band pieces as far as it stays within `allowed` m/s.
fn candidate<'c, 't: 'c>(
    tr: &Trajectory,
    level: u32,
    curve: impl FnOnce() -> &'c curve::Curve<'t>,
    limits: &curve::Limits,
    allowed: f64,
) -> (Trajectory, u64) {
    let period = limits.period_s;
    if level <= CURVE_LEVELS {
        let limits = curve::Limits {
            blend: 1.0 / f64::from(1u32 << level),
            ..*limits
        };
        let (c, dropped) = curve().blend(&limits);
        return (
            average::average(&c, AVERAGE_S[0], Some(allowed), period, &[]),
            dropped,
        );
    }
    let k = (level - CURVE_LEVELS - 1) as usize;
    (
        average::average(tr, AVERAGE_S[k], Some(allowed), period, &[]),
        0,
    )
}

/// The speed of a trajectory's fastest piece, m/s.
fn fastest(tr: &Trajectory) -> f64 {
    tr.points
        .windows(2)
        .filter(|w| w[1].t > w[0].t)
        .map(|w| w[0].pos.distance(w[1].pos) / (w[1].t - w[0].t))
        .fold(0.0, f64::max)
}

/// Halvings of the curve's departure from the polyline before a trajectory ships as its
/// polyline with its corners averaged.
const CURVE_LEVELS: u32 = 4;
/// Half-widths of the windows the corners are averaged over, s: the curve's (where a dropped
/// point or a pause left one), then the polyline's, each moving it less. A corner of 1.5 m/s
/// over 0.1 s plays as 0.25 m/s a frame at 60 fps; over 0.2 s (0.1 here) painting's library
/// held 12 % more points and the runtime took 13 % longer a frame, for 5 % fewer jumps.
const AVERAGE_S: [f64; 3] = [0.05, 0.025, 0.0125];
/// Levels before a trajectory ships as its polyline.
const LEVELS: u32 = CURVE_LEVELS + AVERAGE_S.len() as u32;

/// Times of close encounters at which a trajectory may keep its polyline's corners, before it
/// ships as its polyline.
const HOLDS: u32 = 4;

/// Stage 6's files, encoded: the motion side file, then `smoothed.ron`. The collide stage's
/// figures are carried over: smoothing leaves no pair closer than stage 5 did.
pub fn encode<'a>(
    out: &std::path::Path,
    motion: impl Into<crowd_core::trajectories::SideMotion<'a>>,
    summary: SmoothingSummary,
    collided: &crowd_core::trajectories::TrajectoriesFile,
    inputs: &Inputs,
    hash: Hash,
) -> (
    crowd_core::trajectories::TrajectoriesFile,
    crowd_core::files::Writes,
) {
    crowd_core::trajectories::encode_file(
        out,
        crowd_core::files::Header::new(STAGE, VERSION, hash),
        inputs.period_s,
        collided.radius_m,
        motion,
        collided.collisions.clone(),
        Some(summary),
    )
}
