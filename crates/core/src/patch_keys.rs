//! Per-patch reuse between builds (stages 4-6): each patch's work is keyed by the hash of
//! exactly what it depends on, and a rebuild takes every patch whose key is unchanged from the
//! last build's stage file instead of computing it again.
//!
//! A stage writes `STAGE.keys` beside its file: per patch, its key, where its crossings were in
//! the patterns then ([`Table`]) and the stage's own per-patch figures (`extra`), with the hash
//! of the side file they belong to. Trajectories name their crossings by their index in the
//! whole world's patterns, which a change elsewhere shifts; so a reused patch's motion is read
//! in the old numbering and written in the new one ([`Table::renumber`]), through its place
//! among its own borders' crossings, which its key holds fixed.
//!
//! A cache, not a stage file: a missing, damaged or foreign keys file, or one whose side file
//! changed, is only a missed reuse.

use crate::Hash;
use crate::patch_graph::PatchGraph;
use crate::patterns::{Crossing, Crossings};
use crate::trajectories::PatchMotion;

/// Where one patch's crossings are in the world's patterns: per border of the patch (in the
/// order of the borders' indices), the index of its first crossing and how many it has.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Table(pub Vec<(u32, u32)>);

impl Table {
    /// The patch's own number of a world crossing index (its place among its crossings).
    pub fn local(&self, global: u32) -> u32 {
        let mut before = 0;
        for &(start, count) in &self.0 {
            if (start..start + count).contains(&global) {
                return before + global - start;
            }
            before += count;
        }
        // Not one of the patch's crossings: kept apart from every local number.
        u32::MAX - global
    }

    /// The world crossing index of the patch's own number `local` (the inverse of
    /// [`Table::local`]).
    pub fn global(&self, mut local: u32) -> u32 {
        for &(start, count) in &self.0 {
            if local < count {
                return start + local;
            }
            local -= count;
        }
        u32::MAX - local
    }

    /// `motion` numbered by `self` (the old patterns), numbered by `to` (the new ones).
    pub fn renumber(&self, to: &Table, mut motion: PatchMotion) -> PatchMotion {
        for t in &mut motion.trajectories {
            t.entry = to.global(self.local(t.entry));
            t.exit = to.global(self.local(t.exit));
        }
        motion
    }
}

/// A patch's motion in its own numbering of its crossings, encoded: what a later stage's key
/// hashes of it (the same bytes whatever a change elsewhere did to the world's numbering).
pub fn local_bytes(table: &Table, motion: &PatchMotion) -> Vec<u8> {
    let local = table.renumber(&Table::default(), motion.clone());
    crate::trajectories::encode_motion(&[local])
}

/// The patches sharing a border with `p` (west, east, south, north; `None` where none is
/// kept).
pub fn neighbours(graph: &PatchGraph, p: usize) -> [Option<usize>; 4] {
    let c = graph.patches[p].cell;
    [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)].map(|(dc, dr)| {
        let (col, row) = (i64::from(c.col) + dc, i64::from(c.row) + dr);
        match (u32::try_from(col), u32::try_from(row)) {
            (Ok(col), Ok(row)) => graph.patch_at(crate::Cell { col, row }),
            _ => None,
        }
    })
}

/// A world's patches, borders and crossings as keys see them: every patch's borders and
/// [`Table`], found once.
pub struct Seen<'a> {
    pub graph: &'a PatchGraph,
    pub crossings: Crossings<'a>,
    borders: Vec<Vec<u32>>,
    pub tables: Vec<Table>,
}

