//! The way of an entry-exit pair through its patch: where it turns, its corners round the
//! walls, its length, and the time it has in the looping animation. Both the pair's score
//! (`score.rs`) and its line (`plan.rs`) are measured on it.

use crate::{Endpoint, PatchContext};
use crowd_core::trajectories::PointKind;
use glam::DVec2;

/// Time from `entry` to `exit` in the looping animation, in (0, period].
pub fn wrapped_dt(entry_t: f64, exit_t: f64, period: f64) -> f64 {
    let dt = (exit_t - entry_t).rem_euclid(period);
    if dt <= 1e-9 { period } else { dt }
}

/// Where a walker that enters and leaves by the same border turns: towards the centre, at
/// `turn_depth` of the side, nearer or farther if an obstacle is there.
pub fn turn_point(entry: &Endpoint, exit: &Endpoint, ctx: &PatchContext) -> Option<DVec2> {
    if entry.side != exit.side {
        return None;
    }
    let mid = (entry.pos + exit.pos) / 2.0;
    let depth = ctx.settings.turn_depth * ctx.side_m;
    let free = |p: DVec2| {
        !ctx.obstacles.iter().any(|r| {
            p.x >= r.min.x - 0.3
                && p.x <= r.max.x + 0.3
                && p.y >= r.min.y - 0.3
                && p.y <= r.max.y + 0.3
        })
    };
    let candidates = [1.0, 0.6, 1.4, 0.35];
    let inward = entry.side.inward();
    candidates
        .iter()
        .map(|k| mid + inward * depth * k)
        .find(|&p| free(p))
        .or(Some(mid + inward * depth))
}

/// The corners of the way from `entry` to `exit`: through the turn point, if any, and round
/// the patch's obstacles (see [`crate::route`]).
pub fn waypoints(entry: &Endpoint, exit: &Endpoint, ctx: &PatchContext) -> Vec<(DVec2, PointKind)> {
    let legs = match turn_point(entry, exit, ctx) {
        Some(c) => vec![
            (entry.pos, c, PointKind::Turn),
            (c, exit.pos, PointKind::Exit),
        ],
        None => vec![(entry.pos, exit.pos, PointKind::Exit)],
    };
    let mut out = vec![(entry.pos, PointKind::Entry)];
    for (from, to, end_kind) in legs {
        let corners = crate::route::route(from, to, ctx.obstacles, ctx.radius_m, ctx.side_m);
        let inner = &corners[1..corners.len() - 1];
        out.extend(inner.iter().map(|&p| (p, PointKind::Detour)));
        out.push((to, end_kind));
    }
    out
}

/// Length of the way from `entry` to `exit` (see [`waypoints`]).
pub fn path_length(entry: &Endpoint, exit: &Endpoint, ctx: &PatchContext) -> f64 {
    if ctx.obstacles.is_empty() {
        return match turn_point(entry, exit, ctx) {
            Some(c) => entry.pos.distance(c) + c.distance(exit.pos),
            None => entry.pos.distance(exit.pos),
        };
    }
    waypoints(entry, exit, ctx)
        .windows(2)
        .map(|w| w[0].0.distance(w[1].0))
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_wraps_around_the_period() {
        assert_eq!(wrapped_dt(2.0, 5.0, 20.0), 3.0);
        assert_eq!(wrapped_dt(18.0, 1.0, 20.0), 3.0);
        assert_eq!(wrapped_dt(4.0, 4.0, 20.0), 20.0);
    }
}
