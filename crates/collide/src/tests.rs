//! Stage 5's claims: anchors never move; a converged patch keeps every pair apart.

use super::*;
use crate::repair::{Patch, Speeds, remove_collisions};
use crowd_core::trajectories::{ControlPoint, PointKind, Trajectory};
use glam::DVec2;
use proptest::prelude::*;

fn line(e: DVec2, te: f64, x: DVec2, tx: f64) -> Path {
    path_through(&[(e, te, PointKind::Entry), (x, tx, PointKind::Exit)])
}

fn patch() -> Patch<'static> {
    Patch {
        side_m: 8.0,
        period_s: 20.0,
        radius_m: 0.3,
        obstacles: &[],
        standers: &[],
    }
}

/// Smallest distance between two paths by dense sampling (independent of the analytic code).
fn sampled_distance(a: &Path, b: &Path, period: f64) -> f64 {
    let (a0, a1) = a.span();
    let (b0, b1) = b.span();
    let mut best = f64::INFINITY;
    for k in -3i32..=3 {
        let shift = k as f64 * period;
        let (lo, hi) = (a0.max(b0 + shift), a1.min(b1 + shift));
        let mut t = lo;
        while t <= hi {
            best = best.min(a.position(t).distance(b.position(t - shift)));
            t += 0.005;
        }
    }
    best
}

#[test]
fn two_walkers_head_on_step_aside() {
    let mut paths = vec![
        line(DVec2::new(0.0, 4.0), 1.0, DVec2::new(8.0, 4.0), 7.0),
        line(DVec2::new(8.0, 4.1), 1.0, DVec2::new(0.0, 4.1), 7.0),
    ];
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let out = remove_collisions(&mut paths, &patch(), Speeds::default(), 1000, &mut rng);
    assert!(out.worst.is_none(), "{out:?}");
    assert!(sampled_distance(&paths[0], &paths[1], 20.0) >= 0.6 - 1e-3);
}

fn endpoint(side: u8, s: f64) -> DVec2 {
    match side % 4 {
        0 => DVec2::new(0.0, s),
        1 => DVec2::new(8.0, s),
        2 => DVec2::new(s, 0.0),
        _ => DVec2::new(s, 8.0),
    }
}

fn inward(side: u8) -> DVec2 {
    match side % 4 {
        0 => DVec2::X,
        1 => DVec2::NEG_X,
        2 => DVec2::Y,
        _ => DVec2::NEG_Y,
    }
}

/// A path through `points` (place, time, kind), entry first and exit last.
pub(crate) fn path_through(points: &[(DVec2, f64, PointKind)]) -> Path {
    Path::from_trajectory(&Trajectory {
        entry: 0,
        exit: 0,
        points: points
            .iter()
            .map(|&(pos, t, kind)| ControlPoint { pos, t, kind })
            .collect(),
    })
}

/// Keeps a place out of the border bands of an 8 m patch (as `Patch::keep_inside` does).
fn out_of_bands(p: DVec2) -> DVec2 {
    p.clamp(DVec2::splat(0.31), DVec2::splat(7.69))
}

/// A straight walk with its border bands, as stage 4 draws it: the first and last 0.3 m
/// straight across the border at 1.3 m/s.
fn banded(side_in: u8, s_in: f64, t: f64, side_out: u8, s_out: f64, t_out: f64) -> Path {
    let (e, x) = (endpoint(side_in, s_in), endpoint(side_out, s_out));
    let band = 0.3 / 1.3;
    path_through(&[
        (e, t, PointKind::Entry),
        (e + inward(side_in) * 0.3, t + band, PointKind::Band),
        (x + inward(side_out) * 0.3, t_out - band, PointKind::Band),
        (x, t_out, PointKind::Exit),
    ])
}

/// 1 to 11 banded walkers through an 8 m patch at random (entry side and place and time,
/// exit side and place, 4-12 s in the patch).
fn random_walkers(rng: &mut ChaCha8Rng) -> Vec<Path> {
    use rand::Rng;
    (0..rng.random_range(1..12))
        .map(|_| {
            let (se, s_in, t) = (
                rng.random_range(0u8..4),
                rng.random_range(0.7..7.3),
                rng.random_range(0.0..20.0),
            );
            let (sx, s_out, dt) = (
                rng.random_range(0u8..4),
                rng.random_range(0.7..7.3),
                rng.random_range(4.0..12.0),
            );
            banded(se, s_in, t, sx + 1, s_out, t + dt)
        })
        .collect()
}

