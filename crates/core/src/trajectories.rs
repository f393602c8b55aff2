//! Stage 4's output (and later stages'): per patch, standing characters and space-time
//! trajectories from an entry crossing to an exit crossing.

use crate::error::{Error, Result};
use crate::files::{Header, SideFile};
use glam::DVec2;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::Path;

mod encoded;
pub use encoded::{PatchSums, renumber_encoded, sums_of_encoded};

/// What a control point is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum PointKind {
    /// On the border where the character enters: fixed by the patterns.
    Entry,
    /// On the border where the character leaves: fixed by the patterns.
    Exit,
    /// Where the trajectory passes a multiple of the period (it wraps around in time).
    Split,
    /// Start or end of a pause (two points at the same place, different times).
    Pause,
    /// A turn towards the patch centre (entry and exit on the same border).
    Turn,
    /// A bend that keeps the walker clear of others (added by the collide stage).
    Bend,
    /// A corner of the way round a static obstacle.
    Detour,
    /// A point of the smoothed curve (added by the smooth stage).
    Sample,
    /// Where the border band ends: between a boundary point and this one the walker moves at
    /// its crossing's velocity, as the pattern fixes it, so that the characters of two
    /// neighbouring patches near their border are known to both (stage 4 sets it; no later
    /// stage moves it).
    Band,
}

impl PointKind {
    /// Every kind, in code order.
    pub const ALL: [PointKind; 9] = [
        PointKind::Entry,
        PointKind::Exit,
        PointKind::Split,
        PointKind::Pause,
        PointKind::Turn,
        PointKind::Bend,
        PointKind::Detour,
        PointKind::Sample,
        PointKind::Band,
    ];

    fn code(self) -> u8 {
        self as u8
    }

    fn from_code(code: u8) -> Option<PointKind> {
        Self::ALL.get(code as usize).copied()
    }
}

/// The indices of the points that end the entry's border band and start the exit's, if the
/// trajectory has them: the first [`PointKind::Band`] point with only split points before it,
/// and the last with only split points after it.
pub fn band_ends(points: &[ControlPoint]) -> (Option<usize>, Option<usize>) {
    let n = points.len();
    if n < 4 {
        return (None, None);
    }
    let entry = (1..n - 1)
        .find(|&i| points[i].kind != PointKind::Split)
        .filter(|&i| points[i].kind == PointKind::Band);
    let exit = (1..n - 1)
        .rev()
        .find(|&i| points[i].kind != PointKind::Split)
        .filter(|&i| points[i].kind == PointKind::Band && Some(i) != entry);
    (entry, exit)
}

/// A point of a trajectory in patch-local metres and unwrapped time: times grow from the entry
/// time in [0, period) and may pass the period; the character's position at time `t mod period`
/// in the looping animation is the trajectory's at `t`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControlPoint {
    pub pos: DVec2,
    pub t: f64,
    pub kind: PointKind,
}

/// A walker's path through one patch, piecewise linear in space-time.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// Index of the entry crossing in the patterns.
    pub entry: u32,
    /// Index of the exit crossing.
    pub exit: u32,
    pub points: Vec<ControlPoint>,
}

impl Trajectory {
    /// Time spent inside the patch.
    pub fn duration(&self) -> f64 {
        self.points.last().map_or(0.0, |l| l.t) - self.points.first().map_or(0.0, |f| f.t)
    }
}

/// Position at time `t` on the polyline through `points` (held at its ends outside its span).
pub fn position_at(points: &[ControlPoint], t: f64) -> DVec2 {
    let k = points
        .partition_point(|p| p.t <= t)
        .clamp(1, points.len() - 1);
    position_on(points, k, t)
}

/// [`position_at`] on the piece from point `k - 1` to point `k`, for a caller that knows which
/// piece holds `t`.
pub fn position_on(points: &[ControlPoint], k: usize, t: f64) -> DVec2 {
    let (a, b) = (points[k - 1], points[k]);
    if b.t > a.t {
        a.pos + (b.pos - a.pos) * ((t - a.t) / (b.t - a.t)).clamp(0.0, 1.0)
    } else {
        b.pos
    }
}

/// Inserts a split point wherever the trajectory passes a multiple of the period.
pub fn split_at_periods(points: Vec<ControlPoint>, period: f64) -> Vec<ControlPoint> {
    let mut out = Vec::with_capacity(points.len() + 2);
    for pair in points.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        out.push(a);
        let mut k = (a.t / period).floor() + 1.0;
        while k * period < b.t - 1e-9 {
            let at = k * period;
            if at > a.t + 1e-9 {
                let f = (at - a.t) / (b.t - a.t);
                // A pause stays exactly in place (lerp would round it by an ulp).
                let pos = if a.pos == b.pos {
                    a.pos
                } else {
                    a.pos.lerp(b.pos, f)
                };
                out.push(ControlPoint {
                    pos,
                    t: at,
                    kind: PointKind::Split,
                });
            }
            k += 1.0;
        }
    }
    out.extend(points.last().copied());
    out
}

/// Everything that moves or stands in one patch.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PatchMotion {
    pub standers: Vec<DVec2>,
    pub trajectories: Vec<Trajectory>,
}

const MAGIC: &[u8; 8] = b"CRWDTRAJ";

