//! Stage 3, optimize: [`PatchGraph`] in, [`Patterns`] out (Crowd Art Algorithm 1).
//!
//! Entry and exit points ("crossings") live on the open intervals of shared borders. The start
//! gives every border as many crossings each way as the density regression ([`regression`])
//! asks for its two patches. Then each step of the loop measures every changed patch with the
//! stage-4 matching, computes the signed error e(u) (eq. 7), finds its local maxima and minima,
//! groups nearby optima of a component, finds minimum-cost circular paths through each group
//! (petgraph A*) and removes (maxima) or adds (minima) one crossing per step of the path, so
//! parity always holds. The loop keeps the best state and stops when E has not improved by
//! more than `tolerance` in `patience` steps (converged) or at `max_iterations` (not). A
//! [`polish`] (exact local search over small cycles, each change kept only if E falls) then
//! finishes what the loop's signed error cannot see, such as sideways traffic through a
//! directed patch; its rounds count as iterations in the log.

pub mod align;
pub mod known;
pub mod mutate;
pub mod polish;
pub mod region;
pub mod regression;
pub mod retime;
pub mod search;
pub mod shard;
pub mod spacing;
pub mod state;

use crowd_core::config::{MatchSettings, OptimizeSettings};
use crowd_core::patterns::{
    Crossing, IterationFigures, Measured, PatchError, Regression, SceneError,
};
use crowd_core::{PatchGraph, Progress};
use glam::DVec2;
use mutate::Step;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use region::{Cut, Region, RegionInputs, SeamRule, Solved, Sums};
use search::{Costs, Mode, Net};
use state::State;

/// Paths per step: one per this many patches of a component, plus one (the paper: 400).
const PATCHES_PER_PATH: usize = 40;
/// Optima within this many cells (Manhattan) may share a group, up to this many per group.
const GROUP_RADIUS: u32 = 4;
const GROUP_SIZE: usize = 3;
/// Steps between re-timings of the walkers' loops (see [`retime`]).
const RETIME_EVERY: u32 = 20;
/// Re-timing changes durations, so density: the last one leaves the loop time to settle.
const RETIME_UNTIL: u32 = 60;
/// Rounds of [`polish`] at most, after the loop.
const POLISH_ROUNDS: u32 = 40;

/// Everything stage 3 decides.
pub struct Outcome {
    /// Sorted by border, then time.
    pub crossings: Vec<Crossing>,
    pub measured: Vec<Measured>,
    pub error: SceneError,
    pub worst: Vec<PatchError>,
    pub regression: Regression,
    pub log: Vec<IterationFigures>,
    pub iterations: u32,
    pub converged: bool,
    /// Regions the world was cut into, and how many of them were taken from an earlier build.
    pub regions: usize,
    pub reused: usize,
    /// Every region's result, for the next build to reuse ([`Known`]).
    pub solved: Vec<Solved>,
    /// Where the world's crossings are in `solved` and the seams, before (or without) their
    /// list: [`Outcome::visit_crossings`].
    listing: Listing,
}

impl Outcome {
    /// How many crossings the world has.
    pub fn crossing_count(&self) -> usize {
        self.listing.count
    }

    /// Every crossing of the world in its list's order (by border, then time), with its
    /// number, without putting the list together: a shard keeps only its window of it, and
    /// `patterns.bin` is written from it (the million's list is 0.1 GB).
    pub fn visit_crossings(&self, mut visit: impl FnMut(u32, &Crossing)) {
        let mut k = 0u32;
        let mut border = Vec::new();
        let entries = &self.listing.entries;
        let mut i = 0;
        while i < entries.len() {
            let b = entries[i].border;
            border.clear();
            // One border's crossings from every source that has some (seams first, then the
            // regions in order), then sorted by time: the stable sort by border and time of
            // all of them one after the other, one border at a time.
            while i < entries.len() && entries[i].border == b {
                let e = &entries[i];
                let list = match e.source {
                    Source::Seam => &self.listing.seams[b as usize][..],
                    Source::Region(r) => &self.solved[r as usize].crossings,
                };
                let run = &list[e.start as usize..(e.start + e.count) as usize];
                border.extend(run.iter().map(|c| Crossing { border: b, ..*c }));
                i += 1;
            }
            border.sort_by(|a, b| a.t.total_cmp(&b.t));
            for c in &border {
                visit(k, c);
                k += 1;
            }
        }
    }

