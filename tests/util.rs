//! Helpers shared by the end-to-end tests.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Output;
use std::sync::{LazyLock, Mutex, OnceLock};

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

/// The build folder of a shipped scene (`assets/pipelines/<name>.ron`) built whole, to
/// export: built once per test run (with `--force`, so no output of an earlier run or another
/// version is reused) into `target/tmp/scenes/<name>`, and shared by every test of the run.
/// Read it only: a test that changes, adds or removes files (`crowd check` writes `check.ron`
/// and `report.md`) works on [`copy_of`]. Tests that ask for a scene while it builds wait.
///
/// It builds with [`CACHE_THREADS`] worker threads, so that the determinism test can compare a
/// one-thread build against it.
pub fn scene(name: &str) -> &'static Path {
    static SCENES: OnceLock<Mutex<HashMap<String, &'static OnceLock<PathBuf>>>> = OnceLock::new();
    let cell: &'static OnceLock<PathBuf> = SCENES
        .get_or_init(Default::default)
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .entry(name.to_string())
        .or_insert_with(|| Box::leak(Box::default()));
    cell.get_or_init(|| {
        let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
            .join("scenes")
            .join(name);
        let pipeline = scene_pipeline(name);
        let threads = CACHE_THREADS.to_string();
        crowd_ok(&[
            "--threads",
            &threads,
            "build",
            "-q",
            "--force",
            "--pipeline",
            s(&pipeline),
            "--output",
            s(&out),
        ]);
        out
    })
}

/// Worker threads of the builds of [`scene`]: at least two, more on a machine with more cores.
pub static CACHE_THREADS: LazyLock<usize> = LazyLock::new(|| {
    std::thread::available_parallelism()
        .map_or(2, |n| n.get())
        .max(2)
});

/// A private copy of [`scene`]'s build folder, for a test that changes files in it: the
/// folder's files, directly in the returned temporary folder.
pub fn copy_of(name: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    copy_files(scene(name), dir.path());
    dir
}

/// Copies every file of `from` into `to` (created if missing).
pub fn copy_files(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let path = entry.unwrap().path();
        assert!(
            path.is_file(),
            "{}: a build folder holds files only",
            path.display()
        );
        std::fs::copy(&path, to.join(path.file_name().unwrap())).unwrap();
    }
}

/// Runs `crowd` with `args`. With `CROWD_TEST_LOG=FILE` set, appends a line with the
/// arguments to FILE first (to count the builds of a test run).
pub fn crowd(args: &[&str]) -> Output {
    if let Some(log) = std::env::var_os("CROWD_TEST_LOG") {
        use std::io::Write;
        let mut file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(log)
            .expect("CROWD_TEST_LOG is writable");
        file.write_all(format!("crowd {}\n", args.join(" ")).as_bytes())
            .unwrap();
    }
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
    crowd_exits(args, 1)
}

/// Runs `crowd` and insists that it ends with exit code 3 (it ran to the end and found
/// guarantees broken, `crowd::cli::EXIT_CODES`); returns its stderr.
pub fn crowd_broken(args: &[&str]) -> String {
    crowd_exits(args, 3)
}

fn crowd_exits(args: &[&str], code: i32) -> String {
    let out = crowd(args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(
        out.status.code(),
        Some(code),
        "crowd {args:?} should exit with {code}; stderr:\n{stderr}"
    );
    assert!(stderr.lines().any(|l| l.starts_with("error: ")), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    stderr
}

pub fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 test paths")
}

/// Every file of a folder and its bytes, sorted by name, without `timings.ron` and
/// `report.md` (which hold the build's times) and the folder's lock file (empty, not an output).
pub fn snapshot(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            !["timings.ron", "report.md", ".crowd.lock"]
                .contains(&p.file_name().unwrap().to_str().unwrap())
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
