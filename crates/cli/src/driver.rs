//! The build driver: runs the stages in order and skips the ones whose output is up to date.
//!
//! A stage is up to date when its file exists, is of the stage's format version, and records the
//! hash of exactly the inputs and settings the stage would read now (content hashes, not file
//! times: a fresh clone or a `touch` that changes nothing rebuilds nothing, and a changed pixel
//! always rebuilds). A rerun stage whose output bytes come out the same leaves the next stage up
//! to date.
//!
//! A build is all or nothing: stage outputs are kept in memory and written (each file
//! atomically) only once every stage has succeeded, so a build that fails changes no file.

use crate::memory;
use crate::ui::Ui;
use anyhow::Result;
use crowd_core::config::PipelineFile;
use crowd_core::files::{self, Header, Writes};
use crowd_core::maps::MergeFile;
use crowd_core::patterns::{Crossing, Patterns};
use crowd_core::trajectories::{PatchMotion, TrajectoriesFile, check_motion};
use crowd_core::{Hash, MergedMaps, PatchGraph};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

pub const MERGE_FILE: &str = "merge.ron";
pub const GRAPH_FILE: &str = "graph.ron";
pub const PATTERNS_FILE: &str = "patterns.ron";
pub const TRAJECTORIES_FILE: &str = "trajectories.ron";
pub const COLLIDED_FILE: &str = "collided.ron";
pub const SMOOTHED_FILE: &str = "smoothed.ron";
pub const EXPORT_FILE: &str = "export.ron";
/// Wall time of the last run of each stage. Not compared between builds: it is the one output
/// that is not deterministic.
pub const TIMINGS_FILE: &str = "timings.ron";

#[derive(Debug, Clone, Default)]
pub struct BuildOptions {
    /// Rebuild every stage.
    pub force: bool,
    /// Stop after this stage.
    pub until: Option<Stage>,
    /// Build folder instead of the pipeline's `output`.
    pub output: Option<PathBuf>,
}

/// The stages, in build order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, clap::ValueEnum)]
pub enum Stage {
    Merge,
    Graph,
    Optimize,
    Match,
    Collide,
    Smooth,
    Export,
}

/// What happened to one stage in a build.
#[derive(Debug, Clone, PartialEq)]
pub struct StageOutcome {
    pub stage: &'static str,
    /// `None` when the stage was up to date and skipped.
    pub seconds: Option<f64>,
}

/// Files to write once every stage has succeeded, in order.
#[derive(Default)]
struct Pending(Writes);

