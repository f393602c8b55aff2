//! Who comes too close to whom in a patch, and when: the collision test of stages 5 and 6.
//! A pair of walkers is measured over every copy of the other a whole number of periods
//! apart (the patch plays in a loop), exactly, by the closest approach of their pieces.

use crate::approach::{closest, distance_to_rect, to_rect};
use crate::patch::Patch;
use crate::segment::{Segment, copies};
use crate::tracks::{ALWAYS, Span, Tracks};
use glam::DVec2;

/// Who is too close to walker `a`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Other {
    /// Walker `b` (maybe `a` itself one or more periods later), shifted by `shift` seconds.
    Walker {
        b: usize,
        shift: f64,
    },
    Stander(usize),
    Obstacle(usize),
}

/// The closest encounter of walker `a`: how far, when (in `a`'s time), with whom.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Encounter {
    /// Distance minus the clearance the pair needs: negative is a collision.
    pub margin: f64,
    pub distance: f64,
    pub t: f64,
    pub a: usize,
    pub other: Other,
}

/// The closest encounter of walkers `a` and `b` (or `a` with its own copies a period or more
/// later when `a == b`), if they ever coexist within reach (2r) of each other.
pub fn pair(tracks: &Tracks, a: usize, b: usize, patch: &Patch) -> Option<Encounter> {
    pair_in(tracks, a, b, patch, ALWAYS, ALWAYS)
}

/// [`pair`], over the pieces of `a` that overlap `wa` (in `a`'s time) and of `b` that overlap
/// `wb` (in `b`'s own time) only.
pub(crate) fn pair_in(
    tracks: &Tracks,
    a: usize,
    b: usize,
    patch: &Patch,
    wa: Span,
    wb: Span,
) -> Option<Encounter> {
    let period = patch.period_s;
    let (sa, sb) = (tracks.get(a), tracks.get(b));
    let (a0, a1) = (sa.first()?.t0, sa.last()?.t1);
    let (b0, b1) = (sb.first()?.t0, sb.last()?.t1);
    // Broad phase: walkers whose whole paths stay farther apart than they need never meet.
    let reach = 2.0 * patch.radius_m;
    let ((amin, amax), (bmin, bmax)) = (tracks.boxes[a], tracks.boxes[b]);
    // Squared: most pairs end here, and the sweep finds nothing nearer than the gap anyway.
    if box_gap_squared((amin, amax), (bmin, bmax)) > reach * reach {
        return None;
    }
    // Copies of b that overlap a in time: b shifted by k periods.
    let mut best: Option<(f64, f64, f64)> = None;
    for k in copies((a0, a1), (b0, b1), period) {
        if b == a && k <= 0 {
            continue;
        }
        let shift = k as f64 * period;
        // Both paths run forward in time: one sweep visits every pair of segments that
        // overlap in time, from the first moment both exist to the last.
        let lo = a0.max(b0 + shift).max(wa.0).max(wb.0 + shift);
        let hi = a1.min(b1 + shift).min(wa.1).min(wb.1 + shift);
        if lo > hi {
            continue;
        }
        // Runs of pieces first: only where two runs come within reach (or within the
        // closest so far) are their pieces swept, over the time both runs exist.
        let (ca, cb) = (&tracks.chunks[a], &tracks.chunks[b]);
        let mut i = ca.partition_point(|c| c.t1 < lo);
        let mut j = cb.partition_point(|c| c.t1 + shift < lo);
        while i < ca.len() && j < cb.len() && ca[i].t0 <= hi && cb[j].t0 + shift <= hi {
            let (x, y) = (&ca[i], &cb[j]);
            let limit = best.map_or(reach, |(bd, _, _)| bd.min(reach));
            if box_gap_squared((x.lo, x.hi), (y.lo, y.hi)) <= limit * limit {
                let from = lo.max(x.t0).max(y.t0 + shift);
                let to = hi.min(x.t1).min(y.t1 + shift);
                let (pa, pb) = (
                    &sa[x.start as usize..x.end as usize],
                    &sb[y.start as usize..y.end as usize],
                );
                sweep(pa, pb, shift, (from, to), reach, &mut best);
            }
            if x.t1 <= y.t1 + shift {
                i += 1;
            } else {
                j += 1;
            }
        }
    }
    // Pairs never within reach have no entry: only a collision matters to the repair.
    best.filter(|&(d, _, _)| d < reach)
        .map(|(d, t, shift)| Encounter {
            margin: d - 2.0 * patch.radius_m,
            distance: d,
            t,
            a,
            other: Other::Walker { b, shift },
        })
}

/// The closest approach of the pieces `sa` and `sb` (shifted by `shift` seconds) over
/// `lo..=hi`, where it beats `best`: one sweep visits every pair of pieces that overlap in
/// time, since both runs go forward in time.
fn sweep(
    sa: &[Segment],
    sb: &[Segment],
    shift: f64,
    (lo, hi): Span,
    reach: f64,
    best: &mut Option<(f64, f64, f64)>,
) {
    let mut i = sa.partition_point(|s| s.t1 < lo);
    let mut j = sb.partition_point(|s| s.t1 + shift < lo);
    while i < sa.len() && j < sb.len() && sa[i].t0 <= hi && sb[j].t0 + shift <= hi {
        let x = sb[j].shifted(shift);
        // Two pieces whose boxes are farther apart than the closest so far (or than reach)
        // cannot bring it down: most pairs end here, without the exact approach.
        let limit = best.map_or(reach, |(bd, _, _)| bd.min(reach));
        let (lo_a, hi_a) = (sa[i].p0.min(sa[i].p1), sa[i].p0.max(sa[i].p1));
        let (lo_b, hi_b) = (x.p0.min(x.p1), x.p0.max(x.p1));
        if box_gap_squared((lo_a, hi_a), (lo_b, hi_b)) <= limit * limit
            && let Some((d, t)) = closest(&sa[i], &x)
            && best.is_none_or(|(bd, _, _)| d < bd)
        {
            *best = Some((d, t, shift));
        }
        if sa[i].t1 <= x.t1 {
            i += 1;
        } else {
            j += 1;
        }
    }
}

