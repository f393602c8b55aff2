//! A patch's people as the editing model sees them: every trajectory copied once for each
//! period shift that puts part of it in the edit's time span, and every stander, each following
//! its plan (where stages 4-6 put it) on the problem's timeline, with the mask that says how
//! much of an edit a walker may take at each moment.

use crowd_core::trajectories::{PatchMotion, Trajectory, band_ends, position_at};
use crowd_edit::model::Plan;
use glam::DVec2;

/// The editing model's time step, s.
pub const DT: f64 = 0.1;
/// How long an edit's mask takes to rise from 0 to 1 (and to fall), s: after a walker's entry
/// band, before its exit band, and at both ends of the problem's span. A smoothstep, so the
/// edited walk leaves and rejoins the planned one with the same position and velocity.
pub const RAMP_S: f64 = 1.0;

/// One character of a patch's problem.
#[derive(Clone, Debug)]
pub struct Copy {
    /// The trajectory it walks (`None`: a stander at `stand`).
    pub trajectory: Option<usize>,
    pub stand: DVec2,
    /// Added to the trajectory's times to put them on the problem's clock, s.
    pub shift: f64,
    /// When it is in the patch, on the problem's clock.
    pub span: (f64, f64),
    /// When it may be edited (between its border bands), on the problem's clock.
    pub interior: (f64, f64),
}

/// The characters of one patch over `[start, end]` (absolute seconds, at most a period long).
pub fn copies(motion: &PatchMotion, period: f64, (start, end): (f64, f64)) -> Vec<Copy> {
    let mut out = Vec::new();
    for (j, tr) in motion.trajectories.iter().enumerate() {
        let (a, b) = (tr.points[0].t, tr.points[tr.points.len() - 1].t);
        let (entry_band, exit_band) = band_ends(&tr.points);
        let e0 = entry_band.map_or(a, |i| tr.points[i].t);
        let e1 = exit_band.map_or(b, |i| tr.points[i].t);
        let first = ((start - b) / period).floor() as i64;
        let last = ((end - a) / period).ceil() as i64;
        for m in first..=last {
            let shift = m as f64 * period;
            if a + shift < end && b + shift > start {
                out.push(Copy {
                    trajectory: Some(j),
                    stand: DVec2::ZERO,
                    shift,
                    span: (a + shift, b + shift),
                    interior: (e0 + shift, e1 + shift),
                });
            }
        }
    }
    for &s in &motion.standers {
        out.push(Copy {
            trajectory: None,
            stand: s,
            shift: 0.0,
            span: (f64::NEG_INFINITY, f64::INFINITY),
            interior: (0.0, 0.0),
        });
    }
    out
}

/// 0 below 0, 1 above [`RAMP_S`], a smoothstep between.
fn ramp(x: f64) -> f64 {
    let s = (x / RAMP_S).clamp(0.0, 1.0);
    s * s * (3.0 - 2.0 * s)
}

impl Copy {
    /// How much of the edit it takes at time `t` (problem clock): 0 outside its interior and
    /// the problem's span, rising smoothly to 1 inside.
    pub fn mask(&self, t: f64, (start, end): (f64, f64)) -> f64 {
        if self.trajectory.is_none() {
            return 0.0;
        }
        ramp(t - self.interior.0) * ramp(self.interior.1 - t) * ramp(t - start) * ramp(end - t)
    }

    pub fn present(&self, t: f64) -> bool {
        (self.span.0..=self.span.1).contains(&t)
    }

    /// Where the plan has it at `t` (problem clock).
    pub fn position(&self, motion: &PatchMotion, t: f64) -> DVec2 {
        match self.trajectory {
            Some(j) => position_at(&motion.trajectories[j].points, t - self.shift),
            None => self.stand,
        }
    }

    /// Its plan at `t`: position, and velocity and acceleration by differences over `DT / 2`
    /// (one-sided at its span's ends).
    fn plan(&self, motion: &PatchMotion, t: f64, span: (f64, f64)) -> Plan {
        let present = self.present(t);
        let editable = present && self.mask(t, span) > 0.0;
        let Some(j) = self.trajectory else {
            return Plan {
                pos: self.stand,
                vel: DVec2::ZERO,
                acc: DVec2::ZERO,
                present,
                editable,
            };
        };
        let tr: &Trajectory = &motion.trajectories[j];
        let at = |t: f64| position_at(&tr.points, t - self.shift);
        let h = DT / 2.0;
        let (lo, hi) = ((t - h).max(self.span.0), (t + h).min(self.span.1));
        let (p_lo, p, p_hi) = (at(lo), at(t), at(hi));
        let vel = if hi > lo {
            (p_hi - p_lo) / (hi - lo)
        } else {
            DVec2::ZERO
        };
        let acc = if t - lo > 0.0 && hi - t > 0.0 {
            ((p_hi - p) / (hi - t) - (p - p_lo) / (t - lo)) / ((hi - lo) / 2.0)
        } else {
            DVec2::ZERO
        };
        Plan {
            pos: p,
            vel,
            acc,
            present,
            editable,
        }
    }
}

/// The plans of `copies` at every half step of `steps` steps from `start`
/// (`plans[h * n + i]`), and the state they start in (a character that enters later waits
/// where and how it will enter).
pub fn plans(
    copies: &[Copy],
    motion: &PatchMotion,
    span: (f64, f64),
    steps: usize,
) -> (Vec<Plan>, Vec<f64>) {
    let n = copies.len();
    let mut plans = Vec::with_capacity((2 * steps + 1) * n);
    for h in 0..=2 * steps {
        let t = span.0 + h as f64 * DT / 2.0;
        plans.extend(copies.iter().map(|c| c.plan(motion, t, span)));
    }
    let mut x0 = vec![0.0; 4 * n];
    for i in 0..n {
        let first = (0..=steps)
            .find(|&k| plans[2 * k * n + i].present)
            .unwrap_or(0);
        let p = plans[2 * first * n + i];
        x0[4 * i..4 * i + 4].copy_from_slice(&[p.pos.x, p.pos.y, p.vel.x, p.vel.y]);
    }
    (plans, x0)
}
