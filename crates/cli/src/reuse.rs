//! Patch-level reuse for stages 4-6, at the edge: the last build's keys (`STAGE.keys`) and
//! its side file are read before the stage runs; every patch whose key is unchanged is taken
//! from there (renumbered to the new patterns), and only the rest is computed. The files are
//! then the bytes of a build from scratch (`tests/strokes.rs`).

use crowd_core::Hash;
use crowd_core::patch_keys::{Keys, Record, Table};
use crowd_core::trajectories::{MotionIndex, PatchMotion, PatchSums, TrajectoriesFile};
use std::path::{Path, PathBuf};

/// The keys file beside a stage file.
pub fn keys_path(stage_file: &Path) -> PathBuf {
    stage_file.with_extension("keys")
}

/// A patch of the last build's side file as it is there: its bytes, the table of crossings
/// they are numbered by, and its figures in the keys file.
pub type Encoded<'a> = (&'a [u8], &'a Table, &'a [u8]);

/// A stage's output of the last build, where its keys belong to it.
pub struct Previous {
    keys: Keys,
    bytes: crowd_core::files::Mapped,
    index: MotionIndex,
    side: PathBuf,
}

impl Previous {
    /// The last build's `stage_file` and its keys; `None` when either is missing, damaged,
    /// of another version or not of the same build.
    pub fn load(stage_file: &Path) -> Option<Previous> {
        let keys = Keys::decode(&std::fs::read(keys_path(stage_file)).ok()?)?;
        let file: TrajectoriesFile = crowd_core::files::read_ron(stage_file).ok()?;
        if file.motion.hash != keys.side {
            return None;
        }
        let bytes = file.motion.map(stage_file).ok()?;
        let side = stage_file.with_file_name(&file.motion.file);
        let index = MotionIndex::of(&side, &bytes).ok()?;
        (index.patches() == keys.patches.len()).then_some(Previous {
            keys,
            bytes,
            index,
            side,
        })
    }

    /// Patch `p`'s motion (numbered by `table`) and figures, if its key was `key`.
    pub fn take(&self, p: usize, key: Hash, table: &Table) -> Option<(PatchMotion, &[u8])> {
        let record = self.keys.patches.get(p).filter(|r| r.key == key)?;
        let motion = self.index.decode(&self.side, &self.bytes, p).ok()?;
        Some((record.table.renumber(table, motion), &record.extra))
    }

    /// Patch `p`'s bytes in the side file (numbered as the last build's patterns were: by
    /// its table, given too) and figures, if its key was `key`.
    pub fn take_encoded(&self, p: usize, key: Hash) -> Option<Encoded<'_>> {
        let record = self.keys.patches.get(p).filter(|r| r.key == key)?;
        let bytes = &self.bytes[self.index.span(p)];
        Some((bytes, &record.table, &record.extra))
    }
}

/// The last build's side files of stages 4-6, read and checked on threads of their own from
/// the moment a build first runs a stage: stage 3 re-optimising a region keeps one core busy
/// for a third of a second while the other waits, and a stroke's stage 6 then waited 0.26 s
/// for its 425 MB side file. Only side files under [`PREFETCH_BYTES`] are read ahead (a big
/// world's would sit in memory through stages 3-5).
#[derive(Default)]
pub struct Prefetch {
    loading: Vec<(PathBuf, std::thread::JoinHandle<Option<Previous>>)>,
}

/// The largest side file [`Prefetch`] reads ahead.
const PREFETCH_BYTES: u64 = 1 << 30;

impl Prefetch {
    /// Starts reading the side files of the stage files `stage_files` that are there.
    pub fn start(stage_files: impl IntoIterator<Item = PathBuf>) -> Prefetch {
        let loading = stage_files
            .into_iter()
            .filter(|path| {
                let side = path.with_extension("bin");
                std::fs::metadata(&side).is_ok_and(|m| m.len() < PREFETCH_BYTES)
            })
            .filter_map(|path| {
                let reading = path.clone();
                let thread = std::thread::Builder::new().spawn(move || Previous::load(&reading));
                Some((path, thread.ok()?))
            })
            .collect();
        Prefetch { loading }
    }

