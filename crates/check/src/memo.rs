//! What a check keeps of each patch between builds, so that a rebuild after a brush stroke
//! judges only the patches the stroke reached and takes the rest from the last check.
//!
//! Every figure the check adds up is a sum of integers, a count, or a minimum or maximum under a
//! total order (`motion::Tally`, `world::Pairs`), so a patch's share adds up to the same bytes
//! whichever patches were judged again. A share is found by the hash of exactly what it depends
//! on ([`Keys`]): a patch's own figures by its key (the stage's patch key, which pins its motion
//! and its crossings, or the library's bytes of it), and the pairs it owns by its key and those
//! of every patch within reach of it, with the obstacles there.
//!
//! A cache, not a stage file: a missing, damaged or foreign memo is only work done again.

use crate::motion::PatchTally;
use crate::strips::Extent;
use crate::world::Pairs;
use crowd_core::Hash;
use crowd_geometry::BoxGrid;
use glam::DVec2;
use std::collections::HashMap;

/// One patch's own share: where its characters go, how many walk, and its motion tally (when
/// the check had the patterns).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct Own {
    pub extent: Extent,
    pub walkers: u64,
    pub tally: Option<PatchTally>,
}

/// What a check remembers: each patch's own share and the pairs it owns, for the stage file
/// and for the library, by their keys. Written in patch order (the same bytes for the same
/// world), looked up by key.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct Memo {
    version: u32,
    own: Vec<([u8; 32], Own)>,
    pairs: Vec<([u8; 32], Pairs)>,
    library_pairs: Vec<([u8; 32], Pairs)>,
}

/// A [`Memo`] read for lookups.
#[derive(Default)]
pub struct Recalled {
    own: HashMap<[u8; 32], Own>,
    pairs: HashMap<[u8; 32], Pairs>,
    library_pairs: HashMap<[u8; 32], Pairs>,
}

impl Memo {
    /// The memo as its file holds it (CBOR); `None` when the bytes are not a memo of this
    /// version.
    pub fn from_bytes(bytes: &[u8]) -> Option<Memo> {
        let memo: Memo = ciborium::from_reader(bytes).ok()?;
        (memo.version == crate::VERSION).then_some(memo)
    }

    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        ciborium::into_writer(self, &mut out).expect("a memo always encodes");
        out
    }

    /// For lookups by key.
    pub fn recall(self) -> Recalled {
        Recalled {
            own: self.own.into_iter().collect(),
            pairs: self.pairs.into_iter().collect(),
            library_pairs: self.library_pairs.into_iter().collect(),
        }
    }

    /// The memo of one check: the stage file's part and the library's (what a check did not
    /// judge, a later one judges whole).
    pub fn of(stage: Option<StagePart>, library: Option<LibraryPart>) -> Memo {
        let stage = stage.unwrap_or_default();
        Memo {
            version: crate::VERSION,
            own: stage.own,
            pairs: stage.pairs,
            library_pairs: library.map_or_else(Vec::new, |l| l.0),
        }
    }

    /// Patches remembered: own shares, owned pairs, the library's owned pairs.
    pub fn sizes(&self) -> (usize, usize, usize) {
        (self.own.len(), self.pairs.len(), self.library_pairs.len())
    }
}

impl Recalled {
    pub(crate) fn own(&self, key: &Hash) -> Option<&Own> {
        self.own.get(key.as_bytes())
    }

    pub(crate) fn pairs(&self, key: &Hash) -> Option<Pairs> {
        self.pairs.get(key.as_bytes()).copied()
    }

    pub(crate) fn library_pairs(&self, key: &Hash) -> Option<Pairs> {
        self.library_pairs.get(key.as_bytes()).copied()
    }
}

/// The stage file's part of a memo.
#[derive(Default)]
pub struct StagePart {
    pub(crate) own: Vec<([u8; 32], Own)>,
    pub(crate) pairs: Vec<([u8; 32], Pairs)>,
}

/// The library's part of a memo: each patch's pairs by their key.
#[derive(Default)]
pub struct LibraryPart(pub(crate) Vec<([u8; 32], Pairs)>);

/// Per patch, the patches whose characters come within `reach` of its own (itself included,
/// in index order), from their extents.
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

/// The key of the pairs patch `p` owns: its own key and those of the patches within reach,
/// and the obstacles within reach of it.
pub(crate) fn pairs_key(
    label: &str,
    (own, p): (&[Hash], usize),
    near: &[u32],
    extent: &Extent,
    (walls, wall_grid, reach): (&[crate::Wall], &BoxGrid, f64),
) -> Hash {
    let mut h = crowd_core::Hasher::new(label, crate::VERSION);
    h.part("own", own[p].as_bytes());
    for &q in near {
        h.part("near", own[q as usize].as_bytes());
    }
    if !extent.is_empty() {
        let mut found = Vec::new();
        wall_grid.near(extent.lo, extent.hi, |w| found.push(w));
        found.sort_unstable();
        for w in found {
            let (lo, hi) = walls[w as usize];
            if (lo - extent.hi).max(extent.lo - hi).max_element() <= reach {
                let bits = [lo.x, lo.y, hi.x, hi.y].map(f64::to_bits);
                h.part("wall", &bytes_of(&bits));
            }
        }
    }
    h.finish()
}

/// `values` as little-endian bytes, for a hash.
pub(crate) fn bytes_of(values: &[u64]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}
