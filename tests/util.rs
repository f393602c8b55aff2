//! Helpers shared by the end-to-end tests.

use std::path::{Path, PathBuf};
use std::process::Output;

/// The workspace root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `../shared/scenes`, beside the repository.
pub fn shared_scenes() -> PathBuf {
    let scenes = root().join("../shared/scenes");
    assert!(
        scenes.is_dir(),
        "the tests read the painted scenes of ../shared/scenes beside the repository; {} is missing",
        scenes.display()
    );
    scenes
}

/// Names of the shared scenes.
pub fn scene_names() -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(shared_scenes())
        .expect("../shared/scenes is readable")
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert!(
        names.len() >= 6,
        "expected the shared scenes, found {names:?}"
    );
    names
}

/// The pipeline shipped for a shared scene.
pub fn scene_pipeline(name: &str) -> PathBuf {
    root().join("assets/pipelines").join(format!("{name}.ron"))
}

/// Builds a shared scene up to `until` (a stage name) into a new temporary folder; returns it
/// and the build folder in it.
pub fn build_shared_scene(name: &str, until: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let pipeline = scene_pipeline(name);
    let (p, o) = (s(&pipeline), s(&out));
    crowd_ok(&[
        "build",
        "-q",
        "--pipeline",
        p,
        "--output",
        o,
        "--until",
        until,
    ]);
    (dir, out)
}

/// Runs `crowd` with `args`.
pub fn crowd(args: &[&str]) -> Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_crowd"))
        .args(args)
        .output()
        .expect("crowd runs")
}

/// Runs `crowd` and insists that it succeeds.
pub fn crowd_ok(args: &[&str]) -> Output {
    let out = crowd(args);
    assert!(
        out.status.success(),
        "crowd {args:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Runs `crowd` and insists that it fails; returns its stderr.
pub fn crowd_err(args: &[&str]) -> String {
    let out = crowd(args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        !out.status.success(),
        "crowd {args:?} should fail; stderr:\n{stderr}"
    );
    assert!(stderr.lines().any(|l| l.starts_with("error: ")), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    stderr
}

pub fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 test paths")
}

/// Every file of a folder and its bytes, sorted by name, without `timings.ron` and
/// `report.md` (which hold the build's times).
pub fn snapshot(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            !["timings.ron", "report.md"].contains(&p.file_name().unwrap().to_str().unwrap())
        })
        .map(|p| {
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(&p).unwrap(),
            )
        })
        .collect();
    files.sort();
    files
}

/// A pipeline for the layers of `layers` (kind, absolute path), written to `dir/pipeline.ron`.
pub fn write_pipeline(dir: &Path, layers: &[(&str, &Path)], extra: &str) -> PathBuf {
    let layers: String = layers
        .iter()
        .map(|(kind, path)| format!("            (kind: {kind}, path: {:?}),\n", s(path)))
        .collect();
    let text = format!(
        "(\n    scene: (\n        meters_per_pixel: 1.0,\n        layers: [\n{layers}        ],\n    ),\n    \
         walkers: 1000,\n    patch_side_m: 8.0,\n    period_s: 20.0,\n    radius_m: 0.3,\n    \
         seed: 1,\n    output: \"out\",\n{extra})\n"
    );
    let path = dir.join("pipeline.ron");
    std::fs::write(&path, text).unwrap();
    path
}
