//! The pipeline's stages, in build order: the one table `crowd build`, the stage subcommands,
//! `--until`, the report and the timings read. Each entry says what the stage reads and writes
//! and glues its crate's pure function to the files: hash the inputs, tell whether the file is
//! up to date, run. Stage 7 (edit) runs only when the pipeline has edits; export then reads its
//! file in place of stage 6's.

use crate::artifacts::Artifacts;
use crate::driver::Split;
use crate::reuse;
use crate::stage::{Ran, Stage};
use crate::ui::Ui;
use anyhow::{Result, anyhow, bail};
use crowd_core::files::{self, Header};
use crowd_core::maps::MergeFile;
use crowd_core::patch_keys::Seen;
use crowd_core::patterns::Patterns;
use crowd_core::trajectories::SideMotion::{self, Streamed};
use crowd_core::trajectories::{LazyMotion, PatchMotion, TrajectoriesFile};
use crowd_core::{Hash, PatchGraph};
use rayon::prelude::*;
use std::borrow::Cow;
use std::path::Path;

/// The stage files, by the stage that writes them (side files are named in them).
pub const MERGE_FILE: &str = "merge.ron";
pub const GRAPH_FILE: &str = "graph.ron";
pub const PATTERNS_FILE: &str = "patterns.ron";
pub const TRAJECTORIES_FILE: &str = "trajectories.ron";
pub const COLLIDED_FILE: &str = "collided.ron";
pub const SMOOTHED_FILE: &str = "smoothed.ron";
pub const EDITED_FILE: &str = "edited.ron";
pub const EXPORT_FILE: &str = "export.ron";

/// Every stage, in the order a build runs them.
pub static STAGES: [&Stage; 8] = [
    &MERGE, &GRAPH, &OPTIMIZE, &MATCH, &COLLIDE, &SMOOTH, &EDIT, &EXPORT,
];

/// The stages that `crowd build --shard` splits by patch (the others run whole in every
/// shard, or in the gathering).
pub static SHARDED: [&Stage; 3] = [&MATCH, &COLLIDE, &SMOOTH];

/// The stages that write trajectories (`crowd check` reads them), latest first.
pub static TRAJECTORY_STAGES: [&Stage; 4] = [&EDIT, &SMOOTH, &COLLIDE, &MATCH];

/// Every stage but the edit runs in every build.
fn always(_: &crowd_core::config::PipelineFile) -> bool {
    true
}

/// The stage whose trajectories export reads: the edit's when the pipeline has edits, the
/// smooth stage's otherwise (a pipeline without edits builds the bytes it built before stage 7
/// existed).
pub fn final_motion(pipeline: &crowd_core::config::PipelineFile) -> &'static Stage {
    if pipeline.pipeline.edits.is_empty() {
        &SMOOTH
    } else {
        &EDIT
    }
}

pub static MERGE: Stage = Stage {
    name: "merge",
    number: 1,
    about: "Stage 1: merge the painted layers into grids",
    reads: &[],
    output: MERGE_FILE,
    writes: &["merge.bin", MERGE_FILE],
    kind: MergeFile::STAGE,
    version: MergeFile::VERSION,
    hash: |a| {
        let layers = a.layers()?;
        Ok(crowd_merge::input_hash(a.pipeline, &layers))
    },
    fresh: |a, path, hash| {
        if !header_matches(&MERGE, path, hash) {
            return Ok(false);
        }
        let Ok((_, maps)) = MergeFile::load(path) else {
            return Ok(false);
        };
        a.keep_maps(maps);
        Ok(true)
    },
    run: merge,
    applies: always,
};

pub static GRAPH: Stage = Stage {
    name: "graph",
    number: 2,
    about: "Stage 2: cut the merged grids into the patch graph",
    reads: &[MERGE_FILE],
    output: GRAPH_FILE,
    writes: &[GRAPH_FILE],
    kind: PatchGraph::STAGE,
    version: PatchGraph::VERSION,
    hash: |a| {
        let merge = a.file_hash(&MERGE)?;
        Ok(crowd_graph::input_hash(
            &merge,
            &crowd_graph::inputs(a.pipeline),
        ))
    },
    // The graph is read (and checked) only when a later stage runs.
    fresh: |_, path, hash| Ok(header_matches(&GRAPH, path, hash)),
    run: graph,
    applies: always,
};

pub static OPTIMIZE: Stage = Stage {
    name: "optimize",
    number: 3,
    about: "Stage 3: place the crossings of every border (reads the graph)",
    reads: &[GRAPH_FILE],
    output: PATTERNS_FILE,
    writes: &[
        "patterns.bin",
        "optimize.csv",
        crowd_optimize::REGIONS_FILE,
        PATTERNS_FILE,
    ],
    kind: Patterns::STAGE,
    version: Patterns::VERSION,
    hash: |a| {
        let graph = a.file_hash(&GRAPH)?;
        Ok(crowd_optimize::input_hash(
            &graph,
            &crowd_optimize::inputs(a.pipeline),
        ))
    },
    fresh: |a, path, hash| {
        if !header_matches(&OPTIMIZE, path, hash) {
            return Ok(false);
        }
        let Ok(patterns) = Patterns::load(path) else {
            return Ok(false);
        };
        a.found_patterns(path, patterns)?;
        Ok(true)
    },
    run: optimize,
    applies: always,
};

pub static MATCH: Stage = Stage {
    name: "match",
    number: 4,
    about: "Stage 4: match entries with exits, straight lines and standers (reads the graph and \
            the patterns beside the input)",
    reads: &[GRAPH_FILE, PATTERNS_FILE],
    output: TRAJECTORIES_FILE,
    writes: &["trajectories.bin", "trajectories.keys", TRAJECTORIES_FILE],
    kind: TrajectoriesFile::STAGE,
    version: TrajectoriesFile::VERSION,
    hash: |a| {
        let (graph, patterns) = (a.file_hash(&GRAPH)?, a.file_hash(&OPTIMIZE)?);
        let inputs = crowd_match::inputs(a.pipeline);
        Ok(crowd_match::input_hash(&graph, &patterns, &inputs))
    },
    fresh: |a, path, hash| motion_fresh(&MATCH, a, path, hash),
    run: matching,
    applies: always,
};

pub static COLLIDE: Stage = Stage {
    name: "collide",
    number: 5,
    about: "Stage 5: push walkers apart (reads the trajectories and the graph beside them)",
    reads: &[GRAPH_FILE, TRAJECTORIES_FILE],
    output: COLLIDED_FILE,
    writes: &["collided.bin", "collided.keys", COLLIDED_FILE],
    kind: crowd_collide::STAGE,
    version: crowd_collide::VERSION,
    hash: |a| {
        let inputs = crowd_collide::inputs(a.pipeline);
        if let Split::Shard(_) = a.split {
            // A shard has only its part of stage 4: what that part is made from stands in.
            return Ok(crowd_collide::shard::part_hash(
                a.hashes[MATCH.name],
                &inputs,
            ));
        }
        let (graph, matched) = (a.file_hash(&GRAPH)?, a.file_hash(&MATCH)?);
        Ok(crowd_collide::input_hash(&graph, &matched, &inputs))
    },
    fresh: |a, path, hash| motion_fresh(&COLLIDE, a, path, hash),
    run: collide,
    applies: always,
};

