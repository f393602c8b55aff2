//! Shards: one of `count` processes doing its part of the stages that split by patch
//! (`crowd build --shard I/N`), whose files `crowd build --gather` puts together into the
//! bytes one process would have written (DESIGN.md, "Beyond one machine").

use crate::error::{Error, Result};
use crate::files::{Header, SideFile, Writes};
use crate::trajectories::{MotionIndex, PatchMotion, encode_motion, encoded_head};
use rayon::prelude::*;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::str::FromStr;

/// Shard `index` of `count` (`index < count`, `count >= 1`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Shard {
    index: u32,
    count: u32,
}

impl Shard {
    /// Shard `index` of `count`; `None` unless `index < count`.
    pub fn new(index: u32, count: u32) -> Option<Shard> {
        (index < count).then_some(Shard { index, count })
    }

    pub fn index(self) -> u32 {
        self.index
    }

    pub fn count(self) -> u32 {
        self.count
    }

    /// Its run of items `0..costs.len()`: the runs of the shards, in order, one after another,
    /// each of about the same total cost. Items next to each other in the list (patches in
    /// row order) stay together, so a shard's patches neighbour few of other shards'.
    pub fn run(self, costs: &[u64]) -> std::ops::Range<usize> {
        let total: u128 = costs.iter().map(|&c| u128::from(c)).sum();
        let n = u128::from(self.count);
        // Item k starts shard s's run when the cost before it first reaches total * s / n.
        let start_of = |s: u128| -> usize {
            let goal = total * s;
            let mut before = 0u128;
            for (k, &c) in costs.iter().enumerate() {
                if before * n >= goal {
                    return k;
                }
                before += u128::from(c);
            }
            costs.len()
        };
        let i = u128::from(self.index);
        let end = if self.index + 1 == self.count {
            costs.len()
        } else {
            start_of(i + 1)
        };
        start_of(i).min(end)..end
    }

    /// The name its files carry: `2-of-8` (0-based, as `--shard 2/8` says).
    pub fn tag(self) -> String {
        format!("{}-of-{}", self.index, self.count)
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl FromStr for Shard {
    type Err = String;

    /// `I/N`: shard I (counted from 0) of N.
    fn from_str(s: &str) -> Result<Shard, String> {
        let wrong = || format!("expected I/N with 0 <= I < N (as in 0/4 ... 3/4), not {s:?}");
        let (i, n) = s.split_once('/').ok_or_else(wrong)?;
        let (i, n) = (i.trim().parse::<u32>(), n.trim().parse::<u32>());
        match (i, n) {
            (Ok(i), Ok(n)) => Shard::new(i, n).ok_or_else(wrong),
            _ => Err(wrong()),
        }
    }
}

/// `patches` and every patch next to one of them (sharing a border side), sorted.
pub fn with_neighbours(graph: &crate::PatchGraph, patches: &[usize]) -> Vec<usize> {
    let mut all: Vec<usize> = patches.to_vec();
    for &p in patches {
        let c = graph.patches[p].cell;
        for (dc, dr) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
            let (col, row) = (i64::from(c.col) + dc, i64::from(c.row) + dr);
            if let (Ok(col), Ok(row)) = (u32::try_from(col), u32::try_from(row))
                && let Some(q) = graph.patch_at(crate::Cell { col, row })
            {
                all.push(q);
            }
        }
    }
    all.sort_unstable();
    all.dedup();
    all
}

/// The run of the world's border numbers from the first border of any of `patches` to the
/// last: the crossings a shard holds ([`crate::patterns::HeldCrossings::window`]). Borders are
/// numbered patch by patch (each patch's east and north), so the borders of a run of patches
/// and their surroundings are a run of about as many rows.
pub fn border_window(graph: &crate::PatchGraph, patches: &[usize]) -> std::ops::Range<u32> {
    let mut mine = vec![false; graph.patches.len()];
    patches.iter().for_each(|&p| mine[p] = true);
    let touched = |b: &crate::patch_graph::Border| mine[b.a.0 as usize] || mine[b.b.0 as usize];
    let first = graph.borders.iter().position(touched);
    let last = graph.borders.iter().rposition(touched);
    match first.zip(last) {
        Some((first, last)) => first as u32..last as u32 + 1,
        None => 0..0,
    }
}

/// The folder, in a build folder, that shard files go to and are gathered from.
pub const SHARDS_DIR: &str = "shards";

/// One shard's part of a stage that splits by patch: its patches (in patch order), a report
/// of type `R` for each, and their motion in the side file. The header's hash is of what the
/// whole stage reads, so a part made from another painting or other settings is never
/// gathered.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Part<R> {
    pub header: Header,
    pub shard: Shard,
    pub patches: Vec<u32>,
    pub reports: Vec<R>,
    pub motion: SideFile,
}

