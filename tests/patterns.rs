//! What stages 3 and 4 must show: mirror patterns, parity, spacing, rho_max, exact boundary
//! points, and the painted directions.

use crate::util::*;
use crowd_core::PatchGraph;
use crowd_core::patterns::{Crossing, Patterns, parity};
use crowd_core::trajectories::{PointKind, TrajectoriesFile};
use glam::DVec2;
use std::path::Path;

struct Built {
    graph: PatchGraph,
    patterns: Patterns,
    crossings: Vec<Crossing>,
    out: std::path::PathBuf,
}

/// A shipped scene's stage files, from the run's build of it.
fn build(name: &str) -> Built {
    load(scene(name))
}

fn load(out: &Path) -> Built {
    let graph = PatchGraph::load(&out.join("graph.ron")).unwrap();
    let (patterns, crossings) = Patterns::load(&out.join("patterns.ron")).unwrap();
    Built {
        graph,
        patterns,
        crossings,
        out: out.to_path_buf(),
    }
}

#[test]
fn every_exit_is_the_entry_of_the_neighbour_and_parity_holds() {
    for name in ["city", "ring"] {
        let b = build(name);
        for c in &b.crossings {
            let (from, to) = c.ends(&b.graph);
            assert_ne!(from.patch, to.patch);
            let world = |p: crowd_core::patterns::BorderPoint| {
                b.graph.world_from_patch(b.graph.patch(p.patch).cell) + p.pos
            };
            assert!(
                (world(from) - world(to)).length() < 1e-9,
                "{name}: mirror points differ"
            );
            // The crossing lies on an open interval of its border.
            let border = &b.graph.borders[c.border as usize];
            assert!(border.open.iter().any(|i| c.s > i.start && c.s < i.end));
            assert!(c.t >= 0.0 && c.t < b.patterns.period_s);
        }
        assert!(
            parity(&b.graph, &b.crossings).iter().all(|&x| x == 0),
            "{name}: parity"
        );
    }
}

#[test]
fn crossings_keep_their_spacing_and_no_patch_exceeds_rho_max() {
    for name in ["city", "lanes"] {
        let b = build(name);
        let spacing = crowd_optimize::spacing::Spacing::new(&b.graph);
        let mut per_border = vec![Vec::new(); b.graph.borders.len()];
        for c in &b.crossings {
            per_border[c.border as usize].push(*c);
        }
        assert!(
            crowd_optimize::spacing::all_spaced(&spacing, &per_border, b.patterns.period_s),
            "{name}"
        );
        for (p, m) in b.graph.patches.iter().zip(&b.patterns.measured) {
            assert!(
                m.density <= b.patterns.rho_max + 1e-9,
                "{name}: patch {:?} holds {}",
                p.cell,
                m.density
            );
        }
    }
}

#[test]
fn trajectories_pass_their_boundary_points_exactly() {
    let b = build("city");
    let (file, motion) = TrajectoriesFile::load(&b.out.join("trajectories.ron")).unwrap();
    let period = file.period_s;
    let mut count = 0;
    for (p, m) in motion.iter().enumerate() {
        assert_eq!(m.standers.len() as u32, b.patterns.measured[p].standers);
        for tr in &m.trajectories {
            let (first, last) = (tr.points[0], *tr.points.last().unwrap());
            assert_eq!((first.kind, last.kind), (PointKind::Entry, PointKind::Exit));
            let entry = b.crossings[tr.entry as usize];
            let exit = b.crossings[tr.exit as usize];
            let (_, into) = entry.ends(&b.graph);
            let (out_of, _) = exit.ends(&b.graph);
            assert_eq!((into.patch.0 as usize, out_of.patch.0 as usize), (p, p));
            assert_eq!(first.pos, into.pos);
            assert_eq!(first.t, entry.t);
            assert!((last.pos - out_of.pos).length() < 1e-12);
            assert!(
                ((last.t - exit.t) / period - ((last.t - exit.t) / period).round()).abs() < 1e-9
            );
            for w in tr.points.windows(2) {
                assert!(w[1].t >= w[0].t, "time never runs backwards");
            }
            count += 1;
        }
    }
    assert_eq!(count as u64, file.summary.walkers_trajectories);
    assert!(count > 1000);
}

