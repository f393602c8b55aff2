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

/// What the crate's unit tests build their walks and patches from.
#[cfg(test)]
mod testing {
    use crate::patch::Patch;
    use crate::segment::{Segment, pieces};
    use glam::DVec2;

    /// A walk of pieces from `from` at `start` s, each step moving by `(dx, dy)` over `dt`.
    pub fn walk(start: f64, from: (f64, f64), steps: &[(f64, f64, f64)]) -> Vec<Segment> {
        let mut at = (DVec2::new(from.0, from.1), start);
        let mut points = vec![at];
        for &(dx, dy, dt) in steps {
            at = (at.0 + DVec2::new(dx, dy), at.1 + dt);
            points.push(at);
        }
        pieces(points)
    }

    /// An 8 m patch looping every `period` s, for walkers of `radius` m, with nothing standing
    /// in it.
    pub fn open_patch(period: f64, radius: f64) -> Patch<'static> {
        Patch {
            side_m: 8.0,
            period_s: period,
            radius_m: radius,
            obstacles: &[],
            standers: &[],
        }
    }
}