    /// Lets go of what is read ahead for `stage_file` (its stage is up to date): the thread
    /// finishes its read, and what it read is dropped then.
    pub fn forget(&mut self, stage_file: &Path) {
        self.loading.retain(|(p, _)| p != stage_file);
    }

    /// The last build's output at `stage_file`: as read ahead, or read now. Never on a worker
    /// of the thread pool: the reading thread hashes on the pool, and a worker that waits for it
    /// may be the one its hashing waits for (a worker that helped hash took up the wait, and a
    /// stroke's rebuild hung).
    pub fn take(&mut self, stage_file: &Path) -> Option<Previous> {
        assert!(
            rayon::current_thread_index().is_none(),
            "the last build's files are waited for outside the thread pool"
        );
        match self.loading.iter().position(|(p, _)| p == stage_file) {
            Some(k) => self.loading.swap_remove(k).1.join().ok().flatten(),
            None => Previous::load(stage_file),
        }
    }
}

/// Per patch, what the last build left that still holds (`None`: compute it).
pub fn reusable(
    previous: Option<&Previous>,
    keys: &[Hash],
    tables: &[Table],
) -> Vec<Option<(PatchMotion, Vec<u8>)>> {
    use rayon::prelude::*;
    (0..keys.len())
        .into_par_iter()
        .map(|p| {
            let (m, extra) = previous?.take(p, keys[p], &tables[p])?;
            Some((m, extra.to_vec()))
        })
        .collect()
}

/// The keys file of a stage whose side file hashes to `side`.
pub fn keys_file(
    stage_file: &Path,
    side: Hash,
    keys: Vec<Hash>,
    tables: &[Table],
    extra: Vec<Vec<u8>>,
) -> (PathBuf, Vec<u8>) {
    let patches = keys
        .into_iter()
        .zip(tables)
        .zip(extra)
        .map(|((key, table), extra)| Record {
            key,
            table: table.clone(),
            extra,
        })
        .collect();
    let keys = Keys { side, patches };
    (keys_path(stage_file), keys.encode())
}

/// "N of M patches reused", for a stage's line.
pub fn note(reused: usize, total: usize) -> String {
    format!("{reused} of {total} patches reused")
}

/// A side file made a run of patches at a time ([`side_pieces`]): its head, then each
/// patch's bytes, a piece each (the file is the pieces one after another); the file's size
/// and hash; what each patch adds to the stage file's summary; its index (from the sizes
/// made, not read through again); and each patch's figures for the keys file.
pub struct SidePieces {
    pub pieces: Vec<Vec<u8>>,
    pub file: (u64, Hash),
    pub sums: Vec<PatchSums>,
    pub index: MotionIndex,
    pub figures: Vec<Vec<u8>>,
}

/// Patches made a run at a time before their bytes are hashed.
const RUN: usize = 512;

/// The side file of `patches` patches, patch `p` being the bytes and figures `make(p)` gives:
/// made in parallel a run of [`RUN`] at a time, in patch order, each run hashed on a thread of
/// its own while the next is made. Each patch's bytes are made in a vector of their own, as
/// soon as the patch is, in memory its thread just freed: painting's stage 6 held every
/// smoothed patch (0.6 GB) and then wrote their 412 MB of bytes into one buffer of fresh
/// memory (1.5 s of its cores, most of it the first touch of each page).
pub fn side_pieces(
    patches: usize,
    make: impl Fn(usize) -> (Vec<u8>, Vec<u8>) + Sync,
) -> SidePieces {
    use crowd_core::trajectories::{encoded_head, sums_of_encoded};
    use rayon::prelude::*;
    let mut sizes = Vec::with_capacity(patches);
    let mut sums = Vec::with_capacity(patches);
    let mut figures = Vec::with_capacity(patches);
    let (pieces, file) = std::thread::scope(|s| {
        let (send, receive) = std::sync::mpsc::channel::<Vec<Vec<u8>>>();
        let hasher = s.spawn(move || {
            let mut pieces = Vec::with_capacity(patches + 1);
            pieces.push(encoded_head(patches).to_vec());
            let mut hash = Hash::pieces();
            hash.update(&pieces[0]);
            for run in receive {
                run.iter().for_each(|bytes| hash.update(bytes));
                pieces.extend(run);
            }
            (pieces, hash.finish())
        });
        for start in (0..patches).step_by(RUN) {
            let run: Vec<(Vec<u8>, Vec<u8>, PatchSums)> = (start..(start + RUN).min(patches))
                .into_par_iter()
                .map(|p| {
                    let (bytes, figures) = make(p);
                    let sums = sums_of_encoded(&bytes).expect("a patch's bytes, as encoded");
                    (bytes, figures, sums)
                })
                .collect();
            let mut bytes = Vec::with_capacity(run.len());
            for (b, f, s) in run {
                sizes.push((b.len(), s.trajectories()));
                sums.push(s);
                figures.push(f);
                bytes.push(b);
            }
            // The hasher ends only when the sender is dropped: it is there to receive.
            let _ = send.send(bytes);
        }
        drop(send);
        hasher
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
    });
    SidePieces {
        pieces,
        file,
        sums,
        index: MotionIndex::of_sizes(sizes),
        figures,
    }
}