/// Boundary points and border bands never move, time never runs backwards, every other point
/// stays out of the bands. The repair converges on at least 40 of 48 random patches in 3,000
/// pushes, and every pair of a converged patch keeps its clearance (by sampling, not by the
/// code under test). An unconverged patch reports the encounter sampling finds, and stalls
/// only where no push can help: both walkers held by their bands (these patches are drawn
/// without stage 3's spacing, so two band pieces may meet; 7 of the 48 do).
#[test]
fn random_patches_converge_and_keep_their_anchors_and_clearance() {
    const PATCHES: usize = 48;
    let mut draw = ChaCha8Rng::seed_from_u64(15);
    let mut converged = 0;
    for case in 0..PATCHES {
        let mut paths = random_walkers(&mut draw);
        let ends = |p: &Path| {
            let t = p.to_trajectory();
            let n = t.points.len();
            [t.points[0], t.points[1], t.points[n - 2], t.points[n - 1]]
        };
        let before: Vec<_> = paths
            .iter()
            .map(|p| (p.entry(), p.exit(), ends(p)))
            .collect();
        let mut rng = ChaCha8Rng::seed_from_u64(case as u64);
        let out = remove_collisions(&mut paths, &patch(), Speeds::default(), 3000, &mut rng);
        for (p, (entry, exit, bands)) in paths.iter().zip(&before) {
            assert_eq!((p.entry(), p.exit(), ends(p)), (*entry, *exit, *bands));
            let t = p.to_trajectory();
            assert!(t.points.windows(2).all(|w| w[1].t >= w[0].t), "case {case}");
            for q in &p.free {
                assert!(q.pos.min_element() >= 0.3 && q.pos.max_element() <= 7.7);
            }
        }
        let sampled = smallest_sampled_distance(&paths, 20.0);
        let Some(w) = out.worst else {
            converged += 1;
            assert!(
                sampled >= 0.6 - 0.01,
                "case {case}: a pair comes {sampled} apart"
            );
            continue;
        };
        // Sampling every 5 ms finds the reported encounter to within 1 cm.
        assert!(
            (sampled - w.distance).abs() < 0.01,
            "case {case}: {w:?}, sampled {sampled}"
        );
        let crate::repair::Other::Walker { b, shift } = w.other else {
            panic!("case {case}: stalled on {w:?} in a patch without standers or walls");
        };
        let held = |p: usize, t: f64| !paths[p].movable_at(t, 0.25);
        assert!(
            held(w.a, w.t) && held(b, w.t - shift),
            "case {case}: stalled on {w:?}, which pushes could reach"
        );
    }
    assert!(
        converged >= 40,
        "only {converged} of {PATCHES} random patches converged"
    );
}

#[test]
fn a_piece_that_cuts_through_an_obstacle_is_sent_round_it() {
    let wall = crowd_core::Rect {
        min: DVec2::new(3.0, 2.0),
        max: DVec2::new(5.0, 6.0),
    };
    let mut path = line(DVec2::new(0.0, 4.0), 0.0, DVec2::new(8.0, 4.0), 10.0);
    path.reroute(&[wall], 0.3, 8.0);
    let t = path.to_trajectory();
    assert!(t.points.len() > 2);
    assert!(t.points.windows(2).all(|w| w[1].t > w[0].t));
    assert_eq!(
        (t.points[0].pos, t.points.last().unwrap().pos),
        (DVec2::new(0.0, 4.0), DVec2::new(8.0, 4.0))
    );
    // Sampled along the whole path, the walker keeps its radius from the wall.
    let mut s = 0.0;
    while s <= 10.0 {
        let p = path.position(s);
        assert!(
            (p.clamp(wall.min, wall.max) - p).length() >= 0.3 - 1e-9,
            "{p} at {s}"
        );
        s += 0.01;
    }
}