impl<'a> Seen<'a> {
    /// `crossings` sorted by border, as stage 3 writes them. A border whose crossings are not
    /// held (outside a shard's window) has a place no crossing is at: a patch's table that
    /// names it panics when read.
    pub fn new(graph: &'a PatchGraph, crossings: impl Into<Crossings<'a>>) -> Seen<'a> {
        let crossings = crossings.into();
        let first = crossings.numbers().start;
        let mut starts: Vec<(u32, u32)> = (0..graph.borders.len() as u32)
            .map(|b| match crossings.holds_border(b) {
                true => (first, 0),
                false => (u32::MAX, 0),
            })
            .collect();
        for (i, c) in crossings.indexed() {
            let s = &mut starts[c.border as usize];
            if s.1 == 0 {
                s.0 = i;
            }
            s.1 += 1;
        }
        let mut borders: Vec<Vec<u32>> = vec![Vec::new(); graph.patches.len()];
        for (k, b) in graph.borders.iter().enumerate() {
            borders[b.a.0 as usize].push(k as u32);
            borders[b.b.0 as usize].push(k as u32);
        }
        for list in &mut borders {
            list.sort_unstable();
        }
        let tables = borders
            .iter()
            .map(|list| Table(list.iter().map(|&k| starts[k as usize]).collect()))
            .collect();
        Seen {
            graph,
            crossings,
            borders,
            tables,
        }
    }

    /// What of the world patch `p`'s work sees, without the numbers a change elsewhere shifts
    /// (patch ids, components, border and crossing indices): the patches around it (their
    /// place, densities, direction and obstacles), its borders (their ends and open intervals)
    /// and its crossings, each named by its place among the patch's borders. Keys hash this.
    pub fn surroundings(&self, p: usize) -> Surroundings {
        let graph = self.graph;
        let patches = around(graph, p)
            .into_iter()
            .map(|q| {
                q.map(|q| SeenPatch {
                    cell: q.cell,
                    walker_density: q.walker_density,
                    stander_density: q.stander_density,
                    direction: q.direction,
                    obstacle_coverage: q.obstacle_coverage,
                    obstacles: q.obstacles.clone(),
                })
            })
            .collect();
        let borders = self.borders[p]
            .iter()
            .map(|&k| {
                let b = &graph.borders[k as usize];
                (
                    graph.patch(b.a).cell,
                    graph.patch(b.b).cell,
                    b.axis,
                    b.open.clone(),
                )
            })
            .collect();
        let mut crossings = Vec::new();
        for (slot, &(start, count)) in self.tables[p].0.iter().enumerate() {
            for c in self.crossings.run(start as usize..(start + count) as usize) {
                crossings.push((slot, c.way, c.s, c.t, c.velocity));
            }
        }
        Surroundings {
            patches,
            borders,
            crossings,
        }
    }
}

/// The crossings of a patch's borders, in its own order: what a key hashes of the patterns.
pub fn crossings_of<'a>(table: &Table, crossings: impl Into<Crossings<'a>>) -> Vec<&'a Crossing> {
    let crossings = crossings.into();
    table
        .0
        .iter()
        .flat_map(|&(start, count)| crossings.run(start as usize..(start + count) as usize))
        .collect()
}

/// The patches around a cell (3 x 3, row by row from the south-west; `None` where none is
/// kept): a patch's geometry reaches into its neighbours' (their obstacles near the border).
pub fn around(graph: &PatchGraph, p: usize) -> Vec<Option<&crate::Patch>> {
    let c = graph.patches[p].cell;
    let mut out = Vec::with_capacity(9);
    for dr in -1i64..=1 {
        for dc in -1i64..=1 {
            let (col, row) = (i64::from(c.col) + dc, i64::from(c.row) + dr);
            let found = match (u32::try_from(col), u32::try_from(row)) {
                (Ok(col), Ok(row)) => graph
                    .patch_at(crate::Cell { col, row })
                    .map(|q| &graph.patches[q]),
                _ => None,
            };
            out.push(found);
        }
    }
    out
}

/// A patch as its neighbours' work sees it.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SeenPatch {
    pub cell: crate::Cell,
    pub walker_density: f64,
    pub stander_density: f64,
    pub direction: Option<crate::patch_graph::RequestedDirection>,
    pub obstacle_coverage: f64,
    pub obstacles: Vec<crate::patch_graph::Rect>,
}

/// See [`surroundings`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Surroundings {
    pub patches: Vec<Option<SeenPatch>>,
    #[allow(clippy::type_complexity)]
    pub borders: Vec<(
        crate::Cell,
        crate::Cell,
        crate::patch_graph::BorderAxis,
        Vec<crate::Interval>,
    )>,
    pub crossings: Vec<(usize, crate::patterns::Way, f64, f64, glam::DVec2)>,
}

