//! A walker slot's animation keys: its loop as positions at loop times, the keys of one
//! clip (at 0, at every point inside the period, at the period) and the rotations that face
//! the walk, in glTF's frame (world (x, y) -> glTF (x, 0, -y)).
//!
//! A slot's clip ends where and when its successor's starts, and both are computed from the
//! same loop time ([`LoopPath::tau`] of the successor's lap), so the two keys are the same
//! bits: the same position and the same heading. The keys between are the loop's own points,
//! so the last piece of a slot and the first of its successor are two pieces of one walk.

use crate::glb::World;
use glam::DVec2;

/// Loop times closer than this (seconds) are one instant: a clip's window starts at a period's
/// split point up to the rounding of the sums that make loop times.
const SNAP_S: f64 = 1e-7;
/// Loop points closer than this (seconds) to a clip's ends make no key of their own.
const EDGE_S: f64 = 1e-6;

/// A walker's loop as positions at loop times (seconds from the loop's start).
pub(super) struct LoopPath {
    pub(super) times: Vec<f64>,
    pub(super) points: Vec<DVec2>,
    /// The direction walked from each point on (standing: the last one walked, round the loop).
    headings: Vec<DVec2>,
    /// World time at which the loop's first trajectory starts.
    pub(super) start: f64,
    pub(super) laps: u32,
    period: f64,
}

impl LoopPath {
    fn length(&self) -> f64 {
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

    /// The loop point that starts the piece holding loop time `tau`.
    fn piece(&self, tau: f64) -> usize {
        self.times
            .partition_point(|&t| t <= tau + SNAP_S)
            .clamp(1, self.times.len())
            - 1
    }

    pub(super) fn at(&self, tau: f64) -> DVec2 {
        let k = self.piece(tau);
        if (self.times[k] - tau).abs() <= SNAP_S || k + 1 == self.times.len() {
            return self.points[k];
        }
        let (t0, t1) = (self.times[k], self.times[k + 1]);
        let s = if t1 > t0 { (tau - t0) / (t1 - t0) } else { 1.0 };
        self.points[k].lerp(self.points[k + 1], s.clamp(0.0, 1.0))
    }

    /// The direction walked from loop time `tau` on (standing: the last one walked).
    pub(super) fn heading(&self, tau: f64) -> DVec2 {
        self.headings[self.piece(tau)]
    }
}

/// Pieces shorter than this (metres) are standing: they do not turn the character.
const STILL_M: f64 = 1e-5;

/// The direction walked from each of `points` on; standing, the last one walked before it,
/// round the loop (whose last point is its first).
fn headings(points: &[DVec2]) -> Vec<DVec2> {
    let n = points.len();
    let walked = |k: usize| {
        let d = points[(k + 1).min(n - 1)] - points[k];
        (d.length() > STILL_M).then(|| d.normalize())
    };
    let mut last = (0..n - 1).rev().find_map(walked).unwrap_or(DVec2::Y);
    let mut out: Vec<DVec2> = (0..n - 1)
        .map(|k| {
            if let Some(d) = walked(k) {
                last = d;
            }
            last
        })
        .collect();
    // The loop's end is its start: the direction walked from there on.
    out.push(out.first().copied().unwrap_or(DVec2::Y));
    out
}

pub(super) fn loop_paths(w: &World) -> Vec<LoopPath> {
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
                headings: headings(&points),
                times,
                points,
                start,
                laps,
                period: w.period_s,
            }
        })
        .collect()
}

/// glTF's frame of a world point on the ground.
pub(super) fn gltf_point(p: DVec2) -> [f32; 3] {
    [p.x as f32, 0.0, -p.y as f32]
}

/// The rotation that turns the character's +Z towards world direction `d`, about +Y.
fn facing(d: DVec2) -> [f32; 4] {
    // glTF direction (d.x, 0, -d.y); yaw from +Z towards +X.
    let yaw = d.x.atan2(-d.y);
    let (s, c) = (0.5 * yaw).sin_cos();
    [0.0, s as f32, 0.0, c as f32]
}

