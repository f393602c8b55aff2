//! A walker slot's animation keys: its loop as positions at loop times, the keys of one
//! clip (at 0, at every point inside the period, at the period) and the rotations that face
//! the walk, in glTF's frame (world (x, y) -> glTF (x, 0, -y)).
//!
//! A slot's clip ends where and when its successor's starts, and both are computed from the
//! same loop time ([`LoopPath::tau`] of the successor's lap), so the two keys are the same
//! bits: the same position and the same heading. The keys between are the loop's own points,
//! so the last piece of a slot and the first of its successor are two pieces of one walk.

use crate::glb::World;
use crate::glb::plan::Plan;
use crate::motion::{Held, Summaries};
use crowd_runtime::TICK_S;
use crowd_runtime::turn::{self, LoopPoints, Piece};
use glam::DVec2;

/// Loop times closer than this (seconds) are one instant: a clip's window starts at a period's
/// split point up to the rounding of the sums that make loop times.
const SNAP_S: f64 = 1e-7;
/// Loop points closer than this (seconds) to a clip's ends make no key of their own.
const EDGE_S: f64 = 1e-6;

/// A walker's loop as positions at loop times (seconds from the loop's start): the stretches
/// of it that its shown slots read (the whole loop without a region).
pub(super) struct LoopPath {
    /// Runs of the loop's keys, in loop order, apart; each reaches past the clip windows it
    /// serves by a millisecond (`plan.rs`), or to the loop's end.
    stretches: Vec<Stretch>,
    pub(super) clock: Clock,
}

/// When a loop's slots start: the loop's start in world time, its laps and the period.
#[derive(Debug, Clone, Copy)]
pub(super) struct Clock {
    /// World time at which the loop's first trajectory starts.
    pub(super) start: f64,
    pub(super) laps: u32,
    pub(super) period: f64,
}

impl Clock {
    pub(super) fn length(&self) -> f64 {
        f64::from(self.laps) * self.period
    }

    /// Loop time of slot `lap` at clip time 0, as the runtime counts it.
    pub(super) fn tau(&self, lap: u32) -> f64 {
        (-self.start - f64::from(lap) * self.period).rem_euclid(self.length())
    }

    /// The slot that starts where slot `lap` ends: one lap earlier in the loop.
    pub(super) fn next_lap(&self, lap: u32) -> u32 {
        (lap + self.laps - 1) % self.laps
    }
}

impl LoopPath {
    fn length(&self) -> f64 {
        self.clock.length()
    }

    pub(super) fn tau(&self, lap: u32) -> f64 {
        self.clock.tau(lap)
    }

    pub(super) fn next_lap(&self, lap: u32) -> u32 {
        self.clock.next_lap(lap)
    }

    /// The stretch that holds loop time `tau` (the first for a time before the loop's start;
    /// the last, which then ends the loop, for a time past its last key: a loop's keys may end
    /// a rounding short of its laps' length, and the walker holds its last point there).
    fn stretch(&self, tau: f64) -> &Stretch {
        let i = (self.stretches.partition_point(|s| s.times[0] <= tau)).saturating_sub(1);
        let s = &self.stretches[i];
        let last = i + 1 == self.stretches.len();
        assert!(
            s.times[0] <= tau.max(0.0) && (last || tau <= s.times[s.times.len() - 1]),
            "world.glb reads loop time {tau} outside the keys it holds"
        );
        s
    }

    pub(super) fn at(&self, tau: f64) -> DVec2 {
        self.stretch(tau).at(tau)
    }

    /// The heading at loop time `tau`, radians (world axes).
    pub(super) fn heading(&self, tau: f64) -> f64 {
        self.stretch(tau).heading(tau)
    }

    /// Loop times in `[from, to)` where a turn starts or ends.
    fn turn_breaks(&self, from: f64, to: f64) -> Vec<f64> {
        self.stretch(from).turn_breaks(from, to)
    }

    /// The loop's keys from the stretch that holds `from` (times, places).
    fn keys_from(&self, from: f64) -> (&[f64], &[DVec2]) {
        let s = self.stretch(from);
        (&s.times, &s.points)
    }
}