/// Runs every stage of the pipeline at `pipeline_path`.
pub fn build(pipeline_path: &Path, options: &BuildOptions, ui: &Ui) -> Result<Vec<StageOutcome>> {
    let pipeline = PipelineFile::load(pipeline_path)?;
    let out = options
        .output
        .clone()
        .unwrap_or_else(|| pipeline.output_dir());
    files::ensure_writable_dir(&out)?;
    let mut timings = read_timings(&out);
    let mut outcomes = Vec::new();
    let mut pending = Pending::default();

    // Stage 1: merge. Its maps stay in memory for stage 2 when it runs.
    let merge_path = out.join(MERGE_FILE);
    let layers = crowd_merge::read_layers(&pipeline)?;
    let hash = crowd_merge::input_hash(&pipeline, &layers);
    let (stage1, version1) = (MergeFile::STAGE, MergeFile::VERSION);
    let current = up_to_date(options.force, &merge_path, stage1, version1, hash, || {
        MergeFile::load(&merge_path)
    });
    let fresh = current.is_some();
    let mut merged: Option<(Vec<u8>, MergedMaps)> = current.map(|(bytes, (_, maps))| (bytes, maps));
    outcomes.push(stage(
        ui,
        "merge",
        &merge_path,
        fresh,
        &mut timings,
        || {
            let bar = ui.stage_bar("merge");
            let decoded = crowd_merge::decode(&layers)?;
            let p = &pipeline.pipeline;
            let maps = crowd_merge::merge(&decoded, &p.merge, p.scene.meters_per_pixel, &bar);
            let encoded =
                crowd_merge::encode(&merge_path, &pipeline, &layers, &decoded, hash, &maps);
            merged = Some((encoded.ron_bytes().to_vec(), maps));
            pending.0.extend(encoded.writes);
            Ok(())
        },
    )?);

    if options.until == Some(Stage::Merge) {
        return finish(&out, pending, &timings, outcomes);
    }

    // Stage 2: graph.
    let graph_path = out.join(GRAPH_FILE);
    let (merge_bytes, maps) = merged.expect("merge was built or is up to date");
    let hash = crowd_graph::input_hash(&merge_bytes, &crowd_graph::inputs(&pipeline));
    let fresh =
        !options.force && is_current(&graph_path, PatchGraph::STAGE, PatchGraph::VERSION, hash);
    let mut built_graph: Option<(Vec<u8>, PatchGraph)> = None;
    outcomes.push(stage(
        ui,
        "graph",
        &graph_path,
        fresh,
        &mut timings,
        || {
            let bar = ui.stage_bar("graph");
            let graph = crowd_graph::build(&pipeline, &merge_path, &merge_bytes, &maps, &bar)?;
            let bytes = files::to_ron(&graph).into_bytes();
            built_graph = Some((bytes.clone(), graph));
            pending.0.push((graph_path.clone(), bytes));
            Ok(())
        },
    )?);
    drop(maps);
    if options.until == Some(Stage::Graph) {
        return finish(&out, pending, &timings, outcomes);
    }
    let (graph_bytes, graph) = match built_graph {
        Some(built) => built,
        None => (
            files::read_bytes(&graph_path)?,
            PatchGraph::load(&graph_path)?,
        ),
    };

    // Stage 3: optimize.
    let patterns_path = out.join(PATTERNS_FILE);
    let inputs = crowd_optimize::inputs(&pipeline);
    let hash = crowd_optimize::input_hash(&graph_bytes, &inputs);
    let (stage3, version3) = (Patterns::STAGE, Patterns::VERSION);
    let current = up_to_date(
        options.force,
        &patterns_path,
        stage3,
        version3,
        hash,
        || Patterns::load(&patterns_path),
    );
    let fresh = current.is_some();
    let mut built_patterns: Option<(Vec<u8>, Patterns, Vec<Crossing>)> = None;
    outcomes.push(stage(
        ui,
        "optimize",
        &patterns_path,
        fresh,
        &mut timings,
        || {
            let (outcome, patterns, writes) =
                optimize_stage(&graph, &inputs, hash, &patterns_path, ui);
            let ron = writes.last().expect("the RON file").1.clone();
            built_patterns = Some((ron, patterns, outcome.crossings));
            pending.0.extend(writes);
            Ok(())
        },
    )?);
    if options.until == Some(Stage::Optimize) {
        return finish(&out, pending, &timings, outcomes);
    }
    let (patterns_bytes, patterns, crossings) = match (built_patterns, current) {
        (Some(built), _) => built,
        (None, current) => {
            let (bytes, (p, c)) = current.expect("optimize was built or is up to date");
            crowd_core::patterns::check_crossings(&patterns_path, &graph, &p, &c)?;
            (bytes, p, c)
        }
    };

    // Stage 4: match.
    let trajectories_path = out.join(TRAJECTORIES_FILE);
    let inputs = crowd_match::inputs(&pipeline);
    let hash = crowd_match::input_hash(&graph_bytes, &patterns_bytes, &inputs);
    let (stage4, version4) = (TrajectoriesFile::STAGE, TrajectoriesFile::VERSION);
    let current = up_to_date(
        options.force,
        &trajectories_path,
        stage4,
        version4,
        hash,
        || TrajectoriesFile::load_stage(&trajectories_path, stage4, version4),
    );
    let fresh = current.is_some();
    let mut built_motion: Option<(Vec<u8>, Vec<crowd_core::trajectories::PatchMotion>)> = None;
    outcomes.push(stage(
        ui,
        "match",
        &trajectories_path,
        fresh,
        &mut timings,
        || {
            let (motion, writes) = match_stage(
                &graph,
                &patterns,
                &crossings,
                &inputs,
                hash,
                &trajectories_path,
                ui,
            );
            built_motion = Some((writes.last().expect("the RON file").1.clone(), motion));
            pending.0.extend(writes);
            Ok(())
        },
    )?);
    if options.until == Some(Stage::Match) {
        return finish(&out, pending, &timings, outcomes);
    }
    let (trajectories_bytes, motion) = match (built_motion, current) {
        (Some(built), _) => built,
        (None, current) => {
            let (bytes, (_, motion)) = current.expect("match was built or is up to date");
            check_motion(&trajectories_path, graph.patches.len(), &motion)?;
            (bytes, motion)
        }
    };

    // Stage 5: collide.
    let collided_path = out.join(COLLIDED_FILE);
    let inputs = collide_inputs(&pipeline);
    let hash = crowd_collide::input_hash(&graph_bytes, &trajectories_bytes, &inputs);
    let (stage5, version5) = (crowd_collide::STAGE, crowd_collide::VERSION);
    let current = up_to_date(
        options.force,
        &collided_path,
        stage5,
        version5,
        hash,
        || TrajectoriesFile::load_stage(&collided_path, stage5, version5),
    );
    let fresh = current.is_some();
    let mut built_collided: Option<(Vec<u8>, TrajectoriesFile, Vec<PatchMotion>)> = None;
    outcomes.push(stage(
        ui,
        "collide",
        &collided_path,
        fresh,
        &mut timings,
        || {
            let (file, motion, writes) =
                collide_stage(&graph, &motion, &inputs, hash, &collided_path, ui);
            built_collided = Some((writes.last().expect("the RON file").1.clone(), file, motion));
            pending.0.extend(writes);
            Ok(())
        },
    )?);
    if options.until == Some(Stage::Collide) {
        return finish(&out, pending, &timings, outcomes);
    }
    let (collided_bytes, collided, motion) = match (built_collided, current) {
        (Some(built), _) => built,
        (None, current) => {
            let (bytes, (file, motion)) = current.expect("collide was built or is up to date");
            check_motion(&collided_path, graph.patches.len(), &motion)?;
            (bytes, file, motion)
        }
    };

    // Stage 6: smooth.
    let smoothed_path = out.join(SMOOTHED_FILE);
    let inputs = smooth_inputs(&pipeline);
    let hash = crowd_smooth::input_hash(&graph_bytes, &patterns_bytes, &collided_bytes, &inputs);
    let (stage6, version6) = (crowd_smooth::STAGE, crowd_smooth::VERSION);
    let current = up_to_date(
        options.force,
        &smoothed_path,
        stage6,
        version6,
        hash,
        || TrajectoriesFile::load_stage(&smoothed_path, stage6, version6),
    );
    let fresh = current.is_some();
    let mut smoothed: Option<(Vec<u8>, Vec<PatchMotion>)> = None;
    outcomes.push(stage(
        ui,
        "smooth",
        &smoothed_path,
        fresh,
        &mut timings,
        || {
            let (motion, writes) = smooth_stage(
                &graph,
                &crossings,
                &collided,
                &motion,
                &inputs,
                hash,
                &smoothed_path,
                ui,
            );
            let ron = writes
                .iter()
                .find(|(p, _)| *p == smoothed_path)
                .map(|(_, b)| b.clone())
                .expect("stage 6 writes its RON file");
            smoothed = Some((ron, motion));
            pending.0.extend(writes);
            Ok(())
        },
    )?);
    if options.until == Some(Stage::Smooth) {
        return finish(&out, pending, &timings, outcomes);
    }
    let (smoothed_bytes, final_motion) = match (smoothed, current) {
        (Some(built), _) => built,
        (None, current) => {
            let (bytes, (_, motion)) = current.expect("smooth was built or is up to date");
            check_motion(&smoothed_path, graph.patches.len(), &motion)?;
            (bytes, motion)
        }
    };
    drop(motion);

    // Stage 8: export (stage 7, edit, is optional and not built yet).
    let export_path = out.join(EXPORT_FILE);
    let inputs = export_inputs(&pipeline);
    let hash = crowd_export::input_hash(&graph_bytes, &patterns_bytes, &smoothed_bytes, &inputs);
    let fresh = !options.force && export_current(&export_path, hash);
    outcomes.push(stage(
        ui,
        "export",
        &export_path,
        fresh,
        &mut timings,
        || {
            let writes = export_stage(
                &graph,
                &crossings,
                &final_motion,
                &inputs,
                hash,
                &export_path,
            )?;
            pending.0.extend(writes);
            Ok(())
        },
    )?);

    finish(&out, pending, &timings, outcomes)
}