#[test]
fn ring_walkers_go_counter_clockwise() {
    let b = build("ring");
    let centre = b.graph.world.size_m / 2.0;
    let (mut ccw, mut directed) = (0, 0);
    for (p, m) in b.graph.patches.iter().zip(&b.patterns.measured) {
        if p.direction.is_none() {
            continue;
        }
        directed += 1;
        let middle =
            b.graph.world_from_patch(p.cell) + DVec2::splat(b.graph.world.patch_side_m / 2.0);
        let radial = (middle - centre).normalize();
        if m.direction.is_some_and(|d| radial.perp_dot(d) > 0.0) {
            ccw += 1;
        }
    }
    assert!(
        ccw * 10 >= directed * 9,
        "{ccw} of {directed} ring patches measured counter-clockwise"
    );
}

/// Issue 3's targets for the scenes that build in seconds (the others are in BENCHMARKS.md):
/// E <= 0.05 for `ring` and `city`, the paper's circular-flow and Wall Street cases at 0.067.
#[test]
fn ring_and_city_beat_the_papers_error() {
    for name in ["ring", "city"] {
        let e = build(name).patterns.error;
        assert!(e.e <= 0.05, "{name}: {e:?}");
    }
}

/// A patch's error as `worst` ranks it: density error in units of rho_max plus direction error.
fn size(p: &Patterns, e: &crowd_core::patterns::PatchError) -> f64 {
    (e.requested - e.measured).abs() / p.rho_max + e.direction_error.unwrap_or(0.0)
}

/// Dense on the west, nearly empty on the east, and a flow asking everyone to walk east: the
/// walkers must come back west somewhere, so the flow cannot be met. The build still ends, with
/// a compromise whose error is many times a consistent painting's (the same density, no flow),
/// and `crowd inspect` names the patches where it stays, the worst far off what was painted.
#[test]
fn a_contradictory_painting_ends_with_a_compromise_and_says_where() {
    let dir = tempfile::tempdir().unwrap();
    let density =
        image::GrayImage::from_fn(128, 64, |x, _| image::Luma([if x < 64 { 255 } else { 3 }]));
    let flow = image::RgbaImage::from_pixel(128, 64, image::Rgba([255, 128, 128, 255]));
    let (density_png, flow_png) = (dir.path().join("density.png"), dir.path().join("flow.png"));
    density.save(&density_png).unwrap();
    flow.save(&flow_png).unwrap();
    let build = |name: &str, layers: &[(&str, &Path)], until: &str| {
        let sub = dir.path().join(name);
        std::fs::create_dir_all(&sub).unwrap();
        let pipeline = write_pipeline(&sub, layers, "");
        crowd_ok(&["build", "-q", "--pipeline", s(&pipeline), "--until", until]);
        sub.join("out")
    };
    let consistent = load(&build(
        "consistent",
        &[("Density", &density_png)],
        "optimize",
    ));
    let out = build(
        "contradictory",
        &[("Density", &density_png), ("Flow", &flow_png)],
        "export",
    );
    let b = load(&out);

    let (good, bad) = (&consistent.patterns, &b.patterns);
    assert!(good.error.e < 0.03, "consistent painting: {:?}", good.error);
    assert!(
        size(good, &good.worst[0]) < 0.1,
        "consistent painting: {:?}",
        good.worst[0]
    );
    assert!(
        bad.error.e > 0.08 && bad.error.e > 3.0 * good.error.e && bad.error.e_d > 0.02,
        "contradictory {:?} against consistent {:?}",
        bad.error,
        good.error
    );
    let worst = &bad.worst[0];
    assert!(
        size(bad, worst) > 0.5 && worst.direction_error.is_some_and(|d| d > 0.5),
        "the worst patch of the contradiction: {worst:?}"
    );
    let text =
        String::from_utf8(crowd_ok(&["inspect", s(&out.join("patterns.ron"))]).stdout).unwrap();
    let listed = text
        .split_once("worst patches (where the error stays):\n")
        .map(|(_, rest)| rest.lines().next().unwrap_or(""))
        .unwrap_or_else(|| panic!("no worst patches in\n{text}"));
    let cell = format!("cell ({:>3}, {:>3})", worst.cell.col, worst.cell.row);
    assert!(
        listed.contains(&format!("#{}", worst.patch.0))
            && listed.contains(&cell)
            && listed.contains("direction off by"),
        "{cell} first in\n{text}"
    );
}

