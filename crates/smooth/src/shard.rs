//! Stage 6 split over processes: a shard smooths the patches it owns (its run, as in stage
//! 5), from the collided motion of those patches and their neighbours ([`crate::Smoother`]),
//! and writes them with their counts to `shards/smooth-I-of-N.ron` (and `.bin`) a patch at a
//! time (`crowd_core::shard::PartWriter`). Its header
//! carries [`part_hash`]: what stage 5's part is made from, the patterns and stage 6's
//! settings, which the gathering build, holding all of these, checks.

use crate::Inputs;
use crowd_core::files::Header;
use crowd_core::shard::gather_encoded;
use crowd_core::trajectories::PatchMotion;
use crowd_core::{Hash, Hasher, Result};
use std::path::Path;

/// What a shard's part of stage 6 is made from: what stage 5's part is made from
/// (`crowd_collide::shard::part_hash`), the patterns file's bytes and the settings (a shard has
/// not the collided file whose bytes stage 6's own hash covers: only its part of it).
pub fn part_hash(collide_part_hash: Hash, patterns: &Hash, inputs: &Inputs) -> Hash {
    Hasher::new(crate::STAGE, crate::VERSION)
        .value("stage 5 part", &collide_part_hash)
        .file_hash("patterns file", patterns)
        .value("inputs", inputs)
        .finish()
}

/// The header of stage 6's parts made from `hash` ([`part_hash`]).
pub fn header(hash: Hash) -> Header {
    Header::new(crate::STAGE, crate::VERSION, hash)
}

/// Stage 6's motion for every patch left in the parts, from every shard's part in
/// `dir/shards` (each made for `hash`, holding the patches its shard owns by `costs`;
/// `crowd_core::shard::gather_encoded`): the side file streamed to `side`'s temporary name,
/// and each patch's counts; `each` sees every patch's motion in patch order.
pub fn gather_bytes(
    dir: &Path,
    hash: Hash,
    costs: &[u64],
    each: impl FnMut(&PatchMotion),
    side: &Path,
) -> Result<crowd_core::shard::Gathered<[u64; 3]>> {
    gather_encoded(dir, &header(hash), costs, each, side)
}
