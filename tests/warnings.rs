//! What a build cannot give a painting: warnings on stderr and in `report.md` with a picture,
//! `--deny-warnings` for build systems, and an error naming the patch for a defect the pipeline
//! cannot clear. Each caused by a real painting.

use crate::util::{copy_of, crowd, crowd_broken, crowd_err, root, s, write_pipeline};
use image::{GrayImage, Luma};

/// A 32 x 32 m painting (4 x 4 patches of 8 m) with walkers everywhere and the patch at
/// x 8-16 m, y 8-16 m walled in on every side.
fn walled_in_pocket(dir: &std::path::Path) -> std::path::PathBuf {
    let density = GrayImage::from_pixel(32, 32, Luma([120]));
    let mut walls = GrayImage::new(32, 32);
    // Image rows count from the north: y 8-16 m is rows 16-23.
    for i in 8..16 {
        for (x, y) in [(i, 16), (i, 23), (8, 16 + i - 8), (15, 16 + i - 8)] {
            walls.put_pixel(x, y, Luma([255]));
        }
    }
    let (d, w) = (dir.join("density.png"), dir.join("walls.png"));
    density.save(&d).unwrap();
    walls.save(&w).unwrap();
    write_pipeline(dir, &[("Density", &d), ("Obstacles", &w)], "")
        .to_str()
        .map(|p| {
            let text = std::fs::read_to_string(p).unwrap();
            std::fs::write(p, text.replace("walkers: 1000", "walkers: 60")).unwrap();
            std::path::PathBuf::from(p)
        })
        .unwrap()
}

#[test]
fn a_walled_in_pocket_is_a_warning_on_stderr_and_in_the_report_with_a_picture() {
    let dir = tempfile::tempdir().unwrap();
    let pipeline = walled_in_pocket(dir.path());
    let build = crowd(&["build", "-q", "--pipeline", s(&pipeline)]);
    let stderr = String::from_utf8_lossy(&build.stderr);
    assert!(build.status.success(), "{stderr}");
    let warning = stderr
        .lines()
        .find(|l| l.starts_with("warning: "))
        .unwrap_or_else(|| panic!("a warning on stderr:\n{stderr}"));
    assert!(
        warning.contains("x 8-16 m, y 8-16 m") && warning.contains("walled in"),
        "{warning}"
    );
    let out = dir.path().join("out");
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    let section = &md[md.find("## Warnings").expect("a warnings section")..];
    assert!(section.contains("walled in"), "{md}");
    assert!(section.contains("](report_warnings.png)"), "{md}");
    let picture = image::open(out.join("report_warnings.png"))
        .unwrap()
        .to_rgb8();
    assert!(
        picture.pixels().any(|p| p.0 == [230, 20, 20]),
        "the pocket is drawn red"
    );

    // Built again with --deny-warnings: the same files, and a failure a build system sees.
    let stderr = crowd_broken(&["build", "-q", "--deny-warnings", "--pipeline", s(&pipeline)]);
    assert!(stderr.contains("--deny-warnings"), "{stderr}");
    assert!(stderr.contains("walled in"), "{stderr}");
}

#[test]
fn a_build_without_warnings_says_so_and_passes_deny_warnings() {
    let dir = copy_of("bands");
    let pipeline = root().join("assets/pipelines/bands.ron");
    let out = dir.path();
    let build = crowd(&[
        "build",
        "-q",
        "--deny-warnings",
        "--pipeline",
        s(&pipeline),
        "--output",
        s(out),
    ]);
    let stderr = String::from_utf8_lossy(&build.stderr);
    assert!(build.status.success(), "{stderr}");
    assert!(!stderr.contains("warning"), "{stderr}");
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("## Warnings\n\nNone"), "{md}");
    assert!(!out.join("report_warnings.png").exists());
}

/// Random painting `seed` (`crowd-paintings write --seed SEED --max-patches MAX`), written in
/// `dir`: its pipeline's path.
fn random_painting(dir: &std::path::Path, seed: u64, max_patches: u32) -> std::path::PathBuf {
    crowd_paintings::random(seed, crowd_paintings::Limits { max_patches })
        .write(dir)
        .unwrap()
}

