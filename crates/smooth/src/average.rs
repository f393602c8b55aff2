//! Corners taken over time: a moving average of a walk in time, so that its velocity changes
//! over a short window instead of at once.
//!
//! Stage 5's polylines turn at their corners in no time: a push that steps a walker aside at
//! 1.8 m/s and back again is a velocity jump of up to 3.7 m/s, which every player shows in one
//! frame (and, at a loop seam, as the jump from one node to the next). Averaging the walk over
//! a window of half-width `h` leaves it exactly as it was wherever it is straight for `h` either
//! side, makes the velocity continuous (the window's mean: never faster than the walk was),
//! spreads a corner's change over `2 h`, and moves the walk by at most a quarter of the change
//! times `h` (a corner of 3.7 m/s at `h` = 0.1 s: 9 cm). The window shrinks to nothing at the
//! band ends, which therefore stay exactly where and when they were, with the band pieces
//! beyond them; the ends of the walk are left as they are.

use crowd_core::trajectories::{ControlPoint, PointKind, Trajectory, band_ends, position_on};
use glam::DVec2;

/// The largest change of velocity from one chord of the averaged walk to the next, m/s, where
/// the window allows chords as short as [`MIN_STEP_S`].
const MAX_CHORD_DV: f64 = 0.1;
/// The smallest change of velocity averaged, m/s: a player shows smaller ones as a faint
/// change of pace in one frame. (At 0.25, painting's library held 5 % fewer points, and twice
/// as many velocity jumps over 1 m/s: trajectories with only small corners go down the
/// ladder to their polylines more often.)
const SHARP_DV: f64 = 0.1;
/// How many half-windows the walk takes to ease into a band piece's velocity.
const EASE_WINDOWS: f64 = 3.0;
/// How long before and after a held time corners stay as they were, s.
pub const HOLD_S: f64 = 0.5;
/// The shares of the change of velocity into a band piece tried, largest first.
const EASE_SHARES: [f64; 4] = [1.0, 0.5, 0.25, 0.0];
/// The shortest gap between the times the walk is sampled at, s.
const MIN_GAP_S: f64 = 2e-3;
/// The shortest chord refining makes: a frame at 120 fps.
const MIN_STEP_S: f64 = 1.0 / 120.0;

/// `tr` averaged over windows of half-width up to `half_window_s` between its band ends (or its
/// ends, where it has no bands), and eased into its band pieces' velocities as far as it can
/// without walking faster than `ease_below` m/s there (not at all if `None`); split points at
/// every multiple of `period_s`. Corners and band ends within [`HOLD_S`] of a `held` time keep
/// the polyline's corners (a close encounter the averaged walk would not clear).
pub fn average(
    tr: &Trajectory,
    half_window_s: f64,
    ease_below: Option<f64>,
    period_s: f64,
    held: &[f64],
) -> Trajectory {
    let pts = &tr.points;
    let (entry_band, exit_band) = band_ends(pts);
    let first = entry_band.unwrap_or(0);
    let last = exit_band.unwrap_or(pts.len() - 1);
    if half_window_s <= 0.0 || last < first + 2 {
        return tr.clone();
    }
    let ends = (
        entry_band
            .filter(|_| ease_below.is_some())
            .map(|b| velocity(&pts[b - 1], &pts[b])),
        exit_band
            .filter(|_| ease_below.is_some())
            .map(|b| velocity(&pts[b], &pts[b + 1])),
    );
    let mut walk = Walk::new(&pts[first..=last], half_window_s, ends, held);
    if walk.is_smooth() {
        // Nothing sharper than a chord may turn: already smooth enough to play.
        return tr.clone();
    }
    if let Some(fastest) = ease_below {
        walk.fit_ease(fastest);
    }
    let times = walk.sample_times(period_s);
    let mut out = Vec::with_capacity(pts.len() + 4 * times.len());
    out.extend_from_slice(&pts[..=first]);
    let mut prev = walk.knot(walk.t0);
    let mut next_original = 1;
    for &t in &times[1..] {
        // Where nothing is averaged or eased, the walk's own points, as they were.
        let original = walk.pts[next_original..].iter().position(|p| p.t >= t);
        let original = original.map(|k| next_original + k);
        if let Some(k) = original.filter(|&k| walk.pts[k].t == t && !walk.active(prev.t, t)) {
            next_original = k + 1;
            if t < walk.t1 {
                out.push(walk.pts[k]);
            }
            prev = walk.knot(t);
            continue;
        }
        let k = walk.knot(t);
        refine(&walk, prev, k, 8, &mut out);
        if t < walk.t1 {
            out.push(walk.point(t, period_s));
        }
        prev = k;
    }
    out.extend_from_slice(&pts[last..]);
    Trajectory {
        entry: tr.entry,
        exit: tr.exit,
        points: drop_straight(out),
    }
}