/// Encodes per-patch motion (in patch order) as the trajectories side file: magic, patch count,
/// then per patch: stander count and (x, y) pairs, trajectory count and per trajectory entry,
/// exit, point count and (x, y, t, kind) points. Little-endian u32 / f64 / u8.
///
/// The patches are encoded in parallel, each into its own part of one buffer sized up front:
/// painting's 412 MB took most of a second on one core, and growing it by doubling copied and
/// first-touched it twice over.
pub fn encode_motion<P: std::borrow::Borrow<PatchMotion> + Sync>(patches: &[P]) -> Vec<u8> {
    let sizes: Vec<usize> = patches.iter().map(|p| encoded_size(p.borrow())).collect();
    let mut out = vec![0u8; HEAD_BYTES + sizes.iter().sum::<usize>()];
    let (head, mut rest) = out.split_at_mut(HEAD_BYTES);
    head.copy_from_slice(&encoded_head(patches.len()));
    let mut parts = Vec::with_capacity(patches.len());
    for &size in &sizes {
        let (part, tail) = std::mem::take(&mut rest).split_at_mut(size);
        parts.push(part);
        rest = tail;
    }
    parts
        .into_par_iter()
        .zip(patches)
        .for_each(|(part, p)| encode_patch(p.borrow(), part));
    out
}

/// The magic and the patch count.
const HEAD_BYTES: usize = 12;

/// What [`encode_motion`]'s bytes of `patches` patches start with: the magic, the count.
/// Followed by the patches' bytes one after another, so that the side file of runs of patches
/// encoded apart (a stage's shard parts) is this head and each run's [`encoded_patches`].
pub fn encoded_head(patches: usize) -> [u8; HEAD_BYTES] {
    let mut head = [0u8; HEAD_BYTES];
    head[..8].copy_from_slice(MAGIC);
    head[8..].copy_from_slice(&(patches as u32).to_le_bytes());
    head
}

/// One patch's bytes as [`encode_motion`] writes them among the others: a side file is
/// [`encoded_head`] and its patches' bytes one after another.
pub fn encode_patch_bytes(p: &PatchMotion) -> Vec<u8> {
    let size = encoded_size(p);
    let mut out = Vec::with_capacity(size);
    encode_patch_uninit(p, &mut out.spare_capacity_mut()[..size]);
    // SAFETY: `encode_patch_uninit` wrote every one of the first `size` bytes (or panicked).
    unsafe { out.set_len(size) };
    out
}

/// The patches' bytes of [`encode_motion`]'s `bytes`: all but the head.
pub fn encoded_patches(bytes: &[u8]) -> &[u8] {
    &bytes[HEAD_BYTES.min(bytes.len())..]
}
/// A stander: x and y.
const STANDER_BYTES: usize = 16;
/// A trajectory without its points: entry, exit, point count.
const TRAJECTORY_BYTES: usize = 12;
/// A point: x, y, t and kind.
const POINT_BYTES: usize = 25;

/// The bytes [`encode_patch`] writes for `p`.
pub fn encoded_size(p: &PatchMotion) -> usize {
    let points: usize = p.trajectories.iter().map(|t| t.points.len()).sum();
    8 + STANDER_BYTES * p.standers.len()
        + TRAJECTORY_BYTES * p.trajectories.len()
        + POINT_BYTES * points
}

/// Writes one patch's motion into `out`, exactly [`encoded_size`] bytes.
pub fn encode_patch(p: &PatchMotion, out: &mut [u8]) {
    let mut at = 0;
    write_patch(p, |bytes| {
        out[at..at + bytes.len()].copy_from_slice(bytes);
        at += bytes.len();
    });
}

/// [`encode_patch`] into memory not written yet (a vector's spare room, so that it is not
/// cleared first only to be written over): writes every byte of `out`, which is exactly
/// [`encoded_size`] bytes.
pub fn encode_patch_uninit(p: &PatchMotion, out: &mut [std::mem::MaybeUninit<u8>]) {
    let mut at = 0;
    write_patch(p, |bytes| {
        out[at..at + bytes.len()].write_copy_of_slice(bytes);
        at += bytes.len();
    });
    assert_eq!(at, out.len(), "a patch's room is its encoded size");
}

/// The bytes of one patch's motion, in order, to `put`.
fn write_patch(p: &PatchMotion, mut put: impl FnMut(&[u8])) {
    put(&(p.standers.len() as u32).to_le_bytes());
    for s in &p.standers {
        put(&s.x.to_le_bytes());
        put(&s.y.to_le_bytes());
    }
    put(&(p.trajectories.len() as u32).to_le_bytes());
    for tr in &p.trajectories {
        put(&tr.entry.to_le_bytes());
        put(&tr.exit.to_le_bytes());
        put(&(tr.points.len() as u32).to_le_bytes());
        for cp in &tr.points {
            put(&cp.pos.x.to_le_bytes());
            put(&cp.pos.y.to_le_bytes());
            put(&cp.t.to_le_bytes());
            put(&[cp.kind.code()]);
        }
    }
}

/// A cursor over a side file's bytes that never reads past them.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Option<&[u8]> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len())?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Some(s)
    }

    fn u32(&mut self) -> Option<u32> {
        self.take(4)
            .map(|b| u32::from_le_bytes(b.try_into().unwrap()))
    }

    fn f64(&mut self) -> Option<f64> {
        self.take(8)
            .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
    }
}

/// What [`patch_extent`] reads: counts, and bytes it steps over ([`Reader`] over bytes in
/// memory, [`FileCounts`] over a file).
trait Counts {
    /// The first 8 bytes, at the start.
    fn magic(&mut self) -> Option<[u8; 8]>;
    fn u32(&mut self) -> Option<u32>;
    /// Steps over `n` bytes, if there are that many left.
    fn skip_bytes(&mut self, n: usize) -> Option<()>;
    /// Bytes left.
    fn left(&self) -> usize;
    /// Bytes read or stepped over.
    fn position(&self) -> usize;

