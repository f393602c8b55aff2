//! Stage 5 split over processes: each shard clears its patches ([`crate::collide_shard`]) and
//! writes them, with their reports, to `shards/collide-I-of-N.ron` (and its `.bin`); the
//! gathering build reads every shard's file back and hands the parts, in patch order, to the
//! same encoder one process uses, so `collided.ron` and `collided.bin` are the same bytes.

use crate::PatchReport;
use crowd_core::files::{Header, SideFile, Writes};
use crowd_core::trajectories::{PatchMotion, decode_motion, encode_motion};
use crowd_core::{Error, Hash, Result, Shard};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The folder, in a build folder, that shard files go to and are gathered from.
pub const SHARDS_DIR: &str = "shards";

/// One shard's part of stage 5.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShardFile {
    /// Stage 5's header: the hash is of the inputs the whole stage reads, so a shard made
    /// from another painting or other settings is never gathered.
    pub header: Header,
    pub shard: Shard,
    /// Its patches, in patch order, each with its report; their motion is in the side file.
    pub patches: Vec<u32>,
    pub reports: Vec<PatchReport>,
    pub motion: SideFile,
}

/// Where shard `shard`'s file of stage 5 lies in the build folder `dir`.
pub fn shard_path(dir: &Path, shard: Shard) -> PathBuf {
    dir.join(SHARDS_DIR)
        .join(format!("{}-{}.ron", crate::STAGE, shard.tag()))
}

/// The files of `shard`'s part (`parts`, in patch order) for a build folder `dir`.
pub fn encode_shard(
    dir: &Path,
    shard: Shard,
    hash: Hash,
    parts: Vec<(PatchMotion, PatchReport)>,
) -> Writes {
    let (motion, reports): (Vec<PatchMotion>, Vec<PatchReport>) = parts.into_iter().unzip();
    let path = shard_path(dir, shard);
    let bytes = encode_motion(&motion);
    let (side, record) = SideFile::beside(&path, &bytes);
    let file = ShardFile {
        header: Header::new(crate::STAGE, crate::VERSION, hash),
        shard,
        patches: reports.iter().map(|r| r.patch).collect(),
        reports,
        motion: record,
    };
    let ron = crowd_core::files::to_ron(&file).into_bytes();
    vec![(side, bytes), (path, ron)]
}

/// Stage 5's motion and reports for every patch, put together from the shard files in `dir`
/// (`shards/collide-I-of-N.ron`): all N of one count, each made for `hash` and holding
/// exactly the patches its shard clears of `matched` (stage 4's motion). Refused, naming the
/// file, when one is missing, stale or not what its shard clears.
pub fn gather(
    dir: &Path,
    hash: Hash,
    matched: &[PatchMotion],
) -> Result<(Vec<PatchMotion>, Vec<PatchReport>)> {
    let count = shard_count(dir)?;
    let mut motion: Vec<Option<(PatchMotion, PatchReport)>> = vec![None; matched.len()];
    for index in 0..count {
        let shard = Shard::new(index, count).expect("index < count");
        let path = shard_path(dir, shard);
        if !path.exists() {
            return Err(Error::stage_file(
                &path,
                format!(
                    "is missing: gathering {count} shards needs every one of them \
                     (run `crowd build --shard {shard}` and copy its {SHARDS_DIR}/ here)"
                ),
            ));
        }
        let file: ShardFile = crowd_core::files::read_ron(&path)?;
        let expected = Header::new(crate::STAGE, crate::VERSION, hash);
        if file.header != expected || file.shard != shard {
            return Err(Error::stage_file(
                &path,
                format!(
                    "was made for other inputs (stage {} version {}, inputs {}, shard {}) \
                     than this build's (version {}, inputs {}, shard {shard}): run that shard \
                     again on this painting and settings",
                    file.header.stage,
                    file.header.version,
                    file.header.input_hash.short(),
                    file.shard,
                    crate::VERSION,
                    hash.short()
                ),
            ));
        }
        let mut mine: Vec<u32> = crate::shard_patches(matched, shard)
            .into_iter()
            .map(|p| p as u32)
            .collect();
        mine.sort_unstable();
        let reported: Vec<u32> = file.reports.iter().map(|r| r.patch).collect();
        if file.patches != mine || reported != mine {
            return Err(Error::stage_file(
                &path,
                format!(
                    "holds patches other than the {} its shard clears",
                    mine.len()
                ),
            ));
        }
        let parts = decode_motion(&path, &file.motion.read(&path)?)?;
        if parts.len() != mine.len() {
            return Err(Error::stage_file(
                &path,
                format!(
                    "has motion for {} patches, not its {}",
                    parts.len(),
                    mine.len()
                ),
            ));
        }
        for ((m, r), p) in parts.into_iter().zip(file.reports).zip(mine) {
            motion[p as usize] = Some((m, r));
        }
    }
    Ok(motion
        .into_iter()
        .map(|m| m.expect("every patch is dealt to one shard"))
        .unzip())
}

/// How many shards the files in `dir/shards` are of: one count for all of them.
fn shard_count(dir: &Path) -> Result<u32> {
    let folder = dir.join(SHARDS_DIR);
    let entries =
        std::fs::read_dir(&folder).map_err(|e| Error::io(&folder, "read the shards folder", e))?;
    let prefix = format!("{}-", crate::STAGE);
    let mut counts = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| Error::io(&folder, "read the shards folder", e))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(tag) = name
            .strip_prefix(&prefix)
            .and_then(|n| n.strip_suffix(".ron"))
        else {
            continue;
        };
        match tag.split_once("-of-").map(|(_, n)| n.parse::<u32>()) {
            Some(Ok(n)) if n > 0 => counts.push(n),
            _ => {
                return Err(Error::stage_file(
                    &entry.path(),
                    "is not named as a shard file (collide-I-of-N.ron)",
                ));
            }
        }
    }
    counts.sort_unstable();
    counts.dedup();
    match counts.as_slice() {
        [n] => Ok(*n),
        [] => Err(Error::stage_file(
            &folder,
            "holds no shard file of stage 5 (collide-I-of-N.ron): run `crowd build --shard I/N` \
             for every I and copy each one's shards/ folder here",
        )),
        many => Err(Error::stage_file(
            &folder,
            format!("holds shard files of {many:?} shards at once: keep one build's"),
        )),
    }
}
