//! Straight space-time lines between matched points (Ramirez et al. section 3.3, last step).

use crate::way::{path_length, turn_point, waypoints, wrapped_dt};
use crate::{Endpoint, PatchContext};
use crowd_core::trajectories::{ControlPoint, PointKind, Trajectory};
use glam::DVec2;

/// Whole periods a walker must add so that it never walks faster than `max_speed`: it needs
/// `least` seconds, and the pair gives it `dt`.
fn extra_periods(least: f64, dt: f64, period: f64) -> u32 {
    if least <= dt {
        0
    } else {
        ((least - dt) / period).ceil() as u32
    }
}

/// The least time the walker of this pair needs: its band pieces at their crossings'
/// velocities, and the way between the band ends at `max_speed`. (The whole way at
/// `max_speed` is not enough: a band that walks slowly into the patch, or across the way,
/// leaves the middle less time, and corner-cutting walkers then had to run at 1.9 m/s.)
pub fn least_time(entry: &Endpoint, exit: &Endpoint, ctx: &PatchContext) -> f64 {
    let max = ctx.settings.max_speed;
    let whole = path_length(entry, exit, ctx) / max;
    let depth = ctx.radius_m;
    let (te, tx) = (
        band_time(entry.side, entry.velocity, depth),
        band_time(exit.side, exit.velocity, depth),
    );
    let (start, end) = (
        entry.pos + entry.velocity * te,
        exit.pos - exit.velocity * tx,
    );
    // The way's corners between its ends (the turn, the detours), from band end to band end.
    let way = waypoints(entry, exit, ctx);
    let mut corners: Vec<DVec2> = vec![start];
    corners.extend(way[1..way.len() - 1].iter().map(|w| w.0));
    corners.push(end);
    let middle: f64 = corners.windows(2).map(|w| w[0].distance(w[1])).sum();
    whole.max(te + tx + middle / max)
}

/// Time the walker of this pair spends inside the patch.
pub fn duration(entry: &Endpoint, exit: &Endpoint, ctx: &PatchContext) -> f64 {
    let dt = wrapped_dt(entry.t, exit.t, ctx.period_s);
    dt + extra_periods(least_time(entry, exit, ctx), dt, ctx.period_s) as f64 * ctx.period_s
}

/// The straight-line trajectory of a matched pair: constant speed along the path; a pause in
/// the middle (at the turn point, if any) when that speed would be below `min_speed`, walking
/// at the comfort speed otherwise; split points where it passes a multiple of the period.
pub fn plan(entry: &Endpoint, exit: &Endpoint, ctx: &PatchContext) -> Trajectory {
    let turn = turn_point(entry, exit, ctx);
    let mut length = path_length(entry, exit, ctx);
    let total = duration(entry, exit, ctx);
    let mut path = waypoints(entry, exit, ctx);
    let detour = path.len() > 2 + turn.is_some() as usize;

    let pausing = length / total < ctx.settings.min_speed;
    let speed = if pausing {
        ctx.comfort_speed.max(ctx.settings.min_speed)
    } else {
        length / total
    };
    if pausing && turn.is_none() && !detour {
        // Pause off the border, a third of the way from the middle of the line to the centre
        // of the patch, where it is less in the way of walkers crossing; on the line itself if
        // that detour would not leave time to pause.
        let mid = (entry.pos + exit.pos) / 2.0;
        let spot = mid.lerp(DVec2::splat(ctx.side_m / 2.0), 1.0 / 3.0);
        let detour = entry.pos.distance(spot) + spot.distance(exit.pos);
        let spot = if detour / speed < total { spot } else { mid };
        length = entry.pos.distance(spot) + spot.distance(exit.pos);
        path.insert(1, (spot, PointKind::Pause));
    }
    // Pause at the turn, else at the first corner of a detour, else at the added spot.
    let pause_at = if pausing { Some(1) } else { None };

    let mut points = Vec::with_capacity(path.len() + 3);
    let mut t = entry.t;
    let mut previous = entry.pos;
    for (i, &(pos, kind)) in path.iter().enumerate() {
        t += previous.distance(pos) / speed;
        previous = pos;
        if Some(i) == pause_at {
            let pause = total - length / speed;
            points.push(ControlPoint {
                pos,
                t,
                kind: PointKind::Pause,
            });
            t += pause;
            points.push(ControlPoint {
                pos,
                t,
                kind: PointKind::Pause,
            });
        } else {
            points.push(ControlPoint { pos, t, kind });
        }
    }
    // The exit is reached exactly `total` after the entry, whatever the rounding on the way.
    let last = points.len() - 1;
    points[last].t = entry.t + total;
    let mut points = with_bands(points, entry, exit, ctx.radius_m);
    fit_pause(&mut points, speed, ctx.settings.max_speed);
    Trajectory {
        entry: entry.crossing,
        exit: exit.crossing,
        points: crowd_core::trajectories::split_at_periods(points, ctx.period_s),
    }
}

