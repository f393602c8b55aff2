//! One step of the repair: the pair of the worst encounter pushed apart (Ramirez et al. eq.
//! 5-7), or one of them passing earlier or later instead (a time move), or a pausing walker's
//! pause moved ([`crate::pause`]). Which walkers moved is what the distance matrix measures
//! again.

use crate::path::Path;
use crate::pause::relocate_pause;
use crate::repair::{Encounter, Other, Patch, Speeds, Tracks};
use glam::DVec2;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// How near a band end a path is held, s: no point within it moves (a bend right at the band
/// end would be a turn at the border).
const HELD_S: f64 = 0.25;

/// Applies eq. 5-7 to the encounter: the two points at the moment of closest approach are
/// pushed apart by the clearance they need, shared by speed (the faster walker moves less), a
/// small random rotation against endless loops, and no push that would leave the patch or
/// enter an obstacle. Returns the walkers whose paths changed.
pub(crate) fn push_apart(
    paths: &mut [Path],
    tracks: &Tracks,
    patch: &Patch,
    speeds: Speeds,
    e: &Encounter,
    rng: &mut ChaCha8Rng,
) -> Vec<usize> {
    let r = patch.radius_m;
    let pa = paths[e.a].position(e.t);
    let (q, need, other_walker) = contact(paths, patch, e, pa);
    let mut dir = (pa - q).normalize_or_zero();
    if dir == DVec2::ZERO {
        let angle = rng.random_range(0.0..std::f64::consts::TAU);
        dir = DVec2::new(angle.cos(), angle.sin());
    }
    let share_a = share_of_a(paths, e, other_walker);
    // Push by the missing clearance plus a little, at least a tenth of the clearance.
    let missing = match e.other {
        Other::Obstacle(_) => need - (pa - q).length().min(e.distance),
        _ => need - e.distance,
    };
    let push = (missing + 0.05).max(0.1 * need);
    let keep_inside = |p: DVec2| patch.keep_inside(p);
    let clear = |p: DVec2| {
        !patch
            .obstacles
            .iter()
            .any(|o| (p.clamp(o.min, o.max) - p).length() < r)
    };
    // A third of the time, a walker of the pair first tries to pass earlier or later instead.
    if let Some((b, tb)) = other_walker
        && rng.random_bool(1.0 / 3.0)
        && let Some(p) = time_move(paths, tracks, patch, e, (b, tb), push, speeds.max)
    {
        return vec![p];
    }
    let mut moves = vec![(e.a, e.t, dir, share_a)];
    if let Some((b, tb)) = other_walker {
        moves.push((b, tb, -dir, 1.0 - share_a));
    }
    let mut touched = Vec::new();
    for (p, t, d, share) in moves {
        if share <= 0.0 {
            continue;
        }
        // A walker caught pausing moves its whole pause to the clearest spot for its duration:
        // pushing one moment of a long pause only makes it zigzag.
        let phi = rng.random_range(-0.5..0.5);
        let force = DVec2::from_angle(phi).rotate(d) * push * share;
        if let Some(pause) = paths[p].pause_at(t) {
            // Else the walker steps aside for the part of the pause around the encounter (a
            // bend inside it would end the pause).
            if !relocate_pause(paths, p, pause, patch, speeds, (tracks, &touched)) {
                paths[p].split_pause(pause, t, force, speeds.max, keep_inside, clear);
            }
            touched.push(p);
            continue;
        }
        // Moved or not, a new free point may have been added: the row is recomputed.
        paths[p].push_at(t, force, HELD_S, speeds.bend_limit(), keep_inside, clear);
        touched.push(p);
    }
    touched.sort_unstable();
    touched.dedup();
    touched
}

/// Where the other of encounter `e` is when walker `e.a` is at `pa`, the distance the two
/// need, and the other walker and its time (`None` for a stander or an obstacle). For an
/// obstacle, the nearest point of its box; from inside the box, a point past its nearest
/// edge, with the depth added to what is needed.
fn contact(
    paths: &[Path],
    patch: &Patch,
    e: &Encounter,
    pa: DVec2,
) -> (DVec2, f64, Option<(usize, f64)>) {
    let r = patch.radius_m;
    match e.other {
        Other::Walker { b, shift } => (
            paths[b].position(e.t - shift),
            2.0 * r,
            Some((b, e.t - shift)),
        ),
        Other::Stander(s) => (patch.standers[s], 2.0 * r, None),
        Other::Obstacle(o) => {
            let rect = patch.obstacles[o];
            let q = pa.clamp(rect.min, rect.max);
            if q == pa {
                // Inside the obstacle: out through the nearest edge.
                let exits = [
                    (pa.x - rect.min.x, DVec2::NEG_X),
                    (rect.max.x - pa.x, DVec2::X),
                    (pa.y - rect.min.y, DVec2::NEG_Y),
                    (rect.max.y - pa.y, DVec2::Y),
                ];
                let (depth, out) = exits
                    .into_iter()
                    .min_by(|a, b| a.0.total_cmp(&b.0))
                    .expect("four");
                (pa - out * (depth + 1e-6), r + depth, None)
            } else {
                (q, r, None)
            }
        }
    }
}

/// The share of the push walker `e.a` takes: by speed (eq. 6, the faster walker moves less);
/// a walker held by its band end at that moment takes none; all of it against a stander or
/// an obstacle.
fn share_of_a(paths: &[Path], e: &Encounter, other_walker: Option<(usize, f64)>) -> f64 {
    let (ua, ub) = match other_walker {
        Some((b, tb)) => (paths[e.a].speed(e.t), paths[b].speed(tb)),
        None => (0.0, 1.0),
    };
    let a_free = paths[e.a].movable_at(e.t, HELD_S);
    let b_free = other_walker.is_some_and(|(b, tb)| paths[b].movable_at(tb, HELD_S));
    match (other_walker.is_some(), a_free, b_free) {
        (false, _, _) => 1.0,
        (true, true, false) => 1.0,
        (true, false, true) => 0.0,
        _ if ua + ub > 1e-9 => ub / (ua + ub),
        _ => 0.5,
    }
}

/// The best time move for the pair of `e` (either walker reaching the point of the encounter
/// `push` metres' walk earlier or later), applied if it leaves the two farther apart than
/// they are, and never faster than `max_speed`; returns the walker it moved.
pub(crate) fn time_move(
    paths: &mut [Path],
    tracks: &Tracks,
    patch: &Patch,
    e: &Encounter,
    (b, tb): (usize, f64),
    push: f64,
    max_speed: f64,
) -> Option<usize> {
    let a = e.a;
    let mut best: Option<(f64, usize, Path)> = None;
    for (p, t) in [(a, e.t), (b, tb)] {
        let speed = paths[p].speed(t).max(0.3);
        for sign in [1.0, -1.0] {
            let mut moved = paths[p].clone();
            if !moved.retime_at(t, sign * push / speed, HELD_S, max_speed) {
                continue;
            }
            // Only the moved walker's pieces change; the other's are the row's own.
            let (sa, sb) = if p == a {
                (moved.segments(), tracks.get(b).to_vec())
            } else {
                (tracks.get(a).to_vec(), moved.segments())
            };
            let two = Tracks::new(if a == b { vec![sa] } else { vec![sa, sb] });
            let distance = crowd_geometry::pair(&two, 0, (a != b) as usize, patch)
                .map_or(f64::INFINITY, |x| x.distance);
            if distance > e.distance + 1e-3 && best.as_ref().is_none_or(|x| distance > x.0) {
                best = Some((distance, p, moved));
            }
        }
    }
    let (_, p, moved) = best?;
    paths[p] = moved;
    Some(p)
}
