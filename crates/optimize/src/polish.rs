//! Polish: a local search after Algorithm 1's loop, over small cycles through the patches
//! furthest off, each change kept only when the scene's E falls.
//!
//! Algorithm 1's steps add and remove crossings where the signed error peaks; they do not
//! balance sideways traffic, and the paper's e(u) cannot see it (a patch asked to flow north
//! with three walkers going east and one going west has the right density and a direction 45
//! degrees off, on either side). In the city, the northward patches sit where cross streets
//! meet the avenue, so every walker of a cross street passes through them; they flow north
//! only when those walkers come in low and leave high, as many each way.
//!
//! [`polish`] takes the worst patches one by one, lists every simple cycle of links through
//! the patch up to [`MAX_CYCLE`] steps long (a back-and-forth over one border is a cycle of
//! two), and tries on each one the three changes that keep parity: add a crossing per step,
//! remove one, or turn one around. Each try measures the touched patches again with the real
//! matching and gives the exact new E (the error totals are kept per patch, so a try costs
//! its few measurements, not a scene); the best try per patch is kept if it lowers E with no
//! patch above rho_max. E therefore never rises here, and the polish ends at a round that
//! keeps nothing, or after `max_rounds`. Patches are taken in order and every try is seeded
//! by its place, so the result is the same for any thread count.

use crate::mutate::{self, Step};
use crate::state::State;
use crowd_core::patterns::{Crossing, Measured};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// What a polish did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Polished {
    pub rounds: u32,
    pub tried: u32,
    pub kept: u32,
}

/// Longest cycle tried, in steps (6 reaches every 2 x 3 block of patches around the patch).
const MAX_CYCLE: usize = 6;
/// Patches whose own error (density in units of rho_max plus direction) is below this are
/// left alone.
const GOOD_ENOUGH: f64 = 0.02;
/// Patches polished per round, worst first, at least: bounds the work on small scenes.
const PATCHES_PER_ROUND: usize = 96;
/// ... and at least this share of a large scene's patches (painting's 10,906: 170 a round), so
/// that a round there gains more than `optimize.tolerance` while it can (at 96, painting's
/// rounds each gained about 5e-4 of E, and the polish stopped at E 0.0170).
const SHARE_PER_ROUND: usize = 64;

/// The three changes that keep every patch's parity.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Change {
    Add,
    Remove,
    Turn,
}

/// The scene's error as running totals, so that a change costs only its own patches.
#[derive(Debug, Clone, Copy)]
struct Totals {
    squares: f64,
    directions: f64,
    patches: usize,
    directed: usize,
}

impl Totals {
    fn new(state: &State) -> Totals {
        let mut t = Totals {
            squares: 0.0,
            directions: 0.0,
            patches: state.measured.len().max(1),
            directed: 0,
        };
        for p in 0..state.measured.len() {
            let (sq, dir) = own_error(state, p, &state.measured[p]);
            t.squares += sq;
            if let Some(d) = dir {
                t.directions += d;
                t.directed += 1;
            }
        }
        t
    }

    fn e(&self, rho_max: f64) -> f64 {
        let e_rho = (self.squares.max(0.0) / self.patches as f64).sqrt() / rho_max;
        let e_d = if self.directed > 0 {
            self.directions / self.directed as f64
        } else {
            0.0
        };
        e_rho + e_d
    }

    /// The totals with patch `p` measured as `after` instead of `before`.
    fn swap(mut self, state: &State, p: usize, before: &Measured, after: &Measured) -> Totals {
        let (sq0, d0) = own_error(state, p, before);
        let (sq1, d1) = own_error(state, p, after);
        self.squares += sq1 - sq0;
        self.directions += d1.unwrap_or(0.0) - d0.unwrap_or(0.0);
        self
    }
}

/// A patch's squared density error and, if it asks for a direction, its direction error (the
/// two terms of `scene_error`).
fn own_error(state: &State, p: usize, m: &Measured) -> (f64, Option<f64>) {
    let (density, direction) = crate::patch_terms(&state.graph.patches[p], state.requested[p], m);
    (density.powi(2), direction)
}

