//! The library's bytes (`FORMAT.md`): a header, a section table, packed little-endian records.
//! [`Library::to_bytes`] writes them (stage 8 calls it); [`Library::from_bytes`] reads and
//! checks them without trusting anything, and [`Library::read_from`] reads a file so, a piece
//! at a time.
//!
//! - `records.rs`: the records (`World`, `Patch`, `Point`, ...) and `Library`, what they mean;
//! - `container.rs`: the header, the section table with its checksums, each record's bytes;
//! - `file.rs`: a library left in its file, its points read a part at a time;
//! - `part.rs`: a long loop's walkers played a group at a time, each group with its stretches;
//! - `read.rs`: those read back from bytes or from a file, every slice bounded and checksum
//!   checked;
//! - `rules.rs`: every rule a loaded library must keep, which the sampler relies on.

mod container;
mod file;
mod part;
mod read;
mod records;
mod rules;

pub use file::{LibraryFile, Window};
pub use part::{LoopPart, LoopSkeleton};
pub use records::{Character, Crossing, Library, Patch, Point, Trajectory, World};

/// The first 8 bytes of every library.
pub const MAGIC: [u8; 8] = *b"CRWDLIB\0";
/// The format version this crate reads and writes.
pub const VERSION: u32 = 1;
/// Times are whole ticks of this many seconds (0.1 ms): quantised to within 0.05 ms.
pub const TICK_S: f64 = 1e-4;
/// Positions are patch-local, in steps of side / QUANT_STEPS: within side / 131,070 (0.06 mm
/// for an 8 m patch).
pub const QUANT_STEPS: f64 = 65535.0;

/// The longest a trajectory may last, in periods. It bounds the walkers a library can claim
/// (at most this many per trajectory record), so that loading allocates in proportion to the
/// file's size, whatever it says.
pub const MAX_PERIODS_PER_TRAJECTORY: u32 = 64;

/// The most patches a world has across and up (so a patch's place fits two u16s, as the
/// sampler keeps it): 524 km at 8 m a patch.
pub const MAX_GRID: u32 = 1 << 16;
