//! `report.md`: a build folder's figures for a person to read, with the pictures of its stages.
//! `crowd build` writes it beside the outputs after every build, and `crowd check` refreshes
//! it with the collision and motion figures.

use crate::report::{Report, Scope};
use crate::stages::{
    COLLIDED_FILE, GRAPH_FILE, MERGE_FILE, PATTERNS_FILE, SMOOTHED_FILE, STAGES, TRAJECTORIES_FILE,
};
use anyhow::Result;
use crowd_core::files;
use rayon::prelude::*;
use serde_json::Value;
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// The report's name in a build folder.
pub const REPORT_FILE: &str = "report.md";

/// The last line of `report.md`: the hash of what it was made from ([`made_from`]).
const MADE_FROM: &str = "<!-- made from: ";

/// The hash of everything a report of `dir` in `scope` reads: every RON and CSV file of the
/// folder (stage files name their side files, the library and glTF by hash), by name and
/// bytes, the scope and this program's version. The same hash, the same report.
fn made_from(dir: &Path, scope: Scope) -> Result<crowd_core::Hash> {
    let mut names: Vec<String> = std::fs::read_dir(dir)?
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.ends_with(".ron") || n.ends_with(".csv"))
        .collect();
    names.sort();
    let mut h = crowd_core::Hasher::new("report", 1);
    h.value("crowd", &env!("CARGO_PKG_VERSION"));
    h.value("scope", &scope.last.map(|s| s.name));
    for name in names {
        let bytes = std::fs::read(dir.join(&name))?;
        h.value(&name, &crowd_core::Hash::of(&bytes));
    }
    Ok(h.finish())
}

/// Whether `dir`'s `report.md` was made from exactly what a report in `scope` would read now
/// (and its pictures are there).
pub fn up_to_date(dir: &Path, scope: Scope) -> bool {
    let Ok(text) = std::fs::read_to_string(dir.join(REPORT_FILE)) else {
        return false;
    };
    let pictures_there = text
        .split("](")
        .skip(1)
        .filter_map(|rest| rest.split_once(')'))
        .all(|(file, _)| dir.join(file).is_file());
    let last = text.trim_end().lines().last().unwrap_or_default();
    pictures_there && made_from(dir, scope).is_ok_and(|h| last == format!("{MADE_FROM}{h} -->"))
}

/// Writes `report.md` in `dir` unless it is [`up_to_date`] (a build with nothing to do
/// rewrites nothing). The report's path either way.
pub fn refresh(dir: &Path, scope: Scope) -> Result<PathBuf> {
    if up_to_date(dir, scope) {
        return Ok(dir.join(REPORT_FILE));
    }
    write(dir, scope)
}

/// Draws the pictures of the stage files in `dir` that are in `scope`, then writes `report.md`
/// there, ending with the hash of what it was made from.
pub fn write(dir: &Path, scope: Scope) -> Result<PathBuf> {
    let pictures = draw_pictures(dir, scope)?;
    let report = Report::gather_in(dir, scope)?;
    let warnings = crate::warnings::gather(dir)?;
    let marked = if warnings.iter().any(|w| !w.patches.is_empty()) {
        Some(crate::warnings::draw(
            dir,
            &warnings,
            &dir.join(WARNINGS_PICTURE),
        )?)
    } else {
        // A picture of an earlier build's warnings build had would mislead.
        let _ = std::fs::remove_file(dir.join(WARNINGS_PICTURE));
        None
    };
    let mut text = markdown(dir, &report, &pictures);
    // The warnings go first, under the title: they are what a person must read.
    let at = text.find("\n## ").map_or(text.len(), |i| i + 1);
    text.insert_str(at, &warnings_section(&warnings, marked));
    let _ = writeln!(text, "\n{MADE_FROM}{} -->", made_from(dir, scope)?);
    let path = dir.join(REPORT_FILE);
    files::write_atomic(&path, text.as_bytes())?;
    Ok(path)
}

/// The picture of where the warnings are, beside the report.
pub const WARNINGS_PICTURE: &str = "report_warnings.png";

