//! Tests of `glb`: hand-made `world.glb`s written by stage 8's own writer, each showing a figure catch its defect.

use super::*;
use crowd_core::patterns::{Crossing, Way};
use crowd_core::trajectories::{ControlPoint, PatchMotion, PointKind, Trajectory};
use crowd_export::characters::link;
use crowd_export::glb::{World, world_glb};
use crowd_export::motion::Summaries;

/// `world.glb` of loops in patch 0 of two 8 m patches (20 s clip), each its own successor
/// through its crossing `i` (points: patch-local metres, seconds), with standers, and the
/// figures the check reads from it.
fn figures_of(
    loops: &[Vec<(f64, f64, f64)>],
    standers: &[(f64, f64)],
    region: Option<(f64, f64, f64, f64)>,
) -> ProductFigures {
    let graph = crate::tests::two_patches();
    let trajectories = loops
        .iter()
        .enumerate()
        .map(|(i, pts)| Trajectory {
            entry: i as u32,
            exit: i as u32,
            points: pts
                .iter()
                .map(|&(x, y, t)| ControlPoint {
                    pos: DVec2::new(x, y),
                    t,
                    kind: PointKind::Sample,
                })
                .collect(),
        })
        .collect();
    let standers = standers.iter().map(|&(x, y)| DVec2::new(x, y)).collect();
    let motion = vec![
        PatchMotion {
            standers,
            trajectories,
        },
        PatchMotion::default(),
    ];
    let links = link(&motion, loops.len()).unwrap();
    // The library the glTF takes its headings from (its crossings are never read here).
    let crossings: Vec<Crossing> = (0..loops.len())
        .map(|_| Crossing {
            border: 0,
            way: Way::AToB,
            s: 4.0,
            t: 0.0,
            velocity: DVec2::X,
        })
        .collect();
    let summaries = Summaries::of(&graph, &motion[..]).unwrap();
    let (library, _) = crowd_export::library::build(
        &graph,
        &crossings,
        &motion[..],
        &summaries,
        &links,
        20.0,
        1,
        [0; 8],
    )
    .unwrap();
    let world = World {
        graph: &graph,
        summaries: &summaries,
        motion: &motion,
        links: &links,
        period_s: 20.0,
        seed: 1,
        input_hash: String::new(),
        region,
        library: crowd_export::glb::LibraryRef::Held(&library),
    };
    let inputs = Inputs {
        radius_m: 0.3,
        walls: &[],
        speed_limit_m_s: 1.89,
        world_m: graph.world.covered_m(),
    };
    figures(&world_glb(&world).unwrap(), &inputs).unwrap()
}

/// A square walked from the middle of a side: 24 m, at 1.2 m/s when `last` is 17.5 s.
fn square(last: f64, scale: f64) -> Vec<(f64, f64, f64)> {
    [
        (4.0, 1.0, 0.0),
        (7.0, 1.0, 2.5),
        (7.0, 7.0, 7.5),
        (1.0, 7.0, 12.5),
        (1.0, 1.0, last),
    ]
    .into_iter()
    .chain([(4.0, 1.0, 20.0)])
    .map(|(x, y, t)| (x, y, t * scale))
    .collect()
}

#[test]
fn a_one_lap_node_loops_onto_itself_without_a_jump() {
    let f = figures_of(&[square(17.5, 1.0)], &[], None);
    assert_eq!(
        (f.walkers, f.loops, f.open_loops, f.collisions),
        (1, 1, 0, 0),
        "{f:?}"
    );
    assert!(
        f.max_seam_gap_m < 1e-6 && f.max_seam_velocity_jump < 1e-3,
        "{f:?}"
    );
    assert!(f.max_seam_heading_jump_rad < 1e-3, "{f:?}");
    assert!((f.max_speed_m_s - 1.2).abs() < 1e-3, "{f:?}");
    // Each corner a quarter turn at the turn rate, 360 degrees a second, over the first
    // quarter second after it.
    let turn = f.max_turn_rate_rad_s.unwrap();
    assert!((turn - std::f64::consts::TAU).abs() < 1e-2, "{turn}");
}

