//! Stage 5, collide: straight-line trajectories in, collision-free trajectories out (Ramirez et
//! al. section 3.4, Algorithm 2).
//!
//! In every patch, while two characters come closer than the sum of their radii (walkers with
//! each other, with their own copies a period later, with standers) or a walker comes closer
//! than its radius to an obstacle, the closest pair is pushed apart at the moment of closest
//! approach ([`repair`], [`push`]). Distances are exact: the closest approach of two straight
//! space-time segments is analytic (`crowd_geometry`). Boundary points cannot move
//! ([`path::Anchor`]).

pub mod path;
mod pause;
pub mod push;
pub mod repair;
pub mod replan;
pub mod shard;

use crowd_core::PatchGraph;
use crowd_core::trajectories::PatchMotion;
use path::Path;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

pub use crowd_geometry::obstacles_near;

/// How one patch came out.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PatchReport {
    pub patch: u32,
    pub iterations: u32,
    pub converged: bool,
    /// Smallest distance minus the clearance needed, over every pair (negative: a collision).
    pub worst_margin_m: f64,
    /// The pair left too close, when the patch did not converge.
    pub stall: Option<crowd_core::trajectories::Stall>,
    /// The fastest walker, when the patch was cleared only by letting it hurry.
    pub hurry: Option<crowd_core::trajectories::Hurry>,
    /// The walkers given one more period ([`path::Path::add_period`]).
    pub waited: Vec<u32>,
}

/// Restarts a stalled repair from the straight lines with fresh random pushes, [`RESTARTS`]
/// attempts with doubling budgets that add up to `max_iterations`, and keeps the best attempt. The
/// greedy repair of the paper can cycle (pushing one pair apart pushes another together);
/// another draw of the small random rotations usually breaks the cycle. From the
/// [`RESCUE_AFTER`]th attempt on, a patch still stalled is also rescued by planning
/// ([`replan::rescue`]), which costs milliseconds where the later attempts' pushes cost
/// seconds in a dense patch.
pub fn with_restarts(
    paths: &mut Vec<Path>,
    patch: &repair::Patch,
    speeds: repair::Speeds,
    max_iterations: u32,
    rng: &mut ChaCha8Rng,
) -> repair::Outcome {
    with_attempts(paths, patch, speeds, max_iterations, 0..RESTARTS, rng)
}

/// [`with_restarts`]' attempts `attempts` only (their budgets as in the whole run).
fn with_attempts(
    paths: &mut Vec<Path>,
    patch: &repair::Patch,
    speeds: repair::Speeds,
    max_iterations: u32,
    attempts: std::ops::Range<u32>,
    rng: &mut ChaCha8Rng,
) -> repair::Outcome {
    let start = paths.clone();
    // Budgets double from try to try: most stalls clear on a cheap second draw, the rest get
    // room. They add up to `max_iterations`.
    let unit = (max_iterations / ((1 << RESTARTS) - 1)).max(1);
    let mut best: Option<(Vec<Path>, repair::Outcome)> = None;
    let mut used = 0;
    for k in attempts {
        let per_try = unit << k;
        let mut attempt = start.clone();
        let outcome = repair::remove_collisions(&mut attempt, patch, speeds, per_try, rng);
        used += outcome.iterations;
        if keep_better(&mut best, attempt, outcome) {
            break;
        }
        if k + 1 >= RESCUE_AFTER {
            let (mut rescued, _) = best.clone().expect("an attempt");
            let outcome = replan::rescue(
                &mut rescued,
                patch,
                speeds,
                RESCUE_ROUNDS,
                rescue_pushes(max_iterations),
                rng,
            );
            used += outcome.iterations;
            if keep_better(&mut best, rescued, outcome) {
                break;
            }
        }
    }
    let (chosen, outcome) = best.expect("at least one attempt");
    *paths = chosen;
    repair::Outcome {
        iterations: used,
        ..outcome
    }
}

/// What [`clear_patch`] had to do beyond pushing.
#[derive(Debug, Clone, Default)]
pub(crate) struct Cleared {
    /// Walkers given one more period.
    pub(crate) waited: Vec<u32>,
    /// Bends let hurry past the speed limit.
    pub(crate) hurried: bool,
}

