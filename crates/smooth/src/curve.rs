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
/// A corner sharper than this is taken at rest, as people turn back: the curve slows to a
/// stop there instead of sweeping a wide arc at walking speed (a U-turn at 1.3 m/s on a
/// 1 m radius spins at 1.3 rad/s for 2.4 s; stopped, it does not spin while walking at all).
const SHARP_RAD: f64 = std::f64::consts::FRAC_PI_2;
/// Most of a pause a walker may spend still arriving or already leaving (each side).
const PAUSE_SHARE: f64 = 0.45;
/// The finest resampling step.
const MIN_STEP_S: f64 = 0.05;
/// The largest change of velocity along one chord of the resampled curve, m/s. A player
/// shows each chord at constant velocity and the whole change at its vertex: sparse vertices
/// on a gentle turn would show as jerks (at 0.27 s apart, a 0.3 rad/s turn plays at
/// 0.8 rad/s in one frame and 0 in the next two).
const MAX_CHORD_DV: f64 = 0.025;

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
    Curve::new(tr, v_entry, v_exit, limits).blend(limits)
}

/// A trajectory's curve before it is blended with its polyline: the splines through its tacks
/// and where they are sampled, which do not depend on `Limits::blend`. Stage 6 moves a walker
/// back towards its polyline one halving of the blend at a time; made once, each halving costs
/// only its points (the splines and their sampling were a quarter of the stage, made again at
/// every halving).
pub struct Curve<'a> {
    tr: &'a Trajectory,
    /// The first and last points of the curved stretch (the band ends, or the ends).
    first: usize,
    last: usize,
    parts: Vec<Part>,
}

/// A stretch of a [`Curve`] between two of its polyline's points.
enum Part {
    /// Standing still: the point kept as it is.
    Stand(ControlPoint),
    Moving(Moving),
}

/// A moving stretch's samples: each with its time, its place on the polyline and on the
/// spline.
struct Moving {
    /// When the walker leaves the pause before, if it leaves earlier than the polyline (the
    /// pause's end moves with it).
    leaves: Option<f64>,
    samples: Vec<(f64, DVec2, DVec2)>,
    /// The stretch's last point, its time moved by the slack taken of a pause after it.
    last: ControlPoint,
    /// The multiples of the period inside the stretch.
    splits: Vec<f64>,
}