    /// The world's list of crossings.
    pub fn list_crossings(&self) -> Vec<Crossing> {
        let mut list = Vec::with_capacity(self.listing.count);
        self.visit_crossings(|_, c| list.push(*c));
        list
    }
}

/// Where each border's crossings are: in the seams (by world border) or in a region's result
/// (a run of its crossings, in its own numbering of borders), in the world's border order.
#[derive(Debug, Clone, Default)]
struct Listing {
    seams: Vec<Vec<Crossing>>,
    entries: Vec<Entry>,
    count: usize,
}

#[derive(Debug, Clone, Copy)]
struct Entry {
    border: u32,
    source: Source,
    start: u32,
    count: u32,
}

#[derive(Debug, Clone, Copy)]
enum Source {
    Seam,
    Region(u32),
}

impl Listing {
    /// The listing of the seams' crossings and the regions' (`placed[r]` maps region `r`'s
    /// borders to the world's).
    fn new(seams: Vec<Vec<Crossing>>, placed: &[&Placed], solved: &[&Solved]) -> Listing {
        let mut entries = Vec::new();
        for (b, list) in seams.iter().enumerate() {
            if !list.is_empty() {
                entries.push(Entry {
                    border: b as u32,
                    source: Source::Seam,
                    start: 0,
                    count: list.len() as u32,
                });
            }
        }
        for (r, (place, solved)) in placed.iter().zip(solved).enumerate() {
            let list = &solved.crossings;
            let mut start = 0;
            while start < list.len() {
                let local = list[start].border;
                let end = start + list[start..].partition_point(|c| c.border == local);
                entries.push(Entry {
                    border: place.borders[local as usize] as u32,
                    source: Source::Region(r as u32),
                    start: start as u32,
                    count: (end - start) as u32,
                });
                start = end;
            }
        }
        // Stable: a border's runs stay in the order of the sources (seams, then regions).
        entries.sort_by_key(|e| e.border);
        let count = entries.iter().map(|e| e.count as usize).sum();
        Listing {
            seams,
            entries,
            count,
        }
    }
}

/// A patch's two error terms: requested minus measured density, and, if the patch asks for a
/// direction, 1 - cos of the angle between the requested and the measured one. Every figure
/// of E is built from these.
pub fn patch_terms(patch: &crowd_core::Patch, requested: f64, m: &Measured) -> (f64, Option<f64>) {
    let direction = patch
        .direction
        .map(|d| 1.0 - d.dir.dot(m.direction.unwrap_or(DVec2::ZERO)));
    (requested - m.density, direction)
}

impl Sums {
    /// E_rho, E_d and E (Crowd Art eq. 4-6) of the summed patches.
    pub fn error(&self, rho_max: f64) -> SceneError {
        let e_rho = (self.squares / self.patches.max(1) as f64).sqrt() / rho_max;
        let e_d = if self.directed > 0 {
            self.direction / self.directed as f64
        } else {
            0.0
        };
        SceneError {
            e_rho,
            e_d,
            e: e_rho + e_d,
        }
    }
}

/// E_rho, E_d and E (Crowd Art eq. 4-6) of measured patches.
pub fn scene_error(
    graph: &PatchGraph,
    requested: &[f64],
    measured: &[Measured],
    rho_max: f64,
) -> SceneError {
    let n = measured.len().max(1) as f64;
    let (mut squares, mut sum, mut count) = (0.0, 0.0, 0usize);
    for (p, (&r, m)) in graph.patches.iter().zip(requested.iter().zip(measured)) {
        let (density, direction) = patch_terms(p, r, m);
        squares += density.powi(2);
        if let Some(d) = direction {
            sum += d;
            count += 1;
        }
    }
    let e_rho = (squares / n).sqrt() / rho_max;
    let e_d = if count > 0 { sum / count as f64 } else { 0.0 };
    SceneError {
        e_rho,
        e_d,
        e: e_rho + e_d,
    }
}

/// The `count` patches whose error is largest (density error in units of rho_max plus
/// direction error), worst first.
pub fn worst_patches(
    graph: &PatchGraph,
    requested: &[f64],
    measured: &[Measured],
    rho_max: f64,
    count: usize,
) -> Vec<PatchError> {
    let mut all: Vec<(f64, PatchError)> = graph
        .patches
        .iter()
        .zip(requested.iter().zip(measured))
        .map(|(p, (&r, m))| {
            let (density, direction_error) = patch_terms(p, r, m);
            let size = density.abs() / rho_max + direction_error.unwrap_or(0.0);
            let e = PatchError {
                patch: p.id,
                cell: p.cell,
                requested: r,
                measured: m.density,
                direction_error,
            };
            (size, e)
        })
        .collect();
    all.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.patch.cmp(&b.1.patch)));
    all.into_iter().take(count).map(|(_, e)| e).collect()
}

