//! Shared borders and the intervals where people can cross them.

use crate::cells::Layout;
use crowd_core::patch_graph::{Border, BorderAxis, Cell, Interval};
use crowd_core::{MergedMaps, Patch, PatchId};
use std::collections::HashMap;

/// How much farther than its radius a walker's centre must stay from every wall for stage 2 to
/// count the place walkable: stage 5 pushes a walker clear of an obstacle by the missing
/// clearance plus 5 cm, so a way with less room than this is one it cannot keep.
pub const WALL_MARGIN_M: f64 = 0.05;

/// Every border shared by two kept patches, in patch order (east border, then north border).
///
/// A border pixel is open when the pixels on both sides of it, and those behind them up to
/// 2r + [`WALL_MARGIN_M`] from the border, are free: a crossing's band piece ends r inside, and
/// its end must be r + [`WALL_MARGIN_M`] clear of any wall parallel to the border (walls across
/// the border end the run, and stage 3 keeps crossings inside their run). Runs narrower than
/// `min_opening_m` are closed, since no character fits through them.
pub fn find(
    maps: &MergedMaps,
    layout: &Layout,
    patches: &[Patch],
    min_opening_m: f64,
    radius_m: f64,
) -> Vec<Border> {
    let by_cell: HashMap<Cell, PatchId> = patches.iter().map(|p| (p.cell, p.id)).collect();
    let depth_px = band_depth_px(layout, radius_m);
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
                    open: open_intervals(maps, layout, p.cell, axis, min_opening_m, depth_px),
                });
            }
        }
    }
    borders
}

/// How many pixels deep on each side of a border must be free for a crossing there: 2r +
/// [`WALL_MARGIN_M`], at least one pixel, at most a patch.
fn band_depth_px(layout: &Layout, radius_m: f64) -> u32 {
    let depth = ((2.0 * radius_m + WALL_MARGIN_M) / layout.meters_per_pixel() - 1e-9).ceil();
    (depth.max(1.0) as u32).min(layout.side_px)
}

