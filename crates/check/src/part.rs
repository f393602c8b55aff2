//! A shard's share of the stage file's check (`crowd build --shard I/N`): what the check that
//! gathers would judge of the shard's own patches, judged where their motion already is and
//! handed on as a memo (`memo.rs`), so that the gathering check takes it by key instead of
//! judging the world alone (the million's stage file: half of its check, on one machine).
//!
//! Nothing here is trusted: a share is found by the hash of exactly what it depends on, as a
//! rebuild's check finds the last check's. A share made from other motion, or the pairs of a
//! patch whose surroundings the shard saw otherwise than the world is (a walker of another
//! shard's patch that strays within reach), has another key, and the gathering check judges
//! that patch itself.

use crate::memo::{Own, StagePart};
use crate::strips::{self, Extent};
use crate::world::Pairs;
use crate::{World, in_order, own_keys, own_share, owned_pairs, pair_keys, walls};
use crowd_core::patch_keys::Table;
use crowd_core::{Cell, Hash, PatchGraph};
use rayon::prelude::*;

/// Pieces a shard's strip holds at most: the whole check's (a shard holds its world's graph and
/// stage 3 beside it). The million's shard 0 (stage 6, one thread, the same memo bytes):
/// strips of 4 million pieces 11.3-12.6 s and 1.01 GB, its other stages at most 0.78 GB; of 2
/// million 13.0-13.7 s and 0.73-0.74 GB; of 1 million 15.5-15.9 s and 0.61 GB.
const PART_STRIP_PIECES: u64 = strips::STRIP_PIECES;

/// The memo the check that gathers may take from one shard: the own share of each of
/// `patches` (in patch order, with `keys` their stage keys, `world.source` giving their motion)
/// and the pairs of each of them whose eight neighbours are all among `patches` (the pairs of
/// the others need motion the shard has not). `tables` are where each patch's crossings are
/// among the world's (`patch_keys::Seen`), when the caller has them; else they are found.
pub fn check_part(
    world: &World,
    tables: Option<&[Table]>,
    patches: &[usize],
    keys: &[Hash],
) -> crowd_core::Result<StagePart> {
    assert_eq!(patches.len(), keys.len(), "a key for every patch");
    let graph = world.graph;
    let n = graph.patches.len();
    // Patches not the shard's are given any key: no share of theirs is made or keyed.
    let mut stage_keys = vec![Hash::of(&[]); n];
    patches
        .iter()
        .zip(keys)
        .for_each(|(&p, k)| stage_keys[p] = *k);
    let own_keys = own_keys(world, &stage_keys);
    // The tables go with the crossings: where each patch's are among the world's.
    let seen;
    let tables = match (tables, world.crossings) {
        (Some(t), _) => Some(t),
        (None, Some(c)) => {
            seen = crowd_core::patch_keys::Seen::new(graph, c);
            Some(&seen.tables[..])
        }
        (None, None) => None,
    };
    let own: Vec<Own> = in_order(patches.par_iter().map(|&p| own_share(world, tables, p)))?;
    let mut extents = vec![Extent::EMPTY; n];
    patches
        .iter()
        .zip(&own)
        .for_each(|(&p, o)| extents[p] = o.extent);
    let whole = surrounded(graph, patches);
    let walls = walls(graph);
    let reach = 2.0 * graph.radius_m + 1.0 + 1e-6;
    let near = strips::within_reach(&extents, reach, graph.world.patch_side_m);
    let pair_keys = pair_keys(graph, &own_keys, (&extents, &near), (&walls, reach));
    // Only the whole patches are judged: the others count as known (and are not handed on).
    let known = whole.iter().map(|&w| (!w).then(Pairs::default)).collect();
    let (pairs, _) = owned_pairs(world, (&extents, &near), &walls, known, PART_STRIP_PIECES)?;
    Ok(StagePart {
        own: patches
            .iter()
            .zip(own)
            .map(|(&p, o)| (*own_keys[p].as_bytes(), o))
            .collect(),
        pairs: (0..n)
            .filter(|&p| whole[p])
            .map(|p| (*pair_keys[p].as_bytes(), pairs[p]))
            .collect(),
    })
}

