//! Standing characters: spread over the free part of a patch, apart from each other, clear of
//! obstacles and of the borders.

use crate::PatchContext;
use glam::DVec2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Candidates weighed for each stander.
const CANDIDATES: usize = 32;
/// Random spots drawn at most per stander while looking for its candidates.
const MAX_DRAWS: usize = 1024;

/// Places `count` standers by best-candidate sampling (Mitchell 1991): each new stander is the
/// one of 32 candidates farthest from the standers and obstacles already there.
///
/// A candidate must leave a walker room to pass between it and any wall (a stander's radius
/// plus a walker's diameter and a little), as it must between it and a border: a stander in a
/// corridor one walker wide closes it, and stage 5 cannot clear a walker that has to pass a
/// stander with no room (city patches 587 and 655 stalled so). Only where no spot of the patch
/// is that clear does a stander take the clearest spot it found.
pub fn place(count: u32, ctx: &PatchContext, radius: f64, seed: u64) -> Vec<DVec2> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // Clear of the border bands on both sides of every border (a radius deep, walked by the
    // characters crossing it) by a diameter and a little: what stands in one patch never
    // touches a walker of the next.
    let margin = 3.0 * radius + 0.1;
    let mut placed: Vec<DVec2> = Vec::with_capacity(count as usize);
    for _ in 0..count {
        let mut best: Option<(f64, DVec2)> = None;
        let mut fallback: Option<(f64, DVec2)> = None;
        let mut candidates = 0;
        for _ in 0..MAX_DRAWS {
            let p = DVec2::new(
                rng.random_range(margin..ctx.side_m - margin),
                rng.random_range(margin..ctx.side_m - margin),
            );
            let to_walls = wall_clearance(p, ctx);
            let score = to_walls.min(stander_clearance(p, &placed));
            if to_walls >= margin {
                if best.is_none_or(|(s, _)| score > s) {
                    best = Some((score, p));
                }
                candidates += 1;
                if candidates == CANDIDATES {
                    break;
                }
            } else if fallback.is_none_or(|(s, _)| to_walls > s) {
                fallback = Some((to_walls, p));
            }
        }
        let (_, spot) = best.or(fallback).expect("at least one spot drawn");
        placed.push(spot);
    }
    placed
}

/// Distance from `p` to the nearest stander already placed.
fn stander_clearance(p: DVec2, placed: &[DVec2]) -> f64 {
    placed
        .iter()
        .map(|q| p.distance(*q))
        .fold(f64::INFINITY, f64::min)
}

/// Distance from `p` to the nearest obstacle of the patch (0 inside one).
fn wall_clearance(p: DVec2, ctx: &PatchContext) -> f64 {
    ctx.obstacles
        .iter()
        .map(|r| (p.clamp(r.min, r.max) - p).length())
        .fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crowd_core::config::MatchSettings;
    use crowd_core::patch_graph::Rect;

    const R: f64 = 0.3;

    fn context<'a>(obstacles: &'a [Rect], settings: &'a MatchSettings) -> PatchContext<'a> {
        PatchContext {
            side_m: 8.0,
            period_s: 20.0,
            comfort_speed: 1.3,
            direction: None,
            obstacles,
            radius_m: R,
            settings,
        }
    }

    /// A wall over the west of the patch, leaving a corridor `width` metres wide in the east.
    fn corridor(width: f64) -> Vec<Rect> {
        vec![Rect {
            min: DVec2::ZERO,
            max: DVec2::new(8.0 - width, 8.0),
        }]
    }

    #[test]
    fn a_stander_leaves_room_to_walk_past_it_in_a_corridor() {
        let settings = MatchSettings::default();
        // 2.4 m: the only spots that leave a walker room between stander and wall are a
        // hand's width of the corridor's middle; plain best-candidate sampling hugs the wall
        // half the time.
        let walls = corridor(2.4);
        for seed in 0..50 {
            for spot in place(2, &context(&walls, &settings), R, seed) {
                assert!(
                    wall_clearance(spot, &context(&walls, &settings)) >= 3.0 * R + 0.1,
                    "seed {seed}: stander at {spot} blocks the corridor"
                );
            }
        }
    }

    #[test]
    fn a_corridor_too_narrow_to_pass_still_gets_its_stander_at_the_clearest_spot() {
        let settings = MatchSettings::default();
        let walls = corridor(1.6);
        let spots = place(1, &context(&walls, &settings), R, 7);
        assert_eq!(spots.len(), 1);
        let clear = wall_clearance(spots[0], &context(&walls, &settings));
        assert!(clear > 0.5 && clear < 3.0 * R + 0.1, "clearance {clear}");
    }
}
