//! Tests of `library`: hand-made libraries, loaded back from their bytes as an engine
//! loads them, each showing a figure catch its defect.

use super::*;
use crowd_runtime::{Character, Crossing, Patch, Point, Trajectory, World};

/// One walk through a patch: the patch (column), crossings, the next walk, its start
/// (seconds in the period) and points (patch-local metres, seconds from its start).
struct Way {
    patch: u32,
    entry: u32,
    exit: u32,
    next: u32,
    start: f64,
    points: Vec<(f64, f64, f64)>,
}

/// A library of `cols` 8 m patches in a row, 20 s periods, 0.3 m radius, loaded back from
/// its bytes as an engine loads it. `ways` go patch after patch.
fn library(cols: u32, ways: &[Way], standers: &[(f64, f64)]) -> Library {
    let q = |v: f64| (v / 8.0 * 65535.0).round() as u16;
    let ticks = |s: f64| (s / TICK_S).round() as u32;
    let mut lib = Library {
        world: World {
            patch_side_m: 8.0,
            period_ticks: ticks(20.0),
            radius_m: 0.3,
            cols,
            rows: 1,
            seed: 1,
            input_hash: [0; 8],
            turn_rate_deg_s: 360.0,
        },
        patches: Vec::new(),
        standers: standers
            .iter()
            .map(|&(x, y)| Point {
                x: q(x),
                y: q(y),
                t: 0,
            })
            .collect(),
        crossings: Vec::new(),
        trajectories: Vec::new(),
        points: Vec::new(),
        characters: Vec::new(),
    };
    for col in 0..cols {
        let mine: Vec<usize> = (0..ways.len()).filter(|&i| ways[i].patch == col).collect();
        lib.patches.push(Patch {
            col,
            row: 0,
            first_trajectory: mine.first().map_or(0, |&i| i as u32),
            trajectories: mine.len() as u32,
            first_stander: 0,
            standers: if col == 0 { standers.len() as u32 } else { 0 },
        });
    }
    for w in ways {
        lib.trajectories.push(Trajectory {
            patch: w.patch,
            entry: w.entry,
            exit: w.exit,
            next: w.next,
            first_point: lib.points.len() as u32,
            points: w.points.len() as u32,
            start: ticks(w.start),
        });
        let pts = w.points.iter().map(|&(x, y, t)| Point {
            x: q(x),
            y: q(y),
            t: ticks(t),
        });
        lib.points.extend(pts);
    }
    let crossings = ways
        .iter()
        .map(|w| w.entry.max(w.exit) + 1)
        .max()
        .unwrap_or(0);
    lib.crossings = (0..crossings)
        .map(|_| Crossing {
            from_patch: 0,
            to_patch: 0,
            x: 0.0,
            y: 0.0,
            t: 0,
            vx: 0.0,
            vy: 0.0,
        })
        .collect();
    let mut seen = vec![false; ways.len()];
    for first in 0..ways.len() {
        let (mut at, mut n, mut total) = (first, 0, 0u64);
        while !seen[at] {
            seen[at] = true;
            total += u64::from(lib.duration_ticks(&lib.trajectories[at]));
            n += 1;
            at = ways[at].next as usize;
        }
        if n > 0 {
            let laps = (total / u64::from(lib.world.period_ticks)) as u32;
            let c = Character {
                first_trajectory: first as u32,
                trajectories: n,
                laps,
            };
            lib.characters.push(c);
        }
    }
    Library::from_bytes(&lib.to_bytes()).expect("a valid library")
}

/// A loop of one patch, entering and leaving by crossing `c` (its own next).
fn round(i: u32, c: u32, points: Vec<(f64, f64, f64)>) -> Way {
    Way {
        patch: 0,
        entry: c,
        exit: c,
        next: i,
        start: 0.0,
        points,
    }
}

fn figures_of(lib: &Library) -> ProductFigures {
    let inputs = Inputs {
        walls: &[],
        speed_limit_m_s: 1.89,
        sample_step_s: Some(0.02),
    };
    figures(lib, &inputs)
}

