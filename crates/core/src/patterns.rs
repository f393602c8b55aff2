//! Stage 3's output: where and when people cross every border (the patches' patterns).
//!
//! A crossing is stored once, on its border: the exit of one patch *is* the entry of its
//! neighbour, so mirror patterns cannot disagree. Parity (as many entries as exits in every
//! patch) is checked by [`Patterns::parity`].

use crate::error::{Error, Result};
use crate::files::{Header, SideFile};
use crate::patch_graph::{Border, BorderAxis, PatchGraph, PatchId};
use glam::DVec2;
use serde::{Deserialize, Serialize};

/// Which way a character crosses a border.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Way {
    /// From patch `a` (west or south) to patch `b` (east or north).
    AToB,
    BToA,
}

/// A character crossing a border: an exit of one patch and the entry of the other.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Crossing {
    /// Index of the border in [`PatchGraph::borders`].
    pub border: u32,
    pub way: Way,
    /// Metres along the border from its south or west end, inside an open interval.
    pub s: f64,
    /// Time of the crossing in [0, period).
    pub t: f64,
    /// World-frame velocity at the crossing; its component across the border points `way`.
    pub velocity: DVec2,
}

/// Side of a square patch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Side {
    West,
    East,
    South,
    North,
}

impl Side {
    /// Ramirez et al.'s matching penalty: 0 for opposite sides, 2 for neighbouring ones, 4 for
    /// the same side.
    pub fn penalty(self, other: Side) -> f64 {
        use Side::*;
        match (self, other) {
            (a, b) if a == b => 4.0,
            (West, East) | (East, West) | (South, North) | (North, South) => 0.0,
            _ => 2.0,
        }
    }

    /// Unit normal pointing into the patch from this side.
    pub fn inward(self) -> DVec2 {
        match self {
            Side::West => DVec2::X,
            Side::East => DVec2::NEG_X,
            Side::South => DVec2::Y,
            Side::North => DVec2::NEG_Y,
        }
    }
}

/// Where a border point lies in one of its two patches.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BorderPoint {
    pub patch: PatchId,
    pub side: Side,
    /// Patch-local metres.
    pub pos: DVec2,
}

/// The two patches of a border, seen from each: `(a's view, b's view)` of the point `s`.
pub fn border_point(border: &Border, side_m: f64, s: f64) -> (BorderPoint, BorderPoint) {
    match border.axis {
        BorderAxis::Vertical => (
            BorderPoint {
                patch: border.a,
                side: Side::East,
                pos: DVec2::new(side_m, s),
            },
            BorderPoint {
                patch: border.b,
                side: Side::West,
                pos: DVec2::new(0.0, s),
            },
        ),
        BorderAxis::Horizontal => (
            BorderPoint {
                patch: border.a,
                side: Side::North,
                pos: DVec2::new(s, side_m),
            },
            BorderPoint {
                patch: border.b,
                side: Side::South,
                pos: DVec2::new(s, 0.0),
            },
        ),
    }
}

impl Crossing {
    /// The patch the character leaves (exit point) and the one it enters (entry point).
    pub fn ends(&self, graph: &PatchGraph) -> (BorderPoint, BorderPoint) {
        let border = &graph.borders[self.border as usize];
        let (a, b) = border_point(border, graph.world.patch_side_m, self.s);
        match self.way {
            Way::AToB => (a, b),
            Way::BToA => (b, a),
        }
    }
}

/// Density and direction of a patch as measured from its matched straight lines.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Measured {
    /// Characters per m2: standers / A + walker time inside / (A x period).
    pub density: f64,
    /// Time-weighted mean walking direction (unit), if anyone walks.
    pub direction: Option<DVec2>,
    /// Standing characters placed in the patch.
    pub standers: u32,
}

/// The figures of Crowd Art eq. 4-6 for a whole scene.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SceneError {
    pub e_rho: f64,
    pub e_d: f64,
    pub e: f64,
}

/// Density of a patch against its number of entry points, measured on random patches of the
/// scene's size and period (Crowd Art Figure 4): density = slope x entries + intercept.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Regression {
    pub slope: f64,
    pub intercept: f64,
    /// Coefficient of determination of the fit.
    pub r2: f64,
    pub samples: u32,
}

/// A patch's remaining error.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PatchError {
    pub patch: PatchId,
    pub cell: crate::patch_graph::Cell,
    /// Requested and measured density, characters per m2.
    pub requested: f64,
    pub measured: f64,
    /// 1 - requested . measured direction, where a direction is requested.
    pub direction_error: Option<f64>,
}

/// The figures of one optimisation step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct IterationFigures {
    pub iteration: u32,
    pub e_rho: f64,
    pub e_d: f64,
    pub e: f64,
    pub crossings: u64,
}

/// `patterns.ron`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Patterns {
    pub header: Header,
    pub period_s: f64,
    pub rho_max: f64,
    pub seed: u64,
    /// Optimisation steps run, and whether the error settled before the cap.
    pub iterations: u32,
    pub converged: bool,
    /// The figures of the result (the best step).
    pub error: SceneError,
    /// Where the error stays: the patches with the largest signed error, worst first.
    pub worst: Vec<PatchError>,
    pub regression: Regression,
    /// Figures of every step, step 0 being the start.
    pub log: Vec<IterationFigures>,
    /// Per patch, in [`PatchGraph::patches`] order.
    pub measured: Vec<Measured>,
    /// The crossings (sorted by border, then time) in a binary side file.
    pub crossings: SideFile,
}