pub static SMOOTH: Stage = Stage {
    name: "smooth",
    number: 6,
    about: "Stage 6: smooth the walkers' paths (reads the collided trajectories, and the graph \
            and patterns beside them)",
    reads: &[GRAPH_FILE, PATTERNS_FILE, COLLIDED_FILE],
    output: SMOOTHED_FILE,
    writes: &["smoothed.bin", "smoothed.keys", SMOOTHED_FILE],
    kind: crowd_smooth::STAGE,
    version: crowd_smooth::VERSION,
    hash: |a| {
        let (graph, patterns) = (a.file_hash(&GRAPH)?, a.file_hash(&OPTIMIZE)?);
        let inputs = crowd_smooth::inputs(a.pipeline);
        if let Split::Shard(_) = a.split {
            // A shard has only its part of stage 5: what that part is made from stands in.
            return Ok(crowd_smooth::shard::part_hash(
                a.hashes[COLLIDE.name],
                &patterns,
                &inputs,
            ));
        }
        let collided = a.file_hash(&COLLIDE)?;
        Ok(crowd_smooth::input_hash(
            &graph, &patterns, &collided, &inputs,
        ))
    },
    fresh: |a, path, hash| motion_fresh(&SMOOTH, a, path, hash),
    run: smooth,
    applies: always,
};

pub static EDIT: Stage = Stage {
    name: "edit",
    number: 7,
    about: "Stage 7: edit the pipeline's moments into the patches they cover (reads the \
            smoothed trajectories, and the graph beside them)",
    reads: &[GRAPH_FILE, SMOOTHED_FILE],
    output: EDITED_FILE,
    writes: &["edited.bin", EDITED_FILE],
    kind: crowd_moments::STAGE,
    version: crowd_moments::VERSION,
    hash: |a| {
        let (graph, smoothed) = (a.file_hash(&GRAPH)?, a.file_hash(&SMOOTH)?);
        let inputs = crowd_moments::inputs(a.pipeline);
        let maps = crate::flow_maps::read(a.pipeline)?;
        let bytes: Vec<&[u8]> = maps.iter().map(|m| m.bytes.as_slice()).collect();
        Ok(crowd_moments::input_hash(
            &graph, &smoothed, &inputs, &bytes,
        ))
    },
    fresh: |a, path, hash| motion_fresh(&EDIT, a, path, hash),
    run: edit,
    applies: |p| !p.pipeline.edits.is_empty(),
};

pub static EXPORT: Stage = Stage {
    name: "export",
    number: 8,
    about: "Stage 8: export the final trajectories as a binary patch library for crowd-runtime \
            (reads the smoothed trajectories, and the graph and patterns beside them)",
    reads: &[GRAPH_FILE, PATTERNS_FILE, SMOOTHED_FILE],
    output: EXPORT_FILE,
    writes: &[
        crowd_export::LIBRARY_FILE,
        crowd_export::GLB_FILE,
        EXPORT_FILE,
    ],
    kind: crowd_export::STAGE,
    version: crowd_export::VERSION,
    hash: |a| {
        let (graph, patterns) = (a.file_hash(&GRAPH)?, a.file_hash(&OPTIMIZE)?);
        let smoothed = a.file_hash(final_motion(a.pipeline))?;
        let inputs = crowd_export::inputs(a.pipeline);
        Ok(crowd_export::input_hash(
            &graph, &patterns, &smoothed, &inputs,
        ))
    },
    fresh: |_, path, hash| Ok(export_current(path, hash)),
    run: export,
    applies: always,
};

/// Whether the file at `path` was built by this version of `stage` from exactly `hash`.
/// A file whose header matches but whose body is not as written (cut short, damaged, edited
/// by hand) is said and rebuilt: no later stage builds on it.
fn header_matches(stage: &Stage, path: &Path, hash: Hash) -> bool {
    let header = files::read_header(path);
    if !header.is_ok_and(|h| h == Header::new(stage.kind, stage.version, hash)) {
        return false;
    }
    sealed(stage.name, path)
}

/// Whether `path` is as stage `name` wrote it, saying so on stderr when it is not.
fn sealed(name: &str, path: &Path) -> bool {
    let holds = files::seal_holds(path);
    if !holds {
        crate::ui::say(format!(
            "note: {} is not as stage {name} wrote it (cut short, damaged or edited by hand); \
             rebuilding it: hand edits of stage files are not kept, edit pipeline.ron or the \
             layers instead",
            path.display()
        ));
    }
    holds
}

/// Stages 4-6: up to date when the header matches and the side file is the one it names (size
/// and hash). The motion is decoded only if a later stage runs: a build with nothing to do
/// reads each side file once, in pieces, and keeps none of it.
fn motion_fresh(stage: &'static Stage, _: &mut Artifacts, path: &Path, hash: Hash) -> Result<bool> {
    if !header_matches(stage, path, hash) {
        return Ok(false);
    }
    let Ok(file) = files::read_ron::<TrajectoriesFile>(path) else {
        return Ok(false);
    };
    Ok(
        files::expect_stage(path, &file.header, stage.kind, stage.version).is_ok()
            && file.motion.holds(path),
    )
}

/// Stage 8 is up to date when `export.ron` records `hash` and the library and glTF beside it
/// are the ones it names, byte for byte.
fn export_current(path: &Path, hash: Hash) -> bool {
    let Ok(file) = files::read_ron::<crowd_export::ExportFile>(path) else {
        return false;
    };
    // Hashed as a file (in pieces, and remembered: the check after an up-to-date build asks
    // for the same two files).
    let named = |name: &str, named: Hash| {
        Hash::of_file(&path.with_file_name(name)).is_ok_and(|(_, h)| h == named)
    };
    file.header == Header::new(crowd_export::STAGE, crowd_export::VERSION, hash)
        && sealed(EXPORT.name, path)
        && named(&file.library, file.library_hash)
        && named(&file.gltf, file.gltf_hash)
}

fn merge(a: &mut Artifacts, out: &Path, hash: Hash, ui: &Ui) -> Result<Ran> {
    let bar = ui.stage_bar(MERGE.name);
    let layers = a.layers()?;
    let decoded = crowd_merge::decode(&layers)?;
    let p = &a.pipeline.pipeline;
    let maps = crowd_merge::merge(&decoded, &p.merge, p.scene.meters_per_pixel, &bar);
    let encoded = crowd_merge::encode(out, a.pipeline, &layers, &decoded, hash, &maps);
    a.keep_maps(maps);
    Ok(Ran::files(encoded.writes))
}