    /// A count of items of at least `min_item_bytes` each, refused if they cannot fit.
    fn count(&mut self, min_item_bytes: usize) -> Option<usize> {
        let n = self.u32()? as usize;
        (n.saturating_mul(min_item_bytes) <= self.left()).then_some(n)
    }

    fn skip(&mut self, items: usize, item_bytes: usize) -> Option<()> {
        self.skip_bytes(items.checked_mul(item_bytes)?)
    }
}

impl Counts for Reader<'_> {
    fn magic(&mut self) -> Option<[u8; 8]> {
        self.take(8)?.try_into().ok()
    }
    fn u32(&mut self) -> Option<u32> {
        Reader::u32(self)
    }
    fn skip_bytes(&mut self, n: usize) -> Option<()> {
        self.take(n).map(|_| ())
    }
    fn left(&self) -> usize {
        self.bytes.len() - self.at
    }
    fn position(&self) -> usize {
        self.at
    }
}

/// [`Counts`] over a file of `len` bytes, read through a buffer.
struct FileCounts {
    file: std::io::BufReader<std::fs::File>,
    at: usize,
    len: usize,
}

impl FileCounts {
    /// The next `N` bytes, if there are that many left.
    fn read<const N: usize>(&mut self) -> Option<[u8; N]> {
        let mut b = [0u8; N];
        (self.left() >= N).then_some(())?;
        std::io::Read::read_exact(&mut self.file, &mut b).ok()?;
        self.at += N;
        Some(b)
    }
}

impl Counts for FileCounts {
    fn magic(&mut self) -> Option<[u8; 8]> {
        self.read()
    }
    fn u32(&mut self) -> Option<u32> {
        self.read().map(u32::from_le_bytes)
    }
    fn skip_bytes(&mut self, n: usize) -> Option<()> {
        (n <= self.left()).then_some(())?;
        self.file.seek_relative(i64::try_from(n).ok()?).ok()?;
        self.at += n;
        Some(())
    }
    fn left(&self) -> usize {
        self.len - self.at
    }
    fn position(&self) -> usize {
        self.at
    }
}

/// Decodes [`encode_motion`]'s bytes; `path` names the file in errors. Never trusts a count
/// beyond the bytes that are there.
///
/// A first pass reads only the counts, to find where each patch's bytes start and end; the
/// patches are then decoded in parallel (painting's 412 MB took a second on one core, once in
/// each of export, check and report).
pub fn decode_motion(path: &Path, bytes: &[u8]) -> Result<Vec<PatchMotion>> {
    MotionIndex::of(path, bytes)?.decode_all(path, bytes)
}

/// Where each patch's motion lies in a side file's bytes, and how many trajectories it holds,
/// found from the counts alone (a pass that touches a few bytes a trajectory).
#[derive(Clone)]
pub struct MotionIndex {
    spans: Vec<(std::ops::Range<usize>, u32)>,
}

/// The indexes this process made of side files it wrote, by the files' hashes
/// ([`MotionIndex::share`]), the last few.
static SHARED_INDEXES: std::sync::Mutex<Vec<(crate::Hash, MotionIndex)>> =
    std::sync::Mutex::new(Vec::new());

/// How many [`SHARED_INDEXES`] are kept (a build's stage 6 and, with edits, stage 7).
const SHARED_INDEX_COUNT: usize = 2;

impl MotionIndex {
    /// Keeps this index, of a side file whose bytes hash to `hash`, for
    /// [`TrajectoriesFile::open_for`] in this process: the check and the report after a
    /// stroke read painting's 425 MB stage 6 file through for its index otherwise (55 ms a
    /// time), which stage 6 made as it wrote it.
    pub fn share(&self, hash: crate::Hash) {
        let mut shared = SHARED_INDEXES.lock().unwrap_or_else(|e| e.into_inner());
        shared.retain(|(h, _)| *h != hash);
        shared.push((hash, self.clone()));
        let extra = shared.len().saturating_sub(SHARED_INDEX_COUNT);
        shared.drain(..extra);
    }

    /// The index [`MotionIndex::share`] kept of the side file whose bytes hash to `hash`.
    fn shared(hash: crate::Hash) -> Option<MotionIndex> {
        let shared = SHARED_INDEXES.lock().unwrap_or_else(|e| e.into_inner());
        (shared.iter().find(|(h, _)| *h == hash)).map(|(_, index)| index.clone())
    }

    /// The index of [`encode_motion`]'s `bytes`, refused (naming `path`) unless every count
    /// fits the bytes that are there and they end where the last patch does.
    pub fn of(path: &Path, bytes: &[u8]) -> Result<MotionIndex> {
        MotionIndex::read(path, &mut Reader { bytes, at: 0 })
    }

