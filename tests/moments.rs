//! Stage 7 on real patches: each kind of edit brings its patches nearer its target, and no
//! entry, exit or border band moves.

use crate::util::*;
use crowd_core::PatchGraph;
use crowd_core::config::{Edit, EditKind};
use crowd_core::trajectories::{
    DensityFigures, PatchMotion, TrajectoriesFile, Trajectory, band_ends, position_at,
};
use crowd_geometry::{Tracks, trajectory_segments};
use crowd_moments::{Inputs, edit};
use glam::DVec2;
use std::path::Path;

fn load(out: &Path) -> (PatchGraph, Vec<PatchMotion>) {
    let graph = PatchGraph::load(&out.join("graph.ron")).unwrap();
    let (stage, version) = (crowd_smooth::STAGE, crowd_smooth::VERSION);
    let motion = TrajectoriesFile::load_stage(&out.join("smoothed.ron"), stage, version)
        .unwrap()
        .1;
    (graph, motion)
}

/// Patches by the time walkers spend in them, busiest first.
fn busiest(motion: &[PatchMotion]) -> Vec<usize> {
    let time = |p: usize| -> f64 { motion[p].trajectories.iter().map(|t| t.duration()).sum() };
    let mut order: Vec<usize> = (0..motion.len()).collect();
    order.sort_by(|a, b| time(*b).total_cmp(&time(*a)).then(a.cmp(b)));
    order
}

fn inputs(edits: Vec<Edit>) -> Inputs {
    Inputs {
        period_s: 20.0,
        max_speed: MAX_SPEED,
        margin_m: MARGIN_M,
        edits,
        flow_maps: Vec::new(),
    }
}

/// `match.max_speed` (1.8 m/s) with stage 6's allowance, and the shipping margin of `city`.
const MAX_SPEED: f64 = 1.8 * 1.04;
const MARGIN_M: f64 = 0.0015;

fn edit_of(name: &str, kind: EditKind) -> Edit {
    Edit {
        name: name.into(),
        kind,
        r: None,
        q: None,
    }
}

/// What every edit must keep, checked patch by patch against the unedited motion: the same
/// walkers with bit-identical entry and exit points and border bands, no walk faster than the
/// limit (or than its plan), every point in the patch, and (measured exactly, as stage 5 does)
/// no one closer to anyone or anything than before.
fn assert_kept(graph: &PatchGraph, before: &[PatchMotion], after: &[PatchMotion]) {
    assert_kept_over(graph, before, after, 20.0);
}

/// [`assert_kept`] for a build of period `period` s.
fn assert_kept_over(
    graph: &PatchGraph,
    before: &[PatchMotion],
    after: &[PatchMotion],
    period: f64,
) {
    let side = graph.world.patch_side_m;
    for (p, (b, a)) in before.iter().zip(after).enumerate() {
        if a == b {
            continue;
        }
        assert_eq!(a.standers, b.standers, "patch {p}: standers moved");
        assert_eq!(a.trajectories.len(), b.trajectories.len());
        for (j, (ta, tb)) in a.trajectories.iter().zip(&b.trajectories).enumerate() {
            assert_eq!((ta.entry, ta.exit), (tb.entry, tb.exit));
            let ends = |t: &Trajectory| {
                let (e, x) = band_ends(&t.points);
                let n = t.points.len();
                let head = t.points[..=e.unwrap_or(0)].to_vec();
                let tail = t.points[x.unwrap_or(n - 1)..].to_vec();
                (head, tail)
            };
            assert_eq!(
                ends(ta),
                ends(tb),
                "patch {p} walker {j}: an entry, exit or band moved"
            );
            let allowed = MAX_SPEED.max(crowd_moments::patch::fastest(tb)) + 1e-9;
            assert!(
                crowd_moments::patch::fastest(ta) <= allowed,
                "patch {p} walker {j}: too fast"
            );
            assert!(
                ta.points.iter().all(
                    |q| q.pos.cmpge(DVec2::ZERO).all() && q.pos.cmple(DVec2::splat(side)).all()
                ),
                "patch {p} walker {j} leaves the patch"
            );
        }
        let obstacles = crowd_geometry::obstacles_near(graph, p);
        let patch = crowd_geometry::Patch {
            side_m: side,
            period_s: period,
            radius_m: graph.radius_m + MARGIN_M,
            obstacles: &obstacles,
            standers: &b.standers,
        };
        let margins = |m: &PatchMotion| {
            let tracks = Tracks::new(m.trajectories.iter().map(trajectory_segments).collect());
            crowd_geometry::rows(&tracks, &patch)
                .into_iter()
                .flatten()
                .map(|e| e.margin)
                .fold(f64::INFINITY, f64::min)
        };
        let (was, now) = (margins(b), margins(a));
        assert!(
            now >= was.min(0.0) - 1e-9,
            "patch {p}: closest margin {was} -> {now}"
        );
    }
}

