//! Stage 2's output: square crowd patches, the borders they share and where people can cross.

use crate::files::Header;
use glam::DVec2;
use serde::{Deserialize, Serialize};

/// Index of a patch in [`PatchGraph::patches`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct PatchId(pub u32);

/// Place of a patch in the world: column (east) and row (north), from the south-west corner.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Cell {
    pub col: u32,
    pub row: u32,
}

/// An axis-aligned rectangle in patch-local metres (origin at the patch's south-west corner).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Rect {
    pub min: DVec2,
    pub max: DVec2,
}

impl Rect {
    pub fn area(&self) -> f64 {
        let size = self.max - self.min;
        size.x * size.y
    }
}

/// Where the painting asks people to walk, and how strongly.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RequestedDirection {
    /// Unit vector, world frame.
    pub dir: DVec2,
    /// Mean direction weight over the patch (layer weight x alpha).
    pub weight: f64,
}

/// One crowd patch and what the painting requests of it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Patch {
    pub id: PatchId,
    pub cell: Cell,
    /// Requested walkers per m2 of patch area.
    pub walker_density: f64,
    /// Requested standing characters per m2 of patch area.
    pub stander_density: f64,
    pub direction: Option<RequestedDirection>,
    /// Share of the patch area covered by obstacles.
    pub obstacle_coverage: f64,
    /// The partial obstacles inside the patch, as static obstacles in patch-local metres.
    pub obstacles: Vec<Rect>,
    /// Connected component (patches reachable through open borders).
    pub component: u32,
}

/// Which way a border runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum BorderAxis {
    /// A north-south line: `a` is the west patch, `b` the east one; positions run northward.
    Vertical,
    /// A west-east line: `a` is the south patch, `b` the north one; positions run eastward.
    Horizontal,
}

/// A stretch of a border, in metres from the border's south or west end.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Interval {
    pub start: f64,
    pub end: f64,
}

impl Interval {
    pub fn len(&self) -> f64 {
        self.end - self.start
    }

    pub fn is_empty(&self) -> bool {
        self.end <= self.start
    }
}

/// A border shared by two kept patches, with the intervals where people can cross.
/// A border fully closed by obstacles is kept with no open interval.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Border {
    pub a: PatchId,
    pub b: PatchId,
    pub axis: BorderAxis,
    pub open: Vec<Interval>,
}

impl Border {
    /// The unit vector across the border, from patch `a` to patch `b` (east or north).
    pub fn across(&self) -> glam::DVec2 {
        match self.axis {
            BorderAxis::Vertical => glam::DVec2::X,
            BorderAxis::Horizontal => glam::DVec2::Y,
        }
    }
}

/// The world grid the patches are cut from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct World {
    pub cols: u32,
    pub rows: u32,
    pub patch_side_m: f64,
    pub meters_per_pixel: f64,
    /// Size of the painted maps, in metres.
    pub size_m: DVec2,
}

impl World {
    /// The corner opposite (0, 0) of the patches' grid, m: where the world's characters can be.
    pub fn covered_m(&self) -> DVec2 {
        DVec2::new(f64::from(self.cols), f64::from(self.rows)) * self.patch_side_m
    }
}

/// A connected component of the patch graph.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Component {
    pub id: u32,
    pub patches: u32,
    /// Requested walkers in the component (sum of density x area).
    pub walkers: f64,
    pub standers: f64,
}

/// Cells of the world grid that did not become patches.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Dropped {
    /// Nothing painted.
    pub empty: Vec<Cell>,
    /// Covered by obstacles.
    pub blocked: Vec<Cell>,
    /// Metres east and north of the last whole patch that no patch covers, when the maps are
    /// not a whole number of patches.
    pub uncovered_strip_m: DVec2,
}

/// `graph.ron`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PatchGraph {
    pub header: Header,
    pub world: World,
    pub walkers_requested: u64,
    pub standers_requested: u64,
    pub radius_m: f64,
    pub dropped: Dropped,
    pub components: Vec<Component>,
    pub patches: Vec<Patch>,
    pub borders: Vec<Border>,
}

/// The graph [`PatchGraph::load_shared`] parsed or [`PatchGraph::share`] was given last, by
/// the hash of its file's bytes.
type Shared = Option<(crate::Hash, std::sync::Arc<PatchGraph>)>;
static SHARED: std::sync::Mutex<Shared> = std::sync::Mutex::new(None);

impl PatchGraph {
    pub const STAGE: &'static str = "graph";
    pub const VERSION: u32 = 2;