fn graph(a: &mut Artifacts, out: &Path, _: Hash, ui: &Ui) -> Result<Ran> {
    let bar = ui.stage_bar(GRAPH.name);
    let merge_file = a.file_hash(&MERGE)?;
    let maps = a.take_maps()?;
    let merge_path = a.path(MERGE.output);
    let graph = crowd_graph::build(a.pipeline, &merge_path, &merge_file, &maps, &bar)?;
    let bytes = files::to_stage_ron(&graph).into_bytes();
    a.made_graph(graph.share(&bytes));
    Ok(Ran::files(vec![(out.to_path_buf(), bytes)]))
}

fn optimize(a: &mut Artifacts, out: &Path, hash: Hash, ui: &Ui) -> Result<Ran> {
    let bar = ui.stage_bar(OPTIMIZE.name);
    let graph = a.graph()?;
    let s = crowd_optimize::inputs(a.pipeline);
    // The last build's regions: those whose inputs are unchanged are not optimised again.
    let mut known = std::fs::read(out.with_file_name(crowd_optimize::REGIONS_FILE))
        .ok()
        .and_then(|bytes| crowd_optimize::known::decode(&bytes))
        .unwrap_or_default();
    let dir = out.parent().unwrap_or(Path::new("."));
    let mut from_parts = None;
    match a.split {
        Split::Shard(shard) if a.regions_only => {
            return optimize_part(a, (dir, shard), hash, known, &bar);
        }
        // The regions the shards solved (`--until optimize`), taken instead of solved again.
        Split::Shard(_) | Split::Gather => {
            let (parts, count) = crowd_optimize::shard::read_parts(dir, hash)?;
            from_parts = Some((parts.len(), count));
            known.extend(parts);
        }
        Split::Whole => {}
    }
    let at = (s.period_s, s.seed);
    let outcome = crowd_optimize::solve_world(&graph, &s.settings, &s.matching, at, known, &bar);
    if outcome.crossing_count() == 0 {
        crate::warnings::no_walker(&graph, a.pipeline)?;
    }
    // Both binary files are streamed to disk, not held as bytes (0.19 GB at the million),
    // and the world's list of crossings is made only if this build keeps it whole.
    let regions = crowd_optimize::write_regions(out, &outcome.solved)?;
    let (patterns, side, writes) = crowd_optimize::encode(out, &outcome, &s, hash)?;
    let crossings = held_crossings(a, &outcome)?;
    let note = format!(
        "E = {:.4}, {} of {} regions optimised ({} reused)",
        outcome.error.e,
        outcome.regions - outcome.reused,
        outcome.regions,
        outcome.reused
    ) + &from_parts
        .map(|(regions, parts)| format!("; {regions} in {parts} shard parts"))
        .unwrap_or_default();
    drop(outcome);
    a.made_patterns((patterns, crossings));
    Ok(Ran {
        note: Some(note),
        streamed: vec![side, regions],
        ..Ran::files(writes)
    })
}

/// What this build keeps of stage 3's crossings: the world's list, or a shard's window of it
/// ([`Artifacts::shard_window`], dealt by the world's), taken from `outcome` without the
/// world's list (the million's is 0.1 GB).
fn held_crossings(
    a: &mut Artifacts,
    outcome: &crowd_optimize::Outcome,
) -> Result<crowd_core::patterns::HeldCrossings> {
    use crowd_core::patterns::HeldCrossings;
    let each = |count: &mut dyn FnMut(&crowd_core::patterns::Crossing)| {
        outcome.visit_crossings(|_, c| count(c));
    };
    let Some(borders) = a.shard_window(|graph| crate::artifacts::walkers_of(graph, each))? else {
        return Ok(HeldCrossings::whole(outcome.list_crossings()));
    };
    let (mut before, mut list) = (0, Vec::new());
    outcome.visit_crossings(|_, c| {
        if c.border < borders.start {
            before += 1;
        } else if borders.contains(&c.border) {
            list.push(*c);
        }
    });
    Ok(HeldCrossings::of_borders(before, list, borders))
}

/// A shard's share of stage 3 (`--shard I/N --until optimize`): its run of the regions
/// solved (or taken from the last build's), into `shards/optimize-I-of-N.ron` and `.bin`.
fn optimize_part(
    a: &mut Artifacts,
    (dir, shard): (&Path, crowd_core::Shard),
    hash: Hash,
    known: crowd_optimize::Known,
    bar: &dyn crowd_core::Progress,
) -> Result<Ran> {
    let graph = a.graph()?;
    let s = crowd_optimize::inputs(a.pipeline);
    let costs = crowd_optimize::shard::region_costs(&graph, &s.settings);
    let run = shard.run(&costs);
    let at = (s.period_s, s.seed);
    let part = crowd_optimize::solve_part(
        &graph,
        &s.settings,
        &s.matching,
        at,
        run.clone(),
        known,
        bar,
    );
    let reused = part.iter().filter(|(_, reused)| *reused).count();
    let solved: Vec<_> = part.into_iter().map(|(solved, _)| solved).collect();
    let mut note = format!(
        "regions {}..{} of {}: {} optimised ({reused} reused)",
        run.start,
        run.end,
        costs.len(),
        solved.len() - reused
    );
    // Fewer regions than shards leave shards with nothing to solve: say how to split more.
    let shards = shard.count() as usize;
    if costs.len() < shards {
        note += &match s.settings.region_patches {
            None => format!(
                "; one region for {shards} shards (no `optimize.region_patches`): only shard 0 \
                 solves stage 3; set it to split stage 3 over the shards"
            ),
            Some(n) => format!(
                "; {} regions for {shards} shards: an `optimize.region_patches` under {n} \
                 splits stage 3 further",
                costs.len()
            ),
        };
    }
    let writes = shard_writes(dir, || {
        crowd_optimize::shard::encode_part(dir, shard, hash, run, &solved)
    })?;
    Ok(Ran {
        note: Some(note),
        ..Ran::files(writes)
    })
}

