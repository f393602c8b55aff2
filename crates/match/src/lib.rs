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

mod cache;
pub mod plan;
pub mod random;
pub mod score;
pub mod shard;
pub mod stable;
pub mod standers;
pub mod way;

// The shortest way past a patch's walls is shared geometry (stage 5 routes pushed pieces
// with it too); `plan` reaches it as `crate::route`.
pub use crowd_geometry::route;

pub use cache::{MEMO_SIZE, ScoreCache, match_points_cached, measure_patch_cached};

use crowd_core::config::MatchSettings;
use crowd_core::patterns::{Crossings, Measured, Side};
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
    pub fn new<'a>(graph: &PatchGraph, crossings: impl Into<Crossings<'a>>) -> Incidence {
        let n = graph.patches.len();
        let mut inc = Incidence {
            entries: vec![Vec::new(); n],
            exits: vec![Vec::new(); n],
        };
        for (k, c) in crossings.into().indexed() {
            let (from, to) = c.ends(graph);
            inc.exits[from.patch.0 as usize].push(k);
            inc.entries[to.patch.0 as usize].push(k);
        }
        inc
    }
}

/// The endpoints of a patch, seen from inside it.
pub fn endpoints(
    graph: &PatchGraph,
    crossings: Crossings<'_>,
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
    pub crossings: Crossings<'a>,
    pub incidence: Incidence,
    pub settings: &'a MatchSettings,
    pub period_s: f64,
}

impl<'a> Matcher<'a> {
    pub fn new(
        graph: &'a PatchGraph,
        crossings: impl Into<Crossings<'a>>,
        settings: &'a MatchSettings,
        period_s: f64,
    ) -> Matcher<'a> {
        let crossings = crossings.into();
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

/// The hash of stage 4's inputs: the graph and patterns files (their bytes' hashes) and the
/// settings.
pub fn input_hash(
    graph_file: &crowd_core::Hash,
    patterns_file: &crowd_core::Hash,
    inputs: &Inputs,
) -> crowd_core::Hash {
    use crowd_core::trajectories::TrajectoriesFile;
    crowd_core::Hasher::new(TrajectoriesFile::STAGE, TrajectoriesFile::VERSION)
        .file_hash("graph file", graph_file)
        .file_hash("patterns file", patterns_file)
        .value("period", &inputs.period_s)
        .value("seed", &inputs.seed)
        .value("settings", &inputs.settings)
        .finish()
}

/// Every patch's motion, in patch order (in parallel; the same bytes on any thread count).
pub fn match_all<'a>(
    graph: &PatchGraph,
    crossings: impl Into<Crossings<'a>>,
    measured: &[Measured],
    inputs: &Inputs,
    progress: &dyn crowd_core::Progress,
) -> Vec<PatchMotion> {
    use rayon::prelude::*;
    let matcher = Matcher::new(graph, crossings.into(), &inputs.settings, inputs.period_s);
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

/// The motion of the patches `patches` only (in that order; in parallel): a rebuild computes
/// the patches whose [`patch_key`] changed.
pub fn match_patches<'a>(
    graph: &PatchGraph,
    crossings: impl Into<Crossings<'a>>,
    measured: &[Measured],
    inputs: &Inputs,
    progress: &dyn crowd_core::Progress,
    patches: &[usize],
) -> Vec<PatchMotion> {
    use rayon::prelude::*;
    let matcher = Matcher::new(graph, crossings.into(), &inputs.settings, inputs.period_s);
    progress.begin("match", patches.len() as u64);
    patches
        .par_iter()
        .map(|&p| {
            let m = matcher.motion(p, measured[p].standers, inputs.seed);
            progress.advance(1);
            m
        })
        .collect()
}

/// Everything patch `p`'s stage 4 depends on, hashed: its surroundings (its crossings, its
/// borders, the patches around it), its standers, its index (standers are placed with a seed
/// of it) and the settings.
pub fn patch_key(
    seen: &crowd_core::patch_keys::Seen,
    p: usize,
    standers: u32,
    inputs: &Inputs,
) -> crowd_core::Hash {
    use crowd_core::trajectories::TrajectoriesFile;
    crowd_core::Hasher::new("match patch", TrajectoriesFile::VERSION)
        .binary("world", &seen.graph.world)
        .binary("radius", &seen.graph.radius_m)
        .binary("index", &p)
        .binary("standers", &standers)
        .binary("surroundings", &seen.surroundings(p))
        .binary("period", &inputs.period_s)
        .binary("seed", &inputs.seed)
        .binary("settings", &inputs.settings)
        .finish()
}

/// Stage 4's files, encoded: the motion side file, then `trajectories.ron`.
pub fn encode<'a>(
    out: &std::path::Path,
    motion: impl Into<crowd_core::trajectories::SideMotion<'a>>,
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
