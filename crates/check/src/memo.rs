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
//! A cache, not a stage file: a missing, damaged or foreign memo is only work done again (it
//! ends with the hash of its bytes, so a damaged figure is never taken for a judged one).
//!
//! Written by hand as little-endian numbers ([`Bytes`], [`Reader`]): through `ciborium`, the
//! 47 MB memo of painting took 0.9 s to read and 0.3 s to write, a third of a rebuild's check;
//! read field by field it takes a twentieth of that.

use crate::library::Played;
use crate::motion::PackedTally;
use crate::strips::Extent;
use crate::world::Pairs;
use crowd_core::Hash;
use crowd_geometry::BoxGrid;
use glam::DVec2;
use std::collections::HashMap;

/// One patch's own share: where its characters go, how many walk, and its motion tally (when
/// the check had the patterns).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Own {
    pub extent: Extent,
    pub walkers: u64,
    pub tally: Option<PackedTally>,
}

/// What a check remembers: each patch's own share and the pairs it owns, for the stage file
/// and for the library, by their keys. Written in patch order (the same bytes for the same
/// world), looked up by key.
#[derive(Debug, Clone, Default)]
pub struct Memo {
    own: Vec<([u8; 32], Own)>,
    pairs: Vec<([u8; 32], Pairs)>,
    library_pairs: Vec<([u8; 32], Pairs)>,
    played: Vec<([u8; 32], Played)>,
}

/// A [`Memo`] read for lookups.
#[derive(Default)]
pub struct Recalled {
    /// Taken out as they are looked up ([`Recalled::take_own`]).
    own: std::sync::Mutex<HashMap<[u8; 32], Own>>,
    pairs: HashMap<[u8; 32], Pairs>,
    library_pairs: HashMap<[u8; 32], Pairs>,
    played: HashMap<[u8; 32], Played>,
    /// Memos taken in besides the one recalled (`add`).
    added: usize,
}

impl Memo {
    /// The memo as its file holds it; `None` when the bytes are not a whole memo of this
    /// version.
    pub fn from_bytes(bytes: &[u8]) -> Option<Memo> {
        // The body, then its hash: a damaged figure would otherwise be read as a judged one.
        let body = bytes.len().checked_sub(32).map(|n| &bytes[..n])?;
        if Hash::of(body).as_bytes()[..] != bytes[body.len()..] {
            return None;
        }
        let mut r = Reader(body);
        if r.take(MAGIC.len())? != MAGIC || r.u32()? != crate::VERSION {
            return None;
        }
        let own = r.keyed()?;
        let pairs = r.keyed()?;
        let library_pairs = r.keyed()?;
        let played = r.keyed()?;
        r.0.is_empty().then_some(Memo {
            own,
            pairs,
            library_pairs,
            played,
        })
    }

    pub fn to_bytes(&self) -> Vec<u8> {
        let mut bytes = Vec::new();
        self.write_to(&mut bytes).expect("writing to memory");
        bytes
    }

    /// [`Memo::to_bytes`] written to `out` a piece at a time, hashed as it goes: the million's
    /// memo is 0.3 GB, which the check held whole (grown by doubling) beside the memo itself,
    /// at its peak.
    pub fn write_to<W: std::io::Write + ?Sized>(&self, out: &mut W) -> std::io::Result<()> {
        MemoWriter::begin(out, (&self.own, &self.pairs))?
            .end((&self.library_pairs, &self.played))
            .map(drop)
    }

    /// For lookups by key.
    pub fn recall(self) -> Recalled {
        Recalled {
            own: std::sync::Mutex::new(self.own.into_iter().collect()),
            pairs: self.pairs.into_iter().collect(),
            library_pairs: self.library_pairs.into_iter().collect(),
            played: self.played.into_iter().collect(),
            added: 0,
        }
    }

    /// The memo of one check: the stage file's part and the library's (what a check did not
    /// judge, a later one judges whole).
    pub fn of(stage: Option<StagePart>, library: Option<LibraryPart>) -> Memo {
        let stage = stage.unwrap_or_default();
        let library = library.unwrap_or_default();
        Memo {
            own: stage.own,
            pairs: stage.pairs,
            library_pairs: library.pairs,
            played: library.played,
        }
    }
}

impl Recalled {
    /// Takes in `more`'s shares too (a shard's part of a check, `part.rs`): keys are content
    /// hashes, so two memos that hold one key hold one share for it.
    pub fn add(&mut self, more: Memo) {
        self.added += 1;
        self.own_map().extend(more.own);
        self.pairs.extend(more.pairs);
        self.library_pairs.extend(more.library_pairs);
        self.played.extend(more.played);
    }

    /// How many memos [`Recalled::add`] took in.
    pub fn parts_taken(&self) -> usize {
        self.added
    }

