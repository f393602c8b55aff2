//! Stage 4, match: patterns in, straight-line space-time trajectories and standers out
//! (Ramirez et al. section 3.3, extended as in Crowd Art section 4.1).
//!
//! In every patch, entry and exit points are paired by Gale-Shapley ([`stable`]) on the score
//! of [`score`]; each pair becomes a straight line in space-time ([`plan`]), split where it
//! wraps around the period, with extra periods when the speed would be implausible, a pause when
//! it would be too slow, and a turn towards the centre when both points are on one border.
//! Standing characters are spread over the free part of the patch ([`standers`]).
//!
//! Stage 3 uses [`measure_patch`] to measure density and direction from the same matching.

pub mod plan;
pub mod random;
pub mod score;
pub mod stable;
pub mod standers;
pub mod way;

// The shortest way past a patch's walls is shared geometry (stage 5 routes pushed pieces
// with it too); `plan` reaches it as `crate::route`.
pub use crowd_geometry::route;

use crowd_core::config::MatchSettings;
use crowd_core::patterns::{Crossing, Measured, Side};
use crowd_core::trajectories::{PatchMotion, Trajectory};
use crowd_core::{PatchGraph, Rect, RequestedDirection};
use glam::DVec2;

/// An entry or exit point as one patch sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Endpoint {
    /// Index of the crossing in the patterns.
    pub crossing: u32,
    /// Patch-local metres.
    pub pos: DVec2,
    /// Time in [0, period).
    pub t: f64,
    pub side: Side,
    /// The crossing's velocity (world axes; into the patch for an entry, out for an exit).
    pub velocity: DVec2,
}

/// What the matching of one patch needs to know about it.
#[derive(Debug, Clone)]
pub struct PatchContext<'a> {
    pub side_m: f64,
    pub period_s: f64,
    /// Preferred speed in this patch (fundamental diagram at its requested density).
    pub comfort_speed: f64,
    pub direction: Option<RequestedDirection>,
    pub obstacles: &'a [Rect],
    /// Character radius: paths keep this far from obstacles.
    pub radius_m: f64,
    pub settings: &'a MatchSettings,
}

impl<'a> PatchContext<'a> {
    pub fn new(
        graph: &'a PatchGraph,
        patch: usize,
        settings: &'a MatchSettings,
        period_s: f64,
    ) -> Self {
        let p = &graph.patches[patch];
        PatchContext {
            side_m: graph.world.patch_side_m,
            period_s,
            comfort_speed: score::comfort_speed(
                settings.comfort_speed,
                p.walker_density + p.stander_density,
            ),
            direction: p.direction,
            obstacles: &p.obstacles,
            radius_m: graph.radius_m,
            settings,
        }
    }
}

/// For every patch, the indices of the crossings that enter it and that leave it.
pub struct Incidence {
    pub entries: Vec<Vec<u32>>,
    pub exits: Vec<Vec<u32>>,
}

impl Incidence {
    pub fn new(graph: &PatchGraph, crossings: &[Crossing]) -> Incidence {
        let n = graph.patches.len();
        let mut inc = Incidence {
            entries: vec![Vec::new(); n],
            exits: vec![Vec::new(); n],
        };
        for (k, c) in crossings.iter().enumerate() {
            let (from, to) = c.ends(graph);
            inc.exits[from.patch.0 as usize].push(k as u32);
            inc.entries[to.patch.0 as usize].push(k as u32);
        }
        inc
    }
}

/// The endpoints of a patch, seen from inside it.
pub fn endpoints(
    graph: &PatchGraph,
    crossings: &[Crossing],
    ids: &[u32],
    entering: bool,
) -> Vec<Endpoint> {
    ids.iter()
        .map(|&k| {
            let c = &crossings[k as usize];
            let (from, to) = c.ends(graph);
            let here = if entering { to } else { from };
            Endpoint {
                crossing: k,
                pos: here.pos,
                t: c.t,
                side: here.side,
                velocity: c.velocity,
            }
        })
        .collect()
}

