//! Adding and removing crossings along circular paths of patches (Crowd Art Alg. 1, lines
//! 12-13 and 19). A cycle gives every patch on it one more (or one less) entry and exit, so
//! parity always holds.

use crate::spacing::reverse;
use crate::state::State;
use crowd_core::BorderAxis;
use crowd_core::patterns::{Crossing, Way};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// One step of a cycle: from patch `from` to patch `to` through `border`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    pub from: usize,
    pub to: usize,
    pub border: usize,
    pub way: Way,
}

/// Adds a crossing for every step, threaded in time like one walker going round: each crossing
/// comes a comfortable walk across a patch after the previous one, and keeps to the same line
/// when it goes straight on. Undoes everything and returns false when a border has no room.
pub fn add_cycle(state: &mut State, cycle: &[Step], rng: &mut ChaCha8Rng) -> bool {
    let period = state.period_s;
    let side = state.graph.world.patch_side_m;
    let mut t = rng.random_range(0.0..period);
    let mut previous: Option<(BorderAxis, f64)> = None;
    let mut added: Vec<usize> = Vec::with_capacity(cycle.len());
    for step in cycle {
        let axis = state.graph.borders[step.border].axis;
        let s_pref = match (downstream(state, step), previous) {
            (Some(lean), _) => side / 2.0 + lean * (side / 2.0 - 1.0),
            (None, Some((a, s))) if a == axis => s,
            _ => side / 2.0 + rng.random_range(-1.5..1.5),
        };
        let velocity = state.crossing_velocity(step.border, step.way);
        match find_slot(state, step.border, step.way, s_pref, t, velocity, rng) {
            Some(c) => {
                state.crossings[step.border].push(c);
                added.push(step.border);
                previous = Some((axis, c.s));
                t = c.t + side / velocity.length();
            }
            None => {
                for b in added {
                    state.crossings[b].pop();
                }
                return false;
            }
        }
    }
    true
}

/// Where along its border a crossing best serves the requested directions of its patches, in
/// [-1, 1] from the middle, if either patch asks for one: an entry sits upstream in the patch it
/// enters and an exit downstream in the patch it leaves, so that the straight lines between
/// them run with the direction (a walker turning from a side street into a northward avenue
/// comes in at the south end of the side and leaves at the north).
fn downstream(state: &State, step: &Step) -> Option<f64> {
    let tangent = state
        .normal(step.border, crowd_core::patterns::Way::AToB)
        .perp()
        .abs();
    let lean: Vec<f64> = [(step.from, 1.0), (step.to, -1.0)]
        .iter()
        .filter_map(|&(p, sign)| {
            let d = state.graph.patches[p].direction?;
            Some(sign * d.weight.min(1.0) * d.dir.dot(tangent))
        })
        .collect();
    (!lean.is_empty()).then(|| (lean.iter().sum::<f64>() / lean.len() as f64).clamp(-1.0, 1.0))
}

/// A free place and time near (`s_pref`, `t_pref`) on `border`, if there is one.
pub fn find_slot(
    state: &State,
    border: usize,
    way: Way,
    s_pref: f64,
    t_pref: f64,
    velocity: glam::DVec2,
    rng: &mut ChaCha8Rng,
) -> Option<Crossing> {
    let period = state.period_s;
    for k in 0..48 {
        let spread = 1.5 * (1.0 + k as f64 / 8.0);
        let (s, t) = if k == 0 {
            (s_pref, t_pref)
        } else {
            (
                s_pref + rng.random_range(-1.0..1.0) * spread,
                t_pref + rng.random_range(-1.0..1.0) * spread,
            )
        };
        let s = state.spacing.clamp(border, s)?;
        let c = Crossing {
            border: border as u32,
            way,
            s,
            t: t.rem_euclid(period),
            velocity,
        };
        if state.spacing.fits(&c, &state.crossings[border], period) {
            return Some(c);
        }
    }
    None
}

/// Whether every step of the cycle has a crossing of its own to remove.
pub fn can_remove(state: &State, cycle: &[Step]) -> bool {
    let mut needed: Vec<(usize, Way, usize)> = Vec::new();
    for step in cycle {
        match needed
            .iter_mut()
            .find(|(b, w, _)| *b == step.border && *w == step.way)
        {
            Some(entry) => entry.2 += 1,
            None => needed.push((step.border, step.way, 1)),
        }
    }
    needed
        .iter()
        .all(|&(b, w, n)| state.crossings[b].iter().filter(|c| c.way == w).count() >= n)
}

/// Removes one crossing per step (the latest one of that way on the border).
pub fn remove_cycle(state: &mut State, cycle: &[Step]) {
    for step in cycle {
        let list = &mut state.crossings[step.border];
        if let Some(i) = list.iter().rposition(|c| c.way == step.way) {
            list.remove(i);
        }
    }
}

/// Adds `pairs` crossings each way on a border (a balanced start: parity holds whatever the
/// counts). Returns how many pairs found room.
pub fn add_pairs(state: &mut State, border: usize, pairs: u32, rng: &mut ChaCha8Rng) -> u32 {
    let side = state.graph.world.patch_side_m;
    let period = state.period_s;
    let mut placed = 0;
    for _ in 0..pairs {
        let mut ok = true;
        let mut added = 0;
        for way in [Way::AToB, reverse(Way::AToB)] {
            let v = state.crossing_velocity(border, way);
            let s = rng.random_range(0.0..side);
            let t = rng.random_range(0.0..period);
            match find_slot(state, border, way, s, t, v, rng) {
                Some(c) => {
                    state.crossings[border].push(c);
                    added += 1;
                }
                None => ok = false,
            }
        }
        if !ok {
            for _ in 0..added {
                state.crossings[border].pop();
            }
            break;
        }
        placed += 1;
    }
    placed
}

/// Turns one crossing of every step around, if every turned crossing still keeps its spacing;
/// otherwise changes nothing and returns false. Times are mirrored about the first crossing's,
/// so a walker threaded along the cycle is threaded the other way after the turn (its
/// crossings come a walk apart in the new order, not a period minus a walk).
pub fn reverse_cycle(state: &mut State, cycle: &[Step]) -> bool {
    let period = state.period_s;
    let mut done: Vec<(usize, usize, Crossing)> = Vec::new();
    let mut mirror: Option<f64> = None;
    for step in cycle {
        let list = &state.crossings[step.border];
        let Some(i) = list.iter().position(|c| c.way == step.way) else {
            undo(state, &done);
            return false;
        };
        let old = list[i];
        let way = reverse(old.way);
        let about = *mirror.get_or_insert(old.t);
        let turned = Crossing {
            way,
            t: (2.0 * about - old.t).rem_euclid(period),
            velocity: state.crossing_velocity(step.border, way),
            ..old
        };
        let others: Vec<Crossing> = list
            .iter()
            .enumerate()
            .filter(|(j, _)| *j != i)
            .map(|(_, c)| *c)
            .collect();
        if !state.spacing.fits(&turned, &others, period) {
            undo(state, &done);
            return false;
        }
        state.crossings[step.border][i] = turned;
        done.push((step.border, i, old));
    }
    true
}

fn undo(state: &mut State, done: &[(usize, usize, Crossing)]) {
    for &(b, i, old) in done.iter().rev() {
        state.crossings[b][i] = old;
    }
}
