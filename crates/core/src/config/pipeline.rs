//! The pipeline file: `Pipeline` (the top level of `pipeline.ron`: scene, counts, sizes, and
//! each stage's settings) and `PipelineFile`, which reads, parses and checks it and resolves
//! its paths. `Pipeline::validate` checks the top level and calls each stage's `validate`.

use super::checks::{Check, Num, invalid, not_negative, positive, require};
use super::edits::{Edit, EditLimits, validate_edits};
use super::ron_text::{describe_ron_error, locate_field};
use super::settings::{
    CollideSettings, ExportSettings, GraphSettings, MatchSettings, MergeSettings, OptimizeSettings,
    SmoothSettings,
};
use crate::error::{Error, LineCol, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The build description. Paths are relative to the folder of the pipeline file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pipeline {
    /// The painted layers and their scale.
    pub scene: Scene,
    /// Walking (exogenous) characters in the whole scene, shared out by the `Density` layer
    /// (with `people: Counted`, the default).
    #[serde(default)]
    pub walkers: u64,
    /// Standing (endogenous, static) characters in the whole scene, shared out by the
    /// `Static` layer (with `people: Counted`).
    #[serde(default)]
    pub standers: u64,
    /// How the painted layers become people: totals shared out over the painting, or a
    /// density per painted pixel, which keeps a brush stroke's change where it was painted.
    #[serde(default, skip_serializing_if = "People::is_counted")]
    pub people: People,
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
    /// The moments stage 7 edits in (none: stage 7 does not run, and export reads stage 6).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub edits: Vec<Edit>,
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

/// How the `Density` and `Static` layers become people per m2 (under `optimize.rho_max`).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum People {
    /// `walkers` and `standers` are totals, shared out in proportion to the paint: a brighter
    /// stroke anywhere thins the crowd everywhere else.
    #[default]
    Counted,
    /// The paint is a density: a pixel painted full asks this many walkers and standers per m2,
    /// a half-painted one half as many. A stroke changes only the patches under it.
    PerSquareMetre { walkers: f64, standers: f64 },
}

impl People {
    pub fn is_counted(&self) -> bool {
        *self == People::Counted
    }
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

impl Pipeline {
    /// How far export may move a walker from where stage 6 put it, m: the keyframes it drops
    /// (`export.simplify_mm`), positions rounded to 1/65535 of the patch side, times to half
    /// a 0.1 ms tick at up to 5 m/s. Stages 5 and 6 keep everyone this much farther from
    /// everyone and everything than their radius, so that what ships has no collision (before,
    /// 3-348 pairs per scene came up to 1.1 mm closer than 2r in `library.crowd`). Export's
    /// test holds its stated error to it.
    pub fn shipping_error_m(&self) -> f64 {
        self.export.simplify_mm * 1e-3 + self.patch_side_m * 0.5 / 65535.0 + 5.0 * 0.5e-4
    }

    /// Refuses any value a stage cannot use, naming the field; the settings and painted data
    /// are checked against each other later, by the stages.
    pub fn validate(&self) -> Check {
        self.scene.validate()?;
        for (field, value, unit) in [
            ("patch_side_m", self.patch_side_m, "metres"),
            ("period_s", self.period_s, "seconds"),
            ("radius_m", self.radius_m, "metres"),
        ] {
            positive(field, value, &format!("a positive number of {unit}"))?;
        }
        if 2.0 * self.radius_m >= self.patch_side_m {
            return Err(invalid(
                "radius_m",
                format!(
                    "is {} m; expected less than half the patch side ({} m)",
                    Num(self.radius_m),
                    Num(self.patch_side_m)
                ),
            ));
        }
        let pixels = self.patch_side_m / self.scene.meters_per_pixel;
        if (pixels - pixels.round()).abs() > 1e-6 || pixels.round() < 1.0 {
            return Err(invalid(
                "patch_side_m",
                format!(
                    "is {} m, which is {pixels} pixels at {} m per pixel; expected a whole \
                     number of pixels so that patches follow the painted pixels",
                    Num(self.patch_side_m),
                    Num(self.scene.meters_per_pixel)
                ),
            ));
        }
        let has = |kind: LayerKind| self.scene.layers.iter().any(|l| l.kind == kind);
        if let People::PerSquareMetre { walkers, standers } = self.people {
            for (field, count) in [("walkers", self.walkers), ("standers", self.standers)] {
                if count > 0 {
                    return Err(invalid(
                        field,
                        format!(
                            "is {count}, but `people: PerSquareMetre(..)` takes the numbers \
                             from the painting; leave `{field}` out"
                        ),
                    ));
                }
            }
            let per_m2 = "people per m2 where a pixel is painted full, from 0 to 10";
            for (field, value) in [("people.walkers", walkers), ("people.standers", standers)] {
                require((0.0..=10.0).contains(&value), field, Num(value), per_m2)?;
            }
            if walkers <= 0.0 && standers <= 0.0 {
                return Err(invalid(
                    "people",
                    "asks for no walker and no stander (both densities are 0): expected a \
                     density of people per m2 above 0 for at least one"
                        .to_string(),
                ));
            }
            if walkers > 0.0 && !has(LayerKind::Density) {
                return Err(invalid(
                    "people.walkers",
                    "asks for walkers but the scene has no `Density` layer saying where they \
                     walk"
                        .to_string(),
                ));
            }
            if standers > 0.0 && !has(LayerKind::Static) {
                return Err(invalid(
                    "people.standers",
                    "asks for standers but the scene has no `Static` layer saying where they \
                     stand"
                        .to_string(),
                ));
            }
        }
        if self.walkers > 0 && !has(LayerKind::Density) {
            return Err(invalid(
                "walkers",
                format!(
                    "is {} but the scene has no `Density` layer saying where they walk",
                    self.walkers
                ),
            ));
        }
        if self.standers > 0 && !has(LayerKind::Static) {
            return Err(invalid(
                "standers",
                format!(
                    "is {} but the scene has no `Static` layer saying where they stand",
                    self.standers
                ),
            ));
        }
        self.merge.validate()?;
        self.graph.validate()?;
        self.optimize.validate()?;
        self.matching.validate()?;
        self.collide.validate()?;
        self.smooth.validate()?;
        self.export.validate()?;
        self.validate_sizes()?;
        validate_edits(
            &self.edits,
            &EditLimits {
                period_s: self.period_s,
                rho_max: self.optimize.rho_max,
                max_speed: self.matching.max_speed,
            },
        )
    }
}

impl Pipeline {
    /// The settings that size the work, checked against each other: a patch holds walkers
    /// with room to pass, a period is a whole number of the library's ticks and no longer than
    /// [`MAX_PERIOD_S`], tacks fit in a period, an opening fits in a patch. Without these a
    /// build aborted allocating (`period_s: 1e300`, `tack_spacing_s: 1e-9`), ran for minutes
    /// (`period_s: 1e5`), panicked (`patch_side_m: 1.0`) or built nobody (`radius_m: 2.0`).
    fn validate_sizes(&self) -> Check {
        let (side, r, period) = (self.patch_side_m, self.radius_m, self.period_s);
        require(
            side >= MIN_PATCH_RADII * r && side <= MAX_PATCH_SIDE_M,
            "patch_side_m",
            Num(side),
            &format!(
                "from {} to {MAX_PATCH_SIDE_M} m: at least {MIN_PATCH_RADII} character radii \
                 (`radius_m` is {}), so that walkers cross a patch with room to pass",
                Num(MIN_PATCH_RADII * r),
                Num(r)
            ),
        )?;
        let ticks = period / TICK_S;
        require(
            (MIN_PERIOD_S..=MAX_PERIOD_S).contains(&period) && (ticks - ticks.round()).abs() < 1e-6,
            "period_s",
            Num(period),
            &format!(
                "from {MIN_PERIOD_S} to {MAX_PERIOD_S} seconds, a whole number of 0.1 ms \
                 (the library's ticks), e.g. 20.0"
            ),
        )?;
        let tack = self.smooth.tack_spacing_s;
        require(
            tack >= MIN_TACK_SPACING_S && tack <= period,
            "smooth.tack_spacing_s",
            Num(tack),
            &format!(
                "from {MIN_TACK_SPACING_S} s to the period ({} s)",
                Num(period)
            ),
        )?;
        if let Some(w) = self.graph.min_opening_m {
            require(
                w <= side,
                "graph.min_opening_m",
                Num(w),
                &format!("at most the patch side ({} m)", Num(side)),
            )?;
        }
        for (i, layer) in self.scene.layers.iter().enumerate() {
            require(
                layer.weight <= MAX_LAYER_WEIGHT,
                &format!("scene.layers[{i}].weight"),
                Num(layer.weight),
                &format!(
                    "from 0 to {} (weights are relative: 1 is the layer's paint as painted)",
                    Num(MAX_LAYER_WEIGHT)
                ),
            )?;
        }
        Ok(())
    }
}

/// The smallest patch side, in character radii: a border holds a walker crossing each way with
/// its clearance, and the border bands (a radius deep) leave room inside.
pub const MIN_PATCH_RADII: f64 = 8.0;
/// The largest patch side, m: positions are kept to 1/65535 of it (1.5 mm at 100 m).
pub const MAX_PATCH_SIDE_M: f64 = 100.0;
/// The shortest and longest period, s: every stage's work grows with it.
pub const MIN_PERIOD_S: f64 = 1.0;
pub const MAX_PERIOD_S: f64 = 600.0;
/// The library's time step, s (FORMAT.md).
const TICK_S: f64 = 1e-4;
/// The closest tacks, s (stage 6 samples a chord no shorter than this).
pub const MIN_TACK_SPACING_S: f64 = 0.05;
/// The heaviest layer weight.
pub const MAX_LAYER_WEIGHT: f64 = 1e6;

impl Scene {
    pub fn validate(&self) -> Check {
        positive(
            "scene.meters_per_pixel",
            self.meters_per_pixel,
            "a positive number of metres",
        )?;
        if self.layers.is_empty() {
            return Err(invalid(
                "scene.layers",
                "is empty; expected at least one painted layer",
            ));
        }
        for (i, layer) in self.layers.iter().enumerate() {
            not_negative(
                &format!("scene.layers[{i}].weight"),
                layer.weight,
                "a weight of 0 or more",
            )?;
        }
        Ok(())
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

    /// An error about one setting, at its line, or at its section's when it is not written
    /// (a default refused beside a setting that is: `match.comfort_speed` under `max_speed`).
    pub fn field_error(&self, field: &str, message: impl Into<String>) -> Error {
        let section = || field.rsplit_once('.').and_then(|(s, _)| self.place_of(s));
        Error::Field {
            path: self.path.clone(),
            place: self.place_of(field).or_else(section),
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

    /// Refuses an `export.gltf_region` that is not on the painted maps, `size_m` metres wide
    /// and high from the origin: a clip of a region off the map has no one in it.
    pub fn check_region(&self, (width, height): (f64, f64)) -> Result<()> {
        let Some((x0, y0, x1, y1)) = self.pipeline.export.gltf_region else {
            return Ok(());
        };
        const SLACK: f64 = 1e-6;
        let inside = |lo: f64, hi: f64, size: f64| lo >= -SLACK && hi <= size + SLACK;
        if inside(x0, x1, width) && inside(y0, y1, height) {
            return Ok(());
        }
        Err(self.field_error(
            "export.gltf_region",
            format!(
                "is ({x0}, {y0}, {x1}, {y1}), not on the painted maps; expected a rectangle \
                 inside (0, 0, {width}, {height}), the maps' size in world metres"
            ),
        ))
    }

    /// Refuses an edit whose place is not on the painted maps (`width` x `height` m).
    pub fn check_edits(&self, size: (f64, f64)) -> Result<()> {
        match super::edits::check_edits_on_map(&self.pipeline.edits, size) {
            Ok(()) => Ok(()),
            Err((k, message)) => Err(self.field_error(&format!("edits[{k}].kind"), message)),
        }
    }

    /// Refuses a setting its stage cannot use, at the line of the setting.
    fn check(&self) -> Result<()> {
        self.pipeline
            .validate()
            .map_err(|bad| self.field_error(&bad.field, bad.message))
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