/// Moves a pause's ends so that the walks to and from it, between the band ends put in after
/// the line was timed, go at `speed` (at `max_speed` where `speed` leaves the pause no time):
/// the pause's times came from the plain line, and a band that leans away from the pause left
/// the piece after it 0.24 s for 0.53 m (2.2 m/s; random painting 76).
fn fit_pause(points: &mut [ControlPoint], speed: f64, max_speed: f64) {
    let Some(i) = points.iter().position(|p| p.kind == PointKind::Pause) else {
        return;
    };
    let j = i + 1;
    if j + 1 >= points.len() || i == 0 || points[j].kind != PointKind::Pause {
        return;
    }
    let (prev, next, at) = (points[i - 1], points[j + 1], points[i].pos);
    for v in [speed, max_speed] {
        let start = points[i].t.max(prev.t + prev.pos.distance(at) / v);
        let end = points[j].t.min(next.t - next.pos.distance(at) / v);
        if start < end {
            points[i].t = start;
            points[j].t = end;
            return;
        }
    }
}

/// How long a walker crossing at `velocity` takes to get `depth` away from the border of
/// `side`.
pub fn band_time(side: crowd_core::patterns::Side, velocity: DVec2, depth: f64) -> f64 {
    depth / velocity.dot(side.inward()).abs().max(1e-6)
}