/// A run of a loop's consecutive keys.
struct Stretch {
    times: Vec<f64>,
    points: Vec<DVec2>,
    /// The heading at each point (`crowd_runtime::turn`: periodic, turning at `rate`), and
    /// whether each piece walks: the library's, so that `world.glb` and the runtime face the
    /// same way.
    headings: Vec<f64>,
    walking: Vec<bool>,
    /// Each point's loop time in the library's ticks: the heading model's clock (within
    /// 0.1 ms of `times`).
    turn_times: Vec<f64>,
    /// Turning speed, rad/s (`export.turn_rate_deg_s`).
    rate: f64,
}

impl Stretch {
    /// The loop point that starts the piece holding loop time `tau`.
    fn piece(&self, tau: f64) -> usize {
        self.times
            .partition_point(|&t| t <= tau + SNAP_S)
            .clamp(1, self.times.len())
            - 1
    }

    fn at(&self, tau: f64) -> DVec2 {
        let k = self.piece(tau);
        if (self.times[k] - tau).abs() <= SNAP_S || k + 1 == self.times.len() {
            return self.points[k];
        }
        let (t0, t1) = (self.times[k], self.times[k + 1]);
        let s = if t1 > t0 { (tau - t0) / (t1 - t0) } else { 1.0 };
        self.points[k].lerp(self.points[k + 1], s.clamp(0.0, 1.0))
    }

    /// Piece `k` of the loop (from point `k` to `k + 1`) as the heading model sees it.
    fn turn_piece(&self, k: usize) -> Piece {
        Piece {
            t0: self.turn_times[k],
            t1: self.turn_times[k + 1],
            walks: self.walking[k],
            h0: self.headings[k],
            h1: self.headings[k + 1],
        }
    }

    fn heading(&self, tau: f64) -> f64 {
        if self.times.len() < 2 {
            return self.headings.first().copied().unwrap_or(0.0);
        }
        let k = self
            .turn_times
            .partition_point(|&t| t <= tau)
            .clamp(1, self.turn_times.len() - 1)
            - 1;
        self.turn_piece(k).at(tau, self.rate)
    }

    fn turn_breaks(&self, from: f64, to: f64) -> Vec<f64> {
        let n = self.turn_times.len();
        let first = self
            .turn_times
            .partition_point(|&t| t <= from)
            .saturating_sub(1);
        let mut out = Vec::new();
        for k in first..n.saturating_sub(1) {
            if self.turn_times[k] >= to {
                break;
            }
            let piece = self.turn_piece(k);
            if piece.turn() == 0.0 {
                continue;
            }
            let (start, end) = piece.turning(self.rate);
            out.extend([start, end].into_iter().filter(|&t| t > from && t < to));
        }
        out
    }
}

/// The stretches of loop `plan.lp` (in the library's CHAR order) that its planned slots read:
/// stage 6's kept points at their times (what the translation keys show), and the headings of
/// `crowd_runtime::turn::character_headings` with the library's own ticks for their turns, so
/// that `world.glb` and `crowd-runtime` face the same way.
pub(super) fn loop_path(w: &World, held: &Held, plan: &Plan) -> crowd_core::Result<LoopPath> {
    let members = &w.links.loops[plan.lp];
    let lib = w.library.records();
    let starts = Starts::of(w, members);
    // The headings walk the whole loop in order, and are kept over the stretches the slots
    // read (a long loop's only there: `turn::stretch_headings`). Made beside the path
    // (`rayon::join`) they took 0.4 s off painting's export, but a thread waiting there took
    // up other loops, and the million's export held 11.5 GB against 10.0: one after the
    // other. A gathering build's points are read back from the scratch file as the headings
    // walk the loop, never the whole loop's at once (the million's longest: 0.34 GB).
    let keys: Vec<std::ops::Range<usize>> = (plan.runs.iter())
        .map(|&(a, b)| starts.key[a]..starts.key[b + 1])
        .collect();
    let ch = &lib.characters[plan.lp];
    let headings = turn::stretch_headings_in(lib, &w.library, ch, &keys);
    let stretches = (plan.runs.iter().zip(headings))
        .map(|(&(a, b), (headings, walking))| {
            let (times, points, turn_times) = stretch_keys(w, held, plan, &starts, (a, b));
            Stretch {
                times,
                points,
                headings,
                walking,
                turn_times,
                rate: f64::from(lib.world.turn_rate_deg_s).to_radians(),
            }
        })
        .collect();
    w.library.failure()?;
    Ok(LoopPath {
        stretches,
        clock: plan.clock,
    })
}

