//! Which slots of a loop `world.glb` may show, and which of the loop's keys they read, found
//! from the trajectories' summaries alone (`motion::Summary`: durations and boxes), before any
//! keyframe is read. A region's slots walk near it, so they read a few trajectories of each
//! loop, though a loop may cross the whole world (the million's longest has 36 million keys):
//! `world.glb` then holds the keyframes of the region's neighbourhood, not of the world.

use super::keys::Clock;
use super::region::{self, Region};
use crate::characters::Links;
use crate::motion::Summaries;

/// How far past a clip's window (loop time, s) the keys its slot reads reach: far beyond the
/// instants keys snap to (`keys::SNAP_S`, `keys::EDGE_S`) and the heading clock's 0.1 ms tick.
const MARGIN_S: f64 = 1e-3;

/// A loop's slots that may show, and the runs of its trajectories whose keys they read.
pub(super) struct Plan {
    /// The loop, in the library's CHAR order.
    pub(super) lp: usize,
    pub(super) clock: Clock,
    /// Loop time at which each of its trajectories starts, and at which the last ends
    /// (members + 1): their durations summed in loop order, the same bits as the keys' times.
    pub(super) offsets: Vec<f64>,
    /// The slots whose clip windows' trajectories' boxes meet the region (all without one).
    pub(super) laps: Vec<u32>,
    /// Runs of the loop's trajectories (first, last, by place in the loop) whose keys those
    /// slots read, in order and apart.
    pub(super) runs: Vec<(usize, usize)>,
}

/// The plan of loop `lp`, or None when none of its slots may show.
pub(super) fn plan(
    summaries: &Summaries,
    links: &Links,
    lp: usize,
    clock: Clock,
    region: Option<Region>,
) -> Option<Plan> {
    let members = &links.loops[lp];
    let mut offsets = Vec::with_capacity(members.len() + 1);
    let mut offset = 0.0;
    offsets.push(offset);
    for &i in members {
        offset += summaries.trajectories[i].duration_s;
        offsets.push(offset);
    }
    let Some(region) = region else {
        return Some(Plan {
            lp,
            clock,
            offsets,
            laps: (0..clock.laps).collect(),
            runs: vec![(0, members.len() - 1)],
        });
    };
    let mut laps = Vec::new();
    let mut runs = Vec::new();
    for lap in 0..clock.laps {
        let read: Vec<(usize, usize)> = (windows(&clock, lap).iter())
            .map(|&w| members_around(&offsets, w))
            .collect();
        let empty = (
            glam::DVec2::splat(f64::INFINITY),
            glam::DVec2::splat(f64::NEG_INFINITY),
        );
        let bounds =
            (read.iter().flat_map(|&(a, b)| &members[a..=b])).fold(empty, |(lo, hi), &i| {
                let s = &summaries.trajectories[i];
                (lo.min(s.lo), hi.max(s.hi))
            });
        if region::may_show(bounds, region) {
            laps.push(lap);
            runs.extend(read);
        }
    }
    if laps.is_empty() {
        return None;
    }
    runs.sort_unstable();
    let mut merged: Vec<(usize, usize)> = Vec::with_capacity(runs.len());
    for (a, b) in runs {
        match merged.last_mut() {
            Some(last) if a <= last.1 + 1 => last.1 = last.1.max(b),
            _ => merged.push((a, b)),
        }
    }
    Some(Plan {
        lp,
        clock,
        offsets,
        laps,
        runs: merged,
    })
}

/// The spans of loop time slot `lap` reads: its clip's window (two spans where it wraps past
/// the loop's end) and its end, where its successor starts.
fn windows(clock: &Clock, lap: u32) -> Vec<(f64, f64)> {
    let (tau0, tau_end) = (clock.tau(lap), clock.tau(clock.next_lap(lap)));
    let (end_tau, length) = (tau0 + clock.period, clock.length());
    let mut spans = if end_tau <= length {
        vec![(tau0, end_tau)]
    } else {
        vec![(tau0, length), (0.0, end_tau - length)]
    };
    spans.push((tau_end, tau_end));
    spans
}

/// The loop's trajectories (first, last) whose keys reach [`MARGIN_S`] before `a` and after
/// `b`, or to the loop's ends: a stretch that starts at a trajectory's second key (its first
/// is the one before's last) and ends at a trajectory's last. Two trajectories more each way
/// than the times need, so that one of one key changes nothing.
fn members_around(offsets: &[f64], (a, b): (f64, f64)) -> (usize, usize) {
    let n = offsets.len() - 1;
    let first = offsets[1..]
        .partition_point(|&end| end <= a - MARGIN_S)
        .saturating_sub(2);
    let after = offsets[..n].partition_point(|&start| start < b + MARGIN_S);
    let last = (after + 1).min(n - 1);
    (first, last.max(first))
}

/// The patches whose keyframes `plans` read.
pub(super) fn patches(plans: &[Plan], links: &Links, patches: usize) -> Vec<bool> {
    let mut read = vec![false; patches];
    for plan in plans {
        let members = &links.loops[plan.lp];
        for &(a, b) in &plan.runs {
            for &i in &members[a..=b] {
                read[links.refs[i].patch as usize] = true;
            }
        }
    }
    read
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_span_reads_the_trajectories_around_it_by_the_margin() {
        // Five trajectories of 10 s each.
        let offsets = [0.0, 10.0, 20.0, 30.0, 40.0, 50.0];
        // Inside the third: from two before the one that ends before it to one past the one
        // that starts after it.
        assert_eq!(members_around(&offsets, (25.0, 26.0)), (0, 4));
        // Near the loop's ends: to its first and last.
        assert_eq!(members_around(&offsets, (41.0, 41.0)), (2, 4));
        assert_eq!(members_around(&offsets, (0.0, 0.0)), (0, 2));
        let long = [0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0];
        assert_eq!(members_around(&long, (35.0, 36.0)), (1, 5));
        // A trajectory that ends within the margin before the span counts as reached.
        assert_eq!(members_around(&long, (40.0005, 41.0)), (1, 6));
        assert_eq!(members_around(&long, (40.002, 41.0)), (2, 6));
    }
}