/// The walker's first and last `depth` metres from the border, walked straight at the crossing
/// velocity (the band pieces, fixed by the patterns; see [`PointKind::Band`]): a [`PointKind::Band`]
/// point where each ends, and the points of the line in between kept. A line too short to
/// hold both bands keeps none (stage 3's spacing never makes one).
pub fn with_bands(
    points: Vec<ControlPoint>,
    entry: &Endpoint,
    exit: &Endpoint,
    depth: f64,
) -> Vec<ControlPoint> {
    let (first, last) = (points[0], points[points.len() - 1]);
    let (te, tx) = (
        band_time(entry.side, entry.velocity, depth),
        band_time(exit.side, exit.velocity, depth),
    );
    if last.t - first.t <= te + tx + 1e-6 {
        return points;
    }
    let start = ControlPoint {
        pos: first.pos + entry.velocity * te,
        t: first.t + te,
        kind: PointKind::Band,
    };
    let end = ControlPoint {
        pos: last.pos - exit.velocity * tx,
        t: last.t - tx,
        kind: PointKind::Band,
    };
    let mut out = Vec::with_capacity(points.len() + 2);
    out.extend([first, start]);
    out.extend(
        points[1..points.len() - 1]
            .iter()
            .filter(|p| p.t > start.t + 1e-9 && p.t < end.t - 1e-9),
    );
    out.extend([end, last]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crowd_core::config::MatchSettings;
    use crowd_core::patterns::Side;

    fn ctx(settings: &MatchSettings) -> PatchContext<'_> {
        PatchContext {
            side_m: 8.0,
            period_s: 20.0,
            comfort_speed: 1.33,
            direction: None,
            obstacles: &[],
            radius_m: 0.3,
            settings,
        }
    }

    fn point(x: f64, y: f64, t: f64, side: Side) -> Endpoint {
        Endpoint {
            crossing: 0,
            pos: DVec2::new(x, y),
            t,
            side,
            velocity: side.inward() * 1.33,
        }
    }

    /// An exit: its crossing velocity leaves the patch.
    fn exit_point(x: f64, y: f64, t: f64, side: Side) -> Endpoint {
        Endpoint {
            velocity: -side.inward() * 1.33,
            ..point(x, y, t, side)
        }
    }

    #[test]
    fn a_line_that_wraps_the_period_is_split_at_it() {
        let s = MatchSettings::default();
        let tr = plan(
            &point(0.0, 4.0, 17.0, Side::West),
            &exit_point(8.0, 4.0, 3.0, Side::East),
            &ctx(&s),
        );
        let kinds: Vec<_> = tr.points.iter().map(|p| p.kind).collect();
        use PointKind::*;
        assert_eq!(kinds, [Entry, Band, Split, Band, Exit]);
        assert_eq!(tr.points[2].t, 20.0);
        assert!((tr.points[2].pos.x - 8.0 * 3.0 / 6.0).abs() < 1e-9);
        assert_eq!(tr.points[4].t, 23.0);
    }

    #[test]
    fn the_first_and_last_radius_are_walked_at_the_crossing_velocity() {
        let s = MatchSettings::default();
        let (entry, exit) = (
            point(0.0, 2.0, 1.0, Side::West),
            exit_point(5.0, 8.0, 9.0, Side::North),
        );
        let tr = plan(&entry, &exit, &ctx(&s));
        let p = &tr.points;
        let n = p.len();
        assert_eq!(
            (p[1].kind, p[n - 2].kind),
            (PointKind::Band, PointKind::Band)
        );
        let v = |a: &ControlPoint, b: &ControlPoint| (b.pos - a.pos) / (b.t - a.t);
        assert!((v(&p[0], &p[1]) - entry.velocity).length() < 1e-9);
        assert!((v(&p[n - 2], &p[n - 1]) - exit.velocity).length() < 1e-9);
        assert!((p[1].pos.x - 0.3).abs() < 1e-9 && (p[n - 2].pos.y - 7.7).abs() < 1e-9);
    }

    #[test]
    fn an_implausibly_fast_pair_stays_an_extra_period() {
        let s = MatchSettings::default();
        // 8 m in 1 s: 8 m/s. With one more period: 8 m in 21 s, too slow, so it pauses.
        let tr = plan(
            &point(0.0, 4.0, 5.0, Side::West),
            &exit_point(8.0, 4.0, 6.0, Side::East),
            &ctx(&s),
        );
        assert!((tr.duration() - 21.0).abs() < 1e-9);
        let pauses: Vec<_> = tr
            .points
            .iter()
            .filter(|p| p.kind == PointKind::Pause)
            .collect();
        assert_eq!(pauses.len(), 2);
        assert_eq!(pauses[0].pos, pauses[1].pos);
        for w in tr.points.windows(2) {
            let v = w[0].pos.distance(w[1].pos) / (w[1].t - w[0].t);
            assert!(
                v <= s.max_speed + 1e-9 && (v == 0.0 || v >= s.min_speed - 1e-9),
                "{v}"
            );
        }
    }

    #[test]
    fn a_corner_cutting_pair_whose_bands_leave_the_middle_too_little_time_stays_a_period() {
        let s = MatchSettings::default();
        // Entry on the south border, exit on the west, 3.2 m apart in 1.87 s (1.7 m/s). The
        // band pieces cross each border slanted at 1.33 m/s and take 0.27 s and 0.23 s of
        // it, leaving the middle more than 1.8 m/s to walk.
        let entry = Endpoint {
            velocity: DVec2::new(-0.6, 1.0).normalize() * 1.33,
            ..point(2.09, 0.0, 6.96, Side::South)
        };
        let exit = Endpoint {
            velocity: DVec2::new(-1.0, 0.2).normalize() * 1.33,
            ..exit_point(0.0, 2.43, 8.83, Side::West)
        };
        let c = ctx(&s);
        let whole = entry.pos.distance(exit.pos) / s.max_speed;
        assert!(whole < 1.87, "the whole way fits: {whole}");
        assert!(least_time(&entry, &exit, &c) > 1.87);
        let tr = plan(&entry, &exit, &c);
        assert!((tr.duration() - 21.87).abs() < 1e-9, "{}", tr.duration());
        for w in tr.points.windows(2) {
            let v = w[0].pos.distance(w[1].pos) / (w[1].t - w[0].t);
            assert!(v <= s.max_speed + 1e-9, "{v}");
        }
    }

    #[test]
    fn a_pause_at_the_turn_leaves_the_walks_to_and_from_it_their_time() {
        // Random painting 76, patch 1: both ends on the west border of a 5 m patch, bands
        // 0.35 m deep leaning away from the turn point, which an obstacle kept 0.53 m from the
        // border.
        let s = MatchSettings {
            turn_depth: 0.105,
            ..MatchSettings::default()
        };
        let c = PatchContext {
            side_m: 5.0,
            period_s: 16.0,
            radius_m: 0.35,
            ..ctx(&s)
        };
        let entry = Endpoint {
            velocity: DVec2::new(1.141, -0.684),
            ..point(0.0, 2.932, 0.4217, Side::West)
        };
        let exit = Endpoint {
            velocity: DVec2::new(-1.306, 0.254),
            ..exit_point(0.0, 2.068, 4.1811, Side::West)
        };
        let tr = plan(&entry, &exit, &c);
        assert!(
            tr.points.iter().any(|p| p.kind == PointKind::Pause),
            "{:?}",
            tr.points
        );
        for w in tr.points.windows(2) {
            let v = w[0].pos.distance(w[1].pos) / (w[1].t - w[0].t);
            assert!(v <= s.max_speed + 1e-9, "{v} m/s in {:?}", tr.points);
        }
    }

    #[test]
    fn a_pair_on_one_border_turns_towards_the_centre() {
        let s = MatchSettings::default();
        let tr = plan(
            &point(0.0, 2.0, 1.0, Side::West),
            &exit_point(0.0, 6.0, 9.0, Side::West),
            &ctx(&s),
        );
        let turn = tr
            .points
            .iter()
            .find(|p| p.kind == PointKind::Turn)
            .expect("a turn");
        assert!(turn.pos.x > 2.0 && (turn.pos.y - 4.0).abs() < 1e-9);
    }
}
