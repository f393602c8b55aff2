//! `crowd check DIR`, and the step `crowd build` runs after stage 8 (unless `--no-check`):
//! the latest trajectories of a build folder (crowd-check on the stage file), then what ships,
//! read as an engine reads it (`library.crowd` through crowd-runtime, `world.glb` through the
//! gltf crate), all into `check.ron`. It is not a stage of the table: it writes no input of
//! any stage, and its time goes into `timings.ron` as `check`.

use crate::driver::{StageRun, TIMINGS_FILE, read_timings, timed};
use crate::stage::Stage;
use crate::stages::{self, GRAPH_FILE, PATTERNS_FILE};
use crate::ui::Ui;
use anyhow::{Context, Result, bail};
use crowd_check::library::{InFile, Source};
use crowd_check::memo::{Memo, MemoWriter, Recalled, StageWriter};
use crowd_check::{CheckReport, Judged, ProductFigures};
use crowd_core::config::PipelineFile;
use crowd_core::files;
use crowd_core::patterns::Patterns;
use crowd_core::trajectories::TrajectoriesFile;
use crowd_core::{Hash, Hasher, PatchGraph};
use crowd_export::{GLB_FILE, LIBRARY_FILE};
use std::path::Path;

/// What `crowd check` writes.
pub const CHECK_FILE: &str = "check.ron";
/// What a check keeps of each patch for the next one (`crowd_check::memo`): a cache, rewritten
/// by every check that runs.
pub const MEMO_FILE: &str = "check.memo";
/// The runtime's sampler plays the library every this many seconds over one period.
pub const SAMPLE_STEP_S: f64 = 0.02;

/// What a check is asked for.
#[derive(Debug, Clone, Copy)]
pub struct CheckOptions {
    /// The stage whose trajectories to check (None: the latest in the folder).
    pub stage: Option<&'static Stage>,
    /// `match.max_speed` of the build's pipeline, m/s (the shipped speed limit is 5 % above).
    pub max_speed: f64,
    /// `export.turn_rate_deg_s` of the build's pipeline: no character may turn faster (plus
    /// the keys' rounding, [`TURN_MARGIN`]).
    pub turn_rate_deg_s: f64,
    /// Whether the stage file and the shipped files are judged at once (faster: each works
    /// while the other waits on its serial parts) or one after the other (the stage file's part
    /// of the memo written and let go first: half as much memory again held at once); `None`:
    /// at once where the stage's side file is under [`SMALL_WORLD_BYTES`]. Either way the
    /// same `check.ron` and `check.memo`.
    pub at_once: Option<bool>,
}

/// The shipped files' headings may turn this much faster than `export.turn_rate_deg_s`: f32
/// key times and quaternions, the library's 65536ths of a turn (0.1 % on the shared scenes).
pub const TURN_MARGIN: f64 = 1.01;

impl Default for CheckOptions {
    fn default() -> Self {
        CheckOptions {
            stage: None,
            max_speed: crowd_core::config::MatchSettings::default().max_speed,
            turn_rate_deg_s: crowd_core::config::ExportSettings::default().turn_rate_deg_s,
            at_once: None,
        }
    }
}

/// Checks the build folder `dir`, writes `check.ron` and the check's time in `timings.ron`
/// (returned too).
pub fn check(dir: &Path, options: &CheckOptions) -> Result<(CheckReport, StageRun, Redone)> {
    stages::expect_build_folder(dir)?;
    let ((report, memo, redone), run) = timed(|| measure(dir, options))?;
    // The memo before `check.ron`: a check whose `check.ron` is up to date is skipped, so a
    // check killed between the two must leave `check.ron` stale, not the memo (a killed build's
    // next check would keep the last check's memo beside a fresh report).
    memo.put_in_place()?;
    files::write_atomic(&dir.join(CHECK_FILE), files::to_ron(&report).as_bytes())?;
    let mut timings = read_timings(dir);
    timings.insert("check".to_string(), run);
    files::write_atomic(&dir.join(TIMINGS_FILE), files::to_ron(&timings).as_bytes())?;
    Ok((report, run, redone))
}