/// Where each of a loop's trajectories starts, and where the last ends (members + 1): its first
/// key in the loop's keys (each trajectory's first point left out but for the loop's first),
/// and the library's ticks before it.
struct Starts {
    key: Vec<usize>,
    tick: Vec<u64>,
}

impl Starts {
    fn of(w: &World, members: &[usize]) -> Starts {
        let lib = w.library.records();
        let mut starts = Starts {
            key: Vec::with_capacity(members.len() + 1),
            tick: Vec::with_capacity(members.len() + 1),
        };
        let (mut key, mut tick) = (0usize, 0u64);
        for (j, &i) in members.iter().enumerate() {
            starts.key.push(key);
            starts.tick.push(tick);
            let n = w.summaries.trajectories[i].points;
            key += if j == 0 { n } else { n.saturating_sub(1) };
            tick += u64::from(w.library.duration_ticks(&lib.trajectories[i]));
        }
        starts.key.push(key);
        starts.tick.push(tick);
        starts
    }
}

/// The points of trajectories `a..=b` of a loop at their loop times (seconds and the library's
/// ticks) in world metres, each trajectory's first point left out but for the loop's first.
///
/// A long stretch is made in runs of trajectories, each writing its own part of the lists, on
/// every core (painting's longest loop, 5.5 million keys: 0.13 s on one). Each trajectory
/// starts from the sum of the durations before it, added in the loop's order
/// ([`Plan::offsets`]), so every time is the same bits whatever the stretch.
fn stretch_keys(
    w: &World,
    held: &Held,
    plan: &Plan,
    starts: &Starts,
    (a, b): (usize, usize),
) -> (Vec<f64>, Vec<DVec2>, Vec<f64>) {
    let members = &w.links.loops[plan.lp];
    let key0 = starts.key[a];
    let keys = starts.key[b + 1] - key0;
    let (mut times, mut points, mut turn_times) =
        (vec![0.0; keys], vec![DVec2::ZERO; keys], vec![0.0; keys]);
    let mut parts = Vec::new();
    let (mut t_rest, mut p_rest, mut q_rest) =
        (&mut times[..], &mut points[..], &mut turn_times[..]);
    for first in (a..=b).step_by(MEMBERS_PER_RUN) {
        let end = (first + MEMBERS_PER_RUN).min(b + 1);
        let n = starts.key[end] - starts.key[first];
        let (t, t_tail) = std::mem::take(&mut t_rest).split_at_mut(n);
        let (p, p_tail) = std::mem::take(&mut p_rest).split_at_mut(n);
        let (q, q_tail) = std::mem::take(&mut q_rest).split_at_mut(n);
        (t_rest, p_rest, q_rest) = (t_tail, p_tail, q_tail);
        parts.push(((first, end), (t, p, q)));
    }
    let fill = |((first, end), (t, p, q)): ((usize, usize), KeysPart)| {
        let mut key = 0;
        for (j, &i) in members.iter().enumerate().take(end).skip(first) {
            let r = w.links.refs[i];
            let tr = held.trajectory(r);
            let origin = w
                .graph
                .world_from_patch(w.graph.patches[r.patch as usize].cell);
            let (offset, tick) = (plan.offsets[j], starts.tick[j]);
            let t0 = tr.points[0].t;
            // The library's trajectory `i` holds the same points, quantised.
            let quantised = &w.library.records().trajectories[i];
            let skip = usize::from(j > 0);
            w.library
                .with(quantised.first_point, quantised.points, |quantised| {
                    for (k, cp) in tr.points.iter().enumerate().skip(skip) {
                        t[key] = offset + cp.t - t0;
                        p[key] = origin + cp.pos;
                        q[key] = (tick + u64::from(quantised[k].t)) as f64 * TICK_S;
                        key += 1;
                    }
                });
        }
    };
    if keys >= PARALLEL_KEYS {
        use rayon::prelude::*;
        parts.into_par_iter().for_each(fill);
    } else {
        parts.into_iter().for_each(fill);
    }
    (times, points, turn_times)
}