/// Standing characters per patch: the requested stander densities rounded so that they add up
/// to exactly the requested number (rounding the running total, patch by patch).
pub fn stander_counts(graph: &PatchGraph) -> Vec<u32> {
    let area = graph.patch_area();
    let mut total = 0.0;
    let mut placed = 0i64;
    graph
        .patches
        .iter()
        .map(|p| {
            total += p.stander_density * area;
            let n = total.round() as i64 - placed;
            placed += n;
            n.max(0) as u32
        })
        .collect()
}

/// Runs the optimisation. Deterministic for a seed, whatever the thread count.
pub fn optimize(
    graph: &PatchGraph,
    settings: &OptimizeSettings,
    matching: &MatchSettings,
    period_s: f64,
    seed: u64,
    progress: &dyn Progress,
) -> Outcome {
    optimize_reusing(
        graph,
        settings,
        matching,
        period_s,
        seed,
        Known::new(),
        progress,
    )
}

/// Regions solved by an earlier build, by their [`Region::hash`].
pub type Known = std::collections::HashMap<crowd_core::Hash, Solved>;

/// [`optimize`], taking every region whose hash is in `known` from there instead of solving it
/// again: the same result, since a region's hash holds everything its result depends on.
/// Each result taken is moved out of `known`, not copied: the million's regions, decoded,
/// are 0.2 GB.
pub fn optimize_reusing(
    graph: &PatchGraph,
    settings: &OptimizeSettings,
    matching: &MatchSettings,
    period_s: f64,
    seed: u64,
    known: Known,
    progress: &dyn Progress,
) -> Outcome {
    let at = (period_s, seed);
    let mut outcome = solve_world(graph, settings, matching, at, known, progress);
    outcome.crossings = outcome.list_crossings();
    outcome
}

/// [`optimize_reusing`] without the world's list of crossings (`Outcome::crossings` is left
/// empty): what stage 3 writes is visited in the list's order ([`Outcome::visit_crossings`]),
/// and a shard keeps only its window of it.
pub fn solve_world(
    graph: &PatchGraph,
    settings: &OptimizeSettings,
    matching: &MatchSettings,
    (period_s, seed): (f64, u64),
    known: Known,
    progress: &dyn Progress,
) -> Outcome {
    let world = World::new(graph, settings, matching, period_s, seed);
    let solved = world.solve(0..world.cut.regions.len(), known, progress);
    let World {
        regression,
        standers,
        seams,
        ..
    } = world;
    gather(
        graph,
        settings.rho_max,
        regression,
        &standers,
        seams,
        solved,
    )
}

/// Only the regions `part` of the world's cut (numbered as [`region::Cut`] lists them), each
/// taken from `known` or solved: a shard's share of stage 3 ([`shard`]). Every region's result
/// depends on it alone (its seams are held by a rule), so these are the results
/// [`optimize_reusing`] would find for them.
pub fn solve_part(
    graph: &PatchGraph,
    settings: &OptimizeSettings,
    matching: &MatchSettings,
    (period_s, seed): (f64, u64),
    part: std::ops::Range<usize>,
    known: Known,
    progress: &dyn Progress,
) -> Vec<(Solved, bool)> {
    let world = World::new(graph, settings, matching, period_s, seed);
    let part = part.start.min(world.cut.regions.len())..part.end.min(world.cut.regions.len());
    (world.solve(part, known, progress).into_iter())
        .map(|(_, solved, reused)| (solved, reused))
        .collect()
}

/// Where a solved region lies in the world: [`Region`]'s numbering of its patches and borders,
/// and which patches are its own.
struct Placed {
    own: Vec<bool>,
    patches: Vec<usize>,
    borders: Vec<usize>,
}

/// What every region of a world is solved against: the density regression, the cut into
/// regions, the standers and the seams' crossings (held by a rule, so that regions are
/// independent).
struct World<'a> {
    graph: &'a PatchGraph,
    settings: &'a OptimizeSettings,
    matching: &'a MatchSettings,
    period_s: f64,
    seed: u64,
    regression: Regression,
    cut: Cut,
    standers: Vec<u32>,
    seams: Vec<Vec<Crossing>>,
}

