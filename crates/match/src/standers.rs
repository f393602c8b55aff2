//! Standing characters: spread over the free part of a patch, apart from each other, clear of
//! obstacles and of the borders.

use crate::PatchContext;
use glam::DVec2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Places `count` standers by best-candidate sampling (Mitchell 1991): each new stander is the
/// one of 32 random candidates farthest from the standers and obstacles already there.
pub fn place(count: u32, ctx: &PatchContext, radius: f64, seed: u64) -> Vec<DVec2> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // Clear of the border bands on both sides of every border (a radius deep, walked by the
    // characters crossing it) by a diameter and a little: what stands in one patch never
    // touches a walker of the next.
    let margin = 3.0 * radius + 0.1;
    let mut placed: Vec<DVec2> = Vec::with_capacity(count as usize);
    for _ in 0..count {
        let best = (0..32)
            .map(|_| {
                DVec2::new(
                    rng.random_range(margin..ctx.side_m - margin),
                    rng.random_range(margin..ctx.side_m - margin),
                )
            })
            .map(|p| (clearance(p, &placed, ctx), p))
            .max_by(|a, b| a.0.total_cmp(&b.0))
            .expect("32 candidates");
        placed.push(best.1);
    }
    placed
}

/// Distance from `p` to the nearest stander or obstacle.
fn clearance(p: DVec2, placed: &[DVec2], ctx: &PatchContext) -> f64 {
    let to_standers = placed
        .iter()
        .map(|q| p.distance(*q))
        .fold(f64::INFINITY, f64::min);
    let to_obstacles = ctx
        .obstacles
        .iter()
        .map(|r| (p.clamp(r.min, r.max) - p).length())
        .fold(f64::INFINITY, f64::min);
    to_standers.min(to_obstacles)
}
