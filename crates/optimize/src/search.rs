//! Finding where the error is and the circular paths that fix it (Crowd Art Alg. 1, lines
//! 5-11 and 16-18; section 4.2).

use crate::mutate::Step;
use crate::state::State;
use crowd_core::patterns::Way;
use glam::DVec2;
use petgraph::algo::astar;
use petgraph::graph::{DiGraph, NodeIndex};
use petgraph::visit::EdgeRef;
use std::collections::HashMap;

/// Signed error of every patch, in units of rho_max (eq. 7):
/// e = e_rho + sgn(e_rho) e_d, with e_d = |1 - d_r . d_c| / 2 where a direction is requested.
pub fn signed_errors(state: &State, rho_max: f64, room: f64) -> Vec<f64> {
    state
        .graph
        .patches
        .iter()
        .zip(&state.measured)
        .zip(&state.requested)
        .map(|((p, m), &requested)| {
            let e_rho = (m.density - requested) / rho_max;
            let e_d = p.direction.map_or(0.0, |d| {
                let measured = m.direction.unwrap_or(DVec2::ZERO);
                (1.0 - d.dir.dot(measured)).abs() / 2.0 * d.weight.min(1.0)
            });
            // A patch with too little density but the wrong direction needs aligned walkers
            // added; one that cannot take more (rho_max) needs the misaligned ones removed.
            let full = m.density + room > rho_max;
            let sign = if e_rho > 0.0 || full { 1.0 } else { -1.0 };
            e_rho + sign * e_d
        })
        .collect()
}

/// Whether we look for too much (maxima, remove) or too little (minima, add).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    Remove,
    Add,
    /// Through existing crossings, to turn them around (density stays, direction changes).
    Reverse,
}

/// Local optima of the signed error beyond `threshold`, worst first.
pub fn optima(state: &State, errors: &[f64], mode: Mode, threshold: f64) -> Vec<usize> {
    let key = |u: usize| match mode {
        Mode::Remove | Mode::Reverse => errors[u],
        Mode::Add => -errors[u],
    };
    let mut found: Vec<usize> = (0..errors.len())
        .filter(|&u| key(u) > threshold)
        .filter(|&u| {
            state.links[u]
                .iter()
                .all(|l| key(u) > key(l.to) || (key(u) == key(l.to) && u < l.to))
        })
        .collect();
    found.sort_by(|&a, &b| key(b).total_cmp(&key(a)).then(a.cmp(&b)));
    found
}

/// Groups optima of one component that lie near each other (up to `size` per group, within
/// `radius` cells, the nearest first), worst first; at most `budget(component)` groups of a
/// component, the first it would make.
///
/// Optima are looked up in squares of `radius` cells: a step's optima ran to thousands, and
/// measuring each against every later one was a sixth of stage 3's time on one core. A
/// component's optima past its budget are not grouped at all: they could only join groups of
/// their own component, which would be dropped.
pub fn groups(
    state: &State,
    optima: &[usize],
    (radius, size): (u32, usize),
    budget: impl Fn(u32) -> usize,
) -> Vec<Vec<usize>> {
    let cell = |u: usize| state.graph.patches[u].cell;
    let component = |u: usize| state.graph.patches[u].component;
    let side = radius.max(1);
    let square = |u: usize| (cell(u).col / side, cell(u).row / side);
    // Each square's optima, in the order of `optima`.
    let mut squares: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (i, &u) in optima.iter().enumerate() {
        squares.entry(square(u)).or_default().push(i);
    }
    let mut made: HashMap<u32, usize> = HashMap::new();
    let mut taken = vec![false; optima.len()];
    let mut out = Vec::new();
    for i in 0..optima.len() {
        let (u, c) = (optima[i], component(optima[i]));
        let made = made.entry(c).or_default();
        if taken[i] || *made >= budget(c) {
            continue;
        }
        *made += 1;
        taken[i] = true;
        let (sx, sy) = square(u);
        let mut near: Vec<(u32, usize)> = Vec::new();
        for x in sx.saturating_sub(1)..=sx + 1 {
            for y in sy.saturating_sub(1)..=sy + 1 {
                let Some(list) = squares.get(&(x, y)) else {
                    continue;
                };
                let later = list.partition_point(|&j| j <= i);
                near.extend(
                    list[later..]
                        .iter()
                        .filter(|&&j| !taken[j] && component(optima[j]) == c)
                        .map(|&j| (cells_apart(state, u, optima[j]), j))
                        .filter(|&(d, _)| d <= radius),
                );
            }
        }
        near.sort_unstable();
        let mut group = vec![u];
        for &(_, j) in near.iter().take(size - 1) {
            taken[j] = true;
            group.push(optima[j]);
        }
        out.push(group);
    }
    out
}

