//! `crowd report`: the figures a build folder holds so far, as text or one JSON object.

use crate::check::CHECK_FILE;
use crate::driver::{StageRun, read_timings};
use crate::stage::{self, Stage};
use crate::stages::{
    self, COLLIDED_FILE, EXPORT_FILE, GRAPH_FILE, PATTERNS_FILE, SMOOTHED_FILE, TRAJECTORIES_FILE,
};
use anyhow::{Context, Result};
use crowd_check::ProductFigures;
use crowd_core::PatchGraph;
use crowd_core::files;
use crowd_core::patterns::Patterns;
use crowd_core::trajectories::TrajectoriesFile;
use serde_json::{Map, Value, json};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Figures gathered from the stage files of a build folder.
pub struct Report {
    /// Shared with the check and the pictures of the same process (`PatchGraph::load_shared`:
    /// painting's 3.5 MB of RON took 0.15 s to parse again for the report).
    pub graph: Option<std::sync::Arc<PatchGraph>>,
    pub patterns: Option<Patterns>,
    pub trajectories: Option<TrajectoriesFile>,
    pub collided: Option<TrajectoriesFile>,
    pub smoothed: Option<TrajectoriesFile>,
    /// Stage 7's file, when the pipeline has edits.
    pub edited: Option<TrajectoriesFile>,
    /// The last `crowd check` of the folder.
    pub check: Option<crowd_check::CheckReport>,
    pub export: Option<crowd_export::ExportFile>,
    /// What each stage cost when it last ran.
    pub stages: BTreeMap<String, StageRun>,
    /// Every file of the folder and its size in bytes, by name.
    pub outputs: BTreeMap<String, u64>,
}

/// Which stage files of a folder a report reads. After `crowd build --until graph` the files of
/// later stages may be left from an earlier build of other inputs: the build did not look at
/// them, so its report must not present them (nor fail on them) as if they were its own.
#[derive(Clone, Copy, Default)]
pub struct Scope {
    /// The last stage the build covered; `None` reads every stage file there is.
    pub last: Option<&'static Stage>,
}

impl Scope {
    /// The path of `file` in `dir` when it exists and is in scope.
    pub fn file(&self, dir: &Path, file: &str) -> Option<PathBuf> {
        let in_scope = match self.last {
            None => true,
            Some(last) => {
                let covered: Vec<&Stage> = stage::up_to(Some(last)).collect();
                if file == CHECK_FILE {
                    covered.contains(&&stages::SMOOTH)
                } else {
                    stages::STAGES
                        .iter()
                        .find(|s| s.writes.contains(&file))
                        .is_none_or(|owner| covered.contains(owner))
                }
            }
        };
        let path = dir.join(file);
        (in_scope && path.exists()).then_some(path)
    }
}

impl Report {
    /// The seconds stage 7 spent on edit `name` (`timings.ron`'s `"edit: NAME"`).
    pub fn edit_seconds(&self, name: &str) -> Option<f64> {
        let key = format!("{}: {name}", stages::EDIT.name);
        self.stages.get(&key).map(|r| r.seconds)
    }

    /// Every figure of the folder's stage files.
    pub fn gather(dir: &Path) -> Result<Report> {
        Report::gather_in(dir, Scope::default())
    }

