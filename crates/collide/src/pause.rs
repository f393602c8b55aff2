//! A pausing walker caught in an encounter moves its whole pause to the spot of the patch
//! that stays clearest of everyone during it: pushing one moment of a long pause only made it
//! zigzag, and treating the walker as a stander made five times more failures.

use crate::path::Path;
use crate::repair::{Patch, Speeds, Tracks};
use crowd_geometry::{Segment, copies, distance_to_rect, nearest_along};
use glam::DVec2;

/// Moves the pause `(i, j)` of walker `p` to the spot of the patch that stays farthest from
/// every other walker (and stander and obstacle) during the pause, if that is farther than
/// where it is. Returns whether it moved. `tracks` holds everyone's pieces except those of the
/// walkers `moved` in this push, whose paths have changed since. The walks to and from the
/// new spot go at the comfort speed (the pause starts later or ends sooner for them).
pub(crate) fn relocate_pause(
    paths: &mut [Path],
    p: usize,
    (i, j): (usize, usize),
    patch: &Patch,
    speeds: Speeds,
    (tracks, moved): (&Tracks, &[usize]),
) -> bool {
    let r = patch.radius_m;
    let (t0, t1) = (paths[p].free[i].t, paths[p].free[j].t);
    let here = paths[p].free[i].pos;
    let others = others_during(paths, p, (t0, t1), patch, (tracks, moved));
    let clearance = |q: DVec2| clearance(q, &others, patch);
    // Only spots the walker can reach and leave without walking faster than it may.
    // From where the walker comes and to where it goes: the band ends, not the border points,
    // when the pause is the first or last thing it does in the patch.
    let path = &paths[p];
    let (before, after) = path.neighbours(i, j);
    // The pause may start later and end sooner to leave time for the walk (a time move).
    // Points inside the pause (where it passes the period) keep their times: the walker must
    // be there by the first of them and stay until the last.
    let inner = (i + 1 < j).then(|| (path.free[i + 1].t, path.free[j - 1].t));
    let times = |q: DVec2| {
        let start = t0.max(before.1 + before.0.distance(q) / speeds.comfort);
        let end = t1.min(after.1 - q.distance(after.0) / speeds.comfort);
        let holds = inner.is_none_or(|(a, b)| start <= a && end >= b);
        (start <= end && holds).then_some((start, end))
    };
    // ... and in a straight line, clear of every wall (never into a part a wall cuts off).
    let clear_walk = |a: DVec2, b: DVec2| {
        let walk = Segment {
            p0: a,
            t0: 0.0,
            p1: b,
            t1: 1.0,
        };
        patch
            .obstacles
            .iter()
            .all(|o| distance_to_rect(&walk, o.min, o.max) >= r)
    };
    let reachable =
        |q: DVec2| times(q).is_some() && clear_walk(before.0, q) && clear_walk(q, after.0);
    let margin = r + 0.3;
    let n = 9;
    // The clearest reachable spot (the last of equals); a spot found less clear than the best
    // so far part-way through its others is given up.
    let mut best: Option<(f64, DVec2)> = None;
    for k in 0..n * n {
        let f = |i: usize| margin + (patch.side_m - 2.0 * margin) * i as f64 / (n - 1) as f64;
        let q = DVec2::new(f(k % n), f(k / n));
        if !reachable(q) {
            continue;
        }
        let floor = best.map(|b| b.0);
        if let Some(c) = clearance_above(q, &others, patch, floor)
            && floor.is_none_or(|b| c.total_cmp(&b).is_ge())
        {
            best = Some((c, q));
        }
    }
    let Some(best) = best else { return false };
    if best.0 <= clearance(here) + 1e-9 {
        return false;
    }
    let (start, end) = times(best.1).expect("a reachable spot");
    let path = &mut paths[p];
    for f in &mut path.free[i..=j] {
        f.pos = best.1;
    }
    path.free[i].t = start;
    path.free[j].t = end;
    true
}

/// Where everyone but walker `p` (and `p`'s own copies a period or more away) is during
/// `[t0, t1]`: the standers (as pieces that do not move), and every piece of every walker that
/// overlaps the pause, cut to it, bands and ghosts included. A spot standing still all through
/// the pause is as close to a walker as to the nearest point of its cut pieces: exact, where
/// samples every 0.2 s missed walkers passing between them, and made a pause of a 400 s
/// period measure thousands of points per walker (a stage 5 of more than ten minutes).
fn others_during(
    paths: &[Path],
    p: usize,
    (t0, t1): (f64, f64),
    patch: &Patch,
    (tracks, moved): (&Tracks, &[usize]),
) -> Vec<(DVec2, DVec2)> {
    let mut others: Vec<(DVec2, DVec2)> = patch.standers.iter().map(|&q| (q, q)).collect();
    for (b, path) in paths.iter().enumerate() {
        // Everywhere the walker is near the patch: its bands and their ghosts too.
        let segs: std::borrow::Cow<[Segment]> = if moved.contains(&b) {
            path.segments().into()
        } else {
            tracks.get(b).into()
        };
        let (Some(first), Some(last)) = (segs.first(), segs.last()) else {
            continue;
        };
        for k in copies((t0, t1), (first.t0, last.t1), patch.period_s) {
            if b == p && k == 0 {
                continue;
            }
            // The pause in b's own time.
            let shift = k as f64 * patch.period_s;
            let (lo, hi) = (t0 - shift, t1 - shift);
            let from = segs.partition_point(|s| s.t1 < lo);
            for s in segs[from..].iter().take_while(|s| s.t0 <= hi) {
                let (a, z) = (lo.max(s.t0), hi.min(s.t1));
                if a <= z {
                    others.push((s.at(a), s.at(z)));
                }
            }
        }
    }
    others
}