fn matching(a: &mut Artifacts, out: &Path, hash: Hash, ui: &Ui) -> Result<Ran> {
    let bar = ui.stage_bar(MATCH.name);
    let (graph, patterns) = (a.graph()?, a.patterns()?);
    let (patterns, crossings) = (&patterns.0, &patterns.1);
    let inputs = crowd_match::inputs(a.pipeline);
    match a.split {
        Split::Shard(shard) => return matching_shard(a, (out, shard), hash, &inputs, &bar),
        Split::Gather => return matching_gathered(a, out, hash, &inputs),
        Split::Whole => {}
    }
    let measured = &patterns.measured;
    let seen = Seen::new(&graph, crossings);
    let keys: Vec<Hash> = (0..graph.patches.len())
        .into_par_iter()
        .map(|p| crowd_match::patch_key(&seen, p, measured[p].standers, &inputs))
        .collect();
    let previous = a.previous.take(out);
    let mut motion = reuse::reusable(previous.as_ref(), &keys, &seen.tables);
    drop(previous);
    let todo: Vec<usize> = (0..motion.len()).filter(|&p| motion[p].is_none()).collect();
    let made = crowd_match::match_patches(&graph, crossings, measured, &inputs, &bar, &todo);
    for (&p, m) in todo.iter().zip(made) {
        motion[p] = Some((m, Vec::new()));
    }
    let motion: Vec<PatchMotion> = motion
        .into_iter()
        .map(|m| m.expect("every patch").0)
        .collect();
    let (file, writes) = crowd_match::encode(out, &motion, &graph, &inputs, hash);
    let extra = vec![Vec::new(); keys.len()];
    let writes = with_keys(out, writes, file.motion.hash, keys, &seen.tables, extra);
    let note = reuse::note(motion.len() - todo.len(), motion.len());
    let side = side_file(out, &file);
    a.made_motion(&MATCH, (file, motion));
    Ok(Ran {
        note: Some(note),
        ..Ran::files(writes)
    }
    .knowing(side.0, side.1))
}

/// A shard's part of stage 4: its own patches and their neighbours matched (its stage 5
/// clears them all), its own written to `shards/match-I-of-N`.
fn matching_shard(
    a: &mut Artifacts,
    (out, shard): (&Path, crowd_core::Shard),
    hash: Hash,
    inputs: &crowd_match::Inputs,
    bar: &dyn crowd_core::Progress,
) -> Result<Ran> {
    let dir = out.parent().unwrap_or(Path::new("."));
    let (graph, patterns) = (a.graph()?, a.patterns()?);
    let own: Vec<usize> = shard.run(&a.shard_costs()?).collect();
    let matched = crowd_core::shard::with_neighbours(&graph, &own);
    let (measured, crossings) = (&patterns.0.measured, &patterns.1);
    let made = crowd_match::match_patches(&graph, crossings, measured, inputs, bar, &matched);
    let mut motion = vec![PatchMotion::default(); graph.patches.len()];
    for (&p, m) in matched.iter().zip(made) {
        motion[p] = m;
    }
    let part = own.iter().map(|&p| (p as u32, &motion[p])).collect();
    let writes = shard_writes(dir, || {
        crowd_match::shard::encode_shard(dir, shard, hash, part)
    })?;
    a.shard_matched = Some(motion);
    Ok(Ran::files(writes))
}

/// Stage 4 put together from every shard's part in `shards/`, streamed as stage 5's are
/// ([`collide_gathered`]); the keys a whole build would leave, made here from stage 3.
fn matching_gathered(
    a: &mut Artifacts,
    out: &Path,
    hash: Hash,
    inputs: &crowd_match::Inputs,
) -> Result<Ran> {
    let dir = out.parent().unwrap_or(Path::new("."));
    let mut summing = crowd_core::trajectories::Summing::new(inputs.period_s);
    let side_path = out.with_extension("bin");
    let costs = a.shard_costs()?;
    let gathered =
        crowd_match::shard::gather_bytes(dir, hash, &costs, |m| summing.add(m), &side_path)?;
    let (graph, patterns) = (a.graph()?, a.patterns()?);
    let seen = Seen::new(&graph, &patterns.1);
    let measured = &patterns.0.measured;
    let keys: Vec<Hash> = (0..graph.patches.len())
        .into_par_iter()
        .map(|p| crowd_match::patch_key(&seen, p, measured[p].standers, inputs))
        .collect();
    let side = gathered.side;
    let (file, writes) =
        crowd_match::encode(out, Streamed(&side, summing.finish()), &graph, inputs, hash);
    let extra = vec![Vec::new(); keys.len()];
    let writes = with_keys(out, writes, file.motion.hash, keys, &seen.tables, extra);
    Ok(gathered_ran(
        a,
        &MATCH,
        (file, writes),
        (side, gathered.motion),
    ))
}

/// What a stage put together from the shards' parts hands on: its files, its side file
/// (streamed to its temporary name already) and its motion, left in the parts and read a
/// patch at a time by the stages after. Its line says "gathered": nothing was reused.
fn gathered_ran(
    a: &mut Artifacts,
    stage: &'static Stage,
    (file, writes): (TrajectoriesFile, files::Writes),
    (side, motion): (files::StreamedFile, LazyMotion),
) -> Ran {
    let known = (side.path.clone(), side.hash);
    a.made_lazy_motion(stage, (file, motion));
    Ran {
        note: Some("gathered".to_string()),
        streamed: vec![side],
        ..Ran::files(writes)
    }
    .knowing(known.0, known.1)
}

fn collide(a: &mut Artifacts, out: &Path, hash: Hash, ui: &Ui) -> Result<Ran> {
    let bar = ui.stage_bar(COLLIDE.name);
    let graph = a.graph()?;
    let s = crowd_collide::inputs(a.pipeline);
    let dir = out.parent().unwrap_or(Path::new("."));
    match a.split {
        Split::Whole => {
            let matched = a.take_motion(&MATCH)?;
            let patterns = a.patterns()?;
            let seen = Seen::new(&graph, &patterns.1);
            let held: &[PatchMotion] = &matched.1;
            let keys = collide_keys(&seen, |p| Ok(Cow::Borrowed(&held[p])), &s)?;
            let previous = a.previous.take(out);
            let reused = reuse::reusable(previous.as_ref(), &keys, &seen.tables);
            drop(previous);
            // A reused patch's report is its figures in the keys file.
            let mut done: Vec<Option<(PatchMotion, crowd_collide::PatchReport)>> = reused
                .into_iter()
                .map(|r| {
                    let (m, bytes) = r?;
                    let report = ron::from_str(std::str::from_utf8(&bytes).ok()?).ok()?;
                    Some((m, report))
                })
                .collect();
            let todo: Vec<usize> = (0..done.len()).filter(|&p| done[p].is_none()).collect();
            let made = crowd_collide::collide_patches(&graph, &matched.1, &s, &bar, &todo)
                .map_err(|stall| collide_stall(&graph, &s, stall))?;
            drop(matched);
            for (m, report) in made {
                let p = report.patch as usize;
                done[p] = Some((m, report));
            }
            let (motion, reports): (Vec<_>, Vec<_>) = done
                .into_iter()
                .map(|d| d.expect("every patch cleared or reused"))
                .unzip();
            let note = reuse::note(motion.len() - todo.len(), motion.len());
            finish_collide(a, out, hash, (motion, reports), (keys, seen.tables), note)
        }
        Split::Gather => collide_gathered(a, out, hash, &s),
        Split::Shard(shard) => {
            let own: Vec<usize> = shard.run(&a.shard_costs()?).collect();
            let cleared = crowd_core::shard::with_neighbours(&graph, &own);
            let matched = a.shard_matched.take().expect("stage 4 ran in this shard");
            let parts = crowd_collide::collide_patches(&graph, &matched, &s, &bar, &cleared)
                .map_err(|stall| collide_stall(&graph, &s, stall))?;
            drop(matched);
            // Its own patches go to its part; they and their neighbours, to its stage 6.
            let mut motion = vec![PatchMotion::default(); graph.patches.len()];
            let mut mine = Vec::with_capacity(own.len());
            for (m, report) in parts {
                let p = report.patch as usize;
                motion[p] = m;
                if own.binary_search(&p).is_ok() {
                    mine.push(report);
                }
            }
            let part = mine
                .into_iter()
                .map(|r| (&motion[r.patch as usize], r))
                .collect();
            let writes = shard_writes(dir, || {
                crowd_collide::shard::encode_shard(dir, shard, hash, part)
            })?;
            a.shard_collided = Some(motion);
            Ok(Ran::files(writes))
        }
    }
}