/// A run's share of [`stretch_keys`]' lists.
type KeysPart<'a> = (&'a mut [f64], &'a mut [DVec2], &'a mut [f64]);

/// Trajectories in a run of [`stretch_keys`].
const MEMBERS_PER_RUN: usize = 1024;
/// Keys from which [`stretch_keys`] uses every core.
const PARALLEL_KEYS: usize = 1 << 16;

/// When loop `lp`'s slots start: its first trajectory's start, its `laps` ([`loop_laps`]),
/// the period.
pub(super) fn clock(w: &World, lp: &[usize], laps: u32) -> Clock {
    Clock {
        start: w.summaries.trajectories[lp[0]].start_s,
        laps,
        period: w.period_s,
    }
}

/// How many periods a loop lasts (its trajectories' durations, rounded; at least one).
pub(super) fn loop_laps(w: &World, lp: &[usize]) -> u32 {
    let length: f64 = (lp.iter())
        .map(|&i| w.summaries.trajectories[i].duration_s)
        .sum();
    (length / w.period_s).round().max(1.0) as u32
}

/// The box (world metres) that holds every point of a loop, so every key of its slots.
pub(super) fn loop_box(summaries: &Summaries, lp: &[usize]) -> (DVec2, DVec2) {
    let empty = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    (lp.iter()).fold(empty, |(lo, hi), &i| {
        let s = &summaries.trajectories[i];
        (lo.min(s.lo), hi.max(s.hi))
    })
}

/// glTF's frame of a world point on the ground.
pub(super) fn gltf_point(p: DVec2) -> [f32; 3] {
    [p.x as f32, 0.0, -p.y as f32]
}

/// The rotation that turns the character's +Z towards world heading `h` (radians from +x
/// towards +y), about +Y: glTF direction (cos h, 0, -sin h), a yaw of h + pi/2 from +Z
/// towards +X.
fn facing(h: f64) -> [f32; 4] {
    let yaw = h + std::f64::consts::FRAC_PI_2;
    let (s, c) = (0.5 * yaw).sin_cos();
    [0.0, s as f32, 0.0, c as f32]
}

/// One slot's keys over the clip: times (seconds from 0 to the period) and world positions;
/// rotation keys at their own times, where turns start and end.
pub(super) struct Keys {
    pub(super) times: Vec<f64>,
    pub(super) points: Vec<DVec2>,
    pub(super) turn_times: Vec<f64>,
    pub(super) turns: Vec<[f32; 4]>,
}

/// Rotation keys closer than this (seconds) are one: the later goes (the clip's end stays).
/// Dropping a sample of a heading that turns at most `rate` leaves the keys turning at most
/// `rate` (the turn between two kept keys is at most `rate` times the time between them).
/// Far above f32's step near a period's end (2 us), and turns between keys large enough that
/// a reader's `acos` of their f32 quaternions' dot product measures them within 0.1 % (at
/// 1 ms, 0.6 %); a dropped key moves the heading by at most the rate times this, 1.44
/// degrees, for a few milliseconds. (At 2 ms, bands' `world.glb` was 4.46 MB, not 3.60.)
const TURN_KEY_S: f64 = 4e-3;
/// Largest turn between two rotation keys, radians: a player interpolates the shorter way,
/// which is the way turned only below half a turn.
const MAX_KEY_TURN: f64 = std::f64::consts::FRAC_PI_2;

/// Rotation keys are dropped where the turn between the kept ones stays within this many
/// radians of the heading (half a degree): a smoothed walk turns a little at every keyframe,
/// and its keys then cost more than its positions.
const TURN_TOLERANCE: f64 = 0.5 * std::f64::consts::PI / 180.0;