/// Pairs the entries and exits of a patch: `pairs[i]` is the exit of entry `i`.
/// Requires as many entries as exits (parity).
pub fn match_points(entries: &[Endpoint], exits: &[Endpoint], ctx: &PatchContext) -> Vec<usize> {
    assert_eq!(
        entries.len(),
        exits.len(),
        "parity: as many entries as exits"
    );
    let n = entries.len();
    let mut scores = Vec::with_capacity(n * n);
    for e in entries {
        for x in exits {
            scores.push(score::score(e, x, ctx));
        }
    }
    stable::gale_shapley(n, &scores)
}

/// What a pair's score and duration depend on at one end: where, when, on which side and how
/// fast (the patch's context being fixed).
type PointKey = ([u64; 5], Side);

fn point_key(e: &Endpoint) -> PointKey {
    let bits = [e.pos.x, e.pos.y, e.t, e.velocity.x, e.velocity.y].map(f64::to_bits);
    (bits, e.side)
}

/// A patch's pair scores and matched pairs from its last measurement. Stage 3 measures a patch
/// again after adding, removing or turning a crossing or two, so most pairs are the same: they
/// are looked up and only the new ones scored (the n^2 scores, `atan` in each, were four fifths
/// of stage 3), and a pair matched last time keeps its duration. The figures are exactly those
/// [`measure_patch`] computes.
///
/// It also remembers the figures of the patch's recent endpoint sets ([`MEMO_SIZE`] at most):
/// stage 3's polish tries many changes along cycles that share a border with the patch, and a
/// third of ring's measurements were of a set measured before (the same crossing removed or
/// turned by another cycle).
#[derive(Debug, Clone, Default)]
pub struct ScoreCache {
    memo: foldhash::HashMap<u128, Measured>,
    entries: Vec<PointKey>,
    exits: Vec<PointKey>,
    scores: Vec<f64>,
    /// Per entry of the last measurement, its exit and the pair's duration.
    matched: Vec<(usize, f64)>,
    /// The score matrix before the last, its room reused.
    spare: Vec<f64>,
}

/// Where each of `new` was in `old`, if it was. The lists come from the same borders in the
/// same order, so a key is first looked for where the last one was found; a hash map is built
/// only when that fails.
fn old_places(old: &[PointKey], new: &[PointKey]) -> Vec<Option<usize>> {
    let mut index: Option<foldhash::HashMap<&PointKey, usize>> = None;
    let mut shift = 0isize;
    new.iter()
        .enumerate()
        .map(|(i, key)| {
            let guess = i as isize + shift;
            let near = [guess, guess + 1, guess - 1]
                .into_iter()
                .filter_map(|g| usize::try_from(g).ok())
                .find(|&g| old.get(g) == Some(key));
            let found = near.or_else(|| {
                index
                    .get_or_insert_with(|| old.iter().enumerate().map(|(i, k)| (k, i)).collect())
                    .get(key)
                    .copied()
            });
            if let Some(g) = found {
                shift = g as isize - i as isize;
            }
            found
        })
        .collect()
}

/// Endpoint sets a [`ScoreCache`] remembers the figures of, at most; it forgets them all
/// when full (a patch measured many times over keeps the recent ones).
pub const MEMO_SIZE: usize = 64;

/// A set of endpoints, as a 128-bit hash of every figure a measurement reads (two 64-bit
/// hashes with fixed seeds, of the points and the standers: the same on every machine and run, and a collision within one
/// patch's [`MEMO_SIZE`] sets is out of reach).
fn set_key(entries: &[Endpoint], exits: &[Endpoint], standers: u32) -> u128 {
    use std::hash::{BuildHasher, Hash, Hasher};
    let half = |seed: u64| {
        let mut h = foldhash::quality::FixedState::with_seed(seed).build_hasher();
        (entries.len(), standers).hash(&mut h);
        for e in entries.iter().chain(exits) {
            point_key(e).hash(&mut h);
        }
        h.finish()
    };
    (u128::from(half(0x243f_6a88_85a3_08d3)) << 64) | u128::from(half(0x1319_8a2e_0370_7344))
}

