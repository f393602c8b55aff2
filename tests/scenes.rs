//! What stage 2 must show on every shared scene.

use crate::util::*;
use crowd_core::PatchGraph;
use glam::DVec2;

/// The patch graph of a shipped scene, from the run's build of it.
fn graph_of(name: &str) -> PatchGraph {
    PatchGraph::load(&scene(name).join("graph.ron")).unwrap()
}

#[test]
fn every_scene_requests_exactly_its_walkers() {
    for name in scene_names() {
        let json: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(shared_scenes().join(&name).join("scene.json")).unwrap(),
        )
        .unwrap();
        let characters = json["characters"].as_u64().unwrap();
        let g = graph_of(&name);
        assert_eq!(g.walkers_requested, characters, "{name}");
        let total: f64 = g
            .patches
            .iter()
            .map(|p| p.walker_density * g.patch_area())
            .sum();
        assert!(
            (total - characters as f64).abs() < 1e-6 * characters as f64,
            "{name}: {total} walkers requested in patches, expected {characters}"
        );
        assert_eq!(g.world.patch_side_m, json["patch_m"].as_f64().unwrap());
    }
}

#[test]
fn painting_is_cut_into_its_grid_of_patches() {
    let g = graph_of("painting");
    // 1120 m x 720 m in 8 m patches: 140 x 90 = 12,600 cells. The painting leaves 1,694 cells
    // entirely unpainted (black); those are empty and dropped.
    assert_eq!((g.world.cols, g.world.rows), (140, 90));
    assert_eq!(
        g.patches.len() + g.dropped.empty.len() + g.dropped.blocked.len(),
        12_600
    );
    assert_eq!(g.dropped.empty.len(), 1_694);
    assert_eq!(g.patches.len(), 10_906);
}

#[test]
fn city_obstacles_remove_patches_and_close_border_intervals() {
    let g = graph_of("city");
    assert!(
        g.dropped.blocked.len() > 500,
        "{} blocked",
        g.dropped.blocked.len()
    );
    let closed = g.borders.iter().filter(|b| b.open.is_empty()).count();
    let side = g.world.patch_side_m;
    let partly = g
        .borders
        .iter()
        .filter(|b| !b.open.is_empty() && b.open.iter().map(|i| i.len()).sum::<f64>() < side)
        .count();
    assert!(
        closed > 0 && partly > 0,
        "{closed} closed, {partly} partly closed borders"
    );
    let with_obstacles = g.patches.iter().filter(|p| !p.obstacles.is_empty()).count();
    assert!(with_obstacles > 100, "{with_obstacles}");
    // Open intervals lie on the border, in order, each wide enough for a character.
    for b in &g.borders {
        for w in b.open.windows(2) {
            assert!(w[0].end < w[1].start);
        }
        for i in &b.open {
            assert!(i.start >= 0.0 && i.end <= side && i.len() >= 2.0 * g.radius_m);
        }
    }
    // The avenue asks people to walk north.
    let directed: Vec<_> = g.patches.iter().filter_map(|p| p.direction).collect();
    assert!(!directed.is_empty());
    assert!(directed.iter().all(|d| d.dir.y > 0.9), "northward avenue");
    // The park holds the standers.
    let standers: f64 = g
        .patches
        .iter()
        .map(|p| p.stander_density * g.patch_area())
        .sum();
    assert!((standers - g.standers_requested as f64).abs() < 1e-6);
}

#[test]
fn ring_directions_run_counter_clockwise() {
    let g = graph_of("ring");
    let centre = g.world.size_m / 2.0;
    let mut directed = 0;
    for p in &g.patches {
        if let Some(d) = p.direction {
            let middle = g.world_from_patch(p.cell) + DVec2::splat(g.world.patch_side_m / 2.0);
            let radial = (middle - centre).normalize();
            // Counter-clockwise: the direction turns left of the outward radius.
            assert!(
                radial.perp_dot(d.dir) > 0.9,
                "patch {:?}: {:?} at {middle}",
                p.cell,
                d.dir
            );
            directed += 1;
        }
    }
    assert!(directed > 100, "{directed} patches on the ring");
}

#[test]
fn center_flow_asks_for_east_exactly_where_its_alpha_paints_a_direction() {
    let g = graph_of("center-flow");
    let alpha = image::open(shared_scenes().join("center-flow/direction.png"))
        .unwrap()
        .to_luma_alpha8();
    let side = g.world.patch_side_m as u32;
    let mut directed = 0;
    for p in &g.patches {
        // Mean alpha of the patch's pixels (image rows count from the north edge).
        let top = alpha.height() - (p.cell.row + 1) * side;
        let mut sum = 0.0;
        for y in top..top + side {
            for x in p.cell.col * side..(p.cell.col + 1) * side {
                sum += alpha.get_pixel(x, y)[1] as f64 / 255.0;
            }
        }
        let painted =
            sum / (side * side) as f64 >= crowd_core::GraphSettings::default().direction_min_weight;
        assert_eq!(p.direction.is_some(), painted, "{:?}", p.cell);
        if let Some(d) = p.direction {
            assert!(d.dir.x > 0.99, "{:?} heads {:?}", p.cell, d.dir);
            directed += 1;
        }
    }
    assert!(directed > 20, "{directed}");
}

#[test]
fn graph_pictures_render() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["city", "ring"] {
        let out = scene(name);
        for stage in ["merge", "graph"] {
            let png = dir.path().join(format!("{name}-{stage}.png"));
            crowd_ok(&[
                "render",
                s(&out.join(format!("{stage}.ron"))),
                "-o",
                s(&png),
                "-q",
            ]);
            let picture = image::open(&png).unwrap();
            assert!(picture.width() > 400 && picture.height() > 400);
        }
    }
}
