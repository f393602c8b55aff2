//! Stage 5, collide: straight-line trajectories in, collision-free trajectories out (Ramirez et
//! al. section 3.4, Algorithm 2).
//!
//! In every patch, while two characters come closer than the sum of their radii (walkers with
//! each other, with their own copies a period later, with standers) or a walker comes closer
//! than its radius to an obstacle, the closest pair is pushed apart at the moment of closest
//! approach ([`repair`]). Distances are exact: the closest approach of two straight space-time
//! segments is analytic ([`geometry`]). Boundary points cannot move ([`path::Anchor`]).

pub mod geometry;
pub mod path;
pub mod random;
pub mod repair;
pub mod replan;

use crowd_core::PatchGraph;
use crowd_core::trajectories::PatchMotion;
use path::Path;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// How one patch came out.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PatchReport {
    pub patch: u32,
    pub iterations: u32,
    pub converged: bool,
    /// Smallest distance minus the clearance needed, over every pair (negative: a collision).
    pub worst_margin_m: f64,
    /// The pair left too close, when the patch did not converge.
    pub stall: Option<crowd_core::trajectories::Stall>,
}

/// The static obstacles a walker of patch `p` can touch: its own, and those of the eight
/// neighbours that come within a diameter of its square, in `p`'s local metres (a walker near a
/// border must keep clear of a wall just across it too).
pub fn obstacles_near(graph: &PatchGraph, p: usize) -> Vec<crowd_core::Rect> {
    let side = graph.world.patch_side_m;
    let reach = 2.0 * graph.radius_m;
    let cell = graph.patches[p].cell;
    let mut out = graph.patches[p].obstacles.clone();
    for dc in -1i64..=1 {
        for dr in -1i64..=1 {
            let (c, r) = (cell.col as i64 + dc, cell.row as i64 + dr);
            if (dc, dr) == (0, 0) || c < 0 || r < 0 {
                continue;
            }
            let neighbour = crowd_core::patch_graph::Cell {
                col: c as u32,
                row: r as u32,
            };
            let Some(q) = graph.patch_at(neighbour) else {
                continue;
            };
            let offset = glam::DVec2::new(dc as f64, dr as f64) * side;
            for o in &graph.patches[q].obstacles {
                let moved = crowd_core::Rect {
                    min: o.min + offset,
                    max: o.max + offset,
                };
                let near = moved.max.x > -reach
                    && moved.max.y > -reach
                    && moved.min.x < side + reach
                    && moved.min.y < side + reach;
                if near {
                    out.push(moved);
                }
            }
        }
    }
    out
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
    max_iterations: u32,
    rng: &mut ChaCha8Rng,
) -> repair::Outcome {
    let start = paths.clone();
    // Budgets double from try to try: most stalls clear on a cheap second draw, the rest get
    // room. They add up to `max_iterations`.
    let unit = (max_iterations / ((1 << RESTARTS) - 1)).max(1);
    let mut best: Option<(Vec<Path>, repair::Outcome)> = None;
    let mut used = 0;
    for k in 0..RESTARTS {
        let per_try = unit << k;
        let mut attempt = start.clone();
        let outcome = repair::remove_collisions(&mut attempt, patch, per_try, rng);
        used += outcome.iterations;
        if keep_better(&mut best, attempt, outcome) {
            break;
        }
        if k + 1 >= RESCUE_AFTER {
            let (mut rescued, _) = best.clone().expect("an attempt");
            let outcome = replan::rescue(&mut rescued, patch, RESCUE_ROUNDS, RESCUE_PUSHES, rng);
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

/// Removes collisions in every patch, in parallel; deterministic for a seed.
pub fn collide(
    graph: &PatchGraph,
    motion: &[PatchMotion],
    period_s: f64,
    max_iterations: u32,
    seed: u64,
    progress: &dyn crowd_core::Progress,
) -> (Vec<PatchMotion>, Vec<PatchReport>) {
    progress.begin("collide", motion.len() as u64);
    motion
        .par_iter()
        .enumerate()
        .map(|(p, m)| {
            let obstacles = obstacles_near(graph, p);
            let patch = repair::Patch {
                side_m: graph.world.patch_side_m,
                period_s,
                radius_m: graph.radius_m,
                obstacles: &obstacles,
                standers: &m.standers,
            };
            let mut paths: Vec<Path> = m.trajectories.iter().map(Path::from_trajectory).collect();
            let mut rng = ChaCha8Rng::seed_from_u64(
                seed ^ (p as u64 + 1).wrapping_mul(0xD1B5_4A32_D192_ED03),
            );
            let outcome = with_restarts(&mut paths, &patch, max_iterations, &mut rng);
            progress.advance(1);
            let report = PatchReport {
                patch: p as u32,
                iterations: outcome.iterations,
                converged: outcome.worst.is_none(),
                worst_margin_m: outcome.worst.map_or(0.0, |w| w.margin),
                stall: outcome.worst.map(|w| stall(p, &w)),
            };
            let motion = PatchMotion {
                standers: m.standers.clone(),
                trajectories: paths.iter().map(Path::to_trajectory).collect(),
            };
            (motion, report)
        })
        .unzip()
}

/// The stage name in `collided.ron`'s header.
pub const STAGE: &str = "collide";
pub const VERSION: u32 = 3;

/// What stage 5 reads of a pipeline besides its input files.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Inputs {
    pub period_s: f64,
    pub seed: u64,
    pub max_iterations: u32,
}

/// The hash of stage 5's inputs: the graph and trajectories files' bytes and the settings.
pub fn input_hash(
    graph_bytes: &[u8],
    trajectories_bytes: &[u8],
    inputs: &Inputs,
) -> crowd_core::Hash {
    crowd_core::Hasher::new(STAGE, VERSION)
        .file("graph file", graph_bytes)
        .file("trajectories file", trajectories_bytes)
        .value("inputs", inputs)
        .finish()
}

/// Stage 5's files, encoded: the motion side file, then `collided.ron`.
pub fn encode(
    out: &std::path::Path,
    motion: &[PatchMotion],
    reports: &[PatchReport],
    graph: &PatchGraph,
    inputs: &Inputs,
    hash: crowd_core::Hash,
) -> (
    crowd_core::trajectories::TrajectoriesFile,
    crowd_core::files::Writes,
) {
    use crowd_core::trajectories::CollisionSummary;
    let header = crowd_core::files::Header::new(STAGE, VERSION, hash);
    let collisions = Some(CollisionSummary {
        iterations: reports.iter().map(|r| r.iterations as u64).sum(),
        min_margin_m: reports.iter().map(|r| r.worst_margin_m).fold(0.0, f64::min),
        unconverged: reports.iter().filter_map(|r| r.stall).collect(),
    });
    crowd_core::trajectories::encode_file(
        out,
        header,
        inputs.period_s,
        graph.radius_m,
        motion,
        collisions,
        None,
    )
}

#[cfg(test)]
mod tests;
