//! A density edit short of people: who comes into its rectangle, and what the patch could show.
//!
//! The density constraint pulls a walker through its kernel, which reaches a couple of kernel
//! widths (2 m): a walker across the patch never feels it, and a square that should fill
//! stays nearly as it was (on `city`, 0.11 -> 0.17 people/m2 for a target of 0.3). So a
//! density edit that asks for more people than the plans bring also asks the nearest walkers
//! free at each step of its window to be inside the rectangle then
//! ([`crowd_edit::observe::Within`]), as many as the target needs; the density constraint
//! then spreads them over it.

use crate::plan::{Copy, DT};
use crowd_edit::Rect;
use glam::DVec2;

/// How long before and after a step a gathered walker must be free to move, s: a walker
/// about to take its border band is left where its plan has it.
pub const FREE_S: f64 = 0.0;

/// How far from the rectangle a walker may be planned and still be gathered, m: what it can
/// walk in the lead-in at a little over its own pace.
pub const REACH_M: f64 = 5.0;

/// How far inside the rectangle gathered walkers are asked to stand, m (at most a quarter of
/// its side): half a kernel width, so that most of each one's kernel falls in the rectangle.
pub const INSET_M: f64 = 0.5;

/// The closest two gathered walkers' centres can be on average, m: a body and a step.
pub const SPACING_M: f64 = 1.0;

/// Who comes, where to, and what the patch can show.
#[derive(Clone, Debug)]
pub struct Gathering {
    /// Per step of the window, the walkers asked to be inside [`Gathering::inside`].
    pub who: Vec<Vec<usize>>,
    pub inside: Rect,
    /// Over the window's steps, summed: the walkers the edit may move at all, and the others
    /// the plans put in the rectangle (the most the patch could show, if all stood in it).
    pub people: f64,
}

/// A density edit's rectangle on one patch's problem, and its target, people per m2.
pub struct Square {
    pub rect: Rect,
    pub target: f64,
}

/// The gathering for `square` over the window's `steps` (problem clock from `span.0`);
/// `positions(k, i)` is where copy `i` is planned at step `k`. At each step, the walkers
/// free to move then and near enough come, the nearest first, as many as the target needs
/// beyond the people the others' plans bring (counted: the kernel density constraint then
/// spreads them over the rectangle).
pub fn gather(
    square: &Square,
    steps: std::ops::RangeInclusive<usize>,
    copies: &[Copy],
    span: (f64, f64),
    positions: &dyn Fn(usize, usize) -> DVec2,
) -> Gathering {
    let rect = square.rect;
    let inset = ((rect.max - rect.min) / 4.0).min(DVec2::splat(INSET_M));
    let inside = Rect::new(rect.min + inset, rect.max - inset);
    let fits = (rect.area() / (SPACING_M * SPACING_M)).floor() as usize;
    let asked = square.target * rect.area();
    let mut people = 0.0;
    let who = steps
        .map(|k| {
            let t = span.0 + k as f64 * DT;
            let outside = |i: usize| {
                let p = positions(k, i);
                p.distance(p.clamp(rect.min, rect.max))
            };
            let free =
                |c: &Copy| c.mask(t - FREE_S, span) >= 1.0 && c.mask(t + FREE_S, span) >= 1.0;
            // Those who cannot come, but whose plans bring them.
            let (mut candidates, mut there) = (Vec::new(), 0usize);
            for (i, c) in copies.iter().enumerate() {
                if free(c) && outside(i) <= REACH_M {
                    candidates.push(i);
                } else if c.present(t) && outside(i) == 0.0 {
                    there += 1;
                }
                // Anyone the edit may move at all, or whose plan is in it.
                let movable = c.mask(t, span) > 0.0;
                people += f64::from(u8::from(c.present(t) && (movable || outside(i) == 0.0)));
            }
            let wanted = (asked - there as f64).ceil().max(0.0) as usize;
            candidates.sort_by(|&a, &b| outside(a).total_cmp(&outside(b)).then(a.cmp(&b)));
            candidates.truncate(wanted.min(fits));
            candidates.sort_unstable();
            candidates
        })
        .collect();
    Gathering {
        who,
        inside,
        people,
    }
}