impl<'a> World<'a> {
    fn new(
        graph: &'a PatchGraph,
        settings: &'a OptimizeSettings,
        matching: &'a MatchSettings,
        period_s: f64,
        seed: u64,
    ) -> World<'a> {
        let side = graph.world.patch_side_m;
        let regression = regression::fit(side, period_s, matching, 60, seed);
        let cut = Cut::new(graph, settings.region_patches);
        let standers = region::stander_counts(graph, &cut);
        let rule = SeamRule {
            regression: &regression,
            rho_max: settings.rho_max,
            matching,
            period_s,
            seed,
        };
        let seams = region::seam_crossings(graph, &cut, &rule);
        World {
            graph,
            settings,
            matching,
            period_s,
            seed,
            regression,
            cut,
            standers,
            seams,
        }
    }

    /// The regions `part` of the cut, each from `known` (then `true`) or solved, in order;
    /// each with where it lies in the world (its problem, a copy of its part of the graph, let
    /// go as soon as it is solved).
    fn solve(
        &self,
        part: std::ops::Range<usize>,
        known: Known,
        progress: &dyn Progress,
    ) -> Vec<(Placed, Solved, bool)> {
        let known = std::sync::Mutex::new(known);
        let inputs = RegionInputs {
            settings: self.settings,
            matching: self.matching,
            period_s: self.period_s,
            seed: self.seed,
            regression: &self.regression,
        };
        progress.begin("optimize", part.len() as u64);
        self.cut.regions[part]
            .par_iter()
            .map(|r| {
                let region = Region::new(self.graph, r, &self.standers, &self.seams, self.cut.side);
                let hash = region.hash(&inputs);
                let taken = known
                    .lock()
                    .expect("no thread panics holding it")
                    .remove(&hash);
                let (solved, reused) = match taken {
                    Some(s) => (s, true),
                    None => (solve(&region, hash, &inputs), false),
                };
                progress.advance(1);
                let Region {
                    own,
                    patches,
                    borders,
                    ..
                } = region;
                let placed = Placed {
                    own,
                    patches,
                    borders,
                };
                (placed, solved, reused)
            })
            .collect()
    }
}

/// One region optimised (Algorithm 1 with its seams held, then the polish).
pub fn solve(region: &Region, hash: crowd_core::Hash, inputs: &RegionInputs) -> Solved {
    let mut state = State::with_held(
        &region.graph,
        inputs.matching,
        inputs.period_s,
        region.standers.clone(),
        region.own.clone(),
        region.held.clone(),
    );
    for (l, seam) in region.seams.iter().enumerate() {
        if region.held[l] {
            state.crossings[l] = seam.clone();
        }
    }
    let seed = region::seed_at(inputs.seed, region.block, 0);
    let run = run(&mut state, inputs.regression, inputs.settings, seed);
    let crossings = state
        .crossings
        .iter()
        .enumerate()
        .filter(|(l, _)| !region.held[*l])
        .flat_map(|(_, list)| list.iter().copied())
        .collect();
    let measured = state
        .own_patches()
        .into_iter()
        .map(|p| state.measured[p])
        .collect();
    Solved {
        hash,
        crossings,
        measured,
        log: run.log,
        iterations: run.iterations,
        converged: run.converged,
    }
}