    /// [`MotionIndex::of`] the side file at `path`, read through without keeping its bytes.
    pub fn of_file(path: &Path) -> Result<MotionIndex> {
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, "read", e))?;
        let len = file
            .metadata()
            .map_err(|e| Error::io(path, "read", e))?
            .len();
        let len = usize::try_from(len).map_err(|_| damaged(path, 0))?;
        let mut r = FileCounts {
            file: std::io::BufReader::with_capacity(1 << 20, file),
            at: 0,
            len,
        };
        MotionIndex::read(path, &mut r)
    }

    /// The index of the side file `r` reads from its start ([`MotionIndex::of`]).
    fn read(path: &Path, r: &mut impl Counts) -> Result<MotionIndex> {
        if r.magic().as_ref() != Some(MAGIC) {
            return Err(damaged(path, 0));
        }
        let n = r.count(8).ok_or_else(|| damaged(path, r.position()))?;
        let mut spans = Vec::with_capacity(n);
        for _ in 0..n {
            let start = r.position();
            let trajectories = patch_extent(r).ok_or_else(|| damaged(path, r.position()))?;
            spans.push((start..r.position(), trajectories));
        }
        if r.left() != 0 {
            return Err(damaged(path, r.position()));
        }
        Ok(MotionIndex { spans })
    }

    /// The index of a side file [`encoded_head`] and the patches laid after it, each of
    /// `(bytes, trajectories)` (what its maker knows, without reading them through).
    pub fn of_sizes(patches: impl IntoIterator<Item = (usize, u32)>) -> MotionIndex {
        let mut at = HEAD_BYTES;
        let spans = (patches.into_iter())
            .map(|(bytes, trajectories)| {
                at += bytes;
                (at - bytes..at, trajectories)
            })
            .collect();
        MotionIndex { spans }
    }

    /// How many patches the file holds.
    pub fn patches(&self) -> usize {
        self.spans.len()
    }

    /// How many trajectories patch `p` holds.
    pub fn trajectories(&self, p: usize) -> u32 {
        self.spans[p].1
    }

    /// Every patch's motion, decoded in parallel from the `bytes` this index was made of.
    pub fn decode_all(&self, path: &Path, bytes: &[u8]) -> Result<Vec<PatchMotion>> {
        let decoded: Vec<Result<PatchMotion>> = (0..self.spans.len())
            .into_par_iter()
            .map(|p| self.decode(path, bytes, p))
            .collect();
        decoded.into_iter().collect()
    }

    /// Where patch `p`'s bytes lie in the side file (patch after patch, with nothing between).
    pub fn span(&self, p: usize) -> std::ops::Range<usize> {
        self.spans[p].0.clone()
    }

    /// Patch `p`'s motion, from `bytes`, the side file's from byte `base` on (holding the
    /// patch's [`MotionIndex::span`]).
    pub fn decode_in(
        &self,
        path: &Path,
        bytes: &[u8],
        base: usize,
        p: usize,
    ) -> Result<PatchMotion> {
        let span = &self.spans[p].0;
        let mut r = Reader {
            bytes: &bytes[..span.end - base],
            at: span.start - base,
        };
        decode_patch(&mut r).ok_or_else(|| damaged(path, base + r.at))
    }

    /// Patch `p`'s motion, from the `bytes` this index was made of.
    pub fn decode(&self, path: &Path, bytes: &[u8], p: usize) -> Result<PatchMotion> {
        let span = &self.spans[p].0;
        let mut r = Reader {
            bytes: &bytes[..span.end],
            at: span.start,
        };
        decode_patch(&mut r).ok_or_else(|| damaged(path, r.at))
    }
}

/// A trajectories file's motion left in its side file ([`TrajectoriesFile::open_for`]), or in
/// the side files of a stage's shard parts one after another ([`LazyMotion::of_parts`]), each
/// patch read from its file when asked for.
pub struct LazyMotion {
    /// The files, each holding the patches from its `first` on.
    files: Vec<LazyFile>,
    patches: usize,
}

struct LazyFile {
    /// The stage file (or part), named when a patch does not fit the graph.
    path: std::path::PathBuf,
    /// The side file, named when its bytes are damaged.
    side: std::path::PathBuf,
    from: Bytes,
    index: MotionIndex,
    first: usize,
}

/// Where a [`LazyFile`]'s bytes are: in its file, or held (the side file a build made and
/// writes meanwhile: its head, then each patch's bytes, a piece each).
enum Bytes {
    File(std::fs::File),
    Held(std::sync::Arc<Vec<Vec<u8>>>),
}

impl LazyMotion {
    /// The motion of side files `(stage file, side file, index)` holding runs of patches one
    /// after another, in patch order.
    pub fn of_parts(
        parts: Vec<(std::path::PathBuf, std::path::PathBuf, MotionIndex)>,
    ) -> Result<LazyMotion> {
        let mut files = Vec::with_capacity(parts.len());
        let mut first = 0;
        for (path, side, index) in parts {
            let file = std::fs::File::open(&side).map_err(|e| Error::io(&side, "read", e))?;
            let n = index.patches();
            files.push(LazyFile {
                path,
                side,
                from: Bytes::File(file),
                index,
                first,
            });
            first += n;
        }
        Ok(LazyMotion {
            files,
            patches: first,
        })
    }

    /// The motion of the one side file `side` (of the stage file or part `path`), its index
    /// read from its counts without keeping its bytes.
    pub fn of_side_file(path: &Path, side: &Path) -> Result<LazyMotion> {
        let index = MotionIndex::of_file(side)?;
        LazyMotion::of_parts(vec![(path.to_path_buf(), side.to_path_buf(), index)])
    }

    /// The motion of the side file `pieces` (of the stage file `path`, to be `side`), held:
    /// [`encoded_head`], then each patch's bytes, a piece each; `index` is [`MotionIndex::of`]
    /// them one after another.
    pub fn of_pieces(
        (path, side): (&Path, &Path),
        pieces: std::sync::Arc<Vec<Vec<u8>>>,
        index: MotionIndex,
    ) -> LazyMotion {
        assert_eq!(
            pieces.len(),
            index.patches() + 1,
            "a head and a piece a patch"
        );
        LazyMotion {
            patches: index.patches(),
            files: vec![LazyFile {
                path: path.to_path_buf(),
                side: side.to_path_buf(),
                from: Bytes::Held(pieces),
                index,
                first: 0,
            }],
        }
    }

    pub fn patches(&self) -> usize {
        self.patches
    }