/// A square walked at 1.2 m/s from the middle of a side, 24 m in 20 s.
fn square(last: f64) -> Vec<(f64, f64, f64)> {
    vec![
        (4.0, 1.0, 0.0),
        (7.0, 1.0, 2.5),
        (7.0, 7.0, 7.5),
        (1.0, 7.0, 12.5),
        (1.0, 1.0, last),
        (4.0, 1.0, 20.0),
    ]
}

#[test]
fn a_loop_walked_evenly_closes_without_a_jump_and_plays_so() {
    let f = figures_of(&library(1, &[round(0, 0, square(17.5))], &[]));
    assert_eq!(
        (f.collisions, f.open_loops, f.loops, f.walkers),
        (0, 0, 1, 1),
        "{f:?}"
    );
    assert!((f.max_speed_m_s - 1.2).abs() < 1e-3, "{f:?}");
    assert!(
        f.max_seam_velocity_jump < 1e-3 && f.max_seam_gap_m < 1e-9,
        "{f:?}"
    );
    assert!(
        (f.max_key_velocity_jump - 1.2 * 2f64.sqrt()).abs() < 1e-3,
        "{f:?}"
    );
    assert_eq!(f.share_above_limit, 0.0);
    let s = f.sampled.unwrap();
    assert_eq!((s.frames, s.jumps), (1000, 0));
    assert!((s.max_speed_m_s - 1.2).abs() < 1e-2, "{s:?}");
}

#[test]
fn a_loop_hurrying_to_its_seam_jumps_there_and_runs_too_fast() {
    // The last 3 m in 1.5 s: 2 m/s against the first piece's 1.2 m/s.
    let f = figures_of(&library(1, &[round(0, 0, square(18.5))], &[]));
    assert!((f.max_seam_velocity_jump - 0.8).abs() < 1e-3, "{f:?}");
    assert!((f.max_speed_m_s - 2.0).abs() < 1e-3, "{f:?}");
    assert!((f.share_above_limit - 1.5 / 20.0).abs() < 1e-6, "{f:?}");
    assert_eq!(f.sampled.unwrap().jumps, 0);
}

#[test]
fn a_loop_ending_away_from_its_start_is_open() {
    let mut points = square(17.5);
    points[5].1 = 1.5;
    let f = figures_of(&library(1, &[round(0, 0, points)], &[]));
    assert_eq!(f.open_loops, 1, "{f:?}");
    assert!((f.max_seam_gap_m - 0.5).abs() < 1e-3, "{f:?}");
}

#[test]
fn a_turn_at_a_border_is_a_border_jump_and_the_loop_seam_is_told_apart() {
    // A (patch 0) enters by crossing 0 at its east side and leaves by crossing 1; B
    // (patch 1) enters by 1 and leaves by 0: the loop A -> B -> A, its seam B -> A.
    let a = Way {
        patch: 0,
        entry: 0,
        exit: 1,
        next: 1,
        start: 0.0,
        points: vec![(8.0, 2.0, 0.0), (4.0, 3.0, 5.0), (8.0, 4.0, 9.0)],
    };
    let b = Way {
        patch: 1,
        entry: 1,
        exit: 0,
        next: 0,
        start: 9.0,
        points: vec![(0.0, 4.0, 0.0), (4.0, 3.0, 5.0), (0.0, 2.0, 11.0)],
    };
    let f = figures_of(&library(2, &[a, b], &[]));
    let v = |dx: f64, dy: f64, dt: f64| DVec2::new(dx, dy) / dt;
    let border = (v(4.0, -1.0, 5.0) - v(4.0, 1.0, 4.0)).length();
    let seam = (v(-4.0, 1.0, 5.0) - v(-4.0, -1.0, 6.0)).length();
    assert!(
        (f.max_border_velocity_jump.unwrap() - border).abs() < 1e-3,
        "{f:?}"
    );
    assert!((f.max_seam_velocity_jump - seam).abs() < 1e-3, "{f:?}");
    assert!(
        f.max_border_gap_m.unwrap() < 1e-9 && f.open_loops == 0,
        "{f:?}"
    );
    assert_eq!(f.collisions, 0, "{f:?}");
}

