//! The build driver: runs the stages of the table in `stages.rs` in order and skips the ones
//! whose output is up to date.
//!
//! A stage is up to date when its file exists, is of the stage's format version, and records the
//! hash of exactly the inputs and settings the stage would read now (content hashes, not file
//! times: a fresh clone or a `touch` that changes nothing rebuilds nothing, and a changed pixel
//! always rebuilds). A rerun stage whose output bytes come out the same leaves the next stage up
//! to date.
//!
//! A build is all or nothing: stage outputs are kept in memory and written (each file
//! atomically) only once every stage has succeeded, so a build that fails changes no file.

use crate::artifacts::Artifacts;
use crate::memory;
use crate::stage::{self, Ran, Stage};
use crate::ui::Ui;
use anyhow::Result;
use crowd_core::config::PipelineFile;
use crowd_core::files;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Wall time of the last run of each stage. Not compared between builds: it is the one output
/// that is not deterministic.
pub const TIMINGS_FILE: &str = "timings.ron";

#[derive(Debug, Clone, Default)]
pub struct BuildOptions {
    /// Rebuild every stage.
    pub force: bool,
    /// Stop after this stage.
    pub until: Option<&'static Stage>,
    /// Build folder instead of the pipeline's `output`.
    pub output: Option<PathBuf>,
    /// The most memory the build may take, bytes (None: the machine's; `budget.rs`).
    pub max_memory: Option<u64>,
    /// One process's part of a build split over several, or the gathering of the parts.
    pub split: Split,
}

/// How a build shares its work with other processes (DESIGN.md, "Beyond one machine").
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Split {
    /// All of it here.
    #[default]
    Whole,
    /// Stages 1-3, then this shard's patches of stages 4 to 6 into `shards/` (and nothing
    /// after); or, told to stop at stage 3, stages 1-2 and this shard's regions of stage 3.
    Shard(crowd_core::Shard),
    /// Stages 4 to 6 (and 3, if not made) put together from every shard's files in
    /// `shards/`, then the rest.
    Gather,
}

/// What happened to one stage in a build.
#[derive(Debug, Clone, PartialEq)]
pub struct StageOutcome {
    pub stage: &'static str,
    /// `None` when the stage was up to date and skipped.
    pub seconds: Option<f64>,
}

/// Runs every stage of the pipeline at `pipeline_path` (up to `options.until`), holding the
/// output folder's lock, which it returns so that the caller's check and report are written
/// under it too.
pub fn build(
    pipeline_path: &Path,
    options: &BuildOptions,
    ui: &Ui,
) -> Result<(Vec<StageOutcome>, files::FolderLock)> {
    let pipeline = PipelineFile::load(pipeline_path)?;
    let out = options
        .output
        .clone()
        .unwrap_or_else(|| pipeline.output_dir());
    let mut artifacts = Artifacts::new(&pipeline, &out);
    artifacts.split = options.split;
    // The layers are read (headers checked, the region held to the maps) before the folder
    // is made: a refused painting leaves no trace.
    artifacts.layers()?;
    // A shard goes to stage 6 unless told to stop at its regions.
    let last = match (options.split, options.until) {
        (_, Some(stage)) => stage.number,
        (Split::Shard(_), None) => crate::stages::SMOOTH.number,
        (_, None) => crate::stages::EXPORT.number,
    };
    crate::budget::check(&pipeline, (options.split, last), options.max_memory)?;
    let existed = out.exists();
    std::fs::create_dir_all(&out)
        .map_err(|e| crowd_core::Error::io(&out, "create the output folder", e))?;
    let lock = lock(&out, ui)?;
    match run_stages(&out, &mut artifacts, options, ui) {
        Ok(outcomes) => Ok((outcomes, lock)),
        Err(e) => {
            // A refused build leaves no trace: a folder it made holds only its lock file.
            if !existed {
                drop(lock);
                let _ = std::fs::remove_file(out.join(files::FolderLock::FILE));
                let _ = std::fs::remove_dir(&out);
            }
            Err(e)
        }
    }
}