/// `report.md`'s list of what the build could not meet, with its picture (`marked`: the
/// picture's legend, when there is one).
fn warnings_section(warnings: &[crate::warnings::Warning], marked: Option<&str>) -> String {
    if warnings.is_empty() {
        return "## Warnings\n\nNone: the build met every part of the painting it checks.\n\n"
            .to_string();
    }
    let mut s = format!(
        "## Warnings\n\n{} part(s) of the painting the build could not meet (`crowd build \
         --deny-warnings` fails on them):\n\n",
        warnings.len()
    );
    for w in warnings {
        let _ = writeln!(s, "- {}", w.text);
    }
    if let Some(legend) = marked {
        let _ = writeln!(s, "\n![where]({WARNINGS_PICTURE})\n\n{legend}");
    }
    s.push('\n');
    s
}

/// A picture in the report: file name beside it, caption, legend.
struct Picture {
    file: &'static str,
    caption: &'static str,
    legend: &'static str,
}

/// One PNG per stage file the folder holds (the latest trajectories only), named `report_*`.
fn draw_pictures(dir: &Path, scope: Scope) -> Result<Vec<Picture>> {
    let trajectories = [SMOOTHED_FILE, COLLIDED_FILE, TRAJECTORIES_FILE]
        .into_iter()
        .find(|f| scope.file(dir, f).is_some());
    let wanted = [
        (
            Some(MERGE_FILE),
            "report_maps.png",
            "Stage 1: the merged maps",
        ),
        (
            Some(GRAPH_FILE),
            "report_graph.png",
            "Stage 2: the patch graph",
        ),
        (
            Some(PATTERNS_FILE),
            "report_patterns.png",
            "Stage 3: density error per patch, and E per iteration",
        ),
        (
            trajectories,
            "report_patch.png",
            "The busiest patch's final trajectories",
        ),
    ];
    // Drawn at once: the busiest patch's picture reads the whole trajectories file (a second
    // of painting's build) while the others take a tenth each.
    let drawn: Vec<Option<Result<Picture>>> = wanted
        .into_par_iter()
        .map(|(stage_file, file, caption)| {
            let path = stage_file.and_then(|f| scope.file(dir, f))?;
            Some(
                crate::inspect::render(&path, &dir.join(file), None).map(|legend| Picture {
                    file,
                    caption,
                    legend,
                }),
            )
        })
        .collect();
    drawn.into_iter().flatten().collect()
}