/// Every patch's stage 5 key ([`crowd_collide::patch_key`]), in parallel.
fn collide_keys<'a>(
    seen: &Seen,
    matched: impl Fn(usize) -> crowd_core::Result<Cow<'a, PatchMotion>> + Sync,
    s: &crowd_collide::Inputs,
) -> crowd_core::Result<Vec<Hash>> {
    (0..seen.graph.patches.len())
        .into_par_iter()
        .map(|p| Ok(crowd_collide::patch_key(seen, p, &*matched(p)?, s)))
        .collect()
}

/// Stage 5 put together from every shard's part in `shards/`: their patch bytes one after
/// another make the side file one process would write, streamed to disk and never held whole
/// nor decoded into one world (the million's gather held its motion decoded through stages 5
/// and 6, and the matched motion for the keys: 1.7 GB). Stage 6 reads the patches from the
/// parts.
fn collide_gathered(
    a: &mut Artifacts,
    out: &Path,
    hash: Hash,
    s: &crowd_collide::Inputs,
) -> Result<Ran> {
    let dir = out.parent().unwrap_or(Path::new("."));
    let mut summing = crowd_core::trajectories::Summing::new(s.period_s);
    let side_path = out.with_extension("bin");
    let costs = a.shard_costs()?;
    let made_from = crowd_collide::shard::part_hash(a.hashes[MATCH.name], s);
    let gathered =
        crowd_collide::shard::gather_bytes(dir, made_from, &costs, |m| summing.add(m), &side_path)?;
    // The keys a whole build would leave, so that the next build reuses patches: from the
    // matched motion, each patch read when asked.
    let (graph, patterns) = (a.graph()?, a.patterns()?);
    let seen = Seen::new(&graph, &patterns.1);
    let keys = each_patch(a, &MATCH, |motion| collide_keys(&seen, motion, s))?.0?;
    let reports = gathered.reports;
    let side = gathered.side;
    let (file, writes) = crowd_collide::encode(
        out,
        Streamed(&side, summing.finish()),
        &reports,
        &graph,
        s,
        hash,
    );
    let extra = reports
        .iter()
        .map(|r| ron::to_string(r).map(String::into_bytes))
        .collect::<std::result::Result<Vec<_>, _>>()?;
    let writes = with_keys(out, writes, file.motion.hash, keys, &seen.tables, extra);
    Ok(gathered_ran(
        a,
        &COLLIDE,
        (file, writes),
        (side, gathered.motion),
    ))
}

/// Stage 5's files from every patch's motion and report, with the keys of each patch.
fn finish_collide(
    a: &mut Artifacts,
    out: &Path,
    hash: Hash,
    (motion, reports): (Vec<PatchMotion>, Vec<crowd_collide::PatchReport>),
    (keys, tables): (Vec<Hash>, Vec<crowd_core::patch_keys::Table>),
    note: String,
) -> Result<Ran> {
    let graph = a.graph()?;
    let s = crowd_collide::inputs(a.pipeline);
    let (file, writes) = crowd_collide::encode(out, &motion, &reports, &graph, &s, hash);
    let extra = reports
        .iter()
        .map(|r| ron::to_string(r).map(String::into_bytes))
        .collect::<std::result::Result<Vec<_>, _>>()?;
    let writes = with_keys(out, writes, file.motion.hash, keys, &tables, extra);
    let side = side_file(out, &file);
    a.made_motion(&COLLIDE, (file, motion));
    Ok(Ran {
        note: Some(note),
        ..Ran::files(writes)
    }
    .knowing(side.0, side.1))
}

/// Stage 5's refusal when a patch stalls.
fn collide_stall(
    graph: &crowd_core::PatchGraph,
    s: &crowd_collide::Inputs,
    stall: crowd_core::trajectories::Stall,
) -> anyhow::Error {
    anyhow!(
        "stage 5 could not keep {} clear: walker {} and {:?} stay {:.3} m too close at \
             t = {:.2} s, even with walkers let hurry, after collide.max_iterations = {} \
             pushes; no file was written, and the patches after it (busiest first) were not \
             tried. Paint fewer walkers or crossing flows there, or raise \
             collide.max_iterations",
        crate::warnings::place(graph, stall.patch),
        stall.walker,
        stall.with,
        -stall.margin_m,
        stall.t_s,
        s.max_iterations
    )
}