/// How much of the world a check judged again, the rest taken from the last check's memo:
/// patches of the stage file (their own share, the pairs they own) and of the library (the
/// pairs they own), each of how many.
#[derive(Debug, Clone, Copy, Default)]
pub struct Redone {
    pub stage_own: (usize, usize),
    pub stage_pairs: (usize, usize),
    pub library_pairs: (usize, usize),
    /// Walkers the runtime's sampler played again.
    pub played: (usize, usize),
}

impl Redone {
    /// "judged again: ..." for the build's line (empty when all was judged).
    pub fn note(&self) -> String {
        let parts = [
            ("patches", self.stage_own),
            ("their pairs", self.stage_pairs),
            ("the library's", self.library_pairs),
            ("walkers played", self.played),
        ];
        if parts.iter().all(|(_, (done, of))| done == of) {
            return String::new();
        }
        let said: Vec<String> = parts
            .iter()
            .filter(|(_, (_, of))| *of > 0)
            .map(|(what, (done, of))| format!("{what} {done} of {of}"))
            .collect();
        format!(" (judged again: {})", said.join(", "))
    }
}

/// `crowd check DIR [--stage STAGE] [--pipeline FILE]`: checks, refreshes `report.md`, and
/// returns the summary to print.
pub fn command(
    dir: &Path,
    stage: Option<&'static Stage>,
    pipeline: Option<&Path>,
) -> Result<String> {
    if !dir.is_dir() {
        bail!("{}: no such build folder", dir.display());
    }
    let _lock = files::FolderLock::acquire(dir, || {
        crate::ui::say(format!(
            "waiting: another build or check is writing in {}",
            dir.display()
        ))
    })?;
    let mut options = CheckOptions {
        stage,
        ..Default::default()
    };
    if let Some(p) = pipeline {
        let file = PipelineFile::load(p)?;
        options.max_speed = file.pipeline.matching.max_speed;
        options.turn_rate_deg_s = file.pipeline.export.turn_rate_deg_s;
    }
    let (report, _, _) = check(dir, &options)?;
    crate::report_md::write(dir, Default::default())?;
    let summary = check_summary(&report);
    let findings = findings(&report);
    if !findings.is_empty() {
        crate::ui::out(&summary)?;
        return Err(crate::cli::Broken(format!(
            "{}: {} guarantee(s) broken:\n  {}",
            dir.display(),
            findings.len(),
            findings.join("\n  ")
        ))
        .into());
    }
    Ok(summary)
}

/// The guarantees `report` finds broken in what ships, as `crate::warnings` says them
/// (collisions, speed, loops, turns, the sampler's jumps). A stage file checked on its own
/// (`--stage match`, before stage 5 has pushed anyone apart) is a figure, not a finding.
pub fn findings(report: &CheckReport) -> Vec<String> {
    crate::warnings::shipped(report)
        .into_iter()
        .map(|w| w.text)
        .collect()
}

/// The check `crowd build` runs after stage 8: skipped when `check.ron` is up to date (unless
/// `force`), else run, with its summary said. A gathering build's judges its parts one after
/// the other whatever the world's size (`gathering`): it is the step a job runner sizes by its
/// memory (the quarter of the million, just under [`SMALL_WORLD_BYTES`], held 1.15 GB at once).
pub fn after_build(
    out: &Path,
    (max_speed, turn_rate_deg_s): (f64, f64),
    (force, gathering): (bool, bool),
    ui: &Ui,
) -> Result<()> {
    let options = CheckOptions {
        stage: None,
        max_speed,
        turn_rate_deg_s,
        at_once: gathering.then_some(false),
    };
    let path = out.join(CHECK_FILE);
    if !force && fresh(out, &options)? {
        ui.say(format!(
            "   check: up to date, skipped ({})",
            path.display()
        ));
        return Ok(());
    }
    let (report, run, redone) = check(out, &options)?;
    let seconds = run.seconds;
    ui.say(format!(
        "   check: done in {seconds:.3} s -> {}{}",
        path.display(),
        redone.note()
    ));
    ui.say(check_summary(&report).trim_end());
    Ok(())
}

/// Whether `dir`'s `check.ron` was made from exactly the files and settings a check would read
/// now.
pub fn fresh(dir: &Path, options: &CheckOptions) -> Result<bool> {
    let Ok(old) = files::read_ron::<CheckReport>(&dir.join(CHECK_FILE)) else {
        return Ok(false);
    };
    let stage = chosen(dir, options.stage)?;
    Ok(old.input_hash == Some(input_hash(dir, stage, options)?))
}