/// Two walkers of `patch` who pass near each other (2-4 m apart) at some whole second from 6
/// to 14 s while both are off their border bands: where and when they could meet.
fn near_pair(graph: &PatchGraph, motion: &PatchMotion, patch: usize) -> Option<(DVec2, f64)> {
    let origin = graph.world_from_patch(graph.patches[patch].cell);
    let free = |t: &Trajectory, at: f64| {
        let (e, x) = band_ends(&t.points);
        let from = e.map_or(t.points[0].t, |i| t.points[i].t) + 4.0;
        let to = x.map_or(t.points[t.points.len() - 1].t, |i| t.points[i].t) - 4.0;
        (from..=to).contains(&at)
    };
    for second in 6..=14 {
        for period in [0.0, 20.0] {
            let at = second as f64 + period;
            let here: Vec<&Trajectory> =
                motion.trajectories.iter().filter(|t| free(t, at)).collect();
            for (i, a) in here.iter().enumerate() {
                for b in &here[i + 1..] {
                    let (pa, pb) = (position_at(&a.points, at), position_at(&b.points, at));
                    let d = pa.distance(pb);
                    if (2.0..4.0).contains(&d) {
                        return Some((origin + (pa + pb) / 2.0, second as f64));
                    }
                }
            }
        }
    }
    None
}

#[test]
fn meetings_bring_walkers_within_half_a_metre_and_move_no_border_point() {
    let (graph, motion) = load(scene("city"));
    let mut met = 0;
    for p in busiest(&motion).into_iter().take(8) {
        let Some((at, time)) = near_pair(&graph, &motion[p], p) else {
            continue;
        };
        let kind = EditKind::Meet {
            at: (at.x, at.y),
            time_s: time,
            people: 2,
            radius_m: None,
        };
        let (after, outcomes) = edit(&graph, &motion, &inputs(vec![edit_of("meet", kind)]), &());
        let o = &outcomes[0];
        assert_eq!(o.patches, vec![p as u32]);
        assert!(o.after < 0.5 && o.after < o.before, "patch {p}: {o:?}");
        assert_kept(&graph, &motion, &after);
        met += 1;
    }
    assert!(
        met >= 3,
        "only {met} of the busiest patches had two walkers to meet"
    );
}

#[test]
fn each_area_edit_lowers_its_residual_on_busy_patches() {
    let (graph, motion) = load(scene("city"));
    let side = graph.world.patch_side_m;
    for p in busiest(&motion).into_iter().take(4) {
        let c = graph.world_from_patch(graph.patches[p].cell) + DVec2::splat(side / 2.0);
        let rect = (c.x - 2.5, c.y - 2.5, c.x + 2.5, c.y + 2.5);
        let window_s = (8.0, 10.0);
        let kinds = [
            EditKind::Density {
                rect,
                window_s,
                people_per_m2: 0.3,
            },
            EditKind::Flow {
                rect,
                window_s,
                velocity_m_s: (0.0, -1.0),
            },
            EditKind::Vorticity {
                rect,
                window_s,
                per_s: 0.5,
            },
        ];
        for kind in kinds {
            let name = kind.name();
            let (after, outcomes) = edit(&graph, &motion, &inputs(vec![edit_of(name, kind)]), &());
            let o = &outcomes[0];
            assert_eq!(o.patches, vec![p as u32], "{name}");
            assert!(o.after < o.before, "patch {p}, {name}: {o:?}");
            // People come: 82-101 % of what these patches can give (0.18-0.30 people/m2 of
            // 0.3; their plans have 0.06-0.24).
            if let Some(d) = o.density {
                assert!(
                    d.after > d.before && d.after >= 0.75 * d.attainable(),
                    "patch {p}: {d:?}"
                );
            }
            assert_kept(&graph, &motion, &after);
        }
    }
}

