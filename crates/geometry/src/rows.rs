//! The distance matrix of a patch: every walker's encounters within reach, by walker, and
//! how it is brought up to date after some walkers moved without measuring everything again.

use crate::encounter::{Encounter, Other, box_gap_squared, fixed_row, pair, pair_in};
use crate::patch::Patch;
use crate::tracks::{ALWAYS, Span, Tracks};
use glam::DVec2;

/// Every encounter within reach in a patch, by walker: row `a` holds walker `a`'s encounters
/// with every later walker (and its own later copies), with the standers and the obstacles.
pub fn rows(tracks: &Tracks, patch: &Patch) -> Vec<Vec<Encounter>> {
    (0..tracks.len()).map(|a| row(tracks, a, patch)).collect()
}

/// Brings [`rows`] up to date after the paths of the walkers `touched` changed (through
/// [`Tracks::set`]): their own rows anew, and in every other row only the entries with them.
///
/// Exact, but cheap: where a pair's closest encounter lies outside the span over which one
/// walker changed, it still stands, and only the changed span can bring it down.
pub fn refresh(rows: &mut [Vec<Encounter>], tracks: &mut Tracks, touched: &[usize], patch: &Patch) {
    let changed = |p: usize| tracks.changed[p].unwrap_or(ALWAYS);
    let outside = |t: f64, (lo, hi): Span| t < lo - 1e-9 || t > hi + 1e-9;
    // Where a moved walker's changed pieces stay out of reach of the other's whole path, the
    // pair cannot have come nearer: the test [`pair_in`]'s broad phase makes, on less.
    let reach = 2.0 * patch.radius_m;
    let moved_box: Vec<Option<(DVec2, DVec2)>> = touched
        .iter()
        .map(|&p| tracks.box_during(p, changed(p)))
        .collect();
    let out_of_reach = |moved: usize, other: usize| {
        let k = touched
            .iter()
            .position(|&p| p == moved)
            .expect("a touched walker");
        moved_box[k].is_none_or(|b| box_gap_squared(b, tracks.boxes[other]) > reach * reach)
    };
    // The pair (a, b) after one of them, `moved`, changed over `span`.
    let update = |old: Option<Encounter>, a: usize, b: usize, a_moved: bool| {
        let (moved, other) = if a_moved { (a, b) } else { (b, a) };
        let span = changed(moved);
        let (wa, wb) = if a_moved {
            (span, ALWAYS)
        } else {
            (ALWAYS, span)
        };
        match old {
            Some(e) => {
                let Other::Walker { shift, .. } = e.other else {
                    unreachable!("a walker entry")
                };
                let when = if a_moved { e.t } else { e.t - shift };
                if outside(when, span) {
                    if out_of_reach(moved, other) {
                        return Some(e);
                    }
                    match pair_in(tracks, a, b, patch, wa, wb) {
                        Some(n) if n.distance < e.distance => Some(n),
                        _ => Some(e),
                    }
                } else {
                    pair(tracks, a, b, patch)
                }
            }
            None if out_of_reach(moved, other) => None,
            None => pair_in(tracks, a, b, patch, wa, wb),
        }
    };
    let entry = |encounters: &[Encounter], b: usize| {
        encounters
            .iter()
            .find(|e| matches!(e.other, Other::Walker { b: x, .. } if x == b))
            .copied()
    };
    for (a, encounters) in rows.iter_mut().enumerate() {
        if touched.contains(&a) {
            let mut fresh: Vec<Encounter> = (a..tracks.len())
                .filter_map(|b| {
                    if b == a || touched.contains(&b) {
                        pair(tracks, a, b, patch)
                    } else {
                        update(entry(encounters, b), a, b, true)
                    }
                })
                .collect();
            fresh.extend(fixed_row(tracks, a, patch));
            *encounters = fresh;
        } else {
            for &b in touched.iter().filter(|&&b| b > a) {
                let old = entry(encounters, b);
                encounters.retain(|e| !matches!(e.other, Other::Walker { b: x, .. } if x == b));
                encounters.extend(update(old, a, b, false));
            }
        }
    }
    for &p in touched {
        tracks.changed[p] = None;
    }
}

/// Every encounter of walker `a` with walkers `b >= a`, standers and obstacles.
fn row(tracks: &Tracks, a: usize, patch: &Patch) -> Vec<Encounter> {
    let mut out: Vec<Encounter> = (a..tracks.len())
        .filter_map(|b| pair(tracks, a, b, patch))
        .collect();
    out.extend(fixed_row(tracks, a, patch));
    out
}