    /// The figures of the stage files in `scope`.
    pub fn gather_in(dir: &Path, scope: Scope) -> Result<Report> {
        stages::expect_build_folder(dir)?;
        // Each stage file is read if the build got that far.
        fn read<T: serde::de::DeserializeOwned>(path: Option<PathBuf>) -> Result<Option<T>> {
            Ok(path.map(|p| files::read_ron(&p)).transpose()?)
        }
        let optional = |file: &str| scope.file(dir, file);
        // Its stage and version are checked as it is read.
        let graph = optional(GRAPH_FILE)
            .map(|path| PatchGraph::load_shared(&path))
            .transpose()?;
        let patterns = read(optional(PATTERNS_FILE))?;
        let trajectories = read(optional(TRAJECTORIES_FILE))?;
        let collided = read(optional(COLLIDED_FILE))?;
        let smoothed = read(optional(SMOOTHED_FILE))?;
        let edited = read(optional(stages::EDITED_FILE))?;
        let check = read(optional(CHECK_FILE))?;
        let export = read(optional(EXPORT_FILE))?;
        let mut outputs = BTreeMap::new();
        for entry in std::fs::read_dir(dir).with_context(|| format!("{}", dir.display()))? {
            let entry = entry.with_context(|| format!("{}", dir.display()))?;
            let name = entry.file_name().to_string_lossy().into_owned();
            // A file being written or removed (a replaced one keeps a temporary name until
            // this process's own background thread removes it) is no output, and may be gone
            // by now.
            if files::is_temporary(&name) {
                continue;
            }
            let meta = match entry.metadata() {
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
                meta => meta.with_context(|| format!("{}", entry.path().display()))?,
            };
            if meta.is_file() {
                outputs.insert(name, meta.len());
            }
        }
        Ok(Report {
            graph,
            patterns,
            trajectories,
            collided,
            smoothed,
            edited,
            check,
            export,
            stages: read_timings(dir),
            outputs,
        })
    }

    pub fn to_json(&self) -> Value {
        let mut out = Map::new();
        if let Some(g) = &self.graph {
            let area = g.patch_area();
            out.insert("patches".into(), json!(g.patches.len()));
            out.insert("components".into(), json!(g.components.len()));
            out.insert("walkers_requested".into(), json!(g.walkers_requested));
            out.insert("standers_requested".into(), json!(g.standers_requested));
            let walkers: f64 = g.patches.iter().map(|p| p.walker_density * area).sum();
            let standers: f64 = g.patches.iter().map(|p| p.stander_density * area).sum();
            out.insert("walkers_in_patches".into(), json!(walkers));
            out.insert("standers_in_patches".into(), json!(standers));
            out.insert("patch_side_m".into(), json!(g.world.patch_side_m));
            out.insert("dropped_empty".into(), json!(g.dropped.empty.len()));
            out.insert("dropped_blocked".into(), json!(g.dropped.blocked.len()));
            out.insert(
                "directed_patches".into(),
                json!(g.patches.iter().filter(|p| p.direction.is_some()).count()),
            );
            out.insert("borders".into(), json!(g.borders.len()));
            out.insert(
                "closed_borders".into(),
                json!(g.borders.iter().filter(|b| b.open.is_empty()).count()),
            );
        }
        if let Some(p) = &self.patterns {
            out.insert("E_rho".into(), json!(p.error.e_rho));
            out.insert("E_d".into(), json!(p.error.e_d));
            out.insert("E".into(), json!(p.error.e));
            out.insert("iterations".into(), json!(p.iterations));
            out.insert("converged".into(), json!(p.converged));
            out.insert(
                "standers".into(),
                json!(p.measured.iter().map(|m| m.standers as u64).sum::<u64>()),
            );
        }
        if let Some(t) = &self.trajectories {
            out.insert("walkers_measured".into(), json!(t.summary.walkers_measured));
            out.insert("trajectories".into(), json!(t.summary.walkers_trajectories));
        }
        if let Some(c) = &self.check {
            out.insert("collisions".into(), json!(c.collisions));
            out.insert("collisions_across_borders".into(), json!(c.across_borders));
            out.insert("min_clearance_m".into(), json!(c.min_clearance_m));
            out.insert("checked_stage".into(), json!(c.stage));
            if let Some(m) = &c.motion {
                out.insert("speed_in_band".into(), json!(m.speed_in_band));
                out.insert("accel_p95".into(), json!(m.accel_p95));
                out.insert("turn_rate_p95".into(), json!(m.turn_rate_p95));
                out.insert(
                    "max_border_velocity_jump".into(),
                    json!(m.max_border_velocity_jump),
                );
                out.insert("max_boundary_error_m".into(), json!(m.max_boundary_error_m));
                out.insert(
                    "max_boundary_time_error_s".into(),
                    json!(m.max_boundary_time_error_s),
                );
                out.insert("unmatched_crossings".into(), json!(m.unmatched_crossings));
            }
        }
        for (prefix, p) in [("library", &c_library(self)), ("gltf", &c_gltf(self))] {
            for (key, value) in p.iter().flat_map(product_json) {
                out.insert(format!("{prefix}_{key}"), value);
            }
        }
        if let Some(s) = self.smoothed.as_ref().and_then(|s| s.smoothing.as_ref()) {
            out.insert("smoothed_trajectories".into(), json!(s.smoothed));
            out.insert("kept_straight".into(), json!(s.kept_straight));
        }
        if let Some(edits) = self.edited.as_ref().and_then(|e| e.edits.as_ref()) {
            let with_seconds: Vec<Value> = edits
                .iter()
                .map(|e| {
                    let mut v = json!(e);
                    v["seconds"] = json!(self.edit_seconds(&e.name));
                    v
                })
                .collect();
            out.insert("edits".into(), json!(with_seconds));
        }
        if let Some(c) = self.collided.as_ref().and_then(|c| c.collisions.as_ref()) {
            out.insert("unconverged_patches".into(), json!(c.unconverged.len()));
            out.insert("collide_pushes".into(), json!(c.iterations));
        }
        if let Some(e) = &self.export {
            out.insert("library_walkers".into(), json!(e.walkers));
            out.insert("library_standers".into(), json!(e.standers));
            out.insert("library_loops".into(), json!(e.loops));
            out.insert("library_points".into(), json!(e.points));
            out.insert("library_position_error_m".into(), json!(e.position_error_m));
            out.insert("library_time_error_s".into(), json!(e.time_error_s));
        }
        let whole = || self.stages.iter().filter(|(k, _)| !k.contains(": "));
        let seconds: BTreeMap<_, _> = whole().map(|(k, r)| (k, r.seconds)).collect();
        let peaks: BTreeMap<_, _> = whole().map(|(k, r)| (k, r.peak_mb)).collect();
        out.insert("stage_seconds".into(), json!(seconds));
        out.insert("stage_peak_mb".into(), json!(peaks));
        out.insert("build_seconds".into(), json!(seconds.values().sum::<f64>()));
        let peak = peaks.values().flatten().copied().reduce(f64::max);
        out.insert("build_peak_mb".into(), json!(peak));
        out.insert("output_bytes".into(), json!(self.outputs));
        Value::Object(out)
    }

