//! Stage 3's output: where and when people cross every border (the patches' patterns).
//!
//! A crossing is stored once, on its border: the exit of one patch *is* the entry of its
//! neighbour, so mirror patterns cannot disagree. Parity (as many entries as exits in every
//! patch) is checked by [`Patterns::parity`].

use crate::files::Header;
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
    pub error: SceneError,
    /// Per patch, in [`PatchGraph::patches`] order.
    pub measured: Vec<Measured>,
    /// Sorted by border, then time.
    pub crossings: Vec<Crossing>,
}

impl Patterns {
    pub const STAGE: &'static str = "optimize";
    pub const VERSION: u32 = 1;

    /// Entries minus exits of every patch; all zero when parity holds.
    pub fn parity(&self, graph: &PatchGraph) -> Vec<i64> {
        let mut balance = vec![0i64; graph.patches.len()];
        for c in &self.crossings {
            let (from, to) = c.ends(graph);
            balance[from.patch.0 as usize] -= 1;
            balance[to.patch.0 as usize] += 1;
        }
        balance
    }

    pub fn load(path: &std::path::Path) -> crate::Result<Patterns> {
        let p: Patterns = crate::files::read_ron(path)?;
        crate::files::expect_stage(path, &p.header, Self::STAGE, Self::VERSION)?;
        Ok(p)
    }
}