/// How many cells apart patches `u` and `v` are, along the grid (Manhattan).
pub(crate) fn cells_apart(state: &State, u: usize, v: usize) -> u32 {
    let (a, b) = (state.graph.patches[u].cell, state.graph.patches[v].cell);
    a.col.abs_diff(b.col) + a.row.abs_diff(b.row)
}

/// The patch graph as petgraph sees it: a node per patch, an edge per way through an open
/// border.
pub struct Net {
    pub graph: DiGraph<(), (usize, Way)>,
}

impl Net {
    pub fn new(state: &State) -> Net {
        let mut graph = DiGraph::with_capacity(state.links.len(), 2 * state.graph.borders.len());
        for _ in 0..state.links.len() {
            graph.add_node(());
        }
        for (u, links) in state.links.iter().enumerate() {
            for l in links {
                graph.add_edge(NodeIndex::new(u), NodeIndex::new(l.to), (l.border, l.way));
            }
        }
        Net { graph }
    }
}

/// Weights of the path costs.
pub struct Costs<'e> {
    pub errors: &'e [f64],
    /// Density one more entry-exit pair adds, and the most a patch may hold.
    pub room: f64,
    pub rho_max: f64,
    /// Signed error of one entry-exit pair, in units of rho_max.
    pub quantum: f64,
    pub direction_gain: f64,
}

const BLOCKED: f64 = 1e9;
/// The cheapest step; A*'s estimate is the Manhattan distance times this, so it stays admissible.
const MIN_STEP: f64 = 0.2;

impl Costs<'_> {
    /// Cost of a step from `u` to `v` through `border`: 1 per patch, more where the step makes
    /// a patch's error worse (crossing into the other sign), more against requested directions.
    fn step(&self, state: &State, mode: Mode, u: usize, v: usize, border: usize, way: Way) -> f64 {
        // Cheaper through patches whose error has the sign this path fixes, dearer through
        // the others ("following patches with high same-sign errors", section 4.2).
        let e = self.errors[v] / self.quantum;
        let base = match mode {
            Mode::Add => 1.0 + e,
            Mode::Remove => 1.0 - e,
            Mode::Reverse => 1.0,
        }
        .max(MIN_STEP);
        let step = state.normal(border, way);
        let against: f64 = [u, v]
            .iter()
            .filter_map(|&x| state.graph.patches[x].direction)
            .map(|d| {
                let cos = d.dir.dot(step);
                let w = d.weight.min(1.0);
                match mode {
                    Mode::Add => w * (1.0 - cos) / 2.0,
                    Mode::Remove | Mode::Reverse => w * (1.0 + cos) / 2.0,
                }
            })
            .sum();
        let mut cost = base + self.direction_gain * against;
        let exists = || state.crossings[border].iter().any(|c| c.way == way);
        if matches!(mode, Mode::Remove | Mode::Reverse) && !exists() {
            cost = BLOCKED;
        }
        if matches!(mode, Mode::Add) && state.measured[v].density + self.room > self.rho_max {
            cost = BLOCKED;
        }
        cost
    }
}

