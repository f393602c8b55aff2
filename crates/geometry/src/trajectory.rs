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
    if let (Some(&(p0, t0)), Some((p1, t1))) = (points.first(), entry_band) {
        out.push(Segment {
            p0: p0 - (p1 - p0),
            t0: t0 - (t1 - t0),
            p1: p0,
            t1: t0,
        });
    }
    out.extend(pieces(points.iter().copied()));
    if let (Some(&(p1, t1)), Some((p0, t0))) = (points.last(), exit_band) {
        out.push(Segment {
            p0: p1,
            t0: t1,
            p1: p1 + (p1 - p0),
            t1: t1 + (t1 - t0),
        });
    }
    out
}

/// The straight pieces of a trajectory with its ghosts (see [`ghosts`]).
pub fn trajectory_segments(tr: &Trajectory) -> Vec<Segment> {
    let (e, x) = band_ends(&tr.points);
    let at = |i: usize| (tr.points[i].pos, tr.points[i].t);
    let points: Vec<(DVec2, f64)> = tr.points.iter().map(|p| (p.pos, p.t)).collect();
    ghosts(&points, e.map(at), x.map(at))
}