#[test]
fn no_edits_change_nothing() {
    let (graph, motion) = load(scene("lanes"));
    let (after, outcomes) = edit(&graph, &motion, &inputs(vec![]), &());
    assert!(outcomes.is_empty());
    assert_eq!(after, motion);
}

/// `crowd report DIR --json`.
fn report_json(dir: &Path) -> serde_json::Value {
    let out = crowd_ok(&["report", s(dir), "--json"]);
    serde_json::from_slice(&out.stdout).unwrap()
}

/// The text of `assets/pipelines/city-edits.ron` with `change` applied to it and its layer and
/// flow-map paths made absolute (so that a changed copy can live anywhere).
fn city_edits_text(change: impl Fn(String) -> String) -> String {
    let text = std::fs::read_to_string(scene_pipeline("city-edits")).unwrap();
    let shared = shared_scenes().canonicalize().unwrap();
    let map = root().join("assets/city/edit-turn.png");
    change(text.replace("../../../shared/scenes", s(&shared)))
        .replace("../city/edit-turn.png", s(&map))
}

/// Pipeline text with its `edits` replaced by `edits` (none: no `edits` field), or added
/// before the closing parenthesis when it has none.
fn with_edits(text: &str, edits: &[String]) -> String {
    let (head, tail) = match text.find("    edits: [") {
        Some(start) => {
            let end = text[start..].find("\n    ],\n").unwrap() + start + "\n    ],\n".len();
            (&text[..start], &text[end..])
        }
        None => text.split_at(text.rfind(')').unwrap()),
    };
    if edits.is_empty() {
        return format!("{head}{tail}");
    }
    format!(
        "{head}    edits: [\n        {},\n    ],\n{tail}",
        edits.join(",\n        ")
    )
}

#[test]
fn the_city_with_an_edit_of_each_kind_meets_them_and_ships_without_a_collision() {
    let out = scene("city-edits");
    let json = report_json(out);
    let edits = json["edits"].as_array().expect("report.json has the edits");
    assert_eq!(edits.len(), 5);
    for e in edits {
        let (before, after) = (e["before"].as_f64().unwrap(), e["after"].as_f64().unwrap());
        assert!(after < before, "{e}");
        if e["kind"] == "Meet" {
            assert!(after < 0.5, "{e}");
        }
        // The square fills to within 30 % of what it asks (0.059 -> 0.229 people/m2 for 0.3),
        // and the report warns where it is more than 15 % short. Walkers packed into a
        // square collide, and the ladder holds both of each pair on their plans: before it,
        // this edit's walks held 91 % of the target. What is left is sensitive to the
        // walks it starts from: with the same stage 6, the square moved by 0.5 m or its
        // window by 0.1 s reached 76-91 %; a stage 6 that changed two of the patch's 20
        // walkers a little, 73-91 % (BENCHMARKS.md, twenty-third part).
        if e["kind"] == "Density" {
            let d: DensityFigures = serde_json::from_value(e["density"].clone()).unwrap();
            assert!(d.after > d.before && d.reached(0.3), "{e}");
            let warned = !d.reached(crowd_moments::DENSITY_SHARE);
            assert_eq!(e.get("warning").is_some(), warned, "{e}");
        } else {
            assert!(e.get("warning").is_none(), "{e}");
        }
        // Its time, from `timings.ron`.
        assert!(e["seconds"].as_f64().is_some_and(|t| t > 0.0), "{e}");
    }
    assert_eq!(json["checked_stage"], "edit");
    for key in ["collisions", "library_collisions", "gltf_collisions"] {
        assert_eq!(json[key], 0, "{key}");
    }
    assert!(
        std::fs::read_to_string(out.join("report.md"))
            .unwrap()
            .contains("## Edits (stage 7)")
    );
    // Every entry, exit and band point as stage 6 left it.
    let (graph, smoothed) = load(out);
    let edited = TrajectoriesFile::load_stage(
        &out.join("edited.ron"),
        crowd_moments::STAGE,
        crowd_moments::VERSION,
    )
    .unwrap()
    .1;
    assert_ne!(edited, smoothed);
    assert_kept(&graph, &smoothed, &edited);
    // Each edit pictured before and after; an edit the pipeline does not have is refused.
    let dir = tempfile::tempdir().unwrap();
    let picture = dir.path().join("whirl.png");
    let pipeline = scene_pipeline("city-edits");
    let file = out.join("edited.ron");
    let args = [
        "render",
        s(&file),
        "--pipeline",
        s(&pipeline),
        "-o",
        s(&picture),
    ];
    crowd_ok(&[&args[..], &["--edit", "whirl"]].concat());
    let image = image::open(&picture).unwrap();
    assert!(image.width() > 500 && image.height() > 250);
    let err = crowd_err(&[&args[..], &["--edit", "tornado"]].concat());
    assert!(err.contains("no edit named `tornado`"), "{err}");
}

