//! `pipeline.ron`: what to build and how.
//!
//! Unknown fields are errors (with the nearest valid name suggested), and every value is checked
//! before any stage runs, with the line and column of the offending field.

use crate::error::{Error, LineCol, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The build description. Paths are relative to the folder of the pipeline file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pipeline {
    /// The painted layers and their scale.
    pub scene: Scene,
    /// Walking (exogenous) characters in the whole scene.
    pub walkers: u64,
    /// Standing (endogenous, static) characters in the whole scene.
    #[serde(default)]
    pub standers: u64,
    /// Side of the square crowd patches, in metres.
    pub patch_side_m: f64,
    /// Period of the animation, in seconds.
    pub period_s: f64,
    /// Character radius, in metres.
    pub radius_m: f64,
    /// Seed of every random choice of the build.
    pub seed: u64,
    /// Folder the stage files are written to.
    pub output: PathBuf,
    #[serde(default)]
    pub merge: MergeSettings,
    #[serde(default)]
    pub graph: GraphSettings,
    #[serde(default)]
    pub optimize: OptimizeSettings,
    #[serde(default, rename = "match")]
    pub matching: MatchSettings,
    #[serde(default)]
    pub collide: CollideSettings,
    #[serde(default)]
    pub smooth: SmoothSettings,
    #[serde(default)]
    pub export: ExportSettings,
}

/// Stage 8's settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExportSettings {
    /// The part of the world `world.glb` holds, `(x0, y0, x1, y1)` in world metres: the
    /// characters there at time 0 (DCC tools slow down with tens of thousands of animated
    /// nodes). None: the whole world. The library always holds the whole world.
    #[serde(default)]
    pub gltf_region: Option<(f64, f64, f64, f64)>,
    /// Keyframes are dropped where the walk between the kept ones stays within this many
    /// millimetres of stage 6's: about half of them at 0.75, which halves the library and the
    /// runtime's steps onto new pieces. 0 keeps every keyframe.
    #[serde(default = "default_simplify_mm")]
    pub simplify_mm: f64,
}

fn default_simplify_mm() -> f64 {
    0.75
}

impl Default for ExportSettings {
    fn default() -> ExportSettings {
        ExportSettings {
            gltf_region: None,
            simplify_mm: default_simplify_mm(),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// World size of one pixel, in metres.
    pub meters_per_pixel: f64,
    pub layers: Vec<LayerSpec>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LayerSpec {
    pub kind: LayerKind,
    pub path: PathBuf,
    /// Layer opacity: multiplies every pixel's alpha when layers of a kind are merged.
    #[serde(default = "one")]
    pub weight: f64,
}

fn one() -> f64 {
    1.0
}

/// The painted layer kinds of DESIGN.md.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum LayerKind {
    /// Gray, brighter = more walkers (relative).
    Density,
    /// Gray, brighter = more standing characters (relative).
    Static,
    /// Gray (+ alpha as weight): people walk from dark to bright.
    Direction,
    /// RGBA flow map: R = east, G = north, 128 = zero, A = weight.
    Flow,
    /// Gray, bright = blocked.
    Obstacles,
}

impl LayerKind {
    pub fn name(self) -> &'static str {
        match self {
            LayerKind::Density => "density",
            LayerKind::Static => "static",
            LayerKind::Direction => "direction",
            LayerKind::Flow => "flow",
            LayerKind::Obstacles => "obstacles",
        }
    }
}

/// Settings of stage 1.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MergeSettings {
    /// An obstacle pixel is blocked when value x alpha reaches this (0..1].
    pub obstacle_threshold: f64,
}

impl Default for MergeSettings {
    fn default() -> Self {
        MergeSettings {
            obstacle_threshold: 0.5,
        }
    }
}

/// Settings of stage 2.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GraphSettings {
    /// A patch whose mean painted density (walkers and standers, 0..1 per layer) is at most this
    /// is empty and dropped. The default drops only patches where nothing at all is painted.
    pub empty_below: f64,
    /// A patch whose obstacle coverage reaches this share of its area is blocked and dropped.
    pub blocked_above: f64,
    /// A patch gets a requested direction only where the mean direction weight reaches this.
    pub direction_min_weight: f64,
    /// Open border intervals narrower than this are closed. Default: one character's diameter.
    pub min_opening_m: Option<f64>,
}

impl Default for GraphSettings {
    fn default() -> Self {
        GraphSettings {
            empty_below: 0.0,
            blocked_above: 0.8,
            direction_min_weight: 0.25,
            min_opening_m: None,
        }
    }
}

