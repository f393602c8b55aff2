//! Where each walker of a patch comes, by place and by moment of the loop: the broad phase
//! of [`crate::rows`] for [`crate::Tracks::indexed`]. The patch is cut into cells a reach and
//! a half wide and the period into slices of about 0.75 s; each (slice, cell) slot holds the
//! set of walkers that come within half a reach of the cell during the slice, in any period.
//! Two walkers that come within reach of each other at some moment (a whole number of periods
//! apart) then share that moment's slot, so a walker that shares no slot with a moved
//! walker's changed stretch needs no measuring: in a dense patch a push so measures a few
//! neighbours, not everyone.

use crate::segment::Segment;
use crate::tracks::Span;
use glam::DVec2;

/// About how long a slice of the period lasts, s, and how many reaches wide a cell is: a
/// walker covers about a cell in a slice. (Stage 5 on `painting`, user seconds: 0.5 s and 1
/// reach 10.6-10.9, 0.75 s and 1.5 reaches 10.2-10.7, 1 s and 2 reaches 10.3-10.6; the
/// finer the slots, the fewer pairs measured and the more kept up to date.)
const SLICE_S: f64 = 0.75;
const CELL_REACHES: f64 = 1.5;
/// The most slices of a period, cells along a side of the grid and slots in all: a long period
/// widens the slices, a large patch or a path far outside it widens the cells, and none grows
/// the grid past 2 MB a 64 walkers.
const MAX_SLICES: usize = 256;
const MAX_CELLS: usize = 64;
const MAX_SLOTS: usize = 1 << 18;
/// How far a slice reaches past its ends, s: a moment at a slice's edge, rounded one way in
/// one walker's time and the other way a period later, is in both slices.
const EDGE_S: f64 = 1e-6;

/// The cut of a patch into slots: cells of `1 / per_m` from `origin` (a place beyond the grid
/// falls in its edge cell), slices of `slice_s` of the period.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Grid {
    origin: DVec2,
    /// Cells a metre (the inverse of their side).
    per_m: f64,
    cells: [usize; 2],
    slice_s: f64,
    slices: usize,
    /// How far around a piece its slots reach: half the reach, and a hair more so that a pair
    /// measured a hair nearer than reach by rounding is never missed.
    around: f64,
}