/// A reused patch's bytes copied from the last build's side file, its crossings renumbered
/// from the table they were numbered by (`was`) to its table now.
pub fn renumbered(bytes: &[u8], was: &Table, now: &Table) -> Vec<u8> {
    let mut bytes = bytes.to_vec();
    crowd_core::trajectories::renumber_encoded(&mut bytes, |c| now.global(was.local(c)))
        .expect("a side file's patch, read through by its index");
    bytes
}

#[cfg(test)]
mod tests {
    use super::*;
    use crowd_core::trajectories::{
        ControlPoint, PointKind, Summing, Trajectory, encode_motion, encode_patch_bytes, summarize,
    };
    use glam::DVec2;

    fn patch(k: usize) -> PatchMotion {
        PatchMotion {
            standers: (0..k % 2).map(|i| DVec2::new(i as f64, 1.0)).collect(),
            trajectories: (0..k)
                .map(|j| Trajectory {
                    entry: j as u32,
                    exit: (j + k) as u32,
                    points: (0..2 + j)
                        .map(|i| ControlPoint {
                            pos: DVec2::new(i as f64 * 0.5, k as f64),
                            t: i as f64 * 7.5,
                            kind: if i == 1 {
                                PointKind::Pause
                            } else {
                                PointKind::Sample
                            },
                        })
                        .collect(),
                })
                .collect(),
        }
    }

    #[test]
    fn a_side_file_of_reused_and_made_patches_is_the_encoding_of_their_motion() {
        // More patches than a run, so that runs follow one another through the hasher.
        for count in [0, 7, RUN + 3] {
            let motion: Vec<PatchMotion> = (0..count).map(|k| patch(k % 9)).collect();
            let encoded: Vec<Vec<u8>> = motion.iter().map(encode_patch_bytes).collect();
            // Patches numbered alike before and after (tables with no crossings) are copied
            // as they were; every other patch is made now.
            let same = Table::default();
            let side = side_pieces(count, |p| match p % 2 {
                0 => (renumbered(&encoded[p], &same, &same), vec![p as u8]),
                _ => (encode_patch_bytes(&motion[p]), vec![p as u8]),
            });
            let bytes = side.pieces.concat();
            assert_eq!(bytes, encode_motion(&motion));
            assert_eq!(side.file, (bytes.len() as u64, Hash::of(&bytes)));
            let read = MotionIndex::of(Path::new("m.bin"), &bytes).unwrap();
            assert_eq!(side.index.patches(), count);
            for p in 0..count {
                assert_eq!(side.index.span(p), read.span(p), "patch {p}");
                assert_eq!(
                    side.index.trajectories(p),
                    read.trajectories(p),
                    "patch {p}"
                );
                assert_eq!(side.figures[p], vec![p as u8]);
            }
            let mut summing = Summing::new(20.0);
            side.sums.iter().for_each(|s| summing.add_sums(s));
            assert_eq!(summing.finish(), summarize(&motion, 20.0));
        }
    }
}
