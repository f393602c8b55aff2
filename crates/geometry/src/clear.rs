//! Keeping a changed patch clear: stages that change trajectories after stage 5 (smoothing,
//! editing) keep every change that brings no one closer to anyone or anything than allowed
//! where the unchanged trajectories did not, and walk each one that does back towards its
//! unchanged trajectory, measured with the exact encounters stage 5 uses.

use crate::encounter::{Encounter, Other, encounter_with};
use crate::patch::Patch;
use crate::rows::{refresh, rows};
use crate::tracks::Tracks;
use crate::trajectory::trajectory_segments;
use crowd_core::trajectories::Trajectory;
use std::collections::HashMap;

/// How far back a trajectory that comes too close is walked: `levels` candidates, each nearer
/// the unchanged trajectory, then `holds` candidates that keep the unchanged trajectory near
/// the encounters found (given their times), then the unchanged trajectory itself.
#[derive(Clone, Copy, Debug)]
pub struct Ladder {
    pub levels: u32,
    pub holds: u32,
}

/// Who an encounter is between, whatever the period shift.
fn key(e: &Encounter) -> (usize, u8, usize) {
    match e.other {
        Other::Walker { b, .. } => (e.a, 0, b),
        Other::Stander(s) => (e.a, 1, s),
        Other::Obstacle(o) => (e.a, 2, o),
    }
}

/// The changed trajectories `after`, except where one comes closer to someone or something
/// than allowed where the unchanged ones (`before`) did not (or closer than they already did):
/// both walkers of such a pair take their next candidate (`candidate_at(i, level, [])`, level
/// 1 to `levels`); then candidates that hold the unchanged trajectory near each such encounter
/// (`candidate_at(i, level, times)`), and after `holds` of those the unchanged trajectory, until
/// nothing is worse than before.
pub fn keep_clear(
    before: &[Trajectory],
    mut after: Vec<Trajectory>,
    patch: &Patch,
    ladder: Ladder,
    candidate_at: impl Fn(usize, u32, &[f64]) -> Trajectory,
) -> Vec<Trajectory> {
    let Ladder { levels, holds } = ladder;
    // The polylines' margins, measured only for the pairs whose curves come too close (a
    // few in a patch): the whole matrix of the polylines cost as much as the curves'.
    let old_tracks = Tracks::new(before.iter().map(trajectory_segments).collect());
    let mut old: HashMap<_, f64> = HashMap::new();
    let mut was = |e: &Encounter| {
        *old.entry(key(e)).or_insert_with(|| {
            encounter_with(&old_tracks, e.a, e.other, patch).map_or(f64::INFINITY, |o| o.margin)
        })
    };
    let mut tracks = Tracks::new(after.iter().map(trajectory_segments).collect());
    // Only the rows of walkers that changed are measured again.
    let mut rows = rows(&tracks, patch);
    let mut level = vec![0u32; before.len()];
    let mut held: Vec<Vec<f64>> = vec![Vec::new(); before.len()];
    loop {
        // Who must move back, and when (in their own time) it came too close.
        let mut again: Vec<(usize, f64)> = Vec::new();
        for e in rows.iter().flatten() {
            if e.margin < 0.0 && e.margin < was(e) - 1e-9 {
                again.push((e.a, e.t));
                if let Other::Walker { b, shift } = e.other {
                    again.push((b, e.t - shift));
                }
            }
        }
        again.sort_unstable_by(|x, y| x.0.cmp(&y.0).then(x.1.total_cmp(&y.1)));
        again.retain(|&(i, _)| level[i] <= levels + holds);
        if again.is_empty() {
            return after;
        }
        let mut moved: Vec<usize> = again.iter().map(|&(i, _)| i).collect();
        moved.dedup();
        for &i in &moved {
            level[i] += 1;
            if level[i] > levels {
                held[i].extend(again.iter().filter(|&&(j, _)| j == i).map(|&(_, t)| t));
            }
            after[i] = if level[i] > levels + holds {
                before[i].clone()
            } else if level[i] > levels {
                candidate_at(i, level[i], &held[i])
            } else {
                candidate_at(i, level[i], &[])
            };
            tracks.set(i, trajectory_segments(&after[i]));
        }
        refresh(&mut rows, &mut tracks, &moved, patch);
    }
}