#[test]
fn standers_stand_apart_inside_their_patch_and_clear_of_obstacles() {
    let b = build("city");
    let (file, motion) = TrajectoriesFile::load(&b.out.join("trajectories.ron")).unwrap();
    let (r, side) = (file.radius_m, b.graph.world.patch_side_m);
    let mut standers = 0;
    for (p, m) in motion.iter().enumerate() {
        for (i, s) in m.standers.iter().enumerate() {
            assert!(s.x >= r && s.y >= r && s.x <= side - r && s.y <= side - r);
            for o in &m.standers[i + 1..] {
                assert!(
                    s.distance(*o) >= 2.0 * r,
                    "patch {p}: standers {s} and {o} overlap"
                );
            }
            for rect in &b.graph.patches[p].obstacles {
                assert!(
                    (s.clamp(rect.min, rect.max) - *s).length() >= r,
                    "patch {p}: {s} in an obstacle"
                );
            }
            standers += 1;
        }
    }
    assert_eq!(standers, 160);
}

#[test]
fn the_collide_stage_never_moves_a_boundary_point() {
    let out = scene("bands");
    let (_, before) = TrajectoriesFile::load(&out.join("trajectories.ron")).unwrap();
    let (file, after) = TrajectoriesFile::load_stage(
        &out.join("collided.ron"),
        crowd_collide::STAGE,
        crowd_collide::VERSION,
    )
    .unwrap();
    assert_eq!(before.len(), after.len());
    for (b, a) in before.iter().zip(&after) {
        assert_eq!(b.standers, a.standers);
        assert_eq!(b.trajectories.len(), a.trajectories.len());
        for (tb, ta) in b.trajectories.iter().zip(&a.trajectories) {
            assert_eq!((tb.entry, tb.exit), (ta.entry, ta.exit));
            assert_eq!(tb.points.first(), ta.points.first());
            assert_eq!(tb.points.last(), ta.points.last());
        }
    }
    let c = file.collisions.expect("collide figures");
    assert!(
        c.unconverged.len() * 10 < after.len(),
        "{} of {} patches unconverged",
        c.unconverged.len(),
        after.len()
    );
}

/// `crowd check` on bands' tiled world: stage 5's file holds no collision anywhere and keeps
/// every pair at least its clearance apart; the same file with one stander dropped in a
/// walker's way, and stage 4's straight lines (which walk through each other, across borders
/// too), are reported with their collisions and a clearance below zero.
#[test]
fn crowd_check_reports_collisions_and_clearance_for_the_tiled_world() {
    let dir = copy_of("bands");
    let out = dir.path();
    let check = |stage: &str| -> serde_json::Value {
        let text =
            String::from_utf8(crowd_ok(&["check", s(out), "--stage", stage]).stdout).unwrap();
        assert!(
            text.contains("collisions") && text.contains("smallest clearance"),
            "{text}"
        );
        let json: serde_json::Value =
            serde_json::from_slice(&crowd_ok(&["report", s(out), "--json"]).stdout).unwrap();
        assert_eq!(json["checked_stage"], stage, "{json}");
        json
    };
    let figures = |json: &serde_json::Value| {
        (
            json["collisions"].as_u64().unwrap(),
            json["collisions_across_borders"].as_u64().unwrap(),
            json["min_clearance_m"].as_f64().unwrap(),
        )
    };

    // A collision is a pair closer than 2r by more than 1e-6 m, the checker's tolerance.
    let shipped = check("collide");
    let (collisions, across, clearance) = figures(&shipped);
    assert_eq!((collisions, across), (0, 0), "{shipped}");
    assert!((-1e-6..0.5).contains(&clearance), "{shipped}");

    // Stage 4's straight lines meet, inside patches and across borders.
    let (collisions, across, clearance) = figures(&check("match"));
    assert!(
        collisions > 100 && across > 0 && across < collisions && clearance < -0.3,
        "straight lines: {collisions} collisions, {across} across borders, clearance {clearance}"
    );

    // One stander where a walker is halfway through its walk.
    let collided = out.join("collided.ron");
    let (file, mut motion) =
        TrajectoriesFile::load_stage(&collided, crowd_collide::STAGE, crowd_collide::VERSION)
            .unwrap();
    let m = motion
        .iter_mut()
        .find(|m| !m.trajectories.is_empty())
        .unwrap();
    let tr = &m.trajectories[0];
    let (t0, t1) = (tr.points[0].t, tr.points.last().unwrap().t);
    let there = crowd_core::trajectories::position_at(&tr.points, (t0 + t1) / 2.0);
    m.standers.push(there);
    let (_, writes) = crowd_core::trajectories::encode_file(
        &collided,
        file.header.clone(),
        file.period_s,
        file.radius_m,
        &motion,
        file.collisions.clone(),
        None,
    );
    for (path, bytes) in writes {
        std::fs::write(path, bytes).unwrap();
    }
    let broken = check("collide");
    let (collisions, across, clearance) = figures(&broken);
    assert!(collisions >= 1 && across == 0, "{broken}");
    assert!(
        (clearance + 2.0 * file.radius_m).abs() < 1e-9,
        "a stander on a walker's path: clearance {clearance}, expected -2r"
    );
}

