//! Stage 2 against its claims: densities poured under rho_max add up to the requested counts,
//! open intervals are the runs free on both sides, components and obstacles as painted.

use super::*;
use crowd_core::Grid;
use crowd_core::patch_graph::{BorderAxis, Cell, Interval};
use glam::Vec2;
use proptest::prelude::*;

/// Maps of `w x h` pixels at 1 m per pixel, uniformly painted, with `blocked` pixels.
fn maps(w: u32, h: u32, blocked: impl Fn(u32, u32) -> bool) -> MergedMaps {
    let mut m = MergedMaps::empty(w, h, 1.0);
    m.walkers = Grid::filled(w, h, 1.0);
    for y in 0..h {
        for x in 0..w {
            if blocked(x, y) {
                m.blocked.as_mut_slice()[(y * w + x) as usize] = true;
                m.walkers.as_mut_slice()[(y * w + x) as usize] = 0.0;
            }
        }
    }
    m
}

fn inputs(walkers: u64) -> GraphInputs {
    GraphInputs::counted(walkers, 4.0)
}

fn build(m: &MergedMaps, walkers: u64) -> PatchGraph {
    build_graph(m, &inputs(walkers), Hash::of(b"test"), &()).unwrap()
}

#[test]
fn requested_densities_add_up_to_the_requested_walkers() {
    let mut m = maps(16, 8, |_, _| false);
    for (i, v) in m.walkers.as_mut_slice().iter_mut().enumerate() {
        *v = (i % 7) as f32 / 6.0;
    }
    let g = build(&m, 34);
    let total: f64 = g
        .patches
        .iter()
        .map(|p| p.walker_density * g.patch_area())
        .sum();
    assert!((total - 34.0).abs() < 1e-9, "{total}");
}

#[test]
fn no_patch_is_asked_for_more_than_rho_max_and_the_overflow_goes_elsewhere() {
    // The west half painted four times brighter: linear scaling would ask 0.56 per m2 there.
    let mut m = maps(16, 8, |_, _| false);
    for (i, v) in m.walkers.as_mut_slice().iter_mut().enumerate() {
        *v = if i % 16 < 8 { 1.0 } else { 0.25 };
    }
    let g = build(&m, 40);
    let total: f64 = g.patches.iter().map(|p| p.walker_density).sum::<f64>() * g.patch_area();
    assert!((total - 40.0).abs() < 1e-9, "{total}");
    for p in &g.patches {
        let expected = if p.cell.col < 2 {
            0.35
        } else {
            40.0 / 64.0 - 0.35
        };
        assert!((p.walker_density - expected).abs() < 1e-9, "{p:?}");
    }
}

#[test]
fn more_walkers_than_rho_max_allows_is_refused_with_the_capacity() {
    let err =
        build_graph(&maps(16, 8, |_, _| false), &inputs(50), Hash::of(b"t"), &()).unwrap_err();
    assert_eq!(err.field(), "walkers");
    let text = err.to_string();
    assert!(text.contains("at most 44 fit"), "{text}");
    assert!(text.contains("8 patches"), "{text}");
}

#[test]
fn patches_are_numbered_from_the_south_west_corner() {
    // Block the north-east 4 x 4 pixels: image rows 0..4 are the north edge.
    let g = build(&maps(8, 8, |x, y| x >= 4 && y < 4), 10);
    let cells: Vec<_> = g.patches.iter().map(|p| (p.cell.col, p.cell.row)).collect();
    assert_eq!(cells, vec![(0, 0), (1, 0), (0, 1)]);
    assert_eq!(g.dropped.blocked, vec![Cell { col: 1, row: 1 }]);
}

