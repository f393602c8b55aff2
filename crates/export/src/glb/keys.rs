//! A walker slot's animation keys: its loop as positions at loop times, the keys of one
//! clip (at 0, at every point inside the period, at the period) and the rotations that face
//! the walk, in glTF's frame (world (x, y) -> glTF (x, 0, -y)).

use crate::glb::World;
use glam::DVec2;

/// A walker's loop as positions at loop times (seconds from the loop's start).
pub(super) struct LoopPath {
    pub(super) times: Vec<f64>,
    pub(super) points: Vec<DVec2>,
    /// World time at which the loop's first trajectory starts.
    pub(super) start: f64,
    pub(super) laps: u32,
}

impl LoopPath {
    pub(super) fn at(&self, tau: f64) -> DVec2 {
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
                times,
                points,
                start,
                laps,
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

/// The keys of the slot of `path` that is at loop time `tau0` at clip time 0.
pub(super) fn slot_keys(path: &LoopPath, tau0: f64, period: f64) -> Keys {
    let length = f64::from(path.laps) * period;
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
    Keys {
        times: key_t,
        points: key_p,
        turns: q,
    }
}