#[test]
fn walkers_crossing_at_once_collide_and_so_does_one_walking_into_a_stander() {
    let east = round(
        0,
        0,
        vec![(1.0, 4.0, 0.0), (7.0, 4.0, 10.0), (1.0, 4.0, 20.0)],
    );
    let north = round(
        1,
        1,
        vec![(4.0, 1.0, 0.0), (4.0, 7.0, 10.0), (4.0, 1.0, 20.0)],
    );
    let f = figures_of(&library(1, &[east, north], &[]));
    assert_eq!(f.collisions, 1, "{f:?}");
    assert!((f.min_clearance_m + 0.6).abs() < 1e-3, "{f:?}");
    let east = round(
        0,
        0,
        vec![(1.0, 4.0, 0.0), (7.0, 4.0, 10.0), (1.0, 4.0, 20.0)],
    );
    let f = figures_of(&library(1, &[east], &[(6.0, 4.2)]));
    assert_eq!((f.collisions, f.standers), (1, 1), "{f:?}");
}

/// The sampler's figures do not depend on how its frames were cut into runs: played on 1, 2
/// and 5 threads (1 to 10 runs) they are the same bits, a jump included.
#[test]
fn the_played_frames_give_the_same_figures_on_any_thread_count() {
    // The first loop ends half a metre from its start: a jump at its seam.
    let mut open = square(17.5);
    open[5].1 = 1.5;
    let ways = [
        round(0, 0, open),
        Way {
            start: 3.0,
            ..round(1, 1, square(18.5))
        },
    ];
    let lib = library(1, &ways, &[]);
    let on = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| sample(&lib, 0.02))
    };
    let one = on(1);
    assert!(one.jumps > 0, "{one:?}");
    for threads in [2, 5] {
        assert_eq!(on(threads), one, "{threads} threads");
    }
}

/// A loop of `n` trajectories of 10 s, one a patch along a row, walked left to right at
/// 0.6 m/s through each patch's middle (6 laps of a 20 s period for n = 12), and a walker
/// going round patch 0 on its own. `bend` moves the middle point of trajectory `at` up.
fn long_loop(n: u32, (at, bend): (u32, f64)) -> Library {
    // The walker round patch 0 first: a patch's trajectories are one run of the library's.
    let mut ways = vec![round(0, n, square(17.5))];
    ways.extend((0..n).map(|i| Way {
        patch: i,
        entry: i,
        exit: (i + 1) % n,
        next: 1 + (i + 1) % n,
        start: f64::from(i % 2) * 10.0,
        points: vec![
            (1.0, 4.0, 0.0),
            (4.0, 4.0 + if i == at { bend } else { 0.0 }, 5.0),
            (7.0, 4.0, 10.0),
        ],
    }));
    library(n, &ways, &[])
}

fn memo_of(shares: Vec<([u8; 32], Played)>) -> Recalled {
    let part = memo::LibraryPart {
        pairs: Vec::new(),
        played: shares,
    };
    memo::Memo::from_bytes(&memo::Memo::of(None, Some(part)).to_bytes())
        .expect("a memo reads back")
        .recall()
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(12))]

    /// The sampler's memo: after one trajectory of a loop changes, the walkers whose stretch
    /// of loop does not reach it are not played again, and the figures are the bits of
    /// playing every walker.
    #[test]
    fn a_memo_of_the_played_frames_gives_the_figures_of_playing_all(
        at in 0u32..12,
        bend in 0.05f64..2.5,
    ) {
        let before = long_loop(12, (0, 0.0));
        let first = sampled::sample_memo(&before, 0.02, &Recalled::default()).unwrap();
        proptest::prop_assert_eq!(first.replayed, 7);
        let memo = memo_of(first.kept);
        let again = sampled::sample_memo(&before, 0.02, &memo).unwrap();
        proptest::prop_assert_eq!(again.replayed, 0);
        proptest::prop_assert_eq!(&again.sampled, &first.sampled);

        let after = long_loop(12, (at, bend));
        let played = sampled::sample_memo(&after, 0.02, &memo).unwrap();
        proptest::prop_assert_eq!(&played.sampled, &sample(&after, 0.02));
        // A lap's 20 s (and the trajectory after) are 4 of the 12 trajectories, 2 on from the
        // lap before's: the bent one and the next (whose first headings it may turn) are in
        // at most 3 laps' stretches. The walker round patch 0 is never played again.
        proptest::prop_assert!(
            (1..=3).contains(&played.replayed),
            "{} of 7 walkers played again",
            played.replayed
        );
    }
}