/// Walkers of a stalled patch given one more period, at most, one after another.
const WAITERS: usize = 3;
/// The attempts of [`with_restarts`] in the first, cheap pass of [`clear_patch`]: a ninth of
/// the budget, one rescue. (A rescue of a quarter of [`RESCUE_ROUNDS`] there saved a quarter
/// of ring's pushes, but random painting 20, built in 11 s with it whole, was refused after
/// 55 s: its patch 16 then cleared in no tier.)
const CHEAP: u32 = RESCUE_AFTER;

/// Clears one patch: at walking pace ([`repair::Speeds::bend_limit`]) if it can, else a little
/// faster ([`repair::Speeds::second`]), else by giving a walker of the worst pair one more
/// period in the patch (up to [`WAITERS`] walkers; a walker that must pass behind another at
/// the last moment then has the time: painting's patch 3825, where the other leaves by the
/// border the first walks along), else with bends that may hurry ([`repair::Speeds::hurried`]).
/// Each try starts from the straight lines. The tries run twice: first with the cheap attempts
/// of [`with_restarts`] ([`CHEAP`]), then with the costly ones, and hurrying only then; a stall
/// that a little more speed or a wait clears no longer costs the whole budget at walking pace
/// first (ring's patch 334 took 5 s so). Returns the paths, how the repair ended and what it
/// took.
pub(crate) fn clear_patch(
    start: Vec<Path>,
    patch: &repair::Patch,
    speeds: repair::Speeds,
    (period_s, max_iterations): (f64, u32),
    rng: &mut ChaCha8Rng,
) -> (Vec<Path>, repair::Outcome, Cleared) {
    let margin = |o: &repair::Outcome| o.worst.map_or(f64::INFINITY, |w| w.margin);
    let mut best: Option<(Vec<Path>, repair::Outcome, Cleared)> = None;
    let mut iterations = 0;
    // One try from `paths`, kept if its worst encounter is the best so far; its stall, if any.
    let mut run = |paths: &[Path], speeds, attempts, waited: &[u32], hurried| {
        let mut paths = paths.to_vec();
        let outcome = with_attempts(&mut paths, patch, speeds, max_iterations, attempts, rng);
        iterations += outcome.iterations;
        if best
            .as_ref()
            .is_none_or(|b: &(Vec<Path>, repair::Outcome, Cleared)| margin(&outcome) > margin(&b.1))
        {
            let how = Cleared {
                waited: waited.to_vec(),
                hurried,
            };
            best = Some((paths, outcome, how));
        }
        outcome.worst
    };
    let mut waiting = start.clone();
    let mut waited: Vec<u32> = Vec::new();
    // The last try's stall: `None` once a try cleared the patch (or before any try).
    let (mut stall, mut cleared) = (None, false);
    for attempts in [0..CHEAP, CHEAP..RESTARTS] {
        for s in [speeds, speeds.second()] {
            if !cleared {
                stall = run(&start, s, attempts.clone(), &[], false);
                cleared = stall.is_none();
            }
        }
        // The walkers waited so far, then one more at a time.
        if !cleared && !waited.is_empty() {
            stall = run(&waiting, speeds, attempts.clone(), &waited, false);
            cleared = stall.is_none();
        }
        while let Some(w) = stall.filter(|_| waited.len() < WAITERS) {
            let other = match w.other {
                repair::Other::Walker { b, .. } => Some(b),
                _ => None,
            };
            let Some(i) = [Some(w.a), other]
                .into_iter()
                .flatten()
                .find(|&i| !waited.contains(&(i as u32)))
            else {
                break;
            };
            if !waiting[i].add_period(period_s) {
                break;
            }
            waited.push(i as u32);
            stall = run(&waiting, speeds, attempts.clone(), &waited, false);
            cleared = stall.is_none();
        }
    }
    // Last, hurrying: from the straight lines, then with the waits (stalls are chancy).
    for (paths, waited) in [(&start, &[][..]), (&waiting, &waited[..])] {
        if cleared {
            break;
        }
        stall = run(paths, speeds.hurried(), 0..RESTARTS, waited, true);
        cleared = stall.is_none();
    }
    let (paths, outcome, how) = best.expect("one try at least");
    (
        paths,
        repair::Outcome {
            iterations,
            ..outcome
        },
        how,
    )
}

