//! Stage 7, edit: the moments an artist asks for (`edits` in `pipeline.ron`: people meeting at
//! a point, an area filling, a drift, a whirl) edited into the patches they cover by optimal
//! control of the social-force crowd model (Allain et al. 2014, with `crowd-edit`).
//!
//! Each covered patch is its own problem: its walkers follow their planned walks
//! (`Model::tracking`) and the descent finds the model error that brings the patch nearest the
//! edits' targets at the least cost. A patch's entry and exit points and border bands are never
//! moved (an edit's displacement is masked to zero there), so neighbouring patches, edited or
//! not, still join, and the world still tiles and loops; an edited walk that is too fast, leaves
//! the patch, or comes closer to anyone or anything than its plan did (measured exactly, as
//! stage 5 measures) is walked back towards its plan.
//!
//! - `plan.rs`: a patch's people over the problem's span, their plans and masks;
//! - `targets.rs`: each edit as a patch takes it, its constraints and its residual;
//! - `gather.rs`: who a density edit short of people brings into its rectangle;
//! - `patch.rs`: one patch edited, its walks checked and walked back where they must be.

pub mod gather;
pub mod patch;
pub mod plan;
pub mod targets;

use crowd_core::PatchGraph;
use crowd_core::config::{DEFAULT_Q, Edit, EditKind};
use crowd_core::flow_map::VelocityMap;
use crowd_core::trajectories::{DensityFigures, EditSummary, PatchMotion, TrajectoriesFile};
use crowd_core::{Hash, Hasher};
use glam::DVec2;
use patch::{Context, Edited, edit_patch};
use rayon::prelude::*;
use serde::Serialize;
use std::sync::Arc;
use targets::{Local, Residual, localise};

/// The stage name in `edited.ron`'s header.
pub const STAGE: &str = "edit";
pub const VERSION: u32 = 6;

/// How long before an edit's window its patch's problem starts, s: the time walkers have to
/// get where the edit wants them.
pub const LEAD_IN_S: f64 = 6.0;
/// How long after the window it ends, s: the time they have to rejoin their plans.
pub const LEAD_OUT_S: f64 = 4.0;

/// The longest problem edits of one patch share, s: later edits are solved in turn on the
/// motion the ones before left. A crowd's sensitivity to an early push grows with time (a
/// dense patch's gradient reached 4e9 over 28 s, and no step lowered the cost).
pub const MAX_SPAN_S: f64 = 14.0;

/// What stage 7 reads of a pipeline besides its input files.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Inputs {
    pub period_s: f64,
    /// The fastest an edited walker may walk, m/s (or its plan's fastest piece, where that is
    /// faster already).
    pub max_speed: f64,
    /// Kept beyond every radius, m ([`crowd_core::config::Pipeline::shipping_error_m`]).
    pub margin_m: f64,
    pub edits: Vec<Edit>,
    /// The flow map of each `FlowMap` edit (by its index in `edits`), decoded by the caller
    /// (`crowd_merge::decode_flow_map`; [`input_hash`] takes the files' bytes).
    #[serde(skip)]
    pub flow_maps: Vec<(usize, Arc<VelocityMap>)>,
}

/// What stage 7 reads of a pipeline besides its input files.
pub fn inputs(pipeline: &crowd_core::config::PipelineFile) -> Inputs {
    let p = &pipeline.pipeline;
    Inputs {
        period_s: p.period_s,
        max_speed: p.matching.max_speed * SPEED_ALLOWANCE,
        margin_m: p.shipping_error_m(),
        edits: p.edits.clone(),
        flow_maps: Vec::new(),
    }
}

/// How much faster than `match.max_speed` an edited walk may be: stage 6's allowance, which
/// the shipped files are held to (with export's share).
pub const SPEED_ALLOWANCE: f64 = 1.04;

/// The hash of stage 7's inputs: the graph and smoothed files (their bytes' hashes), the
/// settings, and the bytes of the flow maps the edits name (in the order of the edits).
pub fn input_hash(graph: &Hash, smoothed: &Hash, inputs: &Inputs, flow_maps: &[&[u8]]) -> Hash {
    // A flow map counts by its bytes, not by where it is (as the layers do): a pipeline copied
    // elsewhere with absolute paths rebuilds nothing.
    let mut settings = inputs.clone();
    for edit in &mut settings.edits {
        if let EditKind::FlowMap { map, .. } = &mut edit.kind {
            *map = std::path::PathBuf::new();
        }
    }
    let mut hasher = Hasher::new(STAGE, VERSION);
    hasher
        .file_hash("graph file", graph)
        .file_hash("smoothed file", smoothed)
        .value("inputs", &settings);
    for bytes in flow_maps {
        hasher.file("flow map", bytes);
    }
    hasher.finish()
}

