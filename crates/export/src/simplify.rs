//! Fewer keyframes for engines: stage 6 resamples its curves densely (a keyframe every 0.2 s
//! or so), far more than an engine needs to place a character within a millimetre. Every
//! keyframe the runtime plays is a step onto a new piece, and half of a frame's cost.
//!
//! A trajectory is piecewise linear in space-time, so the kept keyframes' walk differs from
//! stage 6's by an amount that is linear in time between any two of stage 6's keyframes: its
//! largest is at one of them. Checking the dropped keyframes therefore bounds the difference at
//! every time, not only at the keyframes.

use crowd_core::trajectories::{ControlPoint, PatchMotion, PointKind, Trajectory};
use rayon::prelude::*;

/// Longest run of keyframes one piece may replace: keeps the greedy search linear in the
/// keyframes, whatever the trajectory (a long pause is many keyframes at one place).
const MAX_RUN: usize = 256;

/// Every trajectory of `motion` with the keyframes that the walk between its neighbours passes
/// within `tolerance_m` of dropped. Entry, exit and period-split keyframes are always kept.
/// Patch by patch in parallel: each is its own, so the result is the same for any number of
/// threads. Takes the motion: each patch's dense keyframes are freed as it is done (held with
/// the kept ones, the million's were 6 GB of the export's peak).
pub fn motion(motion: Vec<PatchMotion>, tolerance_m: f64) -> Vec<PatchMotion> {
    motion
        .into_par_iter()
        .map(|m| patch(m, tolerance_m))
        .collect()
}

/// One patch of [`motion`]. Each trajectory's keyframes are found in one buffer and copied out
/// at their number: grown a keyframe at a time, the kept vectors' reallocations were a third of
/// a brush stroke's thinning.
pub fn patch(m: PatchMotion, tolerance_m: f64) -> PatchMotion {
    let mut kept = Vec::new();
    PatchMotion {
        standers: m.standers,
        trajectories: m
            .trajectories
            .into_iter()
            .map(|tr| {
                keyframes_into(&tr.points, tolerance_m, &mut kept);
                Trajectory {
                    entry: tr.entry,
                    exit: tr.exit,
                    points: kept.clone(),
                }
            })
            .collect(),
    }
}

/// The keyframes of `points` to keep: greedily, each piece runs from the last kept keyframe as
/// far as every keyframe it passes over stays within `tolerance_m` of it.
pub fn keyframes(points: &[ControlPoint], tolerance_m: f64) -> Vec<ControlPoint> {
    let mut kept = Vec::new();
    keyframes_into(points, tolerance_m, &mut kept);
    kept
}

/// [`keyframes`] into `kept`, emptied first.
fn keyframes_into(points: &[ControlPoint], tolerance_m: f64, kept: &mut Vec<ControlPoint>) {
    kept.clear();
    let Some(&first) = points.first() else {
        return;
    };
    kept.push(first);
    let mut a = 0;
    while a + 1 < points.len() {
        let mut b = a + 1;
        while b + 1 < points.len()
            && b - a < MAX_RUN
            && !fixed(points, b)
            && spans(points, a, b + 1, tolerance_m)
        {
            b += 1;
        }
        kept.push(points[b]);
        a = b;
    }
}

/// Keyframes no export drops: where the patterns fix a character, where a trajectory passes a
/// whole period, and either side of that. There a character hands over from one `world.glb` node
/// to the next: the pieces either side are stage 6's own (a velocity change of at most 0.1 m/s
/// on a curve), not a longer piece whose velocity differs from its neighbour's by up to
/// sqrt(8 x tolerance x acceleration) (0.3 m/s, as pieces through a corner of 10 m/s2 do).
fn fixed(points: &[ControlPoint], k: usize) -> bool {
    let kind = |k: usize| points.get(k).map(|p| p.kind);
    let fixed = |kind| {
        matches!(
            kind,
            Some(PointKind::Entry | PointKind::Exit | PointKind::Split)
        )
    };
    // A neighbour a few milliseconds from the split is no piece to keep: rounded to glTF's f32
    // times or the library's ticks, its velocity is anything.
    let far = |j: usize| (points[j].t - points[k].t).abs() >= MIN_SEAM_PIECE_S;
    fixed(kind(k))
        || (kind(k + 1) == Some(PointKind::Split) && far(k + 1))
        || (k > 0 && kind(k - 1) == Some(PointKind::Split) && far(k - 1))
}

/// The shortest piece either side of a period split kept for its own sake, s.
const MIN_SEAM_PIECE_S: f64 = 5e-3;