/// Builds `pipeline`, which must succeed; its stderr.
fn built(pipeline: &std::path::Path) -> String {
    let build = crowd(&["build", "-q", "--pipeline", s(pipeline)]);
    let stderr = String::from_utf8_lossy(&build.stderr).into_owned();
    assert!(build.status.success(), "{stderr}");
    stderr
}

/// Random painting 1 (`crowd-paintings write --seed 1 --max-patches 8`) paints 72 walkers into
/// patch 27 (1.1 per m2, in crossing flows): at walking pace, and with walkers given a period
/// more, stage 5 keeps them apart only by letting one hurry, and the build says where. (Which
/// try clears so dense a patch is chancy: with other settings of stage 5 it was left colliding,
/// an error naming the patch.)
#[test]
fn a_patch_whose_walkers_must_hurry_is_a_warning_that_names_it() {
    let dir = tempfile::tempdir().unwrap();
    let stderr = built(&random_painting(dir.path(), 1, 8));
    let hurry = stderr
        .lines()
        .find(|l| l.starts_with("warning: patch 27 ") && l.contains(" runs at "))
        .unwrap_or_else(|| panic!("a warning naming the patch:\n{stderr}"));
    assert!(
        hurry.contains("faster than match.max_speed allows"),
        "{hurry}"
    );
    let md = std::fs::read_to_string(dir.path().join("out/report.md")).unwrap();
    assert!(md.contains(" runs at "), "{md}");
    assert!(dir.path().join("out/report_warnings.png").exists());
}

/// Random painting 105 (12 patches of 10 m, walkers of 0.35 m radius past walls): two of its
/// patches stay colliding in every tier of stage 5 (the soak refuses it at the defaults after
/// 84 s; with `collide.max_iterations: 200`, which bounds the rescues too, in seconds). The
/// build is an error naming a patch, the same one on one thread as on every core (stage 5 stops
/// at the first patch it cannot clear, busiest first), and writes nothing: no stage file, no
/// library.
#[test]
fn a_patch_no_try_clears_is_an_error_that_names_it_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let pipeline = random_painting(dir.path(), 105, 8);
    let text = std::fs::read_to_string(&pipeline).unwrap();
    let text = text.replace(
        "    output: \"out\",",
        "    output: \"out\",\n    collide: (max_iterations: 200),",
    );
    assert!(text.contains("max_iterations: 200"), "{text}");
    std::fs::write(&pipeline, text).unwrap();
    let stderr = crowd_err(&["build", "-q", "--pipeline", s(&pipeline)]);
    let error = stderr
        .lines()
        .find(|l| l.starts_with("error: stage 5 could not keep patch "))
        .unwrap_or_else(|| panic!("an error naming the patch:\n{stderr}"));
    assert!(
        error.contains(" clear: ") && error.contains("too close"),
        "{error}"
    );
    let alone = crowd_err(&["--threads", "1", "build", "-q", "--pipeline", s(&pipeline)]);
    assert!(alone.lines().any(|l| l == error), "{error}\n{alone}");
    let out = dir.path().join("out");
    for file in ["collided.ron", "smoothed.ron", "library.crowd", "world.glb"] {
        assert!(!out.join(file).exists(), "{file} was written");
    }
}

/// A 32 x 32 m painting of uniform walkers, asking for `walkers` of them.
fn uniform(dir: &std::path::Path, walkers: u32) -> std::path::PathBuf {
    let density = dir.join("density.png");
    GrayImage::from_pixel(32, 32, Luma([120]))
        .save(&density)
        .unwrap();
    let pipeline = write_pipeline(dir, &[("Density", &density)], "");
    let text = std::fs::read_to_string(&pipeline).unwrap();
    let text = text.replace("walkers: 1000", &format!("walkers: {walkers}"));
    std::fs::write(&pipeline, text).unwrap();
    pipeline
}