/// The stages of [`build`] in order, under the folder's lock; their files written only when
/// every stage has succeeded.
fn run_stages(
    out: &Path,
    artifacts: &mut Artifacts,
    options: &BuildOptions,
    ui: &Ui,
) -> Result<Vec<StageOutcome>> {
    let mut timings = read_timings(out);
    let mut pending = files::Staging::new();
    let mut outcomes = Vec::new();
    // Whether files can be written is proved before the first stage that runs does any work.
    let mut writable = false;
    let mut stale = Vec::new();
    // A shard goes no further than its part of stage 6; told to stop at stage 3, it does only
    // its share of the regions.
    let until = match options.split {
        Split::Shard(_) => Some(options.until.unwrap_or(&crate::stages::SMOOTH)),
        _ => options.until,
    };
    artifacts.regions_only = matches!(options.split, Split::Shard(_))
        && until.is_some_and(|u| *u == crate::stages::OPTIMIZE);
    for stage in stage::up_to(until) {
        if !(stage.applies)(artifacts.pipeline) {
            // An edit stage's files from a build that had edits would be read as this one's
            // (`crowd check` reads the latest trajectories in the folder).
            stale.extend(
                stage
                    .writes
                    .iter()
                    .map(|name| out.join(name))
                    .filter(|path| path.exists()),
            );
            continue;
        }
        let path = out.join(stage.output);
        let hash = (stage.hash)(artifacts)?;
        artifacts.hashes.insert(stage.name, hash);
        // A shard's part is its own file, not the stage's: it always runs.
        let sharded = matches!(options.split, Split::Shard(_))
            && (crate::stages::SHARDED.contains(&stage)
                || (artifacts.regions_only && *stage == crate::stages::OPTIMIZE));
        if !options.force && !sharded && (stage.fresh)(artifacts, &path, hash)? {
            ui.say(format!(
                "{:>8}: up to date, skipped ({})",
                stage.name,
                path.display()
            ));
            // Its last output, read ahead, is not needed: not held through the build.
            artifacts.previous.forget(&path);
            outcomes.push(StageOutcome {
                stage: stage.name,
                seconds: None,
            });
            continue;
        }
        if !writable {
            files::ensure_writable_dir(out)?;
            writable = true;
            // A stage runs: the later stages likely will, and stages 4-6 reuse patches of
            // the last build's side files. Read those of this stage and the ones after it
            // that this build goes to meanwhile (a shard reuses none).
            if options.split == Split::Whole {
                let reused = [
                    &crate::stages::MATCH,
                    &crate::stages::COLLIDE,
                    &crate::stages::SMOOTH,
                ];
                let ahead = stage::up_to(until)
                    .skip_while(|s| *s != stage)
                    .filter(|s| reused.contains(s));
                artifacts.previous =
                    crate::reuse::Prefetch::start(ahead.map(|s| out.join(s.output)));
            }
        }
        let (ran, run) = timed(|| (stage.run)(artifacts, &path, hash, ui))?;
        if let Some(bytes) = ran.bytes_of(&path) {
            artifacts.keep_hash(stage, bytes);
        }
        for file in ran.streamed {
            pending.stage_streamed(file);
        }
        for (path, bytes) in ran.shared {
            pending.stage_shared(path, bytes);
        }
        pending.stage(ran.writes);
        for (path, hash) in ran.hashes {
            pending.know(path, hash);
        }
        let peak = run
            .peak_mb
            .map(|mb| format!(", peak {mb:.0} MB"))
            .unwrap_or_default();
        let note = ran
            .note
            .as_ref()
            .map(|n| format!(" ({n})"))
            .unwrap_or_default();
        ui.say(format!(
            "{:>8}: built in {:.3} s{peak} -> {}{note}",
            stage.name,
            run.seconds,
            path.display()
        ));
        // Its parts' times replace those of its last run (an edit removed leaves none).
        let part = |name: &str| format!("{}: {name}", stage.name);
        timings.retain(|k, _| !k.starts_with(&part("")));
        for (name, seconds) in &ran.parts {
            let run = StageRun {
                seconds: *seconds,
                peak_mb: None,
            };
            timings.insert(part(name), run);
        }
        timings.insert(stage.name.to_string(), run);
        outcomes.push(StageOutcome {
            stage: stage.name,
            seconds: Some(run.seconds),
        });
    }
    // Up to date means read-only: a build that ran nothing writes nothing, not even its
    // timings, so that it succeeds in a read-only folder and wakes no one who watches it.
    if outcomes.iter().any(|o| o.seconds.is_some()) {
        pending.commit()?;
        files::write_atomic(&out.join(TIMINGS_FILE), files::to_ron(&timings).as_bytes())?;
    }
    for path in stale {
        std::fs::remove_file(&path).map_err(|e| crowd_core::Error::io(&path, "remove", e))?;
    }
    Ok(outcomes)
}

/// Takes the build folder `dir`'s lock, saying so when another build or check holds it.
pub fn lock(dir: &Path, ui: &Ui) -> Result<files::FolderLock> {
    Ok(files::FolderLock::acquire(dir, || {
        ui.say(format!(
            "waiting: another build or check is writing in {} (its lock: {})",
            dir.display(),
            files::FolderLock::FILE
        ))
    })?)
}

/// Runs one stage alone (`crowd merge`, `crowd graph`, ...): reads `input` (default: the
/// stage file it reads in the pipeline's output folder) and the files beside it, writes
/// `output` (default: its file in the output folder) and the files beside that. Prints what it
/// wrote.
pub fn run_stage(
    stage: &'static Stage,
    pipeline: &PipelineFile,
    input: Option<PathBuf>,
    output: Option<PathBuf>,
    ui: &Ui,
) -> Result<()> {
    let dir = pipeline.output_dir();
    let out = output.unwrap_or_else(|| dir.join(stage.output));
    ensure_parent(&out)?;
    let mut artifacts = match (stage.main_input(), input) {
        (Some(name), Some(input)) => Artifacts::beside(pipeline, name, &input),
        _ => Artifacts::new(pipeline, &dir),
    };
    let hash = (stage.hash)(&mut artifacts)?;
    let Ran {
        writes,
        streamed,
        shared,
        note,
        ..
    } = (stage.run)(&mut artifacts, &out, hash, ui)?;
    let mut pending = files::Staging::new();
    for file in streamed {
        pending.stage_streamed(file);
    }
    for (path, bytes) in shared {
        pending.stage_shared(path, bytes);
    }
    pending.stage(writes);
    pending.commit()?;
    let note = note.map(|n| format!(" ({n})")).unwrap_or_default();
    ui.say(format!("{}: wrote {}{note}", stage.name, out.display()));
    Ok(())
}

/// Runs `run`, measuring its wall time and the most memory the process held meanwhile.
pub(crate) fn timed<T>(run: impl FnOnce() -> Result<T>) -> Result<(T, StageRun)> {
    memory::reset_peak();
    let start = Instant::now();
    let value = run()?;
    let seconds = start.elapsed().as_secs_f64();
    let peak_mb = memory::peak_bytes().map(|b| b as f64 / 1e6);
    Ok((value, StageRun { seconds, peak_mb }))
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