#[test]
fn a_pause_that_passes_the_period_is_one_pause() {
    // Stage 4 splits a pause at the period; the split point's position may differ in the last
    // bit from the pause's.
    let spot = DVec2::new(4.0, 4.0);
    let path = path_through(&[
        (DVec2::new(0.0, 4.0), 15.0, PointKind::Entry),
        (spot, 18.0, PointKind::Pause),
        (spot + DVec2::new(1e-15, 0.0), 20.0, PointKind::Split),
        (spot, 26.0, PointKind::Pause),
        (DVec2::new(8.0, 4.0), 29.0, PointKind::Exit),
    ]);
    assert_eq!(path.pause_at(22.0), Some((0, 2)));
    assert_eq!(
        path.pause_at(17.99),
        Some((0, 2)),
        "an end, to within rounding"
    );
    assert_eq!(path.pause_at(16.0), None);
}

#[test]
fn stepping_aside_leaves_two_pauses_and_keeps_time_running_forward() {
    let spot = DVec2::new(4.0, 4.0);
    let mut path = path_through(&[
        (DVec2::new(0.0, 4.0), 0.0, PointKind::Entry),
        (spot, 3.0, PointKind::Pause),
        (spot, 13.0, PointKind::Pause),
        (DVec2::new(8.0, 4.0), 16.0, PointKind::Exit),
    ]);
    assert!(path.split_pause(
        (0, 1),
        10.0,
        DVec2::new(0.0, 0.5),
        1.8,
        out_of_bands,
        |_| true
    ));
    let t = path.to_trajectory();
    assert!(t.points.windows(2).all(|w| w[1].t > w[0].t));
    let pauses: Vec<_> = t
        .points
        .iter()
        .filter(|p| p.kind == PointKind::Pause)
        .collect();
    assert_eq!(pauses.len(), 4);
    assert_eq!((pauses[0].pos, pauses[1].pos), (spot, spot));
    assert_eq!(pauses[2].pos, pauses[3].pos);
    assert_eq!(pauses[3].pos, spot + DVec2::new(0.0, 0.5));
    assert_eq!((pauses[0].t, pauses[3].t), (3.0, 13.0));
    assert!(path.pause_at(12.0).is_some() && path.pause_at(4.0).is_some());
}

#[test]
fn stepping_aside_across_the_period_keeps_the_split_point_on_the_walk() {
    let spot = DVec2::new(4.0, 4.0);
    let mut path = path_through(&[
        (DVec2::new(0.0, 4.0), 6.0, PointKind::Entry),
        (spot, 9.0, PointKind::Pause),
        (spot, 20.0, PointKind::Split),
        (spot, 21.2, PointKind::Pause),
        (DVec2::new(8.0, 4.0), 24.0, PointKind::Exit),
    ]);
    assert!(path.split_pause(
        (0, 2),
        21.1,
        DVec2::new(0.0, 0.5),
        1.8,
        out_of_bands,
        |_| true
    ));
    let t = path.to_trajectory();
    assert!(
        t.points.windows(2).all(|w| w[1].t >= w[0].t),
        "{:?}",
        t.points
    );
    let split = t
        .points
        .iter()
        .find(|p| p.kind == PointKind::Split)
        .unwrap();
    assert!((split.pos - path.position(20.0)).length() < 1e-9);
}

#[test]
fn a_time_move_keeps_the_path_and_the_speed_limit() {
    let mut path = line(DVec2::new(0.0, 4.0), 0.0, DVec2::new(8.0, 4.0), 8.0);
    // Asked to arrive 5 s later at the middle: cut short where the rest would pass 1.8 m/s.
    assert!(path.retime_at(4.0, 5.0, 0.25, 1.8));
    let t = path.to_trajectory();
    assert!(t.points.windows(2).all(|w| w[1].t > w[0].t));
    for w in t.points.windows(2) {
        let v = w[0].pos.distance(w[1].pos) / (w[1].t - w[0].t);
        assert!(v <= 1.8 + 1e-9, "{v}");
    }
    let middle = t.points.iter().find(|p| p.kind == PointKind::Bend).unwrap();
    assert_eq!(middle.pos, DVec2::new(4.0, 4.0));
    assert!(middle.t > 4.0);
}

/// Eight walkers asked to cross the centre of the patch at the same moment from every side.
fn crossroads() -> Vec<Path> {
    (0..8u8)
        .map(|k| {
            let s = if k < 4 { 3.2 } else { 4.8 };
            banded(k % 4, s, 1.0 + 0.05 * k as f64, (k % 4) ^ 1, 8.0 - s, 7.0)
        })
        .collect()
}