impl Grid {
    fn new(segs: &[Vec<Segment>], reach: f64, period: f64) -> Grid {
        let around = reach / 2.0 * (1.0 + 1e-9) + 1e-9;
        let (lo, hi) = segs.iter().flatten().fold(
            (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
            |(lo, hi), s| (lo.min(s.p0).min(s.p1), hi.max(s.p0).max(s.p1)),
        );
        let (lo, hi) = match lo.is_finite() && hi.is_finite() {
            true => (lo - around, hi + around),
            false => (DVec2::ZERO, DVec2::ZERO),
        };
        let extent = (hi - lo).max(DVec2::ZERO);
        let slices = ((period / SLICE_S).ceil() as usize).clamp(1, MAX_SLICES);
        let mut cell_m = (CELL_REACHES * reach)
            .max(extent.max_element() / MAX_CELLS as f64)
            .max(1e-3);
        let along = |x: f64, cell_m: f64| ((x / cell_m).ceil() as usize).clamp(1, MAX_CELLS);
        while slices * along(extent.x, cell_m) * along(extent.y, cell_m) > MAX_SLOTS {
            cell_m *= 2.0;
        }
        Grid {
            origin: lo,
            per_m: 1.0 / cell_m,
            cells: [along(extent.x, cell_m), along(extent.y, cell_m)],
            slice_s: period / slices as f64,
            slices,
            around,
        }
    }

    fn slots(&self) -> usize {
        self.slices * self.cells[0] * self.cells[1]
    }

    /// The cell of `p` along each axis, held at the grid's edge.
    fn cell_of(&self, p: DVec2) -> [usize; 2] {
        let c = (p - self.origin) * self.per_m;
        // Truncation is the floor from 0 up, and the edge cell below 0.
        let hold = |x: f64, n: usize| (x.max(0.0) as usize).min(n - 1);
        [hold(c.x, self.cells[0]), hold(c.y, self.cells[1])]
    }

    /// The slice of the moment `t`, counted from time 0 (not wrapped to the period).
    fn slice_of(&self, t: f64) -> i64 {
        floor(t / self.slice_s)
    }

    /// Every slot the pieces `segs` come into, with the slice (counted from time 0) it came
    /// in at (a slot may come more than once).
    fn visit(&self, segs: &[Segment], mut slot: impl FnMut(i64, u32)) {
        let per_slice = self.cells[0] * self.cells[1];
        let slices = self.slices as i64;
        for s in segs {
            let v = s.velocity();
            let (k0, k1) = (self.slice_of(s.t0 - EDGE_S), self.slice_of(s.t1 + EDGE_S));
            // The slice in the period, kept in step with `k` (no division a slice).
            let mut wrapped = k0.rem_euclid(slices) as usize;
            for k in k0..=k1 {
                let from = s.t0.max(k as f64 * self.slice_s - EDGE_S);
                let to = s.t1.min((k + 1) as f64 * self.slice_s + EDGE_S);
                if from <= to {
                    // A piece is straight: where it is over the slice lies between its ends.
                    let (p, q) = (s.p0 + v * (from - s.t0), s.p0 + v * (to - s.t0));
                    let c0 = self.cell_of(p.min(q) - self.around);
                    let c1 = self.cell_of(p.max(q) + self.around);
                    let base = wrapped * per_slice;
                    for y in c0[1]..=c1[1] {
                        for x in c0[0]..=c1[0] {
                            slot(k, (base + y * self.cells[0] + x) as u32);
                        }
                    }
                }
                wrapped += 1;
                if wrapped == self.slices {
                    wrapped = 0;
                }
            }
        }
    }
}

/// `x.floor() as i64` (saturating), without the library call: asked a few times a piece.
fn floor(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) > x {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// A set of a patch's walkers, a bit each.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Walkers(Vec<u64>);

impl Walkers {
    pub(crate) fn contains(&self, p: usize) -> bool {
        self.0.get(p / 64).is_some_and(|w| w >> (p % 64) & 1 == 1)
    }
}

/// The walkers of each slot of a patch (see the module's comment).
#[derive(Debug, Clone)]
pub(crate) struct Occupancy {
    grid: Grid,
    /// Words of a slot's set.
    words: usize,
    /// Slot by slot, `words` words each.
    bits: Vec<u64>,
    /// Each walker's slots, with the slice (from time 0) it came into each at: what takes it
    /// out of them, and what finds who is near it over a stretch of its time.
    slots: Vec<Vec<(i64, u32)>>,
    /// Where each of a walker's pieces' slots end in its `slots`: a push changes a stretch
    /// of a path, and only that stretch's pieces are visited again ([`Occupancy::remark`]).
    ends: Vec<Vec<u32>>,
    /// The slots a [`Occupancy::remark`] took out, a bit each (all clear between calls).
    gone: Vec<u64>,
    /// A [`Occupancy::remark`]'s kept tail of slots and ends, held for their allocations.
    aside: (Vec<(i64, u32)>, Vec<u32>),
}

/// How a walker's pieces changed: the first `head` and the last `tail` are the same pieces as
/// before (as [`crate::Tracks::set`] finds them).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Kept {
    pub head: usize,
    pub tail: usize,
}

impl Occupancy {
    /// The slots of the walkers `segs`, for pairs that matter within `reach` in a loop of
    /// `period`.
    pub(crate) fn new(segs: &[Vec<Segment>], reach: f64, period: f64) -> Occupancy {
        let grid = Grid::new(segs, reach, period);
        let words = segs.len().div_ceil(64).max(1);
        let mut occupancy = Occupancy {
            grid,
            words,
            bits: vec![0; grid.slots() * words],
            slots: vec![Vec::new(); segs.len()],
            ends: vec![Vec::new(); segs.len()],
            gone: vec![0; grid.slots().div_ceil(64)],
            aside: (Vec::new(), Vec::new()),
        };
        for (p, s) in segs.iter().enumerate() {
            occupancy.mark(p, s);
        }
        occupancy
    }

    /// Walker `p` now comes where the pieces `segs` do, and nowhere else.
    pub(crate) fn mark(&mut self, p: usize, segs: &[Segment]) {
        let was = self.ends[p].len();
        self.remark(p, segs, Kept { head: 0, tail: 0 }, was);
    }

