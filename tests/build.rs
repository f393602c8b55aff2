//! The build driver: reruns only what is stale, and writes the same bytes on any thread count.

use crate::util::*;
use std::path::Path;

/// Copies the city demo into `dir` and returns the pipeline path.
fn city_copy(dir: &Path) -> std::path::PathBuf {
    let assets = dir.join("city");
    std::fs::create_dir_all(&assets).unwrap();
    for layer in ["density", "static", "direction", "obstacles"] {
        std::fs::copy(
            shared_scenes().join("city").join(format!("{layer}.png")),
            assets.join(format!("{layer}.png")),
        )
        .unwrap();
    }
    let text = std::fs::read_to_string(root().join("pipeline.ron"))
        .unwrap()
        .replace("assets/city/", "city/")
        .replace("\"build/city\"", "\"out\"");
    let path = dir.join("pipeline.ron");
    std::fs::write(&path, text).unwrap();
    path
}

fn stderr_of(args: &[&str]) -> String {
    String::from_utf8_lossy(&crowd_ok(args).stderr).into_owned()
}

/// The run's city build, copied beside copies of its layers and another pipeline file (the
/// city demo's `pipeline.ron`, which states the default settings): a build reruns nothing, since
/// a stage file is tied to the contents of its inputs, not to their paths or times. An edited
/// layer reruns merge and graph; a graph setting the graph alone.
#[test]
fn a_build_over_the_same_inputs_reruns_nothing_and_an_edited_layer_reruns_merge_and_graph() {
    let dir = tempfile::tempdir().unwrap();
    let pipeline = city_copy(dir.path());
    let p = s(&pipeline);
    let out = dir.path().join("out");
    copy_files(scene("city"), &out);
    let before = snapshot(&out);

    let again = stderr_of(&["build", "--pipeline", p]);
    for stage in [
        "merge", "graph", "optimize", "match", "collide", "smooth", "export",
    ] {
        assert!(again.contains(&format!("{stage}: up to date")), "{again}");
    }
    assert!(!again.contains("built"), "{again}");
    assert!(
        snapshot(&out) == before,
        "a build that reran nothing changed files"
    );

    // From here on, the first two stages alone. The later files stay, built from the old
    // graph: a build until the graph neither reads them nor reports them as its own.
    let before = snapshot(&out);

    // Paint one more pixel of walker density.
    let density = dir.path().join("city/density.png");
    let mut image = image::open(&density).unwrap().to_luma8();
    let (x, y) = (1, 1);
    let old = image.get_pixel(x, y)[0];
    image.put_pixel(x, y, image::Luma([old.wrapping_add(40)]));
    image.save(&density).unwrap();
    let edited = stderr_of(&["build", "--pipeline", p, "--until", "graph"]);
    assert!(
        edited.contains("merge: built") && edited.contains("graph: built"),
        "{edited}"
    );
    let after = snapshot(&out);
    let changed: Vec<&str> = after
        .iter()
        .filter(|file| !before.contains(file))
        .map(|(name, _)| name.as_str())
        .collect();
    assert!(
        !changed.is_empty()
            && changed
                .iter()
                .all(|n| n.starts_with("merge.") || *n == "graph.ron" || n.starts_with("report_")),
        "a build until the graph changed {changed:?}"
    );
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        !report.contains("(report_patterns.png)") && report.contains("Not checked yet"),
        "the report of a build until the graph shows the old later stages:\n{report}"
    );

    // A graph setting alone reruns only the graph.
    let text = std::fs::read_to_string(&pipeline).unwrap();
    std::fs::write(
        &pipeline,
        text.replace("blocked_above: 0.8", "blocked_above: 0.7"),
    )
    .unwrap();
    let setting = stderr_of(&["build", "--pipeline", p, "--until", "graph"]);
    assert!(
        setting.contains("merge: up to date") && setting.contains("graph: built"),
        "{setting}"
    );
}