/// Stage 7's files, encoded: the motion side file, then `edited.ron` (stage 6's figures
/// carried over, and what each edit did).
pub fn encode(
    out: &std::path::Path,
    motion: &[PatchMotion],
    edits: Vec<EditSummary>,
    smoothed: &TrajectoriesFile,
    hash: Hash,
) -> (TrajectoriesFile, crowd_core::files::Writes) {
    let header = crowd_core::files::Header::new(STAGE, VERSION, hash);
    let (mut file, mut writes) = crowd_core::trajectories::encode_file(
        out,
        header,
        smoothed.period_s,
        smoothed.radius_m,
        motion,
        smoothed.collisions.clone(),
        smoothed.smoothing.clone(),
    );
    file.edits = Some(edits);
    let ron = crowd_core::files::to_stage_ron(&file).into_bytes();
    writes
        .last_mut()
        .expect("encode_file writes the file last")
        .1 = ron;
    (file, writes)
}

/// What an edit's residual measures.
fn measure_of(kind: &EditKind) -> &'static str {
    match kind {
        EditKind::Meet { .. } => "largest distance of a meeting walker from its place, m",
        EditKind::Density { .. } => "RMS of density - target in the window, people/m2",
        EditKind::Flow { .. } | EditKind::FlowMap { .. } => {
            "RMS of velocity - target in the window, m/s"
        }
        EditKind::Vorticity { .. } => "RMS of vorticity - target in the window, 1/s",
    }
}

/// Edits of one patch solved as one problem, and the problem's span (absolute seconds).
type Group = (Vec<Local>, (f64, f64));
/// A group, what its problem gave, and the seconds it took.
type Solved = (Vec<Local>, Edited, f64);

/// The edits that reach patch `p`, in groups each of whose windows, with the lead-in before
/// and the lead-out after, fit in one period: one problem per group, solved in turn on the
/// motion the one before left (so no edit is dropped for lack of room), with its span.
fn locals_of(graph: &PatchGraph, p: usize, inputs: &Inputs) -> Vec<Group> {
    let side = graph.world.patch_side_m;
    let origin = graph.world_from_patch(graph.patches[p].cell);
    let period = inputs.period_s;
    let mut locals: Vec<Local> = inputs
        .edits
        .iter()
        .enumerate()
        .filter_map(|(k, e)| {
            let map = inputs
                .flow_maps
                .iter()
                .find(|(i, _)| *i == k)
                .map(|(_, m)| m);
            localise(e, k, origin, side, e.kind.window().0, map)
        })
        .collect();
    locals.sort_by(|a, b| a.window.0.total_cmp(&b.window.0).then(a.edit.cmp(&b.edit)));
    let end = |l: &Local| l.window.1 + LEAD_OUT_S;
    let mut groups: Vec<Group> = Vec::new();
    for local in locals {
        match groups.last_mut() {
            Some((group, span)) if end(&local).max(span.1) - span.0 <= period.min(MAX_SPAN_S) => {
                span.1 = span.1.max(end(&local));
                group.push(local);
            }
            _ => {
                let start = local.window.0 - LEAD_IN_S;
                // A window is at most a period long: its lead-out may have to be cut.
                let span = (start, end(&local).min(start + period));
                groups.push((vec![local], span));
            }
        }
    }
    groups
}

/// Edits every patch an edit reaches, in parallel; deterministic. The others are returned as
/// they came.
pub fn edit(
    graph: &PatchGraph,
    motion: &[PatchMotion],
    inputs: &Inputs,
    progress: &dyn crowd_core::Progress,
) -> (Vec<PatchMotion>, Vec<EditSummary>) {
    let (out, outcomes, _) = edit_timed(graph, motion, inputs, progress);
    (out, outcomes)
}

/// [`edit`], and the seconds each edit took: the wall time of its problems, summed over its
/// patches (a problem of several edits shared between them). On the clock, so kept out of the
/// stage's file (`timings.ron` has them).
pub fn edit_timed(
    graph: &PatchGraph,
    motion: &[PatchMotion],
    inputs: &Inputs,
    progress: &dyn crowd_core::Progress,
) -> (Vec<PatchMotion>, Vec<EditSummary>, Vec<f64>) {
    let work: Vec<(usize, Vec<Group>)> = (0..motion.len())
        .filter_map(|p| {
            let groups = locals_of(graph, p, inputs);
            (!groups.is_empty()).then_some((p, groups))
        })
        .collect();
    progress.begin("edit", work.len() as u64);
    let done: Vec<(usize, Vec<Solved>)> = work
        .into_par_iter()
        .map(|(p, groups)| {
            let obstacles = crowd_geometry::obstacles_near(graph, p);
            let q = groups
                .iter()
                .flat_map(|(locals, _)| locals)
                .filter_map(|l| inputs.edits[l.edit].q)
                .fold(f64::INFINITY, f64::min);
            let cx = Context {
                patch: crowd_geometry::Patch {
                    side_m: graph.world.patch_side_m,
                    period_s: inputs.period_s,
                    radius_m: graph.radius_m + inputs.margin_m,
                    obstacles: &obstacles,
                    standers: &motion[p].standers,
                },
                obstacles: &graph.patches[p].obstacles,
                max_speed: inputs.max_speed,
                q: if q.is_finite() { q } else { DEFAULT_Q },
            };
            let mut now = motion[p].clone();
            let mut done = Vec::new();
            for (locals, span) in groups {
                let clock = std::time::Instant::now();
                let edited = edit_patch(&now, &locals, span, &cx);
                now = edited.motion.clone();
                done.push((locals, edited, clock.elapsed().as_secs_f64()));
            }
            progress.advance(1);
            (p, done)
        })
        .collect();
    let mut out = motion.to_vec();
    let mut outcomes: Vec<EditSummary> = inputs
        .edits
        .iter()
        .map(|e| EditSummary {
            name: e.name.clone(),
            kind: e.kind.name().to_string(),
            rect: e.kind.rect(),
            window_s: e.kind.window(),
            measure: measure_of(&e.kind).to_string(),
            before: 0.0,
            after: 0.0,
            patches: Vec::new(),
            walkers: 0,
            iterations: 0,
            density: None,
            note: None,
            warning: None,
        })
        .collect();
    let mut residuals: Vec<Option<(Residual, Residual)>> = vec![None; inputs.edits.len()];
    let mut seconds = vec![0.0; inputs.edits.len()];
    for (p, groups) in done {
        for (locals, edited, took) in groups {
            merge(p, &locals, &edited, &mut outcomes, &mut residuals);
            for local in &locals {
                seconds[local.edit] += took / locals.len() as f64;
            }
            out[p] = edited.motion;
        }
    }
    finish(&mut outcomes, residuals, &inputs.edits);
    (out, outcomes, seconds)
}