fn smooth(a: &mut Artifacts, out: &Path, hash: Hash, ui: &Ui) -> Result<Ran> {
    let bar = ui.stage_bar(SMOOTH.name);
    let (graph, patterns) = (a.graph()?, a.patterns()?);
    let inputs = crowd_smooth::inputs(a.pipeline);
    let dir = out.parent().unwrap_or(Path::new("."));
    match a.split {
        Split::Shard(shard) => return smooth_shard(a, (dir, shard, hash), &inputs, &bar),
        Split::Gather => return smooth_gathered(a, out, hash, &inputs),
        Split::Whole => {}
    }
    let collided = a.take_motion(&COLLIDE)?;
    let seen = Seen::new(&graph, &patterns.1);
    // The last build's side file is read (and its hash checked) meanwhile, and waited for on
    // this thread, not on a worker of the pool (`reuse::Prefetch::take`).
    let motion: &[PatchMotion] = &collided.1;
    let (keys, previous) = std::thread::scope(|s| {
        let keys =
            s.spawn(|| crowd_smooth::patch_keys(&seen, |p| Ok(Cow::Borrowed(&motion[p])), &inputs));
        let previous = a.previous.take(out);
        let keys = keys.join();
        (
            keys.unwrap_or_else(|panic| std::panic::resume_unwind(panic)),
            previous,
        )
    });
    let keys = keys?;
    // A patch whose key is unchanged stays the last build's bytes: copied and renumbered,
    // never decoded (export reads the side file's bytes as it thins them).
    let reused: Vec<Option<reuse::Encoded>> = (0..keys.len())
        .map(|p| previous.as_ref()?.take_encoded(p, keys[p]))
        .collect();
    let todo = reused.iter().filter(|r| r.is_none()).count();
    let progress: &dyn crowd_core::Progress = &bar;
    progress.begin("smooth", todo as u64);
    let smoother = crowd_smooth::Smoother::new(&graph, patterns.1.view(), &collided.1, &inputs);
    let counted = |counts: [u64; 3]| counts.iter().flat_map(|c| c.to_le_bytes()).collect();
    // Each patch is encoded as soon as it is smoothed: the world's smoothed motion is never
    // held (`reuse::side_pieces`).
    let side = reuse::side_pieces(reused.len(), |p| match &reused[p] {
        Some((bytes, was, figures)) => (
            reuse::renumbered(bytes, was, &seen.tables[p]),
            figures.to_vec(),
        ),
        None => {
            let (motion, counts) = smoother.patch(p);
            progress.advance(1);
            (
                crowd_core::trajectories::encode_patch_bytes(&motion),
                counted(counts),
            )
        }
    });
    drop(smoother);
    drop(reused);
    drop(previous);
    // Stage 5's motion is read no more.
    let collided_file = collided.0.clone();
    drop(collided);
    let count = |bytes: &[u8], i: usize| {
        bytes
            .get(8 * i..8 * i + 8)
            .and_then(|b| b.try_into().ok())
            .map_or(0, u64::from_le_bytes)
    };
    let counts = (side.figures.iter()).map(|b| [count(b, 0), count(b, 1), count(b, 2)]);
    let summary = crowd_smooth::summary_of(counts);
    let mut summing = crowd_core::trajectories::Summing::new(inputs.period_s);
    side.sums.iter().for_each(|s| summing.add_sums(s));
    let encoded = SideMotion::Encoded(side.file, summing.finish());
    let (file, writes) = crowd_smooth::encode(out, encoded, summary, &collided_file, &inputs, hash);
    let note = reuse::note(side.figures.len() - todo, side.figures.len());
    let writes = with_keys(
        out,
        writes,
        file.motion.hash,
        keys,
        &seen.tables,
        side.figures,
    );
    let known = side_file(out, &file);
    side.index.share(known.1);
    // Written meanwhile (`files::Staging`), and thinned by export from memory.
    let pieces = std::sync::Arc::new(side.pieces);
    let motion = LazyMotion::of_pieces((out, &known.0), pieces.clone(), side.index);
    a.made_lazy_motion(&SMOOTH, (file, motion));
    Ok(Ran {
        note: Some(note),
        shared: vec![(known.0.clone(), pieces)],
        ..Ran::files(writes)
    }
    .knowing(known.0, known.1))
}

/// A shard's stage 6: its part ([`smooth_part`]), then its share of the check
/// (`check_shard.rs`), unless stage 7 edits what the check will judge.
fn smooth_shard(
    a: &mut Artifacts,
    (dir, shard, hash): (&Path, crowd_core::Shard, Hash),
    inputs: &crowd_smooth::Inputs,
    bar: &dyn crowd_core::Progress,
) -> Result<Ran> {
    let (graph, patterns) = (a.graph()?, a.patterns()?);
    let collided = a.shard_collided.take().expect("stage 5 ran in this shard");
    let own: Vec<usize> = shard.run(&a.shard_costs()?).collect();
    // The keys of its patches' check are made from stage 5's motion, so before it goes.
    let checked = a.pipeline.pipeline.edits.is_empty().then(|| {
        let seen = Seen::new(&graph, &patterns.1);
        let motion = |p: usize| Ok(Cow::Borrowed(&collided[p]));
        let keys = crowd_smooth::patch_keys_of(&seen, motion, inputs, &own);
        keys.map(|k| (seen.tables, k))
    });
    let checked = checked.transpose()?;
    let smoother = crowd_smooth::Smoother::new(&graph, patterns.1.view(), &collided, inputs);
    let mut ran = smooth_part(dir, (shard, hash), &smoother, &own, bar)?;
    // Stage 5's motion is read no more: let it go before the check's strips.
    drop(smoother);
    drop(collided);
    let Some((tables, keys)) = checked else {
        return Ok(ran);
    };
    let started = std::time::Instant::now();
    let smoothed = crate::check_shard::Smoothed {
        graph: &graph,
        crossings: patterns.1.view(),
        tables: &tables,
        own: &own,
        keys: &keys,
        part: (ran.writes[0].0.as_path(), &ran.streamed[0]),
    };
    let (memo, whole) = crate::check_shard::judge(&smoothed, inputs.period_s)?;
    ran.writes
        .push((crate::check_shard::part_path(dir, shard), memo));
    ran.parts
        .push(("check".to_string(), started.elapsed().as_secs_f64()));
    ran.note = Some(format!(
        "its {} patches checked for the gather ({whole} with their pairs)",
        own.len()
    ));
    Ok(ran)
}

/// A shard's part of stage 6, its `own` patches smoothed a run at a time (in parallel) and
/// each encoded and written at once: the shard holds a run's curves, never its part's.
fn smooth_part(
    dir: &Path,
    (shard, hash): (crowd_core::Shard, Hash),
    smoother: &crowd_smooth::Smoother,
    own: &[usize],
    bar: &dyn crowd_core::Progress,
) -> Result<Ran> {
    /// Patches smoothed before their bytes are written.
    const RUN: usize = 512;
    shard_writes(dir, Vec::new)?;
    let stage = crowd_smooth::STAGE;
    let mut part = crowd_core::shard::PartWriter::create(dir, stage, shard, own.len())?;
    let mut counts = Vec::with_capacity(own.len());
    bar.begin("smooth", own.len() as u64);
    for run in own.chunks(RUN) {
        let done: Vec<(Vec<u8>, [u64; 3])> = run
            .par_iter()
            .map(|&p| {
                let (motion, counts) = smoother.patch(p);
                bar.advance(1);
                (
                    crowd_core::trajectories::encode_patch_bytes(&motion),
                    counts,
                )
            })
            .collect();
        for (&p, (bytes, c)) in run.iter().zip(done) {
            part.write(p as u32, &bytes)?;
            counts.push(c);
        }
    }
    let header = crowd_smooth::shard::header(hash);
    let (side, ron) = part.finish(header, shard, counts)?;
    Ok(Ran {
        streamed: vec![side],
        ..Ran::files(vec![ron])
    })
}