#[test]
fn changing_an_edit_reruns_only_the_edit_and_export_and_removing_them_all_drops_the_edit_file() {
    let dir = copy_of("city-edits");
    let build = |text: String| {
        let pipeline = dir.path().join("changed.ron");
        std::fs::write(&pipeline, text).unwrap();
        let out = crowd_ok(&[
            "build",
            "--pipeline",
            s(&pipeline),
            "--output",
            s(dir.path()),
        ]);
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr)
    };
    let said = build(city_edits_text(|t| t.replace("per_s: 0.5", "per_s: 0.4")));
    for stage in ["merge", "graph", "optimize", "match", "collide", "smooth"] {
        assert!(
            said.contains(&format!("{stage}: up to date, skipped")),
            "{stage}:\n{said}"
        );
    }
    for stage in ["edit", "export"] {
        assert!(
            said.contains(&format!("{stage}: built in")),
            "{stage}:\n{said}"
        );
    }
    let without = city_edits_text(|t| with_edits(&t, &[]));
    let said = build(without);
    assert!(said.contains("export: built in"), "{said}");
    assert!(!said.contains("edit: built"), "{said}");
    assert!(!dir.path().join("edited.ron").exists());
    assert!(!dir.path().join("edited.bin").exists());
    assert!(report_json(dir.path()).get("edits").is_none());
}

#[test]
fn a_bad_edit_is_refused_naming_it_and_leaves_no_folder() {
    let cases = [
        (
            r#"(name: "long", kind: Density(rect: (1, 1, 5, 5), window_s: (5, 30), people_per_m2: 0.2))"#,
            "at most one period",
        ),
        (
            r#"(name: "crammed", kind: Density(rect: (1, 1, 5, 5), window_s: (5, 8), people_per_m2: 2.0))"#,
            "optimize.rho_max",
        ),
        (
            r#"(name: "swirl", kind: Swirl(rect: (1, 1, 5, 5)))"#,
            "Swirl",
        ),
        (
            r#"(name: "far away", kind: Meet(at: (5000, 5), time_s: 3))"#,
            "not on the painted maps",
        ),
    ];
    for (edit, expected) in cases {
        let dir = tempfile::tempdir().unwrap();
        let pipeline = dir.path().join("pipeline.ron");
        let text = city_edits_text(|t| with_edits(&t, &[edit.to_string()]))
            .replace("../../build/city-edits", "out");
        std::fs::write(&pipeline, text).unwrap();
        let err = crowd_err(&["build", "--pipeline", s(&pipeline)]);
        assert!(err.contains(expected), "{edit}: {err}");
        assert!(
            err.contains("edits[0]") || err.contains("Swirl"),
            "{edit}: {err}"
        );
        assert!(
            !dir.path().join("out").exists(),
            "{edit}: a refused build left its folder"
        );
    }
}

