//! The build driver: runs the stages in order and skips the ones whose output is up to date.
//!
//! A stage is up to date when its file exists, is of the stage's format version, and records the
//! hash of exactly the inputs and settings the stage would read now (content hashes, not file
//! times: a fresh clone or a `touch` that changes nothing rebuilds nothing, and a changed pixel
//! always rebuilds). A rerun stage whose output bytes come out the same leaves the next stage up
//! to date.

use crate::ui::Ui;
use anyhow::Result;
use crowd_core::config::PipelineFile;
use crowd_core::files::{self, Header};
use crowd_core::maps::MergeFile;
use crowd_core::{Error, Hash, PatchGraph};
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

pub const MERGE_FILE: &str = "merge.ron";
pub const GRAPH_FILE: &str = "graph.ron";
/// Wall time of the last run of each stage. Not compared between builds: it is the one output
/// that is not deterministic.
pub const TIMINGS_FILE: &str = "timings.ron";

#[derive(Debug, Clone, Default)]
pub struct BuildOptions {
    pub force: bool,
}

/// What happened to one stage in a build.
#[derive(Debug, Clone, PartialEq)]
pub struct StageOutcome {
    pub stage: &'static str,
    /// `None` when the stage was up to date and skipped.
    pub seconds: Option<f64>,
}

/// Runs every stage of the pipeline at `pipeline_path`.
pub fn build(pipeline_path: &Path, options: &BuildOptions, ui: &Ui) -> Result<Vec<StageOutcome>> {
    let pipeline = PipelineFile::load(pipeline_path)?;
    let out = pipeline.output_dir();
    files::ensure_writable_dir(&out)?;
    let mut timings = read_timings(&out);
    let mut outcomes = Vec::new();

    // Stage 1: merge.
    let merge_path = out.join(MERGE_FILE);
    let layers = crowd_merge::read_layers(&pipeline)?;
    let hash = crowd_merge::input_hash(&pipeline, &layers);
    let fresh = !options.force
        && is_current(&merge_path, MergeFile::STAGE, MergeFile::VERSION, hash)
        && MergeFile::load(&merge_path).is_ok();
    outcomes.push(stage(
        ui,
        "merge",
        &merge_path,
        fresh,
        &mut timings,
        || {
            let bar = ui.stage_bar("merge");
            let decoded = crowd_merge::decode(&layers)?;
            let maps = crowd_merge::merge(
                &decoded,
                &pipeline.pipeline.merge,
                pipeline.pipeline.scene.meters_per_pixel,
                &bar,
            );
            crowd_merge::write(&merge_path, &pipeline, &layers, &decoded, hash, &maps)?;
            Ok(())
        },
    )?);

    // Stage 2: graph.
    let graph_path = out.join(GRAPH_FILE);
    let merge_bytes = std::fs::read(&merge_path).map_err(|e| Error::io(&merge_path, "read", e))?;
    let hash = crowd_graph::input_hash(&merge_bytes, &crowd_graph::inputs(&pipeline));
    let fresh =
        !options.force && is_current(&graph_path, PatchGraph::STAGE, PatchGraph::VERSION, hash);
    outcomes.push(stage(
        ui,
        "graph",
        &graph_path,
        fresh,
        &mut timings,
        || {
            let bar = ui.stage_bar("graph");
            crowd_graph::run(&pipeline, &merge_path, &graph_path, &bar)?;
            Ok(())
        },
    )?);

    files::write_atomic(&out.join(TIMINGS_FILE), files::to_ron(&timings).as_bytes())?;
    Ok(outcomes)
}

/// Runs one stage unless `fresh`, timing it and saying what happened.
fn stage(
    ui: &Ui,
    name: &'static str,
    output: &Path,
    fresh: bool,
    timings: &mut BTreeMap<String, f64>,
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
    let start = Instant::now();
    run()?;
    let seconds = start.elapsed().as_secs_f64();
    timings.insert(name.to_string(), seconds);
    ui.say(format!(
        "{name:>8}: built in {seconds:.3} s -> {}",
        output.display()
    ));
    Ok(StageOutcome {
        stage: name,
        seconds: Some(seconds),
    })
}

/// Whether the stage file at `path` was built by this stage version from exactly `hash`.
fn is_current(path: &Path, stage: &str, version: u32, hash: Hash) -> bool {
    files::read_header(path).is_ok_and(|h| {
        h == Header {
            stage: stage.to_string(),
            version,
            input_hash: hash,
        }
    })
}

/// Stage timings of a build folder (empty when there are none yet).
pub fn read_timings(dir: &Path) -> BTreeMap<String, f64> {
    files::read_ron(&dir.join(TIMINGS_FILE)).unwrap_or_default()
}

/// Creates the folder of an output file, proving it can be written.
pub fn ensure_parent(out: &Path) -> Result<()> {
    let dir = out.parent().filter(|p| !p.as_os_str().is_empty());
    files::ensure_writable_dir(dir.unwrap_or(Path::new(".")))?;
    Ok(())
}