/// The interior of a walk (band end to band end) and what averaging does to it.
///
/// The walk is a straight line plus a ramp `dv (t - t_k)+` at each corner, and the average of a
/// straight line is the line: averaging the walk adds, at each corner, `dv K(t - t_k)` with
/// `K(s) = (h - |s|)^2 / 4h` inside the window (a bump with no corner at its edges, whose slope
/// jumps by `-1` at its middle, taking the corner away). Only corners sharper than
/// [`SHARP_DV`] are averaged, each over the widest window up to the half-width that stays
/// between the ends: the rest of the walk is left exactly as it was.
struct Walk<'a> {
    pts: &'a [ControlPoint],
    corners: Vec<Corner>,
    half: f64,
    /// How the walk is eased into its band pieces: the change of velocity to make at each end
    /// (from the walk's first and last pieces to the bands'), over `ease` seconds.
    ease: f64,
    ease_dv: (DVec2, DVec2),
    t0: f64,
    t1: f64,
    /// The piece [`Walk::piece_at`] found last: the walk is read at times close together
    /// (refining a stretch, easing an end), and a binary search of its points each time was
    /// a tenth of stage 6.
    last_piece: std::cell::Cell<usize>,
}

/// A corner of the walk, averaged over `t +- h`.
struct Corner {
    t: f64,
    dv: DVec2,
    h: f64,
}

#[derive(Clone, Copy)]
struct Knot {
    t: f64,
    p: DVec2,
    /// The walk's velocity there.
    v: DVec2,
}

