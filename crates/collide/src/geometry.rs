//! Closest approach of walkers on straight space-time segments (Ramirez et al. eq. 8-10).

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
    pub fn velocity(&self) -> DVec2 {
        if self.t1 > self.t0 {
            (self.p1 - self.p0) / (self.t1 - self.t0)
        } else {
            DVec2::ZERO
        }
    }

    pub fn at(&self, t: f64) -> DVec2 {
        self.p0 + self.velocity() * (t - self.t0)
    }

    /// The same segment `dt` later.
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
    let kmin = ((a.0 - b.1) / period).ceil() as i64;
    let kmax = ((a.1 - b.0) / period).floor() as i64;
    kmin..=kmax
}

/// The smallest distance between walkers on `a` and `b` during the time both exist, and when
/// it happens; `None` when they never coexist. Analytic: with w the offset at the start of the
/// common interval and dv the relative velocity, the distance |w + dv t| is smallest at
/// t = -w.dv / |dv|^2, clamped to the interval (eq. 10).
pub fn closest(a: &Segment, b: &Segment) -> Option<(f64, f64)> {
    let (ts, te) = (a.t0.max(b.t0), a.t1.min(b.t1));
    if ts > te {
        return None;
    }
    let w = a.at(ts) - b.at(ts);
    let dv = a.velocity() - b.velocity();
    let speed2 = dv.length_squared();
    let tc = if speed2 > 1e-18 {
        (-w.dot(dv) / speed2).clamp(0.0, te - ts)
    } else {
        0.0
    };
    Some(((w + dv * tc).length(), ts + tc))
}

/// Smallest distance from the path of `s` to the rectangle [min, max] (0 when it crosses it),
/// the time along `s` where it happens, and the point of the rectangle nearest to it.
pub fn to_rect(s: &Segment, min: DVec2, max: DVec2) -> (f64, f64, DVec2) {
    // The distance to a box is convex along a line: a ternary search finds its minimum, with
    // the two ends checked too.
    let dist = |f: f64| {
        let p = s.p0.lerp(s.p1, f);
        (p.clamp(min, max) - p).length()
    };
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..60 {
        let (m1, m2) = (lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0);
        if dist(m1) <= dist(m2) {
            hi = m2;
        } else {
            lo = m1;
        }
    }
    let f = [0.0, 1.0, (lo + hi) / 2.0]
        .into_iter()
        .min_by(|a, b| dist(*a).total_cmp(&dist(*b)))
        .expect("three candidates");
    let p = s.p0.lerp(s.p1, f);
    (dist(f), s.t0 + f * (s.t1 - s.t0), p.clamp(min, max))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seg(x0: f64, y0: f64, t0: f64, x1: f64, y1: f64, t1: f64) -> Segment {
        Segment {
            p0: DVec2::new(x0, y0),
            t0,
            p1: DVec2::new(x1, y1),
            t1,
        }
    }

    #[test]
    fn head_on_walkers_meet_in_the_middle() {
        let a = seg(0.0, 0.0, 0.0, 8.0, 0.0, 8.0);
        let b = seg(8.0, 0.5, 0.0, 0.0, 0.5, 8.0);
        let (d, t) = closest(&a, &b).unwrap();
        assert!((d - 0.5).abs() < 1e-12 && (t - 4.0).abs() < 1e-12);
    }

    #[test]
    fn walkers_who_never_coexist_never_meet() {
        let a = seg(0.0, 0.0, 0.0, 1.0, 0.0, 1.0);
        let b = seg(0.0, 0.0, 2.0, 1.0, 0.0, 3.0);
        assert_eq!(closest(&a, &b), None);
        assert!(closest(&a, &b.shifted(-2.0)).is_some());
    }

    #[test]
    fn distance_to_a_box_is_found_along_the_path() {
        let s = seg(0.0, 3.0, 0.0, 8.0, 3.0, 8.0);
        let (d, t, q) = to_rect(&s, DVec2::new(3.0, 0.0), DVec2::new(5.0, 2.0));
        assert!((d - 1.0).abs() < 1e-6, "{d}");
        assert!(
            (2.99..=5.01).contains(&t) && (q.y - 2.0).abs() < 1e-12,
            "{t} {q}"
        );
    }
}