/// Settings of stage 3.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OptimizeSettings {
    /// Largest density any patch may reach, characters per m2 (Crowd Art: 0.35).
    pub rho_max: f64,
    /// Optimisation steps at most.
    pub max_iterations: u32,
    /// The loop stops when E has improved by less than this over the last `patience` steps.
    pub tolerance: f64,
    pub patience: u32,
}

impl Default for OptimizeSettings {
    fn default() -> Self {
        OptimizeSettings {
            rho_max: 0.35,
            max_iterations: 400,
            tolerance: 5e-4,
            patience: 30,
        }
    }
}

/// Settings of stage 4 (also used by stage 3 to measure density and direction).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MatchSettings {
    /// Free walking speed of the fundamental diagram, m/s (Ramirez et al.: 1.33).
    pub comfort_speed: f64,
    /// Slower than this, a walker pauses instead; m/s.
    pub min_speed: f64,
    /// Faster than this is implausible: the walker stays for extra periods; m/s.
    pub max_speed: f64,
    /// Weight of the requested-direction term of the matching score.
    pub direction_gain: f64,
    /// How far towards the centre a walker turns when entering and leaving by the same border,
    /// as a share of the patch side.
    pub turn_depth: f64,
}

impl Default for MatchSettings {
    fn default() -> Self {
        MatchSettings {
            comfort_speed: 1.33,
            min_speed: 0.5,
            max_speed: 1.8,
            direction_gain: 3.0,
            turn_depth: 0.3,
        }
    }
}

/// Settings of stage 5.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CollideSettings {
    /// Pushes per patch at most before the patch is reported unconverged.
    pub max_iterations: u32,
}

impl Default for CollideSettings {
    fn default() -> Self {
        CollideSettings {
            max_iterations: 12_000,
        }
    }
}

/// Settings of stage 6 (Ramirez section 3.5).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SmoothSettings {
    /// Time between two tacks sampled on a trajectory, seconds.
    pub tack_spacing_s: f64,
    /// A smoothed point farther than this from the trajectory at the same time is dropped,
    /// metres (Ramirez's alpha; default: a character's diameter, 2 x `radius_m`).
    pub max_displacement_m: Option<f64>,
    /// The curve is resampled until no chord strays farther than this from it, metres.
    pub tolerance_m: f64,
}

impl Default for SmoothSettings {
    fn default() -> Self {
        SmoothSettings {
            tack_spacing_s: 3.0,
            max_displacement_m: None,
            tolerance_m: 0.01,
        }
    }
}

/// A parsed, checked pipeline together with its source text, so that later checks (which need
/// the painted data) can still point at the line of the setting they refuse.
#[derive(Debug, Clone)]
pub struct PipelineFile {
    pub path: PathBuf,
    pub text: String,
    pub pipeline: Pipeline,
}

