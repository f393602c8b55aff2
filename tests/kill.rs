//! kill -9 at any moment of a build leaves a folder the next build recovers from: the folder
//! holds one build's files (seed 1's, over which a build of seed 2 was killed, or seed 2's
//! when the kill came after its last write), the next build of seed 2 ends with exactly the
//! bytes of a clean build of seed 2, no temporary file is left, and `crowd check` passes.

use crate::settings::broken;
use crate::util::*;
use std::path::Path;
use std::time::{Duration, Instant};

const LANES: &str = "assets/pipelines/lanes.ron";
/// Kills per stage window (merge ... export, then the check and report).
const PER_WINDOW: usize = 3;

/// Files of a build folder that are neither the lock nor outputs: what a killed write leaves.
fn temporaries(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.unwrap().file_name().into_string().ok())
        .filter(|n| n.starts_with('.') && n != ".crowd.lock")
        .collect()
}

/// When each stage of a build starts and ends, seconds from the start (from `timings.ron`,
/// in the table's order, the check last).
fn windows(dir: &Path) -> Vec<(String, f64, f64)> {
    let text = std::fs::read_to_string(dir.join("timings.ron")).unwrap();
    let timings: std::collections::BTreeMap<String, (f64, Option<f64>)> = {
        #[derive(serde::Deserialize)]
        struct Run {
            seconds: f64,
            peak_mb: Option<f64>,
        }
        let runs: std::collections::BTreeMap<String, Run> = ron::from_str(&text).unwrap();
        runs.into_iter()
            .map(|(k, r)| (k, (r.seconds, r.peak_mb)))
            .collect()
    };
    let mut at = 0.0;
    [
        "merge", "graph", "optimize", "match", "collide", "smooth", "export", "check",
    ]
    .iter()
    .map(|&name| {
        let d = timings.get(name).map_or(0.0, |t| t.0);
        let w = (name.to_string(), at, at + d);
        at += d;
        w
    })
    .collect()
}

#[test]
fn a_build_killed_at_any_moment_leaves_a_folder_the_next_build_recovers() {
    let dir = tempfile::tempdir().unwrap();
    for sub in ["one", "two"] {
        std::fs::create_dir_all(dir.path().join(sub)).unwrap();
    }
    let (one, _) = broken(&dir.path().join("one"), LANES, "seed", "1");
    let (two, _) = broken(&dir.path().join("two"), LANES, "seed", "2");
    let (ref1, ref2) = (dir.path().join("ref1"), dir.path().join("ref2"));
    let build = |pipeline: &Path, out: &Path| {
        crowd_ok(&["build", "-q", "--pipeline", s(pipeline), "--output", s(out)]);
    };
    build(&one, &ref1);
    let start = Instant::now();
    build(&two, &ref2);
    let whole = start.elapsed().as_secs_f64();
    let (first, second) = (snapshot(&ref1), snapshot(&ref2));
    assert!(first != second, "two seeds, two crowds");
    // Kill times inside each stage's window of the clean build (the process's start-up, a
    // few ms, comes before merge: the first kills land in it or in merge and graph).
    let windows = windows(&ref2);
    let stages_time: f64 = windows.last().unwrap().2;
    let mut kills: Vec<(String, f64)> = Vec::new();
    for (name, a, b) in &windows {
        for k in 0..PER_WINDOW {
            let f = (k as f64 + 0.5) / PER_WINDOW as f64;
            kills.push((name.clone(), a + f * (b - a)));
        }
    }
    // The writes and the report come after the stages' time.
    kills.push((
        "writes".into(),
        stages_time + 0.5 * (whole - stages_time).max(0.0),
    ));
    kills.push(("end".into(), whole * 0.98));
    assert!(kills.len() >= 20);

    let mut failed = Vec::new();
    let mut mixed_before = 0;
    for (stage, at) in &kills {
        let folder = tempfile::tempdir().unwrap();
        let out = folder.path();
        copy_files(&ref1, out);
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_crowd"))
            .args(["build", "-q", "--pipeline", s(&two), "--output", s(out)])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_secs_f64(*at));
        let _ = child.kill(); // SIGKILL
        let _ = child.wait();
        // Killed: every file is whole, of one build or the other (stage files may be of
        // either, each tied to its inputs by its header).
        let now = snapshot(out);
        if now != first && now != second {
            mixed_before += 1;
        }
        let again = crowd(&["build", "-q", "--pipeline", s(&two), "--output", s(out)]);
        let case = format!("killed in {stage} at {at:.3} s");
        if !again.status.success() {
            failed.push(format!(
                "{case}: the next build failed: {}",
                String::from_utf8_lossy(&again.stderr)
            ));
            continue;
        }
        if snapshot(out) != second {
            failed.push(format!(
                "{case}: the next build's files are not a clean build's"
            ));
        }
        let left = temporaries(out);
        if !left.is_empty() {
            failed.push(format!("{case}: temporaries left: {left:?}"));
        }
        let check = crowd(&["check", "-q", s(out)]);
        if !check.status.success() {
            failed.push(format!(
                "{case}: check failed: {}",
                String::from_utf8_lossy(&check.stderr)
            ));
        }
    }
    println!(
        "{} kills over a {whole:.2} s build; {mixed_before} left stage files of both builds \
         (each rebuilt by the next build)",
        kills.len()
    );
    assert!(failed.is_empty(), "{}", failed.join("\n"));
}