/// Whether the straight walk from keyframe `a` to keyframe `b` passes every keyframe between
/// them within `tolerance_m`, at its time.
fn spans(points: &[ControlPoint], a: usize, b: usize, tolerance_m: f64) -> bool {
    let (pa, pb) = (points[a], points[b]);
    let dt = pb.t - pa.t;
    points[a + 1..b].iter().all(|p| {
        let s = if dt > 0.0 { (p.t - pa.t) / dt } else { 0.0 };
        pa.pos.lerp(pb.pos, s).distance(p.pos) <= tolerance_m
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec2;
    use proptest::prelude::*;

    fn point(x: f64, y: f64, t: f64, kind: PointKind) -> ControlPoint {
        ControlPoint {
            pos: DVec2::new(x, y),
            t,
            kind,
        }
    }

    /// Where the walk through `points` is at time `t` (inside their span).
    fn at(points: &[ControlPoint], t: f64) -> DVec2 {
        let k = points
            .partition_point(|p| p.t <= t)
            .clamp(1, points.len() - 1);
        let (a, b) = (points[k - 1], points[k]);
        let s = if b.t > a.t {
            (t - a.t) / (b.t - a.t)
        } else {
            1.0
        };
        a.pos.lerp(b.pos, s.clamp(0.0, 1.0))
    }

    fn walk() -> impl Strategy<Value = Vec<ControlPoint>> {
        prop::collection::vec((-0.01f64..0.01, -0.01f64..0.01, 0.0f64..0.3, 0u8..8), 2..80)
            .prop_map(|steps| {
                let (mut pos, mut t) = (DVec2::ZERO, 0.0);
                let n = steps.len();
                steps
                    .into_iter()
                    .enumerate()
                    .map(|(i, (dx, dy, dt, k))| {
                        pos += DVec2::new(0.01 + dx, dy);
                        t += dt;
                        let kind = match (i, k) {
                            (0, _) => PointKind::Entry,
                            (i, _) if i + 1 == n => PointKind::Exit,
                            (_, 0) => PointKind::Split,
                            _ => PointKind::Sample,
                        };
                        point(pos.x, pos.y, t, kind)
                    })
                    .collect()
            })
    }

    proptest! {
        #[test]
        fn the_kept_walk_stays_within_the_tolerance_at_every_time(points in walk()) {
            let kept = keyframes(&points, 7.5e-4);
            let (t0, t1) = (points[0].t, points[points.len() - 1].t);
            for i in 0..=500 {
                let t = t0 + (t1 - t0) * f64::from(i) / 500.0;
                let d = at(&kept, t).distance(at(&points, t));
                prop_assert!(d <= 7.5e-4 + 1e-12, "{t}: {d}");
            }
        }

        #[test]
        fn entries_exits_and_period_splits_with_their_neighbours_are_kept_and_nothing_is_invented(
            points in walk()
        ) {
            let kept = keyframes(&points, 7.5e-4);
            let split = |j: usize, k: usize| {
                points.get(j).is_some_and(|p| {
                    p.kind == PointKind::Split && (p.t - points[k].t).abs() >= MIN_SEAM_PIECE_S
                })
            };
            let fixed: Vec<_> = points
                .iter()
                .enumerate()
                .filter(|&(k, p)| {
                    matches!(p.kind, PointKind::Entry | PointKind::Exit)
                        || p.kind == PointKind::Split
                        || split(k + 1, k)
                        || (k > 0 && split(k - 1, k))
                })
                .map(|(_, p)| p)
                .collect();
            prop_assert!(fixed.iter().all(|p| kept.contains(p)));
            prop_assert!(kept.iter().all(|p| points.contains(p)));
            prop_assert!(kept.windows(2).all(|w| w[0].t <= w[1].t));
        }
    }

    #[test]
    fn a_straight_steady_walk_keeps_its_ends_and_a_pause_its_corners() {
        let straight: Vec<_> = (0..50)
            .map(|i| {
                point(
                    f64::from(i) * 0.2,
                    0.0,
                    f64::from(i) * 0.15,
                    PointKind::Sample,
                )
            })
            .collect();
        assert_eq!(keyframes(&straight, 1e-4), vec![straight[0], straight[49]]);
        // Walk, stand 3 s, walk on: the stop and the restart are corners in space-time.
        let pause = [
            point(0.0, 0.0, 0.0, PointKind::Entry),
            point(1.0, 0.0, 1.0, PointKind::Sample),
            point(2.0, 0.0, 2.0, PointKind::Pause),
            point(2.0, 0.0, 3.5, PointKind::Sample),
            point(2.0, 0.0, 5.0, PointKind::Pause),
            point(3.0, 0.0, 6.0, PointKind::Exit),
        ];
        let kept = keyframes(&pause, 1e-3);
        assert_eq!(kept, vec![pause[0], pause[2], pause[4], pause[5]]);
    }

    #[test]
    fn no_tolerance_keeps_every_keyframe_off_a_straight_steady_line() {
        let bent: Vec<_> = (0..20)
            .map(|i| {
                let a = f64::from(i) * 0.1;
                point(a.cos(), a.sin(), a, PointKind::Sample)
            })
            .collect();
        assert_eq!(keyframes(&bent, 0.0), bent);
    }
}