/// Where `shard`'s part of the stage `stage` lies in the build folder `dir`:
/// `shards/STAGE-I-of-N.ron` (its motion beside it, `.bin`).
pub fn part_path(dir: &Path, stage: &str, shard: Shard) -> PathBuf {
    dir.join(SHARDS_DIR)
        .join(format!("{stage}-{}.ron", shard.tag()))
}

/// What each patch costs the stages that split, for dealing patches to shards
/// ([`Shard::run`]): its walkers (the crossings that enter it, each a trajectory of stage 4's
/// motion), plus one. `counts` gives patch `p`'s walkers.
pub fn costs(patches: usize, counts: impl Fn(usize) -> usize) -> Vec<u64> {
    (0..patches).map(|p| counts(p) as u64 + 1).collect()
}

/// The files of `shard`'s part of a stage (`header` names it): `parts` are its patches, in
/// patch order, each with its motion and report.
pub fn encode_part<R: Serialize>(
    dir: &Path,
    header: Header,
    shard: Shard,
    parts: Vec<(u32, &PatchMotion, R)>,
) -> Writes {
    let path = part_path(dir, &header.stage, shard);
    let mut patches = Vec::with_capacity(parts.len());
    let mut motion = Vec::with_capacity(parts.len());
    let mut reports = Vec::with_capacity(parts.len());
    for (p, m, r) in parts {
        patches.push(p);
        motion.push(m);
        reports.push(r);
    }
    let bytes = encode_motion(&motion);
    let (side, record) = SideFile::beside(&path, &bytes);
    let file = Part {
        header,
        shard,
        patches,
        reports,
        motion: record,
    };
    let ron = crate::files::to_ron(&file).into_bytes();
    vec![(side, bytes), (path, ron)]
}

/// One shard's part of a stage written a patch at a time, as [`encode_part`] writes it whole:
/// its side file streamed to its temporary name (`files::Streamed`, put in place by the
/// build's commit), so that a shard never holds its part's motion, decoded or encoded (the
/// million's stage 6 part: 0.5 GB of bytes, and more decoded).
pub struct PartWriter {
    path: PathBuf,
    side: crate::files::Streamed,
    patches: Vec<u32>,
    count: usize,
}

impl PartWriter {
    /// The part of `stage` for `shard` in `dir/shards` (which must exist), of `count` patches.
    pub fn create(dir: &Path, stage: &str, shard: Shard, count: usize) -> Result<PartWriter> {
        let path = part_path(dir, stage, shard);
        let (side_path, _) = SideFile::beside(&path, &[]);
        let mut side = crate::files::Streamed::create(&side_path)?;
        side.write(&encoded_head(count))?;
        Ok(PartWriter {
            path,
            side,
            patches: Vec::with_capacity(count),
            count,
        })
    }

    /// The next patch, `p` (in patch order), its bytes as
    /// [`crate::trajectories::encode_patch_bytes`] makes them.
    pub fn write(&mut self, p: u32, encoded: &[u8]) -> Result<()> {
        self.patches.push(p);
        self.side.write(encoded)
    }

