//! A spatial grid of pieces, so that a whole world's pieces are compared only with those near
//! them (near linear in their number instead of quadratic), and each near pair exactly once;
//! and one of boxes (standers, obstacles), so that a piece is compared only with those near it.

use crate::segment::Segment;
use glam::DVec2;
/// Cell maps hashed with foldhash's fixed state: keys are small integer pairs, SipHash was a
/// fifth of the world check, and a fixed state keeps runs alike.
type CellMap<V> = std::collections::HashMap<Key, V, foldhash::fast::FixedState>;

/// A cell's place: column and row of `cell`-wide squares from the origin.
pub type Key = (i64, i64);

/// Pieces by the square cells their boxes, grown by `reach`, touch.
#[derive(Debug, Clone)]
pub struct PieceGrid {
    cell: f64,
    reach: f64,
    /// Every cell that holds a piece, in key order, with its pieces' indices in order.
    cells: Vec<(Key, Vec<u32>)>,
    /// Each piece's lowest cell (its grown box's lower corner), kept for [`PieceGrid::owns`].
    lows: Vec<Key>,
}

impl PieceGrid {
    /// Files every piece of `segs` (by its index) in every cell that its box, grown by
    /// `reach` on each side, touches: two pieces that come within `reach` share a cell.
    pub fn new<'a>(segs: impl IntoIterator<Item = &'a Segment>, cell: f64, reach: f64) -> Self {
        let mut grid = PieceGrid {
            cell,
            reach,
            cells: Vec::new(),
            lows: Vec::new(),
        };
        let mut cells: CellMap<Vec<u32>> = CellMap::default();
        for (i, s) in segs.into_iter().enumerate() {
            let (a, b) = (grid.key(grid.lowest(s)), grid.key(s.p0.max(s.p1) + reach));
            grid.lows.push(a);
            for x in a.0..=b.0 {
                for y in a.1..=b.1 {
                    cells.entry((x, y)).or_default().push(i as u32);
                }
            }
        }
        grid.cells = cells.into_iter().collect();
        grid.cells.sort_by_key(|(k, _)| *k);
        grid
    }

    /// Every cell that holds a piece, in key order, with its pieces in the order they came.
    pub fn cells(&self) -> &[(Key, Vec<u32>)] {
        &self.cells
    }

    /// Whether cell `k` is the one that compares pieces `a` and `b` (indices as filed): each
    /// piece fills a rectangle of cells, and the lowest corner of the two rectangles' overlap
    /// compares the pair, so that it is compared once.
    pub fn owns(&self, k: Key, a: u32, b: u32) -> bool {
        let (la, lb) = (self.lows[a as usize], self.lows[b as usize]);
        (la.0.max(lb.0), la.1.max(lb.1)) == k
    }

    fn lowest(&self, s: &Segment) -> DVec2 {
        s.p0.min(s.p1) - DVec2::splat(self.reach)
    }

    fn key(&self, p: DVec2) -> Key {
        (floor(p.x / self.cell), floor(p.y / self.cell))
    }
}

/// `x.floor() as i64`, without the call to libm's `floor` that x86-64's baseline makes of
/// it (a twentieth of the world check).
fn floor(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) > x { t - 1 } else { t }
}

/// Boxes (standers as points, obstacles) by the 4 m cells they touch grown by their reach, so
/// that a piece is compared only with those that can come within reach of it.
#[derive(Debug, Clone)]
pub struct BoxGrid {
    cell: f64,
    /// Each cell's boxes, with each box's lowest cell (for [`BoxGrid::near`]'s once-only rule).
    cells: CellMap<Vec<(u32, Key)>>,
}

impl BoxGrid {
    fn key(&self, p: DVec2) -> Key {
        (floor(p.x / self.cell), floor(p.y / self.cell))
    }

    /// Files `boxes` in `cell`-wide squares, each in every square its box grown by `reach`
    /// touches (on city's walls, 1, 2, 4 and 8 m squares cost the world check alike).
    pub fn new(boxes: impl Iterator<Item = (DVec2, DVec2)>, cell: f64, reach: f64) -> BoxGrid {
        let mut grid = BoxGrid {
            cell,
            cells: CellMap::default(),
        };
        for (i, (lo, hi)) in boxes.enumerate() {
            let (a, b) = (grid.key(lo - reach), grid.key(hi + reach));
            for x in a.0..=b.0 {
                for y in a.1..=b.1 {
                    grid.cells.entry((x, y)).or_default().push((i as u32, a));
                }
            }
        }
        grid
    }

