//! A shard's share of the check (`crowd build --shard I/N`, after its stage 6): its own
//! patches of the stage file judged where their motion is (`crowd_check::check_part`), into
//! `shards/check-I-of-N.memo`, which the check after the gather takes in beside its own memo
//! (`take_parts`). The million's stage file was half of its check, on the gathering machine alone.
//!
//! A cache, as `check.memo` is: each share is found by the hash of what it depends on, so a
//! part of another build, damaged or missing, is only work the gathering check does itself.

use anyhow::Result;
use crowd_check::memo::{Memo, Recalled};
use crowd_core::files::StreamedFile;
use crowd_core::patch_keys::Table;
use crowd_core::patterns::Crossings;
use crowd_core::trajectories::{LazyMotion, PatchMotion};
use crowd_core::{Hash, PatchGraph, Shard, shard::SHARDS_DIR};
use std::borrow::Cow;
use std::path::{Path, PathBuf};

/// The file of shard `shard`'s share of the check, in build folder `dir`.
pub fn part_path(dir: &Path, shard: Shard) -> PathBuf {
    dir.join(SHARDS_DIR)
        .join(format!("check-{}.memo", shard.tag()))
}

/// What a shard's stage 6 hands its check: the world, the shard's patches and its part.
pub struct Smoothed<'a> {
    pub graph: &'a PatchGraph,
    pub crossings: Crossings<'a>,
    /// Where each patch's crossings are in the world's (`patch_keys::Seen`).
    pub tables: &'a [Table],
    /// The shard's patches, in patch order, and their stage 6 keys (`crowd_smooth::patch_keys_of`).
    pub own: &'a [usize],
    pub keys: &'a [Hash],
    /// The part's stage file (named in errors) and its side file, written.
    pub part: (&'a Path, &'a StreamedFile),
}

/// The shard's share of the check of `smoothed` (played over `period_s`), as the bytes of
/// `shards/check-I-of-N.memo`, with how many of its patches had their pairs judged (the others
/// border another shard's).
pub fn judge(s: &Smoothed, period_s: f64) -> Result<(Vec<u8>, usize)> {
    let (path, side) = s.part;
    let source = Own {
        path,
        own: s.own,
        motion: LazyMotion::of_side_file(path, side.on_disk())?,
    };
    let world = crowd_check::World {
        graph: s.graph,
        source: &source,
        period_s,
        crossings: Some(s.crossings),
    };
    let part = crowd_check::check_part(&world, Some(s.tables), s.own, s.keys)?;
    let whole = part.judged_pairs();
    Ok((Memo::of(Some(part), None).to_bytes(), whole))
}

/// The shard's patches of the world, read from its part's side file.
struct Own<'a> {
    path: &'a Path,
    own: &'a [usize],
    motion: LazyMotion,
}

impl crowd_check::Source for Own<'_> {
    fn patch(&self, p: usize) -> crowd_core::Result<Cow<'_, PatchMotion>> {
        match self.own.binary_search(&p) {
            Ok(i) => self.motion.patch(i).map(Cow::Owned),
            Err(_) => Err(crowd_core::Error::stage_file(
                self.path,
                format!("holds no patch {p}: the shard's check asked for another's"),
            )),
        }
    }
}

/// Takes into `memo` every shard's share of the check in `dir/shards` that is not older than
/// the folder's `check.memo` (`memo_file`): a check after the shards wrote theirs kept in its
/// own memo all of them that the world still had, so a later check (a brush stroke's rebuild
/// in a gathered folder) need not read them again (the million's: 0.3 GB). A file that is not
/// a whole memo of this check's version is passed over: it is a cache.
pub fn take_parts(dir: &Path, memo_file: &Path, memo: &mut Recalled) {
    let Ok(entries) = std::fs::read_dir(dir.join(SHARDS_DIR)) else {
        return;
    };
    let changed = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    let last_check = changed(memo_file);
    let mut parts: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            let name = p.file_name().and_then(|n| n.to_str()).unwrap_or_default();
            name.starts_with("check-") && name.ends_with(".memo")
        })
        .filter(|p| match (changed(p), last_check) {
            (Some(part), Some(check)) => part >= check,
            _ => true,
        })
        .collect();
    parts.sort();
    for path in parts {
        if let Some(part) = std::fs::read(&path).ok().and_then(|b| Memo::from_bytes(&b)) {
            memo.add(part);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::{Duration, SystemTime};

    fn set_changed(path: &Path, at: SystemTime) {
        let file = std::fs::File::options().write(true).open(path).unwrap();
        file.set_modified(at).unwrap();
    }

    /// A share written after the last check is taken in; one the last check already saw is
    /// not read again; without a memo of the folder, every share is.
    #[test]
    fn shares_older_than_the_last_check_are_not_read_again() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join(SHARDS_DIR)).unwrap();
        let share = |i: u32| {
            let path = part_path(dir.path(), Shard::new(i, 2).unwrap());
            // An empty memo, in its file's form: a whole memo, holding nothing.
            std::fs::write(&path, Memo::default().to_bytes()).unwrap();
            path
        };
        let (old, new) = (share(0), share(1));
        let memo_file = dir.path().join("check.memo");
        std::fs::write(&memo_file, b"the last check's").unwrap();
        let now = SystemTime::now();
        set_changed(&old, now - Duration::from_secs(60));
        set_changed(&memo_file, now - Duration::from_secs(30));
        set_changed(&new, now);
        let taken = |memo_file: &Path| {
            let mut memo = Recalled::default();
            take_parts(dir.path(), memo_file, &mut memo);
            memo.parts_taken()
        };
        assert_eq!(
            taken(&memo_file),
            1,
            "only the share newer than the last check"
        );
        assert_eq!(
            taken(&dir.path().join("none.memo")),
            2,
            "no last check: every share"
        );
    }
}
