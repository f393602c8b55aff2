//! The shared vocabulary of the crowd-patches pipeline.
//!
//! Every stage crate reads one of the file types defined here and writes the next one. This crate
//! owns the rules all stage files follow: versioned headers carrying the hash of everything the
//! file was built from ([`files`]), atomic writes, RON with binary side files for bulky arrays,
//! and errors that carry their place ([`Error`]).

pub mod config;
pub mod error;
pub mod files;
pub mod flow_map;
pub mod grid;
pub mod hash;
pub mod maps;
pub mod patch_graph;
pub mod patch_keys;
pub mod patterns;
pub mod progress;
pub mod shard;
pub mod trajectories;

pub use config::{
    GraphSettings, LayerKind, LayerSpec, MatchSettings, MergeSettings, OptimizeSettings, Pipeline,
    Scene,
};
pub use error::{Error, Result};
pub use grid::Grid;
pub use hash::{Hash, Hasher};
pub use maps::MergedMaps;
pub use patch_graph::{
    Border, BorderAxis, Cell, Interval, Patch, PatchGraph, PatchId, Rect, RequestedDirection,
};
pub use progress::Progress;
pub use shard::Shard;
