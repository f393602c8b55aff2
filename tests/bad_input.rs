//! Bad input: a clear error naming the file, the place and what was expected; a non-zero exit;
//! and the outputs of an earlier good build left untouched. Every case uses a real broken file.

use crate::util::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// A folder with a good pipeline over copies of the city layers, and the outputs of a good
/// build of it.
struct Setup {
    dir: tempfile::TempDir,
    pipeline: PathBuf,
    good: Vec<(String, Vec<u8>)>,
}

/// Copies the city layers into `dir` and writes a good pipeline over them.
fn good_pipeline(dir: &Path) -> PathBuf {
    for layer in ["density", "obstacles"] {
        std::fs::copy(
            shared_scenes().join("city").join(format!("{layer}.png")),
            dir.join(format!("{layer}.png")),
        )
        .unwrap();
    }
    write_pipeline(
        dir,
        &[
            ("Density", &dir.join("density.png")),
            ("Obstacles", &dir.join("obstacles.png")),
        ],
        "",
    )
}

/// The outputs of the good pipeline, built once per test run into `target/tmp/bad-input` (a
/// stage file is tied to the contents of its inputs, not their paths, so a copy beside other
/// copies of the layers is up to date there).
fn good_build() -> &'static Path {
    static OUT: OnceLock<PathBuf> = OnceLock::new();
    OUT.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("bad-input");
        std::fs::create_dir_all(&dir).unwrap();
        let pipeline = good_pipeline(&dir);
        crowd_ok(&["build", "-q", "--force", "--pipeline", s(&pipeline)]);
        dir.join("out")
    })
}

