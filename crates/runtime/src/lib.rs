//! The runtime an engine embeds to play a crowd-patches library (stage 8's `library.crowd`).
//!
//! [`Library::from_bytes`] checks untrusted bytes completely (section table, checksums, every
//! index and count, every character's loop) and never panics, reads out of bounds or
//! allocates more than the bytes can hold; [`Library::read_from`] does the same reading a
//! file a piece at a time, so that loading never holds the file's bytes beside the library.
//! [`Sampler::sample`] then yields every character in
//! a view rectangle at a time: per-character cursors make a frame O(characters), with no
//! search while time moves forward. `FORMAT.md` at the repository root documents the bytes.

pub mod crc;
mod error;
mod format;
mod sampler;
pub mod turn;

pub use crc::crc32;
pub use error::LoadError;
pub use format::{
    Character, Crossing, Library, LibraryFile, LoopPart, LoopSkeleton, MAGIC,
    MAX_PERIODS_PER_TRAJECTORY, Patch, Point, QUANT_STEPS, TICK_S, Trajectory, VERSION, Window,
    World,
};
pub use sampler::{PackedHeadings, Sample, Sampler, packed_heading};