/// Every output file, byte for byte, on one thread and on several: city and ring built whole,
/// with the check a build runs after stage 8 (`check.ron`), and painting's first two stages. The run's builds ([`scene`]) use
/// [`CACHE_THREADS`] (at least 2) worker threads; this test builds again on one.
#[test]
fn one_and_two_threads_write_identical_files() {
    let dir = tempfile::tempdir().unwrap();
    let threads = CACHE_THREADS.to_string();
    for (name, until) in [
        ("city", "export"),
        ("ring", "export"),
        ("painting", "graph"),
    ] {
        let pipeline = scene_pipeline(name);
        let one = dir.path().join(format!("{name}-1"));
        crowd_ok(&[
            "--threads",
            "1",
            "build",
            "-q",
            "--pipeline",
            s(&pipeline),
            "--output",
            s(&one),
            "--until",
            until,
        ]);
        // A build to export checks what it made too (`check.ron`).
        let many = scene(name);
        let a = snapshot(&one);
        // The files the one-thread build wrote (painting's run build holds more).
        let b: Vec<_> = snapshot(many)
            .into_iter()
            .filter(|(n, _)| a.iter().any(|(m, _)| m == n))
            .collect();
        let names = |v: &[(String, Vec<u8>)]| v.iter().map(|f| f.0.clone()).collect::<Vec<_>>();
        assert_eq!(names(&a), names(&b), "{name}");
        let expected: &[&str] = if until == "export" {
            &[
                "merge.bin",
                "graph.ron",
                "patterns.bin",
                "trajectories.bin",
                "collided.bin",
                "smoothed.bin",
                "export.ron",
                "library.crowd",
                "world.glb",
                "check.ron",
                "report_patch.png",
            ]
        } else {
            &[
                "merge.ron",
                "merge.bin",
                "graph.ron",
                "report_maps.png",
                "report_graph.png",
            ]
        };
        for file in expected {
            assert!(
                names(&a).iter().any(|n| n == file),
                "{name}: no {file} in {:?}",
                names(&a)
            );
        }
        let differ: Vec<&str> = a
            .iter()
            .zip(&b)
            .filter(|(x, y)| x.1 != y.1)
            .map(|(x, _)| x.0.as_str())
            .collect();
        assert!(
            differ.is_empty(),
            "{name}: 1 and {threads} threads write different {differ:?}"
        );
    }
}

#[test]
fn sixteen_bit_layers_merge_like_their_eight_bit_originals() {
    let dir = tempfile::tempdir().unwrap();
    let d8 = shared_scenes().join("city/density.png");
    let d16 = dir.path().join("density16.png");
    let img = image::open(&d8).unwrap().to_luma8();
    let wide =
        image::ImageBuffer::<image::Luma<u16>, _>::from_fn(img.width(), img.height(), |x, y| {
            image::Luma([img.get_pixel(x, y)[0] as u16 * 257])
        });
    wide.save(&d16).unwrap();
    let graph_of = |layer: &Path, sub: &str| {
        let sub_dir = dir.path().join(sub);
        std::fs::create_dir_all(&sub_dir).unwrap();
        let pipeline = write_pipeline(&sub_dir, &[("Density", layer)], "");
        crowd_ok(&["build", "-q", "--pipeline", s(&pipeline)]);
        crowd_core::PatchGraph::load(&sub_dir.join("out/graph.ron")).unwrap()
    };
    let (g8, g16) = (graph_of(&d8, "eight"), graph_of(&d16, "sixteen"));
    assert_eq!(g8.patches.len(), g16.patches.len());
    for (a, b) in g8.patches.iter().zip(&g16.patches) {
        assert!((a.walker_density - b.walker_density).abs() < 1e-6);
    }
    let merged = String::from_utf8(
        crowd_ok(&["inspect", s(&dir.path().join("sixteen/out/merge.ron"))]).stdout,
    )
    .unwrap();
    assert!(merged.contains("gray 16-bit"), "{merged}");
}

#[test]
fn report_prints_the_figures_as_json() {
    let out = scene("city");
    let json: serde_json::Value =
        serde_json::from_slice(&crowd_ok(&["report", s(out), "--json"]).stdout).unwrap();
    assert_eq!(json["walkers_requested"], 5000);
    assert_eq!(json["standers_requested"], 160);
    assert_eq!(json["components"], 1);
    assert!(json["patches"].as_u64().unwrap() > 1000);
    for stage in ["merge", "graph"] {
        assert!(
            json["stage_seconds"][stage].as_f64().unwrap() > 0.0,
            "{json}"
        );
    }
    let text = String::from_utf8(crowd_ok(&["inspect", s(&out.join("graph.ron"))]).stdout).unwrap();
    assert!(
        text.contains("components: 1") && text.contains("partly closed"),
        "{text}"
    );
}