/// The trajectories a check reads: `stage`'s, or the latest in the folder.
fn chosen(dir: &Path, stage: Option<&'static Stage>) -> Result<&'static Stage> {
    let found = stages::TRAJECTORY_STAGES
        .iter()
        .copied()
        .find(|c| stage.map_or(dir.join(c.output).exists(), |s| s == *c));
    let Some(chosen) = found else {
        bail!(
            "{}: no trajectories to check; expected one of {}",
            dir.display(),
            stages::TRAJECTORY_STAGES.map(|s| s.output).join(", ")
        );
    };
    Ok(chosen)
}

/// The hash of the files a check of `stage`'s trajectories reads (a stage file's RON text
/// holds its side file's hash) and of its settings.
fn input_hash(dir: &Path, stage: &Stage, options: &CheckOptions) -> Result<Hash> {
    let mut h = Hasher::new("check", crowd_check::VERSION);
    for file in [
        GRAPH_FILE,
        PATTERNS_FILE,
        stage.output,
        LIBRARY_FILE,
        GLB_FILE,
        stages::EXPORT_FILE,
    ] {
        let path = dir.join(file);
        // Hashed as read, not held: the million's library is 904 MB.
        let hash = match Hash::of_file(&path) {
            Ok((_, hash)) => Some(hash),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
            Err(e) => return Err(e).with_context(|| format!("{}", path.display())),
        };
        h.value(file, &hash);
    }
    h.value("match.max_speed", &options.max_speed);
    h.value("export.turn_rate_deg_s", &options.turn_rate_deg_s);
    h.value("sample_step_s", &SAMPLE_STEP_S);
    Ok(h.finish())
}

fn measure(
    dir: &Path,
    options: &CheckOptions,
) -> Result<(CheckReport, files::StreamedFile, Redone)> {
    let graph = PatchGraph::load_shared(&dir.join(GRAPH_FILE))?;
    let chosen = chosen(dir, options.stage)?;
    // The stage's files are read (versions, sizes, hashes) before anything is judged: a
    // stale folder is refused in a second, not after the products' minute on the million.
    // The last check's memo is read meanwhile (painting's 62 MB: a tenth of a second).
    // On a small world (see below) `library.crowd` is read and loaded meanwhile too: painting's
    // takes 0.14 s on one core, which the library's judging, the check's longest part, waited
    // for.
    let small = options.at_once.unwrap_or_else(|| small_world(dir, chosen));
    let ((stage, memo), loaded) = rayon::join(
        || {
            rayon::join(
                || StageFiles::open(dir, &graph, chosen),
                || {
                    let mut memo = std::fs::read(dir.join(MEMO_FILE))
                        .ok()
                        .and_then(|b| Memo::from_bytes(&b))
                        .unwrap_or_default()
                        .recall();
                    // What the shards judged of their own patches, after a gathering build.
                    crate::check_shard::take_parts(dir, &dir.join(MEMO_FILE), &mut memo);
                    memo
                },
            )
        },
        || small.then(|| load_library(dir)),
    );
    let stage = stage?;
    let mut memo = memo;
    let walls = crowd_check::walls(&graph);
    let limit = options.max_speed * crowd_check::products::SPEED_MARGIN;
    // The stage file and the products read different files and share nothing. On a small
    // world they are judged at once, each while the other waits on its serial parts (reading,
    // decoding, sorting), which left a core idle (ring's check: 0.86 -> 0.75 s; with the memo,
    // the library and the glTF at once as well: painting's stroke 2.7 -> 2.5 s); on a big one,
    // one after the other, as together they hold half as much memory again. Since the check
    // takes a strip of the world at a time, painting is small: 11.8 -> 10.8 s at once, 1.0 ->
    // 1.4 GB (it held 2.4 -> 3.5 GB when the stage file was one scene).
    // A large library is judged from its file, a part of its points at a time.
    let library = |memo: &Recalled| {
        match loaded {
            Some(lib) => lib?.map(|lib| library(dir, &lib, &walls, limit, memo)),
            None => open_library(dir)?.map(|lib| library(dir, &lib, &walls, limit, memo)),
        }
        .transpose()
    };
    let gltf = || gltf(dir, &graph, &walls, limit);
    // The new memo is begun with each patch's own share as the stage file's check takes it.
    let memo_path = dir.join(MEMO_FILE);
    let shares = stage.keys.as_ref().map_or(0, Vec::len);
    let mut begun = StageWriter::start(files::Streamed::create(&memo_path)?, shares);
    let (stage, (library, gltf), writer) = if small {
        let (stage, products) = rayon::join(
            || stage_figures(&graph, stage, &memo, &mut begun),
            || rayon::join(|| library(&memo), gltf),
        );
        let mut stage = stage?;
        let writer = end_stage(begun, &mut stage, &memo_path)?;
        (stage, products, writer)
    } else {
        let mut stage = stage_figures(&graph, stage, &memo, &mut begun)?;
        // The stage file's shares are looked up no more (the million's: 0.3 GB), and its
        // part of the new memo is ended before the library is judged.
        memo.forget_stage();
        let writer = end_stage(begun, &mut stage, &memo_path)?;
        (stage, (library(&memo), gltf()), writer)
    };
    drop(memo);
    let library = library?;
    let n = graph.patches.len();
    let mut redone = Redone {
        stage_own: (stage.redone.0, n),
        stage_pairs: (stage.redone.1, n),
        library_pairs: (0, 0),
        played: (0, 0),
    };
    let mut report = stage.report;
    let library_memo = library.map(|l| {
        redone.library_pairs = l.redone;
        redone.played = l.played;
        report.library = Some(l.judged.figures);
        l.judged.memo
    });
    let memo = (writer.finish(library_memo.as_ref()))
        .map_err(|e| crowd_core::Error::io(&memo_path, "write", e))?
        .finish()?;
    report.gltf = gltf?;
    // What is judged must be what stage 8 wrote: each file against the manifest's size and hash.
    let manifest = dir.join(stages::EXPORT_FILE);
    let named = files::read_ron::<crowd_export::ExportFile>(&manifest).ok();
    let unnamed = || {
        Some(format!(
            "{} does not name it (build again)",
            manifest.display()
        ))
    };
    if let Some(p) = report.library.as_mut() {
        p.unlike_manifest = named
            .as_ref()
            .map_or_else(unnamed, |m| m.library_differs(&manifest));
    }
    if let Some(p) = report.gltf.as_mut() {
        p.unlike_manifest = named
            .as_ref()
            .map_or_else(unnamed, |m| m.gltf_differs(&manifest));
    }
    let turn_limit = options.turn_rate_deg_s.to_radians() * TURN_MARGIN;
    for p in [&mut report.library, &mut report.gltf]
        .into_iter()
        .flatten()
    {
        p.turn_rate_limit_rad_s = Some(turn_limit);
    }
    report.input_hash = Some(input_hash(dir, chosen, options)?);
    Ok((report, memo, redone))
}

/// Whether the world is small enough to judge its three forms at once: its stage file's
/// side file under [`SMALL_WORLD_BYTES`] (what the judgements hold grows with it).
fn small_world(dir: &Path, chosen: &Stage) -> bool {
    let side = dir.join(chosen.output).with_extension("bin");
    std::fs::metadata(side).is_ok_and(|m| m.len() < SMALL_WORLD_BYTES)
}

/// See [`small_world`] (and [`CheckOptions::at_once`]): ring's and city's stage 6 side files are 22 MB, painting's 412, the
/// million's 4,200 (whose check holds 5.8 GB one part after the other).
pub const SMALL_WORLD_BYTES: u64 = 1 << 30;

/// What the check of a stage's trajectories reads: its file, its motion left in its side file,
/// the crossings of the patterns beside it, and the stage's patch keys when they belong to
/// this side file (`STAGE.keys`; without them every patch is judged).
struct StageFiles {
    stage: &'static Stage,
    file: TrajectoriesFile,
    motion: crowd_core::trajectories::LazyMotion,
    crossings: Vec<crowd_core::patterns::Crossing>,
    keys: Option<Vec<Hash>>,
}

impl StageFiles {
    fn open(dir: &Path, graph: &PatchGraph, stage: &'static Stage) -> Result<StageFiles> {
        let (_, crossings) = Patterns::load_for(&dir.join(PATTERNS_FILE), graph)?;
        let path = dir.join(stage.output);
        let patches = graph.patches.len();
        let (file, motion) = TrajectoriesFile::open_for(&path, stage.kind, stage.version, patches)?;
        let keys = std::fs::read(crate::reuse::keys_path(&path))
            .ok()
            .and_then(|b| crowd_core::patch_keys::Keys::decode(&b))
            .filter(|k| k.side == file.motion.hash && k.patches.len() == patches)
            .map(|k| k.patches.into_iter().map(|r| r.key).collect());
        Ok(StageFiles {
            stage,
            file,
            motion,
            crossings,
            keys,
        })
    }
}

/// The stage file's part of the new memo at `path`, ended with the pairs `judged` holds (let
/// go).
fn end_stage(
    begun: StageWriter<files::Streamed>,
    judged: &mut Judged,
    path: &Path,
) -> Result<MemoWriter<files::Streamed>> {
    let pairs = std::mem::take(&mut judged.pairs);
    (begun.pairs(&pairs)).map_err(|e| crowd_core::Error::io(path, "write", e).into())
}

/// The check of a stage's trajectories, with their motion figures: decoded a strip of the
/// world at a time (`crowd_check::shares`, then `crowd_check::pairs`).
fn stage_figures(
    graph: &PatchGraph,
    s: StageFiles,
    memo: &Recalled,
    out: &mut StageWriter<files::Streamed>,
) -> Result<Judged> {
    let StageFiles {
        stage,
        file,
        motion,
        crossings,
        keys,
    } = s;
    let shares = {
        let world = crowd_check::World {
            graph,
            source: &motion,
            period_s: file.period_s,
            crossings: Some((&crossings).into()),
        };
        crowd_check::shares(&world, keys.as_deref(), memo, Some(out))?
    };
    // The crossings are read no more: let go before the strips' pairs (the million's 92 MB).
    drop(crossings);
    let world = crowd_check::World {
        graph,
        source: &motion,
        period_s: file.period_s,
        crossings: None,
    };
    let mut judged = crowd_check::pairs(&world, shares, memo)?;
    judged.report.stage = stage.kind.to_string();
    Ok(judged)
}

/// The library's figures, and how many of its patches' pairs were judged again and of its walkers
/// played again (each of how many).
struct LibraryJudged {
    judged: crowd_check::library::Judged,
    redone: (usize, usize),
    played: (usize, usize),
}

/// `library.crowd` as the runtime loads it, when the folder holds one.
fn load_library(dir: &Path) -> Result<Option<crowd_runtime::Library>> {
    // Read a piece at a time: the library and its bytes at once were 1.8 GB of the million's
    // check, the spike of its peak.
    with_library(dir, crowd_runtime::Library::read_from)
}

/// `library.crowd` opened as the runtime opens it, its points left in the file, when the
/// folder holds one.
fn open_library(dir: &Path) -> Result<Option<InFile<std::fs::File>>> {
    let file = with_library(dir, crowd_runtime::LibraryFile::open)?;
    Ok(file.map(|file| InFile {
        file,
        budget: crowd_check::library::FILE_BUDGET,
    }))
}

/// `read` of the folder's `library.crowd`, when it holds one; its refusal names the file.
fn with_library<T>(
    dir: &Path,
    read: impl FnOnce(std::fs::File) -> Result<T, crowd_runtime::LoadError>,
) -> Result<Option<T>> {
    let path = dir.join(LIBRARY_FILE);
    if !path.exists() {
        return Ok(None);
    }
    let file = std::fs::File::open(&path).with_context(|| format!("{}", path.display()))?;
    let read = read(file).with_context(|| format!("{}: the runtime refuses it", path.display()))?;
    Ok(Some(read))
}

/// The figures of a library ([`load_library`], [`open_library`]).
fn library(
    dir: &Path,
    src: &impl Source,
    walls: &[crowd_check::Wall],
    limit: f64,
    memo: &Recalled,
) -> Result<LibraryJudged> {
    let inputs = crowd_check::library::Inputs {
        walls,
        speed_limit_m_s: limit,
        sample_step_s: Some(SAMPLE_STEP_S),
    };
    let judged = crowd_check::library::judge(src, &inputs, memo).with_context(|| {
        let path = dir.join(LIBRARY_FILE);
        format!("{}: the runtime refuses it", path.display())
    })?;
    let lib = src.lib();
    let redone = (judged.redone, lib.patches.len());
    let played = (judged.replayed, lib.walkers() as usize);
    Ok(LibraryJudged {
        judged,
        redone,
        played,
    })
}

/// The figures of `world.glb`, when the folder holds one.
fn gltf(
    dir: &Path,
    graph: &PatchGraph,
    walls: &[crowd_check::Wall],
    limit: f64,
) -> Result<Option<ProductFigures>> {
    let path = dir.join(GLB_FILE);
    if !path.exists() {
        return Ok(None);
    }
    let bytes = std::fs::read(&path).with_context(|| format!("{}", path.display()))?;
    let w = &graph.world;
    let inputs = crowd_check::glb::Inputs {
        radius_m: graph.radius_m,
        walls,
        speed_limit_m_s: limit,
        world_m: w.covered_m(),
    };
    let figures = crowd_check::glb::figures(&bytes, &inputs)
        .with_context(|| format!("{}: cannot be played", path.display()))?;
    Ok(Some(figures))
}

/// What `crowd check` prints: collisions and clearance, the motion figures, then what ships.
pub fn check_summary(report: &CheckReport) -> String {
    let worst = report
        .worst_at
        .map(|(x, y, t)| format!(" at ({x:.2}, {y:.2}) m, t = {t:.2} s"))
        .unwrap_or_default();
    let mut s = format!(
        "{} walkers, {} segments: {} collisions ({} across borders); smallest clearance \
         {:+.3} m{worst}\n",
        report.walkers,
        report.segments,
        report.collisions,
        report.across_borders,
        report.min_clearance_m,
    );
    if let Some(m) = &report.motion {
        s += &format!(
            "{}: walking speed in 0.5-1.8 m/s {:.1} % of the time; acceleration p95 {:.3} m/s2; \
             turning rate p95 {:.3} rad/s\n",
            report.stage,
            100.0 * m.speed_in_band,
            m.accel_p95,
            m.turn_rate_p95
        );
        s += &format!(
            "borders: largest velocity jump {:.3} m/s; ends off their crossings by at most \
             {:.2e} m and {:.2e} s; {} crossings not entered and left once\n",
            m.max_border_velocity_jump,
            m.max_boundary_error_m,
            m.max_boundary_time_error_s,
            m.unmatched_crossings
        );
    }
    for p in [&report.library, &report.gltf].into_iter().flatten() {
        s += &product_summary(p);
    }
    s
}

/// A shipped file's figures in three lines.
fn product_summary(p: &ProductFigures) -> String {
    let at = |w: Option<(f64, f64, f64)>| {
        w.map(|(x, y, t)| format!(" at ({x:.2}, {y:.2}) m, t = {t:.2} s"))
            .unwrap_or_default()
    };
    let mut s = format!(
        "{}: {} walkers, {} standers, {} pieces: {} collisions; smallest clearance {:+.3} m{}\n",
        p.file,
        p.walkers,
        p.standers,
        p.pieces,
        p.collisions,
        p.min_clearance_m,
        at(p.worst_at)
    );
    s += &format!(
        "  fastest {:.3} m/s{}; {:.2} % of walking time above {:.3} m/s; velocity jumps: at \
         keys {:.3}",
        p.max_speed_m_s,
        at(p.max_speed_at),
        100.0 * p.share_above_limit,
        p.speed_limit_m_s,
        p.max_key_velocity_jump,
    );
    if let (Some(jump), Some(gap)) = (p.max_border_velocity_jump, p.max_border_gap_m) {
        s += &format!(", at borders {jump:.3} m/s (gap {gap:.2e} m)");
    }
    s += &format!(
        ", at seams {:.3} m/s\n  seams: gap {:.2e} m, heading {:.3} rad; {} of {} loops open",
        p.max_seam_velocity_jump,
        p.max_seam_gap_m,
        p.max_seam_heading_jump_rad,
        p.open_loops,
        p.loops
    );
    if let Some(turn) = p.max_turn_rate_rad_s {
        s += &format!("; fastest turn {turn:.3} rad/s");
    }
    if let Some(sm) = &p.sampled {
        s += &format!(
            "\n  sampler, every {} s over a period: fastest step {:.3} m/s, {} jumps",
            sm.step_s, sm.max_speed_m_s, sm.jumps
        );
    }
    s.push('\n');
    s
}