/// The tiled world's claim, scene by scene: every patch converges, nobody overlaps anybody
/// anywhere at any time (across borders too, thanks to the border bands), every trajectory
/// starts and ends exactly at its crossings, and velocities do not jump at borders. Checked by
/// `crowd check` on the smoothed trajectories, the ones that ship. And smoothing ships almost
/// no polyline, keeping the 95th percentiles of acceleration and turning rate near stage 5's.
fn assert_collision_free_in_the_tiled_world(name: &str) {
    let dir = copy_of(name);
    let out = dir.path();
    // What engines load of it passes the Khronos validator (painting's in its region).
    let glb = out.join("world.glb");
    let validated = std::process::Command::new("node")
        .arg(root().join("tools/gltf/validate.mjs"))
        .arg(&glb)
        .output()
        .expect("node runs (`npm ci --prefix tools/gltf` first)");
    let report = String::from_utf8_lossy(&validated.stdout);
    assert!(
        validated.status.success() && report.contains("0 errors, 0 warnings"),
        "{report}"
    );
    let report = || -> serde_json::Value {
        serde_json::from_slice(&crowd_ok(&["report", s(out), "--json"]).stdout).unwrap()
    };
    crowd_ok(&["check", s(out), "--stage", "collide"]);
    let polylines = report();
    crowd_ok(&["check", s(out)]);
    let json = report();
    for figure in ["accel_p95", "turn_rate_p95"] {
        let of = |json: &serde_json::Value, stage: &str| {
            json[figure]
                .as_f64()
                .unwrap_or_else(|| panic!("{name}: no {figure} after checking {stage}: {json}"))
        };
        let (before, after) = (of(&polylines, "collide"), of(&json, "smooth"));
        // The figure takes a polyline's corner over the time between its pieces' middles
        // (often a second or more), the curves' over the 0.1 s their averaging spreads it:
        // within 10 % of the polylines' (center-flow's acceleration 1.045 -> 1.13 m/s2), but
        // center-flow's turning rate: its polylines turn gently, at few corners, which the
        // averaging turns in 0.1 s (0.565 -> 0.68 rad/s; 0.535 with curves alone, whose
        // corners played as jumps of up to 3.3 m/s in a frame).
        let slack = if (name, figure) == ("center-flow", "turn_rate_p95") {
            1.25
        } else {
            1.1
        };
        assert!(
            after < before * slack,
            "{name} {figure}: {before} -> {after}"
        );
    }
    // What a player shows at a polyline's corner is a velocity jump in one frame: almost no
    // trajectory ships as its polyline (before the averaging, 28 % of bands' and 52 % of
    // ring's did; now at most 1 %).
    let (straight, all) = (
        json["kept_straight"].as_f64(),
        json["trajectories"].as_f64(),
    );
    let (straight, all) = (straight.unwrap(), all.unwrap());
    assert!(
        straight <= 0.01 * all,
        "{name}: {straight} of {all} ship as polylines"
    );
    assert_eq!(json["unconverged_patches"], 0, "{name}: {json}");
    assert_eq!(json["collisions"], 0, "{name}: {json}");
    assert!(json["min_clearance_m"].as_f64().unwrap() >= -1e-6, "{name}");
    assert!(
        json["max_border_velocity_jump"].as_f64().unwrap() < 1e-6,
        "{name}"
    );
    assert_eq!(
        json["max_boundary_error_m"].as_f64().unwrap(),
        0.0,
        "{name}"
    );
    assert!(
        json["max_boundary_time_error_s"].as_f64().unwrap() < 1e-9,
        "{name}"
    );
    assert_eq!(json["unmatched_crossings"], 0, "{name}");
}