/// The keys of `keys` (clip time, heading) that a player needs: Douglas-Peucker on the
/// unwrapped heading, the first and last kept, no two kept keys more than [`MAX_KEY_TURN`]
/// apart. Any subset of samples of a heading turns no faster than it.
fn simplify_turns(keys: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let mut unwrapped = Vec::with_capacity(keys.len());
    for &(t, h) in keys {
        let u = unwrapped.last().map_or(h, |&(_, prev): &(f64, f64)| {
            prev + turn::turn_between(h, prev)
        });
        unwrapped.push((t, u));
    }
    let mut keep = vec![false; keys.len()];
    keep[0] = true;
    keep[keys.len() - 1] = true;
    let mut spans = vec![(0, keys.len() - 1)];
    while let Some((i, j)) = spans.pop() {
        if j <= i + 1 {
            continue;
        }
        let ((ti, hi), (tj, hj)) = (unwrapped[i], unwrapped[j]);
        let off = |k: usize| {
            let (t, h) = unwrapped[k];
            (h - (hi + (hj - hi) * (t - ti) / (tj - ti))).abs()
        };
        let (k, worst) = (i + 1..j)
            .map(|k| (k, off(k)))
            .fold((i + 1, -1.0), |a, b| if b.1 > a.1 { b } else { a });
        if worst > TURN_TOLERANCE || (hj - hi).abs() > MAX_KEY_TURN {
            keep[k] = true;
            spans.push((i, k));
            spans.push((k, j));
        }
    }
    keys.iter()
        .zip(keep)
        .filter_map(|(&k, kept)| kept.then_some(k))
        .collect()
}

/// The rotation keys of the clip that starts at loop time `tau0` and ends at `tau_end`: at 0,
/// at every start and end of a turn inside, and at the period, each a sample of the loop's
/// heading (so the last is the successor's first, bit for bit).
fn turn_keys(path: &LoopPath, tau0: f64, tau_end: f64) -> (Vec<f64>, Vec<[f32; 4]>) {
    let (period, length) = (path.clock.period, path.length());
    let end_tau = tau0 + period;
    let mut breaks: Vec<f64> = if end_tau <= length {
        path.turn_breaks(tau0, end_tau)
            .into_iter()
            .map(|t| t - tau0)
            .collect()
    } else {
        let head = path.turn_breaks(tau0, length).into_iter().map(|t| t - tau0);
        let tail = path.turn_breaks(-1.0, end_tau - length);
        head.chain(tail.into_iter().map(|t| t + length - tau0))
            .collect()
    };
    breaks.sort_by(f64::total_cmp);
    let loop_time = |c: f64| {
        let tau = tau0 + c;
        if tau >= length { tau - length } else { tau }
    };
    let mut keys: Vec<(f64, f64)> = vec![(0.0, path.heading(tau0))];
    for c in breaks {
        if c >= keys.last().expect("the key at 0").0 + TURN_KEY_S && c <= period - TURN_KEY_S {
            keys.push((c, path.heading(loop_time(c))));
        }
    }
    keys.push((period, path.heading(tau_end)));
    let keys = simplify_turns(&keys);
    // A turn of more than a quarter turn between two keys gets keys between.
    let mut split: Vec<(f64, f64)> = Vec::with_capacity(keys.len());
    for w in keys.windows(2) {
        let ((c0, h0), (c1, h1)) = (w[0], w[1]);
        let pieces = (turn::turn_between(h1, h0).abs() / MAX_KEY_TURN)
            .ceil()
            .max(1.0) as usize;
        split.push((c0, h0));
        for i in 1..pieces {
            let c = c0 + (c1 - c0) * i as f64 / pieces as f64;
            split.push((c, path.heading(loop_time(c))));
        }
    }
    split.push(*keys.last().expect("the key at the period"));
    let mut turns: Vec<[f32; 4]> = Vec::with_capacity(split.len());
    for &(_, h) in &split {
        let mut r = facing(h);
        if let Some(prev) = turns.last() {
            let dot: f32 = prev.iter().zip(&r).map(|(a, b)| a * b).sum();
            if dot < 0.0 {
                r = r.map(|v| -v);
            }
        }
        turns.push(r);
    }
    (split.into_iter().map(|k| k.0).collect(), turns)
}