    pub fn to_text(&self) -> String {
        let json = self.to_json();
        let mut s = String::new();
        for (key, value) in json.as_object().expect("an object") {
            let Value::Object(items) = value else {
                s += &format!("{key:<26} {value}\n");
                continue;
            };
            for (item, v) in items {
                let name = format!("{key}.{item}");
                let v = v.as_f64();
                s += &match (key.as_str(), v) {
                    (_, None) => format!("{name:<26} -\n"),
                    ("stage_seconds", Some(v)) => format!("{name:<26} {v:.3} s\n"),
                    ("stage_peak_mb", Some(v)) => format!("{name:<26} {v:.0} MB\n"),
                    ("output_bytes", Some(v)) => format!("{name:<26} {:.2} MB\n", v / 1e6),
                    (_, Some(v)) => format!("{name:<26} {v}\n"),
                };
            }
        }
        s
    }
}

fn c_library(r: &Report) -> Option<ProductFigures> {
    r.check.as_ref().and_then(|c| c.library.clone())
}

fn c_gltf(r: &Report) -> Option<ProductFigures> {
    r.check.as_ref().and_then(|c| c.gltf.clone())
}

/// A shipped file's figures in the report: JSON key (after `library_` or `gltf_`) and label.
pub const PRODUCT_ROWS: [(&str, &str); 17] = [
    ("collisions", "collisions"),
    ("min_clearance_m", "smallest clearance (m)"),
    ("max_speed", "largest speed (m/s)"),
    ("speed_limit", "speed limit, `match.max_speed` + 5 % (m/s)"),
    ("share_above_speed_limit", "share of walking time above it"),
    (
        "max_key_velocity_jump",
        "largest velocity jump at a key (m/s)",
    ),
    (
        "max_border_velocity_jump",
        "largest velocity jump at a border (m/s)",
    ),
    ("max_border_gap_m", "largest gap at a border (m)"),
    (
        "max_seam_velocity_jump",
        "largest velocity jump at a seam (m/s)",
    ),
    (
        "max_seam_heading_jump_rad",
        "largest heading jump at a seam (rad)",
    ),
    ("max_seam_gap_m", "largest gap at a seam (m)"),
    ("loops", "loops (glTF: animated nodes)"),
    ("open_loops", "open loops (end 1 cm or more from any start)"),
    (
        "max_turn_rate_rad_s",
        "fastest turn (rad/s; glTF: between rotation keys, library: its sampler's frames)",
    ),
    (
        "turn_rate_limit_rad_s",
        "turn limit (rad/s; `export.turn_rate_deg_s` + 1 %)",
    ),
    ("sampled_max_speed", "runtime's sampler: fastest step (m/s)"),
    (
        "sampler_jumps",
        "runtime's sampler: steps beyond the walker's fastest piece",
    ),
];