    /// Patch `p`'s motion, refused as [`check_motion`] refuses it.
    pub fn patch(&self, p: usize) -> Result<PatchMotion> {
        let f = &self.files[self.files.partition_point(|f| f.first <= p) - 1];
        let span = f.index.spans[p - f.first].0.clone();
        let read;
        let bytes = match &f.from {
            Bytes::Held(pieces) => &pieces[p - f.first + 1][..],
            Bytes::File(file) => {
                let mut bytes = vec![0u8; span.len()];
                crate::files::read_at(file, &mut bytes, span.start as u64)
                    .map_err(|e| Error::io(&f.side, "read", e))?;
                read = bytes;
                &read[..]
            }
        };
        let mut r = Reader { bytes, at: 0 };
        let m = decode_patch(&mut r).ok_or_else(|| damaged(&f.side, span.start + r.at))?;
        check_patch_motion(&f.path, p, &m)?;
        Ok(m)
    }

    /// Every patch's motion, decoded in parallel.
    pub fn all(&self) -> Result<Vec<PatchMotion>> {
        let all: Vec<Result<PatchMotion>> = (0..self.patches)
            .into_par_iter()
            .map(|p| self.patch(p))
            .collect();
        all.into_iter().collect()
    }
}

/// The error of a side file whose bytes are not what [`encode_motion`] writes.
fn damaged(path: &Path, at: usize) -> Error {
    Error::stage_file(
        path,
        format!("is not a trajectories file: damaged near byte {at}"),
    )
}

/// Moves `r` over one patch's bytes, reading only its counts; its trajectory count.
fn patch_extent(r: &mut impl Counts) -> Option<u32> {
    let ns = r.count(STANDER_BYTES)?;
    r.skip(ns, STANDER_BYTES)?;
    let nt = r.count(TRAJECTORY_BYTES)?;
    for _ in 0..nt {
        r.skip(2, 4)?;
        let np = r.count(POINT_BYTES)?;
        r.skip(np, POINT_BYTES)?;
    }
    Some(nt as u32)
}

/// One patch's motion from `r`, which holds exactly its bytes ([`patch_extent`]).
fn decode_patch(r: &mut Reader) -> Option<PatchMotion> {
    let ns = r.count(STANDER_BYTES)?;
    let mut motion = PatchMotion {
        standers: Vec::with_capacity(ns),
        trajectories: Vec::new(),
    };
    for _ in 0..ns {
        let x = r.f64()?;
        let y = r.f64()?;
        motion.standers.push(DVec2::new(x, y));
    }
    let nt = r.count(TRAJECTORY_BYTES)?;
    motion.trajectories.reserve_exact(nt);
    for _ in 0..nt {
        let entry = r.u32()?;
        let exit = r.u32()?;
        let np = r.count(POINT_BYTES)?;
        let mut points = Vec::with_capacity(np);
        for _ in 0..np {
            let x = r.f64()?;
            let y = r.f64()?;
            let t = r.f64()?;
            let kind = r.take(1).and_then(|k| PointKind::from_code(k[0]))?;
            points.push(ControlPoint {
                pos: DVec2::new(x, y),
                t,
                kind,
            });
        }
        motion.trajectories.push(Trajectory {
            entry,
            exit,
            points,
        });
    }
    Some(motion)
}

/// Figures of a trajectories file.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MotionSummary {
    pub walkers_trajectories: u64,
    pub standers: u64,
    /// Trajectories that pause, that last more than one period, that turn at the centre.
    pub pausing: u64,
    pub multi_period: u64,
    pub same_border: u64,
    /// Walkers present at any time (sum of trajectory durations / period).
    pub walkers_measured: f64,
}

/// Refuses motion that does not fit a graph of `patches` patches (built from another graph, or
/// damaged): one entry per patch, every trajectory at least two points forward in time.
pub fn check_motion(path: &Path, patches: usize, motion: &[PatchMotion]) -> Result<()> {
    check_patch_count(path, motion.len(), patches)?;
    for (p, m) in motion.iter().enumerate() {
        check_patch_motion(path, p, m)?;
    }
    Ok(())
}

/// Refuses motion of `found` patches for a graph of `patches`.
fn check_patch_count(path: &Path, found: usize, patches: usize) -> Result<()> {
    if found == patches {
        return Ok(());
    }
    Err(Error::stage_file(
        path,
        format!(
            "does not fit the graph beside it: {found} patches of motion for {patches} patches"
        ),
    ))
}

/// [`check_motion`]'s test of one patch's trajectories (patch `p`): each a path forward in
/// time, of at least two finite points.
pub fn check_patch_motion(path: &Path, p: usize, m: &PatchMotion) -> Result<()> {
    for (i, tr) in m.trajectories.iter().enumerate() {
        let forward = tr.points.windows(2).all(|w| w[1].t >= w[0].t);
        let finite = tr
            .points
            .iter()
            .all(|c| c.pos.is_finite() && c.t.is_finite());
        if tr.points.len() < 2 || !forward || !finite {
            return Err(Error::stage_file(
                path,
                format!(
                    "does not fit the graph beside it: trajectory {i} of patch {p} is not a \
                     path forward in time"
                ),
            ));
        }
    }
    Ok(())
}

/// Figures of per-patch motion.
pub fn summarize(motion: &[PatchMotion], period_s: f64) -> MotionSummary {
    let mut s = Summing::new(period_s);
    motion.iter().for_each(|m| s.add(m));
    s.finish()
}

/// [`summarize`] a patch at a time, in patch order (the same sums, to the bit), for motion
/// that is never held whole.
pub struct Summing {
    period_s: f64,
    summary: MotionSummary,
    walked_s: f64,
}

impl Summing {
    pub fn new(period_s: f64) -> Summing {
        Summing {
            period_s,
            summary: MotionSummary::default(),
            // Where `Iterator::sum` of floats starts.
            walked_s: std::iter::empty::<f64>().sum(),
        }
    }