/// The world's result from its regions' (each in its own numbering) and the seams.
fn gather(
    graph: &PatchGraph,
    rho_max: f64,
    regression: Regression,
    standers: &[u32],
    seams: Vec<Vec<Crossing>>,
    regions: Vec<(Placed, Solved, bool)>,
) -> Outcome {
    let unmeasured = Measured {
        density: 0.0,
        direction: None,
        standers: 0,
    };
    let mut measured = vec![unmeasured; graph.patches.len()];
    let seam_count = seams.iter().map(Vec::len).sum::<usize>() as u64;
    let listing = {
        let placed: Vec<&Placed> = regions.iter().map(|r| &r.0).collect();
        let solved: Vec<&Solved> = regions.iter().map(|r| &r.1).collect();
        Listing::new(seams, &placed, &solved)
    };
    let steps = regions.iter().map(|r| r.1.log.len()).max().unwrap_or(1);
    let mut log = vec![Sums::default(); steps];
    let (mut iterations, mut converged, mut reused) = (0, true, 0);
    for (region, solved, was_reused) in &regions {
        let own = (0..region.own.len()).filter(|&l| region.own[l]);
        for (l, m) in own.zip(&solved.measured) {
            measured[region.patches[l]] = *m;
        }
        for (i, sums) in log.iter_mut().enumerate() {
            if let Some(s) = solved.log.get(i).or(solved.log.last()) {
                *sums += *s;
            }
        }
        iterations = iterations.max(solved.iterations);
        converged &= solved.converged;
        reused += usize::from(*was_reused);
    }
    let area = graph.patch_area();
    let requested: Vec<f64> = graph
        .patches
        .iter()
        .zip(standers)
        .map(|(p, &s)| p.walker_density + s as f64 / area)
        .collect();
    let log = log
        .into_iter()
        .enumerate()
        .map(|(i, sums)| {
            let e = sums.error(rho_max);
            IterationFigures {
                iteration: i as u32,
                e_rho: e.e_rho,
                e_d: e.e_d,
                e: e.e,
                crossings: sums.crossings + seam_count,
            }
        })
        .collect();
    Outcome {
        error: scene_error(graph, &requested, &measured, rho_max),
        worst: worst_patches(graph, &requested, &measured, rho_max, 10),
        crossings: Vec::new(),
        measured,
        regression,
        log,
        iterations,
        converged,
        regions: regions.len(),
        reused,
        solved: regions.into_iter().map(|r| r.1).collect(),
        listing,
    }
}

/// What [`run`] leaves besides the state: the error sums of every step and how it stopped.
struct Run {
    log: Vec<Sums>,
    iterations: u32,
    converged: bool,
}

/// The error sums of a state's own patches (crossings: those it may change).
fn sums(state: &State) -> Sums {
    let mut sums = Sums::default();
    for p in state.own_patches() {
        let patch = &state.graph.patches[p];
        let (density, direction) = patch_terms(patch, state.requested[p], &state.measured[p]);
        sums.squares += density * density;
        sums.patches += 1;
        if let Some(d) = direction {
            sums.direction += d;
            sums.directed += 1;
        }
    }
    sums.crossings = (0..state.crossings.len())
        .filter(|&k| !state.held[k])
        .map(|k| state.crossings[k].len() as u64)
        .sum();
    sums
}

/// Algorithm 1 on one state: the start, the loop of steps until E settles, the alignment and
/// the polish.
fn run(state: &mut State, regression: &Regression, settings: &OptimizeSettings, seed: u64) -> Run {
    let rho_max = settings.rho_max;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    start(state, regression, rho_max, &mut rng);
    retime::retime(state);
    enforce_rho_max(state, rho_max);
    let net = Net::new(state);

    let mut log = vec![sums(state)];
    let mut best = (log[0].error(rho_max).e, state.crossings.clone(), 0u32);
    let mut converged = false;
    let mut iterations = 0;
    for iteration in 1..=settings.max_iterations {
        iterations = iteration;
        if iteration % RETIME_EVERY == 0 && iteration <= RETIME_UNTIL {
            retime::retime(state);
            enforce_rho_max(state, rho_max);
        }
        step(state, &net, regression, settings, iteration, seed);
        let f = sums(state);
        log.push(f);
        let e = f.error(rho_max).e;
        // Copied into the best state's own lists (no allocation per border): each copy of
        // painting's 250,000 crossings was a pause of the other core.
        if e < best.0 - settings.tolerance {
            (best.0, best.2) = (e, iteration);
            best.1.clone_from(&state.crossings);
        } else if e < best.0 {
            best.0 = e;
            best.1.clone_from(&state.crossings);
        }
        if iteration - best.2 >= settings.patience {
            converged = true;
            break;
        }
    }
    state.crossings = best.1;
    state.remeasure_all();
    enforce_rho_max(state, rho_max);
    // Velocities are turned towards the lines before the polish, and the crossings it adds
    // after: a pair's least time depends on its band pieces (stage 4 adds a period where they
    // leave the way too little time at max_speed), so what the polish measures is what ships.
    align::align(state);
    state.remeasure_all();
    enforce_rho_max(state, rho_max);
    polish::polish(
        state,
        rho_max,
        POLISH_ROUNDS,
        settings.tolerance,
        seed,
        |state| {
            iterations += 1;
            log.push(sums(state));
        },
    );
    if align::align(state) > 0 {
        state.remeasure_all();
        enforce_rho_max(state, rho_max);
    }
    settle_rho_max(state, rho_max);
    Run {
        log,
        iterations,
        converged,
    }
}