/// The squared distance between two boxes (lowest and highest corners), 0 where they
/// overlap: no point of one is nearer the other. The broad phase of every encounter test.
pub(crate) fn box_gap_squared((alo, ahi): (DVec2, DVec2), (blo, bhi): (DVec2, DVec2)) -> f64 {
    (blo - ahi).max(alo - bhi).max(DVec2::ZERO).length_squared()
}

/// Every encounter of walker `a` with the standers and the obstacles.
pub(crate) fn fixed_row(tracks: &Tracks, a: usize, patch: &Patch) -> Vec<Encounter> {
    let standers = (0..patch.standers.len()).filter_map(|s| with_stander(tracks, a, s, patch));
    let obstacles = (0..patch.obstacles.len()).filter_map(|o| with_obstacle(tracks, a, o, patch));
    standers.chain(obstacles).collect()
}

/// Walker `a`'s encounter with `other` (for a walker, over every period shift), as
/// [`crate::rows`] holds it: `None` where the rows hold no entry.
pub fn encounter_with(tracks: &Tracks, a: usize, other: Other, patch: &Patch) -> Option<Encounter> {
    match other {
        Other::Walker { b, .. } => pair(tracks, a.min(b), a.max(b), patch),
        Other::Stander(s) => with_stander(tracks, a, s, patch),
        Other::Obstacle(o) => with_obstacle(tracks, a, o, patch),
    }
}

/// Walker `a`'s closest approach to stander `s`.
fn with_stander(tracks: &Tracks, a: usize, s: usize, patch: &Patch) -> Option<Encounter> {
    let q = patch.standers[s];
    let (d, t) = tracks
        .get(a)
        .iter()
        .filter_map(|sa| closest(sa, &Segment::standing(q, sa.t0, sa.t1)))
        .min_by(|x, y| x.0.total_cmp(&y.0))?;
    Some(Encounter {
        margin: d - 2.0 * patch.radius_m,
        distance: d,
        t,
        a,
        other: Other::Stander(s),
    })
}

/// Walker `a`'s closest approach to obstacle `o`.
fn with_obstacle(tracks: &Tracks, a: usize, o: usize, patch: &Patch) -> Option<Encounter> {
    let rect = &patch.obstacles[o];
    // The searched approach of the nearest piece (the first on a tie). A piece whose exact
    // distance is already farther than the nearest so far cannot be it: the search is only
    // run on the others (it was 90 % of a thin-walled painting's build).
    let mut best: Option<(f64, f64, DVec2)> = None;
    for sa in tracks.get(a) {
        if best.is_some_and(|b| distance_to_rect(sa, rect.min, rect.max) > b.0) {
            continue;
        }
        let found = to_rect(sa, rect.min, rect.max);
        if best.is_none_or(|b| found.0 < b.0) {
            best = Some(found);
        }
    }
    let (d, t, _) = best?;
    Some(Encounter {
        margin: d - patch.radius_m,
        distance: d,
        t,
        a,
        other: Other::Obstacle(o),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{open_patch, walk};
    use proptest::prelude::*;

    fn any_walk() -> impl Strategy<Value = Vec<Segment>> {
        (
            0.0f64..20.0,
            (0.0f64..8.0, 0.0f64..8.0),
            proptest::collection::vec((-1.0f64..1.0, -1.0f64..1.0, 0.05f64..1.5), 1..40),
        )
            .prop_map(|(start, from, steps)| walk(start, from, &steps))
    }

    /// Every piece against every piece of every copy: what the sweeps must find.
    fn brute(a: &[Segment], b: &[Segment], same: bool, period: f64) -> Option<f64> {
        let mut best: Option<f64> = None;
        for k in -10i64..=10 {
            if same && k <= 0 {
                continue;
            }
            for x in a {
                for y in b {
                    if let Some((d, _)) = closest(x, &y.shifted(k as f64 * period)) {
                        best = Some(best.map_or(d, |b: f64| b.min(d)));
                    }
                }
            }
        }
        best
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]
        /// The runs of pieces only skip what cannot come within reach: the closest approach
        /// is the one every pair of pieces gives.
        #[test]
        fn the_sweep_finds_what_every_pair_of_pieces_finds(
            a in any_walk(),
            b in any_walk(),
            period in 8.0f64..30.0,
            radius in 0.2f64..1.5,
        ) {
            let tracks = Tracks::new(vec![a.clone(), b.clone()]);
            let patch = open_patch(period, radius);
            for (x, y, same) in [(0, 1, false), (0, 0, true), (1, 1, true)] {
                let (sa, sb) = (tracks.get(x), tracks.get(y));
                let want = brute(sa, sb, same, period).filter(|&d| d < 2.0 * radius);
                let got = pair(&tracks, x, y, &patch).map(|e| e.distance);
                match (want, got) {
                    (Some(w), Some(g)) => prop_assert!((w - g).abs() < 1e-9, "{} {}", w, g),
                    (None, None) => {}
                    // At reach within rounding either may say so.
                    (w, g) => prop_assert!(
                        w.or(g).is_some_and(|d| (d - 2.0 * radius).abs() < 1e-9),
                        "{:?} {:?}", w, g
                    ),
                }
            }
        }
    }
}