impl<'a> Walk<'a> {
    fn new(
        pts: &'a [ControlPoint],
        half: f64,
        bands: (Option<DVec2>, Option<DVec2>),
        held: &[f64],
    ) -> Walk<'a> {
        let (t0, t1) = (pts[0].t, pts[pts.len() - 1].t);
        let free = |from: f64, to: f64| held.iter().all(|&t| t < from - HOLD_S || t > to + HOLD_S);
        let n = pts.len();
        let corners = (1..n - 1)
            .filter_map(|k| {
                let dv = velocity(&pts[k], &pts[k + 1]) - velocity(&pts[k - 1], &pts[k]);
                let t = pts[k].t;
                let h = half.min(t - t0).min(t1 - t);
                (dv.length() > SHARP_DV && h > 0.0 && free(t - h, t + h)).then_some(Corner {
                    t,
                    dv,
                    h,
                })
            })
            .collect();
        let ease = (EASE_WINDOWS * half).min(0.5 * (t1 - t0));
        let ease_dv = (
            bands
                .0
                .filter(|_| free(t0, t0 + ease))
                .map_or(DVec2::ZERO, |v| v - velocity(&pts[0], &pts[1])),
            bands
                .1
                .filter(|_| free(t1 - ease, t1))
                .map_or(DVec2::ZERO, |v| v - velocity(&pts[n - 2], &pts[n - 1])),
        );
        Walk {
            pts,
            corners,
            half,
            ease,
            ease_dv,
            t0,
            t1,
            last_piece: std::cell::Cell::new(1),
        }
    }

    /// The index `k` of the point that ends the piece holding `t`: the first point after `t`,
    /// kept within `1..len` (exactly `position_at`'s). The last piece found, or the one after
    /// it, when either holds `t`; a binary search otherwise.
    fn piece_at(&self, t: f64) -> usize {
        let n = self.pts.len();
        // `k` is the first point after `t` when the one before it is not.
        let first_after =
            |k: usize| (k == 0 || self.pts[k - 1].t <= t) && (k == n || self.pts[k].t > t);
        let hint = self.last_piece.get();
        let k = if first_after(hint) {
            hint
        } else if hint < n && first_after(hint + 1) {
            hint + 1
        } else {
            self.pts.partition_point(|p| p.t <= t)
        };
        self.last_piece.set(k);
        k.clamp(1, n - 1)
    }

    /// Whether averaging or easing moves the walk anywhere in `[a, b]`.
    fn active(&self, a: f64, b: f64) -> bool {
        let from = self.corners.partition_point(|c| c.t <= a - self.half);
        let corner = self.corners[from..]
            .iter()
            .take_while(|c| c.t < b + self.half)
            .any(|c| c.t - c.h < b && c.t + c.h > a);
        let eases = (self.ease_dv.0 != DVec2::ZERO && a < self.t0 + self.ease)
            || (self.ease_dv.1 != DVec2::ZERO && b > self.t1 - self.ease);
        corner || eases
    }

    /// Whether there is nothing to do: no corner to average, no band to ease into.
    fn is_smooth(&self) -> bool {
        self.corners.is_empty()
            && self.ease_dv.0.length() <= SHARP_DV
            && self.ease_dv.1.length() <= SHARP_DV
    }

    /// Eases each end only as far as keeps it no faster than `fastest` (m/s): easing from a
    /// band slower than the walk, the walker is behind and must catch up.
    fn fit_ease(&mut self, fastest: f64) {
        let full = self.ease_dv;
        let steps = (self.ease / MIN_STEP_S).ceil().max(1.0) as usize;
        let dt = self.ease / steps as f64;
        for end in 0..2 {
            let from = if end == 0 {
                self.t0
            } else {
                self.t1 - self.ease
            };
            for share in EASE_SHARES {
                let dv = if end == 0 {
                    &mut self.ease_dv.0
                } else {
                    &mut self.ease_dv.1
                };
                *dv = if end == 0 { full.0 } else { full.1 } * share;
                if dv.length() <= SHARP_DV {
                    break;
                }
                let mut prev = self.at(from);
                let fits = (1..=steps).all(|i| {
                    let p = self.at(from + i as f64 * dt);
                    let fits = p.distance(prev) <= fastest * dt;
                    prev = p;
                    fits
                });
                if fits {
                    break;
                }
            }
        }
    }

    /// The averaged walk at `t`, eased into the bands.
    fn at(&self, t: f64) -> DVec2 {
        // Cubic Hermite's h10: 0 at both ends, slope 1 at 0 and 0 at 1.
        let h10 = |s: f64| s * (1.0 - s) * (1.0 - s);
        let mut p = position_on(self.pts, self.piece_at(t), t);
        let from = self.corners.partition_point(|c| c.t <= t - self.half);
        for c in self.corners[from..]
            .iter()
            .take_while(|c| c.t < t + self.half)
        {
            let s = (t - c.t).abs();
            if s < c.h {
                p += c.dv * ((c.h - s) * (c.h - s) / (4.0 * c.h));
            }
        }
        let (from_start, to_end) = ((t - self.t0) / self.ease, (self.t1 - t) / self.ease);
        if from_start < 1.0 {
            p += self.ease_dv.0 * (self.ease * h10(from_start));
        }
        if to_end < 1.0 {
            p -= self.ease_dv.1 * (self.ease * h10(to_end));
        }
        p
    }

    fn knot(&self, t: f64) -> Knot {
        Knot {
            t,
            p: self.at(t),
            v: self.velocity_at(t),
        }
    }

    /// The averaged walk's velocity at `t` (continuous, so either side of a point will do: the
    /// piece after it).
    fn velocity_at(&self, t: f64) -> DVec2 {
        // The slope of h10.
        let dh10 = |s: f64| (1.0 - s) * (1.0 - 3.0 * s);
        let k = self.piece_at(t);
        let mut v = velocity(&self.pts[k - 1], &self.pts[k]);
        let from = self.corners.partition_point(|c| c.t <= t - self.half);
        for c in self.corners[from..]
            .iter()
            .take_while(|c| c.t < t + self.half)
        {
            let s = t - c.t;
            if s.abs() < c.h {
                v -= c.dv * (s.signum() * (c.h - s.abs()) / (2.0 * c.h));
            }
        }
        let (from_start, to_end) = ((t - self.t0) / self.ease, (self.t1 - t) / self.ease);
        if from_start < 1.0 {
            v += self.ease_dv.0 * dh10(from_start);
        }
        if to_end < 1.0 {
            v += self.ease_dv.1 * dh10(to_end);
        }
        v
    }

    /// A point of the averaged walk: a split point on a multiple of the period, otherwise a
    /// sample (or the original point, where the walk there is unchanged).
    fn point(&self, t: f64, period: f64) -> ControlPoint {
        let pos = self.at(t);
        let on_period = (t / period).round() * period == t;
        let original = self
            .pts
            .binary_search_by(|p| p.t.total_cmp(&t))
            .ok()
            .map(|k| self.pts[k])
            .filter(|p| p.pos == pos);
        let kind = match original {
            _ if on_period => PointKind::Split,
            Some(p) => p.kind,
            None => PointKind::Sample,
        };
        ControlPoint { pos, t, kind }
    }

    /// Where the averaged walk needs a point: the ends, every point of the walk, where a
    /// corner's window opens and closes, where the easing ends, and every multiple of the period.
    fn sample_times(&self, period: f64) -> Vec<f64> {
        let mut times: Vec<f64> = self.pts.iter().map(|p| p.t).collect();
        for c in &self.corners {
            times.push(c.t - c.h);
            times.push(c.t + c.h);
        }
        times.push(self.t0 + self.ease);
        times.push(self.t1 - self.ease);
        let mut k = (self.t0 / period).floor() + 1.0;
        while k * period < self.t1 {
            times.push(k * period);
            k += 1.0;
        }
        times.retain(|&t| t >= self.t0 && t <= self.t1);
        times.sort_by(f64::total_cmp);
        times.dedup();
        // No new chord shorter than a few milliseconds: glTF's f32 times near 20 s are 2 us
        // apart, and the library's ticks 0.1 ms. The ends, the multiples of the period and the
        // walk's own points where it is left as it was stay (dropping one of those would move
        // the walk there: a corner 1 ms after a split point, held for an encounter).
        let point_times: Vec<f64> = self.pts.iter().map(|p| p.t).collect();
        let fixed = |t: f64| {
            t == self.t0
                || t == self.t1
                || (t / period).round() * period == t
                || (point_times.binary_search_by(|p| p.total_cmp(&t)).is_ok() && !self.active(t, t))
        };
        let mut kept: Vec<f64> = Vec::with_capacity(times.len());
        for t in times {
            match kept.last_mut() {
                Some(last) if t - *last < MIN_GAP_S && !(fixed(t) && fixed(*last)) => {
                    if fixed(t) {
                        *last = t;
                    }
                }
                _ => kept.push(t),
            }
        }
        kept
    }
}