impl PipelineFile {
    /// Reads, parses and checks a pipeline file.
    pub fn load(path: &Path) -> Result<PipelineFile> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, "read", e))?;
        PipelineFile::parse(path, text)
    }

    /// Parses and checks pipeline text that was read from `path`.
    pub fn parse(path: &Path, text: String) -> Result<PipelineFile> {
        let pipeline: Pipeline =
            ron::Options::default()
                .from_str(&text)
                .map_err(|e| Error::Syntax {
                    path: path.to_path_buf(),
                    place: LineCol {
                        line: e.span.start.line,
                        col: e.span.start.col,
                    },
                    message: describe_ron_error(&e.code),
                })?;
        let file = PipelineFile {
            path: path.to_path_buf(),
            text,
            pipeline,
        };
        file.check()?;
        Ok(file)
    }

    /// The folder relative paths are resolved against.
    pub fn base_dir(&self) -> &Path {
        self.path.parent().unwrap_or(Path::new(""))
    }

    /// A path of the pipeline, resolved against the pipeline's folder.
    pub fn resolve(&self, path: &Path) -> PathBuf {
        if path.is_absolute() {
            path.to_path_buf()
        } else {
            tidy(&self.base_dir().join(path))
        }
    }

    /// The output folder, resolved.
    pub fn output_dir(&self) -> PathBuf {
        self.resolve(&self.pipeline.output)
    }

    /// Where the key `field` (a dotted path like `graph.empty_below` or `scene.layers[2].path`)
    /// is written in the source text, if it is.
    pub fn place_of(&self, field: &str) -> Option<LineCol> {
        locate_field(&self.text, field)
    }

    /// An error about one setting.
    pub fn field_error(&self, field: &str, message: impl Into<String>) -> Error {
        Error::Field {
            path: self.path.clone(),
            place: self.place_of(field),
            field: field.to_string(),
            message: message.into(),
        }
    }

    /// An error where the settings and the painted data contradict each other.
    pub fn scene_error(&self, field: &str, message: impl Into<String>) -> Error {
        Error::Scene {
            path: self.path.clone(),
            place: self.place_of(field),
            message: message.into(),
        }
    }

    fn check(&self) -> Result<()> {
        let p = &self.pipeline;
        let positive = |field: &str, value: f64, unit: &str| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(self.field_error(
                    field,
                    format!("is {value}; expected a positive number of {unit}"),
                ))
            }
        };
        positive("scene.meters_per_pixel", p.scene.meters_per_pixel, "metres")?;
        positive("patch_side_m", p.patch_side_m, "metres")?;
        positive("period_s", p.period_s, "seconds")?;
        positive("radius_m", p.radius_m, "metres")?;
        if 2.0 * p.radius_m >= p.patch_side_m {
            return Err(self.field_error(
                "radius_m",
                format!(
                    "is {} m; expected less than half the patch side ({} m)",
                    p.radius_m, p.patch_side_m
                ),
            ));
        }
        let pixels = p.patch_side_m / p.scene.meters_per_pixel;
        if (pixels - pixels.round()).abs() > 1e-6 || pixels.round() < 1.0 {
            return Err(self.field_error(
                "patch_side_m",
                format!(
                    "is {} m, which is {pixels} pixels at {} m per pixel; expected a whole \
                     number of pixels so that patches follow the painted pixels",
                    p.patch_side_m, p.scene.meters_per_pixel
                ),
            ));
        }
        if p.scene.layers.is_empty() {
            return Err(self.field_error(
                "scene.layers",
                "is empty; expected at least one painted layer",
            ));
        }
        for (i, layer) in p.scene.layers.iter().enumerate() {
            if !(layer.weight.is_finite() && layer.weight >= 0.0) {
                return Err(self.field_error(
                    &format!("scene.layers[{i}].weight"),
                    format!("is {}; expected a weight of 0 or more", layer.weight),
                ));
            }
        }
        let has = |kind: LayerKind| p.scene.layers.iter().any(|l| l.kind == kind);
        if p.walkers > 0 && !has(LayerKind::Density) {
            return Err(self.field_error(
                "walkers",
                format!(
                    "is {} but the scene has no `Density` layer saying where they walk",
                    p.walkers
                ),
            ));
        }
        if p.standers > 0 && !has(LayerKind::Static) {
            return Err(self.field_error(
                "standers",
                format!(
                    "is {} but the scene has no `Static` layer saying where they stand",
                    p.standers
                ),
            ));
        }
        let m = &p.merge;
        if !(m.obstacle_threshold > 0.0 && m.obstacle_threshold <= 1.0) {
            return Err(self.field_error(
                "merge.obstacle_threshold",
                format!("is {}; expected a value in (0, 1]", m.obstacle_threshold),
            ));
        }
        let g = &p.graph;
        if !(g.empty_below.is_finite() && g.empty_below >= 0.0) {
            return Err(self.field_error(
                "graph.empty_below",
                format!("is {}; expected 0 or more", g.empty_below),
            ));
        }
        if !(g.blocked_above > 0.0 && g.blocked_above <= 1.0) {
            return Err(self.field_error(
                "graph.blocked_above",
                format!(
                    "is {}; expected a share of the patch in (0, 1]",
                    g.blocked_above
                ),
            ));
        }
        if !(g.direction_min_weight.is_finite() && g.direction_min_weight >= 0.0) {
            return Err(self.field_error(
                "graph.direction_min_weight",
                format!("is {}; expected 0 or more", g.direction_min_weight),
            ));
        }
        if let Some(w) = g.min_opening_m
            && !(w.is_finite() && w > 0.0)
        {
            return Err(self.field_error(
                "graph.min_opening_m",
                format!("is {w}; expected a positive width in metres"),
            ));
        }
        let sm = &p.smooth;
        let positive = |v: f64| v.is_finite() && v > 0.0;
        for (field, value) in [
            ("smooth.tack_spacing_s", sm.tack_spacing_s),
            ("smooth.tolerance_m", sm.tolerance_m),
            (
                "smooth.max_displacement_m",
                sm.max_displacement_m.unwrap_or(1.0),
            ),
        ] {
            if !positive(value) {
                return Err(
                    self.field_error(field, format!("is {value}; expected a positive number"))
                );
            }
        }
        let o = &p.optimize;
        if !(o.rho_max.is_finite() && o.rho_max > 0.0) {
            return Err(self.field_error(
                "optimize.rho_max",
                format!(
                    "is {}; expected a positive density in characters per m2",
                    o.rho_max
                ),
            ));
        }
        let m = &p.matching;
        if !(m.min_speed > 0.0 && m.min_speed < m.comfort_speed && m.comfort_speed < m.max_speed) {
            return Err(self.field_error(
                "match.comfort_speed",
                format!(
                    "is {} m/s with `min_speed` {} and `max_speed` {}; expected \
                     0 < min_speed < comfort_speed < max_speed",
                    m.comfort_speed, m.min_speed, m.max_speed
                ),
            ));
        }
        if !(m.turn_depth > 0.0 && m.turn_depth < 0.5) {
            return Err(self.field_error(
                "match.turn_depth",
                format!(
                    "is {}; expected a share of the patch side in (0, 0.5)",
                    m.turn_depth
                ),
            ));
        }
        let e = &p.export;
        if !(e.simplify_mm.is_finite() && (0.0..=10.0).contains(&e.simplify_mm)) {
            return Err(self.field_error(
                "export.simplify_mm",
                format!(
                    "is {}; expected a distance in millimetres from 0 (every keyframe) to 10",
                    e.simplify_mm
                ),
            ));
        }
        Ok(())
    }
}