impl<'a> Curve<'a> {
    pub fn new(tr: &'a Trajectory, v_entry: DVec2, v_exit: DVec2, limits: &Limits) -> Curve<'a> {
        let pts = &tr.points;
        // The band pieces at either end stay as they are: straight, at the crossing velocity.
        let (entry_band, exit_band) = crowd_core::trajectories::band_ends(pts);
        let first = entry_band.unwrap_or(0);
        let last = exit_band.unwrap_or(pts.len() - 1);
        let mut parts = Vec::new();
        let mut i = first;
        while i < last {
            if pts[i + 1].pos == pts[i].pos {
                parts.push(Part::Stand(pts[i + 1]));
                i += 1;
                continue;
            }
            let mut j = i + 1;
            while j < last && pts[j + 1].pos != pts[j].pos && !sharp(&pts[j - 1..=j + 1]) {
                j += 1;
            }
            let v0 = if i == first { v_entry } else { DVec2::ZERO };
            let v1 = if j == last { v_exit } else { DVec2::ZERO };
            // Leaving a pause a little earlier and reaching the next one a little later, at
            // most PAUSE_SHARE of the standing either side.
            let leave = if i > first && pts[i - 1].pos == pts[i].pos {
                PAUSE_SHARE * (pts[i].t - pts[i - 1].t)
            } else {
                0.0
            };
            let reach = if j < last && pts[j + 1].pos == pts[j].pos {
                PAUSE_SHARE * (pts[j + 1].t - pts[j].t)
            } else {
                0.0
            };
            parts.push(Part::Moving(moving(
                &pts[i..=j],
                v0,
                v1,
                (leave, reach),
                limits,
            )));
            i = j;
        }
        Curve {
            tr,
            first,
            last,
            parts,
        }
    }

    /// The curve blended with the polyline by `limits.blend`, and how many of its points were
    /// dropped for straying too far.
    pub fn blend(&self, limits: &Limits) -> (Trajectory, u64) {
        let pts = &self.tr.points;
        let duration = pts[pts.len() - 1].t - pts[0].t;
        let mut out = Vec::with_capacity(pts.len() + (duration / MIN_STEP_S) as usize / 4);
        out.extend_from_slice(&pts[..=self.first]);
        let mut dropped = 0;
        for part in &self.parts {
            match part {
                Part::Stand(p) => out.push(*p),
                Part::Moving(m) => dropped += blend_moving(m, limits, &mut out),
            }
        }
        out.extend_from_slice(&pts[self.last + 1..]);
        (
            Trajectory {
                entry: self.tr.entry,
                exit: self.tr.exit,
                points: out,
            },
            dropped,
        )
    }
}

/// Does the polyline turn back at the middle of `w` (three points) by more than [`SHARP_RAD`]?
fn sharp(w: &[ControlPoint]) -> bool {
    let (u, v) = (w[1].pos - w[0].pos, w[2].pos - w[1].pos);
    u.length() > 0.0 && v.length() > 0.0 && u.perp_dot(v).atan2(u.dot(v)).abs() > SHARP_RAD
}

/// The curve of the moving stretch `pts` (no pause inside), sampled.
///
/// A stretch that leaves or reaches a pause at rest may take up to `pause_slack` (before,
/// after) of it: it starts moving that much earlier and stops that much later, so that it
/// slows over its whole last tack interval instead of braking at its end (a clamped cubic
/// that must cover its interval's distance and stop brakes at 4 u / h at the end; given half
/// the interval more, at 4 u / 3 h).
fn moving(
    pts: &[ControlPoint],
    v0: DVec2,
    v1: DVec2,
    pause_slack: (f64, f64),
    limits: &Limits,
) -> Moving {
    let (first, last) = (pts[0], pts[pts.len() - 1]);
    let duration = last.t - first.t;
    let n = ((duration / limits.tack_spacing_s).round() as usize).max(1);
    let interval = duration / n as f64;
    let (early, late) = (
        pause_slack.0.min(0.5 * interval),
        pause_slack.1.min(0.5 * interval),
    );
    let tack_t: Vec<f64> = (0..=n)
        .map(|k| {
            if k == n {
                last.t + late
            } else if k == 0 {
                first.t - early
            } else {
                first.t + duration * k as f64 / n as f64
            }
        })
        .collect();
    let (first, last) = (
        ControlPoint {
            t: first.t - early,
            ..first
        },
        ControlPoint {
            t: last.t + late,
            ..last
        },
    );
    let tack_p: Vec<DVec2> = tack_t.iter().map(|&t| position_at(pts, t)).collect();
    let spline = Spline::clamped(tack_t.clone(), tack_p, v0, v1);

    // Times to sample: the tacks, a step from either end, and midpoints wherever the curve
    // strays from the chord; every multiple of the period is marked on the walk after.
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
    base.sort_by(f64::total_cmp);
    base.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    let base: Vec<Knot> = base.into_iter().map(|t| Knot::on(&spline, t)).collect();
    let mut times = vec![base[0]];
    for w in base.windows(2) {
        refine(&spline, w[0], w[1], limits.tolerance_m, 8, &mut times);
        times.push(w[1]);
    }
    let samples = times[1..times.len() - 1]
        .iter()
        .map(|k| (k.t, position_at(pts, k.t), k.p))
        .collect();
    Moving {
        leaves: (early > 0.0).then_some(first.t),
        samples,
        last,
        splits,
    }
}

/// Appends the moving stretch `m`, blended, after the point before it (already in `out`);
/// returns how many of its samples it dropped.
fn blend_moving(m: &Moving, limits: &Limits, out: &mut Vec<ControlPoint>) -> u64 {
    if let Some(t) = m.leaves {
        // The pause's end point, already written, moves with the start.
        let end = out.last_mut().expect("a pause before the piece");
        end.t = t;
    }
    let mut dropped = 0;
    // Out of the border bands, as stage 5 keeps every free point.
    let (lo, hi) = (limits.band_m, limits.side_m - limits.band_m);
    let inside = |p: DVec2| p.x >= lo && p.y >= lo && p.x <= hi && p.y <= hi;
    let from = out.len() - 1;
    for &(t, on_line, curve) in &m.samples {
        let p = on_line + limits.blend * (curve - on_line);
        if p.distance(on_line) <= limits.max_displacement_m && inside(p) {
            out.push(ControlPoint {
                pos: p,
                t,
                kind: PointKind::Sample,
            });
        } else {
            dropped += 1;
        }
    }
    out.push(m.last);
    // A character passes the period where the walk between the points kept either side passes
    // then: a mark, not a corner, so that a player's loop seam, where a character goes from one
    // node to the next, has the same velocity on both sides. (Sampled on the curve it was a
    // corner; put back on the polyline where the curve point was dropped, a jump of up to
    // alpha in a few hundredths of a second.)
    for &s in &m.splits {
        let k = from + out[from..].partition_point(|c| c.t < s);
        if out[k].t == s {
            out[k].kind = PointKind::Split;
            continue;
        }
        let (a, b) = (out[k - 1], out[k]);
        let pos = if a.pos == b.pos {
            a.pos
        } else {
            a.pos.lerp(b.pos, (s - a.t) / (b.t - a.t))
        };
        let split = ControlPoint {
            pos,
            t: s,
            kind: PointKind::Split,
        };
        // A sample a moment from the split goes: no piece of a few microseconds, whose
        // velocity glTF's f32 times or the library's ticks would make anything.
        if a.kind == PointKind::Sample && s - a.t < MIN_GAP_S {
            out[k - 1] = split;
        } else if b.kind == PointKind::Sample && b.t - s < MIN_GAP_S {
            out[k] = split;
        } else {
            out.insert(k, split);
        }
    }
    dropped
}

/// The shortest piece next to a split point, s.
const MIN_GAP_S: f64 = 2e-3;

/// A time on the curve with its position and velocity there.
#[derive(Clone, Copy)]
struct Knot {
    t: f64,
    p: DVec2,
    v: DVec2,
}

impl Knot {
    fn on(s: &Spline, t: f64) -> Knot {
        Knot {
            t,
            p: s.at(t),
            v: s.velocity(t),
        }
    }
}

/// Adds the points strictly between `a` and `b` where the curve needs more points than its
/// chord, in increasing order.
fn refine(s: &Spline, a: Knot, b: Knot, tolerance: f64, depth: u32, out: &mut Vec<Knot>) {
    if depth == 0 || b.t - a.t < 2.0 * MIN_STEP_S {
        return;
    }
    let m = Knot::on(s, 0.5 * (a.t + b.t));
    // The chord plays at its own velocity: it must be near the curve's all along it.
    let along = (b.p - a.p) / (b.t - a.t);
    let close = |k: &Knot| k.v.distance(along) <= 0.5 * MAX_CHORD_DV;
    if m.p.distance(0.5 * (a.p + b.p)) <= tolerance && close(&a) && close(&m) && close(&b) {
        return;
    }
    refine(s, a, m, tolerance, depth - 1, out);
    out.push(m);
    refine(s, m, b, tolerance, depth - 1, out);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::cp;

    /// A walk across the patch with one bend in the middle, between its border bands.
    fn bend() -> Trajectory {
        Trajectory {
            entry: 0,
            exit: 1,
            points: vec![
                cp(0.0, 2.0, 1.0, PointKind::Entry),
                cp(0.3, 2.0, 1.0 + 0.3 / 1.3, PointKind::Band),
                cp(4.0, 3.0, 4.0, PointKind::Bend),
                cp(7.7, 2.0, 7.0 - 0.3 / 1.3, PointKind::Band),
                cp(8.0, 2.0, 7.0, PointKind::Exit),
            ],
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
        let tr = bend();
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

    /// Largest change of velocity from one chord of `tr` to the next, over the time between
    /// their middles (m/s2), and the largest change itself (m/s).
    fn chord_changes(tr: &Trajectory) -> (f64, f64) {
        let chords: Vec<(DVec2, f64)> = tr
            .points
            .windows(2)
            .map(|w| {
                (
                    (w[1].pos - w[0].pos) / (w[1].t - w[0].t),
                    0.5 * (w[0].t + w[1].t),
                )
            })
            .collect();
        chords.windows(2).fold((0.0, 0.0), |(a, d), w| {
            let dv = (w[1].0 - w[0].0).length();
            (f64::max(a, dv / (w[1].1 - w[0].1)), f64::max(d, dv))
        })
    }

    #[test]
    fn a_pause_stays_where_it_was_and_is_reached_at_rest_without_braking_hard() {
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
        // Tacks 3 s apart, as pipelines have them by default.
        let limits = Limits {
            tack_spacing_s: 3.0,
            ..limits()
        };
        let (s, _) = smooth(&tr, DVec2::new(1.3, 0.0), DVec2::new(0.0, 1.3), &limits);
        let pauses: Vec<_> = s
            .points
            .iter()
            .filter(|p| p.kind == PointKind::Pause)
            .collect();
        assert_eq!(pauses.len(), 2);
        assert!(pauses.iter().all(|p| p.pos == DVec2::new(4.0, 4.0)));
        // Reached a little later and left a little earlier: it still stands most of the time.
        let (start, end) = (pauses[0].t, pauses[1].t);
        assert!(
            (3.0..=4.5).contains(&start) && (7.5..=9.0).contains(&end),
            "{start} {end}"
        );
        let k = s.points.iter().position(|p| p.t == start).unwrap();
        let before = s.points[k - 1];
        assert!(before.pos.distance(pauses[0].pos) / (start - before.t) < 0.3);
        // Braking into the pause over the whole interval: 4 u / 3 h = 0.59 m/s2, not 4 u / h.
        let (accel, _) = chord_changes(&s);
        assert!(accel < 0.8, "{accel}");
    }

    #[test]
    fn a_turn_back_is_taken_at_rest() {
        let tr = Trajectory {
            entry: 0,
            exit: 1,
            points: vec![
                cp(2.0, 8.0, 0.0, PointKind::Entry),
                cp(2.0, 7.7, 0.25, PointKind::Band),
                cp(3.0, 4.0, 3.25, PointKind::Turn),
                cp(4.0, 7.7, 6.25, PointKind::Band),
                cp(4.0, 8.0, 6.5, PointKind::Exit),
            ],
        };
        let (s, _) = smooth(&tr, DVec2::new(0.0, -1.2), DVec2::new(0.0, 1.2), &limits());
        let k = s.points.iter().position(|p| p.t == 3.25).unwrap();
        assert_eq!(s.points[k].pos, DVec2::new(3.0, 4.0));
        let speed = |a: &ControlPoint, b: &ControlPoint| a.pos.distance(b.pos) / (b.t - a.t);
        assert!(speed(&s.points[k - 1], &s.points[k]) < 0.2);
        assert!(speed(&s.points[k], &s.points[k + 1]) < 0.2);
    }

    #[test]
    fn the_curve_changes_velocity_little_from_one_chord_to_the_next() {
        let tr = bend();
        let v = DVec2::new(1.3, 0.0);
        let (s, _) = smooth(&tr, v, v, &limits());
        // The polyline changes velocity at once at its bend; the curve in steps that a player
        // shows as a smooth turn.
        // (Chords shorter than a frame, where the curve turns fast, may change by more than
        // MAX_CHORD_DV; a fifth of the polyline's corner is still far from a corner.)
        let (_, corner) = chord_changes(&tr);
        let (_, step) = chord_changes(&s);
        assert!(corner > 0.5 && step < corner / 5.0, "{corner} {step}");
    }

    #[test]
    fn a_split_point_lies_on_the_walk_kept_around_it_so_the_loop_seam_is_no_corner() {
        // The period passes at a bend stage 5 made there, between two tacks; with a small
        // alpha the curve points around it are dropped, with the default they are kept.
        let tr = Trajectory {
            entry: 0,
            exit: 1,
            points: vec![
                cp(0.0, 2.0, 16.0, PointKind::Entry),
                cp(0.3, 2.0, 16.0 + 0.3 / 1.3, PointKind::Band),
                cp(4.0, 3.0, 20.0, PointKind::Split),
                cp(7.7, 2.0, 23.0 - 0.3 / 1.3, PointKind::Band),
                cp(8.0, 2.0, 23.0, PointKind::Exit),
            ],
        };
        for alpha in [0.05, 0.6] {
            let limits = Limits {
                max_displacement_m: alpha,
                tack_spacing_s: 3.0,
                ..limits()
            };
            let v = DVec2::new(1.3, 0.0);
            let (s, dropped) = smooth(&tr, v, v, &limits);
            assert_eq!(dropped > 0, alpha < 0.1);
            let k = s.points.iter().position(|p| p.t == 20.0).unwrap();
            assert_eq!(s.points[k].kind, PointKind::Split);
            let (a, b, c) = (s.points[k - 1], s.points[k], s.points[k + 1]);
            let chord = a.pos.lerp(c.pos, (b.t - a.t) / (c.t - a.t));
            assert!(
                chord.distance(b.pos) < 1e-9,
                "{alpha}: {:?} off {chord:?}",
                b.pos
            );
            // The same velocity either side, at walking speed: no corner, no jump.
            let v0 = (b.pos - a.pos) / (b.t - a.t);
            let v1 = (c.pos - b.pos) / (c.t - b.t);
            assert!(
                v0.distance(v1) < 1e-6 && v0.length() < 1.5,
                "{alpha}: {v0} {v1}"
            );
        }
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
