//! The records of a library, decoded: what holds for the whole world, patches, standers,
//! crossings, trajectories, their points and the characters' loops, and `Library`, which holds
//! them all, with the readings the sampler and stage 8 share.

use super::{QUANT_STEPS, TICK_S};

/// What holds for the whole world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct World {
    pub patch_side_m: f32,
    /// The loop: every character's motion repeats after `period_ticks` x [`TICK_S`] seconds
    /// (or a whole number of them, for a character whose loop crosses several periods).
    pub period_ticks: u32,
    pub radius_m: f32,
    /// Patch grid size.
    pub cols: u32,
    pub rows: u32,
    pub seed: u64,
    /// The first 8 bytes of the build's input hash, to tell builds apart.
    pub input_hash: [u8; 8],
    /// How fast characters turn to face their walk, degrees a second (the `TURN` section;
    /// [`crate::turn::DEFAULT_TURN_RATE_DEG_S`] for a library without one).
    pub turn_rate_deg_s: f32,
}

/// A patch: its place in the grid (south-west corner at (col, row) x side) and its records.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Patch {
    pub col: u32,
    pub row: u32,
    pub first_trajectory: u32,
    pub trajectories: u32,
    pub first_stander: u32,
    pub standers: u32,
}

/// A patch-local position in steps of side / 65535, and for a trajectory point the ticks since
/// its trajectory's start (standers: `t` is 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Point {
    pub x: u16,
    pub y: u16,
    pub t: u32,
}

impl Point {
    /// A PNTS record's size (FORMAT.md): `x: u16, y: u16, t: u32`, little-endian.
    pub const BYTES: usize = 8;

    /// Its PNTS record.
    pub fn to_le_bytes(self) -> [u8; Point::BYTES] {
        let mut b = [0u8; Point::BYTES];
        b[0..2].copy_from_slice(&self.x.to_le_bytes());
        b[2..4].copy_from_slice(&self.y.to_le_bytes());
        b[4..8].copy_from_slice(&self.t.to_le_bytes());
        b
    }

    /// The point of a PNTS record (its first [`Point::BYTES`] bytes).
    pub fn from_le_bytes(b: &[u8]) -> Point {
        Point {
            x: u16::from_le_bytes([b[0], b[1]]),
            y: u16::from_le_bytes([b[2], b[3]]),
            t: u32::from_le_bytes([b[4], b[5], b[6], b[7]]),
        }
    }
}

/// An entry or exit point of the patterns: where (world metres), when (ticks in the period),
/// at what velocity (m/s), from which patch to which.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crossing {
    pub from_patch: u32,
    pub to_patch: u32,
    pub x: f32,
    pub y: f32,
    pub t: u32,
    pub vx: f32,
    pub vy: f32,
}

/// One walker's way through one patch, and the link to the way it continues on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Trajectory {
    pub patch: u32,
    /// Crossings it enters and leaves by.
    pub entry: u32,
    pub exit: u32,
    /// The trajectory (in the patch across `exit`) that enters by `exit`: the same character.
    pub next: u32,
    pub first_point: u32,
    pub points: u32,
    /// Ticks in [0, period) when it starts at its entry.
    pub start: u32,
}

/// A loop of linked trajectories. It lasts `laps` periods, so `laps` characters walk it at
/// once, a period apart: character ids `first_id .. first_id + laps`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Character {
    pub first_trajectory: u32,
    pub trajectories: u32,
    pub laps: u32,
}

/// A whole library, decoded and checked.
#[derive(Debug, Clone, PartialEq)]
pub struct Library {
    pub world: World,
    pub patches: Vec<Patch>,
    pub standers: Vec<Point>,
    pub crossings: Vec<Crossing>,
    pub trajectories: Vec<Trajectory>,
    pub points: Vec<Point>,
    pub characters: Vec<Character>,
}

impl Library {
    /// Seconds of one period.
    pub fn period_s(&self) -> f64 {
        f64::from(self.world.period_ticks) * TICK_S
    }

    /// How many characters walk (each loop's laps) and stand.
    pub fn walkers(&self) -> u64 {
        self.characters.iter().map(|c| u64::from(c.laps)).sum()
    }

    /// World position of a patch-local quantised point of `patch`.
    pub fn world_position(&self, patch: &Patch, p: Point) -> [f64; 2] {
        let side = f64::from(self.world.patch_side_m);
        let q = side / QUANT_STEPS;
        [
            f64::from(patch.col) * side + f64::from(p.x) * q,
            f64::from(patch.row) * side + f64::from(p.y) * q,
        ]
    }

    /// The points of a trajectory of this library.
    pub fn points_of(&self, t: &Trajectory) -> &[Point] {
        let first = t.first_point as usize;
        &self.points[first..first + t.points as usize]
    }

    /// Ticks from a trajectory's start to its end.
    pub fn duration_ticks(&self, t: &Trajectory) -> u32 {
        self.points_of(t).last().map_or(0, |p| p.t)
    }
}
