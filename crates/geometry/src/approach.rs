//! How close two moving things come: the one closest-approach computation of the pipeline
//! (Ramirez et al. eq. 8-10), and a straight walk's distance to a box.
//!
//! Every distance a stage decides by (stage 3's spacing of crossings, stage 5's encounters,
//! stage 6's re-check, the world check) goes through [`approach`], so they cannot disagree in
//! the last bit about whether two walkers touch.

use crate::segment::Segment;
use glam::DVec2;

/// The closest approach of two points moving at constant velocities for `duration` seconds:
/// with `w` their offset at the start and `dv` their relative velocity, the distance
/// |w + dv t| is smallest at t = -w.dv / |dv|^2, clamped to `[0, duration]` (eq. 10).
/// Returns that distance and t. Points at the same velocity are closest at the start.
#[inline]
pub fn approach(w: DVec2, dv: DVec2, duration: f64) -> (f64, f64) {
    let speed2 = dv.length_squared();
    let t = if speed2 > 1e-18 {
        (-w.dot(dv) / speed2).clamp(0.0, duration)
    } else {
        0.0
    };
    ((w + dv * t).length(), t)
}

/// The smallest distance between walkers on `a` and `b` during the time both exist, and when
/// it happens; `None` when they never coexist. Analytic ([`approach`] over the common
/// interval).
#[inline]
pub fn closest(a: &Segment, b: &Segment) -> Option<(f64, f64)> {
    let (ts, te) = (a.t0.max(b.t0), a.t1.min(b.t1));
    if ts > te {
        return None;
    }
    let w = a.at(ts) - b.at(ts);
    let dv = a.velocity() - b.velocity();
    let (d, tc) = approach(w, dv, te - ts);
    Some((d, ts + tc))
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

/// Where on the straight piece from `a` to `z` the point nearest `q` lies, as a share of the
/// way (0 at `a`, 1 at `z`; 0 when the piece is a point).
pub fn nearest_along(a: DVec2, z: DVec2, q: DVec2) -> f64 {
    let d = z - a;
    let l2 = d.length_squared();
    if l2 > 0.0 {
        ((q - a).dot(d) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// The smallest distance from the path of `s` to the rectangle [min, max], exactly (0 when it
/// crosses it): what [`to_rect`] finds, without its search, for callers that need only the
/// distance (a random painting of thin walls spent 90 % of its build in `to_rect`).
pub fn distance_to_rect(s: &Segment, min: DVec2, max: DVec2) -> f64 {
    let dist = |f: f64| {
        let p = s.p0.lerp(s.p1, f);
        (p.clamp(min, max) - p).length()
    };
    let d = s.p1 - s.p0;
    // Where the line is inside the box (slab clipping): the segment enters it at f0.
    let (mut f0, mut f1) = (0.0f64, 1.0f64);
    for (p, v, lo, hi) in [(s.p0.x, d.x, min.x, max.x), (s.p0.y, d.y, min.y, max.y)] {
        if v == 0.0 {
            if p < lo || p > hi {
                f0 = f64::INFINITY;
            }
        } else {
            let (a, b) = ((lo - p) / v, (hi - p) / v);
            f0 = f0.max(a.min(b));
            f1 = f1.min(a.max(b));
        }
    }
    if f0 <= f1 {
        return 0.0;
    }
    // Apart, the two convex shapes are closest at an end of the segment or at a corner of the
    // box (its point nearest the segment).
    let along = |c: DVec2| nearest_along(s.p0, s.p1, c);
    let corners = [min, DVec2::new(max.x, min.y), DVec2::new(min.x, max.y), max];
    [0.0, 1.0]
        .into_iter()
        .chain(corners.map(along))
        .map(dist)
        .fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

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
    fn walkers_at_one_velocity_keep_their_distance() {
        let a = seg(0.0, 0.0, 0.0, 4.0, 0.0, 4.0);
        let b = seg(0.0, 0.7, 1.0, 4.0, 0.7, 5.0).shifted(-1.0);
        let (d, t) = closest(&a, &b).unwrap();
        assert!((d - 0.7).abs() < 1e-12 && t == 0.0);
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

    /// A segment with coordinates in a 16 m patch and a time span inside [0, 20] s.
    fn any_segment() -> impl Strategy<Value = Segment> {
        (
            0.0f64..16.0,
            0.0f64..16.0,
            0.0f64..10.0,
            0.0f64..16.0,
            0.0f64..16.0,
            0.01f64..10.0,
        )
            .prop_map(|(x0, y0, t0, x1, y1, dt)| seg(x0, y0, t0, x1, y1, t0 + dt))
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]

        /// Who is `a` and who is `b` does not matter: the same distance at the same moment.
        #[test]
        fn closest_approach_is_symmetric(a in any_segment(), b in any_segment()) {
            match (closest(&a, &b), closest(&b, &a)) {
                (Some((d1, t1)), Some((d2, t2))) => {
                    prop_assert!((d1 - d2).abs() < 1e-9, "{} against {}", d1, d2);
                    prop_assert!((t1 - t2).abs() < 1e-9, "{} against {}", t1, t2);
                }
                (x, y) => prop_assert_eq!(x, y),
            }
        }

        /// The closest approach is no farther than the two are at any moment both exist
        /// (sampled), and it is where they are at the time it names.
        #[test]
        fn closest_approach_is_never_larger_than_any_sampled_distance(
            a in any_segment(),
            b in any_segment(),
        ) {
            let (lo, hi) = (a.t0.max(b.t0), a.t1.min(b.t1));
            let Some((d, t)) = closest(&a, &b) else {
                prop_assert!(lo > hi, "they coexist over [{}, {}]", lo, hi);
                return Ok(());
            };
            prop_assert!(t >= lo - 1e-12 && t <= hi + 1e-12, "{} outside [{}, {}]", t, lo, hi);
            prop_assert!((a.at(t).distance(b.at(t)) - d).abs() < 1e-9);
            for k in 0..=200 {
                let s = lo + (hi - lo) * k as f64 / 200.0;
                let sampled = a.at(s).distance(b.at(s));
                prop_assert!(d <= sampled + 1e-9, "{} at {} is closer than {}", sampled, s, d);
            }
        }

        /// A walker standing still is as close to a passer-by as the passer-by's path comes to
        /// it, when the passer-by walks past it while it stands there.
        #[test]
        fn a_stander_is_as_close_as_the_path_comes(a in any_segment(), x in 0.0f64..16.0, y in 0.0f64..16.0) {
            let q = DVec2::new(x, y);
            let (d, _) = closest(&a, &Segment::standing(q, a.t0, a.t1)).unwrap();
            let (along, _, _) = to_rect(&a, q, q);
            prop_assert!((d - along).abs() < 1e-6, "{} against {}", d, along);
        }

        /// The exact distance to a box is the one the search finds.
        #[test]
        fn the_exact_distance_to_a_box_is_the_searched_one(
            a in any_segment(),
            (x, y, w, h) in (0.0f64..16.0, 0.0f64..16.0, 0.0f64..4.0, 0.0f64..4.0),
        ) {
            let (min, max) = (DVec2::new(x, y), DVec2::new(x + w, y + h));
            let (searched, _, _) = to_rect(&a, min, max);
            let exact = distance_to_rect(&a, min, max);
            prop_assert!(exact <= searched + 1e-12 && searched - exact < 1e-9, "{} {}", exact, searched);
        }

        /// The distance to a box is the smallest over the whole walk (sampled), and zero
        /// exactly when the walk enters the box.
        #[test]
        fn distance_to_a_box_is_never_larger_than_any_sampled_distance(
            a in any_segment(),
            (x, y, w, h) in (0.0f64..16.0, 0.0f64..16.0, 0.0f64..4.0, 0.0f64..4.0),
        ) {
            let (min, max) = (DVec2::new(x, y), DVec2::new(x + w, y + h));
            let (d, t, q) = to_rect(&a, min, max);
            prop_assert!(q.cmpge(min).all() && q.cmple(max).all());
            prop_assert!((a.at(t).distance(q) - d).abs() < 1e-6);
            for k in 0..=200 {
                let p = a.p0.lerp(a.p1, k as f64 / 200.0);
                prop_assert!(d <= (p.clamp(min, max) - p).length() + 1e-9);
            }
        }
    }
}