#[test]
fn an_obstacle_closes_part_of_a_border() {
    // A wall 2 px thick across the vertical border x = 4, over the 2 southmost pixels.
    let g = build(&maps(8, 4, |x, y| (3..5).contains(&x) && y >= 2), 10);
    assert_eq!(g.borders.len(), 1);
    let b = &g.borders[0];
    assert_eq!(b.axis, BorderAxis::Vertical);
    assert_eq!(
        b.open,
        vec![Interval {
            start: 2.0,
            end: 4.0
        }]
    );
    // The wall stays inside both patches as static obstacles.
    assert_eq!(g.patches[0].obstacles.len(), 1);
    assert_eq!(g.patches[0].obstacles[0].min, DVec2::new(3.0, 0.0));
    assert_eq!(g.patches[0].obstacles[0].max, DVec2::new(4.0, 2.0));
}

#[test]
fn a_wall_across_a_patch_closes_the_border_of_the_part_it_cuts_off() {
    // A one-pixel wall across the south-west patch from its west to its east edge, one metre
    // above its south edge: the strip below it opens only east (1 m), the part above east
    // (2 m) and north (4 m). The strip's opening closes, so no walker can come in below the
    // wall and leave above it.
    let g = build(&maps(8, 8, |x, y| x < 4 && y == 6), 10);
    let east = g
        .borders
        .iter()
        .find(|b| b.a.0 == 0 && b.axis == BorderAxis::Vertical)
        .unwrap();
    assert_eq!(
        east.open,
        vec![Interval {
            start: 2.0,
            end: 4.0
        }]
    );
}

#[test]
fn an_opening_narrower_than_a_character_is_closed() {
    // The border x = 4 is walled but for one 0.5 m pixel: too narrow for a 0.6 m character.
    let mut m = maps(16, 8, |x, y| (7..9).contains(&x) && y != 3);
    m.meters_per_pixel = 0.5;
    let mut i = inputs(10);
    i.patch_side_m = 4.0;
    let g = build_graph(&m, &i, Hash::of(b"t"), &()).unwrap();
    assert!(g.borders[0].open.is_empty());
    assert_eq!(g.components.len(), 2, "a closed border splits the graph");
}

#[test]
fn unpainted_patches_are_dropped_and_split_components() {
    let mut m = maps(12, 4, |_, _| false);
    for y in 0..4 {
        for x in 4..8 {
            m.walkers.as_mut_slice()[(y * 12 + x) as usize] = 0.0;
        }
    }
    let g = build(&m, 10);
    assert_eq!(g.patches.len(), 2);
    assert_eq!(g.dropped.empty, vec![Cell { col: 1, row: 0 }]);
    assert_eq!(g.components.len(), 2);
    assert!(g.borders.is_empty(), "dropped patches share no border");
}

#[test]
fn zero_walkers_with_painted_density_is_refused() {
    let err = build_graph(&maps(8, 8, |_, _| false), &inputs(0), Hash::of(b"t"), &()).unwrap_err();
    assert_eq!(err, GraphProblem::ZeroWalkers { pixels: 64 });
}

#[test]
fn a_fully_blocked_scene_has_no_walkable_patch() {
    let err = build_graph(&maps(8, 8, |_, _| true), &inputs(5), Hash::of(b"t"), &()).unwrap_err();
    assert!(
        matches!(err, GraphProblem::NoWalkablePatch { blocked: 4, .. }),
        "{err}"
    );
}

#[test]
fn directions_are_requested_only_where_weighted_enough() {
    let mut m = maps(8, 4, |_, _| false);
    for y in 0..4 {
        for x in 0..8 {
            let i = (y * 8 + x) as usize;
            m.flow.as_mut_slice()[i] = Vec2::new(0.0, 1.0);
            m.flow_weight.as_mut_slice()[i] = if x < 4 { 1.0 } else { 0.1 };
        }
    }
    let g = build(&m, 10);
    let d = g.patches[0]
        .direction
        .expect("a strongly painted direction");
    assert_eq!(d.dir, DVec2::Y);
    assert_eq!(g.patches[1].direction, None);
}

