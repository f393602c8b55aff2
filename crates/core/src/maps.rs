//! Stage 1's output: the painted layers merged into one grid per meaning.

use crate::config::LayerKind;
use crate::error::{Error, Result};
use crate::files::{Header, SideFile};
use crate::grid::Grid;
use crate::hash::Hash;
use glam::Vec2;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The merged maps, in image order (row 0 north). Densities are relative (painted gray levels
/// weighted by layer weight x alpha and summed); stage 2 scales them to characters per m2.
#[derive(Debug, Clone, PartialEq)]
pub struct MergedMaps {
    pub meters_per_pixel: f64,
    /// Relative walker density, 0 under obstacles.
    pub walkers: Grid<f32>,
    /// Relative stander density, 0 under obstacles.
    pub standers: Grid<f32>,
    /// Sum of weight x unit walking direction, in the world frame (x east, y north).
    pub flow: Grid<Vec2>,
    /// Sum of the direction weights (layer weight x alpha) that painted a direction here.
    pub flow_weight: Grid<f32>,
    /// Pixels blocked by an obstacle layer.
    pub blocked: Grid<bool>,
}

const MAGIC: &[u8; 8] = b"CRWDMAPS";

impl MergedMaps {
    /// Maps of `width x height` pixels on which nothing is painted yet.
    pub fn empty(width: u32, height: u32, meters_per_pixel: f64) -> MergedMaps {
        MergedMaps {
            meters_per_pixel,
            walkers: Grid::filled(width, height, 0.0),
            standers: Grid::filled(width, height, 0.0),
            flow: Grid::filled(width, height, Vec2::ZERO),
            flow_weight: Grid::filled(width, height, 0.0),
            blocked: Grid::filled(width, height, false),
        }
    }

    pub fn width(&self) -> u32 {
        self.walkers.width()
    }

    pub fn height(&self) -> u32 {
        self.walkers.height()
    }

    /// The binary side file: magic, width, height (u32 LE), then the grids as little-endian
    /// f32 arrays (walkers, standers, flow x, flow y, flow weight) and one byte per blocked flag.
    pub fn to_bytes(&self) -> Vec<u8> {
        let n = self.walkers.as_slice().len();
        let mut out = Vec::with_capacity(16 + n * 21);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&self.width().to_le_bytes());
        out.extend_from_slice(&self.height().to_le_bytes());
        let f32s = |out: &mut Vec<u8>, values: &mut dyn Iterator<Item = f32>| {
            for v in values {
                out.extend_from_slice(&v.to_le_bytes());
            }
        };
        f32s(&mut out, &mut self.walkers.as_slice().iter().copied());
        f32s(&mut out, &mut self.standers.as_slice().iter().copied());
        f32s(&mut out, &mut self.flow.as_slice().iter().map(|v| v.x));
        f32s(&mut out, &mut self.flow.as_slice().iter().map(|v| v.y));
        f32s(&mut out, &mut self.flow_weight.as_slice().iter().copied());
        out.extend(self.blocked.as_slice().iter().map(|&b| b as u8));
        out
    }

    /// Decodes the side file; `path` names it in errors.
    pub fn from_bytes(path: &Path, meters_per_pixel: f64, bytes: &[u8]) -> Result<MergedMaps> {
        let bad =
            |what: &str| Error::stage_file(path, format!("is not a merged-maps file: {what}"));
        if bytes.len() < 16 || &bytes[..8] != MAGIC {
            return Err(bad("wrong magic"));
        }
        let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
        let (width, height) = (word(8), word(12));
        let n = width as usize * height as usize;
        if bytes.len() != 16 + n * 21 {
            return Err(bad(&format!(
                "{} bytes for {width} x {height} pixels, expected {}",
                bytes.len(),
                16 + n * 21
            )));
        }
        let f32s = |k: usize| -> Vec<f32> {
            bytes[16 + k * n * 4..16 + (k + 1) * n * 4]
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
                .collect()
        };
        fn grid<T>(width: u32, height: u32, data: Vec<T>) -> Grid<T> {
            Grid::from_vec(width, height, data).expect("sizes checked above")
        }
        let (fx, fy) = (f32s(2), f32s(3));
        let flow = fx
            .into_iter()
            .zip(fy)
            .map(|(x, y)| Vec2::new(x, y))
            .collect();
        let blocked = bytes[16 + 5 * n * 4..].iter().map(|&b| b != 0).collect();
        Ok(MergedMaps {
            meters_per_pixel,
            walkers: grid(width, height, f32s(0)),
            standers: grid(width, height, f32s(1)),
            flow: grid(width, height, flow),
            flow_weight: grid(width, height, f32s(4)),
            blocked: grid(width, height, blocked),
        })
    }
}

/// One painted layer as the merge stage read it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LayerRecord {
    pub kind: LayerKind,
    pub path: String,
    pub weight: f64,
    /// `"gray 8-bit"`, `"gray+alpha 16-bit"`, `"rgba 8-bit"`, ...
    pub format: String,
    pub hash: Hash,
}

/// Figures of the merged maps, for people and reports.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MapsSummary {
    /// Pixels with a walker density above zero.
    pub walker_pixels: u64,
    pub stander_pixels: u64,
    /// Pixels where some layer paints a walking direction.
    pub directed_pixels: u64,
    pub blocked_pixels: u64,
}

/// `merge.ron`: the RON half of stage 1's output.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MergeFile {
    pub header: Header,
    pub width: u32,
    pub height: u32,
    pub meters_per_pixel: f64,
    pub layers: Vec<LayerRecord>,
    pub summary: MapsSummary,
    pub grids: SideFile,
}

impl MergeFile {
    pub const STAGE: &'static str = "merge";
    pub const VERSION: u32 = 1;

    /// Reads `merge.ron` and its checked side file.
    pub fn load(path: &Path) -> Result<(MergeFile, MergedMaps)> {
        let file: MergeFile = crate::files::read_ron(path)?;
        crate::files::expect_stage(path, &file.header, Self::STAGE, Self::VERSION)?;
        let bytes = file.grids.read(path)?;
        let maps = MergedMaps::from_bytes(
            &path.with_file_name(&file.grids.file),
            file.meters_per_pixel,
            &bytes,
        )?;
        Ok((file, maps))
    }
}
