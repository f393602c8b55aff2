//! The check on what ships: `crowd build` checks `library.crowd` and `world.glb` after stage 8
//! (as an engine reads them) into `check.ron` and `report.md`, skips a check whose inputs are
//! unchanged, and `--no-check` leaves it out.

use crate::util::*;
use crowd_check::CheckReport;
use std::path::Path;

fn check_file(dir: &Path) -> CheckReport {
    let text = std::fs::read_to_string(dir.join("check.ron")).unwrap();
    ron::from_str(&text).unwrap()
}

/// The run's build of bands holds the figures of both shipped files: every walker and stander
/// of `export.ron` read back, the library played by the runtime's sampler without a jump, and
/// every figure in `crowd report --json` and `report.md`.
#[test]
fn a_build_checks_the_library_and_the_gltf_it_ships() {
    let out = scene("bands");
    let report = check_file(out);
    let export: crowd_export::ExportFile =
        ron::from_str(&std::fs::read_to_string(out.join("export.ron")).unwrap()).unwrap();
    let library = report.library.as_ref().expect("library figures");
    let gltf = report.gltf.as_ref().expect("glTF figures");
    assert_eq!(
        (library.walkers, library.loops),
        (export.walkers, export.loops)
    );
    assert_eq!(library.standers, export.standers);
    // bands ships the whole world in its glTF: a node per walker slot.
    assert_eq!((gltf.walkers, gltf.loops), (export.walkers, export.walkers));
    assert!((library.speed_limit_m_s - 1.8 * 1.05).abs() < 1e-12);
    for p in [library, gltf] {
        assert!(p.pieces > p.walkers && p.max_speed_m_s > 1.0, "{p:?}");
        assert!(p.min_clearance_m.is_finite(), "{p:?}");
    }
    // Every loop of the library closes on itself; the sampler shows no step beyond the
    // fastest piece.
    assert_eq!(library.open_loops, 0, "{library:?}");
    assert!(library.max_seam_gap_m < 1e-6 && library.max_border_gap_m.unwrap() < 1e-6);
    let sampled = library.sampled.as_ref().expect("the sampler played");
    assert_eq!((sampled.frames, sampled.jumps), (1000, 0), "{sampled:?}");

    let json: serde_json::Value =
        serde_json::from_slice(&crowd_ok(&["report", s(out), "--json"]).stdout).unwrap();
    for prefix in ["library", "gltf"] {
        for key in [
            "collisions",
            "min_clearance_m",
            "max_speed",
            "max_seam_velocity_jump",
        ] {
            let key = format!("{prefix}_{key}");
            assert!(json[&key].is_number(), "{key} in {json}");
        }
    }
    assert_eq!(json["library_sampler_jumps"], 0);
    assert!(json["stage_seconds"]["check"].as_f64().unwrap() > 0.0);
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    for row in [
        "## What ships",
        "| figure | `library.crowd` | `world.glb` |",
        "| largest speed (m/s) |",
        "| largest velocity jump at a seam (m/s) |",
        "| open loops (end 1 cm or more from any start) | 0 |",
        "| runtime's sampler: steps beyond the walker's fastest piece | 0 | - |",
        "| check |",
    ] {
        assert!(md.contains(row), "{row} in\n{md}");
    }
}

/// `--no-check` leaves the check out (and `report.md` says so); a build without it checks; a
/// build whose check inputs have not changed skips the check, and one whose `check.ron` came
/// from other inputs checks again.
#[test]
fn no_check_skips_the_check_and_an_unchanged_build_keeps_it() {
    let dir = copy_of("bands");
    let out = dir.path();
    std::fs::remove_file(out.join("check.ron")).unwrap();
    let pipeline = scene_pipeline("bands");
    let build = |extra: &[&str]| {
        let mut args = vec!["build", "--pipeline", s(&pipeline), "--output", s(out)];
        args.extend(extra);
        String::from_utf8_lossy(&crowd_ok(&args).stderr).into_owned()
    };
    let said = build(&["--no-check"]);
    assert!(
        !said.contains("check:") && !out.join("check.ron").exists(),
        "{said}"
    );
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("Not checked yet"), "{md}");

    let said = build(&[]);
    assert!(said.contains("check: done in"), "{said}");
    assert!(
        said.contains("library.crowd:") && said.contains("world.glb:"),
        "{said}"
    );
    assert_eq!(check_file(out), check_file(scene("bands")));
    let said = build(&[]);
    assert!(said.contains("check: up to date, skipped"), "{said}");

    // A check.ron of other inputs (here: of none recorded) is checked again.
    let mut old = check_file(out);
    old.input_hash = None;
    std::fs::write(out.join("check.ron"), ron::to_string(&old).unwrap()).unwrap();
    let said = build(&[]);
    assert!(said.contains("check: done in"), "{said}");
    assert_eq!(check_file(out), check_file(scene("bands")));
}

/// `crowd check` exits non-zero, naming each broken guarantee, when what ships breaks one:
/// here, against a pipeline that asks for slower turns (90 degrees a second) and a lower speed
/// limit than bands was built with. The same build checked against its own pipeline passes.
#[test]
fn crowd_check_fails_naming_every_broken_guarantee() {
    let dir = copy_of("bands");
    let out = dir.path();
    crowd_ok(&[
        "check",
        "-q",
        s(out),
        "--pipeline",
        s(&scene_pipeline("bands")),
    ]);
    let layer = shared_scenes().join("bands/density.png");
    let settings = tempfile::tempdir().unwrap();
    let strict = write_pipeline(
        settings.path(),
        &[("Density", &layer)],
        "    match: (max_speed: 1.5),\n    export: (turn_rate_deg_s: 90.0),\n",
    );
    let err = crowd_broken(&["check", "-q", s(out), "--pipeline", s(&strict)]);
    for said in [
        "4 guarantee(s) broken",
        "faster than 1.58 m/s",
        "degrees a second, above 90.9",
    ] {
        assert!(err.contains(said), "{said:?} not in: {err}");
    }
    assert!(
        err.contains("library.crowd") && err.contains("world.glb"),
        "{err}"
    );
    // What it found is written, for the report.
    let report = check_file(out);
    assert!(report.gltf.unwrap().turn_rate_limit_rad_s.unwrap() < 1.6);
}

