//! A spatial grid of pieces, so that a whole world's pieces are compared only with those near
//! them (near linear in their number instead of quadratic), and each near pair exactly once;
//! and one of boxes (standers, obstacles), so that a piece is compared only with those near it.

use crate::segment::Segment;
use glam::DVec2;
use std::collections::HashMap;

/// A cell's place: column and row of `cell`-wide squares from the origin.
pub type Key = (i64, i64);

/// Pieces by the square cells their boxes, grown by `reach`, touch.
#[derive(Debug, Clone)]
pub struct PieceGrid {
    cell: f64,
    reach: f64,
    /// Every cell that holds a piece, in key order, with its pieces' indices in order.
    cells: Vec<(Key, Vec<u32>)>,
}

impl PieceGrid {
    /// Files every piece of `segs` (by its index) in every cell that its box, grown by
    /// `reach` on each side, touches: two pieces that come within `reach` share a cell.
    pub fn new<'a>(segs: impl IntoIterator<Item = &'a Segment>, cell: f64, reach: f64) -> Self {
        let mut grid = PieceGrid {
            cell,
            reach,
            cells: Vec::new(),
        };
        let mut cells: HashMap<Key, Vec<u32>> = HashMap::new();
        for (i, s) in segs.into_iter().enumerate() {
            let (a, b) = (grid.key(grid.lowest(s)), grid.key(s.p0.max(s.p1) + reach));
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

    /// Whether cell `k` is the one that compares pieces `a` and `b`: each piece fills a
    /// rectangle of cells, and the lowest corner of the two rectangles' overlap compares the
    /// pair, so that it is compared once.
    pub fn owns(&self, k: Key, a: &Segment, b: &Segment) -> bool {
        let (la, lb) = (self.key(self.lowest(a)), self.key(self.lowest(b)));
        (la.0.max(lb.0), la.1.max(lb.1)) == k
    }

    fn lowest(&self, s: &Segment) -> DVec2 {
        s.p0.min(s.p1) - DVec2::splat(self.reach)
    }

    fn key(&self, p: DVec2) -> Key {
        (
            (p.x / self.cell).floor() as i64,
            (p.y / self.cell).floor() as i64,
        )
    }
}

/// Boxes (standers as points, obstacles) by the 4 m cells they touch grown by their reach, so
/// that a piece is compared only with those that can come within reach of it.
#[derive(Debug, Clone)]
pub struct BoxGrid {
    cells: HashMap<(i64, i64), Vec<u32>>,
}

impl BoxGrid {
    const CELL: f64 = 4.0;

    fn key(p: DVec2) -> (i64, i64) {
        (
            (p.x / Self::CELL).floor() as i64,
            (p.y / Self::CELL).floor() as i64,
        )
    }

    pub fn new(boxes: impl Iterator<Item = (DVec2, DVec2)>, reach: f64) -> BoxGrid {
        let mut cells: HashMap<(i64, i64), Vec<u32>> = HashMap::new();
        for (i, (lo, hi)) in boxes.enumerate() {
            let (a, b) = (Self::key(lo - reach), Self::key(hi + reach));
            for x in a.0..=b.0 {
                for y in a.1..=b.1 {
                    cells.entry((x, y)).or_default().push(i as u32);
                }
            }
        }
        BoxGrid { cells }
    }

    /// The boxes whose grown box shares a cell with [lo, hi], ascending, each once.
    pub fn near(&self, lo: DVec2, hi: DVec2) -> Vec<u32> {
        if self.cells.is_empty() {
            return Vec::new();
        }
        let (a, b) = (Self::key(lo), Self::key(hi));
        let mut out: Vec<u32> = (a.0..=b.0)
            .flat_map(|x| (a.1..=b.1).map(move |y| (x, y)))
            .filter_map(|k| self.cells.get(&k))
            .flatten()
            .copied()
            .collect();
        out.sort_unstable();
        out.dedup();
        out
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
                        if grid.owns(*k, &pieces[i as usize], &pieces[j as usize]) {
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

    #[test]
    fn a_piece_is_compared_with_the_boxes_within_reach_only() {
        let grid = BoxGrid::new([(DVec2::ZERO, DVec2::ONE)].into_iter(), 1.0);
        assert_eq!(
            grid.near(DVec2::new(1.5, 1.5), DVec2::new(2.0, 2.0)),
            vec![0]
        );
        assert!(
            grid.near(DVec2::new(9.0, 9.0), DVec2::new(10.0, 10.0))
                .is_empty()
        );
    }
}