    /// Lets the stage file's shares go (once it is judged, the library's are all a check
    /// looks up).
    pub fn forget_stage(&mut self) {
        *self.own_map() = HashMap::new();
        self.pairs = HashMap::new();
    }

    /// The own share of `key`, taken out: the check that looks it up keeps it in its new memo,
    /// and a copy left here doubled the million's 0.2 GB of shares while the stage file was
    /// judged. A key is looked up once (it pins its patch's place); asked again, it is judged
    /// again.
    pub(crate) fn take_own(&self, key: &Hash) -> Option<Own> {
        self.own_map().remove(key.as_bytes())
    }

    fn own_map(&self) -> std::sync::MutexGuard<'_, HashMap<[u8; 32], Own>> {
        self.own
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    pub(crate) fn pairs(&self, key: &Hash) -> Option<Pairs> {
        self.pairs.get(key.as_bytes()).copied()
    }

    pub(crate) fn library_pairs(&self, key: &Hash) -> Option<Pairs> {
        self.library_pairs.get(key.as_bytes()).copied()
    }

    pub(crate) fn played(&self, key: &[u8; 32]) -> Option<Played> {
        self.played.get(key).copied()
    }
}

/// The stage file's part of a memo.
#[derive(Default)]
pub struct StagePart {
    pub(crate) own: Vec<([u8; 32], Own)>,
    pub(crate) pairs: Vec<([u8; 32], Pairs)>,
}

impl StagePart {
    /// How many patches' pairs it holds.
    pub fn judged_pairs(&self) -> usize {
        self.pairs.len()
    }
}

/// The pairs each patch owns, by key, as a check of a stage file judged them: the end of a
/// memo's stage part ([`StageWriter::pairs`]).
#[derive(Default)]
pub struct OwnedPairs(pub(crate) Vec<([u8; 32], Pairs)>);

/// The library's part of a memo: each patch's pairs by their key, and each walker's share of
/// the sampler's figures by its window's key.
#[derive(Default)]
pub struct LibraryPart {
    pub(crate) pairs: Vec<([u8; 32], Pairs)>,
    pub(crate) played: Vec<([u8; 32], Played)>,
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

/// The memo's format: a memo of another one is not read (its patches are judged again).
const MAGIC: &[u8; 8] = b"CRWDMEM2";

/// A memo being written: little-endian numbers.
pub(crate) struct Bytes(pub Vec<u8>);

impl Bytes {
    pub fn u8(&mut self, v: u8) {
        self.0.push(v);
    }
    pub fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    pub fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    pub fn f64(&mut self, v: f64) {
        self.u64(v.to_bits());
    }
    pub fn vec2(&mut self, v: DVec2) {
        self.f64(v.x);
        self.f64(v.y);
    }
    /// `v` in LEB128: seven bits a byte, the lowest first, the top bit set on all but the last.
    pub fn varint(&mut self, mut v: u64) {
        while v >= 0x80 {
            self.0.push(v as u8 | 0x80);
            v >>= 7;
        }
        self.0.push(v as u8);
    }
    /// `bytes`, after their count.
    pub fn blob(&mut self, bytes: &[u8]) {
        self.u64(bytes.len() as u64);
        self.0.extend_from_slice(bytes);
    }
    /// `v`, after whether there is one.
    pub fn option<T>(&mut self, v: &Option<T>, put: impl FnOnce(&mut Bytes, &T)) {
        self.u8(u8::from(v.is_some()));
        if let Some(v) = v {
            put(self, v);
        }
    }
}

/// A memo written as a check goes, in its file's order: the stage file's part
/// ([`StageWriter`]), then the library's. A large world's check ends the stage file's part
/// before it judges the library.
pub struct MemoWriter<W: std::io::Write>(Sink<W>);

impl<W: std::io::Write> MemoWriter<W> {
    /// Ends the memo with the library's part (`None`: the check judged no library), and its
    /// hash; `out` is handed back.
    pub fn finish(self, library: Option<&LibraryPart>) -> std::io::Result<W> {
        match library {
            Some(l) => self.end((&l.pairs, &l.played)),
            None => self.end((&[], &[])),
        }
    }

    fn begin(out: W, (own, pairs): StageLists) -> std::io::Result<MemoWriter<W>> {
        let mut stage = StageWriter::start(out, own.len());
        for (key, o) in own {
            stage.own(key, o);
        }
        stage.pairs_of(pairs)
    }

