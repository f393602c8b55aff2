//! A walker's motion as straight space-time segments: the shape every stage after matching
//! measures (stage 5 pushes them apart, stage 6 re-checks its curves with them, the check
//! tiles the world with them). A segment is a straight walk at constant velocity from one
//! place and time to another; a path is segments end to end in time.

use glam::DVec2;

/// A walker moving in a straight line from `p0` at `t0` to `p1` at `t1`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    pub p0: DVec2,
    pub t0: f64,
    pub p1: DVec2,
    pub t1: f64,
}

impl Segment {
    #[inline]
    pub fn velocity(&self) -> DVec2 {
        if self.t1 > self.t0 {
            (self.p1 - self.p0) / (self.t1 - self.t0)
        } else {
            DVec2::ZERO
        }
    }

    #[inline]
    pub fn at(&self, t: f64) -> DVec2 {
        self.p0 + self.velocity() * (t - self.t0)
    }

    /// The same segment `dt` later.
    #[inline]
    pub fn shifted(&self, dt: f64) -> Segment {
        Segment {
            t0: self.t0 + dt,
            t1: self.t1 + dt,
            ..*self
        }
    }

    /// A character standing at `p` during `[t0, t1]`.
    pub fn standing(p: DVec2, t0: f64, t1: f64) -> Segment {
        Segment {
            p0: p,
            t0,
            p1: p,
            t1,
        }
    }
}

/// The straight pieces between consecutive `(position, time)` points of a path.
pub fn pieces(points: impl IntoIterator<Item = (DVec2, f64)>) -> Vec<Segment> {
    let points: Vec<(DVec2, f64)> = points.into_iter().collect();
    points
        .windows(2)
        .map(|w| Segment {
            p0: w[0].0,
            t0: w[0].1,
            p1: w[1].0,
            t1: w[1].1,
        })
        .collect()
}

/// Where a walker on the pieces `segs` (in time order, end to end) is at time `t`, held at
/// the first or last point outside their span.
pub fn at_time(segs: &[Segment], t: f64) -> Option<DVec2> {
    let i = segs
        .partition_point(|s| s.t1 < t)
        .min(segs.len().checked_sub(1)?);
    Some(segs[i].at(t.clamp(segs[i].t0, segs[i].t1)))
}

/// The whole numbers of periods k for which something existing during `b`, shifted k periods
/// later, exists during `a` too.
pub fn copies(a: (f64, f64), b: (f64, f64), period: f64) -> std::ops::RangeInclusive<i64> {
    let kmin = ceil_i64((a.0 - b.1) / period);
    let kmax = floor_i64((a.1 - b.0) / period);
    kmin..=kmax
}

/// `x.ceil() as i64`, without the library call (most of `copies`, asked for every pair).
fn ceil_i64(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) < x {
        t.saturating_add(1)
    } else {
        t
    }
}

/// `x.floor() as i64`, likewise.
fn floor_i64(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) > x {
        t.saturating_sub(1)
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn a_path_is_held_at_its_ends_outside_its_span() {
        let segs = pieces([
            (DVec2::new(0.0, 0.0), 1.0),
            (DVec2::new(2.0, 0.0), 3.0),
            (DVec2::new(2.0, 2.0), 4.0),
        ]);
        assert_eq!(segs.len(), 2);
        assert_eq!(at_time(&segs, 0.0), Some(DVec2::new(0.0, 0.0)));
        assert_eq!(at_time(&segs, 2.0), Some(DVec2::new(1.0, 0.0)));
        assert_eq!(at_time(&segs, 3.5), Some(DVec2::new(2.0, 1.0)));
        assert_eq!(at_time(&segs, 9.0), Some(DVec2::new(2.0, 2.0)));
        assert_eq!(at_time(&[], 1.0), None);
    }

    #[test]
    fn whole_numbers_round_as_the_library_does() {
        let edges = [
            0.0, -0.0, 0.5, -0.5, 2.0, -2.0, 2.5, -2.5, 1e300, -1e300, 9.3e18, -9.3e18,
        ];
        for x in edges
            .into_iter()
            .chain([f64::NAN, f64::INFINITY, f64::NEG_INFINITY])
        {
            assert_eq!(ceil_i64(x), x.ceil() as i64, "{x}");
            assert_eq!(floor_i64(x), x.floor() as i64, "{x}");
        }
    }

    proptest! {
        #[test]
        fn rounding_to_whole_numbers_matches_the_library(x in -1e20f64..1e20) {
            prop_assert_eq!(ceil_i64(x), x.ceil() as i64);
            prop_assert_eq!(floor_i64(x), x.floor() as i64);
        }

        /// `copies` names exactly the whole numbers of periods by which `b`, shifted, overlaps
        /// `a` in time.
        #[test]
        fn copies_are_exactly_the_overlapping_shifts(
            (a0, da) in (-30.0f64..30.0, 0.0f64..25.0),
            (b0, db) in (-30.0f64..30.0, 0.0f64..25.0),
            period in 1.0f64..20.0,
        ) {
            let (a, b) = ((a0, a0 + da), (b0, b0 + db));
            let named = copies(a, b, period);
            for k in -20i64..=20 {
                let shift = k as f64 * period;
                let overlaps = b.0 + shift <= a.1 && b.1 + shift >= a.0;
                // At the very ends the division may round either way.
                let edge = ((b.0 + shift - a.1).abs() < 1e-9) || ((b.1 + shift - a.0).abs() < 1e-9);
                if !edge {
                    prop_assert_eq!(named.contains(&k), overlaps, "k = {}", k);
                }
            }
        }
    }
}