/// The velocity of the piece from `a` to `b` (none if it takes no time).
fn velocity(a: &ControlPoint, b: &ControlPoint) -> DVec2 {
    if b.t > a.t {
        (b.pos - a.pos) / (b.t - a.t)
    } else {
        DVec2::ZERO
    }
}

/// Adds the points strictly between `a` and `b` that keep the chords' velocities within
/// [`MAX_CHORD_DV`] of each other (down to chords of [`MIN_STEP_S`]), in increasing order.
fn refine(walk: &Walk, a: Knot, b: Knot, depth: u32, out: &mut Vec<ControlPoint>) {
    if depth == 0 || b.t - a.t < 2.0 * MIN_STEP_S {
        return;
    }
    let m = walk.knot(0.5 * (a.t + b.t));
    // A chord plays at its own velocity: within half the allowed change of the walk's all
    // along it, so that neighbouring chords differ by no more than the change.
    let chord = (b.p - a.p) / (b.t - a.t);
    if [a, m, b]
        .iter()
        .all(|k| k.v.distance(chord) <= 0.5 * MAX_CHORD_DV)
    {
        return;
    }
    refine(walk, a, m, depth - 1, out);
    out.push(ControlPoint {
        pos: m.p,
        t: m.t,
        kind: PointKind::Sample,
    });
    refine(walk, m, b, depth - 1, out);
}