fn markdown(dir: &Path, report: &Report, pictures: &[Picture]) -> String {
    let json = report.to_json();
    let name = dir.file_name().map_or_else(
        || dir.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let mut s = format!("# Crowd build report: {name}\n\n");
    let _ = writeln!(
        s,
        "Written by `crowd build` (collision and motion figures by `crowd check`). Figures as \
         defined in DESIGN.md, \"The figures we judge by\".\n"
    );
    let sections: [(&str, &[(&str, &str)]); 4] = [
        (
            "World (stages 1 and 2)",
            &[
                ("patches", "patches"),
                ("patch_side_m", "patch side (m)"),
                ("components", "connected components"),
                ("borders", "borders"),
                ("closed_borders", "closed borders"),
                ("walkers_requested", "walkers requested"),
                ("walkers_measured", "walkers measured"),
                ("standers", "standers"),
            ],
        ),
        (
            "Patterns (stage 3, Crowd Art eq. 4-6)",
            &[
                ("E_rho", "E_rho"),
                ("E_d", "E_d"),
                ("E", "E"),
                ("iterations", "iterations"),
                ("converged", "converged"),
            ],
        ),
        (
            "Collisions and motion (`crowd check`, whole tiled world)",
            &[
                ("checked_stage", "trajectories checked"),
                ("collisions", "collisions"),
                ("collisions_across_borders", "of them across borders"),
                ("min_clearance_m", "smallest clearance (m)"),
                ("unconverged_patches", "unconverged patches (stage 5)"),
                ("speed_in_band", "share of walking time at 0.5-1.8 m/s"),
                ("accel_p95", "acceleration p95 (m/s2)"),
                ("turn_rate_p95", "turning rate p95 (rad/s)"),
                (
                    "max_border_velocity_jump",
                    "largest velocity jump at a border (m/s)",
                ),
                ("max_boundary_error_m", "boundary points off (m)"),
                ("max_boundary_time_error_s", "boundary points off (s)"),
                ("unmatched_crossings", "crossings not entered and left once"),
            ],
        ),
        (
            "Library (stage 8)",
            &[
                ("library_walkers", "walkers"),
                ("library_standers", "standers"),
                ("library_loops", "loops"),
                ("library_points", "trajectory points"),
                ("library_position_error_m", "worst position error (m)"),
                ("library_time_error_s", "worst time error (s)"),
            ],
        ),
    ];
    for (title, rows) in sections {
        if title.starts_with("Collisions")
            && report.check.is_some()
            && let Some(stale) = stale_check(dir)
        {
            let _ = writeln!(
                s,
                "## {title}\n\n`{}` is older than `{stale}`: run `crowd check {}` for figures \
                 of this build.\n",
                crate::check::CHECK_FILE,
                dir.display()
            );
            continue;
        }
        let present: Vec<_> = rows
            .iter()
            .filter_map(|(key, label)| json.get(*key).map(|v| (label, v)))
            .collect();
        if present.is_empty() && !title.starts_with("Collisions") {
            let _ = writeln!(s, "## {title}\n\nNot built yet.\n");
            continue;
        }
        if title.starts_with("Collisions") && report.check.is_none() {
            let _ = writeln!(
                s,
                "## {title}\n\nNot checked yet: run `crowd check {}` for the collision and \
                 motion figures.\n",
                dir.display()
            );
        } else {
            let _ = writeln!(s, "## {title}\n");
        }
        if present.is_empty() {
            continue;
        }
        let _ = writeln!(s, "| figure | value |\n| --- | ---: |");
        for (label, value) in present {
            let _ = writeln!(s, "| {label} | {} |", cell(value));
        }
        s.push('\n');
    }

    shipped(&mut s, dir, report, &json);
    edits(&mut s, report);
    let _ = writeln!(
        s,
        "## Cost\n\nWall time and peak resident memory of each stage (and of the check) when it \
         last ran.\n\n| stage | wall (s) | peak memory (MB) |\n| --- | ---: | ---: |"
    );
    for stage in STAGES.map(|s| s.name).into_iter().chain(["check"]) {
        if let Some(run) = report.stages.get(stage) {
            let peak = run.peak_mb.map_or("-".into(), |mb| format!("{mb:.0}"));
            let _ = writeln!(s, "| {stage} | {:.2} | {peak} |", run.seconds);
        }
    }
    // Whole stages only: the parts of one (`edit: NAME`) are inside its time.
    let whole = || (report.stages.iter()).filter(|(k, _)| !k.contains(": "));
    let total: f64 = whole().map(|(_, r)| r.seconds).sum();
    let peak = whole()
        .filter_map(|(_, r)| r.peak_mb)
        .reduce(f64::max)
        .map_or("-".into(), |mb| format!("{mb:.0}"));
    let _ = writeln!(s, "| **all stages** | **{total:.2}** | **{peak}** |\n");

    let _ = writeln!(s, "## Outputs\n\n| file | size |\n| --- | ---: |");
    for (file, bytes) in report.outputs.iter().filter(|(f, _)| *f != REPORT_FILE) {
        let _ = writeln!(s, "| `{file}` | {} |", size(*bytes));
    }
    s.push('\n');

    if !pictures.is_empty() {
        let _ = writeln!(s, "## Pictures\n");
        for p in pictures {
            let _ = writeln!(
                s,
                "### {}\n\n![{}]({})\n\n{}\n",
                p.caption, p.caption, p.file, p.legend
            );
        }
    }
    s
}

/// The section of what ships: `crowd check`'s figures of `library.crowd` and `world.glb`, side
/// by side.
fn shipped(s: &mut String, dir: &Path, report: &Report, json: &Value) {
    let title =
        "What ships (`crowd check` on `library.crowd` and `world.glb`, as an engine reads them)";
    let checked = report.check.as_ref();
    if checked.is_none_or(|c| c.library.is_none() && c.gltf.is_none()) {
        if report.export.is_some() {
            let _ = writeln!(
                s,
                "## {title}\n\nNot checked yet: run `crowd check {}`.\n",
                dir.display()
            );
        }
        return;
    }
    if stale_check(dir).is_some() {
        return; // said in the section above
    }
    let _ = writeln!(
        s,
        "## {title}\n\nThe library is rebuilt as the runtime plays it and also played by its \
         `Sampler` every {} s over a period; the glTF's nodes are read through its LINEAR \
         samplers. A seam is where a path hands over after its last key: a library loop's end to \
         its start, a glTF node at the clip's end to the node that starts there.\n\n\
         | figure | `library.crowd` | `world.glb` |\n| --- | ---: | ---: |",
        crate::check::SAMPLE_STEP_S
    );
    for (key, label) in crate::report::PRODUCT_ROWS {
        let value = |prefix: &str| json.get(format!("{prefix}_{key}")).map(cell);
        let (a, b) = (value("library"), value("gltf"));
        if a.is_some() || b.is_some() {
            let dash = || "-".to_string();
            let (a, b) = (a.unwrap_or_else(dash), b.unwrap_or_else(dash));
            let _ = writeln!(s, "| {label} | {a} | {b} |");
        }
    }
    s.push('\n');
}

/// The file that changed after `check.ron` was written, if one did.
fn stale_check(dir: &Path) -> Option<&'static str> {
    let modified = |f: &str| {
        std::fs::metadata(dir.join(f))
            .and_then(|m| m.modified())
            .ok()
    };
    let checked = modified(crate::check::CHECK_FILE)?;
    [
        SMOOTHED_FILE,
        COLLIDED_FILE,
        TRAJECTORIES_FILE,
        crowd_export::LIBRARY_FILE,
        crowd_export::GLB_FILE,
    ]
    .into_iter()
    .find(|f| modified(f).is_some_and(|t| t > checked))
}