#[test]
fn a_build_writes_a_report_with_every_stage_its_cost_its_outputs_and_pictures() {
    let dir = copy_of("bands");
    let out = dir.path();
    // The build checked what it made; `crowd check` writes the report again.
    let built = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(!built.contains("Not checked yet"), "{built}");
    crowd_ok(&["check", s(out)]);
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(!md.contains("Not checked yet"), "{md}");
    for figure in [
        "| E_rho |",
        "| collisions | 0 |",
        "| smallest clearance (m) |",
        "| acceleration p95 (m/s2) |",
        "| walkers | 1105 |",
        "| worst position error (m) |",
        "| **all stages** |",
        "| `library.crowd` | 1.1 MB |",
        "| `world.glb` |",
    ] {
        assert!(md.contains(figure), "{figure} in\n{md}");
    }
    // A row per stage: wall time and (on Linux) a peak of at least a megabyte.
    for stage in [
        "merge", "graph", "optimize", "match", "collide", "smooth", "export",
    ] {
        let row = md
            .lines()
            .find(|l| l.starts_with(&format!("| {stage} |")))
            .unwrap_or_else(|| panic!("no {stage} row in\n{md}"));
        let peak = row.split('|').nth(3).unwrap().trim();
        if cfg!(target_os = "linux") {
            assert!(peak.parse::<f64>().unwrap() >= 1.0, "{row}");
        }
    }
    for picture in [
        "report_maps.png",
        "report_graph.png",
        "report_patterns.png",
        "report_patch.png",
    ] {
        assert!(md.contains(&format!("]({picture})")), "{picture}");
        let png = image::open(out.join(picture)).unwrap();
        assert!(png.width() > 100 && png.height() > 100, "{picture}");
    }
    let json: serde_json::Value =
        serde_json::from_slice(&crowd_ok(&["report", s(out), "--json"]).stdout).unwrap();
    assert!(
        json["stage_peak_mb"]["export"].as_f64().unwrap() >= 1.0,
        "{json}"
    );
    assert_eq!(
        json["output_bytes"]["library.crowd"].as_u64().unwrap(),
        std::fs::metadata(out.join("library.crowd")).unwrap().len()
    );
}

#[test]
fn stages_run_one_at_a_time_write_the_same_files_as_a_build() {
    let dir = tempfile::tempdir().unwrap();
    let pipeline = scene_pipeline("bands");
    let p = s(&pipeline);
    let (a, b) = (scene("bands"), dir.path().join("staged"));
    std::fs::create_dir_all(&b).unwrap();
    let f = |name: &str| b.join(name);
    crowd_ok(&["merge", "-q", "--pipeline", p, "-o", s(&f("merge.ron"))]);
    crowd_ok(&[
        "graph",
        "-q",
        "--pipeline",
        p,
        "-i",
        s(&f("merge.ron")),
        "-o",
        s(&f("graph.ron")),
    ]);
    crowd_ok(&[
        "optimize",
        "-q",
        "--pipeline",
        p,
        "-i",
        s(&f("graph.ron")),
        "-o",
        s(&f("patterns.ron")),
    ]);
    crowd_ok(&[
        "match",
        "-q",
        "--pipeline",
        p,
        "-i",
        s(&f("patterns.ron")),
        "-o",
        s(&f("trajectories.ron")),
    ]);
    crowd_ok(&[
        "collide",
        "-q",
        "--pipeline",
        p,
        "-i",
        s(&f("trajectories.ron")),
        "-o",
        s(&f("collided.ron")),
    ]);
    crowd_ok(&[
        "smooth",
        "-q",
        "--pipeline",
        p,
        "-i",
        s(&f("collided.ron")),
        "-o",
        s(&f("smoothed.ron")),
    ]);
    crowd_ok(&[
        "export",
        "-q",
        "--pipeline",
        p,
        "-i",
        s(&f("smoothed.ron")),
        "-o",
        s(&f("export.ron")),
    ]);
    // The check a build runs after stage 8, run by hand on the same pipeline.
    crowd_ok(&["check", "-q", s(&b), "--pipeline", p]);
    crowd_ok(&["report", s(&b), "--markdown"]);
    let (built, staged) = (snapshot(a), snapshot(&b));
    let names = |v: &[(String, Vec<u8>)]| v.iter().map(|f| f.0.clone()).collect::<Vec<_>>();
    assert_eq!(names(&built), names(&staged));
    for (x, y) in built.iter().zip(&staged) {
        assert!(x.1 == y.1, "{} differs", x.0);
    }
}

#[test]
fn a_second_build_into_a_locked_folder_waits_for_the_first_and_clears_its_leftovers() {
    let dir = copy_of("bands");
    let out = dir.path();
    let pipeline = root().join("assets/pipelines/bands.ron");
    // What a build killed while writing leaves: a temporary file.
    let stale = out.join(".graph.ron.tmp4194304");
    std::fs::write(&stale, b"half a graph").unwrap();
    // Another build holds the folder (this test, through the same kind of lock).
    let held = std::fs::File::create(out.join(".crowd.lock")).unwrap();
    held.lock().unwrap();
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_crowd"))
        .args(["build", "--pipeline", s(&pipeline), "--output", s(out)])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = std::io::BufReader::new(child.stderr.take().unwrap());
    let mut first = String::new();
    std::io::BufRead::read_line(&mut stderr, &mut first).unwrap();
    assert!(
        first.starts_with("waiting: ") && first.contains(s(out)),
        "{first}"
    );
    assert!(
        stale.exists(),
        "nothing is touched while the other holds the folder"
    );
    held.unlock().unwrap();
    let status = child.wait().unwrap();
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut stderr, &mut rest).unwrap();
    assert!(status.success(), "{rest}");
    assert!(!stale.exists(), "the stale temporary file is removed");
}