proptest! {
    /// The static obstacles of a patch cover exactly its blocked pixels, without overlap.
    #[test]
    fn obstacle_rectangles_cover_exactly_the_blocked_pixels(mask in proptest::collection::vec(any::<bool>(), 64)) {
        let m = maps(8, 8, |x, y| mask[(y * 8 + x) as usize] && !(x == 0 && y == 7));
        let mut i = inputs(10);
        i.patch_side_m = 8.0;
        i.settings.blocked_above = 1.0;
        let g = build_graph(&m, &i, Hash::of(b"t"), &()).unwrap();
        let p = &g.patches[0];
        let area: f64 = p.obstacles.iter().map(|r| r.area()).sum();
        prop_assert!((area - p.obstacle_coverage * 64.0).abs() < 1e-9);
        for (k, a) in p.obstacles.iter().enumerate() {
            for b in &p.obstacles[k + 1..] {
                let overlap = a.min.x < b.max.x && b.min.x < a.max.x && a.min.y < b.max.y && b.min.y < a.max.y;
                prop_assert!(!overlap);
            }
            // Every rectangle lies on blocked pixels (pixel (x, k) from the south-west).
            for yy in a.min.y as u32..a.max.y as u32 {
                for xx in a.min.x as u32..a.max.x as u32 {
                    prop_assert!(*m.blocked.get(xx, 7 - yy));
                }
            }
        }
    }
}

/// Maps of `w x h` pixels at 0.5 m per pixel with `blocked` pixels given by (x east, north
/// index from the south edge), and inputs of 4 m patches and r = 0.25 (random painting 3's).
fn half_metre(w: u32, h: u32, blocked: impl Fn(u32, u32) -> bool) -> (MergedMaps, GraphInputs) {
    let mut m = maps(w, h, |x, y| blocked(x, h - 1 - y));
    m.meters_per_pixel = 0.5;
    let mut i = inputs(10);
    i.radius_m = 0.25;
    (m, i)
}

fn open_of(g: &PatchGraph, a: u32, b: u32) -> Vec<Interval> {
    let border = g.borders.iter().find(|x| x.a.0 == a && x.b.0 == b);
    border.unwrap().open.clone()
}

#[test]
fn a_strip_no_wider_than_a_character_behind_a_border_is_closed() {
    // Random painting 3's patch 30: in the north-west patch of 2 x 2, a wall 0.5 m above its
    // south edge runs from side to side, and the strip below it (3 m of south border, a
    // diameter wide) ties in open length with the part above (3 m of east border). Walkers let
    // into the strip had to leave above the wall, through it; a walker's centre has no room
    // there at all, so the south border closes and the part above keeps its east opening.
    let (m, i) = half_metre(16, 16, |x, y| {
        (y == 9 && x < 8) || (y == 8 && (6..8).contains(&x))
    });
    let g = build_graph(&m, &i, Hash::of(b"t"), &()).unwrap();
    assert_eq!(open_of(&g, 0, 2), vec![], "south border of the strip");
    assert_eq!(
        open_of(&g, 2, 3),
        vec![Interval {
            start: 1.0,
            end: 4.0
        }]
    );
}

#[test]
fn a_border_behind_which_a_wall_runs_a_diameter_away_is_closed() {
    // Random painting 3's patch 1: in the south-east patch of 2 x 2, a wall 0.5 m east of its
    // west border runs along it but for a gap of one pixel (0.5 m, a diameter): a band piece
    // there ends r from the wall, and the strip it enters leads on only through the gap. No
    // crossing may go there; the part east of the wall keeps its north opening.
    let (m, i) = half_metre(16, 16, |x, y| x == 9 && y < 8 && y != 4);
    let g = build_graph(&m, &i, Hash::of(b"t"), &()).unwrap();
    assert_eq!(open_of(&g, 0, 1), vec![]);
    assert_eq!(
        open_of(&g, 1, 3),
        vec![Interval {
            start: 1.0,
            end: 4.0
        }]
    );
}

