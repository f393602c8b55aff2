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

#[test]
fn a_second_build_reruns_nothing_and_an_edited_layer_reruns_merge_and_graph() {
    let dir = tempfile::tempdir().unwrap();
    let pipeline = city_copy(dir.path());
    let p = s(&pipeline);
    let first = stderr_of(&["build", "--pipeline", p]);
    assert!(
        first.contains("merge: built") && first.contains("graph: built"),
        "{first}"
    );
    let out = dir.path().join("out");
    let before = snapshot(&out);

    let second = stderr_of(&["build", "--pipeline", p]);
    assert!(
        second.contains("merge: up to date") && second.contains("graph: up to date"),
        "{second}"
    );
    assert_eq!(snapshot(&out), before);

    // Paint one more pixel of walker density.
    let density = dir.path().join("city/density.png");
    let mut image = image::open(&density).unwrap().to_luma8();
    let (x, y) = (1, 1);
    let old = image.get_pixel(x, y)[0];
    image.put_pixel(x, y, image::Luma([old.wrapping_add(40)]));
    image.save(&density).unwrap();
    let third = stderr_of(&["build", "--pipeline", p]);
    assert!(
        third.contains("merge: built") && third.contains("graph: built"),
        "{third}"
    );
    assert_ne!(snapshot(&out), before);

    // A graph setting alone reruns only the graph.
    let text = std::fs::read_to_string(&pipeline).unwrap();
    std::fs::write(
        &pipeline,
        text.replace("blocked_above: 0.8", "blocked_above: 0.7"),
    )
    .unwrap();
    let fourth = stderr_of(&["build", "--pipeline", p]);
    assert!(
        fourth.contains("merge: up to date") && fourth.contains("graph: built"),
        "{fourth}"
    );
}

#[test]
fn one_and_two_threads_write_identical_files() {
    let dir = tempfile::tempdir().unwrap();
    for (name, until, files) in [
        // Stage files, and the report's pictures of them.
        ("city", "match", 8 + 4),
        ("ring", "match", 8 + 4),
        ("painting", "graph", 3 + 2),
    ] {
        let pipeline = scene_pipeline(name);
        let (a, b) = (
            dir.path().join(format!("{name}-1")),
            dir.path().join(format!("{name}-2")),
        );
        for (threads, out) in [("1", &a), ("2", &b)] {
            let p = s(&pipeline);
            crowd_ok(&[
                "--threads",
                threads,
                "build",
                "-q",
                "--pipeline",
                p,
                "--output",
                s(out),
                "--until",
                until,
            ]);
        }
        let (sa, sb) = (snapshot(&a), snapshot(&b));
        assert_eq!(
            sa.len(),
            files,
            "{name}: {:?}",
            sa.iter().map(|f| &f.0).collect::<Vec<_>>()
        );
        assert!(sa == sb, "{name}: 1 and 2 threads differ");
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
    let (_dir, out) = build_shared_scene("city", "match");
    let json: serde_json::Value =
        serde_json::from_slice(&crowd_ok(&["report", s(&out), "--json"]).stdout).unwrap();
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
    let (_dir, out) = build_shared_scene("bands", "export");
    let unchecked = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        unchecked.contains("Not checked yet: run `crowd check"),
        "{unchecked}"
    );
    crowd_ok(&["check", s(&out)]);
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(!md.contains("Not checked yet"), "{md}");
    for figure in [
        "| E_rho |",
        "| collisions | 0 |",
        "| smallest clearance (m) |",
        "| acceleration p95 (m/s2) |",
        "| walkers | 1102 |",
        "| worst position error (m) |",
        "| **all stages** |",
        "| `library.crowd` | 839.2 kB |",
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
        serde_json::from_slice(&crowd_ok(&["report", s(&out), "--json"]).stdout).unwrap();
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
    let (a, b) = (dir.path().join("built"), dir.path().join("staged"));
    crowd_ok(&["build", "-q", "--pipeline", p, "--output", s(&a)]);
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
    crowd_ok(&["report", s(&b), "--markdown"]);
    let (built, staged) = (snapshot(&a), snapshot(&b));
    let names = |v: &[(String, Vec<u8>)]| v.iter().map(|f| f.0.clone()).collect::<Vec<_>>();
    assert_eq!(names(&built), names(&staged));
    for (x, y) in built.iter().zip(&staged) {
        assert!(x.1 == y.1, "{} differs", x.0);
    }
}