    fn end(self, (pairs, played): LibraryLists) -> std::io::Result<W> {
        let mut sink = self.0;
        sink.keyed(pairs)?;
        sink.keyed(played)?;
        sink.spill()?;
        let (_, hash) = sink.hash.finish();
        sink.out.write_all(hash.as_bytes())?;
        Ok(sink.out)
    }
}

/// A memo begun with the stage file's own shares, written as a check takes them, one patch
/// after another in patch order: the million's 0.2 GB of shares were held until its pairs were
/// judged, at the gathering check's peak. Then its pairs ([`StageWriter::pairs`]) and the
/// library's part ([`MemoWriter::finish`]).
pub struct StageWriter<W: std::io::Write> {
    sink: Sink<W>,
    /// Shares still to come (the count is written first).
    left: usize,
    /// The first failure to write, reported by [`StageWriter::pairs`].
    failed: Option<std::io::Error>,
}

impl<W: std::io::Write> StageWriter<W> {
    /// Starts the memo in `out`, for the own shares of `own` patches.
    pub fn start(out: W, own: usize) -> StageWriter<W> {
        let mut sink = Sink {
            buf: Bytes(Vec::with_capacity(SINK_BYTES)),
            hash: Hash::pieces(),
            out,
        };
        sink.buf.0.extend_from_slice(MAGIC);
        sink.buf.u32(crate::VERSION);
        sink.buf.u64(own as u64);
        StageWriter {
            sink,
            left: own,
            failed: None,
        }
    }

    /// How many own shares are still to come.
    pub fn own_left(&self) -> usize {
        self.left
    }

    /// The next patch's own share, by its key. A failure to write is kept for
    /// [`StageWriter::pairs`].
    pub(crate) fn own(&mut self, key: &[u8; 32], own: &Own) {
        assert!(
            self.left > 0,
            "no more own shares than the memo was begun for"
        );
        self.left -= 1;
        if self.failed.is_none()
            && let Err(e) = self.sink.record(key, own)
        {
            self.failed = Some(e);
        }
    }

    /// The stage file's part ended with the pairs each patch owns, by key; refused if a write
    /// failed, or if shares are missing (the memo would not read back).
    pub fn pairs(self, pairs: &OwnedPairs) -> std::io::Result<MemoWriter<W>> {
        self.pairs_of(&pairs.0)
    }

    fn pairs_of(mut self, pairs: &[([u8; 32], Pairs)]) -> std::io::Result<MemoWriter<W>> {
        if let Some(e) = self.failed {
            return Err(e);
        }
        if self.left > 0 {
            let message = format!("{} own shares missing from the memo", self.left);
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                message,
            ));
        }
        self.sink.keyed(pairs)?;
        Ok(MemoWriter(self.sink))
    }
}

/// The stage file's lists of a memo: own shares and pairs, by key.
type StageLists<'a> = (&'a [([u8; 32], Own)], &'a [([u8; 32], Pairs)]);
/// The library's lists of a memo: pairs and played walkers, by key.
type LibraryLists<'a> = (&'a [([u8; 32], Pairs)], &'a [([u8; 32], Played)]);

/// Where [`MemoWriter`] puts its bytes: a buffer handed on (and hashed) each time it holds
/// [`SINK_BYTES`].
struct Sink<W: std::io::Write> {
    buf: Bytes,
    hash: crowd_core::hash::Pieces,
    out: W,
}

/// Bytes [`Sink`] holds before it hands them on.
const SINK_BYTES: usize = 1 << 20;

impl<W: std::io::Write> Sink<W> {
    /// `items` (records by key), after their count, handed on a buffer at a time.
    fn keyed<T: Record>(&mut self, items: &[([u8; 32], T)]) -> std::io::Result<()> {
        self.buf.u64(items.len() as u64);
        for (key, item) in items {
            self.record(key, item)?;
        }
        Ok(())
    }

    /// One record of a list, after its key.
    fn record<T: Record>(&mut self, key: &[u8; 32], item: &T) -> std::io::Result<()> {
        self.buf.0.extend_from_slice(key);
        item.put(&mut self.buf);
        if self.buf.0.len() >= SINK_BYTES {
            self.spill()?;
        }
        Ok(())
    }

    fn spill(&mut self) -> std::io::Result<()> {
        self.hash.update(&self.buf.0);
        self.out.write_all(&self.buf.0)?;
        self.buf.0.clear();
        Ok(())
    }
}

