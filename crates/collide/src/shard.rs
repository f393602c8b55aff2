//! Stage 5 split over processes. A shard owns a run of patches (in patch order, of like cost:
//! [`crowd_core::Shard::run`]) and clears them and their neighbours ([`crowd_core::shard::with_neighbours`]:
//! stage 6 of a patch needs the pieces its neighbours walk up to their shared crossings); it
//! writes its own patches, with their reports, to `shards/collide-I-of-N.ron` (and `.bin`).
//! The gathering build puts every shard's part together ([`gather_bytes`]): their patches'
//! bytes one after another make the side file one process writes, so `collided.ron` and
//! `collided.bin` are the same bytes.

use crate::PatchReport;
use crowd_core::files::{Header, Writes};
use crowd_core::shard::{Gathered, encode_part, gather_encoded};
use crowd_core::trajectories::PatchMotion;
use crowd_core::{Hash, Result, Shard};
use std::path::Path;

/// What a shard's part of stage 5 is made from: stage 4's input hash (what the matched motion
/// is made from) and the settings. A shard has not the matched file whose bytes stage 5's own
/// hash covers: only its part of it.
pub fn part_hash(match_hash: Hash, inputs: &crate::Inputs) -> Hash {
    crowd_core::Hasher::new(crate::STAGE, crate::VERSION)
        .value("stage 4 inputs", &match_hash)
        .value("inputs", inputs)
        .finish()
}

/// The header of stage 5's parts made from `hash` ([`part_hash`]).
pub fn header(hash: Hash) -> Header {
    Header::new(crate::STAGE, crate::VERSION, hash)
}

/// The files of `shard`'s part: `parts` its own patches (motion and report), in patch order.
pub fn encode_shard(
    dir: &Path,
    shard: Shard,
    hash: Hash,
    parts: Vec<(&PatchMotion, PatchReport)>,
) -> Writes {
    let parts = parts.into_iter().map(|(m, r)| (r.patch, m, r)).collect();
    encode_part(dir, header(hash), shard, parts)
}

/// Stage 5's motion for every patch left in the parts, from every shard's part in
/// `dir/shards` (each made from `hash`, [`part_hash`], holding the patches its shard owns by `costs`): the side
/// file one process would write streamed to `side`'s temporary name, and each patch's report;
/// `each` sees every patch's motion in patch order. The million's gather held the world's
/// motion decoded (1.4 GB) through stages 5 and 6.
pub fn gather_bytes(
    dir: &Path,
    hash: Hash,
    costs: &[u64],
    each: impl FnMut(&PatchMotion),
    side: &Path,
) -> Result<Gathered<PatchReport>> {
    gather_encoded(dir, &header(hash), costs, each, side)
}