/// Stage 6 put together from the shards' parts: their patch bytes one after another make the
/// side file one process would write, streamed to disk part by part and never held whole, nor
/// decoded into one world (the million's gather held its motion decoded and encoded at once:
/// 11 GB; then its 4.2 GB side file). Export then reads the patches from the parts.
fn smooth_gathered(
    a: &mut Artifacts,
    out: &Path,
    hash: Hash,
    inputs: &crowd_smooth::Inputs,
) -> Result<Ran> {
    let dir = out.parent().unwrap_or(Path::new("."));
    // What each part says it is made from: stage 5's part's, the patterns, the settings.
    let collide_part =
        crowd_collide::shard::part_hash(a.hashes[MATCH.name], &crowd_collide::inputs(a.pipeline));
    let made_from = crowd_smooth::shard::part_hash(collide_part, &a.file_hash(&OPTIMIZE)?, inputs);
    let mut summing = crowd_core::trajectories::Summing::new(inputs.period_s);
    let side_path = out.with_extension("bin");
    let gathered = crowd_smooth::shard::gather_bytes(
        dir,
        made_from,
        &a.shard_costs()?,
        |m| summing.add(m),
        &side_path,
    )?;
    let counts = gathered.reports;
    let (graph, patterns) = (a.graph()?, a.patterns()?);
    // The keys from stage 5's motion, each patch read when asked.
    let seen = Seen::new(&graph, &patterns.1);
    let (keys, collided_file) = each_patch(a, &COLLIDE, |motion| {
        crowd_smooth::patch_keys(&seen, motion, inputs)
    })?;
    let keys = keys?;
    let extra = (counts.iter())
        .map(|c| c.iter().flat_map(|c| c.to_le_bytes()).collect())
        .collect();
    let summary = crowd_smooth::summary_of(counts.iter().copied());
    let side = gathered.side;
    let (file, writes) = crowd_smooth::encode(
        out,
        Streamed(&side, summing.finish()),
        summary,
        &collided_file,
        inputs,
        hash,
    );
    let writes = with_keys(out, writes, file.motion.hash, keys, &seen.tables, extra);
    Ok(gathered_ran(
        a,
        &SMOOTH,
        (file, writes),
        (side, gathered.motion),
    ))
}

/// A stage's writes with its keys file put before its stage file (which comes last).
fn with_keys(
    out: &Path,
    mut writes: files::Writes,
    side: Hash,
    keys: Vec<Hash>,
    tables: &[crowd_core::patch_keys::Table],
    extra: Vec<Vec<u8>>,
) -> files::Writes {
    let seal = writes.pop().expect("the stage file comes last");
    writes.push(reuse::keys_file(out, side, keys, tables, extra));
    writes.push(seal);
    writes
}

/// Where a trajectories file's side file goes, and its hash.
fn side_file(out: &Path, file: &TrajectoriesFile) -> (std::path::PathBuf, Hash) {
    (out.with_file_name(&file.motion.file), file.motion.hash)
}

/// A shard's files (`encode`), in `dir/shards`, made first so that they can be written.
fn shard_writes(dir: &Path, encode: impl FnOnce() -> files::Writes) -> Result<files::Writes> {
    let folder = dir.join(crowd_core::shard::SHARDS_DIR);
    std::fs::create_dir_all(&folder)
        .map_err(|e| crowd_core::Error::io(&folder, "create the shards folder", e))?;
    Ok(encode())
}

fn edit(a: &mut Artifacts, out: &Path, hash: Hash, ui: &Ui) -> Result<Ran> {
    if a.pipeline.pipeline.edits.is_empty() {
        bail!(
            "{}: the pipeline has no `edits`; stage 7 edits nothing (export reads {SMOOTHED_FILE})",
            a.pipeline.path.display()
        );
    }
    let graph = a.graph()?;
    a.pipeline
        .check_edits((graph.world.size_m.x, graph.world.size_m.y))?;
    let bar = ui.stage_bar(EDIT.name);
    let smoothed = a.take_motion(&SMOOTH)?;
    let mut inputs = crowd_moments::inputs(a.pipeline);
    let maps = crate::flow_maps::read(a.pipeline)?;
    inputs.flow_maps = crate::flow_maps::decode(a.pipeline, &graph, maps)?;
    let (motion, edits, seconds) = crowd_moments::edit_timed(&graph, &smoothed.1, &inputs, &bar);
    let parts = edits.iter().map(|e| e.name.clone()).zip(seconds).collect();
    let (file, writes) = crowd_moments::encode(out, &motion, edits, &smoothed.0, hash);
    drop(smoothed);
    let side = side_file(out, &file);
    a.made_motion(&EDIT, (file, motion));
    Ok(Ran {
        parts,
        ..Ran::files(writes)
    }
    .knowing(side.0, side.1))
}

fn export(a: &mut Artifacts, out: &Path, hash: Hash, _: &Ui) -> Result<Ran> {
    let graph = a.graph()?;
    // Taken, so that export lets the world's crossings go once the library has their records
    // (before `world.glb`'s longest loop: 92 MB of the million's gather).
    let patterns = a.take_patterns()?;
    let crossings = std::rc::Rc::try_unwrap(patterns).map_or_else(
        |shared| shared.1.world().to_vec(),
        |(_, held)| held.into_world(),
    );
    a.pipeline
        .check_region((graph.world.size_m.x, graph.world.size_m.y))?;
    let inputs = crowd_export::inputs(a.pipeline);
    let tolerance_m = crowd_export::tolerance_m(&inputs);
    let stage = final_motion(a.pipeline);
    let failed = |e| anyhow!("{}: cannot export: {e}", out.display());
    // A gathering build keeps its library's points in a scratch file beside it and writes
    // the library a piece at a time whatever its size, as a world too large for one process
    // needs (and the shards' tests see that path).
    let dir = out.parent().unwrap_or(Path::new("."));
    let library = out.with_file_name(crowd_export::LIBRARY_FILE);
    // Else a library's bytes are written on a thread of their own as soon as they are made.
    let writing = std::sync::Mutex::new(None);
    let hand = |bytes: Vec<u8>, hash: Hash| {
        let started = files::Writing::start(&library, (bytes, hash));
        *writing.lock().unwrap_or_else(|e| e.into_inner()) = Some(started);
    };
    let handing = match a.split {
        Split::Gather => crowd_export::Handing::Spilled(dir),
        _ => crowd_export::Handing::Handed(&hand),
    };
    let export = if a.holds_motion(stage) {
        // Each patch's dense keyframes are freed as it is thinned.
        let held = a.take_motion(stage)?;
        let motion = std::rc::Rc::try_unwrap(held).map_or_else(|shared| shared.1.clone(), |m| m.1);
        let kept = crowd_export::simplify::motion(motion, tolerance_m);
        crowd_export::export(&graph, crossings, &kept, &inputs, hash, handing)
    } else if a.split != Split::Gather {
        // Left in its side file (a stroke's stage 6 holds its bytes): each patch decoded and
        // thinned once, its dense keyframes freed as it is.
        let lazy = a.take_lazy_motion(stage);
        let lazy = lazy.map_or_else(|| lazy_motion(a, stage), Ok)?;
        let motion = &lazy.1;
        let kept: Vec<crowd_core::Result<PatchMotion>> = (0..motion.patches())
            .into_par_iter()
            .map(|p| Ok(crowd_export::simplify::patch(motion.patch(p)?, tolerance_m)))
            .collect();
        let kept = kept.into_iter().collect::<crowd_core::Result<Vec<_>>>()?;
        drop(lazy);
        crowd_export::export(&graph, crossings, &kept, &inputs, hash, handing)
    } else {
        // A gathering build: each patch read from the stage's files and thinned when export
        // asks, so neither the world's dense motion nor its thinned copy is held.
        let lazy = lazy_motion(a, stage)?;
        let motion = &lazy.1;
        let made = crowd_export::motion::Made::new(motion.patches(), |p| {
            Ok(crowd_export::simplify::patch(motion.patch(p)?, tolerance_m))
        });
        crowd_export::export(&graph, crossings, &made, &inputs, hash, handing)
    };
    // Waited for whether the export failed or not: no thread is left writing.
    let handed = writing.into_inner().unwrap_or_else(|e| e.into_inner());
    let handed = handed.map(files::Writing::finish).transpose();
    let export = export.map_err(failed)?;
    let handed = handed?;
    let gltf = (
        out.with_file_name(crowd_export::GLB_FILE),
        export.manifest.gltf_hash(),
    );
    let (lib, spilled) = match export.library {
        crowd_export::LibraryBytes::Held(_) | crowd_export::LibraryBytes::Handed(..) => {
            let (writes, file) = crowd_export::writes(out, export).map_err(failed)?;
            let ran = Ran {
                streamed: handed.into_iter().collect(),
                ..Ran::files(writes)
            };
            let ran = ran.knowing(library, file.library_hash);
            return Ok(ran.knowing(gltf.0, gltf.1));
        }
        crowd_export::LibraryBytes::Records(lib) => (lib, None),
        crowd_export::LibraryBytes::Spilled(lib, spilled) => (lib, Some(spilled)),
    };
    let streamed = write_library(&library, lib, spilled)?;
    let file = export.manifest.file((streamed.bytes, streamed.hash));
    let hash = streamed.hash;
    let ran = Ran {
        streamed: vec![streamed],
        ..Ran::files(vec![
            (gltf.0.clone(), export.glb),
            (out.to_path_buf(), files::to_stage_ron(&file).into_bytes()),
        ])
    }
    .knowing(library, hash);
    Ok(ran.knowing(gltf.0, gltf.1))
}