    /// Area of one patch in m2.
    pub fn patch_area(&self) -> f64 {
        self.world.patch_side_m * self.world.patch_side_m
    }

    /// World position of a patch's south-west corner.
    pub fn world_from_patch(&self, cell: Cell) -> DVec2 {
        DVec2::new(cell.col as f64, cell.row as f64) * self.world.patch_side_m
    }

    pub fn patch(&self, id: PatchId) -> &Patch {
        &self.patches[id.0 as usize]
    }

    /// The index of the patch in `cell`, if it was kept. Patches run row by row from the
    /// south-west, so this is a binary search.
    pub fn patch_at(&self, cell: Cell) -> Option<usize> {
        self.patches
            .binary_search_by_key(&(cell.row, cell.col), |p| (p.cell.row, p.cell.col))
            .ok()
    }

    /// Reads and checks `graph.ron`.
    pub fn load(path: &std::path::Path) -> crate::Result<PatchGraph> {
        let text = std::fs::read_to_string(path).map_err(|e| crate::Error::io(path, "read", e))?;
        Self::parse(path, &text)
    }

    fn parse(path: &std::path::Path, text: &str) -> crate::Result<PatchGraph> {
        let graph: PatchGraph = crate::files::parse_ron(path, text)?;
        crate::files::expect_stage(path, &graph.header, Self::STAGE, Self::VERSION)?;
        graph.check(path)?;
        Ok(graph)
    }

    /// [`PatchGraph::load`], parsed once per content in a process: a build reads `graph.ron`
    /// for its stages, its check, its warnings and each report picture (3.5 MB of RON on
    /// painting, 0.15 s a time). The file is read and hashed each time, so an edit is seen.
    pub fn load_shared(path: &std::path::Path) -> crate::Result<std::sync::Arc<PatchGraph>> {
        let text = std::fs::read_to_string(path).map_err(|e| crate::Error::io(path, "read", e))?;
        let hash = crate::Hash::of(text.as_bytes());
        let held = SHARED.lock().unwrap_or_else(|e| e.into_inner()).clone();
        if let Some((h, graph)) = held
            && h == hash
        {
            return Ok(graph);
        }
        let graph = std::sync::Arc::new(Self::parse(path, &text)?);
        *SHARED.lock().unwrap_or_else(|e| e.into_inner()) = Some((hash, graph.clone()));
        Ok(graph)
    }

    /// This graph, made by the process and written as `text` (its stage file's bytes), shared
    /// as [`PatchGraph::load_shared`] would parse it from them: a build that makes its graph
    /// then checks and reports on it does not parse it again (painting's, 55 ms on the check's
    /// path after a brush stroke).
    pub fn share(self, text: &[u8]) -> std::sync::Arc<PatchGraph> {
        let graph = std::sync::Arc::new(self);
        *SHARED.lock().unwrap_or_else(|e| e.into_inner()) =
            Some((crate::Hash::of(text), graph.clone()));
        graph
    }

    /// Refuses a graph whose numbers do not hold together (an edited or damaged file), so that
    /// later stages can index it without checking again.
    fn check(&self, path: &std::path::Path) -> crate::Result<()> {
        let bad = |what: String| {
            crate::Error::stage_file(
                path,
                format!("is inconsistent: {what}; build the graph again"),
            )
        };
        let w = &self.world;
        if !(w.patch_side_m.is_finite()
            && w.patch_side_m > 0.0
            && self.radius_m.is_finite()
            && self.radius_m > 0.0)
        {
            return Err(bad("patch side and radius must be positive".into()));
        }
        for (i, p) in self.patches.iter().enumerate() {
            if p.id.0 as usize != i {
                return Err(bad(format!("patch {i} is numbered {}", p.id.0)));
            }
            if p.cell.col >= w.cols || p.cell.row >= w.rows {
                return Err(bad(format!(
                    "patch {i} lies outside the {} x {} cells",
                    w.cols, w.rows
                )));
            }
            if i > 0 {
                let before = self.patches[i - 1].cell;
                if (before.row, before.col) >= (p.cell.row, p.cell.col) {
                    return Err(bad(format!(
                        "patch {i} does not follow patch {} row by row from the south-west",
                        i - 1
                    )));
                }
            }
            if p.component as usize >= self.components.len() {
                return Err(bad(format!("patch {i} names component {}", p.component)));
            }
        }
        let n = self.patches.len() as u32;
        for (k, b) in self.borders.iter().enumerate() {
            if b.a.0 >= n || b.b.0 >= n {
                return Err(bad(format!(
                    "border {k} names a patch beyond the {n} there are"
                )));
            }
        }
        Ok(())
    }
}