/// The cheapest path from `from` to `to` (not using the edge `forbid`, if given).
pub fn path(
    state: &State,
    net: &Net,
    costs: &Costs,
    mode: Mode,
    from: usize,
    to: usize,
    forbid: Option<(usize, usize)>,
) -> Option<Vec<Step>> {
    let cell = |u: usize| state.graph.patches[u].cell;
    let goal = cell(to);
    let (cost, nodes) = astar(
        &net.graph,
        NodeIndex::new(from),
        |n| n.index() == to,
        |e| {
            let (u, v) = (e.source().index(), e.target().index());
            if forbid == Some((u, v)) {
                return BLOCKED;
            }
            let (border, way) = *e.weight();
            costs.step(state, mode, u, v, border, way)
        },
        |n| {
            let c = cell(n.index());
            (c.col.abs_diff(goal.col) + c.row.abs_diff(goal.row)) as f64 * MIN_STEP
        },
    )?;
    if cost >= BLOCKED {
        return None;
    }
    Some(
        nodes
            .windows(2)
            .map(|w| {
                let (u, v) = (w[0].index(), w[1].index());
                let link = state.links[u]
                    .iter()
                    .find(|l| l.to == v)
                    .expect("an edge of the net");
                Step {
                    from: u,
                    to: v,
                    border: link.border,
                    way: link.way,
                }
            })
            .collect(),
    )
}

/// A circular path through the optima of a group: O1 -> O2 -> ... -> Ok -> O1. A lone optimum
/// leaves towards the neighbour its requested direction (or its error) favours most and comes
/// back another way if it can, the way back through that neighbour otherwise.
pub fn cycle(
    state: &State,
    net: &Net,
    costs: &Costs,
    mode: Mode,
    group: &[usize],
) -> Option<Vec<Step>> {
    if group.len() >= 2 {
        let mut steps = Vec::new();
        for (i, &a) in group.iter().enumerate() {
            let b = group[(i + 1) % group.len()];
            steps.extend(path(state, net, costs, mode, a, b, None)?);
        }
        return Some(steps);
    }
    let o = group[0];
    let first = state.links[o]
        .iter()
        .map(|l| (costs.step(state, mode, o, l.to, l.border, l.way), l))
        .filter(|(c, _)| *c < BLOCKED)
        .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.to.cmp(&b.1.to)))?
        .1;
    let out = crate::mutate::Step {
        from: o,
        to: first.to,
        border: first.border,
        way: first.way,
    };
    let back = if state.graph.patches[o].direction.is_some() {
        path(state, net, costs, mode, first.to, o, Some((first.to, o)))
            .filter(|p| p.len() <= 400)
            .or_else(|| path(state, net, costs, mode, first.to, o, None))
    } else {
        path(state, net, costs, mode, first.to, o, None)
    }?;
    let mut steps = vec![out];
    steps.extend(back);
    Some(steps)
}

/// Alignment gained by turning a crossing of way `way` on `border` around: positive when it
/// ran against the requested directions of its two patches.
pub fn reversal_gain(state: &State, from: usize, to: usize, border: usize, way: Way) -> f64 {
    let step = state.normal(border, way);
    [from, to]
        .iter()
        .filter_map(|&x| state.graph.patches[x].direction)
        .map(|d| -2.0 * d.weight.min(1.0) * d.dir.dot(step))
        .sum()
}

/// For a directed patch, the crossing through it that runs most against its direction, as the
/// step it makes, if any does.
pub fn most_misaligned(state: &State, patch: usize) -> Option<Step> {
    let d = state.graph.patches[patch].direction?;
    let mut best: Option<(f64, Step)> = None;
    for l in &state.links[patch] {
        for c in &state.crossings[l.border] {
            let (from, to) = if c.way == l.way {
                (patch, l.to)
            } else {
                (l.to, patch)
            };
            let cos = d.dir.dot(state.normal(l.border, c.way));
            if cos < -0.1 && best.is_none_or(|(b, _)| cos < b) {
                best = Some((
                    cos,
                    Step {
                        from,
                        to,
                        border: l.border,
                        way: c.way,
                    },
                ));
            }
        }
    }
    best.map(|(_, s)| s)
}

/// A cycle of existing crossings through `first` whose reversal turns the flow towards the
/// requested directions: `first`, then the cheapest way back through existing crossings (never
/// straight back over the same border).
pub fn reversal_cycle(state: &State, net: &Net, costs: &Costs, first: Step) -> Option<Vec<Step>> {
    let back = path(
        state,
        net,
        costs,
        Mode::Reverse,
        first.to,
        first.from,
        Some((first.to, first.from)),
    )?;
    let mut cycle = vec![first];
    cycle.extend(back);
    let gain: f64 = cycle
        .iter()
        .map(|s| reversal_gain(state, s.from, s.to, s.border, s.way))
        .sum();
    (gain > 0.0).then_some(cycle)
}