#[test]
fn the_repair_clears_a_crossroads_where_everyone_meets_at_once_at_walking_pace() {
    let mut paths = crossroads();
    let before: Vec<_> = paths.iter().map(|p| (p.entry(), p.exit())).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    assert!(
        remove_collisions(&mut paths, &patch(), Speeds::default(), 0, &mut rng)
            .worst
            .is_some(),
        "the straight lines collide"
    );
    let speeds = Speeds::default();
    let out = crate::with_restarts(&mut paths, &patch(), speeds, 12_000, &mut rng);
    assert!(out.worst.is_none(), "{out:?}");
    for p in &paths {
        for s in p.segments() {
            let v = s.velocity().length();
            assert!(v <= speeds.bend_limit() + 1e-9, "{v} m/s");
        }
    }
    for (p, (entry, exit)) in paths.iter().zip(&before) {
        assert_eq!((p.entry(), p.exit()), (*entry, *exit));
        let t = p.to_trajectory();
        assert!(
            t.points.windows(2).all(|w| w[1].t > w[0].t),
            "{:?}",
            t.points
        );
        assert!(
            p.free
                .iter()
                .all(|q| q.pos.min_element() >= 0.3 && q.pos.max_element() <= 7.7)
        );
    }
    for i in 0..paths.len() {
        for j in i + 1..paths.len() {
            let d = sampled_distance(&paths[i], &paths[j], 20.0);
            assert!(d >= 0.6 - 0.01, "walkers {i} and {j} come {d} apart");
        }
    }
}

#[test]
fn a_planned_way_round_a_pausing_walker_keeps_its_split_point_at_the_period() {
    // Walker 0 crosses the period (t = 20) on its way east; walker 1 pauses right on its line.
    let mut paths = vec![
        banded(0, 4.0, 16.0, 1, 4.0, 24.0),
        path_through(&[
            (DVec2::new(4.0, 0.0), 14.0, PointKind::Entry),
            (DVec2::new(4.0, 0.3), 14.25, PointKind::Band),
            (DVec2::new(4.0, 4.0), 17.0, PointKind::Pause),
            (DVec2::new(4.0, 4.0), 23.0, PointKind::Pause),
            (DVec2::new(4.0, 7.7), 25.75, PointKind::Band),
            (DVec2::new(4.0, 8.0), 26.0, PointKind::Exit),
        ]),
    ];
    let way = crate::replan::plan(&paths, 0, &patch(), crate::replan::STRICT, 1.8).expect("a way");
    paths[0].free = way;
    assert!(sampled_distance(&paths[0], &paths[1], 20.0) >= 0.6);
    let t = paths[0].to_trajectory();
    let splits: Vec<_> = t
        .points
        .iter()
        .filter(|p| p.kind == PointKind::Split)
        .collect();
    assert_eq!(splits.len(), 1);
    assert_eq!(splits[0].t, 20.0);
    assert!(t.points.windows(2).all(|w| w[1].t > w[0].t));
}