/// Entry pairs per patch that the regression predicts for a density (at most rho_max).
pub(crate) fn pairs_for(density: f64, regression: &Regression, rho_max: f64) -> f64 {
    ((density.min(rho_max) - regression.intercept) / regression.slope).max(0.0)
}

/// The start: on every open border not held, as many crossings each way as the two patches
/// need on average per border (balanced, so parity holds), then nothing above rho_max.
fn start(state: &mut State, regression: &Regression, rho_max: f64, rng: &mut ChaCha8Rng) {
    let need: Vec<f64> = (0..state.links.len())
        .map(|p| {
            let walkers = state.graph.patches[p].walker_density;
            pairs_for(walkers, regression, rho_max) / state.open_borders(p).max(1) as f64
        })
        .collect();
    for (k, b) in state.graph.borders.iter().enumerate() {
        if b.open.is_empty() || state.held[k] {
            continue;
        }
        let pairs = ((need[b.a.0 as usize] + need[b.b.0 as usize]) / 2.0).round() as u32;
        mutate::add_pairs(state, k, pairs, rng);
    }
    state.remeasure_all();
    enforce_rho_max(state, rho_max);
}

/// Takes crossings out of every patch above rho_max until it is not: a cycle of existing
/// crossings through the patch at a time (the shortest one), so parity holds.
fn enforce_rho_max(state: &mut State, rho_max: f64) {
    let _ = enforce_pass(state, rho_max);
}

/// [`enforce_rho_max`] in passes until one takes nothing out: taking a cycle out re-matches
/// the patches it runs through, and a patch already passed may come out denser (seed
/// 1791716007936587886 of the constraints' proptest, 375 walkers: patch 8 at 0.3517 after one
/// pass). Each pass that goes on took crossings out, so this ends. Run once at the end: the
/// passes in between are a step of the search, which later steps clean up after.
fn settle_rho_max(state: &mut State, rho_max: f64) {
    while enforce_pass(state, rho_max) {}
}

/// One pass of [`enforce_rho_max`]; whether it took anything out.
fn enforce_pass(state: &mut State, rho_max: f64) -> bool {
    let mut removed = false;
    for p in 0..state.links.len() {
        while state.measured[p].density > rho_max {
            let Some(cycle) = cycle_through(state, p) else {
                break;
            };
            mutate::remove_cycle(state, &cycle);
            removed = true;
            let mut touched: Vec<usize> = cycle.iter().map(|s| s.to).collect();
            touched.sort_unstable();
            touched.dedup();
            state.remeasure(&touched);
        }
    }
    removed
}

/// The shortest cycle of existing crossings through patch `p` (breadth-first), if `p` has
/// any exit. One exists whenever `p` has an exit, since parity holds everywhere.
fn cycle_through(state: &State, p: usize) -> Option<Vec<Step>> {
    use std::collections::{HashMap, VecDeque};
    let exits = |u: usize| {
        state.links[u]
            .iter()
            .filter(move |l| state.crossings[l.border].iter().any(|c| c.way == l.way))
    };
    let mut came_from: HashMap<usize, Step> = HashMap::new();
    let mut queue = VecDeque::from([p]);
    while let Some(u) = queue.pop_front() {
        for l in exits(u) {
            let step = Step {
                from: u,
                to: l.to,
                border: l.border,
                way: l.way,
            };
            if l.to == p {
                let mut steps = vec![step];
                let mut at = u;
                while at != p {
                    let back = came_from[&at];
                    steps.push(back);
                    at = back.from;
                }
                steps.reverse();
                return Some(steps);
            }
            if l.to != p
                && let std::collections::hash_map::Entry::Vacant(e) = came_from.entry(l.to)
            {
                e.insert(step);
                queue.push_back(l.to);
            }
        }
    }
    None
}

