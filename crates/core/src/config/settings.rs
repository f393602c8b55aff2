//! The settings of each stage (`merge: (...)`, `graph: (...)` and so on in `pipeline.ron`):
//! every field may be left out for its default, and each struct's `validate` refuses the values
//! its stage cannot use (NaN, a negative or zero where it means nothing, a minimum above its
//! maximum) before any stage runs.

use super::checks::{Check, count_up_to, invalid, not_negative, positive, require, share};
use serde::{Deserialize, Serialize};

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

impl MergeSettings {
    pub fn validate(&self) -> Check {
        share(
            "merge.obstacle_threshold",
            self.obstacle_threshold,
            "a value in (0, 1]",
        )
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

impl GraphSettings {
    pub fn validate(&self) -> Check {
        not_negative("graph.empty_below", self.empty_below, "0 or more")?;
        share(
            "graph.blocked_above",
            self.blocked_above,
            "a share of the patch in (0, 1]",
        )?;
        not_negative(
            "graph.direction_min_weight",
            self.direction_min_weight,
            "0 or more",
        )?;
        if let Some(w) = self.min_opening_m {
            positive("graph.min_opening_m", w, "a positive width in metres")?;
        }
        Ok(())
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
    /// Side, in patches, of the square regions optimised apart (none: the world is one
    /// region). The crossings on a border between two regions are placed once and held, so a
    /// change re-optimises only the regions it touches and stage 3 holds one region at a time;
    /// but a flow across a seam gets walkers against it there (ARCHITECTURE.md, "Stage 3 by
    /// region").
    pub region_patches: Option<u32>,
}

impl Default for OptimizeSettings {
    fn default() -> Self {
        OptimizeSettings {
            rho_max: 0.35,
            max_iterations: 400,
            tolerance: 5e-4,
            patience: 30,
            region_patches: None,
        }
    }
}

impl OptimizeSettings {
    pub fn validate(&self) -> Check {
        positive(
            "optimize.rho_max",
            self.rho_max,
            "a positive density in characters per m2",
        )?;
        count_up_to(
            "optimize.max_iterations",
            self.max_iterations,
            Self::MOST_ITERATIONS,
            "from 1 to 10000 optimisation steps (each measures the whole scene: `painting` \
             takes about 0.2 s a step)",
        )?;
        not_negative(
            "optimize.tolerance",
            self.tolerance,
            "a gain in E of 0 or more (the loop stops when E gains less in `patience` steps)",
        )?;
        count_up_to(
            "optimize.patience",
            self.patience,
            Self::MOST_ITERATIONS,
            "from 1 to 10000 steps to wait for E to gain `tolerance`",
        )?;
        match self.region_patches {
            // A region of one patch has every border held: nothing left to optimise.
            Some(side) => require(
                (2..=Self::MOST_REGION_PATCHES).contains(&side),
                "optimize.region_patches",
                side,
                "a region side from 2 to 4096 patches (one patch would hold all its borders), \
                 or None for one region",
            ),
            None => Ok(()),
        }
    }

    /// The largest region side `region_patches` may ask for.
    pub const MOST_REGION_PATCHES: u32 = 4096;

    /// The most steps `max_iterations` and `patience` may ask for.
    pub const MOST_ITERATIONS: u32 = 10_000;
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

impl MatchSettings {
    pub fn validate(&self) -> Check {
        for (field, value) in [
            ("match.min_speed", self.min_speed),
            ("match.comfort_speed", self.comfort_speed),
            ("match.max_speed", self.max_speed),
        ] {
            positive(field, value, "a positive speed in m/s")?;
        }
        if !(self.min_speed < self.comfort_speed && self.comfort_speed < self.max_speed) {
            return Err(invalid(
                "match.comfort_speed",
                format!(
                    "is {} m/s with `min_speed` {} and `max_speed` {}; expected \
                     0 < min_speed < comfort_speed < max_speed",
                    self.comfort_speed, self.min_speed, self.max_speed
                ),
            ));
        }
        not_negative(
            "match.direction_gain",
            self.direction_gain,
            "a weight of 0 or more (0: the requested direction does not count)",
        )?;
        require(
            self.turn_depth > 0.0 && self.turn_depth < 0.5,
            "match.turn_depth",
            self.turn_depth,
            "a share of the patch side in (0, 0.5)",
        )
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

impl CollideSettings {
    pub fn validate(&self) -> Check {
        count_up_to(
            "collide.max_iterations",
            self.max_iterations,
            Self::MOST_PUSHES,
            "from 1 to 1000000 pushes per patch (a patch that stalls spends about this many \
             in each way stage 5 tries to clear it, so the worst build time grows with it: \
             `bands` takes 4 s at 2000000, 17 s at 20000000)",
        )
    }

    /// The most pushes per patch `max_iterations` may allow.
    pub const MOST_PUSHES: u32 = 1_000_000;
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

impl SmoothSettings {
    pub fn validate(&self) -> Check {
        for (field, value) in [
            ("smooth.tack_spacing_s", self.tack_spacing_s),
            ("smooth.tolerance_m", self.tolerance_m),
            (
                "smooth.max_displacement_m",
                self.max_displacement_m.unwrap_or(1.0),
            ),
        ] {
            positive(field, value, "a positive number")?;
        }
        Ok(())
    }
}

/// Stage 8's settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExportSettings {
    /// The part of the world `world.glb` holds, `(x0, y0, x1, y1)` in world metres: the
    /// characters while they are there, hidden (scale 0) while outside (DCC tools slow down
    /// with tens of thousands of animated nodes). None: the whole world. The library always
    /// holds the whole world.
    #[serde(default)]
    pub gltf_region: Option<(f64, f64, f64, f64)>,
    /// Keyframes are dropped where the walk between the kept ones stays within this many
    /// millimetres of stage 6's: about half of them at 0.75, which halves the library and the
    /// runtime's steps onto new pieces. 0 keeps every keyframe.
    #[serde(default = "default_simplify_mm")]
    pub simplify_mm: f64,
    /// How fast a character turns to face the way it walks, degrees a second (a person's
    /// brisk turn: 360). Players show headings that never turn faster, and a standing
    /// character turns once, just before it walks off.
    #[serde(default = "default_turn_rate_deg_s")]
    pub turn_rate_deg_s: f64,
}

fn default_simplify_mm() -> f64 {
    0.75
}

fn default_turn_rate_deg_s() -> f64 {
    360.0
}

impl Default for ExportSettings {
    fn default() -> ExportSettings {
        ExportSettings {
            gltf_region: None,
            simplify_mm: default_simplify_mm(),
            turn_rate_deg_s: default_turn_rate_deg_s(),
        }
    }
}

impl ExportSettings {
    pub fn validate(&self) -> Check {
        if let Some((x0, y0, x1, y1)) = self.gltf_region {
            // An empty or NaN region would write a `world.glb` without a single walker.
            let finite = [x0, y0, x1, y1].iter().all(|v| v.is_finite());
            require(
                finite && x0 < x1 && y0 < y1,
                "export.gltf_region",
                format!("({x0}, {y0}, {x1}, {y1})"),
                "(x0, y0, x1, y1) in world metres with x0 < x1 and y0 < y1",
            )?;
        }
        require(
            self.simplify_mm.is_finite() && (0.0..=10.0).contains(&self.simplify_mm),
            "export.simplify_mm",
            self.simplify_mm,
            "a distance in millimetres from 0 (every keyframe) to 10",
        )?;
        require(
            (30.0..=3600.0).contains(&self.turn_rate_deg_s),
            "export.turn_rate_deg_s",
            self.turn_rate_deg_s,
            "a turning speed in degrees a second from 30 to 3600 (a person: about 360)",
        )
    }

    /// [`Self::turn_rate_deg_s`] in radians a second.
    pub fn turn_rate_rad_s(&self) -> f64 {
        self.turn_rate_deg_s.to_radians()
    }
}