    /// The side file (at its temporary name) and the part's file (path and bytes), whose
    /// `header` names the stage, with every patch's report.
    pub fn finish<R: Serialize>(
        self,
        header: Header,
        shard: Shard,
        reports: Vec<R>,
    ) -> Result<(crate::files::StreamedFile, (PathBuf, Vec<u8>))> {
        assert_eq!(
            self.patches.len(),
            self.count,
            "every patch of the part written"
        );
        assert_eq!(reports.len(), self.count, "a report for every patch");
        let side = self.side.finish()?;
        let (_, mut motion) = SideFile::beside(&self.path, &[]);
        (motion.bytes, motion.hash) = (side.bytes, side.hash);
        let file = Part {
            header,
            shard,
            patches: self.patches,
            reports,
            motion,
        };
        let ron = crate::files::to_ron(&file).into_bytes();
        Ok((side, (self.path, ron)))
    }
}

/// Every patch's motion and report, put together from the parts of the stage `header` names
/// in `dir/shards`: all N parts of one count, each made for `header` and holding exactly the
/// patches its shard's run of `costs` ([`costs`]) gives it (refused, naming the file, when one
/// is missing, stale or holds other patches). Left encoded: the side file one process would
/// have written ([`encode_motion`] of every patch: the parts' patch bytes one after another),
/// streamed to `side`'s temporary name part by part, and every patch's report. `each` sees every patch's
/// motion in patch order, decoded one part at a time: the world's motion is never held, decoded
/// (the million's was 11 GB with its bytes) or encoded (4.2 GB).
pub fn gather_encoded<R: DeserializeOwned + Clone>(
    dir: &Path,
    header: &Header,
    costs: &[u64],
    mut each: impl FnMut(&PatchMotion),
    side: &Path,
) -> Result<Gathered<R>> {
    let mut out = crate::files::Streamed::create(side)?;
    out.write(&encoded_head(costs.len()))?;
    let mut reports = Vec::with_capacity(costs.len());
    let mut parts = Vec::new();
    for_each_part(dir, header, costs, |part: Part<R>, read| {
        // A run of patches read, copied and decoded at a time (in parallel): a part read whole
        // and decoded whole were the million's smooth gather's peak (0.54 GB and 0.77 GB).
        let io = |e| Error::io(&read.side, "read", e);
        let mut file = std::fs::File::open(&read.side).map_err(io)?;
        let patches = read.index.patches();
        if patches > 0 {
            file.seek(SeekFrom::Start(read.index.span(0).start as u64))
                .map_err(io)?;
        }
        let mut bytes = Vec::new();
        for run in (0..patches).step_by(DECODED_AT_ONCE) {
            let end = (run + DECODED_AT_ONCE).min(patches);
            let base = read.index.span(run).start;
            bytes.resize(read.index.span(end - 1).end - base, 0);
            file.read_exact(&mut bytes).map_err(io)?;
            out.write(&bytes)?;
            let decoded: Vec<Result<PatchMotion>> = (run..end)
                .into_par_iter()
                .map(|p| read.index.decode_in(&read.side, &bytes, base, p))
                .collect();
            for m in decoded {
                each(&m?);
            }
        }
        reports.extend(part.reports);
        parts.push((read.path, read.side, read.index));
        Ok(())
    })?;
    let motion = crate::trajectories::LazyMotion::of_parts(parts)?;
    Ok(Gathered {
        side: out.finish()?,
        reports,
        motion,
    })
}

/// Patches of a part [`gather_encoded`] decodes at once.
const DECODED_AT_ONCE: usize = 256;

/// What [`gather_encoded`] puts together.
pub struct Gathered<R> {
    /// The side file one process would have written, written to its temporary name.
    pub side: crate::files::StreamedFile,
    /// Every patch's report, in patch order.
    pub reports: Vec<R>,
    /// Every patch's motion, left in the parts' side files.
    pub motion: crate::trajectories::LazyMotion,
}

/// A part's file as [`read_part`] checked it: its path, its side file's path and index.
struct ReadPart {
    path: PathBuf,
    side: PathBuf,
    index: MotionIndex,
}