/// One step of Algorithm 1 over every component.
fn step(
    state: &mut State,
    net: &Net,
    regression: &Regression,
    settings: &OptimizeSettings,
    iteration: u32,
    seed: u64,
) {
    let rho_max = settings.rho_max;
    let errors = search::signed_errors(state, rho_max, regression.slope);
    let quantum = regression.slope / rho_max;
    let costs = Costs {
        errors: &errors,
        room: regression.slope,
        rho_max,
        quantum,
        direction_gain: 30.0,
    };
    // Every component gets its own budget of paths per step.
    let mut sizes = vec![0usize; state.graph.components.len()];
    for p in &state.graph.patches {
        sizes[p.component as usize] += 1;
    }
    let budget = |component: u32| sizes[component as usize] / PATCHES_PER_PATH + 1;
    let choose = |mode: Mode| -> Vec<Vec<usize>> {
        let optima = search::optima(state, &errors, mode, quantum / 2.0);
        search::groups(state, &optima, (GROUP_RADIUS, GROUP_SIZE), budget)
    };
    let (maxima, minima) = rayon::join(|| choose(Mode::Remove), || choose(Mode::Add));
    // Paths are found in parallel on this step's snapshot, then applied in order.
    let find = |groups: &[Vec<usize>], mode: Mode| -> Vec<Option<Vec<Step>>> {
        groups
            .par_iter()
            .map(|g| search::cycle(state, net, &costs, mode, g))
            .collect()
    };
    let (removals, additions) = (find(&maxima, Mode::Remove), find(&minima, Mode::Add));
    let mut rng =
        ChaCha8Rng::seed_from_u64(seed ^ (iteration as u64).wrapping_mul(0xA076_1D64_78BD_642F));
    let mut dirty = Vec::new();
    for cycle in removals.into_iter().flatten() {
        if mutate::can_remove(state, &cycle) {
            mutate::remove_cycle(state, &cycle);
            dirty.extend(cycle.iter().map(|s| s.to));
        }
    }
    add_in_waves(state, additions.into_iter().flatten(), rho_max, &mut rng);
    dirty.sort_unstable();
    dirty.dedup();
    state.remeasure(&dirty);
    turn_around(state, net, &costs, &sizes);
    // Re-matching after removals and turns can lengthen a patch's pairs: never above rho_max.
    enforce_rho_max(state, rho_max);
}

/// Adds each cycle in turn, taking it back if it leaves a patch above rho_max, as if one at a
/// time. A cycle's patches are measured only with the cycles around it that share none of its
/// patches (a wave): cycles that share no patch share no border either, so neither what one
/// adds nor what it takes back changes the other's measurement or the slots it finds, and the
/// wave's measurements run in parallel (painting's steps spent two thirds of their time
/// measuring one cycle after another).
fn add_in_waves(
    state: &mut State,
    cycles: impl Iterator<Item = Vec<Step>>,
    rho_max: f64,
    rng: &mut ChaCha8Rng,
) {
    struct Added {
        cycle: Vec<Step>,
        before: Vec<usize>,
    }
    let mut busy = vec![false; state.links.len()];
    let mut wave: Vec<Added> = Vec::new();
    let settle = |state: &mut State, wave: &mut Vec<Added>, busy: &mut [bool]| {
        let touched: Vec<usize> = wave
            .iter()
            .flat_map(|a| a.cycle.iter().map(|s| s.to))
            .collect();
        state.remeasure(&touched);
        let mut again = Vec::new();
        for a in wave.drain(..) {
            if a.cycle
                .iter()
                .any(|s| state.measured[s.to].density > rho_max)
            {
                // Never above rho_max: take the cycle back.
                for (s, &n) in a.cycle.iter().zip(&a.before) {
                    state.crossings[s.border].truncate(n);
                }
                again.extend(a.cycle.iter().map(|s| s.to));
            }
        }
        state.remeasure(&again);
        for p in touched {
            busy[p] = false;
        }
    };
    for cycle in cycles {
        if cycle.iter().any(|s| busy[s.to]) {
            settle(state, &mut wave, &mut busy);
        }
        let before: Vec<usize> = cycle
            .iter()
            .map(|s| state.crossings[s.border].len())
            .collect();
        if mutate::add_cycle(state, &cycle, rng) {
            for s in &cycle {
                busy[s.to] = true;
            }
            wave.push(Added { cycle, before });
        }
    }
    settle(state, &mut wave, &mut busy);
}

/// Density-neutral direction fixing: in the directed patches whose direction is furthest off,
/// turn around a cycle of existing crossings that runs against the requested directions.
fn turn_around(state: &mut State, net: &Net, costs: &Costs, sizes: &[usize]) {
    let off = |p: usize| {
        let d = state.graph.patches[p].direction.expect("directed");
        let m = state.measured[p].direction.unwrap_or(DVec2::ZERO);
        (1.0 - d.dir.dot(m)) * d.weight.min(1.0)
    };
    let mut directed: Vec<usize> = (0..state.links.len())
        .filter(|&p| state.graph.patches[p].direction.is_some() && off(p) > 0.05)
        .collect();
    directed.sort_by(|&a, &b| off(b).total_cmp(&off(a)).then(a.cmp(&b)));
    let _ = sizes;
    let starts: Vec<Step> = directed
        .iter()
        .filter_map(|&p| search::most_misaligned(state, p))
        .collect();
    let cycles: Vec<Option<Vec<Step>>> = starts
        .par_iter()
        .map(|&first| search::reversal_cycle(state, net, costs, first))
        .collect();
    let mut dirty = Vec::new();
    for cycle in cycles.into_iter().flatten() {
        if mutate::reverse_cycle(state, &cycle) {
            dirty.extend(cycle.iter().map(|s| s.to));
        }
    }
    dirty.sort_unstable();
    dirty.dedup();
    state.remeasure(&dirty);
}

