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
    let gap = (bmin - amax).max(amin - bmax).max(DVec2::ZERO);
    if gap.length() > reach {
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
        let mut i = sa.partition_point(|s| s.t1 < lo);
        let mut j = sb.partition_point(|s| s.t1 + shift < lo);
        while i < sa.len() && j < sb.len() && sa[i].t0 <= hi && sb[j].t0 + shift <= hi {
            let x = sb[j].shifted(shift);
            // Two pieces whose boxes are farther apart than the closest so far (or than reach)
            // cannot bring it down: most pairs end here, without the exact approach.
            let limit = best.map_or(reach, |(bd, _, _)| bd.min(reach));
            let (lo_a, hi_a) = (sa[i].p0.min(sa[i].p1), sa[i].p0.max(sa[i].p1));
            let (lo_b, hi_b) = (x.p0.min(x.p1), x.p0.max(x.p1));
            let gap = (lo_b - hi_a).max(lo_a - hi_b).max(DVec2::ZERO);
            if gap.length_squared() <= limit * limit
                && let Some((d, t)) = closest(&sa[i], &x)
                && best.is_none_or(|(bd, _, _)| d < bd)
            {
                best = Some((d, t, shift));
            }
            if sa[i].t1 <= x.t1 {
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

/// Every encounter of walker `a` with the standers and the obstacles.
pub(crate) fn fixed_row(tracks: &Tracks, a: usize, patch: &Patch) -> Vec<Encounter> {
    let r = patch.radius_m;
    let mut out = Vec::new();
    for (s, &q) in patch.standers.iter().enumerate() {
        let best = tracks
            .get(a)
            .iter()
            .filter_map(|sa| closest(sa, &Segment::standing(q, sa.t0, sa.t1)))
            .min_by(|x, y| x.0.total_cmp(&y.0));
        if let Some((d, t)) = best {
            out.push(Encounter {
                margin: d - 2.0 * r,
                distance: d,
                t,
                a,
                other: Other::Stander(s),
            });
        }
    }
    for (o, rect) in patch.obstacles.iter().enumerate() {
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
        if let Some((d, t, _)) = best {
            out.push(Encounter {
                margin: d - r,
                distance: d,
                t,
                a,
                other: Other::Obstacle(o),
            });
        }
    }
    out
}