/// Drops sample points that lie on the chord of their neighbours, at their time (the averaged
/// walk is straight wherever the original was, for a window either side).
fn drop_straight(points: Vec<ControlPoint>) -> Vec<ControlPoint> {
    let mut out: Vec<ControlPoint> = Vec::with_capacity(points.len());
    for (i, p) in points.iter().enumerate() {
        if let (Some(&a), Some(&b)) = (out.last(), points.get(i + 1))
            && p.kind == PointKind::Sample
            && b.t > a.t
            && a.pos.lerp(b.pos, (p.t - a.t) / (b.t - a.t)).distance(p.pos) < 1e-9
        {
            continue;
        }
        out.push(*p);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::cp;
    use crowd_core::trajectories::position_at;
    use proptest::prelude::*;

    /// A walk as stage 5 leaves one: an entry band eastwards at 1.3 m/s, then random pieces of
    /// 0.1-1.5 s at up to 1.8 m/s (pushes, pauses, turns back), then an exit band.
    fn polyline() -> impl Strategy<Value = Trajectory> {
        prop::collection::vec((-1.8f64..1.8, -1.8f64..1.8, 0.1f64..1.5, 0u8..6), 2..14).prop_map(
            |pieces| {
                let mut points = vec![
                    cp(0.0, 4.0, 13.0, PointKind::Entry),
                    cp(0.3, 4.0, 13.0 + 0.3 / 1.3, PointKind::Band),
                ];
                for (vx, vy, dt, kind) in pieces {
                    let last = points[points.len() - 1];
                    let v = if kind == 0 {
                        DVec2::ZERO
                    } else {
                        DVec2::new(vx, vy).clamp_length_max(1.8)
                    };
                    let pos = last.pos + v * dt;
                    points.push(cp(pos.x, pos.y, last.t + dt, PointKind::Bend));
                }
                let last = points[points.len() - 1];
                points.push(cp(
                    last.pos.x,
                    last.pos.y + 0.3,
                    last.t + 0.25,
                    PointKind::Band,
                ));
                points.push(cp(
                    last.pos.x,
                    last.pos.y + 0.6,
                    last.t + 0.5,
                    PointKind::Exit,
                ));
                Trajectory {
                    entry: 0,
                    exit: 1,
                    points: crowd_core::trajectories::split_at_periods(points, 20.0),
                }
            },
        )
    }

    fn chord(a: &ControlPoint, b: &ControlPoint) -> DVec2 {
        (b.pos - a.pos) / (b.t - a.t)
    }

    /// The largest change of velocity from one chord to the next, leaving out the band ends.
    fn largest_change(tr: &Trajectory) -> f64 {
        let p = &tr.points;
        (1..p.len() - 1)
            .filter(|&k| p[k].kind != PointKind::Band && p[k].kind != PointKind::Split)
            .map(|k| chord(&p[k - 1], &p[k]).distance(chord(&p[k], &p[k + 1])))
            .fold(0.0, f64::max)
    }

    fn fastest(tr: &Trajectory) -> f64 {
        tr.points
            .windows(2)
            .map(|w| chord(&w[0], &w[1]).length())
            .fold(0.0, f64::max)
    }

    proptest! {
        #[test]
        fn the_ends_and_bands_stay_and_the_corners_go(tr in polyline()) {
            let out = average(&tr, 0.1, None, 20.0, &[]);
            let (p, q) = (&tr.points, &out.points);
            let bands = |pts: &[ControlPoint]| band_ends(pts);
            let ((a, b), (c, d)) = (bands(p), bands(q));
            let (a, b, c, d) = (a.unwrap(), b.unwrap(), c.unwrap(), d.unwrap());
            // Entry, exit and the band pieces exactly as they were.
            prop_assert_eq!(&p[..=a], &q[..=c]);
            prop_assert_eq!(&p[b..], &q[d..]);
            prop_assert!(q.windows(2).all(|w| w[1].t > w[0].t));
            // A corner of up to 3.6 m/s, spread over 0.2 s: chords a sixtieth of a second
            // apart change by a fraction of it.
            let change = largest_change(&out);
            prop_assert!(change <= 0.75, "{} (polyline {})", change, largest_change(&tr));
            // Never faster than the walk was (the window's mean velocity).
            prop_assert!(fastest(&out) <= fastest(&tr) + 1e-9);
        }

        #[test]
        fn the_walk_moves_at_most_a_quarter_of_each_corner_times_the_window(tr in polyline()) {
            let h = 0.1;
            let out = average(&tr, h, None, 20.0, &[]);
            let corners: f64 = tr
                .points
                .windows(3)
                .map(|w| chord(&w[0], &w[1]).distance(chord(&w[1], &w[2])))
                .fold(0.0, f64::max);
            for q in &out.points {
                let d = q.pos.distance(position_at(&tr.points, q.t));
                // Two windows overlap at most (pieces last at least 0.1 s = h).
                prop_assert!(d <= 2.0 * corners * h / 4.0 + 1e-9, "{} at {}", d, q.t);
            }
        }

        #[test]
        fn the_velocity_is_the_slope_of_the_walk(tr in polyline(), u in 0.0f64..1.0) {
            let pts = &tr.points;
            let (a, b) = band_ends(pts);
            let (a, b) = (a.unwrap(), b.unwrap());
            let ends = (Some(DVec2::new(1.3, 0.0)), Some(DVec2::new(0.0, 1.2)));
            let walk = Walk::new(&pts[a..=b], 0.1, ends, &[]);
            let t = walk.t0 + 1e-3 + u * (walk.t1 - walk.t0 - 2e-3);
            let d = 1e-6;
            // Away from the walk's own points, where only the pieces either side would do.
            prop_assume!(pts.iter().all(|p| (p.t - t).abs() > 2.0 * d));
            let slope = (walk.at(t + d) - walk.at(t - d)) / (2.0 * d);
            prop_assert!(slope.distance(walk.velocity_at(t)) < 1e-4, "{} {}", slope, walk.velocity_at(t));
        }

        #[test]
        fn every_multiple_of_the_period_stays_a_split_point(tr in polyline()) {
            let out = average(&tr, 0.1, None, 20.0, &[]);
            let (t0, t1) = (tr.points[0].t, tr.points[tr.points.len() - 1].t);
            let splits: Vec<f64> = out
                .points
                .iter()
                .filter(|p| p.kind == PointKind::Split)
                .map(|p| p.t)
                .collect();
            let wanted: Vec<f64> = [20.0, 40.0].into_iter().filter(|&t| t > t0 && t < t1).collect();
            prop_assert_eq!(splits, wanted);
        }

        #[test]
        fn corners_near_a_held_time_stay_as_they_were(tr in polyline(), k in 3usize..10) {
            let k = k.min(tr.points.len() - 4);
            let held = tr.points[k];
            let out = average(&tr, 0.1, Some(1.872), 20.0, &[held.t]);
            // Every point of the walk within the hold, as it was, and the walk through it.
            for p in tr.points.iter().filter(|p| (p.t - held.t).abs() < HOLD_S - 0.1) {
                prop_assert!(out.points.contains(p), "{:?}", p);
            }
        }
    }

    #[test]
    fn a_walk_eases_into_a_band_it_can_reach_and_not_one_it_must_run_for() {
        // Northwards at 1.2 m/s after an eastward band at 1.3: a turn the walk can ease into.
        let turn = |speed: f64| Trajectory {
            entry: 0,
            exit: 1,
            points: vec![
                cp(0.0, 4.0, 1.0, PointKind::Entry),
                cp(0.3, 4.0, 1.0 + 0.3 / 1.3, PointKind::Band),
                cp(0.3, 4.0 + 2.0 * speed, 3.0 + 0.3 / 1.3, PointKind::Bend),
                cp(0.3, 4.3 + 2.0 * speed, 3.25 + 0.3 / 1.3, PointKind::Band),
                cp(0.3, 4.6 + 2.0 * speed, 3.5 + 0.3 / 1.3, PointKind::Exit),
            ],
        };
        let band_corner = |tr: &Trajectory| {
            let p = &tr.points;
            chord(&p[0], &p[1]).distance(chord(&p[1], &p[2]))
        };
        let eased = average(&turn(1.2), 0.1, Some(1.872), 20.0, &[]);
        assert!(band_corner(&turn(1.2)) > 1.7);
        assert!(band_corner(&eased) < 0.2, "{}", band_corner(&eased));
        assert!(fastest(&eased) <= 1.872);
        // At 1.85 m/s the walk is already at the limit: easing would have to run to catch up.
        let hurried = average(&turn(1.85), 0.1, Some(1.872), 20.0, &[]);
        assert!(fastest(&hurried) <= 1.872 + 1e-9);
        assert!(band_corner(&hurried) > 1.0);
    }
}