/// Stage 3 in memory, with a progress bar: what `crowd build` and `crowd optimize` both run.
pub fn optimize_stage(
    graph: &PatchGraph,
    inputs: &crowd_optimize::Inputs,
    hash: Hash,
    out: &Path,
    ui: &Ui,
) -> (crowd_optimize::Outcome, Patterns, Writes) {
    let bar = ui.stage_bar("optimize");
    let s = inputs;
    let outcome =
        crowd_optimize::optimize(graph, &s.settings, &s.matching, s.period_s, s.seed, &bar);
    let (patterns, writes) = crowd_optimize::encode(out, &outcome, s, hash);
    (outcome, patterns, writes)
}

/// Stage 4 in memory: what `crowd build` and `crowd match` both run.
pub fn match_stage(
    graph: &PatchGraph,
    patterns: &Patterns,
    crossings: &[Crossing],
    inputs: &crowd_match::Inputs,
    hash: Hash,
    out: &Path,
    ui: &Ui,
) -> (Vec<crowd_core::trajectories::PatchMotion>, Writes) {
    let bar = ui.stage_bar("match");
    let motion = crowd_match::match_all(graph, crossings, &patterns.measured, inputs, &bar);
    let (_, writes) = crowd_match::encode(out, &motion, graph, inputs, hash);
    (motion, writes)
}