/// Calls `take` with every part of the stage `header` names, in shard order (so in patch
/// order), as [`read_part`] reads and checks it.
fn for_each_part<R: DeserializeOwned + Clone>(
    dir: &Path,
    header: &Header,
    costs: &[u64],
    mut take: impl FnMut(Part<R>, ReadPart) -> Result<()>,
) -> Result<()> {
    let count = part_count(dir, &header.stage)?;
    let mut next = 0usize;
    for index in 0..count {
        let shard = Shard::new(index, count).expect("index < count");
        let path = part_path(dir, &header.stage, shard);
        let (file, read) = read_part::<R>(&path, header, shard, costs)?;
        let run = shard.run(costs);
        if run.start != next {
            return Err(Error::stage_file(
                &dir.join(SHARDS_DIR),
                format!("has no shard holding patch {next}"),
            ));
        }
        next = run.end;
        take(file, read)?;
    }
    if next != costs.len() {
        return Err(Error::stage_file(
            &dir.join(SHARDS_DIR),
            format!("has no shard holding patch {next}"),
        ));
    }
    Ok(())
}

/// `shard`'s part at `path` and its side file, refused unless it is there, made for `header`,
/// and holds exactly the patches its run of `costs` gives it, with motion for each.
fn read_part<R: DeserializeOwned + Clone>(
    path: &Path,
    header: &Header,
    shard: Shard,
    costs: &[u64],
) -> Result<(Part<R>, ReadPart)> {
    let count = shard.count();
    if !path.exists() {
        return Err(Error::stage_file(
            path,
            format!(
                "is missing: gathering {count} shards needs every one of them \
                 (run `crowd build --shard {shard}` and copy its {SHARDS_DIR}/ here)"
            ),
        ));
    }
    let file: Part<R> = crate::files::read_ron(path)?;
    if file.header != *header || file.shard != shard {
        return Err(Error::stage_file(
            path,
            format!(
                "was made for other inputs (stage {} version {}, inputs {}, shard {}) than \
                 this build's (version {}, inputs {}, shard {shard}): run that shard again \
                 on this painting and settings",
                file.header.stage,
                file.header.version,
                file.header.input_hash.short(),
                file.shard,
                header.version,
                header.input_hash.short()
            ),
        ));
    }
    let mine: Vec<u32> = shard.run(costs).map(|p| p as u32).collect();
    if file.patches != mine || file.reports.len() != mine.len() {
        return Err(Error::stage_file(
            path,
            format!("holds patches other than the {} its shard does", mine.len()),
        ));
    }
    // Its side file checked (size and hash) and indexed, each read through without keeping
    // its bytes: a part's were the million's smooth gather's peak (0.54 GB).
    let side = file.motion.check(path)?;
    let index = MotionIndex::of_file(&side)?;
    if index.patches() != mine.len() {
        return Err(Error::stage_file(
            path,
            format!(
                "has motion for {} patches, not its {}",
                index.patches(),
                mine.len()
            ),
        ));
    }
    let read = ReadPart {
        path: path.to_path_buf(),
        side,
        index,
    };
    Ok((file, read))
}

