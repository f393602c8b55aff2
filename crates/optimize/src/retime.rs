//! Re-timing: every crossing is the entry of one matched pair and the exit of another, so the
//! matched pairs chain into loops, one per walker going round the world. Spacing each loop's
//! crossings by a comfortable walk across each patch (scaled so the loop lasts a whole number
//! of periods) threads its walker like a train: no needless pauses or extra periods, durations
//! that are what the density regression expects, and directions that are not drowned by the
//! long waits of leftover pairs.

use crate::state::{State, unkey};
use crowd_core::patterns::Crossing;
use rayon::prelude::*;

/// Re-times the crossings loop by loop, keeping the spacing of every border. Returns how many
/// crossings got a new time.
pub fn retime(state: &mut State) -> usize {
    let offsets: Vec<usize> = state
        .crossings
        .iter()
        .scan(0, |acc, list| {
            let start = *acc;
            *acc += list.len();
            Some(start)
        })
        .collect();
    let total: usize = state.crossings.iter().map(Vec::len).sum();
    let id = |key: u32| {
        let (b, i) = unkey(key);
        offsets[b] + i
    };
    // next[c] = (crossing after c, time walked between them).
    let pairs: Vec<Vec<(usize, usize, f64)>> = state
        .own_patches()
        .into_par_iter()
        .map(|p| {
            let ctx = state.context(p);
            let (entries, exits) = state.endpoints(p);
            let matched = state.pairs(p, &entries, &exits);
            entries
                .iter()
                .zip(matched)
                .map(|(e, o)| {
                    let x = &exits[o];
                    let walk = crowd_match::way::path_length(e, x, &ctx) / ctx.comfort_speed;
                    (id(e.crossing), id(x.crossing), walk)
                })
                .collect()
        })
        .collect();
    let mut next = vec![(usize::MAX, 0.0); total];
    for (e, x, walk) in pairs.into_iter().flatten() {
        next[e] = (x, walk);
    }
    let location: Vec<(usize, usize)> = state
        .crossings
        .iter()
        .enumerate()
        .flat_map(|(b, list)| (0..list.len()).map(move |i| (b, i)))
        .collect();
    let mut seen = vec![false; total];
    let mut retimed = 0;
    for start in 0..total {
        if seen[start] {
            continue;
        }
        // Follow the loop from `start`: each crossing a comfortable walk after the previous
        // one, nudged in time where the border is busy, left alone where no nudge fits. The
        // loop closes with one pair of whatever duration is left: loops of a random matching
        // are long, so that is one pair in many.
        seen[start] = true;
        let (b, i) = location[start];
        let mut t = state.crossings[b][i].t;
        let (mut c, mut walk) = next[start];
        while c != usize::MAX && !seen[c] {
            seen[c] = true;
            let (b, i) = location[c];
            if state.held[b] {
                // A held crossing keeps its time: the walker goes on from it.
            } else if let Some(new_t) = nudge(state, b, i, t + walk) {
                state.crossings[b][i].t = new_t;
                retimed += 1;
            }
            t = state.crossings[b][i].t;
            (c, walk) = next[c];
        }
    }
    state.remeasure_all();
    retimed
}

/// The time nearest `target` (within a few seconds) at which crossing `i` of `border` keeps
/// its spacing, if any.
fn nudge(state: &State, border: usize, i: usize, target: f64) -> Option<f64> {
    let period = state.period_s;
    let list = &state.crossings[border];
    [0.0, 0.3, -0.3, 0.6, -0.6, 1.0, -1.0, 1.5, -1.5, 2.0, -2.0]
        .iter()
        .map(|d| (target + d).rem_euclid(period))
        .find(|&t| {
            let c = Crossing { t, ..list[i] };
            list.iter()
                .enumerate()
                .all(|(j, o)| j == i || state.spacing.compatible(&c, o, period))
        })
}