#[test]
fn a_gap_narrower_than_a_character_with_room_splits_a_patch() {
    // In the south-east patch of 2 x 2, a wall 1 m east of its west border runs from south to
    // north but for a gap of 0.5 m: the strip west of it (its west border, 1 m of its north
    // border) is wide enough to walk but joined to the rest only through a gap a walker
    // cannot keep clear of. The strip's 5 m of border win; the rest's north opening closes.
    let (m, i) = half_metre(16, 16, |x, y| x == 10 && y < 8 && y != 4);
    let g = build_graph(&m, &i, Hash::of(b"t"), &()).unwrap();
    assert_eq!(
        open_of(&g, 0, 1),
        vec![Interval {
            start: 0.0,
            end: 4.0
        }]
    );
    assert_eq!(
        open_of(&g, 1, 3),
        vec![Interval {
            start: 0.0,
            end: 1.0
        }]
    );
}

/// Read as people per m2, the paint asks its density where it is: a stroke changes the patches
/// under it and no other (shared-out totals would thin every other patch), under rho_max.
#[test]
fn per_square_metre_a_stroke_changes_only_the_patches_under_it() {
    let per_m2 = GraphInputs {
        walkers: 0,
        people: crowd_core::config::People::PerSquareMetre {
            walkers: 0.2,
            standers: 0.0,
        },
        ..inputs(0)
    };
    let mut m = maps(16, 8, |_, _| false);
    m.walkers = Grid::filled(16, 8, 0.5);
    let before = build_graph(&m, &per_m2, Hash::of(b"test"), &()).unwrap();
    assert!(
        before
            .patches
            .iter()
            .all(|p| (p.walker_density - 0.1).abs() < 1e-6)
    );
    for y in 0..4 {
        for x in 0..4 {
            m.walkers.as_mut_slice()[(y * 16 + x) as usize] = 4.0;
        }
    }
    let after = build_graph(&m, &per_m2, Hash::of(b"test"), &()).unwrap();
    // The painted 4 x 4 pixels are one patch (rows run from the north in the maps).
    let changed: Vec<(Cell, f64)> = before
        .patches
        .iter()
        .zip(&after.patches)
        .filter(|(a, b)| a.walker_density != b.walker_density)
        .map(|(_, b)| (b.cell, b.walker_density))
        .collect();
    assert_eq!(
        changed,
        vec![(Cell { col: 0, row: 1 }, 0.35)],
        "capped at rho_max"
    );
    assert_eq!(
        after.walkers_requested,
        (0.1f64 * 16.0 * 7.0 + 0.35 * 16.0).round() as u64
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// What lets a build share the graph it made with its check and report
    /// (`PatchGraph::share`) rather than parse the file it wrote: the file parses back to
    /// the same graph, bit for bit.
    #[test]
    fn a_graph_read_back_from_its_file_is_the_graph_that_was_written(
        w in 1u32..6, h in 1u32..5, seed in 0u64..1000, walkers in 1u64..40
    ) {
        let mut m = maps(w * 4, h * 4, |x, y| (x * 7 + y * 13 + seed as u32).is_multiple_of(11));
        for (i, v) in m.walkers.as_mut_slice().iter_mut().enumerate() {
            if *v > 0.0 {
                *v = ((i as u64 * 2654435761 + seed) % 1000) as f32 / 999.0;
            }
        }
        let g = build_graph(&m, &inputs(walkers), Hash::of(b"test"), &());
        prop_assume!(g.is_ok(), "a painting stage 2 refuses: {:?}", g.err());
        let g = g.unwrap();
        let text = crowd_core::files::to_stage_ron(&g);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("graph.ron");
        std::fs::write(&path, &text).unwrap();
        let read = PatchGraph::load(&path).unwrap();
        prop_assert_eq!(&read, &g);
        let shared = g.share(text.as_bytes());
        let loaded = PatchGraph::load_shared(&path).unwrap();
        prop_assert!(std::sync::Arc::ptr_eq(&shared, &loaded));
    }
}