impl Setup {
    fn new() -> Setup {
        let dir = tempfile::tempdir().unwrap();
        let pipeline = good_pipeline(dir.path());
        let out = dir.path().join("out");
        copy_files(good_build(), &out);
        let good = snapshot(&out);
        Setup {
            dir,
            pipeline,
            good,
        }
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    /// Rewrites the pipeline text.
    fn edit(&self, from: &str, to: &str) {
        let text = std::fs::read_to_string(&self.pipeline).unwrap();
        assert!(text.contains(from), "{from:?} not in the pipeline");
        std::fs::write(&self.pipeline, text.replacen(from, to, 1)).unwrap();
    }

    /// Builds, expects failure, checks the earlier outputs are intact, returns the message.
    fn fails(&self) -> String {
        let err = crowd_err(&["build", "--pipeline", s(&self.pipeline)]);
        assert!(
            snapshot(&self.path("out")) == self.good,
            "earlier outputs changed"
        );
        err
    }
}

fn assert_has(err: &str, parts: &[&str]) {
    for part in parts {
        assert!(err.contains(part), "expected {part:?} in:\n{err}");
    }
}

#[test]
fn a_missing_layer_file_names_the_pipeline_line() {
    let t = Setup::new();
    std::fs::remove_file(t.path("density.png")).unwrap();
    let err = t.fails();
    assert_has(
        &err,
        &[
            "pipeline.ron:5:",
            "scene.layers[0].path",
            "density.png",
            "cannot be read",
        ],
    );
}

#[test]
fn a_file_that_is_not_an_image_is_refused() {
    let t = Setup::new();
    std::fs::write(
        t.path("density.png"),
        "this is a text file, not a painting\n",
    )
    .unwrap();
    let err = t.fails();
    assert_has(
        &err,
        &[
            "density.png",
            "is not a PNG image",
            "expected the PNG signature",
        ],
    );
}

#[test]
fn a_truncated_png_is_refused() {
    let t = Setup::new();
    let bytes = std::fs::read(t.path("density.png")).unwrap();
    std::fs::write(t.path("density.png"), &bytes[..bytes.len() / 2]).unwrap();
    let err = t.fails();
    assert_has(
        &err,
        &[
            "density.png",
            "damaged or truncated PNG",
            &format!("({} bytes)", bytes.len() / 2),
        ],
    );
}

#[test]
fn layers_of_different_pixel_sizes_are_refused() {
    let t = Setup::new();
    std::fs::copy(
        shared_scenes().join("lanes/density.png"),
        t.path("obstacles.png"),
    )
    .unwrap();
    let err = t.fails();
    assert_has(
        &err,
        &[
            "obstacles.png",
            "is 160 x 64 pixels",
            "400 x 400 pixels",
            "same pixel size",
        ],
    );
}

#[test]
fn a_ron_syntax_error_names_line_and_column() {
    let t = Setup::new();
    t.edit("walkers: 1000,", "walkers: 1000\n    oops");
    let err = t.fails();
    assert_has(&err, &["pipeline.ron:10:5:"]);
}

#[test]
fn an_unknown_field_suggests_the_nearest_name() {
    let t = Setup::new();
    t.edit("radius_m:", "raduis_m:");
    let err = t.fails();
    assert_has(
        &err,
        &[
            "pipeline.ron:",
            "unknown field `raduis_m`",
            "did you mean `radius_m`?",
        ],
    );
}

#[test]
fn zero_or_negative_sizes_are_refused() {
    for (field, bad) in [
        ("patch_side_m", "-8.0"),
        ("period_s", "0.0"),
        ("radius_m", "-0.3"),
    ] {
        let t = Setup::new();
        let text = std::fs::read_to_string(&t.pipeline).unwrap();
        let line = text
            .lines()
            .find(|l| l.trim_start().starts_with(field))
            .unwrap()
            .to_string();
        t.edit(&line, &format!("    {field}: {bad},"));
        let err = t.fails();
        assert_has(
            &err,
            &[
                "pipeline.ron:",
                &format!("`{field}` is {}", bad.trim_end_matches(".0")),
                "expected a positive number",
            ],
        );
    }
}

#[test]
fn zero_walkers_over_a_painted_density_map_is_refused() {
    let t = Setup::new();
    t.edit("walkers: 1000,", "walkers: 0,");
    let err = t.fails();
    assert_has(
        &err,
        &[
            "pipeline.ron:9:5:",
            "`walkers` is 0",
            "pixels outside obstacles",
        ],
    );
}

#[test]
fn more_walkers_than_rho_max_allows_is_refused_with_the_capacity() {
    let t = Setup::new();
    t.edit("walkers: 1000,", "walkers: 90000,");
    let err = t.fails();
    assert_has(
        &err,
        &[
            "pipeline.ron:9:5:",
            "`walkers` is 90000 but at most",
            "rho_max = 0.35",
        ],
    );
}

#[test]
fn a_scene_without_a_walkable_patch_is_refused() {
    let t = Setup::new();
    let all_blocked = image::GrayImage::from_pixel(400, 400, image::Luma([255]));
    all_blocked.save(t.path("obstacles.png")).unwrap();
    let err = t.fails();
    assert_has(
        &err,
        &["pipeline.ron", "no walkable patch", "2500 are blocked"],
    );
}

#[test]
fn an_output_folder_that_cannot_be_written_is_refused() {
    let t = Setup::new();
    std::fs::write(t.path("not-a-folder"), b"a plain file").unwrap();
    t.edit("output: \"out\"", "output: \"not-a-folder/out\"");
    let err = t.fails();
    assert_has(
        &err,
        &["not-a-folder/out", "cannot create the output folder"],
    );
}

/// What a user names most often is not a stage file but the build folder or what ships:
/// `inspect` reads them through the manifest beside them, and says what a binary file is.
#[test]
fn inspect_reads_a_build_folder_and_its_products_through_the_manifest() {
    let t = Setup::new();
    let out = t.path("out");
    for named in [
        out.clone(),
        out.join("library.crowd"),
        out.join("world.glb"),
    ] {
        let said = crowd_ok(&["inspect", s(&named)]);
        let said = String::from_utf8_lossy(&said.stdout);
        assert!(
            said.contains("stage 8 (export)"),
            "{}: {said}",
            named.display()
        );
        assert!(
            said.contains("loads and checks"),
            "{}: {said}",
            named.display()
        );
    }
    // A library moved away from its manifest, and a binary file of any other name.
    let alone = t.path("alone");
    std::fs::create_dir_all(&alone).unwrap();
    std::fs::copy(out.join("library.crowd"), alone.join("library.crowd")).unwrap();
    let err = crowd_err(&["inspect", s(&alone.join("library.crowd"))]);
    assert_has(
        &err,
        &[
            "library.crowd",
            "a product of stage 8",
            "export.ron is not there",
        ],
    );
    std::fs::copy(out.join("library.crowd"), t.path("mine.bin")).unwrap();
    let err = crowd_err(&["inspect", s(&t.path("mine.bin"))]);
    assert_has(&err, &["mine.bin", "is not a stage file", "it is binary"]);
}

#[test]
fn a_stage_file_of_another_kind_is_refused_by_inspect() {
    let t = Setup::new();
    let err = crowd_err(&["inspect", s(&t.path("pipeline.ron"))]);
    assert_has(
        &err,
        &[
            "pipeline.ron",
            "is not a stage file",
            "expected RON starting with `header:",
        ],
    );
}

#[test]
fn an_edited_graph_file_is_refused_not_trusted() {
    let dir = copy_of("bands");
    let graph = dir.path().join("graph.ron");
    let text = std::fs::read_to_string(&graph).unwrap();
    let broken = text.replacen("(a: (0), b: (1),", "(a: (0), b: (99999),", 1);
    assert_ne!(text, broken);
    std::fs::write(&graph, broken).unwrap();
    let p = scene_pipeline("bands");
    let err = crowd_err(&[
        "optimize",
        "--pipeline",
        s(&p),
        "-i",
        s(&graph),
        "-o",
        s(&dir.path().join("patterns.ron")),
    ]);
    assert_has(
        &err,
        &[
            "graph.ron",
            "is inconsistent",
            "border 0 names a patch beyond",
        ],
    );
}

#[test]
fn a_graph_file_with_patches_out_of_order_is_refused() {
    let dir = copy_of("bands");
    let graph = dir.path().join("graph.ron");
    let text = std::fs::read_to_string(&graph).unwrap();
    let broken = text.replacen("cell: (col: 1, row: 0)", "cell: (col: 0, row: 0)", 1);
    assert_ne!(text, broken);
    std::fs::write(&graph, broken).unwrap();
    let err = crowd_err(&["inspect", s(&graph)]);
    assert_has(
        &err,
        &[
            "graph.ron",
            "is inconsistent",
            "patch 1 does not follow patch 0",
        ],
    );
}

#[test]
fn patterns_of_another_graph_are_refused() {
    let dir = copy_of("bands");
    let out = dir.path();
    std::fs::copy(scene("lanes").join("graph.ron"), out.join("graph.ron")).unwrap();
    let p = scene_pipeline("bands");
    let err = crowd_err(&[
        "match",
        "--pipeline",
        s(&p),
        "-i",
        s(&out.join("patterns.ron")),
        "-o",
        s(&out.join("t.ron")),
    ]);
    assert_has(&err, &["patterns.ron", "build the patterns again"]);
}

/// A stage file of another format version (an older build's) is refused by `crowd inspect` and
/// `crowd render`, which read the version this build writes, not the one the file claims.
#[test]
fn a_stage_file_of_another_version_is_refused_by_inspect_and_render() {
    let dir = copy_of("bands");
    for (file, stage, version) in [
        (
            "trajectories.ron",
            "match",
            crowd_core::trajectories::TrajectoriesFile::VERSION,
        ),
        ("collided.ron", crowd_collide::STAGE, crowd_collide::VERSION),
        ("smoothed.ron", crowd_smooth::STAGE, crowd_smooth::VERSION),
    ] {
        let path = dir.path().join(file);
        let text = std::fs::read_to_string(&path).unwrap();
        let claimed = format!("version: {version},");
        assert!(text.contains(&claimed), "{file}: {claimed} in\n{text}");
        let old = version + 41;
        std::fs::write(
            &path,
            text.replacen(&claimed, &format!("version: {old},"), 1),
        )
        .unwrap();
        let expected = format!(
            "is `{stage}` format version {old}; this build reads version {version}: build again"
        );
        let err = crowd_err(&["inspect", s(&path)]);
        assert_has(&err, &[file, &expected]);
        let png = dir.path().join("picture.png");
        let err = crowd_err(&["render", s(&path), "-o", s(&png)]);
        assert_has(&err, &[file, &expected]);
        assert!(!png.exists(), "{file}: rendered anyway");
    }
}

/// Runs `crowd` with its stdout a pipe closed before it writes (`crowd report | head -0`).
fn into_closed_pipe(args: &[&str]) -> std::process::Output {
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_crowd"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("crowd runs");
    drop(child.stdout.take());
    child.wait_with_output().expect("crowd ends")
}

#[test]
fn every_command_takes_a_closed_stdout_as_the_end_of_its_output() {
    let copy = copy_of("bands");
    let dir = copy.path();
    let graph = dir.join("graph.ron");
    for args in [
        vec!["report", s(dir), "--json"],
        vec!["report", s(dir)],
        vec!["report", "--table", s(dir)],
        vec!["inspect", s(&graph)],
        vec!["check", s(dir)],
    ] {
        let out = into_closed_pipe(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            out.status.success(),
            "crowd {args:?}: {:?}\n{stderr}",
            out.status
        );
        assert!(!stderr.contains("panicked"), "crowd {args:?}: {stderr}");
    }
}

#[test]
fn a_layer_too_large_to_decode_is_refused_from_its_header() {
    // City's density with its header saying 20,000 x 20,000 pixels (1.6 GB decoded as one
    // channel of f32): refused before a byte of it is decoded.
    let dir = tempfile::tempdir().unwrap();
    let pipeline = good_pipeline(dir.path());
    let layer = dir.path().join("density.png");
    let mut bytes = std::fs::read(&layer).unwrap();
    assert_eq!(&bytes[12..16], b"IHDR");
    bytes[16..20].copy_from_slice(&20_000u32.to_be_bytes());
    bytes[20..24].copy_from_slice(&20_000u32.to_be_bytes());
    std::fs::write(&layer, bytes).unwrap();
    let stderr = crowd_err(&["build", "-q", "--pipeline", s(&pipeline)]);
    assert!(stderr.contains(s(&layer)), "{stderr}");
    assert!(
        stderr.contains("20000 x 20000 pixels (read from its header"),
        "{stderr}"
    );
    assert!(stderr.contains("scene.meters_per_pixel"), "{stderr}");
    assert!(!dir.path().join("out").exists());
}

/// A folder that is not a build (the scene's folder, say) is named as such by the commands
/// that read a build folder, not by the first file they miss.
#[test]
fn report_and_check_of_a_folder_without_a_build_say_so() {
    let dir = tempfile::tempdir().unwrap();
    for command in ["report", "check"] {
        let err = crowd_err(&[command, s(dir.path())]);
        assert_has(&err, &["no stage files here", "expected a build folder"]);
    }
}