/// How clear spot `q` is: the distance to the nearest of `others`, or to the nearest wall plus
/// a radius (as if the wall were a walker's centre a radius away from it); a spot inside or
/// within a radius of a wall is never chosen.
fn clearance(q: DVec2, others: &[(DVec2, DVec2)], patch: &Patch) -> f64 {
    clearance_above(q, others, patch, None).expect("no floor")
}

/// [`clearance`], or `None` as soon as it is sure to be below `floor`: the nearest of `others`
/// is found by squared distances (the root of the least is the least of the roots, to the
/// bit), and given up once one is surely nearer than `floor` (a pause's spot is chosen among
/// 81, against hundreds of pieces each).
fn clearance_above(
    q: DVec2,
    others: &[(DVec2, DVec2)],
    patch: &Patch,
    floor: Option<f64>,
) -> Option<f64> {
    let r = patch.radius_m;
    let walls = patch
        .obstacles
        .iter()
        .map(|o| {
            let d = (q.clamp(o.min, o.max) - q).length();
            if d < r + 0.05 {
                f64::NEG_INFINITY
            } else {
                d + r
            }
        })
        .fold(f64::INFINITY, f64::min);
    // Squared distances below `below` have a root surely below `floor`.
    let below = floor.map_or(f64::NEG_INFINITY, |f| {
        if f > 0.0 {
            f * f * (1.0 - 1e-9)
        } else {
            f64::NEG_INFINITY
        }
    });
    if floor.is_some_and(|f| walls < f) {
        return None;
    }
    let mut least = f64::INFINITY;
    for &(a, z) in others {
        let d2 = squared_distance_to_piece(q, a, z);
        if d2 < below {
            return None;
        }
        least = least.min(d2);
    }
    Some(walls.min(least.sqrt()))
}

/// The squared distance from `q` to the straight piece from `a` to `z`.
fn squared_distance_to_piece(q: DVec2, a: DVec2, z: DVec2) -> f64 {
    (a + (z - a) * nearest_along(a, z, q)).distance_squared(q)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tests::path_through;
    use crowd_core::trajectories::PointKind;

    /// A walker pausing at (2, 4) from 1 s to 9 s, and one that runs across the patch at
    /// 10 m/s along y = 6 at about 5 s: between two samples 0.2 s apart it covers 2 m.
    fn pause_and_runner() -> (Vec<Path>, Patch<'static>) {
        use PointKind::{Entry, Exit, Pause};
        let at = DVec2::new;
        let pausing = path_through(&[
            (at(0.0, 4.0), 0.0, Entry),
            (at(2.0, 4.0), 1.0, Pause),
            (at(2.0, 4.0), 9.0, Pause),
            (at(0.0, 4.0), 10.0, Exit),
        ]);
        let runner = path_through(&[(at(0.0, 6.0), 4.61, Entry), (at(8.0, 6.0), 5.41, Exit)]);
        let patch = Patch {
            side_m: 8.0,
            period_s: 20.0,
            radius_m: 0.3,
            obstacles: &[],
            standers: &[],
        };
        (vec![pausing, runner], patch)
    }

    #[test]
    fn a_spot_is_as_clear_as_the_nearest_point_anyone_passes_during_the_pause() {
        let (paths, patch) = pause_and_runner();
        let tracks = Tracks::new(paths.iter().map(Path::segments).collect());
        let others = others_during(&paths, 0, (1.0, 9.0), &patch, (&tracks, &[]));
        // On the runner's line at any x, and a metre off it: exactly 0 and 1 m.
        for x in [0.5, 3.3, 5.9, 7.5] {
            assert!(clearance(DVec2::new(x, 6.0), &others, &patch) < 1e-12);
            let off = clearance(DVec2::new(x, 5.0), &others, &patch);
            assert!((off - 1.0).abs() < 1e-12, "{off}");
        }
    }

    #[test]
    fn what_happens_outside_the_pause_is_not_in_the_way() {
        let (paths, patch) = pause_and_runner();
        let tracks = Tracks::new(paths.iter().map(Path::segments).collect());
        // The runner is gone by 5.41 s: a pause from 6 s to 9 s sees nobody.
        let others = others_during(&paths, 0, (6.0, 9.0), &patch, (&tracks, &[]));
        assert!(others.is_empty(), "{others:?}");
        // From 5 s: only the runner's last 0.41 s, from x = 3.9 m on.
        let others = others_during(&paths, 0, (5.0, 9.0), &patch, (&tracks, &[]));
        let near = clearance(DVec2::new(1.0, 6.0), &others, &patch);
        assert!((near - 2.9).abs() < 1e-9, "{near}");
    }
}
