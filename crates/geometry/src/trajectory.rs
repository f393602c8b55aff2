//! A trajectory's straight pieces as the encounter test needs them: its own, and the band
//! pieces it walks in the neighbouring patches (its ghosts), so that a patch's check covers
//! everyone near its borders.

use crate::segment::{Segment, pieces};
use crowd_core::trajectories::{Trajectory, band_ends};
use glam::DVec2;

/// The straight pieces through `points` (a trajectory's, in time order), with the band pieces
/// the walker walks in the neighbouring patches: given where the entry's band ends, the same
/// straight walk continued as far back before the entry; likewise after the exit.
pub fn ghosts(
    points: &[(DVec2, f64)],
    entry_band: Option<(DVec2, f64)>,
    exit_band: Option<(DVec2, f64)>,
) -> Vec<Segment> {
    let mut out = Vec::with_capacity(points.len() + 1);
    if let (Some(&first), Some(band)) = (points.first(), entry_band) {
        out.push(entry_ghost(first, band));
    }
    out.extend(pieces(points.iter().copied()));
    if let (Some(&last), Some(band)) = (points.last(), exit_band) {
        out.push(exit_ghost(last, band));
    }
    out
}

/// The ghost before an entry at `(p0, t0)` whose band ends at `(p1, t1)` (see [`ghosts`]).
pub fn entry_ghost((p0, t0): (DVec2, f64), (p1, t1): (DVec2, f64)) -> Segment {
    Segment {
        p0: p0 - (p1 - p0),
        t0: t0 - (t1 - t0),
        p1: p0,
        t1: t0,
    }
}

/// The ghost after an exit at `(p1, t1)` whose band starts at `(p0, t0)` (see [`ghosts`]).
pub fn exit_ghost((p1, t1): (DVec2, f64), (p0, t0): (DVec2, f64)) -> Segment {
    Segment {
        p0: p1,
        t0: t1,
        p1: p1 + (p1 - p0),
        t1: t1 + (t1 - t0),
    }
}

/// The straight pieces of a trajectory with its ghosts (see [`ghosts`]).
pub fn trajectory_segments(tr: &Trajectory) -> Vec<Segment> {
    let (e, x) = band_ends(&tr.points);
    let at = |i: usize| (tr.points[i].pos, tr.points[i].t);
    let points: Vec<(DVec2, f64)> = tr.points.iter().map(|p| (p.pos, p.t)).collect();
    ghosts(&points, e.map(at), x.map(at))
}