/// The fastest piece of a patch's paths, as the file records a patch that hurried.
fn hurry(patch: usize, paths: &[Path]) -> crowd_core::trajectories::Hurry {
    let mut best = crowd_core::trajectories::Hurry {
        patch: patch as u32,
        walker: 0,
        speed_m_s: 0.0,
        t_s: 0.0,
    };
    for (w, path) in paths.iter().enumerate() {
        for s in path.segments() {
            let v = s.velocity().length();
            if v > best.speed_m_s {
                best.walker = w as u32;
                best.speed_m_s = v;
                best.t_s = s.t0;
            }
        }
    }
    best
}

/// Keeps `paths` as the best try if its worst encounter is better than the best's; returns
/// whether it cleared the patch.
fn keep_better(
    best: &mut Option<(Vec<Path>, repair::Outcome)>,
    paths: Vec<Path>,
    outcome: repair::Outcome,
) -> bool {
    let margin = |o: &repair::Outcome| o.worst.map_or(f64::INFINITY, |w| w.margin);
    if best
        .as_ref()
        .is_none_or(|(_, b)| margin(&outcome) > margin(b))
    {
        *best = Some((paths, outcome));
    }
    outcome.worst.is_none()
}

/// The file's record of a patch left with encounter `w`.
fn stall(patch: usize, w: &repair::Encounter) -> crowd_core::trajectories::Stall {
    use crowd_core::trajectories::{Stall, StallWith};
    Stall {
        patch: patch as u32,
        margin_m: w.margin,
        walker: w.a as u32,
        with: match w.other {
            repair::Other::Walker { b, .. } => StallWith::Walker(b as u32),
            repair::Other::Stander(s) => StallWith::Stander(s as u32),
            repair::Other::Obstacle(o) => StallWith::Obstacle(o as u32),
        },
        t_s: w.t,
    }
}

/// Attempts per patch (see [`with_restarts`]).
pub const RESTARTS: u32 = 6;
/// Attempts after which a stalled patch is rescued by planning too.
pub const RESCUE_AFTER: u32 = 3;
/// Walkers planned anew in a rescue, at most ([`replan::rescue`]), and the pushes after each.
pub const RESCUE_ROUNDS: u32 = 40;
pub const RESCUE_PUSHES: u32 = 400;

/// The pushes after each planned walker of a rescue: [`RESCUE_PUSHES`] at the default
/// `collide.max_iterations` (12,000), in proportion otherwise, so that the setting bounds a
/// rescue's work too (a random painting refused after 3 min with `max_iterations: 200`).
pub fn rescue_pushes(max_iterations: u32) -> u32 {
    (u64::from(RESCUE_PUSHES) * u64::from(max_iterations) / 12_000).max(1) as u32
}

/// Removes collisions in every patch, in parallel; deterministic for a seed.
pub fn collide(
    graph: &PatchGraph,
    motion: &[PatchMotion],
    inputs: &Inputs,
    progress: &dyn crowd_core::Progress,
) -> (Vec<PatchMotion>, Vec<PatchReport>) {
    match clear_all(graph, motion, costly_first(motion), inputs, progress, false) {
        Ok(done) => done.into_iter().unzip(),
        Err(_) => unreachable!("clear_all stops only when asked to"),
    }
}

/// [`collide`], or the first patch it cannot clear: the patches are cleared busiest first
/// ([`costly_first`]), and none is started after one of them has stalled. A build refuses on
/// any stalled patch, and the rest are not worth their time: a long-period painting (bands at
/// 0.25 m a pixel, 401.8 s) spent 90 s clearing its seven hopeless patches before it refused,
/// where the first had stalled after 21 s. Deterministic: every patch started before the
/// first that stalls (in that order) runs to its end, so the stall named is the same for any
/// thread count.
pub fn collide_or_first_stall(
    graph: &PatchGraph,
    motion: &[PatchMotion],
    inputs: &Inputs,
    progress: &dyn crowd_core::Progress,
) -> Result<(Vec<PatchMotion>, Vec<PatchReport>), crowd_core::trajectories::Stall> {
    clear_all(graph, motion, costly_first(motion), inputs, progress, true)
        .map(|done| done.into_iter().unzip())
}