    /// The next patch's motion.
    pub fn add(&mut self, m: &PatchMotion) {
        let s = &mut self.summary;
        s.standers += m.standers.len() as u64;
        for t in &m.trajectories {
            s.walkers_trajectories += 1;
            s.pausing += u64::from(t.points.iter().any(|p| p.kind == PointKind::Pause));
            s.multi_period += u64::from(t.duration() > self.period_s + 1e-9);
            s.same_border += u64::from(t.points.iter().any(|p| p.kind == PointKind::Turn));
            self.walked_s += t.duration();
        }
    }

    pub fn finish(self) -> MotionSummary {
        MotionSummary {
            walkers_measured: self.walked_s / self.period_s,
            ..self.summary
        }
    }
}

/// The motion a stage file names: held, to be encoded beside it; or its side file's bytes,
/// streamed to its temporary name already ([`crate::files::Streamed`], at the owner's side
/// file path: a gathering build's) or made and written by the owner (a stroke's stage 6, from
/// the last build's bytes), with the summary of its motion.
pub enum SideMotion<'a> {
    Held(&'a [PatchMotion]),
    Streamed(&'a crate::files::StreamedFile, MotionSummary),
    /// Encoded already (its size and hash), to be written by the caller, with the summary of
    /// its motion.
    Encoded((u64, crate::Hash), MotionSummary),
}

impl<'a> From<&'a [PatchMotion]> for SideMotion<'a> {
    fn from(motion: &'a [PatchMotion]) -> Self {
        SideMotion::Held(motion)
    }
}

impl<'a> From<&'a Vec<PatchMotion>> for SideMotion<'a> {
    fn from(motion: &'a Vec<PatchMotion>) -> Self {
        SideMotion::Held(motion)
    }
}

/// Encodes a trajectories-shaped stage file at `out`: its motion side file (`.bin` beside it,
/// unless streamed already), then the RON that names it. Stages 4 and later all write this
/// shape.
pub fn encode_file<'a>(
    out: &Path,
    header: Header,
    period_s: f64,
    radius_m: f64,
    motion: impl Into<SideMotion<'a>>,
    collisions: Option<CollisionSummary>,
    smoothing: Option<SmoothingSummary>,
) -> (TrajectoriesFile, crate::files::Writes) {
    let (summary, record, side) = match motion.into() {
        SideMotion::Held(motion) => {
            let bytes = encode_motion(motion);
            let (path, record) = SideFile::beside(out, &bytes);
            (summarize(motion, period_s), record, Some((path, bytes)))
        }
        SideMotion::Encoded((bytes, hash), summary) => {
            let (_, mut record) = SideFile::beside(out, &[]);
            (record.bytes, record.hash) = (bytes, hash);
            (summary, record, None)
        }
        SideMotion::Streamed(side, summary) => {
            let (path, mut record) = SideFile::beside(out, &[]);
            debug_assert_eq!(
                path, side.path,
                "a side file streamed where its owner names it"
            );
            (record.bytes, record.hash) = (side.bytes, side.hash);
            (summary, record, None)
        }
    };
    let file = file_of(
        header,
        (period_s, radius_m),
        (summary, record),
        (collisions, smoothing),
    );
    let ron = crate::files::to_stage_ron(&file).into_bytes();
    let writes = side.into_iter().chain([(out.to_path_buf(), ron)]).collect();
    (file, writes)
}

/// The file that names side file `record`, whose motion `summary` sums.
fn file_of(
    header: Header,
    (period_s, radius_m): (f64, f64),
    (summary, record): (MotionSummary, SideFile),
    (collisions, smoothing): (Option<CollisionSummary>, Option<SmoothingSummary>),
) -> TrajectoriesFile {
    TrajectoriesFile {
        header,
        period_s,
        radius_m,
        summary,
        collisions,
        smoothing,
        edits: None,
        motion: record,
    }
}

/// `trajectories.ron` (stage 4's file, and the shape of stages 5 and 6's).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrajectoriesFile {
    pub header: Header,
    pub period_s: f64,
    pub radius_m: f64,
    pub summary: MotionSummary,
    /// What the collide stage did (absent before it).
    #[serde(default)]
    pub collisions: Option<CollisionSummary>,
    /// What the smooth stage did (absent before it).
    #[serde(default)]
    pub smoothing: Option<SmoothingSummary>,
    /// What the edit stage did, per edit (absent before it, and in every file of a pipeline
    /// without edits, so that those files are the bytes they were before stage 7 existed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub edits: Option<Vec<EditSummary>>,
    /// Per patch motion, in patch order.
    pub motion: SideFile,
}

/// What one edit of stage 7 did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EditSummary {
    pub name: String,
    /// Meet, Density, Flow, FlowMap or Vorticity.
    pub kind: String,
    /// Where it is, `(x0, y0, x1, y1)` world metres (a meeting: its point twice), and its
    /// window in the period, s (a meeting: its instant twice): what a viewer draws.
    pub rect: (f64, f64, f64, f64),
    pub window_s: (f64, f64),
    /// What `before` and `after` measure, with its unit.
    pub measure: String,
    pub before: f64,
    pub after: f64,
    /// The patches it covers (indices in the graph).
    pub patches: Vec<u32>,
    /// Walkers whose walk changed, over those patches.
    pub walkers: usize,
    /// Descent iterations, summed over its patches.
    pub iterations: usize,
    /// A density edit's people in its rectangle (the others: `None`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub density: Option<DensityFigures>,
    /// What else the report should say of it (a density edit: its people before and after).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
    /// What it could not do (an edit over no patch with walkers; a density edit more than 15 %
    /// short of its target): a build warning.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub warning: Option<String>,
}

