//! Keeping a changed patch clear: stages that change trajectories after stage 5 (smoothing,
//! editing) keep every change that brings no one closer to anyone or anything than allowed
//! where the unchanged trajectories did not, and walk each one that does back towards its
//! unchanged trajectory, measured with the exact encounters stage 5 uses.

use crate::encounter::{Encounter, Other, encounter_with};
use crate::patch::Patch;
use crate::rows::{refresh, rows};
use crate::segment::at_time;
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
    /// How many levels after the first each halve its departure from the unchanged
    /// trajectory (level `k <= halvings` departs by `2^-k` of level 0's): a walker steps past
    /// those the encounter shows cannot clear it (see [`keep_clear`]). With none (stage 7,
    /// whose levels past the first are holds), every level is stepped one at a time and both
    /// walkers of a pair always step: stage 7 was left as it was (its density edit on
    /// `city-edits` loses most to the holds of both walkers; holding one is not tried yet).
    pub halvings: u32,
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
/// both walkers of such a pair take a later candidate (`candidate_at(i, level, [])`, level 1 to
/// `levels`); then candidates that hold the unchanged trajectory near each such encounter
/// (`candidate_at(i, level, times)`), and after `holds` of those the unchanged trajectory, until
/// nothing is worse than before.
///
/// On the halvings, a pair steps past every level the encounter shows cannot clear it, and a
/// walker whose partner is already past the halvings steps back alone. On `painting` that
/// took stage 6's candidates past each walker's first from 0.85 million to 0.34 million and
/// left more walkers on their curves and fewer far down the ladder (BENCHMARKS.md,
/// twenty-third part).
pub fn keep_clear(
    before: &[Trajectory],
    mut after: Vec<Trajectory>,
    patch: &Patch,
    ladder: Ladder,
    candidate_at: impl Fn(usize, u32, &[f64]) -> Trajectory,
) -> Vec<Trajectory> {
    let Ladder {
        levels,
        halvings,
        holds,
    } = ladder;
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
        // Who must move back, how far, and when (in their own time) it came too close.
        let mut again: Vec<(usize, f64)> = Vec::new();
        let mut target = vec![0u32; before.len()];
        for e in rows.iter().flatten() {
            let w = was(e);
            if e.margin < 0.0 && e.margin < w - 1e-9 {
                let step = Step::of(e, w, &level, halvings, &old_tracks, &tracks, patch);
                for (i, t) in step.movers {
                    again.push((i, t));
                    target[i] = target[i].max(level[i] + step.levels);
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
            level[i] = target[i];
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

/// Who of a pair that came too close steps back, and by how many levels.
///
/// A walker on the halvings whose partner is past them steps alone: the partner already walks
/// near its unchanged trajectory, and stepping it back further would take its smoothness for
/// the other's curve. Otherwise both step (a walker alone, against a stander or a wall).
///
/// Along the halvings, the movers step past every level the encounter shows must fail too.
/// Stepped together by `k` levels, their gap at the encounter's moment moves along the line
/// from where they would be unchanged (`s` = 0) to where they are (`s` = 1), at `s = 2^-k`;
/// the distance is convex along a line, so the margin there is at most `(1 - s) d0 + s m`
/// (`d0` unchanged, `m` now). A level where that bound is too close cannot clear the pair.
struct Step {
    movers: Vec<(usize, f64)>,
    levels: u32,
}

impl Step {
    fn of(
        e: &Encounter,
        was: f64,
        level: &[u32],
        halvings: u32,
        old: &Tracks,
        now: &Tracks,
        patch: &Patch,
    ) -> Step {
        // With no halvings (stage 7's ladder), both always step.
        let on_halvings = |i: usize| halvings == 0 || level[i] <= halvings;
        let mut movers = vec![(e.a, e.t)];
        if let Other::Walker { b, shift } = e.other {
            let t = e.t - shift;
            match (on_halvings(e.a), on_halvings(b)) {
                (false, true) => movers = vec![(b, t)],
                (true, false) => {}
                _ => movers.push((b, t)),
            }
        }
        let highest = movers.iter().map(|&(i, _)| level[i]).max().unwrap_or(0);
        if highest >= halvings {
            return Step { movers, levels: 1 };
        }
        let moves = |i: usize| movers.iter().any(|&(j, _)| j == i);
        // Where a walker is at `t`: unchanged if it moves, else where it walks now.
        let at = |i: usize, t: f64| at_time(if moves(i) { old.get(i) } else { now.get(i) }, t);
        let Some(pa) = at(e.a, e.t) else {
            return Step { movers, levels: 1 };
        };
        let d0 = match e.other {
            Other::Walker { b, shift } => match at(b, e.t - shift) {
                Some(pb) => pa.distance(pb) - 2.0 * patch.radius_m,
                None => return Step { movers, levels: 1 },
            },
            Other::Stander(s) => pa.distance(patch.standers[s]) - 2.0 * patch.radius_m,
            Other::Obstacle(o) => {
                let r = &patch.obstacles[o];
                pa.distance(pa.clamp(r.min, r.max)) - patch.radius_m
            }
        };
        let allowed = was.min(0.0) - 1e-9;
        let cleared = |k: u32| {
            let s = 0.5f64.powi(k as i32);
            d0 + s * (e.margin - d0) >= allowed
        };
        // Past the last halving at most.
        let levels = (1..=halvings - highest)
            .find(|&k| cleared(k))
            .unwrap_or(halvings + 1 - highest);
        Step { movers, levels }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encounter::pair;
    use crate::testing::open_patch;
    use crowd_core::trajectories::{ControlPoint, PointKind};
    use glam::DVec2;
    use proptest::prelude::*;

    const HALVINGS: u32 = 4;

    /// A walk through `points` (x, y) m, one every second from `start` s.
    fn walk(start: f64, points: &[(f64, f64)]) -> Trajectory {
        let points = points
            .iter()
            .enumerate()
            .map(|(k, &(x, y))| ControlPoint {
                pos: DVec2::new(x, y),
                t: start + k as f64,
                kind: PointKind::Bend,
            })
            .collect();
        Trajectory {
            entry: 0,
            exit: 1,
            points,
        }
    }

    /// `before` moved by `2^-level` of `moved - before`, point by point (the same times): a
    /// ladder whose levels are exact halvings, then the unchanged walk.
    fn halved(before: &Trajectory, moved: &Trajectory, level: u32) -> Trajectory {
        if level > HALVINGS {
            return before.clone();
        }
        let s = 0.5f64.powi(level as i32);
        let mut out = before.clone();
        for (p, q) in out.points.iter_mut().zip(&moved.points) {
            p.pos += s * (q.pos - p.pos);
        }
        out
    }

    /// Walks of 6 points a second apart in an 8 m patch, and each walk moved up to 1.5 m at
    /// its inner points.
    fn walkers(n: usize) -> impl Strategy<Value = Vec<(Trajectory, Trajectory)>> {
        let point = (0.0f64..8.0, 0.0f64..8.0);
        let offset = (-1.5f64..1.5, -1.5f64..1.5);
        let one = (
            0.0f64..4.0,
            proptest::collection::vec(point, 6),
            proptest::collection::vec(offset, 4),
        )
            .prop_map(|(start, points, offsets)| {
                let before = walk(start, &points);
                let mut moved = before.clone();
                for (p, (dx, dy)) in moved.points[1..5].iter_mut().zip(offsets) {
                    p.pos += DVec2::new(dx, dy);
                }
                (before, moved)
            });
        proptest::collection::vec(one, n)
    }

    /// Every pair's closest margin, by pair.
    fn margins(walks: &[Trajectory], patch: &Patch) -> Vec<f64> {
        let tracks = Tracks::new(walks.iter().map(trajectory_segments).collect());
        let n = walks.len();
        (0..n)
            .flat_map(|a| (a..n).map(move |b| (a, b)))
            .map(|(a, b)| pair(&tracks, a, b, patch).map_or(f64::INFINITY, |e| e.margin))
            .collect()
    }

    fn clear(now: &[f64], was: &[f64]) -> bool {
        now.iter()
            .zip(was)
            .all(|(&m, &w)| m >= 0.0 || m >= w - 1e-9)
    }

    /// A walker pushed past its halvings by a stander is not stepped back further for a
    /// partner whose curve then comes too close: the partner steps back alone, as far as the
    /// encounter shows it must.
    #[test]
    fn a_walker_past_its_halvings_is_not_stepped_back_for_a_partner_still_on_them() {
        let stander = [DVec2::new(4.0, 4.61)];
        let patch = Patch {
            standers: &stander,
            ..open_patch(20.0, 0.3)
        };
        // Along y, bent by `by` m at its middle (at 2 s).
        let bent = |y: f64, by: f64| {
            walk(
                0.0,
                &[(0.0, y), (2.0, y), (4.0, y + by), (6.0, y), (8.0, y)],
            )
        };
        // A's curve bends 0.3 m towards the stander its line passes 1 cm clear of: no
        // halving clears it. B's curve bends 0.3 m towards A's line, 0.7 m from its own.
        let walks = [
            (bent(4.0, 0.0), bent(4.0, 0.3)),
            (bent(3.3, 0.0), bent(3.3, 0.3)),
        ];
        let candidate = |i: usize, level: u32| {
            let (before, moved) = &walks[i];
            match level {
                0..=HALVINGS => halved(before, moved, level),
                // Past the halvings: a 64th of the bend, clear of the stander.
                5 => bent(before.points[0].pos.y, 0.3 / 64.0),
                _ => before.clone(),
            }
        };
        let before: Vec<Trajectory> = walks.iter().map(|w| w.0.clone()).collect();
        let ladder = Ladder {
            levels: 6,
            halvings: HALVINGS,
            holds: 0,
        };
        let chosen = keep_clear(
            &before,
            vec![candidate(0, 0), candidate(1, 0)],
            &patch,
            ladder,
            |i, level, _| candidate(i, level),
        );
        // A took the first walk past its halvings and kept it; B steps back two halvings,
        // the first that clear A there (one would pass 0.45 m from it).
        assert_eq!(chosen, vec![candidate(0, 5), candidate(1, 2)]);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// Stepping past the levels an encounter shows must fail changes nothing for a lone
        /// pair: it ends on the first level (the same for both, stepped together) that
        /// clears it, as stepping one level at a time would.
        #[test]
        fn a_lone_pair_ends_on_the_first_level_that_clears_it(walks in walkers(2)) {
            let patch = open_patch(20.0, 0.3);
            let before: Vec<Trajectory> = walks.iter().map(|w| w.0.clone()).collect();
            let at = |level: u32| -> Vec<Trajectory> {
                walks.iter().map(|(b, m)| halved(b, m, level)).collect()
            };
            let was = margins(&before, &patch);
            let first = (0..=HALVINGS + 1)
                .find(|&level| clear(&margins(&at(level), &patch), &was))
                .expect("the unchanged walks are clear of themselves");
            let ladder = Ladder { levels: HALVINGS, halvings: HALVINGS, holds: 0 };
            let chosen = keep_clear(&before, at(0), &patch, ladder, |i, level, _| {
                halved(&walks[i].0, &walks[i].1, level)
            });
            prop_assert_eq!(chosen, at(first));
        }

        /// However many walkers and however they step, none ends closer to another than
        /// allowed where the unchanged walks were not.
        #[test]
        fn no_pair_ends_closer_than_allowed_where_it_was_not(walks in walkers(6)) {
            let patch = open_patch(20.0, 0.3);
            let before: Vec<Trajectory> = walks.iter().map(|w| w.0.clone()).collect();
            let moved = walks.iter().map(|(b, m)| halved(b, m, 0)).collect();
            let ladder = Ladder { levels: HALVINGS, halvings: HALVINGS, holds: 0 };
            let chosen = keep_clear(&before, moved, &patch, ladder, |i, level, _| {
                halved(&walks[i].0, &walks[i].1, level)
            });
            prop_assert!(clear(&margins(&chosen, &patch), &margins(&before, &patch)));
        }
    }
}