/// A figure as a table cell: floats to four significant places, shares as percentages.
fn cell(v: &Value) -> String {
    match v {
        Value::Number(n) if n.is_f64() => {
            let x = n.as_f64().unwrap_or(f64::NAN);
            if x.fract() == 0.0 && x.abs() < 1e15 {
                format!("{x:.0}")
            } else if x != 0.0 && x.abs() < 1e-3 {
                format!("{x:.2e}")
            } else {
                format!("{x:.4}")
            }
        }
        Value::String(t) => t.clone(),
        other => other.to_string(),
    }
}

fn size(bytes: u64) -> String {
    match bytes {
        b if b >= 1_000_000 => format!("{:.1} MB", b as f64 / 1e6),
        b if b >= 1_000 => format!("{:.1} kB", b as f64 / 1e3),
        b => format!("{b} B"),
    }
}

/// The edits of stage 7, when the pipeline has any: each one's residual before and after.
fn edits(s: &mut String, report: &Report) {
    let Some(edits) = report.edited.as_ref().and_then(|e| e.edits.as_ref()) else {
        return;
    };
    let _ = writeln!(
        s,
        "## Edits (stage 7)\n\nEach edit's residual on the patches it covers, before and after \
         (what it measures in the last column), and the seconds its problems took.\n\n| edit | \
         kind | before | after | patches | walkers changed | iterations | seconds | measure \
         |\n| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |"
    );
    for e in edits {
        let seconds = report
            .edit_seconds(&e.name)
            .map_or("-".to_string(), |t| format!("{t:.3}"));
        let _ = writeln!(
            s,
            "| {} | {} | {:.3} | {:.3} | {} | {} | {} | {seconds} | {} |",
            e.name,
            e.kind,
            e.before,
            e.after,
            e.patches.len(),
            e.walkers,
            e.iterations,
            e.measure
        );
    }
    s.push('\n');
    for e in edits {
        if let Some(note) = &e.note {
            let _ = writeln!(s, "- {}: {note}.", e.name);
        }
    }
    if edits.iter().any(|e| e.note.is_some()) {
        s.push('\n');
    }
}