/// Stage 5 in memory: what `crowd build` and `crowd collide` both run.
pub fn collide_stage(
    graph: &PatchGraph,
    motion: &[crowd_core::trajectories::PatchMotion],
    inputs: &crowd_collide::Inputs,
    hash: Hash,
    out: &Path,
    ui: &Ui,
) -> (TrajectoriesFile, Vec<PatchMotion>, Writes) {
    let bar = ui.stage_bar("collide");
    let s = inputs;
    let (motion, reports) = crowd_collide::collide(graph, motion, s, &bar);
    let (file, writes) = crowd_collide::encode(out, &motion, &reports, graph, s, hash);
    (file, motion, writes)
}

/// Stage 6 in memory: what `crowd build` and `crowd smooth` both run.
#[allow(clippy::too_many_arguments)]
pub fn smooth_stage(
    graph: &PatchGraph,
    crossings: &[Crossing],
    collided: &TrajectoriesFile,
    motion: &[PatchMotion],
    inputs: &crowd_smooth::Inputs,
    hash: Hash,
    out: &Path,
    ui: &Ui,
) -> (Vec<PatchMotion>, Writes) {
    let bar = ui.stage_bar("smooth");
    let (motion, summary) = crowd_smooth::smooth(graph, crossings, motion, inputs, &bar);
    let writes = crowd_smooth::encode(out, &motion, summary, collided, inputs, hash).1;
    (motion, writes)
}

/// Stage 8 in memory: what `crowd build` and `crowd export` both run. `out` is `export.ron`;
/// the library goes beside it.
pub fn export_stage(
    graph: &PatchGraph,
    crossings: &[Crossing],
    motion: &[PatchMotion],
    inputs: &crowd_export::Inputs,
    hash: Hash,
    out: &Path,
) -> Result<Writes> {
    let export = crowd_export::export(graph, crossings, motion, inputs, hash)
        .map_err(|e| anyhow::anyhow!("{}: cannot export: {e}", out.display()))?;
    Ok(crowd_export::writes(out, export))
}

/// What stage 8 reads of a pipeline.
pub fn export_inputs(pipeline: &PipelineFile) -> crowd_export::Inputs {
    let p = &pipeline.pipeline;
    crowd_export::Inputs {
        period_s: p.period_s,
        seed: p.seed,
        settings: p.export.clone(),
    }
}

/// What stage 6 reads of a pipeline.
pub fn smooth_inputs(pipeline: &PipelineFile) -> crowd_smooth::Inputs {
    let p = &pipeline.pipeline;
    crowd_smooth::Inputs {
        period_s: p.period_s,
        settings: p.smooth.clone(),
    }
}