    /// Walker `p` now walks `segs`, whose first `kept.head` and last `kept.tail` pieces are
    /// the first and last of the `was` pieces it walked before: only the pieces between are
    /// visited again (a push moves a stretch of a path: a quarter of its pieces on
    /// `painting`, where visiting every piece again was a sixth of stage 5). The slots and
    /// sets are the ones visiting every piece again gives.
    pub(crate) fn remark(&mut self, p: usize, segs: &[Segment], kept: Kept, was: usize) {
        let (word, bit) = (p / 64, 1u64 << (p % 64));
        let Kept { head, tail } = kept;
        let mut slots = std::mem::take(&mut self.slots[p]);
        let mut ends = std::mem::take(&mut self.ends[p]);
        let end_of = |ends: &[u32], piece: usize| piece.checked_sub(1).map_or(0, |n| ends[n]);
        // The old slots of the changed pieces: from the end of the head's to the start of
        // the tail's. Each is taken out, and noted in `gone`.
        let (from, to) = (
            end_of(&ends, head) as usize,
            end_of(&ends, was - tail) as usize,
        );
        let flip = |gone: &mut [u64], slot: u32| gone[slot as usize / 64] ^= 1 << (slot % 64);
        let is_gone = |gone: &[u64], slot: u32| gone[slot as usize / 64] >> (slot % 64) & 1 == 1;
        for &(_, slot) in &slots[from..to] {
            self.bits[slot as usize * self.words + word] &= !bit;
            if !is_gone(&self.gone, slot) {
                flip(&mut self.gone, slot);
            }
        }
        if from < to {
            // A kept piece may come into a slot a changed one left: it is still in it.
            for &(_, slot) in slots[..from].iter().chain(&slots[to..]) {
                if is_gone(&self.gone, slot) {
                    self.bits[slot as usize * self.words + word] |= bit;
                }
            }
            for &(_, slot) in &slots[from..to] {
                if is_gone(&self.gone, slot) {
                    flip(&mut self.gone, slot);
                }
            }
        }
        // The tail's slots and ends wait aside while the changed pieces' are made; its ends
        // then move by how many more (or fewer) slots those took.
        let (mut tail_slots, mut tail_ends) = std::mem::take(&mut self.aside);
        tail_slots.clear();
        tail_slots.extend_from_slice(&slots[to..]);
        tail_ends.clear();
        tail_ends.extend_from_slice(&ends[was - tail..]);
        slots.truncate(from);
        ends.truncate(head);
        for s in &segs[head..segs.len() - tail] {
            self.grid.visit(std::slice::from_ref(s), |k, slot| {
                self.bits[slot as usize * self.words + word] |= bit;
                slots.push((k, slot));
            });
            ends.push(slots.len() as u32);
        }
        let made = slots.len();
        ends.extend(tail_ends.iter().map(|&e| (e as usize - to + made) as u32));
        slots.extend_from_slice(&tail_slots);
        self.slots[p] = slots;
        self.ends[p] = ends;
        self.aside = (tail_slots, tail_ends);
    }