/// A density edit's people per m2 in its rectangle over its window, counted (a person is in
/// or out), as the plans had them, as edited, and the most its patches could show: the
/// walkers the edit may move, all in it, with those whose plans bring them. A patch's walkers
/// are fixed by its crossings, so that can be below the target: the most is everyone the edit
/// may move at all (off the border bands) in the rectangle, with those whose plans are.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DensityFigures {
    pub target: f64,
    pub before: f64,
    pub after: f64,
    pub reachable: f64,
}

impl DensityFigures {
    /// What the edit can be held to: the target, or what the patches could show where that
    /// is less.
    pub fn attainable(&self) -> f64 {
        self.target.min(self.reachable)
    }

    /// Within `share` (0.15: 15 %) of [`DensityFigures::attainable`], either way.
    pub fn reached(&self, share: f64) -> bool {
        (self.after - self.attainable()).abs() <= share * self.attainable()
    }
}

/// The collide stage's figures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CollisionSummary {
    /// Pushes applied, over all patches.
    pub iterations: u64,
    /// Smallest distance minus needed clearance over all patches (negative: a collision left).
    pub min_margin_m: f64,
    /// Patches that hit the iteration cap, with their worst pair.
    pub unconverged: Vec<Stall>,
    /// Patches cleared only by letting some walker walk faster than `match.max_speed` allows
    /// (a warning: the painting asks for more than walking pace gives there).
    #[serde(default)]
    pub hurried: Vec<Hurry>,
    /// Walkers given one more period in their patch so that others could pass first: (patch,
    /// walker). Each adds a walker to its patch for a period.
    #[serde(default)]
    pub waited: Vec<(u32, u32)>,
}

/// A patch whose walkers stage 5 could keep apart only by letting one hurry.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Hurry {
    pub patch: u32,
    /// The fastest walker (its trajectory's index in the patch), its speed and when.
    pub walker: u32,
    pub speed_m_s: f64,
    pub t_s: f64,
}

/// A patch that stage 5 could not clear, and its worst pair there.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Stall {
    pub patch: u32,
    /// Distance minus the clearance the pair needs (negative).
    pub margin_m: f64,
    /// The walker (its trajectory's index in the patch) and who it comes too close to.
    pub walker: u32,
    pub with: StallWith,
    /// When, in the walker's unwrapped time.
    pub t_s: f64,
}

/// Who a stalled walker comes too close to.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum StallWith {
    /// Another walker of the patch (its trajectory's index), or the same one a period later.
    Walker(u32),
    Stander(u32),
    Obstacle(u32),
}

/// The smooth stage's figures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SmoothingSummary {
    /// Trajectories that ship smoothed.
    pub smoothed: u64,
    /// Trajectories kept as the collide stage left them, because their smoothed curve came too
    /// close to someone or something.
    pub kept_straight: u64,
    /// Curve points dropped for straying farther than the allowed displacement.
    pub dropped_points: u64,
}

impl TrajectoriesFile {
    pub const STAGE: &'static str = "match";
    pub const VERSION: u32 = 4;

    pub fn load(path: &Path) -> Result<(TrajectoriesFile, Vec<PatchMotion>)> {
        Self::load_stage(path, Self::STAGE, Self::VERSION)
    }

    /// Reads a trajectories file written by `stage` (match, collide, smooth) at `version`.
    pub fn load_stage(
        path: &Path,
        stage: &str,
        version: u32,
    ) -> Result<(TrajectoriesFile, Vec<PatchMotion>)> {
        let (file, bytes) = Self::read_stage(path, stage, version)?;
        let motion = decode_motion(&path.with_file_name(&file.motion.file), &bytes)?;
        Ok((file, motion))
    }

    /// The file written by `stage` at `version`, and its motion side file's bytes (size and
    /// hash checked), not yet decoded.
    fn read_stage(path: &Path, stage: &str, version: u32) -> Result<(TrajectoriesFile, Vec<u8>)> {
        let file: TrajectoriesFile = crate::files::read_ron(path)?;
        crate::files::expect_stage(path, &file.header, stage, version)?;
        let bytes = file.motion.read(path)?;
        Ok((file, bytes))
    }

    /// One patch of a trajectories file written by `stage` at `version` for a graph of
    /// `patches` patches, chosen by `choose` from the index (None: the file holds none to
    /// choose), without decoding the others or keeping the side file's bytes: a picture of the
    /// busiest patch of painting's 412 MB decoded all of it, and of the million's held 4.2 GB.
    pub fn load_patch(
        path: &Path,
        stage: &str,
        version: u32,
        patches: usize,
        choose: impl FnOnce(&MotionIndex) -> Option<usize>,
    ) -> Result<(TrajectoriesFile, Option<(usize, PatchMotion)>)> {
        let (file, lazy) = Self::open_for(path, stage, version, patches)?;
        let Some(p) = choose(&lazy.files[0].index) else {
            return Ok((file, None));
        };
        let motion = lazy.patch(p)?;
        Ok((file, Some((p, motion))))
    }

    /// A file written by `stage` at `version` for a graph of `patches` patches, its motion
    /// left in its side file (size and hash checked), to be read a patch at a time
    /// ([`LazyMotion`]): a million walkers' side file is 4.2 GB, and more decoded.
    pub fn open_for(
        path: &Path,
        stage: &str,
        version: u32,
        patches: usize,
    ) -> Result<(TrajectoriesFile, LazyMotion)> {
        let file: TrajectoriesFile = crate::files::read_ron(path)?;
        crate::files::expect_stage(path, &file.header, stage, version)?;
        let side = file.motion.check(path)?;
        // The file holds the bytes of that hash: an index made of them is its index.
        let index = MotionIndex::shared(file.motion.hash)
            .map_or_else(|| MotionIndex::of_file(&side), Ok)?;
        check_patch_count(path, index.patches(), patches)?;
        let lazy = LazyMotion::of_parts(vec![(path.to_path_buf(), side, index)])?;
        Ok((file, lazy))
    }