/// The box that holds every key of slot `lap` ([`slot_keys`]): its clip's ends and the
/// loop's points in between.
pub(super) fn window_box(path: &LoopPath, lap: u32) -> (DVec2, DVec2) {
    let (tau0, tau_end) = (path.tau(lap), path.tau(path.next_lap(lap)));
    let (start, end) = (path.at(tau0), path.at(tau_end));
    let mut bounds = (start.min(end), start.max(end));
    let mut run = |from: f64, to: f64| {
        let (times, points) = path.keys_from(from);
        let (a, b) = (
            times.partition_point(|&t| t < from),
            times.partition_point(|&t| t <= to),
        );
        for p in &points[a..b.max(a)] {
            bounds = (bounds.0.min(*p), bounds.1.max(*p));
        }
    };
    let end_tau = tau0 + path.clock.period;
    if end_tau <= path.length() {
        run(tau0, end_tau);
    } else {
        run(tau0, path.length());
        run(f64::NEG_INFINITY, end_tau - path.length());
    }
    bounds
}

/// The keys of slot `lap` of `path` (at loop time `path.tau(lap)` at clip time 0).
pub(super) fn slot_keys(path: &LoopPath, lap: u32) -> Keys {
    let period = path.clock.period;
    let length = path.length();
    let tau0 = path.tau(lap);
    // Its end is its successor's start, the same loop time.
    let tau_end = path.tau(path.next_lap(lap));
    // Keys: 0, every point inside the clip, the period; each with its loop time.
    let mut keys: Vec<(f64, f64, DVec2)> = vec![(0.0, tau0, path.at(tau0))];
    // The loop's points inside the clip's window [tau0, tau0 + period) of loop time,
    // which may wrap past the loop's end: one or two binary-searched runs.
    let run = |from: f64, to: f64, shift: f64| {
        let (loop_times, loop_points) = path.keys_from(from);
        let (a, b) = (
            loop_times.partition_point(|&t| t <= from),
            loop_times.partition_point(|&t| t < to),
        );
        (a..b.max(a)).map(move |k| (loop_times[k] - shift, loop_times[k], loop_points[k]))
    };
    let end_tau = tau0 + period;
    let inner: Vec<(f64, f64, DVec2)> = if end_tau <= length {
        run(tau0, end_tau, tau0).collect()
    } else {
        run(tau0, length, tau0)
            .chain(run(-1.0, end_tau - length, tau0 - length))
            .collect()
    };
    // Keys strictly increasing as f32, as glTF wants them (and short of the last); a point
    // within a microsecond of either end is that end's key (f32 times near the period are
    // 2 us apart, and stage 5 leaves a split point a moment before a band end).
    let end = period as f32;
    for (t, tau, p) in inner {
        let last = keys.last().expect("the key at 0").0 as f32;
        if t > EDGE_S && t < period - EDGE_S && (t as f32) > last && (t as f32) < end {
            keys.push((t, tau, p));
        }
    }
    keys.push((period, tau_end, path.at(tau_end)));
    let (turn_times, turns) = turn_keys(path, tau0, tau_end);
    Keys {
        times: keys.iter().map(|k| k.0).collect(),
        points: keys.iter().map(|k| k.2).collect(),
        turn_times,
        turns,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const RATE: f64 = std::f64::consts::TAU;

    fn path(times: Vec<f64>, points: Vec<DVec2>, start: f64, laps: u32, period: f64) -> LoopPath {
        let xy: Vec<[f64; 2]> = points.iter().map(|p| [p.x, p.y]).collect();
        let whole = Stretch {
            headings: turn::loop_headings(&times, &xy, RATE),
            walking: (1..times.len())
                .map(|k| turn::walks(points[k].distance(points[k - 1]), times[k] - times[k - 1]))
                .collect(),
            turn_times: times.clone(),
            rate: RATE,
            times,
            points,
        };
        LoopPath {
            stretches: vec![whole],
            clock: Clock {
                start,
                laps,
                period,
            },
        }
    }

    /// A square loop of 4 m sides walked at 1 m/s in 16 s, two laps of an 8 s period, with
    /// a period split point at every corner, entered at world time 3.
    fn square() -> LoopPath {
        path(vec![0.0, 4.0, 8.0, 12.0, 16.0], corners(), 3.0, 2, 8.0)
    }

    /// The square's corners, the first again at the end.
    fn corners() -> Vec<DVec2> {
        vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(4.0, 0.0),
            DVec2::new(4.0, 4.0),
            DVec2::new(0.0, 4.0),
            DVec2::new(0.0, 0.0),
        ]
    }

    /// The angle between two rotation keys, radians.
    fn angle(a: [f32; 4], b: [f32; 4]) -> f64 {
        let dot: f32 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
        2.0 * f64::from(dot.abs().min(1.0)).acos()
    }

    /// Keys that end a rounding short of the laps' length: a slot whose clip starts or ends
    /// past the last key holds the last point there, as a player holds a track's last key.
    #[test]
    fn a_loop_a_hair_short_of_its_laps_holds_its_last_point_to_the_end() {
        let end = 16.0 - 1e-9;
        let p = path(vec![0.0, 4.0, 8.0, 12.0, end], corners(), 0.0, 2, 8.0);
        let tau = 16.0 - 1e-10;
        assert_eq!(p.at(tau), DVec2::ZERO);
        assert!(p.heading(tau).is_finite());
        assert!(p.turn_breaks(tau, 16.0).is_empty());
    }

    #[test]
    fn a_slot_ends_where_and_facing_as_its_successor_starts() {
        let path = square();
        for lap in 0..path.clock.laps {
            let (a, b) = (slot_keys(&path, lap), slot_keys(&path, path.next_lap(lap)));
            let n = a.times.len();
            assert_eq!(a.points[n - 1], b.points[0]);
            assert_eq!(
                a.turns.last().unwrap().map(f32::abs),
                b.turns[0].map(f32::abs)
            );
            // Both pieces at the handover are pieces of the walk at 1 m/s.
            let speed = |k: &Keys, i: usize| {
                k.points[i].distance(k.points[i + 1]) / (k.times[i + 1] - k.times[i])
            };
            assert!((speed(&a, n - 2) - 1.0).abs() < 1e-9);
            assert!((speed(&b, 0) - 1.0).abs() < 1e-9);
        }
    }

    #[test]
    fn corners_turn_at_the_rate_over_a_quarter_second() {
        let path = square();
        for lap in 0..path.clock.laps {
            let k = slot_keys(&path, lap);
            for i in 1..k.turns.len() {
                let dt = k.turn_times[i] - k.turn_times[i - 1];
                let rate = angle(k.turns[i - 1], k.turns[i]) / dt;
                assert!(rate <= RATE * 1.0001, "{rate} rad/s at {}", k.turn_times[i]);
            }
            // Two corners in the clip, each a quarter turn over 0.25 s: keys where each turn
            // starts and ends, and at the clip's ends.
            assert_eq!(k.turn_times.len(), 6, "{:?}", k.turn_times);
        }
    }

    #[test]
    fn a_standing_walker_holds_its_heading_and_turns_as_it_walks_off() {
        // Walks east 0-3 s, stands 3-10 s, walks back west 10-13 s, stands to 16 s.
        let points = vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(3.0, 0.0),
            DVec2::new(3.0, 0.0),
            DVec2::new(0.0, 0.0),
            DVec2::new(0.0, 0.0),
        ];
        let path = path(vec![0.0, 3.0, 10.0, 13.0, 16.0], points, 0.0, 1, 16.0);
        let east = path.heading(3.0);
        assert!(east.abs() < 1e-12);
        assert_eq!(path.heading(9.5), east);
        // Half a turn at 360 degrees a second: 9.5-10 s (a piece turns a milliradian short of
        // half a turn, the walk finishes it).
        let back = turn::turn_between(path.heading(10.0), std::f64::consts::PI);
        assert!(back.abs() < 1e-3 + 1e-12, "{back}");
        let k = slot_keys(&path, 0);
        let quiet: Vec<f64> = k
            .turn_times
            .iter()
            .copied()
            .filter(|&t| t > 3.0 && t < 9.5 - 1e-9)
            .collect();
        assert!(quiet.is_empty(), "keys while standing: {quiet:?}");
    }
}
