//! The world cut into strips for the check: runs of patches of about [`STRIP_PIECES`] pieces
//! (of the patches to judge: all, or those a change reached), each checked with the patches
//! within reach of them present but not counted (`world::Scene::owned`). What the check holds
//! then grows with a strip, not with the world:
//! a million walkers' 165 million pieces held 20 GB at once.

use crate::world::{Pairs, Scene};
use crowd_core::PatchGraph;
use crowd_core::trajectories::PatchMotion;
use crowd_geometry::BoxGrid;
use glam::DVec2;

/// Pieces a strip holds at most, give or take a chunk of patches (56 bytes each, with the
/// spatial grid's entries about 200 MB). Of 4 million, painting's check alone peaked at 1.06
/// GB (262,000 page faults); of 2 million, at 0.68 GB (167,000), in as little time (8.2 s
/// against 8.3-9.6 s, for 0.3-0.5 s more of its cores on the neighbours more strips hold):
/// on a machine where a fresh page costs several times a reused one, the memory is the time.
pub(crate) const STRIP_PIECES: u64 = 2_000_000;

/// Where a patch's characters go: the box of every point of its trajectories and of its
/// standers, world metres, and how many pieces its trajectories have.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Extent {
    pub lo: DVec2,
    pub hi: DVec2,
    pub pieces: u64,
}

impl Extent {
    /// A patch with no one in it.
    pub const EMPTY: Extent = Extent {
        lo: DVec2::INFINITY,
        hi: DVec2::NEG_INFINITY,
        pieces: 0,
    };

    /// Patch `p`'s extent in `graph`'s world.
    pub fn of(graph: &PatchGraph, p: usize, m: &PatchMotion) -> Extent {
        let origin = graph.world_from_patch(graph.patches[p].cell);
        let points = (m.trajectories.iter())
            .flat_map(|t| t.points.iter().map(|c| c.pos))
            .chain(m.standers.iter().copied());
        let mut e = Extent::EMPTY;
        for q in points {
            e.grow(origin + q);
        }
        e.pieces = (m.trajectories.iter())
            .map(|t| t.points.len().saturating_sub(1) as u64)
            .sum();
        e
    }

    /// Takes in point `q` (world metres).
    pub fn grow(&mut self, q: DVec2) {
        self.lo = self.lo.min(q);
        self.hi = self.hi.max(q);
    }

    pub fn is_empty(&self) -> bool {
        self.lo.x > self.hi.x
    }

    /// Whether `o`'s box comes within `reach` of this one's (neither empty).
    pub fn near(&self, o: &Extent, reach: f64) -> bool {
        !self.is_empty()
            && !o.is_empty()
            && (o.lo - self.hi).max(self.lo - o.hi).max_element() <= reach
    }
}

/// The strips that judge patches `todo` (in order): runs of its patches whose scenes hold
/// about `budget` pieces, counting the patches within reach that each holds besides its own
/// (`near`: [`held`]); a run of one patch however many it holds. A strip owns only its
/// patches of `todo`, wherever they are: the few hundred a brush stroke reaches are one scene
/// with the patches around them, not one scene per row of the world each with its own (3.4
/// times as many pieces on painting's stroke). Counting only its own pieces, a strip of the
/// patches along the shards' edges held several times its budget (the million's gather: 2.1
/// GB at its check of the stage file).
pub(crate) fn runs(
    todo: &[usize],
    extents: &[Extent],
    near: &[Vec<u32>],
    budget: u64,
) -> Vec<Vec<usize>> {
    let mut strips: Vec<Vec<usize>> = Vec::new();
    // The strip that holds each patch (its number), and how many pieces the last one holds.
    let mut holder = vec![usize::MAX; extents.len()];
    let mut pieces = 0u64;
    for &p in todo {
        if strips
            .last()
            .and_then(|s| s.last())
            .is_some_and(|&q| p <= q)
        {
            continue; // a repeat
        }
        let now = strips.len().wrapping_sub(1);
        let adds = |of: usize| {
            let mut patches = near[p]
                .iter()
                .map(|&q| q as usize)
                .chain([p])
                .collect::<Vec<_>>();
            patches.sort_unstable();
            patches.dedup();
            patches.retain(|&q| holder[q] != of);
            patches
        };
        let mut more = adds(now);
        let count = |patches: &[usize]| patches.iter().map(|&q| extents[q].pieces).sum::<u64>();
        if strips.is_empty() || pieces + count(&more) > budget {
            strips.push(Vec::new());
            more = adds(strips.len() - 1);
            pieces = 0;
        }
        pieces += count(&more);
        let at = strips.len() - 1;
        more.iter().for_each(|&q| holder[q] = at);
        strips[at].push(p);
    }
    strips
}

