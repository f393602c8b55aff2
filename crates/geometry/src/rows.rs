//! The distance matrix of a patch: every walker's encounters within reach, by walker, and
//! how it is brought up to date after some walkers moved without measuring everything again.

use crate::encounter::{Encounter, Other, fixed_row, pair, pair_in};
use crate::patch::Patch;
use crate::tracks::{ALWAYS, Near, Span, Tracks};

/// Every encounter within reach in a patch, by walker: row `a` holds walker `a`'s encounters
/// with every later walker (and its own later copies), with the standers and the obstacles.
/// Of [`Tracks::indexed`], only the walkers that may come within reach are measured, here and
/// in [`refresh`].
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
    // Where a moved walker's changed pieces cannot come within reach of the other, the pair
    // cannot have come nearer: most pairs end here, unmeasured.
    let reach = 2.0 * patch.radius_m;
    let near: Vec<Near> = touched
        .iter()
        .map(|&p| tracks.near(p, changed(p), reach))
        .collect();
    let at = |moved: usize| {
        touched
            .iter()
            .position(|&p| p == moved)
            .expect("a touched walker")
    };
    let out_of_reach = |moved: usize, other: usize| !near[at(moved)].may_meet(tracks, other);
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
    let near = tracks.near(a, ALWAYS, 2.0 * patch.radius_m);
    let mut out: Vec<Encounter> = (a..tracks.len())
        .filter(|&b| b == a || near.may_meet(tracks, b))
        .filter_map(|b| pair(tracks, a, b, patch))
        .collect();
    out.extend(fixed_row(tracks, a, patch));
    out
}