/// Adds one problem's residuals and figures to its edits'.
fn merge(
    p: usize,
    locals: &[Local],
    edited: &Edited,
    outcomes: &mut [EditSummary],
    residuals: &mut [Option<(Residual, Residual)>],
) {
    for (local, &(before, after)) in locals.iter().zip(&edited.residuals) {
        let o = &mut outcomes[local.edit];
        // A patch edited for this edit in two problems is listed once.
        if o.patches.last() != Some(&(p as u32)) {
            o.patches.push(p as u32);
        }
        o.walkers += edited.walkers;
        o.iterations += edited.iterations;
        let r = &mut residuals[local.edit];
        *r = Some(match *r {
            Some((b, a)) => (b.combine(before), a.combine(after)),
            None => (before, after),
        });
    }
}

/// How near a density edit must come to its target (or to what its patches could show) for
/// the report not to warn.
pub const DENSITY_SHARE: f64 = 0.15;

/// Each edit's residual before and after, a density edit's people, and a note where the
/// report should say more.
fn finish(
    outcomes: &mut [EditSummary],
    residuals: Vec<Option<(Residual, Residual)>>,
    edits: &[Edit],
) {
    for ((o, r), e) in outcomes.iter_mut().zip(residuals).zip(edits) {
        let Some((before, after)) = r else {
            o.warning = Some(
                "it covers no patch of the crowd (only cells left out: blocked, unpainted or \
                 walled in), so nothing was edited; move it onto painted ground"
                    .to_string(),
            );
            continue;
        };
        o.before = before.value();
        o.after = after.value();
        if let (EditKind::Density { people_per_m2, .. }, Some(was), Some(now)) =
            (&e.kind, before.people(), after.people())
        {
            let figures = DensityFigures {
                target: *people_per_m2,
                before: was.density(),
                after: now.density(),
                reachable: was.reachable(),
            };
            o.density = Some(figures);
            o.note = Some(density_note(&figures));
            o.warning = density_warning(&figures);
        }
    }
}

/// What the report says of a density edit.
fn density_note(d: &DensityFigures) -> String {
    let mut note = format!(
        "{:.3} -> {:.3} people/m2 in the rectangle for a target of {} ({:.0} % of it)",
        d.before,
        d.after,
        d.target,
        100.0 * d.after / d.target
    );
    if d.after < (1.0 - DENSITY_SHARE) * d.target && d.reachable < d.target {
        note += &format!(
            "; its walkers could give at most {:.3} (a patch's walkers are fixed by its \
             crossings: paint more density there for more)",
            d.reachable
        );
    }
    note
}

/// A density edit more than [`DENSITY_SHARE`] away from its target (or from what its patches
/// could show, where that is less).
fn density_warning(d: &DensityFigures) -> Option<String> {
    if d.reached(DENSITY_SHARE) {
        return None;
    }
    let goal = d.attainable();
    let capped = if d.reachable < d.target {
        " (as many as its patches' walkers could give)"
    } else {
        ""
    };
    let (how, why) = if d.after < goal {
        (
            "short of",
            "the walkers the edit may move cannot all get there in time; lower its `r` to pull \
             harder, or paint more walkers there",
        )
    } else {
        (
            "over",
            "the plans bring more people there than asked, and the edit could not send enough \
             away; lower its `r`, or paint fewer walkers there",
        )
    };
    Some(format!(
        "{:.3} people/m2 in its rectangle, more than {:.0} % {how} the {goal:.3} asked{capped}: \
         {why}",
        d.after,
        100.0 * DENSITY_SHARE,
    ))
}

/// The world position of patch-local point `p` in patch `patch`.
pub fn world_point(graph: &PatchGraph, patch: usize, p: DVec2) -> DVec2 {
    graph.world_from_patch(graph.patches[patch].cell) + p
}