/// One slot's keys over the clip: times (seconds from 0 to the period), world positions and
/// rotations, as many of each.
pub(super) struct Keys {
    pub(super) times: Vec<f64>,
    pub(super) points: Vec<DVec2>,
    pub(super) turns: Vec<[f32; 4]>,
}

/// The keys of slot `lap` of `path` (at loop time `path.tau(lap)` at clip time 0).
pub(super) fn slot_keys(path: &LoopPath, lap: u32) -> Keys {
    let period = path.period;
    let length = path.length();
    let tau0 = path.tau(lap);
    // Its end is its successor's start, the same loop time.
    let tau_end = path.tau(path.next_lap(lap));
    // Keys: 0, every point inside the clip, the period; each with its loop time.
    let mut keys: Vec<(f64, f64, DVec2)> = vec![(0.0, tau0, path.at(tau0))];
    // The loop's points inside the clip's window [tau0, tau0 + period) of loop time,
    // which may wrap past the loop's end: one or two binary-searched runs.
    let (loop_times, loop_points) = (&path.times, &path.points);
    let run = |from: f64, to: f64, shift: f64| {
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
    // Facing: the direction walked from each key on, taken from the loop, so that the last
    // key faces as the successor's first does.
    let mut turns: Vec<[f32; 4]> = Vec::with_capacity(keys.len());
    for &(_, tau, _) in &keys {
        let mut r = facing(path.heading(tau));
        if let Some(prev) = turns.last() {
            let dot: f32 = prev.iter().zip(&r).map(|(a, b)| a * b).sum();
            if dot < 0.0 {
                r = r.map(|v| -v);
            }
        }
        turns.push(r);
    }
    Keys {
        times: keys.iter().map(|k| k.0).collect(),
        points: keys.iter().map(|k| k.2).collect(),
        turns,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A square loop of 4 m sides walked at 1 m/s in 16 s, two laps of an 8 s period, with
    /// a period split point at every corner, entered at world time 3.
    fn square() -> LoopPath {
        let corners = [
            DVec2::new(0.0, 0.0),
            DVec2::new(4.0, 0.0),
            DVec2::new(4.0, 4.0),
            DVec2::new(0.0, 4.0),
            DVec2::new(0.0, 0.0),
        ];
        let points = corners.to_vec();
        LoopPath {
            headings: headings(&points),
            times: vec![0.0, 4.0, 8.0, 12.0, 16.0],
            points,
            start: 3.0,
            laps: 2,
            period: 8.0,
        }
    }

    #[test]
    fn a_slot_ends_where_and_facing_as_its_successor_starts() {
        let path = square();
        for lap in 0..path.laps {
            let (a, b) = (slot_keys(&path, lap), slot_keys(&path, path.next_lap(lap)));
            let n = a.times.len();
            assert_eq!(a.points[n - 1], b.points[0]);
            let (qa, qb) = (a.turns[n - 1], b.turns[0]);
            let dot: f32 = qa.iter().zip(&qb).map(|(x, y)| x * y).sum();
            assert!((dot.abs() - 1.0).abs() < 1e-6, "{qa:?} {qb:?}");
            // Both pieces at the handover are pieces of the walk at 1 m/s.
            let speed = |k: &Keys, i: usize| {
                k.points[i].distance(k.points[i + 1]) / (k.times[i + 1] - k.times[i])
            };
            assert!((speed(&a, n - 2) - 1.0).abs() < 1e-9);
            assert!((speed(&b, 0) - 1.0).abs() < 1e-9);
        }
    }

    #[test]
    fn a_standing_walker_faces_the_way_it_last_walked_round_the_loop() {
        // Stands at its start and end: the loop's last walk faces -y.
        let points = vec![
            DVec2::new(0.0, 0.0),
            DVec2::new(0.0, 0.0),
            DVec2::new(3.0, 0.0),
            DVec2::new(0.0, 0.0),
            DVec2::new(0.0, 0.0),
        ];
        let h = headings(&points);
        assert_eq!(h[0], DVec2::NEG_X);
        assert_eq!(h[1], DVec2::X);
        assert_eq!(h[2], DVec2::NEG_X);
        assert_eq!(h[3], DVec2::NEG_X);
        assert_eq!(h[4], h[0]);
    }
}