/// The best try for one patch so far: its E, and what the touched borders and patches become.
struct Best {
    e: f64,
    borders: Vec<(usize, Vec<Crossing>)>,
    measured: Vec<(usize, Measured)>,
}

/// Runs rounds of the local search until one keeps nothing or `max_rounds` have run; after
/// every round, `after_round` sees the state (for the per-step log).
///
/// A patch's tries are independent (each starts from the same state, with its own seeded
/// random numbers), so they run in parallel, one copy of the state per thread; the best is
/// the least E, the first try on a tie, whatever the thread count.
pub fn polish(
    state: &mut State,
    rho_max: f64,
    max_rounds: u32,
    tolerance: f64,
    seed: u64,
    mut after_round: impl FnMut(&State),
) -> Polished {
    let mut done = Polished::default();
    let mut totals = Totals::new(state);
    let mut forks: Vec<State> = (1..rayon::current_num_threads())
        .map(|_| state.fork())
        .collect();
    for round in 0..max_rounds {
        done.rounds += 1;
        let start = totals.e(rho_max);
        let mut kept = 0;
        for p in worst(state, rho_max) {
            let tries = tries_for(state, p);
            done.tried += tries.len() as u32;
            let bar = totals.e(rho_max) - 1e-9;
            let salt = seed ^ 0x9e37_79b9_7f4a_7c15 ^ ((round as u64) << 40) ^ ((p as u64) << 20);
            let best = {
                let mut copies: Vec<&mut State> = std::iter::once(&mut *state)
                    .chain(forks.iter_mut())
                    .collect();
                let size = tries.len().div_ceil(copies.len()).max(1);
                let found: Vec<Vec<Option<Best>>> = copies
                    .par_iter_mut()
                    .zip(tries.par_chunks(size))
                    .enumerate()
                    .map(|(chunk, (copy, tries))| {
                        tries
                            .iter()
                            .enumerate()
                            .map(|(j, (cycle, change))| {
                                let k = (chunk * size + j) as u64;
                                let mut rng = ChaCha8Rng::seed_from_u64(salt ^ k);
                                try_change(copy, cycle, *change, totals, rho_max, bar, &mut rng)
                            })
                            .collect()
                    })
                    .collect();
                // `min_by` keeps the first of equal minima: the earliest try.
                found
                    .into_iter()
                    .flatten()
                    .flatten()
                    .min_by(|a, b| a.e.total_cmp(&b.e))
            };
            if let Some(b) = best {
                for (p, m) in &b.measured {
                    totals = totals.swap(state, *p, &state.measured[*p], m);
                }
                for copy in std::iter::once(&mut *state).chain(forks.iter_mut()) {
                    for (border, list) in &b.borders {
                        copy.crossings[*border].clone_from(list);
                    }
                    for (p, m) in &b.measured {
                        copy.measured[*p] = *m;
                    }
                }
                kept += 1;
            }
        }
        done.kept += kept;
        after_round(state);
        let e = totals.e(rho_max);
        if kept == 0 || e > start - tolerance {
            break;
        }
    }
    done
}

/// The changes worth trying through patch `p`: every cycle through it with each of the three
/// changes that can help (a patch that asks for no direction gains nothing from walkers it has
/// too many of, and a turn helps only directions: a back-and-forth turned is the same
/// back-and-forth).
fn tries_for(state: &State, p: usize) -> Vec<(Vec<Step>, Change)> {
    let directed = |q: usize| state.graph.patches[q].direction.is_some();
    let short = state.measured[p].density < state.requested[p];
    let mut tries = Vec::new();
    for cycle in cycles_through(state, p) {
        let turns = cycle.len() > 2 && cycle.iter().any(|s| directed(s.to));
        for change in [Change::Add, Change::Remove, Change::Turn] {
            let useful = match change {
                Change::Add => short || directed(p),
                Change::Remove => !short || directed(p),
                Change::Turn => turns,
            };
            if useful {
                tries.push((cycle.clone(), change));
            }
        }
    }
    tries
}

