//! Stage 3 split over processes: `crowd build --shard I/N --until optimize` solves shard I's
//! run of the world's regions (runs of like estimated cost: [`region_costs`]) and writes their
//! results to `shards/optimize-I-of-N.ron` (and `.bin`, in `regions.bin`'s form). Regions are
//! independent (their seams are held by a rule), so a later build of the whole stage (each
//! shard's `crowd build --shard I/N`, or the gather) takes every region from the parts
//! ([`read_parts`]) instead of solving it again: the million's stage 3, 95 s in every shard,
//! becomes an eighth of it in each, and 3 s to put together.

use crate::Known;
use crate::region::{Cut, Solved};
use crowd_core::config::OptimizeSettings;
use crowd_core::files::{Header, SideFile, Writes};
use crowd_core::patterns::Patterns;
use crowd_core::shard::{SHARDS_DIR, part_path};
use crowd_core::{Error, Hash, PatchGraph, Result, Shard};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// One shard's regions: which of the cut's (`first..end`) and their results in the side file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionsPart {
    pub header: Header,
    pub shard: Shard,
    pub first: u32,
    pub end: u32,
    pub results: SideFile,
}

/// What each region of the world's cut costs to solve, roughly: the people its patches ask
/// for (walkers and standers), plus one a patch. For dealing regions to shards
/// ([`Shard::run`]); a poor estimate only unbalances the shards, it changes no result.
pub fn region_costs(graph: &PatchGraph, settings: &OptimizeSettings) -> Vec<u64> {
    let area = graph.patch_area();
    let cut = Cut::new(graph, settings.region_patches);
    (cut.regions.iter())
        .map(|(_, own, _)| {
            (own.iter())
                .map(|&p| {
                    let patch = &graph.patches[p];
                    let people = (patch.walker_density + patch.stander_density) * area;
                    1 + people.clamp(0.0, 1e9) as u64
                })
                .sum()
        })
        .collect()
}

/// The files of `shard`'s part: `solved` the results of the regions `regions`, in order.
/// `hash` is stage 3's input hash.
pub fn encode_part(
    dir: &Path,
    shard: Shard,
    hash: Hash,
    regions: std::ops::Range<usize>,
    solved: &[Solved],
) -> Writes {
    let path = part_path(dir, Patterns::STAGE, shard);
    let bytes = crate::known::encode(solved);
    let (side, results) = SideFile::beside(&path, &bytes);
    let part = RegionsPart {
        header: header(hash),
        shard,
        first: regions.start as u32,
        end: regions.end as u32,
        results,
    };
    let ron = crowd_core::files::to_ron(&part).into_bytes();
    vec![(side, bytes), (path, ron)]
}

fn header(hash: Hash) -> Header {
    Header::new(Patterns::STAGE, Patterns::VERSION, hash)
}

/// Every region result in the stage 3 parts in `dir/shards` (any count of shards, any of them
/// missing: a region no part holds is solved again), and how many parts there were. A part made
/// for other inputs than `hash`, or damaged, is refused, naming it: taking it would be harmless
/// (its regions' hashes match none of this build's) but would solve the world again unasked.
pub fn read_parts(dir: &Path, hash: Hash) -> Result<(Known, usize)> {
    let mut known = Known::new();
    let paths = part_paths(dir)?;
    for path in &paths {
        let part: RegionsPart = crowd_core::files::read_ron(path)?;
        if part.header != header(hash) {
            return Err(Error::stage_file(
                path,
                format!(
                    "was made for other inputs (stage {} version {}, inputs {}) than this \
                     build's (version {}, inputs {}): run `crowd build --shard {} --until \
                     optimize` again on this painting and settings, or remove it",
                    part.header.stage,
                    part.header.version,
                    part.header.input_hash.short(),
                    Patterns::VERSION,
                    hash.short(),
                    part.shard
                ),
            ));
        }
        let bytes = part.results.read(path)?;
        let results = crate::known::decode(&bytes).ok_or_else(|| {
            Error::stage_file(
                &path.with_file_name(&part.results.file),
                "is not a whole list of region results (expected regions.bin's form)",
            )
        })?;
        if results.len() != part.end.saturating_sub(part.first) as usize {
            return Err(Error::stage_file(
                path,
                format!(
                    "names regions {}..{} but holds {} results",
                    part.first,
                    part.end,
                    results.len()
                ),
            ));
        }
        known.extend(results);
    }
    Ok((known, paths.len()))
}

/// The stage 3 parts in `dir/shards` (`optimize-I-of-N.ron`), sorted by name.
fn part_paths(dir: &Path) -> Result<Vec<PathBuf>> {
    let folder = dir.join(SHARDS_DIR);
    let entries = match std::fs::read_dir(&folder) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(Error::io(&folder, "read the shards folder", e)),
    };
    let prefix = format!("{}-", Patterns::STAGE);
    let mut paths = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| Error::io(&folder, "read the shards folder", e))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with(&prefix) && name.ends_with(".ron") && name.contains("-of-") {
            paths.push(entry.path());
        }
    }
    paths.sort();
    Ok(paths)
}