/// A flow map painted in one colour asks what its vector asks: the same constraints, the same
/// edited motion, bit for bit.
#[test]
fn a_flow_map_of_one_colour_edits_as_its_vector_does() {
    let (graph, motion) = load(scene("city"));
    let p = busiest(&motion)[0];
    let side = graph.world.patch_side_m;
    let c = graph.world_from_patch(graph.patches[p].cell) + DVec2::splat(side / 2.0);
    let rect = (c.x - 2.5, c.y - 2.5, c.x + 2.5, c.y + 2.5);
    let window_s = (8.0, 10.0);
    let vector = EditKind::Flow {
        rect,
        window_s,
        velocity_m_s: (0.6, -0.8),
    };
    let painted = EditKind::FlowMap {
        rect,
        window_s,
        map: "south-east.png".into(),
        speed_m_s: 1.0,
    };
    let size = graph.world.size_m;
    let (w, h) = (size.x as u32, size.y as u32);
    let n = (w * h) as usize;
    let map = crowd_core::flow_map::VelocityMap {
        width: w,
        height: h,
        meters_per_pixel: 1.0,
        velocity: vec![DVec2::new(0.6, -0.8); n],
        weight: vec![1.0; n],
    };
    let (by_vector, was) = edit(
        &graph,
        &motion,
        &inputs(vec![edit_of("drift", vector)]),
        &(),
    );
    let mut with_map = inputs(vec![edit_of("drift", painted)]);
    with_map.flow_maps = vec![(0, std::sync::Arc::new(map))];
    let (by_map, is) = edit(&graph, &motion, &with_map, &());
    assert_eq!(was[0].patches, vec![p as u32]);
    assert!(was[0].after < was[0].before, "{:?}", was[0]);
    assert_eq!((was[0].before, was[0].after), (is[0].before, is[0].after));
    assert!(by_vector == by_map, "the edited motion differs");
}

/// A flow map that cannot be read, is damaged, or is not the layers' size is refused naming
/// the edit and the file, and the build leaves no folder.
#[test]
fn a_bad_flow_map_is_refused_naming_the_edit_and_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let turn = root().join("assets/city/edit-turn.png");
    let bytes = std::fs::read(&turn).unwrap();
    std::fs::write(dir.path().join("cut.png"), &bytes[..bytes.len() / 2]).unwrap();
    let mut small = Vec::new();
    image::RgbaImage::new(40, 40)
        .write_to(
            &mut std::io::Cursor::new(&mut small),
            image::ImageFormat::Png,
        )
        .unwrap();
    std::fs::write(dir.path().join("small.png"), small).unwrap();
    let cases = [
        ("missing.png", "edits[3].kind.map"),
        ("cut.png", "damaged or truncated"),
        ("small.png", "expected 400 x 400"),
    ];
    for (file, expected) in cases {
        let path = dir.path().join(file);
        let pipeline = dir.path().join("pipeline.ron");
        let text = city_edits_text(|t| t.replace("../city/edit-turn.png", s(&path)))
            .replace("../../build/city-edits", "out");
        std::fs::write(&pipeline, text).unwrap();
        let err = crowd_err(&["build", "-q", "--pipeline", s(&pipeline)]);
        assert!(err.contains(expected), "{file}: {err}");
        assert!(
            err.contains("corner turn") && err.contains(file),
            "{file}: {err}"
        );
        assert!(
            !dir.path().join("out").exists(),
            "{file}: a folder was left"
        );
    }
}