/// The patches whose own error is above [`GOOD_ENOUGH`], worst first, at most
/// [`PATCHES_PER_ROUND`].
fn worst(state: &State, rho_max: f64) -> Vec<usize> {
    let mut all: Vec<(f64, usize)> = (0..state.links.len())
        .filter(|&p| !state.links[p].is_empty())
        .map(|p| {
            let (sq, dir) = own_error(state, p, &state.measured[p]);
            (sq.sqrt() / rho_max + dir.unwrap_or(0.0), p)
        })
        .filter(|&(size, _)| size > GOOD_ENOUGH)
        .collect();
    all.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    all.into_iter()
        .take(PATCHES_PER_ROUND.max(state.links.len() / SHARE_PER_ROUND))
        .map(|(_, p)| p)
        .collect()
}

/// Every simple cycle of links from `p` back to `p` of at most [`MAX_CYCLE`] steps, in both
/// orientations, as the steps a walker going round takes.
fn cycles_through(state: &State, p: usize) -> Vec<Vec<Step>> {
    let mut found = Vec::new();
    let mut path = Vec::with_capacity(MAX_CYCLE);
    walk(state, p, p, &mut path, &mut found);
    found
}

fn walk(state: &State, start: usize, at: usize, path: &mut Vec<Step>, found: &mut Vec<Vec<Step>>) {
    for l in &state.links[at] {
        let step = Step {
            from: at,
            to: l.to,
            border: l.border,
            way: l.way,
        };
        if l.to == start {
            // Back over the border just crossed only as a back-and-forth of two steps.
            let same_border = path.last().is_some_and(|s: &Step| s.border == l.border);
            if !path.is_empty() && (path.len() == 1 || !same_border) {
                path.push(step);
                found.push(path.clone());
                path.pop();
            }
            continue;
        }
        if path.len() + 1 >= MAX_CYCLE || path.iter().any(|s| s.to == l.to) {
            continue;
        }
        path.push(step);
        walk(state, start, l.to, path, found);
        path.pop();
    }
}

/// Makes `change` along `cycle`, measures the touched patches and puts everything back; returns
/// the after-state if E falls below `bar` with no touched patch above rho_max.
fn try_change(
    state: &mut State,
    cycle: &[Step],
    change: Change,
    totals: Totals,
    rho_max: f64,
    bar: f64,
    rng: &mut ChaCha8Rng,
) -> Option<Best> {
    let mut borders: Vec<usize> = cycle.iter().map(|s| s.border).collect();
    borders.sort_unstable();
    borders.dedup();
    let saved: Vec<(usize, Vec<Crossing>)> = borders
        .iter()
        .map(|&b| (b, state.crossings[b].clone()))
        .collect();
    let made = match change {
        Change::Add => mutate::add_cycle(state, cycle, rng),
        Change::Remove => {
            let ok = mutate::can_remove(state, cycle);
            if ok {
                mutate::remove_cycle(state, cycle);
            }
            ok
        }
        Change::Turn => mutate::reverse_cycle(state, cycle),
    };
    if !made {
        return None;
    }
    let mut touched: Vec<usize> = cycle.iter().map(|s| s.to).collect();
    touched.sort_unstable();
    let mut after = totals;
    let fresh: Vec<Measured> = touched.iter().map(|&p| state.measure(p)).collect();
    let mut measured = Vec::with_capacity(touched.len());
    let mut full = false;
    for (&p, m) in touched.iter().zip(fresh) {
        full |= m.density > rho_max;
        after = after.swap(state, p, &state.measured[p], &m);
        measured.push((p, m));
    }
    let e = after.e(rho_max);
    let result = (!full && e < bar).then(|| Best {
        e,
        borders: borders
            .iter()
            .map(|&b| (b, state.crossings[b].clone()))
            .collect(),
        measured,
    });
    for (b, list) in saved {
        state.crossings[b] = list;
    }
    result
}