#[test]
fn a_stage_file_cut_short_or_edited_by_hand_is_said_and_rebuilt() {
    let dir = copy_of("bands");
    let out = dir.path();
    let pipeline = root().join("assets/pipelines/bands.ron");
    let graph = out.join("graph.ron");
    let written = std::fs::read(&graph).unwrap();
    let text = String::from_utf8(written.clone()).unwrap();
    // Cut after its header (which still matches), and edited (one patch's density).
    let cut = &text[..text.find("  patches:").unwrap()];
    let at = text.find("walker_density: ").unwrap() + "walker_density: ".len();
    let edited = format!("{}9{}", &text[..at], &text[at + 1..]);
    for (what, body) in [("cut", cut.to_string()), ("edited", edited)] {
        std::fs::write(&graph, &body).unwrap();
        let build = crowd(&["build", "--pipeline", s(&pipeline), "--output", s(out)]);
        let stderr = String::from_utf8_lossy(&build.stderr);
        assert!(build.status.success(), "{what}: {stderr}");
        assert!(
            stderr.contains("graph.ron is not as stage graph wrote it"),
            "{what}: {stderr}"
        );
        assert!(stderr.contains("graph: built"), "{what}: {stderr}");
        assert_eq!(
            std::fs::read(&graph).unwrap(),
            written,
            "{what}: rebuilt as it was"
        );
        assert!(stderr.contains("optimize: up to date"), "{what}: {stderr}");
    }
}

/// Every file of a folder with its bytes and modification time, sorted by name (the lock file
/// included: even it is not written again).
fn stamped(dir: &Path) -> Vec<(String, Vec<u8>, std::time::SystemTime)> {
    let mut files: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .map(|p| {
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(&p).unwrap(),
                std::fs::metadata(&p).unwrap().modified().unwrap(),
            )
        })
        .collect();
    files.sort();
    files
}

/// Up to date means read-only: a second build with nothing stale leaves every file's bytes
/// and modification time alone (report and timings included), adds none, and succeeds in a
/// folder it may not write in.
#[test]
fn an_up_to_date_build_writes_nothing_and_succeeds_in_a_read_only_folder() {
    use std::os::unix::fs::PermissionsExt;
    let dir = copy_of("bands");
    let out = dir.path();
    let pipeline = scene_pipeline("bands");
    let build = || crowd_ok(&["build", "--pipeline", s(&pipeline), "--output", s(out)]);
    build();
    let before = stamped(out);
    std::thread::sleep(std::time::Duration::from_millis(20));
    let said = String::from_utf8_lossy(&build().stderr).into_owned();
    assert!(!said.contains("built"), "{said}");
    assert!(stamped(out) == before, "an up-to-date build wrote: {said}");

    std::fs::set_permissions(out, std::fs::Permissions::from_mode(0o555)).unwrap();
    // Root writes anyway; then the folder is not read-only and the run below proves less.
    let probe = out.join("probe");
    let privileged = std::fs::write(&probe, b"").is_ok();
    let _ = std::fs::remove_file(&probe);
    let result = crate::util::crowd(&["build", "--pipeline", s(&pipeline), "--output", s(out)]);
    std::fs::set_permissions(out, std::fs::Permissions::from_mode(0o755)).unwrap();
    assert!(
        result.status.success(),
        "read-only folder (privileged: {privileged}): {}",
        String::from_utf8_lossy(&result.stderr)
    );
    assert!(stamped(out) == before);
}

/// A reader of stderr gone (`crowd build 2>&1 | head -1`) loses the build's lines, not the
/// build: it runs to the end, exit 0, and writes its files.
#[test]
fn a_build_whose_stderr_is_closed_still_builds() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_crowd"))
        .args([
            "build",
            "--no-check",
            "--pipeline",
            s(&scene_pipeline("bands")),
            "--output",
        ])
        .arg(&out)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("crowd runs");
    drop(child.stderr.take());
    let status = child.wait().expect("crowd ends");
    assert_eq!(status.code(), Some(0), "a closed stderr ended the build");
    assert!(out.join("library.crowd").exists() && out.join("world.glb").exists());
}