/// An edit over a city block (a cell no patch covers) edits nothing, and says so: a warning
/// on stderr and in the report, a failure under `--deny-warnings`.
#[test]
fn an_edit_over_no_patch_is_a_warning() {
    let (graph, _) = load(scene("city"));
    let side = graph.world.patch_side_m;
    let block = graph.dropped.blocked[0];
    let (x, y) = (f64::from(block.col) * side, f64::from(block.row) * side);
    let edit = format!(
        r#"(name: "in a wall", kind: Density(rect: ({}, {}, {}, {}), window_s: (5, 8), people_per_m2: 0.2))"#,
        x + 1.0,
        y + 1.0,
        x + side - 1.0,
        y + side - 1.0
    );
    let dir = tempfile::tempdir().unwrap();
    let pipeline = dir.path().join("pipeline.ron");
    let text = city_edits_text(|t| with_edits(&t, std::slice::from_ref(&edit)))
        .replace("../../build/city-edits", "out");
    std::fs::write(&pipeline, text).unwrap();
    let build = crowd(&["build", "-q", "--pipeline", s(&pipeline)]);
    let stderr = String::from_utf8_lossy(&build.stderr);
    assert!(build.status.success(), "{stderr}");
    assert!(
        stderr.contains("warning: edit \"in a wall\": it covers no patch"),
        "{stderr}"
    );
    let out = dir.path().join("out");
    let json = report_json(&out);
    assert_eq!(json["edits"][0]["patches"].as_array().unwrap().len(), 0);
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("it covers no patch"), "{md}");
    let stderr = crowd_broken(&["build", "-q", "--deny-warnings", "--pipeline", s(&pipeline)]);
    assert!(stderr.contains("--deny-warnings"), "{stderr}");
}

#[test]
fn crowd_edit_alone_writes_the_bytes_the_build_wrote() {
    let built = scene("city-edits");
    let dir = tempfile::tempdir().unwrap();
    let pipeline = dir.path().join("city-edits.ron");
    std::fs::write(&pipeline, city_edits_text(|t| t)).unwrap();
    let out = dir.path().join("edited.ron");
    let input = built.join("smoothed.ron");
    crowd_ok(&[
        "edit",
        "--pipeline",
        s(&pipeline),
        "-i",
        s(&input),
        "-o",
        s(&out),
    ]);
    for name in ["edited.ron", "edited.bin"] {
        let (a, b) = (
            std::fs::read(built.join(name)).unwrap(),
            std::fs::read(dir.path().join(name)).unwrap(),
        );
        assert!(a == b, "{name} differs from the build's");
    }
    // An experiment's flags belong to `--experiment`.
    let err = crowd_err(&["edit", "--pipeline", s(&pipeline), "--iterations", "3"]);
    assert!(
        err.contains("--iterations") && err.contains("--experiment"),
        "{err}"
    );
}

/// The largest change of any walker's velocity from one frame to the next (30 frames a
/// second over one period), m/s, as the runtime plays `library.crowd`: the jolt a player
/// shows.
fn largest_jolt(out: &Path) -> f64 {
    let lib =
        crowd_runtime::Library::from_bytes(&std::fs::read(out.join("library.crowd")).unwrap())
            .unwrap();
    let mut sampler = crowd_runtime::Sampler::new(&lib);
    let step = 1.0 / 30.0;
    let frames = (lib.period_s() / step).round() as usize;
    let (mut seen, mut at) = (Vec::new(), Vec::new());
    for f in 0..=frames + 1 {
        sampler.sample(f as f64 * step, [-1e9, -1e9, 1e9, 1e9], &mut seen);
        at.push(
            seen.iter()
                .filter(|c| u64::from(c.id) < lib.walkers())
                .map(|c| (c.id, DVec2::new(f64::from(c.x), f64::from(c.y))))
                .collect::<Vec<_>>(),
        );
    }
    let mut worst = 0.0f64;
    for w in at.windows(3) {
        for ((a, b), c) in w[0].iter().zip(&w[1]).zip(&w[2]) {
            assert!(
                a.0 == b.0 && b.0 == c.0,
                "the runtime keeps its walkers' order"
            );
            let jolt = ((c.1 - b.1) - (b.1 - a.1)).length() / step;
            worst = worst.max(jolt);
        }
    }
    worst
}