/// Removes `.` and `dir/..` from a relative path, for readable messages
/// (`assets/pipelines/../../build` is `build`).
fn tidy(path: &Path) -> PathBuf {
    use std::path::Component;
    let mut out: Vec<Component> = Vec::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir if matches!(out.last(), Some(Component::Normal(_))) => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    if out.is_empty() {
        PathBuf::from(".")
    } else {
        out.iter().collect()
    }
}

/// A RON error in words, with the nearest valid name for a misspelt field or variant.
fn describe_ron_error(code: &ron::Error) -> String {
    match code {
        ron::Error::NoSuchStructField {
            expected,
            found,
            outer,
        } => {
            let within = outer
                .as_ref()
                .map(|o| format!(" in `{o}`"))
                .unwrap_or_default();
            format!(
                "unknown field `{found}`{within}{}; expected one of {}",
                suggestion(found, expected),
                list(expected)
            )
        }
        ron::Error::NoSuchEnumVariant {
            expected, found, ..
        } => format!(
            "unknown value `{found}`{}; expected one of {}",
            suggestion(found, expected),
            list(expected)
        ),
        ron::Error::IntegerOutOfBounds => "integer out of range here; expected a whole number \
            of 0 or more (`walkers`, `standers` and `seed` are counts)"
            .to_string(),
        other => other.to_string(),
    }
}

fn suggestion(found: &str, expected: &[&str]) -> String {
    expected
        .iter()
        .map(|e| (strsim::levenshtein(found, e), *e))
        .filter(|(d, e)| *d <= (e.len().max(found.len()) / 2).max(2))
        .min()
        .map(|(_, e)| format!(" (did you mean `{e}`?)"))
        .unwrap_or_default()
}

