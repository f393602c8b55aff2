//! The walkers whose heading is turning at a frame's time ([`crate::turn`]). Turns last
//! milliseconds (a quarter turn: 0.25 s at 360 degrees a second), so at any frame a few walkers
//! turn; the placing loops write every walker's held heading, and these few samples are set
//! afterwards. Turns still to come (a standing walker turns as it walks off) wait in a heap
//! by their start, so a frame touches only the turns under way.

use super::Sample;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// A walker's turn: from `h0` by `turn` radians, evenly from absolute tick `from` to `to`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Turn {
    pub id: u32,
    pub from: f64,
    pub to: f64,
    pub h0: f32,
    pub turn: f32,
}

impl Turn {
    /// The heading at absolute tick `now`, radians in [-pi, pi).
    pub fn at(&self, now: f64) -> f32 {
        let s = ((now - self.from) / (self.to - self.from)).clamp(0.0, 1.0) as f32;
        let h = self.h0 + self.turn * s;
        let pi = std::f32::consts::PI;
        if h >= pi {
            h - 2.0 * pi
        } else if h < -pi {
            h + 2.0 * pi
        } else {
            h
        }
    }
}

/// A turn still to come, first out of the heap the one that starts first.
#[derive(Debug, Clone, Copy)]
struct Later(Turn);

impl PartialEq for Later {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Later {}

impl PartialOrd for Later {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Later {
    fn cmp(&self, other: &Self) -> Ordering {
        // Reversed: the max-heap gives the earliest start.
        other.0.from.total_cmp(&self.0.from)
    }
}

/// The turns of a sampler: under way, in id order, and still to come.
#[derive(Debug, Clone, Default)]
pub(super) struct Turning {
    under_way: Vec<Turn>,
    /// Turns met this frame that are under way, in the order met (id order: blocks go in
    /// order, and so do the walkers of a block).
    fresh: Vec<Turn>,
    later: BinaryHeap<Later>,
}

impl Turning {
    pub fn clear(&mut self) {
        self.under_way.clear();
        self.fresh.clear();
        self.later.clear();
    }

    /// Keeps turn `t`, met at absolute tick `now` (in id order within a frame).
    pub fn add(&mut self, t: Turn, now: f64) {
        if t.from <= now {
            self.fresh.push(t);
        } else {
            self.later.push(Later(t));
        }
    }

    /// Sets the headings of the samples in `out` (in id order, placed at absolute tick `now`)
    /// whose walker is turning, and forgets the turns that are over. A turn of a walker that
    /// has since left its piece is over by then: turns lie inside their pieces.
    pub fn apply(&mut self, now: f64, out: &mut [Sample]) {
        let mut woken = Vec::new();
        while self.later.peek().is_some_and(|l| l.0.from <= now) {
            woken.push(self.later.pop().expect("peeked").0);
        }
        // One list in id order: the turns still under way, this frame's and the woken, three
        // runs in id order that the stable sort finds and merges in one pass.
        self.under_way.retain(|t| t.to > now);
        self.under_way
            .extend(self.fresh.drain(..).filter(|t| t.to > now));
        self.under_way
            .extend(woken.into_iter().filter(|t| t.to > now));
        self.under_way.sort_by_key(|t| t.id);
        // Each looked for after the last (galloping): a few steps each.
        let mut from = 0;
        for t in &self.under_way {
            // With every walker in view, walker `id` is sample `id`.
            let i = match out.get(t.id as usize) {
                Some(s) if s.id == t.id => t.id as usize,
                _ => from + gallop(&out[from..], t.id),
            };
            from = i;
            if out.get(i).is_some_and(|s| s.id == t.id) {
                out[i].heading = t.at(now);
            }
        }
    }
}

/// The first place in `out` (in id order) whose id is at least `id`: doubling steps from the
/// start, then a binary search of the last step.
fn gallop(out: &[Sample], id: u32) -> usize {
    let mut hi = 1;
    while hi < out.len() && out[hi - 1].id < id {
        hi *= 2;
    }
    let lo = hi / 2;
    let hi = hi.min(out.len());
    lo + out[lo..hi].partition_point(|s| s.id < id)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(id: u32) -> Sample {
        Sample {
            id,
            x: 0.0,
            y: 0.0,
            heading: 9.0,
        }
    }

    /// Walker `id` turns from 1 rad by half a radian, from tick `from` to `to`.
    fn turn(id: u32, from: f64, to: f64) -> Turn {
        Turn {
            id,
            from,
            to,
            h0: 1.0,
            turn: 0.5,
        }
    }

    #[test]
    fn a_turn_sets_its_walkers_heading_only_while_it_runs() {
        let mut t = Turning::default();
        // Walker 1 turns from tick 10 to 20 (met at 5: still to come); walker 3 from 0 to 8.
        t.add(turn(1, 10.0, 20.0), 5.0);
        t.add(turn(3, 0.0, 8.0), 5.0);
        let mut out = vec![sample(0), sample(1), sample(3)];
        t.apply(5.0, &mut out);
        assert_eq!(out[1].heading, 9.0, "not started");
        assert!((out[2].heading - (1.0 + 0.5 * 5.0 / 8.0)).abs() < 1e-6);
        let mut out = vec![sample(1), sample(3)];
        t.apply(15.0, &mut out);
        assert!((out[0].heading - 1.25).abs() < 1e-6, "{}", out[0].heading);
        assert_eq!(out[1].heading, 9.0, "over");
        let mut out = vec![sample(1)];
        t.apply(25.0, &mut out);
        assert_eq!(out[0].heading, 9.0, "over");
        assert!(t.under_way.is_empty() && t.later.is_empty());
    }

    #[test]
    fn a_turn_past_half_a_turn_wraps_into_the_headings_range() {
        let t = Turn {
            h0: 3.0,
            ..turn(0, 0.0, 10.0)
        };
        let h = t.at(5.0);
        assert!((h - (3.25 - std::f32::consts::TAU)).abs() < 1e-6, "{h}");
    }

    #[test]
    fn walkers_out_of_view_are_skipped() {
        let mut t = Turning::default();
        for id in [2, 5, 7, 40] {
            t.add(turn(id, 0.0, 10.0), 1.0);
        }
        // Only 5 and 40 in view (samples in id order, not at their id's place).
        let mut out = vec![sample(5), sample(40)];
        t.apply(5.0, &mut out);
        assert!(
            out.iter().all(|s| (s.heading - 1.25).abs() < 1e-6),
            "{out:?}"
        );
    }
}
