//! One trajectory made smooth (Ramirez section 3.5): tacks sampled along it, a clamped cubic
//! spline through them, sampled again more finely where it bends.

use crate::spline::Spline;
use crowd_core::trajectories::{ControlPoint, PointKind, Trajectory, position_at};
use glam::DVec2;

/// What the curve of one trajectory may do.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    pub side_m: f64,
    pub period_s: f64,
    pub tack_spacing_s: f64,
    /// Ramirez's alpha: a curve point farther than this from the trajectory is dropped.
    pub max_displacement_m: f64,
    pub tolerance_m: f64,
    /// Share of the way from the polyline to the curve (1: the curve).
    pub blend: f64,
    /// Depth of the border bands (the character radius): curve points stay out of them.
    pub band_m: f64,
}

/// Time from a border point to the sample that fixes the velocity there: the polyline's first
/// and last chords then leave and reach the border at the crossing velocity, to within
/// acceleration x this.
const END_STEP_S: f64 = 0.1;
/// The finest resampling step.
const MIN_STEP_S: f64 = 0.05;

/// The smoothed trajectory and how many curve points it dropped. Entry and exit stay exactly
/// where and when they were; the curve leaves the entry at `v_entry` and reaches the exit at
/// `v_exit` (the crossing velocities, so joins between patches are C1); a pause stays a pause,
/// reached and left at rest.
pub fn smooth(
    tr: &Trajectory,
    v_entry: DVec2,
    v_exit: DVec2,
    limits: &Limits,
) -> (Trajectory, u64) {
    let pts = &tr.points;
    // The band pieces at either end stay as they are: straight, at the crossing velocity.
    let (entry_band, exit_band) = crowd_core::trajectories::band_ends(pts);
    let first = entry_band.unwrap_or(0);
    let last = exit_band.unwrap_or(pts.len() - 1);
    let mut out = pts[..=first].to_vec();
    let mut dropped = 0;
    let mut i = first;
    while i < last {
        if pts[i + 1].pos == pts[i].pos {
            // Standing still: kept as it is.
            out.push(pts[i + 1]);
            i += 1;
            continue;
        }
        let mut j = i + 1;
        while j < last && pts[j + 1].pos != pts[j].pos {
            j += 1;
        }
        let v0 = if i == first { v_entry } else { DVec2::ZERO };
        let v1 = if j == last { v_exit } else { DVec2::ZERO };
        dropped += piece(&pts[i..=j], v0, v1, limits, &mut out);
        i = j;
    }
    out.extend_from_slice(&pts[last + 1..]);
    (
        Trajectory {
            entry: tr.entry,
            exit: tr.exit,
            points: out,
        },
        dropped,
    )
}

/// Smooths the moving piece `pts` (no pause inside) and appends its points after the first.
fn piece(
    pts: &[ControlPoint],
    v0: DVec2,
    v1: DVec2,
    limits: &Limits,
    out: &mut Vec<ControlPoint>,
) -> u64 {
    let (first, last) = (pts[0], pts[pts.len() - 1]);
    let duration = last.t - first.t;
    let n = ((duration / limits.tack_spacing_s).round() as usize).max(1);
    let tack_t: Vec<f64> = (0..=n)
        .map(|k| {
            if k == n {
                last.t
            } else {
                first.t + duration * k as f64 / n as f64
            }
        })
        .collect();
    let tack_p: Vec<DVec2> = tack_t.iter().map(|&t| position_at(pts, t)).collect();
    let spline = Spline::clamped(tack_t.clone(), tack_p, v0, v1);

    // Times to sample: the tacks, a step from either end, every multiple of the period, and
    // midpoints wherever the curve strays from the chord.
    let mut base = tack_t;
    if duration > 4.0 * END_STEP_S {
        base.push(first.t + END_STEP_S);
        base.push(last.t - END_STEP_S);
    }
    let period = limits.period_s;
    let mut k = (first.t / period).floor() + 1.0;
    let mut splits = Vec::new();
    while k * period < last.t {
        splits.push(k * period);
        k += 1.0;
    }
    base.extend(&splits);
    base.sort_by(f64::total_cmp);
    base.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    let mut times = vec![base[0]];
    for w in base.windows(2) {
        refine(&spline, w[0], w[1], limits.tolerance_m, 8, &mut times);
        times.push(w[1]);
    }

    let mut dropped = 0;
    // Out of the border bands, as stage 5 keeps every free point.
    let (lo, hi) = (limits.band_m, limits.side_m - limits.band_m);
    let inside = |p: DVec2| p.x >= lo && p.y >= lo && p.x <= hi && p.y <= hi;
    for &t in &times[1..times.len() - 1] {
        let is_split = splits.iter().any(|&s| (s - t).abs() < 1e-9);
        let on_line = position_at(pts, t);
        let p = on_line + limits.blend * (spline.at(t) - on_line);
        let kept = p.distance(on_line) <= limits.max_displacement_m && inside(p);
        if kept {
            let kind = if is_split {
                PointKind::Split
            } else {
                PointKind::Sample
            };
            out.push(ControlPoint { pos: p, t, kind });
        } else {
            dropped += 1;
            if is_split {
                // A character still passes the period here: keep the mark, on the old path.
                out.push(ControlPoint {
                    pos: position_at(pts, t),
                    t,
                    kind: PointKind::Split,
                });
            }
        }
    }
    out.push(last);
    dropped
}