/// Each pair's closest distance in a patch's rows, by pair.
fn distances(rows: &[Vec<repair::Encounter>]) -> Vec<((usize, String), f64)> {
    let mut out: Vec<_> = rows
        .iter()
        .flatten()
        .map(|e| ((e.a, format!("{:?}", e.other)), e.distance))
        .collect();
    out.sort_by(|x, y| x.0.cmp(&y.0));
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Refreshing the rows after some walkers moved (only the changed spans measured again,
    /// and of those only the walkers the index places near) gives the rows a fresh
    /// measurement of every pair gives.
    #[test]
    fn refreshed_rows_equal_rows_measured_anew(
        walkers in proptest::collection::vec((0u8..4, 0.7f64..7.3, 0.0f64..20.0, 0u8..4, 0.7f64..7.3, 4.0f64..12.0), 4..16),
        moves in proptest::collection::vec((0usize..16, 0.0f64..1.0, -2.0f64..2.0, -2.0f64..2.0), 1..12),
    ) {
        let patch = patch();
        let mut paths: Vec<Path> = walkers
            .iter()
            .map(|&(se, s_in, t, sx, s_out, dt)| banded(se, s_in, t, sx + 1, s_out, t + dt))
            .collect();
        let mut tracks =
            repair::Tracks::indexed(paths.iter().map(Path::segments).collect(), &patch);
        let mut rows = repair::rows(&tracks, &patch);
        for (w, when, dx, dy) in moves {
            let p = w % paths.len();
            let (t0, t1) = paths[p].span();
            let t = t0 + (t1 - t0) * when;
            paths[p].push_at(t, DVec2::new(dx, dy), 0.25, 1.8, out_of_bands, |_| true);
            tracks.set(p, paths[p].segments());
            repair::refresh(&mut rows, &mut tracks, &[p], &patch);
            let every_pair = repair::Tracks::new(paths.iter().map(Path::segments).collect());
            let fresh = repair::rows(&every_pair, &patch);
            let (got, want) = (distances(&rows), distances(&fresh));
            prop_assert_eq!(got.len(), want.len());
            for (g, w) in got.iter().zip(&want) {
                prop_assert_eq!(&g.0, &w.0);
                prop_assert!((g.1 - w.1).abs() < 1e-12, "{:?} against {:?}", g, w);
            }
        }
    }
}

/// Smallest distance between every pair of walkers (and each walker and its own copies whole
/// periods away), sampled every 5 ms over all their pieces, bands and ghosts included:
/// independent of the analytic code under test.
fn smallest_sampled_distance(paths: &[Path], period: f64) -> f64 {
    let segs: Vec<Vec<crowd_geometry::Segment>> = paths.iter().map(Path::segments).collect();
    let at = |s: &[crowd_geometry::Segment], t: f64| crowd_geometry::at_time(s, t).expect("pieces");
    let mut best = f64::INFINITY;
    for i in 0..segs.len() {
        for j in i..segs.len() {
            let (a, b) = (&segs[i], &segs[j]);
            let (a0, a1) = (a[0].t0, a[a.len() - 1].t1);
            let (b0, b1) = (b[0].t0, b[b.len() - 1].t1);
            for k in -4i32..=4 {
                if i == j && k == 0 {
                    continue;
                }
                let shift = k as f64 * period;
                let (lo, hi) = (a0.max(b0 + shift), a1.min(b1 + shift));
                let mut t = lo;
                while t <= hi {
                    best = best.min(at(a, t).distance(at(b, t - shift)));
                    t += 0.005;
                }
            }
        }
    }
    best
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Ramirez's Figure 6 patches (16 m, period 10 s, 1 to 50 pairs at random under stage 3's
    /// spacing rule, matched by stage 4): every one converges within stage 5's default budget
    /// and tries (walking pace, a walker given a period more, hurrying: `clear_patch`),
    /// and then every pair keeps its clearance (by sampling). No walk has a corner where it
    /// passes the period (a player's loop seam): every split point lies on the straight walk
    /// between the points either side, which keep their order in time.
    #[test]
    fn a_random_patch_always_converges(pairs in 1usize..=50, seed in any::<u64>()) {
        let shape = crowd_match::random::Shape { side_m: 16.0, period_s: 10.0, radius_m: 0.3 };
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut paths: Vec<Path> = crowd_match::random::walkers(pairs, shape, &mut rng)
            .iter()
            .map(Path::from_trajectory)
            .collect();
        let patch = Patch {
            side_m: 16.0,
            period_s: 10.0,
            radius_m: 0.3,
            obstacles: &[],
            standers: &[],
        };
        let (cleared, out, _) =
            crate::clear_patch(paths, &patch, Speeds::default(), (10.0, 12_000), &mut rng);
        paths = cleared;
        prop_assert!(out.worst.is_none(), "{} pairs: {:?}", pairs, out);
        let d = smallest_sampled_distance(&paths, 10.0);
        prop_assert!(d >= 0.6 - 0.01, "{} pairs come {} apart", pairs, d);
        for path in &paths {
            let points = path.to_trajectory().points;
            prop_assert!(points.windows(2).all(|w| w[1].t >= w[0].t));
            for w in points.windows(3).filter(|w| w[1].kind == PointKind::Split) {
                let (a, b, c) = (w[0], w[1], w[2]);
                let on = if c.t > a.t { a.pos.lerp(c.pos, (b.t - a.t) / (c.t - a.t)) } else { a.pos };
                prop_assert!(on.distance(b.pos) < 1e-9, "a corner at the period: {:?}", w);
            }
        }
    }
}

/// A pipeline with `extra` settings (RON fields) besides a scene's.
fn pipeline(extra: &str) -> crowd_core::config::PipelineFile {
    let text = format!(
        "(scene: (meters_per_pixel: 1.0, layers: [(kind: Density, path: \"d.png\")]), \
         walkers: 10, standers: 0, patch_side_m: 8.0, period_s: 20.0, radius_m: 0.3, seed: 1, \
         output: \"out\", {extra})"
    );
    crowd_core::config::PipelineFile::parse(std::path::Path::new("p.ron"), text).unwrap()
}

/// Two walkers at 1.7 m/s between their bands, one eastward, one northward, who reach the
/// centre of the patch at the same moment.
fn perpendicular_at_1_7() -> Vec<Path> {
    let t_out = 7.4 / 1.7 + 2.0 * 0.3 / 1.3;
    vec![
        banded(0, 4.0, 0.0, 1, 4.0, t_out),
        banded(2, 4.0, 0.0, 3, 4.0, t_out),
    ]
}

/// The fastest piece of a path, m/s.
fn fastest(p: &Path) -> f64 {
    p.segments()
        .iter()
        .map(|s| s.velocity().length())
        .fold(0.0, f64::max)
}

#[test]
fn a_time_move_may_walk_as_fast_as_the_pipelines_max_speed_and_no_faster() {
    for (extra, max) in [("", 1.8), ("match: (max_speed: 2.0)", 2.0)] {
        let speeds = crate::inputs(&pipeline(extra)).speeds;
        assert_eq!(speeds.max, max);
        let mut paths = perpendicular_at_1_7();
        let tracks = repair::Tracks::new(paths.iter().map(Path::segments).collect());
        let e = repair::rows(&tracks, &patch())
            .into_iter()
            .flatten()
            .min_by(|x, y| x.margin.total_cmp(&y.margin))
            .expect("they meet");
        let b = 1 - e.a;
        // Reaching the centre 0.65 m's walk earlier or later needs 2.1 m/s: the move is cut
        // short at the limit, and the walker that moved walks that fast.
        let before: Vec<f64> = paths.iter().map(fastest).collect();
        let moved = crate::push::time_move(
            &mut paths,
            &tracks,
            &patch(),
            &e,
            (b, e.t),
            0.65,
            speeds.max,
        )
        .expect("passing earlier or later leaves them farther apart");
        assert!(before[moved] < 1.8);
        let v = fastest(&paths[moved]);
        assert!(
            (v - max).abs() < 1e-9,
            "max_speed {max}: the walker walks at {v} m/s"
        );
    }
}

#[test]
fn stage_5_reads_its_speeds_and_margin_from_the_pipeline_and_hashes_them() {
    let default = crate::inputs(&pipeline(""));
    assert_eq!((default.speeds.comfort, default.speeds.max), (1.33, 1.8));
    assert!((default.speeds.bend_limit() - 1.8 * 1.03).abs() < 1e-12);
    let faster = crate::inputs(&pipeline("match: (comfort_speed: 1.4, max_speed: 2.0)"));
    assert_eq!((faster.speeds.comfort, faster.speeds.max), (1.4, 2.0));
    // Export's error is kept beyond every radius: 0.75 mm dropped keyframes, 0.06 mm rounding
    // of an 8 m patch, 0.25 mm of time rounding at 5 m/s.
    assert!(
        (default.margin_m - 0.00106).abs() < 1e-5,
        "{}",
        default.margin_m
    );
    let coarser = crate::inputs(&pipeline("export: (simplify_mm: 2.0)"));
    assert!(coarser.margin_m > default.margin_m + 1e-3);
    let (g, t) = (crowd_core::Hash::of(b"g"), crowd_core::Hash::of(b"t"));
    let hash = |i: &crate::Inputs| input_hash(&g, &t, i);
    let only_max = crate::inputs(&pipeline("match: (max_speed: 2.0)"));
    let all = [&default, &faster, &only_max, &coarser].map(hash);
    for (i, a) in all.iter().enumerate() {
        for b in &all[i + 1..] {
            assert_ne!(a, b);
        }
    }
}

#[test]
fn a_bend_too_fast_for_its_time_takes_time_from_the_rest_of_the_walk() {
    // Straight east at 1 m/s, then pushed 1.5 m north at t = 2: the pieces to and from the
    // bend would be walked at 1.8 m/s each. The walk has time to spare (9.6 m in 8 s).
    let mut path = path_through(&[
        (DVec2::new(0.0, 4.0), 0.0, PointKind::Entry),
        (DVec2::new(1.0, 5.5), 1.0, PointKind::Bend),
        (DVec2::new(2.0, 4.0), 2.0, PointKind::Bend),
        (DVec2::new(3.0, 4.0), 3.0, PointKind::Split),
        (DVec2::new(8.0, 4.0), 8.0, PointKind::Exit),
    ]);
    assert!(path.limit_speed(1.3));
    let t = path.to_trajectory();
    let (first, last) = (t.points[0], t.points[t.points.len() - 1]);
    assert_eq!((first.t, last.t), (0.0, 8.0), "the ends keep their times");
    for w in t.points.windows(2) {
        let v = w[0].pos.distance(w[1].pos) / (w[1].t - w[0].t);
        assert!(v <= 1.3 + 1e-9, "{v} m/s in {w:?}");
    }
    let split = t
        .points
        .iter()
        .find(|p| p.kind == PointKind::Split)
        .unwrap();
    assert_eq!(split.t, 3.0, "the period stays where it was");
    assert!(
        (split.pos - path.position(3.0)).length() < 1e-9,
        "on the walk"
    );
    // Too long for its time: one speed, the least there is.
    let mut rush = path_through(&[
        (DVec2::new(0.0, 4.0), 0.0, PointKind::Entry),
        (DVec2::new(4.0, 7.0), 1.0, PointKind::Bend),
        (DVec2::new(8.0, 4.0), 4.0, PointKind::Exit),
    ]);
    assert!(!rush.limit_speed(1.2));
    let t = rush.to_trajectory();
    let v: Vec<f64> = t
        .points
        .windows(2)
        .map(|w| w[0].pos.distance(w[1].pos) / (w[1].t - w[0].t))
        .collect();
    assert!(
        (v[0] - v[1]).abs() < 1e-3 && (v[0] - 10.0 / 4.0).abs() < 0.01,
        "{v:?}"
    );
}

#[test]
fn a_walker_given_one_more_period_keeps_its_ends_modulo_the_period() {
    let mut path = banded(0, 3.0, 18.0, 1, 5.0, 23.0);
    let before = path.to_trajectory();
    assert!(path.add_period(20.0));
    let after = path.to_trajectory();
    let (b0, b1) = (before.points[0], before.points[before.points.len() - 1]);
    let (a0, a1) = (after.points[0], after.points[after.points.len() - 1]);
    assert_eq!((a0.pos, a0.t), (b0.pos, b0.t), "the entry stays");
    assert_eq!(
        (a1.pos, a1.t),
        (b1.pos, b1.t + 20.0),
        "the exit a period later"
    );
    let splits: Vec<f64> = after
        .points
        .iter()
        .filter(|p| p.kind == PointKind::Split)
        .map(|p| p.t)
        .collect();
    assert_eq!(splits, [20.0, 40.0], "a split at every multiple passed");
    assert!(after.points.windows(2).all(|w| w[1].t >= w[0].t));
    // The band pieces are the same walks, the exit's a period later.
    let n = after.points.len();
    let m = before.points.len();
    assert_eq!(after.points[n - 2].pos, before.points[m - 2].pos);
}

/// A rescue that brings nothing better gives up after [`replan::RESCUE_PATIENCE`] rounds, not
/// all [`RESCUE_ROUNDS`]: two walkers that enter at the same place at the same moment (anchors
/// no push or plan can move) stay as close, whatever is planned.
#[test]
fn a_rescue_that_brings_nothing_better_gives_up_early() {
    let mut paths = vec![
        banded(0, 4.0, 1.0, 1, 2.0, 8.0),
        banded(0, 4.0, 1.0, 1, 6.0, 8.0),
    ];
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let pushes = 20;
    let speeds = Speeds::default();
    let out = replan::rescue(
        &mut paths,
        &patch(),
        speeds,
        RESCUE_ROUNDS,
        pushes,
        &mut rng,
    );
    assert!(out.worst.is_some_and(|w| w.margin < -0.5), "{out:?}");
    // Each round plans one walker and pushes `pushes` times at most.
    let most = replan::RESCUE_PATIENCE * (pushes + 1);
    assert!(out.iterations <= most, "{} > {most}", out.iterations);
}