#[test]
fn bands_is_collision_free_in_the_tiled_world() {
    assert_collision_free_in_the_tiled_world("bands");
}

#[test]
fn center_flow_is_collision_free_in_the_tiled_world() {
    assert_collision_free_in_the_tiled_world("center-flow");
}

#[test]
fn city_is_collision_free_in_the_tiled_world() {
    assert_collision_free_in_the_tiled_world("city");
}

#[test]
fn lanes_is_collision_free_in_the_tiled_world() {
    assert_collision_free_in_the_tiled_world("lanes");
}

#[test]
fn ring_is_collision_free_in_the_tiled_world() {
    assert_collision_free_in_the_tiled_world("ring");
}

#[test]
fn painting_is_collision_free_in_the_tiled_world() {
    assert_collision_free_in_the_tiled_world("painting");
}

#[test]
fn smoothing_keeps_boundary_points_exact_and_never_brings_a_pair_closer_than_stage_5_left_it() {
    let dir = copy_of("bands");
    let out = dir.path();
    let graph = crowd_core::PatchGraph::load(&out.join("graph.ron")).unwrap();
    let load = |name: &str, stage: &str, version: u32| {
        TrajectoriesFile::load_stage(&out.join(name), stage, version)
            .unwrap()
            .1
    };
    let before = load("collided.ron", crowd_collide::STAGE, crowd_collide::VERSION);
    let after = load("smoothed.ron", crowd_smooth::STAGE, crowd_smooth::VERSION);
    let mut smoothed = 0;
    for (p, (b, a)) in before.iter().zip(&after).enumerate() {
        for (tb, ta) in b.trajectories.iter().zip(&a.trajectories) {
            assert_eq!(tb.points.first(), ta.points.first());
            assert_eq!(tb.points.last(), ta.points.last());
            smoothed += (tb != ta) as usize;
        }
        let obstacles = crowd_collide::obstacles_near(&graph, p);
        let patch = crowd_collide::repair::Patch {
            side_m: graph.world.patch_side_m,
            period_s: 20.0,
            radius_m: graph.radius_m,
            obstacles: &obstacles,
            standers: &b.standers,
        };
        let worst = |m: &crowd_core::trajectories::PatchMotion| {
            let segs: Vec<_> = m
                .trajectories
                .iter()
                .map(crowd_collide::path::trajectory_segments)
                .collect();
            crowd_collide::repair::rows(&crowd_collide::repair::Tracks::new(segs), &patch)
                .iter()
                .flatten()
                .map(|e| e.margin)
                .fold(0.0, f64::min)
        };
        assert!(worst(a) >= worst(b) - 1e-9, "patch {p}");
    }
    assert!(smoothed * 2 > after.iter().map(|m| m.trajectories.len()).sum::<usize>());
    let smoothed = out.join("smoothed.ron");
    let text = String::from_utf8(crowd_ok(&["inspect", s(&smoothed)]).stdout).unwrap();
    assert!(text.contains("trajectories smoothed"), "{text}");
    let picture = out.join("patch.png");
    crowd_ok(&["render", s(&smoothed), "-o", s(&picture)]);
    assert!(image::open(&picture).is_ok());
    crowd_ok(&["check", s(out)]);
    let json: serde_json::Value =
        serde_json::from_slice(&crowd_ok(&["report", s(out), "--json"]).stdout).unwrap();
    assert_eq!(json["checked_stage"], "smooth");
    assert_eq!(json["max_boundary_error_m"].as_f64(), Some(0.0));
    assert!(json["max_boundary_time_error_s"].as_f64().unwrap() < 1e-9);
    assert_eq!(json["unmatched_crossings"], 0);
    for key in [
        "speed_in_band",
        "accel_p95",
        "turn_rate_p95",
        "max_border_velocity_jump",
    ] {
        assert!(json[key].as_f64().is_some_and(f64::is_finite), "{key}");
    }
}