/// [`collide_or_first_stall`] on `patches` only (busiest first), each with its report, in
/// patch order: a shard's part ([`shard`]). A patch's result depends on it alone, so the
/// parts put together are what one process makes.
pub fn collide_patches(
    graph: &PatchGraph,
    motion: &[PatchMotion],
    inputs: &Inputs,
    progress: &dyn crowd_core::Progress,
    patches: &[usize],
) -> Result<Vec<(PatchMotion, PatchReport)>, crowd_core::trajectories::Stall> {
    let mut order = patches.to_vec();
    order.sort_by_key(|&p| (std::cmp::Reverse(motion[p].trajectories.len()), p));
    clear_all(graph, motion, order, inputs, progress, true)
}

/// Clears the patches `order` (in that order), each with its report, in patch order.
fn clear_all(
    graph: &PatchGraph,
    motion: &[PatchMotion],
    order: Vec<usize>,
    inputs: &Inputs,
    progress: &dyn crowd_core::Progress,
    stop_at_stall: bool,
) -> Result<Vec<(PatchMotion, PatchReport)>, crowd_core::trajectories::Stall> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let Inputs {
        period_s,
        seed,
        max_iterations,
        speeds,
        ..
    } = *inputs;
    progress.begin("collide", order.len() as u64);
    // The place, in the order patches are started, of the first that stalled (so far).
    let first_stall = AtomicUsize::new(usize::MAX);
    let mut done: Vec<(usize, usize, (PatchMotion, PatchReport))> = order
        .into_iter()
        .enumerate()
        .par_bridge()
        .filter_map(|(k, p)| {
            // Never one started before the first stall: a later stall cannot lower it below k.
            if stop_at_stall && k > first_stall.load(Ordering::Relaxed) {
                return None;
            }
            let m = &motion[p];
            let obstacles = obstacles_near(graph, p);
            let patch = repair::Patch {
                side_m: graph.world.patch_side_m,
                period_s,
                radius_m: graph.radius_m + inputs.margin_m,
                obstacles: &obstacles,
                standers: &m.standers,
            };
            let paths: Vec<Path> = m.trajectories.iter().map(Path::from_trajectory).collect();
            let mut rng = ChaCha8Rng::seed_from_u64(
                seed ^ (p as u64 + 1).wrapping_mul(0xD1B5_4A32_D192_ED03),
            );
            let (paths, outcome, how) =
                clear_patch(paths, &patch, speeds, (period_s, max_iterations), &mut rng);
            progress.advance(1);
            let report = PatchReport {
                patch: p as u32,
                iterations: outcome.iterations,
                converged: outcome.worst.is_none(),
                worst_margin_m: outcome.worst.map_or(0.0, |w| w.margin),
                stall: outcome.worst.map(|w| stall(p, &w)),
                hurry: how.hurried.then(|| hurry(p, &paths)),
                waited: how.waited,
            };
            if report.stall.is_some() {
                first_stall.fetch_min(k, Ordering::Relaxed);
            }
            let motion = PatchMotion {
                standers: m.standers.clone(),
                trajectories: paths.iter().map(Path::to_trajectory).collect(),
            };
            Some((k, p, (motion, report)))
        })
        .collect();
    if stop_at_stall {
        let k = first_stall.into_inner();
        if let Some((_, _, (_, report))) = done.iter().find(|d| d.0 == k) {
            return Err(report.stall.expect("the first stall"));
        }
    }
    done.sort_unstable_by_key(|d| d.1);
    Ok(done.into_iter().map(|d| d.2).collect())
}

