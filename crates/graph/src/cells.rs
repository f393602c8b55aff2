//! Per-patch means of the merged maps.

use crowd_core::patch_graph::{Cell, Rect, RequestedDirection};
use crowd_core::{MergedMaps, Progress};
use glam::{DVec2, Vec2};
use rayon::prelude::*;

/// How world cells map onto pixels. Rows count northward from the south edge of the maps;
/// image rows count southward from the north edge.
pub struct Layout {
    pub side_px: u32,
    pub cols: u32,
    pub rows: u32,
    height_px: u32,
    mpp: f64,
}

impl Layout {
    pub fn new(maps: &MergedMaps, side_px: u32, cols: u32, rows: u32) -> Layout {
        Layout {
            side_px,
            cols,
            rows,
            height_px: maps.height(),
            mpp: maps.meters_per_pixel,
        }
    }

    /// Image pixel of cell-local pixel (i east, k north) in `cell`.
    pub fn pixel(&self, cell: Cell, i: u32, k: u32) -> (u32, u32) {
        let x = cell.col * self.side_px + i;
        let y = self.height_px - 1 - (cell.row * self.side_px + k);
        (x, y)
    }

    pub fn meters(&self, px: u32) -> f64 {
        px as f64 * self.mpp
    }

    pub fn meters_per_pixel(&self) -> f64 {
        self.mpp
    }

    /// Whether cell-local pixel (i east, k north) of `cell` is blocked; `i` and `k` may reach
    /// into the neighbouring cells. Pixels off the maps are free (nobody walks there anyway).
    pub fn blocked(&self, maps: &MergedMaps, cell: Cell, i: i64, k: i64) -> bool {
        let s = self.side_px as i64;
        let x = cell.col as i64 * s + i;
        let north = cell.row as i64 * s + k;
        if x < 0 || north < 0 || x >= maps.width() as i64 || north >= self.height_px as i64 {
            return false;
        }
        *maps
            .blocked
            .get(x as u32, (self.height_px as i64 - 1 - north) as u32)
    }
}

/// The painted means of one cell.
pub struct CellStats {
    pub cell: Cell,
    pub mean_walkers: f64,
    pub mean_standers: f64,
    pub flow: DVec2,
    pub mean_flow_weight: f64,
    pub coverage: f64,
    pub obstacles: Vec<Rect>,
}

impl CellStats {
    /// The requested direction, where the painting asks for one strongly enough.
    pub fn direction(&self, min_weight: f64) -> Option<RequestedDirection> {
        let enough = self.mean_flow_weight >= min_weight && self.mean_flow_weight > 0.0;
        let dir = self.flow.try_normalize()?;
        enough.then_some(RequestedDirection {
            dir,
            weight: self.mean_flow_weight,
        })
    }
}

/// Measures every cell, in row-major order from the south-west corner.
pub fn measure(maps: &MergedMaps, layout: &Layout, progress: &dyn Progress) -> Vec<CellStats> {
    (0..layout.rows)
        .into_par_iter()
        .flat_map_iter(|row| {
            let cells: Vec<CellStats> = (0..layout.cols)
                .map(|col| measure_cell(maps, layout, Cell { col, row }))
                .collect();
            progress.advance(1);
            cells
        })
        .collect()
}

fn measure_cell(maps: &MergedMaps, layout: &Layout, cell: Cell) -> CellStats {
    let s = layout.side_px;
    let (mut walkers, mut standers, mut weight, mut blocked) = (0.0f64, 0.0f64, 0.0f64, 0u32);
    let mut flow = Vec2::ZERO.as_dvec2();
    for k in 0..s {
        for i in 0..s {
            let (x, y) = layout.pixel(cell, i, k);
            walkers += *maps.walkers.get(x, y) as f64;
            standers += *maps.standers.get(x, y) as f64;
            flow += maps.flow.get(x, y).as_dvec2();
            weight += *maps.flow_weight.get(x, y) as f64;
            blocked += *maps.blocked.get(x, y) as u32;
        }
    }
    let n = (s * s) as f64;
    CellStats {
        cell,
        mean_walkers: walkers / n,
        mean_standers: standers / n,
        flow,
        mean_flow_weight: weight / n,
        coverage: blocked as f64 / n,
        obstacles: if blocked > 0 {
            obstacle_rects(maps, layout, cell)
        } else {
            Vec::new()
        },
    }
}

/// The blocked pixels of a cell as few axis-aligned rectangles, exactly: runs of blocked pixels
/// per pixel row, merged with the rectangle below when they span the same columns.
fn obstacle_rects(maps: &MergedMaps, layout: &Layout, cell: Cell) -> Vec<Rect> {
    let s = layout.side_px;
    // (first column, end column, first row) of rectangles still growing northward.
    let mut open: Vec<(u32, u32, u32)> = Vec::new();
    let mut done: Vec<(u32, u32, u32, u32)> = Vec::new();
    for k in 0..=s {
        let mut runs = Vec::new();
        if k < s {
            let mut i = 0;
            while i < s {
                let blocked = |i| {
                    let (x, y) = layout.pixel(cell, i, k);
                    *maps.blocked.get(x, y)
                };
                if blocked(i) {
                    let start = i;
                    while i < s && blocked(i) {
                        i += 1;
                    }
                    runs.push((start, i));
                } else {
                    i += 1;
                }
            }
        }
        let mut still_open = Vec::new();
        for (a, b, k0) in open.drain(..) {
            if let Some(pos) = runs.iter().position(|&r| r == (a, b)) {
                runs.remove(pos);
                still_open.push((a, b, k0));
            } else {
                done.push((a, b, k0, k));
            }
        }
        still_open.extend(runs.into_iter().map(|(a, b)| (a, b, k)));
        open = still_open;
    }
    done.sort_by_key(|&(a, _, k0, _)| (k0, a));
    done.into_iter()
        .map(|(a, b, k0, k1)| Rect {
            min: DVec2::new(layout.meters(a), layout.meters(k0)),
            max: DVec2::new(layout.meters(b), layout.meters(k1)),
        })
        .collect()
}
