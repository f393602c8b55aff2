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

/// Closes the open intervals through which a patch could only be entered into a part of it
/// that a wall cuts off from the rest (a wall from side to side that covers too little of the
/// patch to drop it). Stages 3 and 4 keep parity and pair entries with exits per patch, so a
/// walker could otherwise come in on one side of the wall and leave on the other, through it.
/// Each patch keeps the intervals of its free region with the most open border length (the
/// first such region in pixel order on a tie); the others close for both of their patches.
pub fn close_cut_off_regions(
    maps: &MergedMaps,
    layout: &Layout,
    patches: &[Patch],
    borders: &mut [Border],
) {
    let s = layout.side_px;
    let index: HashMap<PatchId, usize> =
        patches.iter().enumerate().map(|(i, p)| (p.id, i)).collect();
    // Per patch, its borders with the side it sees them from.
    let mut sides: Vec<Vec<(usize, bool)>> = vec![Vec::new(); patches.len()];
    for (k, b) in borders.iter().enumerate() {
        sides[index[&b.a]].push((k, true));
        sides[index[&b.b]].push((k, false));
    }
    for (i, p) in patches.iter().enumerate() {
        let regions = free_regions(maps, layout, p.cell);
        // The region of each open interval (the pixel on this patch's side at its start).
        let mut touched: Vec<(usize, usize, usize, f64)> = Vec::new(); // (border, interval, region, length)
        for &(k, is_a) in &sides[i] {
            for (j, interval) in borders[k].open.iter().enumerate() {
                let along = (interval.start / layout.meters(1)).round() as u32;
                let (x, y) = match (borders[k].axis, is_a) {
                    (BorderAxis::Vertical, true) => (s - 1, along),
                    (BorderAxis::Vertical, false) => (0, along),
                    (BorderAxis::Horizontal, true) => (along, s - 1),
                    (BorderAxis::Horizontal, false) => (along, 0),
                };
                if let Some(region) = regions[(y * s + x) as usize] {
                    touched.push((k, j, region, interval.len()));
                }
            }
        }
        let mut length: Vec<f64> = Vec::new();
        for &(_, _, region, len) in &touched {
            if length.len() <= region {
                length.resize(region + 1, 0.0);
            }
            length[region] += len;
        }
        let Some(keep) =
            (0..length.len()).max_by(|&a, &b| length[a].total_cmp(&length[b]).then(b.cmp(&a)))
        else {
            continue;
        };
        let mut closing: Vec<(usize, usize)> = touched
            .iter()
            .filter(|t| t.2 != keep)
            .map(|t| (t.0, t.1))
            .collect();
        // Highest index first, so removing one does not shift the others.
        closing.sort_unstable_by(|a, b| b.cmp(a));
        for (k, j) in closing {
            borders[k].open.remove(j);
        }
    }
}

/// The 4-connected regions of free pixels of a cell, by cell-local pixel (i east, k north, row
/// by row from the south-west): `None` for a blocked pixel.
fn free_regions(maps: &MergedMaps, layout: &Layout, cell: Cell) -> Vec<Option<usize>> {
    let s = layout.side_px;
    let free = |i: u32, k: u32| {
        let (x, y) = layout.pixel(cell, i, k);
        !*maps.blocked.get(x, y)
    };
    let mut label: Vec<Option<usize>> = vec![None; (s * s) as usize];
    let mut next = 0;
    for start in 0..s * s {
        let (i0, k0) = (start % s, start / s);
        if label[start as usize].is_some() || !free(i0, k0) {
            continue;
        }
        let mut stack = vec![(i0, k0)];
        label[start as usize] = Some(next);
        while let Some((i, k)) = stack.pop() {
            let mut visit = |i: u32, k: u32| {
                let at = (k * s + i) as usize;
                if label[at].is_none() && free(i, k) {
                    label[at] = Some(next);
                    stack.push((i, k));
                }
            };
            if i > 0 {
                visit(i - 1, k);
            }
            if i + 1 < s {
                visit(i + 1, k);
            }
            if k > 0 {
                visit(i, k - 1);
            }
            if k + 1 < s {
                visit(i, k + 1);
            }
        }
        next += 1;
    }
    label
}
