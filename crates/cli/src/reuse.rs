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

/// A patch of a side file made of bytes ([`side_bytes`]): the last build's, numbered by its
/// table, or made now.
pub enum PatchBytes<'a> {
    Reused(&'a [u8], &'a Table),
    Made(PatchMotion),
}

/// The side file of `patches` (in patch order), each reused patch copied and renumbered from
/// its last build's table to its table in `tables`, each made one encoded, in parallel; with
/// what each patch adds to the stage file's summary, and the file's index (from the sizes
/// laid out, not read through again). The bytes of the motion decoded,
/// renumbered and encoded again (`crowd_core::trajectories::encode_motion`), without
/// decoding: a stroke's stage 6 decoded painting's 17 million points (0.54 GB of fresh
/// memory) and encoded them again, a tenth of the stroke.
pub fn side_bytes(
    patches: &[PatchBytes],
    tables: &[Table],
) -> (Vec<u8>, Vec<PatchSums>, MotionIndex) {
    use crowd_core::trajectories::{self as tr, encoded_head};
    use rayon::prelude::*;
    let bytes_of = |p: &PatchBytes| match p {
        PatchBytes::Reused(bytes, _) => bytes.len(),
        PatchBytes::Made(motion) => tr::encoded_size(motion),
    };
    let head = encoded_head(patches.len());
    let sizes: Vec<usize> = patches.iter().map(bytes_of).collect();
    let body: usize = sizes.iter().sum();
    // Every byte after the head is written once, by its patch's part below: a buffer cleared
    // first was a tenth of a second of one core on a stroke (the allocator clears memory it
    // takes back), with the other idle.
    let mut out: Vec<u8> = Vec::with_capacity(head.len() + body);
    out.extend_from_slice(&head);
    let mut rest = &mut out.spare_capacity_mut()[..body];
    let mut parts = Vec::with_capacity(patches.len());
    for &size in &sizes {
        let (part, tail) = std::mem::take(&mut rest).split_at_mut(size);
        parts.push(part);
        rest = tail;
    }
    (parts.into_par_iter().zip(patches).zip(tables)).for_each(|((part, p), table)| match p {
        PatchBytes::Reused(bytes, was) => {
            let part = part.write_copy_of_slice(bytes);
            tr::renumber_encoded(part, |c| table.global(was.local(c)))
                .expect("a side file's patch, read through by its index");
        }
        PatchBytes::Made(motion) => tr::encode_patch_uninit(motion, part),
    });
    // SAFETY: the parts split the first `body` bytes of the spare room between them, and each
    // part was written whole above (`write_copy_of_slice` copies a patch's bytes of the same
    // size; `encode_patch_uninit` writes every byte of its part or panics).
    unsafe { out.set_len(head.len() + body) };
    let mut starts = Vec::with_capacity(sizes.len());
    sizes.iter().fold(head.len(), |at, &size| {
        starts.push(at);
        at + size
    });
    let sums: Vec<PatchSums> = (starts.par_iter().zip(&sizes))
        .map(|(&at, &size)| {
            tr::sums_of_encoded(&out[at..at + size])
                .expect("a patch's bytes, encoded or read through")
        })
        .collect();
    let index = MotionIndex::of_sizes(sizes.into_iter().zip(sums.iter().map(|s| s.trajectories())));
    (out, sums, index)
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
        let motion: Vec<PatchMotion> = (0..7).map(patch).collect();
        let encoded: Vec<Vec<u8>> = motion.iter().map(encode_patch_bytes).collect();
        // Patches numbered alike before and after (tables with no crossings) are kept as
        // they were; every other patch is made now.
        let same = Table::default();
        let patches: Vec<PatchBytes> = (0..motion.len())
            .map(|p| match p % 2 {
                0 => PatchBytes::Reused(&encoded[p], &same),
                _ => PatchBytes::Made(motion[p].clone()),
            })
            .collect();
        let tables = vec![Table::default(); motion.len()];
        let (bytes, sums, index) = side_bytes(&patches, &tables);
        assert_eq!(bytes, encode_motion(&motion));
        let read = MotionIndex::of(Path::new("m.bin"), &bytes).unwrap();
        for p in 0..motion.len() {
            assert_eq!(index.span(p), read.span(p), "patch {p}");
            assert_eq!(index.trajectories(p), read.trajectories(p), "patch {p}");
        }
        let mut summing = Summing::new(20.0);
        sums.iter().for_each(|s| summing.add_sums(s));
        assert_eq!(summing.finish(), summarize(&motion, 20.0));
    }
}