fn open_intervals(
    maps: &MergedMaps,
    layout: &Layout,
    cell: Cell,
    axis: BorderAxis,
    min_opening_m: f64,
    depth_px: u32,
) -> Vec<Interval> {
    let s = layout.side_px as i64;
    let open_at = |k: u32| {
        // The pixels of `cell` behind the border and those of the neighbour across it, in
        // `cell`'s coordinates (the neighbour's run past `s`).
        (0..depth_px as i64).all(|d| {
            let (here, there) = match axis {
                BorderAxis::Vertical => ((s - 1 - d, k as i64), (s + d, k as i64)),
                BorderAxis::Horizontal => ((k as i64, s - 1 - d), (k as i64, s + d)),
            };
            !layout.blocked(maps, cell, here.0, here.1)
                && !layout.blocked(maps, cell, there.0, there.1)
        })
    };
    let s = layout.side_px;
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

/// Closes the open intervals through which a walker could only come into a part of a patch it
/// cannot walk from to the rest: a part a wall cuts off (a wall from side to side that covers
/// too little of the patch to drop it), or one joined to the rest only through a gap narrower
/// than 2 (r + [`WALL_MARGIN_M`]), or a place where the band piece's end has no such room.
/// Stages 3 and 4 keep parity and pair entries with exits per patch, so a walker could
/// otherwise come in on one side of the wall and have to leave on the other, through it.
///
/// The parts are those of the walkers' free space ([`FreeSpace`]: where a centre stays in
/// [r, side - r]^2 and r + [`WALL_MARGIN_M`] from every blocked pixel), and an interval belongs
/// to the part its band ends (r inside) reach. Each patch keeps the intervals of its part with
/// the most open border length (the first such part in point order on a tie); the others, and
/// intervals whose band ends have no room at all, close for both of their patches.
pub fn close_cut_off_regions(
    maps: &MergedMaps,
    layout: &Layout,
    patches: &[Patch],
    borders: &mut [Border],
    radius_m: f64,
) {
    let index: HashMap<PatchId, usize> =
        patches.iter().enumerate().map(|(i, p)| (p.id, i)).collect();
    // Per patch, its borders with the side it sees them from.
    let mut sides: Vec<Vec<(usize, bool)>> = vec![Vec::new(); patches.len()];
    for (k, b) in borders.iter().enumerate() {
        sides[index[&b.a]].push((k, true));
        sides[index[&b.b]].push((k, false));
    }
    for (i, p) in patches.iter().enumerate() {
        let Some(space) = FreeSpace::of(maps, layout, p.cell, radius_m) else {
            continue; // no wall within reach: one part
        };
        // The part of each open interval (None: its band ends have no room).
        let mut touched: Vec<(usize, usize, Option<usize>, f64)> = Vec::new(); // (border, interval, part, length)
        for &(k, is_a) in &sides[i] {
            for (j, interval) in borders[k].open.iter().enumerate() {
                let part = space.part_behind(borders[k].axis, is_a, interval);
                touched.push((k, j, part, interval.len()));
            }
        }
        let mut length: Vec<f64> = Vec::new();
        for &(_, _, part, len) in &touched {
            if let Some(part) = part {
                if length.len() <= part {
                    length.resize(part + 1, 0.0);
                }
                length[part] += len;
            }
        }
        let keep =
            (0..length.len()).max_by(|&a, &b| length[a].total_cmp(&length[b]).then(b.cmp(&a)));
        let mut closing: Vec<(usize, usize)> = touched
            .iter()
            .filter(|t| t.2.is_none() || t.2 != keep)
            .map(|t| (t.0, t.1))
            .collect();
        // Highest index first, so removing one does not shift the others.
        closing.sort_unstable_by(|a, b| b.cmp(a));
        for (k, j) in closing {
            borders[k].open.remove(j);
        }
    }
}

/// Where a walker's centre may be off the border bands, sampled on a square grid of points
/// from r to side - r (about a quarter of r or of a pixel apart, whichever is finer): in
/// [r, side - r]^2 and at least r + [`WALL_MARGIN_M`] from every blocked pixel, this patch's
/// or a neighbour's. `part` labels its 4-connected parts (`None`: no room there), so two parts
/// joined only through a gap narrower than 2 (r + margin) are two.
struct FreeSpace {
    /// Points per axis.
    n: usize,
    step: f64,
    radius: f64,
    part: Vec<Option<usize>>,
}

impl FreeSpace {
    /// `None` when no blocked pixel comes within reach of the grid: the whole patch is one part.
    fn of(maps: &MergedMaps, layout: &Layout, cell: Cell, radius_m: f64) -> Option<FreeSpace> {
        let mpp = layout.meters_per_pixel();
        let side = layout.meters(layout.side_px);
        let clear = radius_m + WALL_MARGIN_M;
        let span = (side - 2.0 * radius_m).max(0.0);
        let steps = ((span / (radius_m.min(mpp) / 4.0)).ceil() as usize).max(1);
        let step = span / steps as f64;
        let n = steps + 1;
        let mut free = vec![true; n * n];
        let mut any = false;
        let reach = (clear / mpp).ceil() as i64;
        let s = layout.side_px as i64;
        // The grid indices whose coordinate lies strictly within `clear` of [lo, hi].
        let range = |lo: f64, hi: f64| {
            let a = ((lo - clear - radius_m) / step).floor().max(0.0) as usize;
            let b = ((hi + clear - radius_m) / step).ceil();
            (a, (b.max(-1.0) as i64).min(n as i64 - 1))
        };
        for k in -reach..s + reach {
            for i in -reach..s + reach {
                if !layout.blocked(maps, cell, i, k) {
                    continue;
                }
                let (x0, y0) = (i as f64 * mpp, k as f64 * mpp);
                let (x1, y1) = (x0 + mpp, y0 + mpp);
                let (ax, bx) = range(x0, x1);
                let (ay, by) = range(y0, y1);
                for b in ay as i64..=by {
                    let y = radius_m + b as f64 * step;
                    let dy = (y0 - y).max(y - y1).max(0.0);
                    for a in ax as i64..=bx {
                        let x = radius_m + a as f64 * step;
                        let dx = (x0 - x).max(x - x1).max(0.0);
                        if dx * dx + dy * dy < clear * clear {
                            free[b as usize * n + a as usize] = false;
                            any = true;
                        }
                    }
                }
            }
        }
        if !any {
            return None;
        }
        let mut part: Vec<Option<usize>> = vec![None; n * n];
        let mut next = 0;
        for start in 0..n * n {
            if part[start].is_some() || !free[start] {
                continue;
            }
            part[start] = Some(next);
            let mut stack = vec![start];
            while let Some(at) = stack.pop() {
                let (a, b) = (at % n, at / n);
                let mut visit = |to: usize| {
                    if part[to].is_none() && free[to] {
                        part[to] = Some(next);
                        stack.push(to);
                    }
                };
                if a > 0 {
                    visit(at - 1);
                }
                if a + 1 < n {
                    visit(at + 1);
                }
                if b > 0 {
                    visit(at - n);
                }
                if b + 1 < n {
                    visit(at + n);
                }
            }
            next += 1;
        }
        Some(FreeSpace {
            n,
            step,
            radius: radius_m,
            part,
        })
    }

    /// The part reached by the band ends (r inside the border) of an open interval, seen from
    /// the patch on side `a` (west or south) or `b`: the first point with room along it.
    fn part_behind(&self, axis: BorderAxis, is_a: bool, interval: &Interval) -> Option<usize> {
        let n = self.n;
        let line = if is_a { n - 1 } else { 0 };
        let first = ((interval.start - self.radius) / self.step).ceil().max(0.0) as usize;
        let last = ((interval.end - self.radius) / self.step).floor();
        if last < 0.0 {
            return None;
        }
        let last = (last as usize).min(n - 1);
        (first..=last).find_map(|j| match axis {
            BorderAxis::Vertical => self.part[j * n + line],
            BorderAxis::Horizontal => self.part[line * n + j],
        })
    }
}
