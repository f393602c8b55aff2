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

/// Stage 3's crossings as a build holds them: the world's whole list, or a shard's window of
/// it ([`HeldCrossings::window`]). Either way a crossing keeps its number in the world's list,
/// the number trajectories name their entry and exit by, so the stages after stage 3 read both
/// alike; a shard holds only the crossings its patches and their surroundings reach (the
/// million's world list is 0.1 GB, in every shard).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct HeldCrossings {
    first: u32,
    list: Vec<Crossing>,
    borders: (u32, u32),
}

impl HeldCrossings {
    /// The world's whole list (sorted by border, then time).
    pub fn whole(list: Vec<Crossing>) -> HeldCrossings {
        HeldCrossings {
            first: 0,
            list,
            borders: (0, u32::MAX),
        }
    }

    /// Only the crossings of borders `borders` (the world's list is sorted by border, so they
    /// are one run of it), numbered as in the world's list.
    pub fn window(self, borders: std::ops::Range<u32>) -> HeldCrossings {
        let list = self.list;
        let lo = list.partition_point(|c| c.border < borders.start);
        let hi = list.partition_point(|c| c.border < borders.end);
        HeldCrossings::of_borders(self.first + lo as u32, list[lo..hi].to_vec(), borders)
    }

    /// The crossings of borders `borders`, all of them in the world's order (`list`), the
    /// first of them being the world's crossing `first` (the count of the world's crossings on
    /// borders before them).
    pub fn of_borders(
        first: u32,
        list: Vec<Crossing>,
        borders: std::ops::Range<u32>,
    ) -> HeldCrossings {
        HeldCrossings {
            first,
            list,
            borders: (borders.start, borders.end),
        }
    }

    pub fn view(&self) -> Crossings<'_> {
        Crossings {
            first: self.first,
            list: &self.list,
            borders: self.borders,
        }
    }

    /// The world's whole list; asked of a shard's window, a bug, which panics.
    pub fn world(&self) -> &[Crossing] {
        self.expect_whole();
        &self.list
    }

    /// [`HeldCrossings::world`], taken.
    pub fn into_world(self) -> Vec<Crossing> {
        self.expect_whole();
        self.list
    }

    fn expect_whole(&self) {
        assert!(
            self.first == 0 && self.borders == (0, u32::MAX),
            "the world's crossings asked of a shard's window"
        );
    }
}

/// A view of [`HeldCrossings`], indexed by the world's numbers: `crossings[k]` is the world's
/// crossing `k`, and asking for one the window does not hold is a bug, which panics.
#[derive(Debug, Clone, Copy)]
pub struct Crossings<'a> {
    first: u32,
    list: &'a [Crossing],
    borders: (u32, u32),
}

impl<'a> From<&'a [Crossing]> for Crossings<'a> {
    /// The world's whole list.
    fn from(list: &'a [Crossing]) -> Crossings<'a> {
        Crossings {
            first: 0,
            list,
            borders: (0, u32::MAX),
        }
    }
}

impl<'a> From<&'a Vec<Crossing>> for Crossings<'a> {
    fn from(list: &'a Vec<Crossing>) -> Crossings<'a> {
        Crossings::from(&list[..])
    }
}

impl<'a> From<&'a HeldCrossings> for Crossings<'a> {
    fn from(held: &'a HeldCrossings) -> Crossings<'a> {
        held.view()
    }
}

impl<'a> Crossings<'a> {
    /// Every crossing held, with its number in the world's list.
    pub fn indexed(self) -> impl Iterator<Item = (u32, &'a Crossing)> + 'a {
        (self.first..).zip(self.list)
    }

    /// The world's numbers held: `first..end`.
    pub fn numbers(self) -> std::ops::Range<u32> {
        self.first..self.first + self.list.len() as u32
    }

    /// The world's crossing `k`, if held.
    pub fn get(self, k: u32) -> Option<&'a Crossing> {
        self.list.get(k.checked_sub(self.first)? as usize)
    }

    /// Whether every crossing of border `b` is held.
    pub fn holds_border(self, b: u32) -> bool {
        (self.borders.0..self.borders.1).contains(&b)
    }

    fn offset(self, k: usize) -> usize {
        let held = self.numbers();
        assert!(
            (held.start as usize..=held.end as usize).contains(&k),
            "crossing {k} is not held (this build holds {held:?} of the world's)"
        );
        k - held.start as usize
    }
}

impl std::ops::Index<usize> for Crossings<'_> {
    type Output = Crossing;
    fn index(&self, k: usize) -> &Crossing {
        &self.list[self.offset(k)]
    }
}

impl<'a> Crossings<'a> {
    /// The world's crossings `range` (as a slice of the world's list would be).
    pub fn run(self, range: std::ops::Range<usize>) -> &'a [Crossing] {
        let start = self.offset(range.start);
        &self.list[start..start + range.len()]
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
    let mut out = Vec::with_capacity(crossings_file_bytes(crossings.len()));
    write_crossings(&mut out, crossings).expect("writing to memory");
    out
}

/// The size of [`encode_crossings`]'s bytes for `n` crossings.
pub fn crossings_file_bytes(n: usize) -> usize {
    12 + n * RECORD
}

/// [`encode_crossings`]'s bytes written to `out` as they are made, for a list too large to
/// hold twice (the million's 85 MB `patterns.bin` beside its 98 MB of crossings).
pub fn write_crossings<W: std::io::Write + ?Sized>(
    out: &mut W,
    crossings: &[Crossing],
) -> std::io::Result<()> {
    write_crossings_header(out, crossings.len())?;
    crossings.iter().try_for_each(|c| write_crossing(out, c))
}

/// The start of [`encode_crossings`]'s bytes for `count` crossings, each then written by
/// [`write_crossing`]: for crossings visited in order, never listed.
pub fn write_crossings_header<W: std::io::Write + ?Sized>(
    out: &mut W,
    count: usize,
) -> std::io::Result<()> {
    out.write_all(MAGIC)?;
    out.write_all(&(count as u32).to_le_bytes())
}

/// One crossing's record of [`encode_crossings`]'s bytes.
pub fn write_crossing<W: std::io::Write + ?Sized>(
    out: &mut W,
    c: &Crossing,
) -> std::io::Result<()> {
    let mut record = [0u8; RECORD];
    record[..4].copy_from_slice(&c.border.to_le_bytes());
    record[4] = match c.way {
        Way::AToB => 0,
        Way::BToA => 1,
    };
    for (k, v) in [c.s, c.t, c.velocity.x, c.velocity.y]
        .into_iter()
        .enumerate()
    {
        record[5 + 8 * k..13 + 8 * k].copy_from_slice(&v.to_le_bytes());
    }
    out.write_all(&record)
}

pub fn decode_crossings(path: &std::path::Path, bytes: &[u8]) -> Result<Vec<Crossing>> {
    let bad = |what: String| Error::stage_file(path, format!("is not a crossings file: {what}"));
    if bytes.len() < 12 || &bytes[..8] != MAGIC {
        return Err(bad("wrong magic".into()));
    }
    let n = u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize;
    if bytes.len() != crossings_file_bytes(n) {
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
