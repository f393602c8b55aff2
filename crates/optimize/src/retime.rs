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
    let mut nodes: Vec<Node> = state
        .crossings
        .iter()
        .enumerate()
        .flat_map(|(b, list)| {
            (0..list.len()).map(move |i| Node {
                border: b as u32,
                index: i as u32,
                next: END,
                seen: false,
                walk: 0.0,
            })
        })
        .collect();
    for (e, x, walk) in pairs.into_iter().flatten() {
        let x = u32::try_from(x).ok().filter(|&x| x != END);
        (nodes[e].next, nodes[e].walk) = (x.expect("fewer than 2^32 - 1 crossings"), walk);
    }
    // The loops in the order they are followed: a chain of random places in memory, walked
    // here with nothing else to wait for. Then followed along this list, whose next steps'
    // borders the processor reads ahead while it nudges (0.46 -> 0.38 s on painting).
    let mut order: Vec<Visit> = Vec::with_capacity(total);
    for start in 0..total {
        if nodes[start].seen {
            continue;
        }
        nodes[start].seen = true;
        let visit = |node: &Node, walk| Visit {
            border: node.border,
            index: node.index,
            walk,
        };
        order.push(visit(&nodes[start], None));
        let (mut c, mut walk) = (nodes[start].next, nodes[start].walk);
        while c != END && !nodes[c as usize].seen {
            let node = &mut nodes[c as usize];
            node.seen = true;
            order.push(visit(node, Some(walk)));
            (c, walk) = (node.next, node.walk);
        }
    }
    drop(nodes);
    let mut retimed = 0;
    let mut t = 0.0;
    for &Visit {
        border,
        index,
        walk,
    } in &order
    {
        let (b, i) = (border as usize, index as usize);
        // Each crossing a comfortable walk after the previous one, nudged in time where the
        // border is busy, left alone where no nudge fits. A loop closes with one pair of
        // whatever duration is left: loops of a random matching are long, so that is one pair
        // in many.
        if let Some(walk) = walk {
            if state.held[b] {
                // A held crossing keeps its time: the walker goes on from it.
            } else if let Some(new_t) = nudge(state, b, i, t + walk) {
                state.crossings[b][i].t = new_t;
                retimed += 1;
            }
        }
        t = state.crossings[b][i].t;
    }
    state.remeasure_all();
    retimed
}

/// A crossing as the loops are followed: its border and place in the border's list, the
/// crossing after it in its loop ([`END`]: none) and the walk between them, and whether its
/// loop was followed yet. One record, so that a step of the loop (a random place in memory)
/// misses the cache once for it, not once per list.
#[derive(Debug, Clone, Copy)]
struct Node {
    border: u32,
    index: u32,
    next: u32,
    seen: bool,
    walk: f64,
}

const END: u32 = u32::MAX;

/// A step of a loop: a crossing, and the walk from the one before (`None`: the loop's first).
#[derive(Debug, Clone, Copy)]
struct Visit {
    border: u32,
    index: u32,
    walk: Option<f64>,
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