/// Adds the times strictly between `a` and `b` where the curve needs more points than its
/// chord, in increasing order.
fn refine(s: &Spline, a: f64, b: f64, tolerance: f64, depth: u32, times: &mut Vec<f64>) {
    if depth == 0 || b - a < 2.0 * MIN_STEP_S {
        return;
    }
    let m = 0.5 * (a + b);
    let chord = 0.5 * (s.at(a) + s.at(b));
    if s.at(m).distance(chord) <= tolerance {
        return;
    }
    refine(s, a, m, tolerance, depth - 1, times);
    times.push(m);
    refine(s, m, b, tolerance, depth - 1, times);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cp(x: f64, y: f64, t: f64, kind: PointKind) -> ControlPoint {
        ControlPoint {
            pos: DVec2::new(x, y),
            t,
            kind,
        }
    }

    fn limits() -> Limits {
        Limits {
            side_m: 8.0,
            period_s: 20.0,
            tack_spacing_s: 1.0,
            max_displacement_m: 0.6,
            tolerance_m: 0.01,
            blend: 1.0,
            band_m: 0.3,
        }
    }

    #[test]
    fn a_bend_is_rounded_and_the_ends_stay_exact() {
        let tr = Trajectory {
            entry: 0,
            exit: 1,
            points: vec![
                cp(0.0, 2.0, 1.0, PointKind::Entry),
                cp(0.3, 2.0, 1.0 + 0.3 / 1.3, PointKind::Band),
                cp(4.0, 3.0, 4.0, PointKind::Bend),
                cp(7.7, 2.0, 7.0 - 0.3 / 1.3, PointKind::Band),
                cp(8.0, 2.0, 7.0, PointKind::Exit),
            ],
        };
        let v = DVec2::new(1.3, 0.0);
        let (s, _) = smooth(&tr, v, v, &limits());
        let n = s.points.len();
        // The border bands stay exactly as they were.
        assert_eq!(s.points[..2], tr.points[..2]);
        assert_eq!(s.points[n - 2..], tr.points[3..]);
        assert!(n > 8);
        assert!(s.points.windows(2).all(|w| w[1].t > w[0].t));
        // The curve leaves and reaches the bands at the crossing velocity.
        let chord = |a: &ControlPoint, b: &ControlPoint| (b.pos - a.pos) / (b.t - a.t);
        assert!((chord(&s.points[1], &s.points[2]) - v).length() < 0.1);
        assert!((chord(&s.points[n - 3], &s.points[n - 2]) - v).length() < 0.1);
    }

    #[test]
    fn a_pause_stays_and_is_reached_at_rest() {
        let tr = Trajectory {
            entry: 0,
            exit: 1,
            points: vec![
                cp(0.0, 4.0, 0.0, PointKind::Entry),
                cp(4.0, 4.0, 3.0, PointKind::Pause),
                cp(4.0, 4.0, 9.0, PointKind::Pause),
                cp(4.0, 8.0, 12.0, PointKind::Exit),
            ],
        };
        let (s, _) = smooth(&tr, DVec2::new(1.3, 0.0), DVec2::new(0.0, 1.3), &limits());
        let pauses: Vec<_> = s
            .points
            .iter()
            .filter(|p| p.kind == PointKind::Pause)
            .collect();
        assert_eq!(pauses.len(), 2);
        assert_eq!((pauses[0].t, pauses[1].t), (3.0, 9.0));
        let k = s.points.iter().position(|p| p.t == 3.0).unwrap();
        let before = s.points[k - 1];
        assert!(before.pos.distance(pauses[0].pos) / (3.0 - before.t) < 0.3);
    }

    #[test]
    fn a_period_crossing_keeps_its_split_point() {
        let tr = Trajectory {
            entry: 0,
            exit: 1,
            points: vec![
                cp(0.0, 4.0, 16.0, PointKind::Entry),
                cp(5.0, 4.0, 20.0, PointKind::Split),
                cp(8.0, 4.0, 22.5, PointKind::Exit),
            ],
        };
        let (s, _) = smooth(&tr, DVec2::new(1.25, 0.0), DVec2::new(1.2, 0.0), &limits());
        assert!(
            s.points
                .iter()
                .any(|p| p.kind == PointKind::Split && p.t == 20.0)
        );
    }
}