/// How many shards the parts of `stage` in `dir/shards` are of: one count for all of them.
fn part_count(dir: &Path, stage: &str) -> Result<u32> {
    let folder = dir.join(SHARDS_DIR);
    let none = || {
        Error::stage_file(
            &folder,
            format!(
                "holds no shard file of stage {stage} ({stage}-I-of-N.ron): run `crowd build \
                 --shard I/N` for every I and copy each one's {SHARDS_DIR}/ folder here"
            ),
        )
    };
    let entries = match std::fs::read_dir(&folder) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Err(none()),
        Err(e) => return Err(Error::io(&folder, "read the shards folder", e)),
    };
    let prefix = format!("{stage}-");
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
                    format!("is not named as a shard file ({stage}-I-of-N.ron)"),
                ));
            }
        }
    }
    counts.sort_unstable();
    counts.dedup();
    match counts.as_slice() {
        [n] => Ok(*n),
        [] => Err(none()),
        many => Err(Error::stage_file(
            &folder,
            format!("holds {stage} shard files of {many:?} shards at once: keep one build's"),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A part written a patch at a time is the part [`encode_part`] writes whole: the same
    /// side file and the same `.ron`, once the build's commit puts the side file in place.
    #[test]
    fn a_part_written_a_patch_at_a_time_is_the_part_written_whole() {
        use crate::trajectories::{ControlPoint, PointKind, Trajectory, encode_patch_bytes};
        use glam::DVec2;
        let patch = |k: u32| PatchMotion {
            standers: (0..k % 3).map(|i| DVec2::new(f64::from(i), 0.5)).collect(),
            trajectories: (0..k % 4)
                .map(|i| Trajectory {
                    entry: k + i,
                    exit: k * 2 + i,
                    points: (0..2 + i)
                        .map(|j| ControlPoint {
                            pos: DVec2::new(f64::from(j) * 1.5, f64::from(k)),
                            t: f64::from(j) + 0.25,
                            kind: PointKind::Sample,
                        })
                        .collect(),
                })
                .collect(),
        };
        let motion: Vec<PatchMotion> = (0..7).map(patch).collect();
        let shard = Shard::new(1, 3).unwrap();
        let header = Header::new("smooth", 4, crate::Hash::of(b"made from"));
        let whole = tempfile::tempdir().unwrap();
        std::fs::create_dir(whole.path().join(SHARDS_DIR)).unwrap();
        let parts = (motion.iter().enumerate())
            .map(|(p, m)| (p as u32 + 10, m, [p as u64; 3]))
            .collect();
        let writes = encode_part(whole.path(), header.clone(), shard, parts);
        let streamed = tempfile::tempdir().unwrap();
        std::fs::create_dir(streamed.path().join(SHARDS_DIR)).unwrap();
        let mut part = PartWriter::create(streamed.path(), "smooth", shard, motion.len()).unwrap();
        for (p, m) in motion.iter().enumerate() {
            part.write(p as u32 + 10, &encode_patch_bytes(m)).unwrap();
        }
        let reports: Vec<[u64; 3]> = (0..motion.len()).map(|p| [p as u64; 3]).collect();
        let (side, ron) = part.finish(header, shard, reports).unwrap();
        let mut staging = crate::files::Staging::new();
        staging.stage_streamed(side);
        staging.stage(vec![ron]);
        staging.commit().unwrap();
        for (path, bytes) in writes {
            let name = path.strip_prefix(whole.path()).unwrap();
            let written = std::fs::read(streamed.path().join(name)).unwrap();
            assert!(written == bytes, "{} differs", name.display());
        }
    }

    #[test]
    fn shards_read_as_written_and_refuse_what_is_not_one() {
        let s: Shard = "2/8".parse().unwrap();
        assert_eq!(
            (s.index(), s.count(), s.to_string()),
            (2, 8, "2/8".to_string())
        );
        assert_eq!(s.tag(), "2-of-8");
        for bad in ["8/8", "1/0", "-1/4", "a/4", "3", "1/4/2", ""] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }

    #[test]
    fn the_runs_cover_every_item_once_with_like_costs() {
        let costs: Vec<u64> = (0..97u64).map(|k| 1 + (k * 37) % 11).collect();
        let total: u64 = costs.iter().sum();
        for count in 1..9 {
            let mut next = 0;
            for i in 0..count {
                let run = Shard::new(i, count).unwrap().run(&costs);
                assert_eq!(run.start, next, "{count} shards: runs follow one another");
                next = run.end;
                let cost: u64 = costs[run].iter().sum();
                assert!(
                    cost.abs_diff(total / u64::from(count)) <= 11,
                    "{count} shards: shard {i} costs {cost} of {total}"
                );
            }
            assert_eq!(next, costs.len());
        }
        assert_eq!(Shard::new(2, 4).unwrap().run(&[]), 0..0);
    }
}