/// A memo being read: every read is `None` past the end.
pub(crate) struct Reader<'a>(pub &'a [u8]);

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        if n > self.0.len() {
            return None;
        }
        let (head, rest) = self.0.split_at(n);
        self.0 = rest;
        Some(head)
    }
    pub fn u8(&mut self) -> Option<u8> {
        Some(self.take(1)?[0])
    }
    pub fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }
    pub fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
    pub fn f64(&mut self) -> Option<f64> {
        Some(f64::from_bits(self.u64()?))
    }
    pub fn vec2(&mut self) -> Option<DVec2> {
        Some(DVec2::new(self.f64()?, self.f64()?))
    }
    /// A number written by [`Bytes::varint`] (`None` past 64 bits).
    pub fn varint(&mut self) -> Option<u64> {
        let mut v = 0u64;
        for shift in (0..64).step_by(7) {
            let b = self.u8()?;
            v |= u64::from(b & 0x7f).checked_shl(shift)?;
            if b & 0x80 == 0 {
                return (shift < 63 || b <= 1).then_some(v);
            }
        }
        None
    }
    /// Bytes written by [`Bytes::blob`].
    pub fn blob(&mut self) -> Option<&'a [u8]> {
        let n = usize::try_from(self.u64()?).ok()?;
        self.take(n)
    }
    fn key(&mut self) -> Option<[u8; 32]> {
        self.take(32)?.try_into().ok()
    }
    /// A list, its count first (the count checked against what is left, so a damaged
    /// count allocates nothing).
    pub fn list<T>(&mut self, mut get: impl FnMut(&mut Reader<'a>) -> Option<T>) -> Option<Vec<T>> {
        let n = usize::try_from(self.u64()?).ok()?;
        if n > self.0.len() {
            return None;
        }
        (0..n).map(|_| get(self)).collect()
    }
    /// Records by key, as [`Sink::keyed`] wrote them.
    fn keyed<T: Record>(&mut self) -> Option<Vec<([u8; 32], T)>> {
        self.list(|r| Some((r.key()?, T::get(r)?)))
    }
    /// An option written by [`Bytes::option`].
    pub fn option<T>(
        &mut self,
        get: impl FnOnce(&mut Reader<'a>) -> Option<T>,
    ) -> Option<Option<T>> {
        match self.u8()? {
            0 => Some(None),
            1 => get(self).map(Some),
            _ => None,
        }
    }
}

/// A memo's record kept by key: an own share, a patch's pairs, a walker's play.
trait Record: Sized {
    fn put(&self, o: &mut Bytes);
    fn get(r: &mut Reader) -> Option<Self>;
}

impl Record for Own {
    fn put(&self, o: &mut Bytes) {
        self.extent.put(o);
        o.u64(self.walkers);
        o.option(&self.tally, |o, t| t.put(o));
    }

    fn get(r: &mut Reader) -> Option<Own> {
        Some(Own {
            extent: Extent::get(r)?,
            walkers: r.u64()?,
            tally: r.option(PackedTally::get)?,
        })
    }
}

impl Record for crate::world::Pairs {
    fn put(&self, o: &mut Bytes) {
        crate::world::Pairs::put(self, o);
    }

    fn get(r: &mut Reader) -> Option<Self> {
        crate::world::Pairs::get(r)
    }
}

impl Extent {
    fn put(&self, o: &mut Bytes) {
        o.vec2(self.lo);
        o.vec2(self.hi);
        o.u64(self.pieces);
    }

    fn get(r: &mut Reader) -> Option<Extent> {
        Some(Extent {
            lo: r.vec2()?,
            hi: r.vec2()?,
            pieces: r.u64()?,
        })
    }
}

impl Record for Played {
    fn put(&self, o: &mut Bytes) {
        o.f64(self.max_step2);
        o.f64(self.max_turn);
        o.u64(self.jumps);
    }

    fn get(r: &mut Reader) -> Option<Played> {
        Some(Played {
            max_step2: r.f64()?,
            max_turn: r.f64()?,
            jumps: r.u64()?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A memo of several megabytes written a buffer at a time reads back whole: the hash at
    /// its end is of every byte before it, however the writing was cut.
    #[test]
    fn a_memo_written_a_piece_at_a_time_reads_back_as_it_was() {
        let played: Vec<([u8; 32], Played)> = (0..100_000u32)
            .map(|i| {
                let mut key = [0u8; 32];
                key[..4].copy_from_slice(&i.to_le_bytes());
                let share = Played {
                    max_step2: f64::from(i) * 0.25,
                    max_turn: f64::from(i % 7),
                    jumps: u64::from(i % 3),
                };
                (key, share)
            })
            .collect();
        let memo = Memo {
            played: played.clone(),
            ..Memo::default()
        };
        let mut written = Vec::new();
        memo.write_to(&mut written).expect("writing to memory");
        assert!(written.len() > 4 * SINK_BYTES, "{} bytes", written.len());
        let read = Memo::from_bytes(&written).expect("the memo reads back");
        assert_eq!(read.played, played);
        assert!(read.own.is_empty() && read.pairs.is_empty() && read.library_pairs.is_empty());
        // One byte changed anywhere, and the memo is not read.
        written[SINK_BYTES + 17] ^= 1;
        assert!(Memo::from_bytes(&written).is_none());
    }
}
