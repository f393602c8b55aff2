//! The connected pairs of the adjacency matrix A (Allain eq. 22): characters closer than the
//! cutoff, found through a grid of cutoff-sized cells so that a model evaluation costs O(n).

use crate::model::position;
use glam::DVec2;

/// How much farther than the cutoff `near` looks, so that its list stays complete while no
/// character has moved more than half of this since it was made (a Verlet list), m.
pub const SKIN: f64 = 0.6;

/// Reusable buffers for finding pairs; `find` overwrites the list.
#[derive(Clone, Debug, Default)]
pub struct Pairs {
    pairs: Vec<(usize, usize)>,
    /// Where the characters stood when `near` last searched, and its cutoff.
    anchor: Vec<DVec2>,
    anchor_cutoff: f64,
    cell_of: Vec<usize>,
    starts: Vec<usize>,
    sorted: Vec<usize>,
}

impl Pairs {
    /// Every pair (i < j) of characters in `x` (a state vector) closer than `cutoff`, in an
    /// order that depends only on the positions (none when a position is not finite).
    pub fn find(&mut self, x: &[f64], cutoff: f64) {
        let n = x.len() / 4;
        self.pairs.clear();
        self.anchor.clear();
        if n < 2 {
            return;
        }
        let (mut min, mut max) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for i in 0..n {
            let p = position(x, i);
            min = min.min(p);
            max = max.max(p);
        }
        if !(min.is_finite() && max.is_finite()) {
            return;
        }
        // Cells of the cutoff's size, or larger when the crowd is spread so far that there
        // would be many more cells than characters.
        let extent = max - min;
        let mut size = cutoff;
        while (extent.x / size + 1.0) * (extent.y / size + 1.0) > (4 * n + 16) as f64 {
            size *= 2.0;
        }
        let cols = (extent.x / size) as usize + 1;
        let rows = (extent.y / size) as usize + 1;
        let cell = |p: DVec2| {
            let c = (((p.x - min.x) / size) as usize).min(cols - 1);
            let r = (((p.y - min.y) / size) as usize).min(rows - 1);
            (c, r)
        };
        // Counting sort of the characters by cell.
        self.cell_of.clear();
        self.starts.clear();
        self.starts.resize(cols * rows + 1, 0);
        for i in 0..n {
            let (c, r) = cell(position(x, i));
            self.cell_of.push(r * cols + c);
            self.starts[r * cols + c + 1] += 1;
        }
        for k in 1..self.starts.len() {
            self.starts[k] += self.starts[k - 1];
        }
        self.sorted.clear();
        self.sorted.resize(n, 0);
        let mut fill = self.starts.clone();
        for i in 0..n {
            let k = self.cell_of[i];
            self.sorted[fill[k]] = i;
            fill[k] += 1;
        }
        let limit = cutoff * cutoff;
        for i in 0..n {
            let p = position(x, i);
            let (c, r) = cell(p);
            for rr in r.saturating_sub(1)..(r + 2).min(rows) {
                for cc in c.saturating_sub(1)..(c + 2).min(cols) {
                    let k = rr * cols + cc;
                    for &j in &self.sorted[self.starts[k]..self.starts[k + 1]] {
                        if j > i && (position(x, j) - p).length_squared() < limit {
                            self.pairs.push((i, j));
                        }
                    }
                }
            }
        }
    }

    /// A list holding every pair closer than `cutoff` (and maybe some up to `cutoff + SKIN`
    /// apart; callers check the distance): searched again only when someone has moved more
    /// than `SKIN / 2` since the last search, so consecutive stages and steps share one search.
    pub fn near(&mut self, x: &[f64], cutoff: f64) {
        let n = x.len() / 4;
        let limit = (SKIN / 2.0) * (SKIN / 2.0);
        let fresh = self.anchor.len() == n
            && self.anchor_cutoff == cutoff
            && (0..n).all(|i| (position(x, i) - self.anchor[i]).length_squared() <= limit);
        if fresh {
            return;
        }
        self.find(x, cutoff + SKIN);
        self.anchor.clear();
        self.anchor.extend((0..n).map(|i| position(x, i)));
        self.anchor_cutoff = cutoff;
        if !self.anchor.iter().all(|p| p.is_finite()) {
            self.anchor.clear();
        }
    }

    pub fn list(&self) -> &[(usize, usize)] {
        &self.pairs
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grid_finds_exactly_the_pairs_within_the_cutoff() {
        let mut x = Vec::new();
        for k in 0..200u64 {
            let a = (k * 2654435761 % 1000) as f64 / 1000.0 * 20.0;
            let b = (k * 40503 % 997) as f64 / 997.0 * 12.0;
            x.extend_from_slice(&[a, b, 0.0, 0.0]);
        }
        let mut pairs = Pairs::default();
        pairs.find(&x, 3.0);
        let mut found = pairs.list().to_vec();
        found.sort();
        let mut brute = Vec::new();
        for i in 0..200 {
            for j in i + 1..200 {
                if (position(&x, i) - position(&x, j)).length() < 3.0 {
                    brute.push((i, j));
                }
            }
        }
        assert_eq!(found, brute);
    }
}