impl Patterns {
    pub const STAGE: &'static str = "optimize";
    pub const VERSION: u32 = 10;

    /// Reads `patterns.ron` and its crossings.
    pub fn load(path: &std::path::Path) -> Result<(Patterns, Vec<Crossing>)> {
        let p: Patterns = crate::files::read_ron(path)?;
        crate::files::expect_stage(path, &p.header, Self::STAGE, Self::VERSION)?;
        let bytes = p.crossings.read(path)?;
        let crossings = decode_crossings(&path.with_file_name(&p.crossings.file), &bytes)?;
        Ok((p, crossings))
    }

    /// Reads `patterns.ron` and refuses it unless it fits `graph` ([`check_crossings`]).
    pub fn load_for(
        path: &std::path::Path,
        graph: &PatchGraph,
    ) -> Result<(Patterns, Vec<Crossing>)> {
        let (p, crossings) = Self::load(path)?;
        check_crossings(path, graph, &p, &crossings)?;
        Ok((p, crossings))
    }
}

/// Refuses crossings that do not fit `graph` (patterns built from another graph, or damaged):
/// one measure per patch, every border they name must exist and be open, and their times
/// within the period.
pub fn check_crossings(
    path: &std::path::Path,
    graph: &PatchGraph,
    patterns: &Patterns,
    crossings: &[Crossing],
) -> Result<()> {
    let period_s = patterns.period_s;
    if patterns.measured.len() != graph.patches.len() {
        return Err(Error::stage_file(
            path,
            format!(
                "measures {} patches but the graph beside it has {}; build the patterns again",
                patterns.measured.len(),
                graph.patches.len()
            ),
        ));
    }
    for (k, c) in crossings.iter().enumerate() {
        let fits = graph
            .borders
            .get(c.border as usize)
            .is_some_and(|b| !b.open.is_empty())
            && c.s.is_finite()
            && (0.0..=graph.world.patch_side_m).contains(&c.s)
            && (0.0..period_s).contains(&c.t);
        if !fits {
            return Err(Error::stage_file(
                path,
                format!(
                    "crossing {k} does not fit the graph beside it (border {}, s {}, t {}); build the patterns again",
                    c.border, c.s, c.t
                ),
            ));
        }
    }
    Ok(())
}

/// Entries minus exits of every patch; all zero when parity holds.
pub fn parity(graph: &PatchGraph, crossings: &[Crossing]) -> Vec<i64> {
    let mut balance = vec![0i64; graph.patches.len()];
    for c in crossings {
        let (from, to) = c.ends(graph);
        balance[from.patch.0 as usize] -= 1;
        balance[to.patch.0 as usize] += 1;
    }
    balance
}

const MAGIC: &[u8; 8] = b"CRWDXING";
const RECORD: usize = 4 + 1 + 4 * 8;

/// The crossings side file: magic, count (u32 LE), then per crossing border (u32), way (u8: 0
/// a to b, 1 b to a), s, t, velocity x, velocity y (f64), all little-endian.
pub fn encode_crossings(crossings: &[Crossing]) -> Vec<u8> {
    let mut out = Vec::with_capacity(12 + crossings.len() * RECORD);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&(crossings.len() as u32).to_le_bytes());
    for c in crossings {
        out.extend_from_slice(&c.border.to_le_bytes());
        out.push(match c.way {
            Way::AToB => 0,
            Way::BToA => 1,
        });
        for v in [c.s, c.t, c.velocity.x, c.velocity.y] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out
}

pub fn decode_crossings(path: &std::path::Path, bytes: &[u8]) -> Result<Vec<Crossing>> {
    let bad = |what: String| Error::stage_file(path, format!("is not a crossings file: {what}"));
    if bytes.len() < 12 || &bytes[..8] != MAGIC {
        return Err(bad("wrong magic".into()));
    }
    let n = u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize;
    if bytes.len() != 12 + n * RECORD {
        return Err(bad(format!("{} bytes for {n} crossings", bytes.len())));
    }
    // At its size (the count was checked against the bytes above): collected from results,
    // the list grew by doubling, 0.17 GB for the million's 0.1 GB of crossings.
    let mut crossings = Vec::with_capacity(n);
    for r in bytes[12..].chunks_exact(RECORD) {
        let f = |k: usize| f64::from_le_bytes(r[5 + 8 * k..13 + 8 * k].try_into().unwrap());
        let way = match r[4] {
            0 => Way::AToB,
            1 => Way::BToA,
            w => return Err(bad(format!("way {w}"))),
        };
        crossings.push(Crossing {
            border: u32::from_le_bytes(r[..4].try_into().unwrap()),
            way,
            s: f(0),
            t: f(1),
            velocity: DVec2::new(f(2), f(3)),
        });
    }
    Ok(crossings)
}
