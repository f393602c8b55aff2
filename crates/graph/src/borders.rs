//! Shared borders and the intervals where people can cross them.

use crate::cells::Layout;
use crowd_core::patch_graph::{Border, BorderAxis, Cell, Interval};
use crowd_core::{MergedMaps, Patch, PatchId};
use std::collections::HashMap;

/// Every border shared by two kept patches, in patch order (east border, then north border).
///
/// A border pixel is open when the pixels on both sides of it are free; runs of open pixels
/// narrower than `min_opening_m` are closed, since no character fits through them.
pub fn find(
    maps: &MergedMaps,
    layout: &Layout,
    patches: &[Patch],
    min_opening_m: f64,
) -> Vec<Border> {
    let by_cell: HashMap<Cell, PatchId> = patches.iter().map(|p| (p.cell, p.id)).collect();
    let mut borders = Vec::new();
    for p in patches {
        let east = Cell {
            col: p.cell.col + 1,
            row: p.cell.row,
        };
        let north = Cell {
            col: p.cell.col,
            row: p.cell.row + 1,
        };
        for (neighbour, axis) in [
            (east, BorderAxis::Vertical),
            (north, BorderAxis::Horizontal),
        ] {
            if let Some(&b) = by_cell.get(&neighbour) {
                borders.push(Border {
                    a: p.id,
                    b,
                    axis,
                    open: open_intervals(maps, layout, p.cell, axis, min_opening_m),
                });
            }
        }
    }
    borders
}

fn open_intervals(
    maps: &MergedMaps,
    layout: &Layout,
    cell: Cell,
    axis: BorderAxis,
    min_opening_m: f64,
) -> Vec<Interval> {
    let s = layout.side_px;
    let open_at = |k: u32| {
        // The pixel of `cell` on the border and the pixel of the neighbour across it.
        let (here, there) = match axis {
            BorderAxis::Vertical => (
                layout.pixel(cell, s - 1, k),
                layout.pixel(
                    Cell {
                        col: cell.col + 1,
                        ..cell
                    },
                    0,
                    k,
                ),
            ),
            BorderAxis::Horizontal => (
                layout.pixel(cell, k, s - 1),
                layout.pixel(
                    Cell {
                        row: cell.row + 1,
                        ..cell
                    },
                    k,
                    0,
                ),
            ),
        };
        !*maps.blocked.get(here.0, here.1) && !*maps.blocked.get(there.0, there.1)
    };
    let mut intervals = Vec::new();
    let mut k = 0;
    while k < s {
        if open_at(k) {
            let start = k;
            while k < s && open_at(k) {
                k += 1;
            }
            let interval = Interval {
                start: layout.meters(start),
                end: layout.meters(k),
            };
            if interval.len() >= min_opening_m - 1e-9 {
                intervals.push(interval);
            }
        } else {
            k += 1;
        }
    }
    intervals
}