/// Per patch of the graph, whether it is one of `patches` and so is every patch of the eight
/// cells round it (those painted): its characters can meet no one the shard has not.
fn surrounded(graph: &PatchGraph, patches: &[usize]) -> Vec<bool> {
    let mut mine = vec![false; graph.patches.len()];
    patches.iter().for_each(|&p| mine[p] = true);
    let mut whole = vec![false; graph.patches.len()];
    for &p in patches {
        let c = graph.patches[p].cell;
        whole[p] = (-1i64..=1)
            .flat_map(|dr| (-1i64..=1).map(move |dc| (dc, dr)))
            .all(|(dc, dr)| {
                let (col, row) = (i64::from(c.col) + dc, i64::from(c.row) + dr);
                let cell = u32::try_from(col).ok().zip(u32::try_from(row).ok());
                cell.and_then(|(col, row)| graph.patch_at(Cell { col, row }))
                    .is_none_or(|q| mine[q])
            });
    }
    whole
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::memo::{Memo, Recalled};
    use crate::tests::{content_keys, judged, painted_full, random_motion};
    use crate::{Source, World};
    use crowd_core::trajectories::PatchMotion;
    use std::borrow::Cow;

    /// The motion of one shard's patches, and no other's: a part that asked for another
    /// patch's would fail.
    struct OnlyMine<'a> {
        motion: &'a [PatchMotion],
        mine: std::ops::Range<usize>,
    }

    impl Source for OnlyMine<'_> {
        fn patch(&self, p: usize) -> crowd_core::Result<Cow<'_, PatchMotion>> {
            if !self.mine.contains(&p) {
                let path = std::path::Path::new("shard");
                return Err(crowd_core::Error::stage_file(
                    path,
                    format!("patch {p} asked"),
                ));
            }
            Ok(Cow::Borrowed(&self.motion[p]))
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(6))]

        /// Shards that each judge their own patches, their memos read back from their bytes and
        /// taken in together, leave the check that gathers only the pairs along the shards'
        /// edges to judge, and it gives the figures of a whole check to the bit.
        #[test]
        fn shards_shares_give_the_figures_of_a_whole_check(
            seed in proptest::prelude::any::<u64>(),
            shards in 1usize..6,
        ) {
            let graph = painted_full(12, 12, 1440);
            let motion = random_motion(&graph, seed);
            let keys = content_keys(&motion);
            let n = graph.patches.len();
            let mut memo = Recalled::default();
            let mut edges = 0;
            for s in 0..shards {
                let mine = n * s / shards..n * (s + 1) / shards;
                let source = OnlyMine { motion: &motion, mine: mine.clone() };
                let world = World { graph: &graph, source: &source, period_s: 20.0, crossings: Some((&[][..]).into()) };
                let patches: Vec<usize> = mine.clone().collect();
                let part = check_part(&world, None, &patches, &keys[mine]).unwrap();
                edges += patches.len() - part.pairs.len();
                let bytes = Memo::of(Some(part), None).to_bytes();
                memo.add(Memo::from_bytes(&bytes).unwrap());
            }
            let none = Recalled::default();
            let whole = judged(&graph, &motion, None, &none, u64::MAX);
            let gathered = judged(&graph, &motion, Some(&keys), &memo, 300);
            proptest::prop_assert_eq!(&gathered.report, &whole.report);
            proptest::prop_assert_eq!(gathered.redone.0, 0, "every own share taken");
            // The shards' edges (a row either side of each cut) and no more are judged again.
            proptest::prop_assert_eq!(gathered.redone.1, edges);
            proptest::prop_assert!(edges <= 36 * (shards - 1), "{} edge patches", edges);
        }
    }

    #[test]
    fn a_patch_is_whole_when_the_shard_holds_its_eight_neighbours() {
        let graph = painted_full(4, 3, 120);
        // Patches run row by row: the first seven are row 0 and three of row 1.
        let whole = surrounded(&graph, &(0..7).collect::<Vec<_>>());
        let said: Vec<usize> = (0..12).filter(|&p| whole[p]).collect();
        // Row 0's first two: their neighbours are of rows 0 and 1, cols 0-2, all held.
        assert_eq!(said, vec![0, 1]);
        assert!(
            surrounded(&graph, &(0..12).collect::<Vec<_>>())
                .iter()
                .all(|&w| w)
        );
    }
}