fn list(names: &[&str]) -> String {
    names
        .iter()
        .map(|n| format!("`{n}`"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Finds a dotted field path in RON text by walking its keys in order: `scene.layers[2].path`
/// finds `scene:`, then the third `kind:` of a layer after it, then `path:` after that. Good
/// enough to point a person at the line; `None` when the field is not written (a default).
fn locate_field(text: &str, field: &str) -> Option<LineCol> {
    let mut from = 0;
    for part in field.split('.') {
        let (key, index) = match part.split_once('[') {
            Some((key, rest)) => (key, rest.trim_end_matches(']').parse::<usize>().ok()),
            None => (part, None),
        };
        from = find_key(text, key, from)?;
        if let Some(index) = index {
            // Items of a list are told apart by their first key (`kind` for layers).
            let mut at = from;
            for _ in 0..=index {
                at = find_key(text, "kind", at + 1)?;
            }
            from = at;
        }
    }
    Some(line_col(text, from))
}

/// The byte offset of the next `key:` at or after `from`, skipping comments and strings.
fn find_key(text: &str, key: &str, from: usize) -> Option<usize> {
    let bytes = text.as_bytes();
    let mut i = from;
    while i < bytes.len() {
        match bytes[i] {
            b'/' if bytes.get(i + 1) == Some(&b'/') => {
                while i < bytes.len() && bytes[i] != b'\n' {
                    i += 1;
                }
            }
            b'"' => {
                i += 1;
                while i < bytes.len() && bytes[i] != b'"' {
                    i += if bytes[i] == b'\\' { 2 } else { 1 };
                }
                i += 1;
            }
            _ => {
                let is_ident = |b: u8| b.is_ascii_alphanumeric() || b == b'_';
                if text[i..].starts_with(key) && (i == 0 || !is_ident(bytes[i - 1])) {
                    let after = text[i + key.len()..].trim_start();
                    let boundary = bytes.get(i + key.len()).is_none_or(|b| !is_ident(*b));
                    if boundary && after.starts_with(':') {
                        return Some(i);
                    }
                }
                i += 1;
            }
        }
    }
    None
}

fn line_col(text: &str, offset: usize) -> LineCol {
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let col = before.len() - before.rfind('\n').map_or(0, |n| n + 1) + 1;
    LineCol { line, col }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"(
    scene: (
        meters_per_pixel: 1.0,
        layers: [
            (kind: Density, path: "d.png"),
            (kind: Static, path: "s.png", weight: 0.5), // the park
        ],
    ),
    walkers: 100,
    standers: 10,
    patch_side_m: 8.0,
    period_s: 20.0,
    radius_m: 0.3,
    seed: 1,
    output: "build",
)"#;

    fn parse(text: &str) -> Result<PipelineFile> {
        PipelineFile::parse(Path::new("p.ron"), text.to_string())
    }

    #[test]
    fn a_good_pipeline_parses_with_defaults() {
        let p = parse(GOOD).unwrap().pipeline;
        assert_eq!(p.scene.layers[0].weight, 1.0);
        assert_eq!(p.scene.layers[1].weight, 0.5);
        assert_eq!(p.graph, GraphSettings::default());
    }

    #[test]
    fn fields_are_located_by_their_dotted_path() {
        let f = parse(GOOD).unwrap();
        assert_eq!(
            f.place_of("patch_side_m"),
            Some(LineCol { line: 11, col: 5 })
        );
        assert_eq!(
            f.place_of("scene.layers[1].path"),
            Some(LineCol { line: 6, col: 28 })
        );
        assert_eq!(f.place_of("graph.empty_below"), None);
    }

    #[test]
    fn paths_resolve_against_the_pipeline_folder() {
        let f = PipelineFile::parse(Path::new("assets/pipelines/p.ron"), GOOD.to_string()).unwrap();
        assert_eq!(
            f.resolve(Path::new("../../build/x")),
            PathBuf::from("build/x")
        );
        assert_eq!(
            f.resolve(Path::new("../../../shared/a.png")),
            PathBuf::from("../shared/a.png")
        );
        assert_eq!(
            f.resolve(Path::new("/abs/a.png")),
            PathBuf::from("/abs/a.png")
        );
    }

    #[test]
    fn a_misspelt_field_suggests_the_nearest_name() {
        let text = GOOD.replace("period_s", "periode_s");
        let err = parse(&text).unwrap_err().to_string();
        assert!(err.starts_with("p.ron:12:"), "{err}");
        assert!(err.contains("did you mean `period_s`?"), "{err}");
    }

    #[test]
    fn a_zero_patch_side_names_its_line() {
        let text = GOOD.replace("patch_side_m: 8.0", "patch_side_m: 0.0");
        let err = parse(&text).unwrap_err().to_string();
        assert!(err.starts_with("p.ron:11:5: `patch_side_m` is 0"), "{err}");
    }

    #[test]
    fn export_keeps_keyframes_within_0_75_mm_unless_told_and_refuses_a_negative_distance() {
        assert_eq!(parse(GOOD).unwrap().pipeline.export.simplify_mm, 0.75);
        let text = GOOD.replace("output:", "export: (simplify_mm: -1.0),\n    output:");
        let err = parse(&text).unwrap_err().to_string();
        assert!(err.starts_with("p.ron:15:14: "), "{err}");
        assert!(err.contains("`export.simplify_mm` is -1"), "{err}");
        assert!(err.contains("expected a distance in millimetres"), "{err}");
    }
}
