//! The space-time geometry every stage after the patterns shares: walkers as straight walks
//! in time ([`Segment`]), how close two of them come ([`approach`], the one closest-approach
//! computation), a trajectory's pieces with its ghosts in the neighbouring patches
//! ([`trajectory_segments`]), who comes too close to whom in a patch ([`Encounter`], kept as
//! a distance matrix by [`rows`] and [`refresh`]), a spatial grid of pieces for a whole world
//! ([`PieceGrid`]), the shortest way round a patch's walls ([`route::route`]) and the rule
//! that keeps two crossings of a border apart ([`spacing::CrossingRule`]).
//!
//! It belongs to no stage: stage 3 spaces crossings with it, stage 4 routes with it, stage 5
//! pushes walkers apart by it, stage 6 re-checks its curves with it and the world check
//! measures with it, and none of them reaches into another for it. Pure functions of their
//! arguments; it depends on `crowd-core` for the vocabulary only.

pub mod approach;
pub mod clear;
pub mod encounter;
pub mod grid;
mod occupancy;
pub mod patch;
pub mod route;
pub mod rows;
pub mod segment;
pub mod spacing;
pub mod tracks;
pub mod trajectory;

pub use approach::{approach, closest, distance_to_rect, nearest_along, to_rect};
pub use clear::{Ladder, keep_clear};
pub use encounter::{Encounter, Other, encounter_with, pair};
pub use grid::{BoxGrid, PieceGrid};
pub use patch::{Patch, obstacles_near};
pub use rows::{refresh, rows};
pub use segment::{Segment, at_time, copies, pieces};
pub use tracks::Tracks;
pub use trajectory::{entry_ghost, exit_ghost, ghosts, trajectory_segments};