/// The patches in the order they are started: most walkers first (ties in patch order), so
/// that a long patch does not start last and leave the other cores idle (painting's patch
/// 10807, 71 walkers and a seventh of stage 5's work, came near the end of 10,906). Each
/// patch's result depends on it alone, so the order changes no output.
fn costly_first(motion: &[PatchMotion]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..motion.len()).collect();
    order.sort_by_key(|&p| std::cmp::Reverse(motion[p].trajectories.len()));
    order
}

/// The stage name in `collided.ron`'s header.
pub const STAGE: &str = "collide";
pub const VERSION: u32 = 16;

/// Everything patch `p`'s stage 5 depends on, hashed: its stage 4 motion (in its own
/// numbering of its crossings), its surroundings (the obstacles near it), its index (its
/// random stream) and the settings.
pub fn patch_key(
    seen: &crowd_core::patch_keys::Seen,
    p: usize,
    matched: &PatchMotion,
    inputs: &Inputs,
) -> crowd_core::Hash {
    let motion = crowd_core::patch_keys::local_bytes(&seen.tables[p], matched);
    let mut h = crowd_core::Hasher::new("collide patch", VERSION);
    h.binary("world", &seen.graph.world)
        .binary("radius", &seen.graph.radius_m)
        .binary("index", &p)
        .binary("surroundings", &seen.surroundings(p))
        .part("motion", &motion)
        .binary("inputs", inputs);
    h.finish()
}

/// What stage 5 reads of a pipeline besides its input files.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Inputs {
    pub period_s: f64,
    pub seed: u64,
    pub max_iterations: u32,
    /// `match.comfort_speed` and `match.max_speed`.
    pub speeds: repair::Speeds,
    /// Kept beyond every radius, m ([`crowd_core::config::Pipeline::shipping_error_m`]).
    pub margin_m: f64,
}

/// What stage 5 reads of `pipeline`.
pub fn inputs(pipeline: &crowd_core::config::PipelineFile) -> Inputs {
    let p = &pipeline.pipeline;
    Inputs {
        period_s: p.period_s,
        seed: p.seed,
        max_iterations: p.collide.max_iterations,
        speeds: repair::Speeds::of(&p.matching),
        margin_m: p.shipping_error_m(),
    }
}

/// The hash of stage 5's inputs: the graph and trajectories files (their bytes' hashes) and
/// the settings.
pub fn input_hash(
    graph_file: &crowd_core::Hash,
    trajectories_file: &crowd_core::Hash,
    inputs: &Inputs,
) -> crowd_core::Hash {
    crowd_core::Hasher::new(STAGE, VERSION)
        .file_hash("graph file", graph_file)
        .file_hash("trajectories file", trajectories_file)
        .value("inputs", inputs)
        .finish()
}

/// Stage 5's files, encoded: the motion side file, then `collided.ron`.
pub fn encode<'a>(
    out: &std::path::Path,
    motion: impl Into<crowd_core::trajectories::SideMotion<'a>>,
    reports: &[PatchReport],
    graph: &PatchGraph,
    inputs: &Inputs,
    hash: crowd_core::Hash,
) -> (
    crowd_core::trajectories::TrajectoriesFile,
    crowd_core::files::Writes,
) {
    crowd_core::trajectories::encode_file(
        out,
        crowd_core::files::Header::new(STAGE, VERSION, hash),
        inputs.period_s,
        graph.radius_m,
        motion,
        Some(collisions(reports)),
        None,
    )
}

/// What the patches' reports say of the clearing, for `collided.ron`.
fn collisions(reports: &[PatchReport]) -> crowd_core::trajectories::CollisionSummary {
    crowd_core::trajectories::CollisionSummary {
        iterations: reports.iter().map(|r| r.iterations as u64).sum(),
        min_margin_m: reports.iter().map(|r| r.worst_margin_m).fold(0.0, f64::min),
        unconverged: reports.iter().filter_map(|r| r.stall).collect(),
        hurried: reports.iter().filter_map(|r| r.hurry).collect(),
        waited: reports
            .iter()
            .flat_map(|r| r.waited.iter().map(|&w| (r.patch, w)))
            .collect(),
    }
}

#[cfg(test)]
mod tests;