#[test]
fn a_painting_too_sparse_for_one_walker_is_an_error_and_nothing_is_written() {
    // Two walkers over 1024 m2 ask 0.002 per m2: one walker crossing a patch makes 0.005.
    let dir = tempfile::tempdir().unwrap();
    let pipeline = uniform(dir.path(), 2);
    let stderr = crowd_err(&["build", "-q", "--pipeline", s(&pipeline)]);
    assert!(stderr.contains("placed no walker"), "{stderr}");
    assert!(stderr.contains("`walkers`"), "{stderr}");
    assert!(stderr.contains("scene.meters_per_pixel"), "{stderr}");
    assert!(!dir.path().join("out").join("graph.ron").exists());
}

#[test]
fn walkers_painted_only_in_a_walled_in_pocket_are_an_error_that_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let pipeline = walled_in_pocket(dir.path());
    // Walkers painted inside the pocket only (x 9-15 m, y 9-15 m: rows 17-22).
    let mut density = GrayImage::new(32, 32);
    for x in 9..15 {
        for y in 17..23 {
            density.put_pixel(x, y, Luma([200]));
        }
    }
    density.save(dir.path().join("density.png")).unwrap();
    let text = std::fs::read_to_string(&pipeline).unwrap();
    std::fs::write(&pipeline, text.replace("walkers: 60", "walkers: 10")).unwrap();
    let stderr = crowd_err(&["build", "-q", "--pipeline", s(&pipeline)]);
    assert!(stderr.contains("placed no walker"), "{stderr}");
    assert!(stderr.contains("walled in on every side"), "{stderr}");
}

#[test]
fn a_sparse_painting_that_places_fewer_walkers_than_asked_is_a_warning() {
    // 60 walkers over bands' 160 x 80 m: most patches ask less than one crossing walker makes.
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(root().join("assets/pipelines/bands.ron")).unwrap();
    let density = crate::util::shared_scenes().join("bands/density.png");
    let text = text
        .replace("walkers: 1100", "walkers: 60")
        .replace("../../../shared/scenes/bands/density.png", s(&density))
        .replace("../../build/bands", "out");
    let pipeline = dir.path().join("pipeline.ron");
    std::fs::write(&pipeline, text).unwrap();
    let build = crowd(&["build", "-q", "--pipeline", s(&pipeline)]);
    let stderr = String::from_utf8_lossy(&build.stderr);
    assert!(build.status.success(), "{stderr}");
    let warning = stderr
        .lines()
        .find(|l| l.contains("walkers placed of 60 asked"))
        .unwrap_or_else(|| panic!("a shortfall warning:\n{stderr}"));
    // The folder does not say how `people` was given: both settings are named.
    assert!(
        warning.contains("`walkers`, or `people.walkers` per m2"),
        "{warning}"
    );
    let md = std::fs::read_to_string(dir.path().join("out/report.md")).unwrap();
    assert!(md.contains("walkers placed of 60 asked"), "{md}");
    let stderr = crowd_broken(&["build", "-q", "--deny-warnings", "--pipeline", s(&pipeline)]);
    assert!(stderr.contains("--deny-warnings"), "{stderr}");
}

/// Random painting 9001 (`crowd-paintings write --seed 9001 --max-patches 14`) asks for 17
/// walkers over 27 patches of 6 m with a flow layer: stage 3's whole walkers, and those it sends
/// to walk the painted directions, come out 44. More than asked is said as plainly as fewer.
#[test]
fn a_sparse_painting_that_places_more_walkers_than_asked_is_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let stderr = built(&random_painting(dir.path(), 9001, 14));
    let warning = stderr
        .lines()
        .find(|l| l.contains("walkers placed of 17 asked"))
        .unwrap_or_else(|| panic!("a surplus warning:\n{stderr}"));
    assert!(warning.contains("more than asked"), "{warning}");
    let md = std::fs::read_to_string(dir.path().join("out/report.md")).unwrap();
    assert!(md.contains("walkers placed of 17 asked"), "{md}");
}