/// A large library written to `path`'s temporary name a piece at a time, its records freed
/// as soon as it is (the million's 0.9 GB of bytes were held beside its 0.9 GB of records),
/// its points from `spilled` when they are there.
fn write_library(
    path: &Path,
    lib: crowd_runtime::Library,
    spilled: Option<crowd_export::spill::Spilled>,
) -> Result<files::StreamedFile> {
    let mut file = files::Streamed::create(path)?;
    let mut write = |piece: &[u8]| file.write(piece).map_err(anyhow::Error::from);
    match &spilled {
        None => lib.write_to(write)?,
        Some(spilled) => {
            let points = |sink: &mut dyn FnMut(&[u8]) -> Result<()>| spilled.copy_to(sink);
            lib.write_with_points(spilled.section(), points, &mut write)?
        }
    }
    drop((lib, spilled));
    Ok(file.finish()?)
}

/// `f` of `stage`'s motion a patch at a time, and the stage's file: held by this build (its
/// stage ran, and its files wait for the commit), or else read from its files when asked.
fn each_patch<T>(
    a: &mut Artifacts,
    stage: &'static Stage,
    f: impl for<'m> FnOnce(&'m (dyn Fn(usize) -> crowd_core::Result<Cow<'m, PatchMotion>> + Sync)) -> T,
) -> Result<(T, TrajectoriesFile)> {
    if a.holds_motion(stage) {
        let held = a.take_motion(stage)?;
        let motion: &[PatchMotion] = &held.1;
        return Ok((f(&|p| Ok(Cow::Borrowed(&motion[p]))), held.0.clone()));
    }
    let lazy = lazy_motion(a, stage)?;
    let motion = &lazy.1;
    Ok((f(&|p| motion.patch(p).map(Cow::Owned)), lazy.0.clone()))
}

/// `stage`'s motion left in its files, each patch read when asked: the read-ahead's, or
/// opened now.
fn lazy_motion(
    a: &mut Artifacts,
    stage: &'static Stage,
) -> Result<std::rc::Rc<(TrajectoriesFile, LazyMotion)>> {
    if let Some(made) = a.lazy_motion(stage) {
        return Ok(made);
    }
    let path = a.path(stage.output);
    let patches = a.graph()?.patches.len();
    let opened = TrajectoriesFile::open_for(&path, stage.kind, stage.version, patches)?;
    Ok(std::rc::Rc::new(opened))
}

/// Refuses a folder that holds no stage file, for the commands that read a build folder
/// (`report`, `check`): the likely mistake, said as one (not as the first file missing).
pub fn expect_build_folder(dir: &Path) -> Result<()> {
    if !dir.join(MERGE_FILE).exists() && !dir.join(GRAPH_FILE).exists() {
        bail!(
            "{}: no stage files here; expected a build folder (the `output` of a pipeline) \
             holding {MERGE_FILE} or {GRAPH_FILE}",
            dir.display()
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_stage_reads_only_files_of_stages_before_it() {
        for (i, stage) in STAGES.iter().enumerate() {
            for read in stage.reads {
                assert!(
                    STAGES[..i].iter().any(|s| s.output == *read),
                    "{stage:?} reads {read}, which no earlier stage writes"
                );
            }
        }
    }

    #[test]
    fn names_files_and_numbers_are_distinct_and_in_order() {
        for (i, a) in STAGES.iter().enumerate() {
            assert_eq!(
                a.writes.last(),
                Some(&a.output),
                "{a:?} writes its file last"
            );
            for b in &STAGES[i + 1..] {
                assert!(a.number < b.number, "{a:?} before {b:?}");
                assert_ne!(a.name, b.name);
                assert!(
                    a.writes.iter().all(|w| !b.writes.contains(w)),
                    "{a:?} {b:?}"
                );
            }
        }
    }

    #[test]
    fn until_stops_after_the_named_stage() {
        let names = |until| {
            crate::stage::up_to(until)
                .map(|s| s.name)
                .collect::<Vec<_>>()
        };
        assert_eq!(names(Some(&OPTIMIZE)), ["merge", "graph", "optimize"]);
        assert_eq!(names(None).len(), STAGES.len());
        assert_eq!(crate::stage::named("collide"), Some(&COLLIDE));
    }

    #[test]
    fn every_stage_has_a_subcommand() {
        use clap::CommandFactory;
        let cli = crate::cli::Cli::command();
        for stage in STAGES {
            let sub = cli
                .find_subcommand(stage.name)
                .expect("a subcommand per stage");
            let has = |id: &str| sub.get_arguments().any(|a| a.get_id() == id);
            assert!(has("pipeline") && has("output"), "{stage:?}");
            assert_eq!(has("input"), !stage.reads.is_empty(), "{stage:?}");
        }
    }
}