/// What stage 5 reads of a pipeline.
pub fn collide_inputs(pipeline: &PipelineFile) -> crowd_collide::Inputs {
    crowd_collide::inputs(pipeline)
}

/// Writes the stage files of a build that succeeded, then the timings.
fn finish(
    out: &Path,
    pending: Pending,
    timings: &BTreeMap<String, StageRun>,
    outcomes: Vec<StageOutcome>,
) -> Result<Vec<StageOutcome>> {
    files::write_all(&pending.0)?;
    files::write_atomic(&out.join(TIMINGS_FILE), files::to_ron(timings).as_bytes())?;
    Ok(outcomes)
}

/// Runs one stage unless `fresh`, timing it and saying what happened.
fn stage(
    ui: &Ui,
    name: &'static str,
    output: &Path,
    fresh: bool,
    timings: &mut BTreeMap<String, StageRun>,
    run: impl FnOnce() -> Result<()>,
) -> Result<StageOutcome> {
    if fresh {
        ui.say(format!(
            "{name:>8}: up to date, skipped ({})",
            output.display()
        ));
        return Ok(StageOutcome {
            stage: name,
            seconds: None,
        });
    }
    memory::reset_peak();
    let start = Instant::now();
    run()?;
    let seconds = start.elapsed().as_secs_f64();
    let peak_mb = memory::peak_bytes().map(|b| b as f64 / 1e6);
    timings.insert(name.to_string(), StageRun { seconds, peak_mb });
    let peak = peak_mb
        .map(|mb| format!(", peak {mb:.0} MB"))
        .unwrap_or_default();
    ui.say(format!(
        "{name:>8}: built in {seconds:.3} s{peak} -> {}",
        output.display()
    ));
    Ok(StageOutcome {
        stage: name,
        seconds: Some(seconds),
    })
}

/// The bytes and contents of a stage file that can be kept: not `force`d, built by this stage
/// version from exactly `hash`, and readable whole (side files included). Loaded once, it both
/// lets the stage be skipped and feeds the next one. `None`: build the stage.
fn up_to_date<T>(
    force: bool,
    path: &Path,
    stage: &str,
    version: u32,
    hash: Hash,
    load: impl FnOnce() -> crowd_core::Result<T>,
) -> Option<(Vec<u8>, T)> {
    if force || !is_current(path, stage, version, hash) {
        return None;
    }
    let value = load().ok()?;
    Some((files::read_bytes(path).ok()?, value))
}

/// Whether the stage file at `path` was built by this stage version from exactly `hash`.
/// Stage 8 is up to date when `export.ron` records `hash` and the library beside it is the
/// one it names, byte for byte.
fn export_current(path: &Path, hash: Hash) -> bool {
    let Ok(file) = files::read_ron::<crowd_export::ExportFile>(path) else {
        return false;
    };
    file.header == Header::new(crowd_export::STAGE, crowd_export::VERSION, hash)
        && std::fs::read(path.with_file_name(&file.library))
            .is_ok_and(|b| Hash::of(&b) == file.library_hash)
        && std::fs::read(path.with_file_name(&file.gltf))
            .is_ok_and(|b| Hash::of(&b) == file.gltf_hash)
}

fn is_current(path: &Path, stage: &str, version: u32, hash: Hash) -> bool {
    files::read_header(path).is_ok_and(|h| h == Header::new(stage, version, hash))
}

/// What a stage cost when it last ran: wall time, and the most memory the process held while
/// it ran (None where the system does not say).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StageRun {
    pub seconds: f64,
    pub peak_mb: Option<f64>,
}

/// Stage costs of a build folder (empty when there are none yet, or from before they held
/// memory).
pub fn read_timings(dir: &Path) -> BTreeMap<String, StageRun> {
    files::read_ron(&dir.join(TIMINGS_FILE)).unwrap_or_default()
}

/// Creates the folder of an output file, proving it can be written.
pub fn ensure_parent(out: &Path) -> Result<()> {
    let dir = out.parent().filter(|p| !p.as_os_str().is_empty());
    files::ensure_writable_dir(dir.unwrap_or(Path::new(".")))?;
    Ok(())
}