/// What stage 3 reads of a pipeline besides the graph.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Inputs {
    pub period_s: f64,
    pub seed: u64,
    pub settings: OptimizeSettings,
    pub matching: MatchSettings,
}

pub fn inputs(pipeline: &crowd_core::config::PipelineFile) -> Inputs {
    let p = &pipeline.pipeline;
    Inputs {
        period_s: p.period_s,
        seed: p.seed,
        settings: p.optimize.clone(),
        matching: p.matching.clone(),
    }
}

/// The hash of stage 3's inputs: the graph file (its bytes' hash) and the settings.
pub fn input_hash(graph_file: &crowd_core::Hash, inputs: &Inputs) -> crowd_core::Hash {
    crowd_core::Hasher::new(
        crowd_core::patterns::Patterns::STAGE,
        crowd_core::patterns::Patterns::VERSION,
    )
    .file_hash("graph file", graph_file)
    .value("inputs", inputs)
    .finish()
}

/// The cache of every region's result, beside `patterns.ron` ([`known`]).
pub const REGIONS_FILE: &str = "regions.bin";

/// Stage 3's files beside `out`: the crossings side file, streamed to its temporary name
/// (the million's is 85 MB: held as bytes beside the crossings, it was a third of the
/// stage's peak), then `patterns.ron` and the per-step figures as CSV (`optimize.csv`),
/// encoded. The regions' cache is [`write_regions`]'.
pub fn encode(
    out: &std::path::Path,
    outcome: &Outcome,
    inputs: &Inputs,
    hash: crowd_core::Hash,
) -> crowd_core::Result<(
    crowd_core::patterns::Patterns,
    crowd_core::files::StreamedFile,
    crowd_core::files::Writes,
)> {
    use crowd_core::files::{Header, SideFile};
    let side = crowd_core::files::Streamed::written_by(&out.with_extension("bin"), |w| {
        use crowd_core::patterns::{write_crossing, write_crossings_header};
        write_crossings_header(w, outcome.crossing_count())?;
        let mut written = Ok(());
        outcome.visit_crossings(|_, c| {
            if written.is_ok() {
                written = write_crossing(w, c);
            }
        });
        written
    })?;
    let patterns = crowd_core::patterns::Patterns {
        header: Header::new(
            crowd_core::patterns::Patterns::STAGE,
            crowd_core::patterns::Patterns::VERSION,
            hash,
        ),
        period_s: inputs.period_s,
        rho_max: inputs.settings.rho_max,
        seed: inputs.seed,
        iterations: outcome.iterations,
        converged: outcome.converged,
        error: outcome.error,
        worst: outcome.worst.clone(),
        regression: outcome.regression,
        log: outcome.log.clone(),
        measured: outcome.measured.clone(),
        crossings: SideFile::streamed(&side),
    };
    let mut csv = String::from("iteration,E_rho,E_d,E,crossings\n");
    for f in &outcome.log {
        csv += &format!(
            "{},{:.6},{:.6},{:.6},{}\n",
            f.iteration, f.e_rho, f.e_d, f.e, f.crossings
        );
    }
    let ron = crowd_core::files::to_stage_ron(&patterns).into_bytes();
    let writes = vec![
        (out.with_file_name("optimize.csv"), csv.into_bytes()),
        (out.to_path_buf(), ron),
    ];
    Ok((patterns, side, writes))
}

/// `regions.bin` beside `out` for these results, streamed to its temporary name (86 MB at
/// the million, never held as bytes).
pub fn write_regions(
    out: &std::path::Path,
    solved: &[Solved],
) -> crowd_core::Result<crowd_core::files::StreamedFile> {
    crowd_core::files::Streamed::written_by(&out.with_file_name(REGIONS_FILE), |w| {
        known::write(w, solved)
    })
}

#[cfg(test)]
mod tests;