    /// Every walker that shares a slot with walker `p` over `span` of its time: a walker not in
    /// it never comes within reach of `p` then, in any period.
    pub(crate) fn near(&self, p: usize, (lo, hi): Span) -> Walkers {
        let (from, to) = (
            self.grid.slice_of(lo - EDGE_S),
            self.grid.slice_of(hi + EDGE_S),
        );
        let mut near = vec![0u64; self.words];
        for &(k, slot) in &self.slots[p] {
            if k >= from && k <= to {
                let of = &self.bits[slot as usize * self.words..][..self.words];
                for (n, w) in near.iter_mut().zip(of) {
                    *n |= w;
                }
            }
        }
        Walkers(near)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encounter::pair;
    use crate::testing::{open_patch, walk};
    use crate::tracks::{ALWAYS, Tracks};
    use proptest::prelude::*;

    fn any_walk() -> impl Strategy<Value = Vec<Segment>> {
        (
            -25.0f64..25.0,
            (-1.0f64..9.0, -1.0f64..9.0),
            proptest::collection::vec((0.0f64..4.0, -3.0f64..3.0, -3.0f64..3.0), 1..8),
        )
            .prop_map(|(start, from, steps)| {
                let steps: Vec<_> = steps.into_iter().map(|(dt, dx, dy)| (dx, dy, dt)).collect();
                walk(start, from, &steps)
            })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// Every pair the exact test finds within reach shares a slot, over the whole of both
        /// walks and over any stretch of the first that holds the encounter.
        #[test]
        fn every_pair_within_reach_shares_a_slot(
            walks in proptest::collection::vec(any_walk(), 2..7),
            period in 2.0f64..30.0,
            radius in 0.05f64..1.0,
            moved in 0usize..7,
            (from, to) in (-30.0f64..30.0, 0.0f64..20.0),
        ) {
            let patch = open_patch(period, radius);
            let tracks = Tracks::new(walks.clone());
            let occupancy = Occupancy::new(&walks, 2.0 * radius, period);
            let a = moved % walks.len();
            let span = (from, from + to);
            let whole = occupancy.near(a, ALWAYS);
            let during = occupancy.near(a, span);
            for b in 0..walks.len() {
                if let Some(e) = pair(&tracks, a, b, &patch) {
                    prop_assert!(whole.contains(b), "{a} and {b} met at {}", e.t);
                    if e.t >= span.0 && e.t <= span.1 {
                        prop_assert!(during.contains(b), "{a} and {b} met at {}", e.t);
                    }
                }
            }
        }
    }

    proptest! {
        /// Two walkers side by side a hair less than a reach apart, anywhere in the grid and
        /// at any moment of the loop, share a slot: the slots reach round a piece far enough.
        #[test]
        fn walkers_just_within_reach_share_a_slot(
            walks in proptest::collection::vec(any_walk(), 1..4),
            (x, y, quarter, speed) in (0.0f64..8.0, 0.0f64..8.0, 0u8..4, 0.0f64..2.0),
            (start, duration, apart) in (-20.0f64..20.0, 0.1f64..6.0, 0.99f64..0.9999),
            (period, radius) in (2.0f64..30.0, 0.05f64..1.0),
        ) {
            let reach = 2.0 * radius;
            // Along an axis: the gap between their slots is then the gap between them.
            let along = DVec2::from_angle(f64::from(quarter) * std::f64::consts::FRAC_PI_2);
            let step = along * speed * duration;
            let a = walk(start, (x, y), &[(step.x, step.y, duration)]);
            let aside = DVec2::new(x, y) + along.perp() * apart * reach;
            let b = walk(start, (aside.x, aside.y), &[(step.x, step.y, duration)]);
            let mut all = walks;
            all.push(a);
            all.push(b);
            let (ia, ib) = (all.len() - 2, all.len() - 1);
            let occupancy = Occupancy::new(&all, reach, period);
            prop_assert!(occupancy.near(ia, ALWAYS).contains(ib));
            prop_assert!(occupancy.near(ib, (start, start)).contains(ia));
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// Visiting only a walk's changed stretch again leaves every slot's set, and every
        /// walker's slots, as visiting the whole walk again does: over a run of changes, in
        /// any grid, with kept pieces that share slots with the changed ones.
        #[test]
        fn a_changed_stretch_remarked_is_a_walk_marked_anew(
            walks in proptest::collection::vec(any_walk(), 1..5),
            changes in proptest::collection::vec(
                (0usize..5, 0usize..8, 0usize..8, any_walk()), 1..6),
            period in 2.0f64..30.0,
            radius in 0.05f64..1.0,
        ) {
            let reach = 2.0 * radius;
            let mut walks = walks;
            let mut occupancy = Occupancy::new(&walks, reach, period);
            for (who, head, tail, middle) in changes {
                let p = who % walks.len();
                let old = &walks[p];
                let head = head.min(old.len());
                let tail = tail.min(old.len() - head);
                // Changed pieces anywhere the walk goes: the middle moved to start where
                // the head ends.
                let start = head.checked_sub(1).map_or(0.0, |h| old[h].t1);
                let shift = start - middle[0].t0;
                let middle = middle.iter().map(|s| s.shifted(shift));
                let new: Vec<Segment> = old[..head]
                    .iter()
                    .copied()
                    .chain(middle)
                    .chain(old[old.len() - tail..].iter().copied())
                    .collect();
                let was = old.len();
                occupancy.remark(p, &new, Kept { head, tail }, was);
                walks[p] = new;
                // The grid was cut for the first walks: the same cut, marked anew.
                let mut fresh = occupancy.clone();
                fresh.bits.iter_mut().for_each(|w| *w = 0);
                fresh.slots.iter_mut().for_each(Vec::clear);
                fresh.ends.iter_mut().for_each(Vec::clear);
                for (q, w) in walks.iter().enumerate() {
                    fresh.mark(q, w);
                }
                prop_assert_eq!(&occupancy.bits, &fresh.bits);
                prop_assert_eq!(&occupancy.slots, &fresh.slots);
                prop_assert_eq!(&occupancy.ends, &fresh.ends);
                prop_assert!(occupancy.gone.iter().all(|&w| w == 0));
            }
        }
    }

    /// A long loop over a large place widens the slots; it does not grow their number.
    #[test]
    fn the_grid_holds_at_most_max_slots() {
        let far = walk(0.0, (-400.0, -300.0), &[(800.0, 700.0, 900.0)]);
        let grid = Grid::new(&[far], 0.6, 1000.0);
        assert!(grid.slots() <= MAX_SLOTS, "{} slots", grid.slots());
        assert_eq!(grid.slices, MAX_SLICES);
    }

    /// Two walkers that cross one place half a period apart share no slot; at the same moment
    /// they do, and a walker moved to the later walk is no longer near.
    #[test]
    fn walkers_apart_in_time_share_no_slot() {
        let across = walk(0.0, (0.0, 4.0), &[(8.0, 0.0, 8.0)]);
        let later = walk(10.0, (4.0, 0.0), &[(0.0, 8.0, 8.0)]);
        let now = walk(0.0, (4.0, 0.0), &[(0.0, 8.0, 8.0)]);
        let mut occupancy = Occupancy::new(&[across, later.clone(), now], 0.6, 20.0);
        let near = occupancy.near(0, ALWAYS);
        assert!(near.contains(0) && !near.contains(1) && near.contains(2));
        occupancy.mark(2, &later);
        assert!(!occupancy.near(0, ALWAYS).contains(2));
    }
}