    /// [`Self::load_stage`], refused unless the motion fits a graph of `patches` patches
    /// ([`check_motion`]).
    pub fn load_for(
        path: &Path,
        stage: &str,
        version: u32,
        patches: usize,
    ) -> Result<(TrajectoriesFile, Vec<PatchMotion>)> {
        let (file, motion) = Self::load_stage(path, stage, version)?;
        check_motion(path, patches, &motion)?;
        Ok((file, motion))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn motion_round_trips_through_its_side_file_with_every_point_kind() {
        let points = PointKind::ALL
            .iter()
            .enumerate()
            .map(|(i, &kind)| ControlPoint {
                pos: DVec2::new(i as f64, 0.5),
                t: i as f64,
                kind,
            })
            .collect();
        let motion = vec![
            PatchMotion {
                standers: vec![DVec2::new(1.0, 2.0)],
                trajectories: vec![Trajectory {
                    entry: 3,
                    exit: 4,
                    points,
                }],
            },
            PatchMotion::default(),
        ];
        let bytes = encode_motion(&motion);
        assert_eq!(decode_motion(Path::new("m.bin"), &bytes).unwrap(), motion);
        for cut in [0, 9, bytes.len() / 2, bytes.len() - 1] {
            assert!(
                decode_motion(Path::new("m.bin"), &bytes[..cut]).is_err(),
                "cut at {cut}"
            );
        }
    }

    #[test]
    fn one_patch_decodes_alone_as_it_does_with_the_others() {
        let walk = |n: usize, x: f64| Trajectory {
            entry: n as u32,
            exit: n as u32 + 1,
            points: (0..n + 2)
                .map(|i| ControlPoint {
                    pos: DVec2::new(x, i as f64),
                    t: i as f64,
                    kind: PointKind::Sample,
                })
                .collect(),
        };
        let motion: Vec<PatchMotion> = (0..5)
            .map(|p| PatchMotion {
                standers: vec![DVec2::splat(p as f64); p % 2],
                trajectories: (0..p).map(|k| walk(k, p as f64)).collect(),
            })
            .collect();
        let bytes = encode_motion(&motion);
        let index = MotionIndex::of(Path::new("m.bin"), &bytes).unwrap();
        assert_eq!(index.patches(), 5);
        for (p, m) in motion.iter().enumerate() {
            assert_eq!(index.trajectories(p) as usize, m.trajectories.len());
            assert_eq!(&index.decode(Path::new("m.bin"), &bytes, p).unwrap(), m);
        }
        // A bad point kind in patch 3 is found when patch 3 is decoded.
        let mut bad = bytes.clone();
        let last = encode_motion(&motion[..4]).len() - 1; // patch 3's last point's kind
        bad[last] = 200;
        let index = MotionIndex::of(Path::new("m.bin"), &bad).unwrap();
        assert!(index.decode(Path::new("m.bin"), &bad, 3).is_err());
        assert!(decode_motion(Path::new("m.bin"), &bad).is_err());
    }

    /// The index read through a file finds what the index of the bytes in memory finds, and
    /// refuses what it refuses: every cut, and a count made too large at every place.
    #[test]
    fn a_side_file_read_through_is_indexed_as_its_bytes_are() {
        let motion: Vec<PatchMotion> = (0..4)
            .map(|p| PatchMotion {
                standers: vec![DVec2::splat(p as f64); p % 2],
                trajectories: (0..p)
                    .map(|k| Trajectory {
                        entry: k as u32,
                        exit: k as u32 + 1,
                        points: (0..k + 2)
                            .map(|i| ControlPoint {
                                pos: DVec2::new(p as f64, i as f64),
                                t: i as f64,
                                kind: PointKind::Sample,
                            })
                            .collect(),
                    })
                    .collect(),
            })
            .collect();
        let bytes = encode_motion(&motion);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.bin");
        let spans = |i: &MotionIndex| i.spans.clone();
        let same = |b: &[u8]| {
            std::fs::write(&path, b).unwrap();
            let (mem, file) = (MotionIndex::of(&path, b), MotionIndex::of_file(&path));
            match (mem, file) {
                (Ok(a), Ok(b)) => assert_eq!(spans(&a), spans(&b)),
                (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string()),
                (a, b) => panic!("in memory {:?}, read through {:?}", a.is_ok(), b.is_ok()),
            }
        };
        same(&bytes);
        for cut in 0..bytes.len() {
            same(&bytes[..cut]);
        }
        for at in 0..bytes.len() {
            let mut b = bytes.clone();
            b[at] = 0xff;
            same(&b);
        }
    }

    #[test]
    fn an_index_shared_by_its_file_hash_is_found_by_that_hash_alone_and_the_last_two_kept() {
        let motion = vec![PatchMotion::default(); 3];
        let bytes = encode_motion(&motion);
        let index = MotionIndex::of(Path::new("m.bin"), &bytes).unwrap();
        let hashes: Vec<crate::Hash> = (0..3u8).map(|k| crate::Hash::of(&[k, 42, 7])).collect();
        for &h in &hashes {
            index.share(h);
        }
        assert!(
            MotionIndex::shared(hashes[0]).is_none(),
            "only the last two are kept"
        );
        for &h in &hashes[1..] {
            let found = MotionIndex::shared(h).expect("shared");
            assert_eq!(found.spans, index.spans);
        }
        assert!(MotionIndex::shared(crate::Hash::of(b"another file")).is_none());
    }
}