/// A loop longer than the check's budget, played a group of its walkers at a time from the
/// library's file (each group with its stretches of the loop alone, the rest standing in),
/// gives every walker the share, key and figures, it has played among all: whatever the
/// budget, however many laps a group holds.
#[test]
fn a_long_loop_played_a_group_at_a_time_from_its_file_is_the_loop_played_whole() {
    for (n, at, bend) in [(12, 3, 2.0), (40, 17, 1.0), (64, 0, 0.0)] {
        let lib = long_loop(n, (at, bend));
        let whole = sampled::sample_memo(&lib, 0.02, &Recalled::default()).unwrap();
        let bytes = lib.to_bytes();
        for budget in [1, 7, 30, 100] {
            let file = InFile {
                file: crowd_runtime::LibraryFile::open(std::io::Cursor::new(&bytes)).unwrap(),
                budget,
            };
            let parts = sampled::sample_memo(&file, 0.02, &Recalled::default()).unwrap();
            let case = format!("{n} trajectories, bent at {at} by {bend}, budget {budget}");
            assert_eq!(parts.kept, whole.kept, "{case}");
            assert_eq!(parts.sampled, whole.sampled, "{case}");
            assert_eq!(parts.replayed, whole.replayed, "{case}");
        }
    }
}

/// A jump is judged against the walker's own pace: a slow walker's 3 cm jump at its seam is
/// one, though another walker of the library runs at 2 m/s (4 cm a frame).
#[test]
fn a_slow_walker_s_small_jump_is_a_jump_whoever_else_runs() {
    let slow = vec![
        (3.0, 3.0, 0.0),
        (4.5, 3.0, 5.0),
        (4.5, 4.5, 10.0),
        (3.0, 4.5, 15.0),
        (3.0, 3.03, 20.0),
    ];
    let ways = [round(0, 0, slow), round(1, 1, square(18.5))];
    let s = sample(&library(1, &ways, &[]), 0.02);
    assert!((s.max_speed_m_s - 2.0).abs() < 1e-2, "{s:?}");
    assert_eq!(s.jumps, 1, "{s:?}");
}

/// A trajectory's ends read from the points there are its whole path's: the first and last
/// pieces an engine shows, past points repeated at the same time and place (a split point
/// on an entry), and standing for a trajectory that never moves.
#[test]
fn a_trajectory_s_ends_from_its_end_points_are_its_whole_path_s() {
    // The square walked from a split point at its entry to one at its exit.
    let mut repeated = square(17.5);
    repeated.insert(0, repeated[0]);
    repeated.push(repeated[repeated.len() - 1]);
    let standing = vec![(2.0, 2.0, 0.0), (2.0, 2.0, 20.0)];
    let still = vec![(5.0, 5.0, 0.0), (5.0, 5.0, 0.0), (5.0, 5.0, 20.0)];
    let ways = [
        round(0, 0, repeated),
        round(1, 1, square(17.5)),
        round(2, 2, standing),
        round(3, 3, still),
    ];
    let lib = library(1, &ways, &[]);
    let end_of = |i: usize, last| end_of(&lib, i, lib.points_of(&lib.trajectories[i]), last);
    for i in 0..lib.trajectories.len() {
        let p = path(&lib, i);
        let (first, last) = crate::products::end_velocities(&p, TICK_S);
        assert_eq!(
            end_of(i, false),
            (p[0].0, first),
            "trajectory {i}'s first end"
        );
        assert_eq!(
            end_of(i, true),
            (p[p.len() - 1].0, last),
            "trajectory {i}'s last end"
        );
    }
    assert!(
        end_of(0, false).1.length() > 1.0,
        "past the repeated entry, it walks"
    );
    assert_eq!(end_of(3, true).1, DVec2::ZERO, "standing where it entered");
}