#[test]
fn a_node_hurrying_to_its_seam_jumps_there_and_runs_too_fast() {
    let f = figures_of(&[square(18.5, 1.0)], &[], None);
    assert!((f.max_seam_velocity_jump - 0.8).abs() < 1e-3, "{f:?}");
    assert!((f.max_speed_m_s - 2.0).abs() < 1e-3, "{f:?}");
    assert!((f.share_above_limit - 1.5 / 20.0).abs() < 1e-5, "{f:?}");
}

#[test]
fn a_walker_turning_back_at_a_handover_jumps_in_velocity_and_heading() {
    // One lap: the velocity turns round at the seam, but the node's rotation keys turn it
    // over its last piece (the rotation at the clip's end is the one at its start).
    let back = vec![(1.0, 4.0, 0.0), (7.0, 4.0, 10.0), (1.0, 4.0, 20.0)];
    let f = figures_of(&[back], &[], None);
    assert!((f.max_seam_velocity_jump - 1.2).abs() < 1e-3, "{f:?}");
    assert!(f.max_seam_heading_jump_rad < 1e-3, "{f:?}");
    // Two laps, turning back where slot 0 hands over to slot 1: the velocity turns round, and
    // export turns the heading before the handover, so the two slots face the same way there.
    let back = vec![(1.0, 4.0, 0.0), (7.0, 4.0, 20.0), (1.0, 4.0, 40.0)];
    let f = figures_of(&[back], &[], None);
    assert_eq!((f.walkers, f.open_loops), (2, 0), "{f:?}");
    assert!((f.max_seam_velocity_jump - 0.6).abs() < 1e-3, "{f:?}");
    assert!(f.max_seam_heading_jump_rad < 1e-3, "{f:?}");
}

#[test]
fn two_slots_of_a_two_lap_loop_hand_over_to_each_other() {
    let f = figures_of(&[square(17.5, 2.0)], &[], None);
    assert_eq!((f.walkers, f.open_loops), (2, 0), "{f:?}");
    assert!(
        f.max_seam_gap_m < 1e-5 && f.max_seam_velocity_jump < 1e-3,
        "{f:?}"
    );
}

#[test]
fn a_region_shows_every_slot_that_walks_into_it_and_its_loop_closes() {
    // At clip time 0 slot 0 is at (4, 1), slot 1 half-way round, at (4, 7); slot 1 walks into
    // the region during the clip, so export shows it there (hidden outside) and the loop closes.
    let f = figures_of(&[square(17.5, 2.0)], &[], Some((0.0, 0.0, 8.0, 4.0)));
    assert_eq!((f.walkers, f.open_loops), (2, 0), "{f:?}");
}

#[test]
fn two_nodes_crossing_at_once_collide_and_so_does_one_walking_into_a_stander() {
    let east = vec![(1.0, 4.0, 0.0), (7.0, 4.0, 10.0), (1.0, 4.0, 20.0)];
    let north = vec![(4.0, 1.0, 0.0), (4.0, 7.0, 10.0), (4.0, 1.0, 20.0)];
    let f = figures_of(&[east.clone(), north], &[], None);
    assert_eq!(f.collisions, 1, "{f:?}");
    assert!((f.min_clearance_m + 0.6).abs() < 1e-3, "{f:?}");
    let f = figures_of(&[east], &[(6.0, 4.2)], None);
    assert_eq!((f.collisions, f.standers), (1, 1), "{f:?}");
}

#[test]
fn bytes_that_are_no_gltf_are_an_error() {
    let inputs = Inputs {
        radius_m: 0.3,
        walls: &[],
        speed_limit_m_s: 1.89,
        world_m: glam::DVec2::splat(100.0),
    };
    let e = figures(b"glTF but not really", &inputs).unwrap_err();
    assert!(e.0.starts_with("not a glTF"), "{e}");
}