    /// Calls `visit` once with each box whose grown box shares a cell with [lo, hi] (in no
    /// particular order): from the lowest corner of the two rectangles of cells' overlap, so
    /// that nothing is gathered, sorted or deduplicated per query.
    pub fn near(&self, lo: DVec2, hi: DVec2, mut visit: impl FnMut(u32)) {
        if self.cells.is_empty() {
            return;
        }
        let (a, b) = (self.key(lo), self.key(hi));
        for x in a.0..=b.0 {
            for y in a.1..=b.1 {
                let Some(boxes) = self.cells.get(&(x, y)) else {
                    continue;
                };
                for &(i, low) in boxes {
                    if (a.0.max(low.0), a.1.max(low.1)) == (x, y) {
                        visit(i);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::approach::closest;
    use proptest::prelude::*;

    fn any_piece() -> impl Strategy<Value = Segment> {
        (-20.0f64..20.0, -20.0f64..20.0, -3.0f64..3.0, -3.0f64..3.0).prop_map(|(x, y, dx, dy)| {
            Segment {
                p0: DVec2::new(x, y),
                t0: 0.0,
                p1: DVec2::new(x + dx, y + dy),
                t1: 1.0,
            }
        })
    }

    proptest! {
        /// Every pair of pieces that come within reach of each other is compared by exactly one
        /// cell, one that holds them both.
        #[test]
        fn every_near_pair_is_compared_once(pieces in proptest::collection::vec(any_piece(), 2..40)) {
            let reach = 0.6;
            let grid = PieceGrid::new(&pieces, 4.0, reach);
            let mut compared = vec![0u32; pieces.len() * pieces.len()];
            for (k, ids) in grid.cells() {
                prop_assert!(ids.windows(2).all(|w| w[0] < w[1]));
                for (x, &i) in ids.iter().enumerate() {
                    for &j in &ids[x + 1..] {
                        if grid.owns(*k, i, j) {
                            compared[i as usize * pieces.len() + j as usize] += 1;
                        }
                    }
                }
            }
            for i in 0..pieces.len() {
                for j in i + 1..pieces.len() {
                    let n = compared[i * pieces.len() + j];
                    prop_assert!(n <= 1, "pieces {} and {} compared {} times", i, j, n);
                    // Pieces over the same second: their closest approach bounds their paths'.
                    let (d, _) = closest(&pieces[i], &pieces[j]).expect("same span");
                    if d < reach {
                        prop_assert_eq!(n, 1, "pieces {} and {} ({} m apart) never compared", i, j, d);
                    }
                }
            }
        }
    }

    fn near(grid: &BoxGrid, lo: DVec2, hi: DVec2) -> Vec<u32> {
        let mut out = Vec::new();
        grid.near(lo, hi, |i| out.push(i));
        out.sort_unstable();
        out
    }

    #[test]
    fn a_piece_is_compared_with_the_boxes_within_reach_only() {
        let grid = BoxGrid::new([(DVec2::ZERO, DVec2::ONE)].into_iter(), 4.0, 1.0);
        assert_eq!(
            near(&grid, DVec2::new(1.5, 1.5), DVec2::new(2.0, 2.0)),
            vec![0]
        );
        assert!(near(&grid, DVec2::new(9.0, 9.0), DVec2::new(10.0, 10.0)).is_empty());
    }

    proptest! {
        #[test]
        fn floor_is_the_floor(x in -1e12f64..1e12) {
            prop_assert_eq!(floor(x), x.floor() as i64);
        }
    }

    fn any_box() -> impl Strategy<Value = (DVec2, DVec2)> {
        (-20.0f64..20.0, -20.0f64..20.0, 0.0f64..9.0, 0.0f64..9.0)
            .prop_map(|(x, y, w, h)| (DVec2::new(x, y), DVec2::new(x + w, y + h)))
    }

    proptest! {
        /// A query meets every box whose grown box overlaps it, each exactly once.
        #[test]
        fn every_box_within_reach_is_met_once(
            boxes in proptest::collection::vec(any_box(), 1..30),
            (lo, hi) in any_box(),
            cell in 0.5f64..6.0,
        ) {
            let reach = 0.7;
            let grid = BoxGrid::new(boxes.iter().copied(), cell, reach);
            let mut met = vec![0u32; boxes.len()];
            grid.near(lo, hi, |i| met[i as usize] += 1);
            for (i, &(blo, bhi)) in boxes.iter().enumerate() {
                prop_assert!(met[i] <= 1, "box {} met {} times", i, met[i]);
                let apart = (blo - reach - hi).max(lo - (bhi + reach)).max_element();
                if apart < 0.0 {
                    prop_assert_eq!(met[i], 1, "box {} within reach never met", i);
                }
            }
        }
    }
}