impl ScoreCache {
    /// Takes in this measurement's endpoints: scores their pairs (row-major) reusing the last
    /// measurement's, and returns where each entry was last time (for [`Self::matched`]).
    fn update(
        &mut self,
        entries: &[Endpoint],
        exits: &[Endpoint],
        ctx: &PatchContext,
    ) -> (Vec<Option<usize>>, Vec<Option<usize>>) {
        let entry_keys: Vec<PointKey> = entries.iter().map(point_key).collect();
        let exit_keys: Vec<PointKey> = exits.iter().map(point_key).collect();
        if entry_keys == self.entries && exit_keys == self.exits {
            let same = |n: usize| (0..n).map(Some).collect();
            return (same(entries.len()), same(exits.len()));
        }
        let old_entry = old_places(&self.entries, &entry_keys);
        let old_exit = old_places(&self.exits, &exit_keys);
        let old_width = self.exits.len();
        let mut scores = std::mem::take(&mut self.spare);
        scores.clear();
        scores.reserve(entries.len() * exits.len());
        for (e, old_e) in entries.iter().zip(&old_entry) {
            for (x, old_x) in exits.iter().zip(&old_exit) {
                scores.push(match (old_e, old_x) {
                    (Some(i), Some(o)) => self.scores[i * old_width + o],
                    _ => score::score(e, x, ctx),
                });
            }
        }
        self.entries = entry_keys;
        self.exits = exit_keys;
        self.spare = std::mem::replace(&mut self.scores, scores);
        (old_entry, old_exit)
    }
}

/// [`match_points`] with the patch's scores kept in `cache` (see [`measure_patch_cached`]).
pub fn match_points_cached(
    entries: &[Endpoint],
    exits: &[Endpoint],
    ctx: &PatchContext,
    cache: &mut ScoreCache,
) -> Vec<usize> {
    assert_eq!(
        entries.len(),
        exits.len(),
        "parity: as many entries as exits"
    );
    cache.update(entries, exits, ctx);
    // The matched pairs' durations are indexed by the last measurement's entries.
    cache.matched.clear();
    stable::gale_shapley(entries.len(), &cache.scores)
}

/// [`measure_patch`] with the patch's scores kept in `cache` between calls: the same figures,
/// with only the pairs that changed since the last call scored.
pub fn measure_patch_cached(
    entries: &[Endpoint],
    exits: &[Endpoint],
    standers: u32,
    ctx: &PatchContext,
    cache: &mut ScoreCache,
) -> Measured {
    assert_eq!(
        entries.len(),
        exits.len(),
        "parity: as many entries as exits"
    );
    let key = set_key(entries, exits, standers);
    if let Some(m) = cache.memo.get(&key) {
        return *m;
    }
    let (old_entry, old_exit) = cache.update(entries, exits, ctx);
    let pairs = stable::gale_shapley(entries.len(), &cache.scores);
    let area = ctx.side_m * ctx.side_m;
    let mut time = 0.0;
    let mut direction = DVec2::ZERO;
    let mut matched = Vec::with_capacity(pairs.len());
    for ((e, &o), old_e) in entries.iter().zip(&pairs).zip(&old_entry) {
        let x = &exits[o];
        let last = old_e.and_then(|a| cache.matched.get(a).copied());
        let duration = match (last, old_exit[o]) {
            (Some((b, d)), Some(b2)) if b == b2 => d,
            _ => plan::duration(e, x, ctx),
        };
        matched.push((o, duration));
        time += duration;
        direction += duration * (x.pos - e.pos).normalize_or_zero();
    }
    cache.matched = matched;
    let measured = Measured {
        density: standers as f64 / area + time / (area * ctx.period_s),
        direction: direction.try_normalize(),
        standers,
    };
    if cache.memo.len() >= MEMO_SIZE {
        cache.memo.clear();
    }
    cache.memo.insert(key, measured);
    measured
}

/// Trajectories of a patch from its endpoints.
pub fn trajectories(
    entries: &[Endpoint],
    exits: &[Endpoint],
    ctx: &PatchContext,
) -> Vec<Trajectory> {
    let pairs = match_points(entries, exits, ctx);
    entries
        .iter()
        .zip(pairs)
        .map(|(e, o)| plan::plan(e, &exits[o], ctx))
        .collect()
}

/// Density and direction of a patch from its matched lines (Crowd Art eq. 2 and 3).
pub fn measure_patch(
    entries: &[Endpoint],
    exits: &[Endpoint],
    standers: u32,
    ctx: &PatchContext,
) -> Measured {
    measure_patch_cached(entries, exits, standers, ctx, &mut ScoreCache::default())
}