/// A small random painting (`crowd-paintings`, seeds 1 to 8, at most 8 patches) built, then
/// built again with one edit of each kind on its busiest patch (windows spread over the
/// period, the meeting where two walkers pass near each other): each residual falls, what
/// ships is clean, and no walker jolts more than it did unedited or than
/// [`crowd_moments::patch::MAX_JOLT`]. Before that bound, seed 1's hurried walker jolted by
/// 4.3 m/s from one frame to the next (1.9 unedited): the edited walk was the plan resampled
/// every 0.1 s, which turned its quick, finely sampled corners into single jumps.
#[test]
fn every_kind_of_edit_works_on_a_small_random_painting() {
    let dir = tempfile::tempdir().unwrap();
    let (mut edited_scenes, mut total) = (0, 0);
    for seed in 1..=8u64 {
        let painting = crowd_paintings::random(seed, crowd_paintings::Limits { max_patches: 8 });
        let scene = dir.path().join(format!("seed-{seed}"));
        let pipeline = painting.write(&scene).unwrap();
        let out = scene.join("out");
        if !crowd(&["build", "-q", "--pipeline", s(&pipeline)])
            .status
            .success()
        {
            continue;
        }
        let (graph, motion) = load(&out);
        let unedited_jolt = largest_jolt(&out);
        let p = busiest(&motion)[0];
        if motion[p].trajectories.len() < 6 {
            continue;
        }
        let period = TrajectoriesFile::load_stage(
            &out.join("smoothed.ron"),
            crowd_smooth::STAGE,
            crowd_smooth::VERSION,
        )
        .unwrap()
        .0
        .period_s;
        let side = graph.world.patch_side_m;
        let c = graph.world_from_patch(graph.patches[p].cell) + DVec2::splat(side / 2.0);
        let h = side * 0.3;
        let rect = format!("({}, {}, {}, {})", c.x - h, c.y - h, c.x + h, c.y + h);
        let window = |a: f64, b: f64| format!("({}, {})", a * period, b * period);
        let mut edits = vec![
            format!(
                "(name: \"fill\", kind: Density(rect: {rect}, window_s: {}, people_per_m2: 0.3))",
                window(0.40, 0.50)
            ),
            format!(
                "(name: \"drift\", kind: Flow(rect: {rect}, window_s: {}, velocity_m_s: (1.0, 0.0)))",
                window(0.65, 0.75)
            ),
            format!(
                "(name: \"whirl\", kind: Vorticity(rect: {rect}, window_s: {}, per_s: 0.5))",
                window(0.15, 0.25)
            ),
        ];
        if period >= 15.0
            && let Some((at, time)) = near_pair(&graph, &motion[p], p)
        {
            edits.push(format!(
                "(name: \"meet\", kind: Meet(at: ({}, {}), time_s: {time}))",
                at.x, at.y
            ));
        }
        let with = with_edits(&std::fs::read_to_string(&pipeline).unwrap(), &edits);
        std::fs::write(&pipeline, with).unwrap();
        crowd_ok(&["build", "-q", "--pipeline", s(&pipeline)]);
        let json = report_json(&out);
        let outcomes = json["edits"]
            .as_array()
            .expect("the report lists the edits");
        assert_eq!(outcomes.len(), edits.len(), "seed {seed}");
        for e in outcomes {
            let (before, after) = (e["before"].as_f64().unwrap(), e["after"].as_f64().unwrap());
            eprintln!(
                "seed {seed}: {} {before:.3} -> {after:.3} ({} iterations) {} {}",
                e["name"], e["iterations"], e["density"], e["warning"]
            );
            assert!(after < before, "seed {seed}: {e}");
            total += 1;
        }
        for key in ["library_collisions", "gltf_collisions"] {
            assert_eq!(json[key], 0, "seed {seed}: {key}");
        }
        let edited = TrajectoriesFile::load_stage(
            &out.join("edited.ron"),
            crowd_moments::STAGE,
            crowd_moments::VERSION,
        )
        .unwrap()
        .1;
        assert_kept_over(&graph, &motion, &edited, period);
        let jolt = largest_jolt(&out);
        eprintln!("seed {seed}: largest jolt {unedited_jolt:.3} m/s unedited, {jolt:.3} edited");
        assert!(
            jolt <= unedited_jolt.max(crowd_moments::patch::MAX_JOLT) + 0.01,
            "seed {seed}: a walker jolts by {jolt} m/s in a frame (unedited {unedited_jolt})"
        );
        edited_scenes += 1;
    }
    assert!(
        edited_scenes >= 2,
        "only {edited_scenes} small paintings had a busy patch to edit"
    );
    assert!(total >= 12, "only {total} edits tried");
}