/// The pairs each patch owns: those `known` (a check's memo) as they are, the rest judged a
/// strip at a time ([`runs`] of about `budget` pieces) in the scene `scene_of` makes of a strip
/// and the patches it holds ([`held`], from each patch's `near`: [`within_reach`]); with how
/// many patches were judged. The stage files' check and the library's share it.
pub(crate) fn judge_pairs<E>(
    mut known: Vec<Option<Pairs>>,
    (extents, near, budget): (&[Extent], &[Vec<u32>], u64),
    mut scene_of: impl FnMut(&[usize], &[usize]) -> Result<Scene, E>,
) -> Result<(Vec<Pairs>, usize), E> {
    let todo: Vec<usize> = (0..known.len()).filter(|&p| known[p].is_none()).collect();
    for strip in runs(&todo, extents, near, budget) {
        let scene = scene_of(&strip, &held(&strip, near))?;
        strip
            .iter()
            .for_each(|&p| known[p] = Some(Pairs::default()));
        for (p, found) in scene.pairs_by_patch() {
            known[p as usize] = Some(found);
        }
    }
    let pairs = known.into_iter().map(Option::unwrap_or_default).collect();
    Ok((pairs, todo.len()))
}

/// The patches a strip's scene holds, in order: the strip's own, and every other whose
/// characters come within reach of one of them (`near`: [`within_reach`]; they may meet one of
/// its characters).
pub(crate) fn held(strip: &[usize], near: &[Vec<u32>]) -> Vec<usize> {
    let mut held: Vec<usize> = strip.to_vec();
    for &p in strip {
        held.extend(near[p].iter().map(|&q| q as usize));
    }
    held.sort_unstable();
    held.dedup();
    held
}

/// Per patch, the patches whose characters come within `reach` of its own (itself included,
/// in index order), from their extents in a grid of `cell`-wide squares.
pub(crate) fn within_reach(extents: &[Extent], reach: f64, cell: f64) -> Vec<Vec<u32>> {
    let boxes = extents.iter().map(|e| {
        if e.is_empty() {
            (DVec2::ZERO, DVec2::ZERO)
        } else {
            (e.lo, e.hi)
        }
    });
    let grid = BoxGrid::new(boxes, cell, reach);
    extents
        .iter()
        .map(|e| {
            if e.is_empty() {
                return Vec::new();
            }
            let mut near = Vec::new();
            grid.near(e.lo, e.hi, |q| {
                if e.near(&extents[q as usize], reach) {
                    near.push(q);
                }
            });
            near.sort_unstable();
            near
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(x: f64, y: f64, pieces: u64) -> Extent {
        Extent {
            lo: DVec2::new(x, y),
            hi: DVec2::new(x + 8.0, y + 8.0),
            pieces,
        }
    }

    #[test]
    fn runs_cover_every_patch_to_judge_once_in_order_within_their_budget() {
        let extents: Vec<Extent> = (0..1000).map(|i| at(0.0, 0.0, i % 7)).collect();
        // Alone, or with the patches either side within reach.
        let alone: Vec<Vec<u32>> = (0..1000).map(|i| vec![i]).collect();
        let row: Vec<Vec<u32>> = (0..1000u32)
            .map(|i| (i.saturating_sub(1)..(i + 2).min(1000)).collect())
            .collect();
        let every: Vec<usize> = (0..1000).collect();
        let some: Vec<usize> = (0..1000)
            .filter(|i| i % 97 < 3 || (400..420).contains(i))
            .collect();
        for near in [&alone, &row] {
            for todo in [&every, &some] {
                for budget in [0, 1, 100, 500, 2_000, u64::MAX] {
                    let strips = runs(todo, &extents, near, budget);
                    let walked: Vec<usize> = strips.iter().flatten().copied().collect();
                    assert_eq!(&walked, todo, "each patch once, in order");
                    for s in &strips {
                        let pieces: u64 = held(s, near).iter().map(|&p| extents[p].pieces).sum();
                        assert!(s.len() == 1 || pieces <= budget, "{s:?} {pieces} {budget}");
                    }
                }
                assert_eq!(runs(todo, &extents, near, u64::MAX), vec![todo.clone()]);
            }
            assert!(runs(&[], &extents, near, 10).is_empty());
        }
        // The strips of scattered patches are fewer when only their own pieces count.
        let scattered = |near| runs(&some, &extents, near, 100).len();
        assert!(scattered(&alone) < scattered(&row));
    }

    #[test]
    fn a_strip_holds_the_patches_within_reach_and_no_farther_ones() {
        // A row of 8 m patches along x; the strip is patch 2.
        let mut extents: Vec<Extent> = (0..6).map(|i| at(8.0 * i as f64, 0.0, 1)).collect();
        extents[4] = Extent::EMPTY;
        let of =
            |extents: &[Extent], strip: &[usize]| held(strip, &within_reach(extents, 1.6, 8.0));
        assert_eq!(of(&extents, &[2]), vec![1, 2, 3]);
        // A walker of patch 5 that strays to x = 25 comes within reach of patch 2's box.
        extents[5].lo.x = 25.0;
        assert_eq!(of(&extents, &[2]), vec![1, 2, 3, 5]);
        // Patches 0 and 5 far apart: each with its own neighbours, not what lies between.
        let row: Vec<Extent> = (0..12).map(|i| at(8.0 * i as f64, 0.0, 1)).collect();
        assert_eq!(of(&row, &[0, 9]), vec![0, 1, 8, 9, 10]);
    }
}
