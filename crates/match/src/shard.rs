//! Stage 4 split over processes: a shard matches the patches it owns (its run, as in stages 5
//! and 6: [`crowd_core::Shard::run`]) and their neighbours, whose motion its stage 5 clears
//! too ([`crowd_core::shard::with_neighbours`]), and writes its own patches to
//! `shards/match-I-of-N.ron` (and `.bin`). The gathering build puts every shard's part
//! together ([`gather_bytes`]): their patches' bytes one after another make the side file one
//! process writes. So no shard holds, nor matches, the world's stage 4 (the million's: 5 s and
//! 1.2 GB in every shard).

use crowd_core::files::{Header, Writes};
use crowd_core::shard::{Gathered, encode_part, gather_encoded};
use crowd_core::trajectories::{PatchMotion, TrajectoriesFile};
use crowd_core::{Hash, Result, Shard};
use std::path::Path;

/// The header of stage 4's parts for stage 4's input hash `hash`.
pub fn header(hash: Hash) -> Header {
    Header::new(TrajectoriesFile::STAGE, TrajectoriesFile::VERSION, hash)
}

/// The files of `shard`'s part: `parts` its own patches (index and motion), in patch order.
pub fn encode_shard(
    dir: &Path,
    shard: Shard,
    hash: Hash,
    parts: Vec<(u32, &PatchMotion)>,
) -> Writes {
    let parts = parts.into_iter().map(|(p, m)| (p, m, ())).collect();
    encode_part(dir, header(hash), shard, parts)
}

/// Stage 4's motion for every patch left in the parts, from every shard's part in
/// `dir/shards` (each made for `hash`, holding the patches its shard owns by `costs`): the side
/// file one process would write streamed to `side`'s temporary name; `each` sees every
/// patch's motion in patch order.
pub fn gather_bytes(
    dir: &Path,
    hash: Hash,
    costs: &[u64],
    each: impl FnMut(&PatchMotion),
    side: &Path,
) -> Result<Gathered<()>> {
    gather_encoded(dir, &header(hash), costs, each, side)
}