/// One patch's record in a keys file.
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    pub key: Hash,
    pub table: Table,
    /// The stage's own per-patch figures, as it encodes them.
    pub extra: Vec<u8>,
}

/// A stage's keys file: the hash of the side file the records belong to, and a record per
/// patch in patch order.
#[derive(Debug, Clone, PartialEq)]
pub struct Keys {
    pub side: Hash,
    pub patches: Vec<Record>,
}

const MAGIC: &[u8; 8] = b"CRWDKEY1";

impl Keys {
    pub fn encode(&self) -> Vec<u8> {
        let mut out = MAGIC.to_vec();
        let u32s = |out: &mut Vec<u8>, v: u32| out.extend_from_slice(&v.to_le_bytes());
        out.extend_from_slice(self.side.as_bytes());
        u32s(&mut out, self.patches.len() as u32);
        for r in &self.patches {
            out.extend_from_slice(r.key.as_bytes());
            u32s(&mut out, r.table.0.len() as u32);
            for &(start, count) in &r.table.0 {
                u32s(&mut out, start);
                u32s(&mut out, count);
            }
            u32s(&mut out, r.extra.len() as u32);
            out.extend_from_slice(&r.extra);
        }
        out
    }

    /// The keys in `bytes`, or `None` if they are not a whole keys file.
    pub fn decode(bytes: &[u8]) -> Option<Keys> {
        let mut rest = bytes;
        let mut take = |n: usize| -> Option<&[u8]> {
            let (head, tail) = rest.split_at_checked(n)?;
            rest = tail;
            Some(head)
        };
        if take(8)? != MAGIC {
            return None;
        }
        let hash = |b: &[u8]| Some(Hash::from_bytes(b.try_into().ok()?));
        let side = hash(take(32)?)?;
        let u32_of = |b: &[u8]| Some(u32::from_le_bytes(b.try_into().ok()?));
        let count = u32_of(take(4)?)?;
        let mut patches = Vec::new();
        for _ in 0..count {
            let key = hash(take(32)?)?;
            let borders = u32_of(take(4)?)?;
            let mut table = Vec::new();
            for _ in 0..borders.min(8) {
                table.push((u32_of(take(4)?)?, u32_of(take(4)?)?));
            }
            if borders > 8 {
                return None;
            }
            let len = u32_of(take(4)?)? as usize;
            let extra = take(len)?.to_vec();
            patches.push(Record {
                key,
                table: Table(table),
                extra,
            });
        }
        rest.is_empty().then_some(Keys { side, patches })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trajectories::Trajectory;

    #[test]
    fn a_patch_renumbered_keeps_its_place_among_its_crossings() {
        // Borders with crossings 10..13 and 40..42, which become 7..10 and 52..54.
        let (old, new) = (Table(vec![(10, 3), (40, 2)]), Table(vec![(7, 3), (52, 2)]));
        let motion = PatchMotion {
            standers: Vec::new(),
            trajectories: vec![Trajectory {
                entry: 12,
                exit: 41,
                points: Vec::new(),
            }],
        };
        let moved = old.renumber(&new, motion);
        assert_eq!(
            (moved.trajectories[0].entry, moved.trajectories[0].exit),
            (9, 53)
        );
    }

    #[test]
    fn keys_round_trip_and_a_cut_file_is_no_cache() {
        let keys = Keys {
            side: Hash::of(b"side"),
            patches: vec![Record {
                key: Hash::of(b"patch"),
                table: Table(vec![(1, 2), (5, 0)]),
                extra: b"(iterations: 3)".to_vec(),
            }],
        };
        let bytes = keys.encode();
        assert_eq!(Keys::decode(&bytes), Some(keys));
        assert_eq!(Keys::decode(&bytes[..bytes.len() - 1]), None);
        assert_eq!(Keys::decode(b"CRWDKEY1"), None);
    }
}