/// What is judged is what stage 8 wrote: a `world.glb` changed after the build (one letter of
/// its JSON, still a valid glTF) fails `crowd check` and `crowd inspect export.ron`, both
/// naming the file and the manifest's size and hash.
#[test]
fn a_product_changed_after_the_build_fails_check_and_inspect() {
    let dir = copy_of("bands");
    let out = dir.path();
    let glb = out.join("world.glb");
    let mut bytes = std::fs::read(&glb).unwrap();
    let at = bytes
        .windows(b"walker_0".len())
        .position(|w| w == b"walker_0")
        .expect("a node name");
    bytes[at] = b'W';
    std::fs::write(&glb, &bytes).unwrap();
    let err = crowd_broken(&["check", "-q", s(out)]);
    assert!(
        err.contains("world.glb: is") && err.contains("export.ron names"),
        "{err}"
    );
    assert!(!err.contains("library.crowd: is"), "{err}");
    let err = crowd_err(&["inspect", s(&out.join("export.ron"))]);
    assert!(
        err.contains("world.glb: is") && err.contains("changed since stage 8 wrote it"),
        "{err}"
    );
}

/// The library judged from its file a part at a time (runs of trajectories, patches and loops
/// of a few thousand points, `crowd check` of a large library) comes to the same figures and
/// the same memo as the library judged whole in memory; and judged again from the file with
/// that memo, it plays and pairs nothing again.
#[test]
fn a_library_judged_from_its_file_a_part_at_a_time_is_judged_as_in_memory() {
    use crowd_check::library::{InFile, Inputs, Source, figures_memo, judge};
    use crowd_check::memo::{Memo, Recalled};
    for name in ["city", "ring"] {
        let dir = scene(name);
        let path = dir.join("library.crowd");
        let lib = crowd_runtime::Library::from_bytes(&std::fs::read(&path).unwrap()).unwrap();
        let graph = crowd_core::PatchGraph::load(&dir.join("graph.ron")).unwrap();
        let walls = crowd_check::walls(&graph);
        let inputs = Inputs {
            walls: &walls,
            speed_limit_m_s: 1.8 * 1.05,
            sample_step_s: Some(0.02),
        };
        let whole = figures_memo(&lib, &inputs, &Recalled::default());
        let memo_bytes = |part| Memo::of(None, Some(part)).to_bytes();
        let (figures, memo) = (whole.figures, memo_bytes(whole.memo));
        for budget in [1 << 12, 1 << 15] {
            let file = crowd_runtime::LibraryFile::open(std::fs::File::open(&path).unwrap());
            let src = InFile {
                file: file.unwrap(),
                budget,
            };
            assert!(src.points() > 4 * budget, "{name}: more than a few parts");
            let parts = judge(&src, &inputs, &Recalled::default()).unwrap();
            assert_eq!(parts.figures, figures, "{name}, {budget} points at a time");
            assert_eq!(
                memo_bytes(parts.memo),
                memo,
                "{name}, {budget} points at a time"
            );
            let recalled = Memo::from_bytes(&memo).unwrap().recall();
            let again = judge(&src, &inputs, &recalled).unwrap();
            assert_eq!((again.redone, again.replayed), (0, 0), "{name}");
            assert_eq!(again.figures, figures, "{name}");
        }
    }
}

/// A large world's check judges the stage file first, writes its part of the memo and lets it
/// go, then judges the shipped files (`CheckOptions::at_once`): the same `check.ron` and
/// `check.memo`, to the byte, as the check that judges them at once, from nothing and again
/// with the memo it wrote.
#[test]
fn a_check_one_part_after_the_other_writes_what_one_at_once_writes() {
    use crowd::check::{CheckOptions, check};
    for name in ["city", "ring"] {
        let pipeline = crowd_core::config::PipelineFile::load(&scene_pipeline(name)).unwrap();
        let judged = |at_once: bool| {
            let dir = copy_of(name);
            for file in ["check.ron", "check.memo"] {
                std::fs::remove_file(dir.path().join(file)).unwrap();
            }
            let options = CheckOptions {
                max_speed: pipeline.pipeline.matching.max_speed,
                turn_rate_deg_s: pipeline.pipeline.export.turn_rate_deg_s,
                at_once: Some(at_once),
                ..CheckOptions::default()
            };
            let read = |file: &str| std::fs::read(dir.path().join(file)).unwrap();
            let (_, _, from_nothing) = check(dir.path(), &options).unwrap();
            let first = (read("check.ron"), read("check.memo"));
            let (_, _, again) = check(dir.path(), &options).unwrap();
            assert_eq!(
                (read("check.ron"), read("check.memo")),
                first,
                "{name}: again"
            );
            (first, from_nothing, again)
        };
        let (at_once, one_after) = (judged(true), judged(false));
        assert!(
            at_once.0 == one_after.0,
            "{name}: check.ron and check.memo differ"
        );
        for (what, redone) in [("from nothing", &one_after.1), ("again", &one_after.2)] {
            let n = redone.stage_own.1;
            assert!(n > 0, "{name}: patches");
            let expected = if what == "again" { 0 } else { n };
            assert_eq!(
                redone.stage_own.0, expected,
                "{name} {what}: own shares judged"
            );
        }
    }
}