/// Stage 4 over a whole scene: the graph, its patterns and the settings.
pub struct Matcher<'a> {
    pub graph: &'a PatchGraph,
    pub crossings: &'a [Crossing],
    pub incidence: Incidence,
    pub settings: &'a MatchSettings,
    pub period_s: f64,
}

impl<'a> Matcher<'a> {
    pub fn new(
        graph: &'a PatchGraph,
        crossings: &'a [Crossing],
        settings: &'a MatchSettings,
        period_s: f64,
    ) -> Matcher<'a> {
        Matcher {
            graph,
            crossings,
            incidence: Incidence::new(graph, crossings),
            settings,
            period_s,
        }
    }

    pub fn context(&self, patch: usize) -> PatchContext<'a> {
        PatchContext::new(self.graph, patch, self.settings, self.period_s)
    }

    /// The entries and exits of a patch.
    pub fn endpoints(&self, patch: usize) -> (Vec<Endpoint>, Vec<Endpoint>) {
        (
            endpoints(
                self.graph,
                self.crossings,
                &self.incidence.entries[patch],
                true,
            ),
            endpoints(
                self.graph,
                self.crossings,
                &self.incidence.exits[patch],
                false,
            ),
        )
    }

    /// Everything that moves and stands in one patch; standers are placed with a seed of
    /// their own per patch, so a patch's motion does not depend on the others.
    pub fn motion(&self, patch: usize, standers: u32, seed: u64) -> PatchMotion {
        let ctx = self.context(patch);
        let (entries, exits) = self.endpoints(patch);
        let patch_seed = seed ^ (patch as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        PatchMotion {
            standers: standers::place(standers, &ctx, self.graph.radius_m, patch_seed),
            trajectories: trajectories(&entries, &exits, &ctx),
        }
    }
}

/// What stage 4 reads of a pipeline besides the graph and the patterns.
#[derive(Debug, Clone, PartialEq)]
pub struct Inputs {
    pub period_s: f64,
    pub seed: u64,
    pub settings: MatchSettings,
}

pub fn inputs(pipeline: &crowd_core::config::PipelineFile) -> Inputs {
    let p = &pipeline.pipeline;
    Inputs {
        period_s: p.period_s,
        seed: p.seed,
        settings: p.matching.clone(),
    }
}

/// The hash of stage 4's inputs: the graph and patterns files' bytes and the settings.
pub fn input_hash(graph_bytes: &[u8], patterns_bytes: &[u8], inputs: &Inputs) -> crowd_core::Hash {
    use crowd_core::trajectories::TrajectoriesFile;
    crowd_core::Hasher::new(TrajectoriesFile::STAGE, TrajectoriesFile::VERSION)
        .file("graph file", graph_bytes)
        .file("patterns file", patterns_bytes)
        .value("period", &inputs.period_s)
        .value("seed", &inputs.seed)
        .value("settings", &inputs.settings)
        .finish()
}

/// Every patch's motion, in patch order (in parallel; the same bytes on any thread count).
pub fn match_all(
    graph: &PatchGraph,
    crossings: &[Crossing],
    measured: &[Measured],
    inputs: &Inputs,
    progress: &dyn crowd_core::Progress,
) -> Vec<PatchMotion> {
    use rayon::prelude::*;
    let matcher = Matcher::new(graph, crossings, &inputs.settings, inputs.period_s);
    progress.begin("match", graph.patches.len() as u64);
    (0..graph.patches.len())
        .into_par_iter()
        .map(|p| {
            let m = matcher.motion(p, measured[p].standers, inputs.seed);
            progress.advance(1);
            m
        })
        .collect()
}

/// Stage 4's files, encoded: the motion side file, then `trajectories.ron`.
pub fn encode(
    out: &std::path::Path,
    motion: &[PatchMotion],
    graph: &PatchGraph,
    inputs: &Inputs,
    hash: crowd_core::Hash,
) -> (
    crowd_core::trajectories::TrajectoriesFile,
    crowd_core::files::Writes,
) {
    use crowd_core::trajectories::TrajectoriesFile;
    let header =
        crowd_core::files::Header::new(TrajectoriesFile::STAGE, TrajectoriesFile::VERSION, hash);
    crowd_core::trajectories::encode_file(
        out,
        header,
        inputs.period_s,
        graph.radius_m,
        motion,
        None,
        None,
    )
}

#[cfg(test)]
mod tests;