/// The figures of [`PRODUCT_ROWS`] a shipped file has.
fn product_json(p: &ProductFigures) -> Vec<(&'static str, Value)> {
    let mut v = vec![
        ("collisions", json!(p.collisions)),
        ("min_clearance_m", json!(p.min_clearance_m)),
        ("max_speed", json!(p.max_speed_m_s)),
        ("speed_limit", json!(p.speed_limit_m_s)),
        ("share_above_speed_limit", json!(p.share_above_limit)),
        ("max_key_velocity_jump", json!(p.max_key_velocity_jump)),
        ("max_seam_velocity_jump", json!(p.max_seam_velocity_jump)),
        (
            "max_seam_heading_jump_rad",
            json!(p.max_seam_heading_jump_rad),
        ),
        ("max_seam_gap_m", json!(p.max_seam_gap_m)),
        ("loops", json!(p.loops)),
        ("open_loops", json!(p.open_loops)),
    ];
    let sampled = p.sampled.as_ref();
    let optional = [
        (
            "max_border_velocity_jump",
            p.max_border_velocity_jump.map(|x| json!(x)),
        ),
        ("max_border_gap_m", p.max_border_gap_m.map(|x| json!(x))),
        (
            "max_turn_rate_rad_s",
            p.max_turn_rate_rad_s.map(|x| json!(x)),
        ),
        (
            "turn_rate_limit_rad_s",
            p.turn_rate_limit_rad_s.map(|x| json!(x)),
        ),
        ("sampled_max_speed", sampled.map(|s| json!(s.max_speed_m_s))),
        ("sampler_jumps", sampled.map(|s| json!(s.jumps))),
    ];
    v.extend(optional.into_iter().filter_map(|(k, x)| Some((k, x?))));
    v
}

/// Columns of [`Report::table_row`].
pub const TABLE_HEADER: &str = "| scene | patches | walkers requested | walkers measured | standers | \
iterations | optimise (s) | match (s) | E_rho | E_d | E |\n\
| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |";

impl Report {
    /// One markdown row of figures (a dash where a stage has not run).
    pub fn table_row(&self, dir: &Path) -> String {
        let json = self.to_json();
        let f = |key: &str, digits: usize| match json.get(key).and_then(Value::as_f64) {
            Some(v) => format!("{v:.digits$}"),
            None => "-".to_string(),
        };
        let seconds = |stage: &str| {
            self.stages
                .get(stage)
                .map_or("-".to_string(), |r| format!("{:.2}", r.seconds))
        };
        let name = dir.file_name().map_or(dir.display().to_string(), |n| {
            n.to_string_lossy().into_owned()
        });
        format!(
            "| {name} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            f("patches", 0),
            f("walkers_requested", 0),
            f("walkers_measured", 0),
            f("standers", 0),
            f("iterations", 0),
            seconds("optimize"),
            seconds("match"),
            f("E_rho", 4),
            f("E_d", 4),
            f("E", 4),
        )
    }
}
