//! Tests of the pipeline file: parsing, defaults, places of fields, and each settings
//! struct's refusals.

use super::*;
use crate::error::{LineCol, Result};
use std::path::{Path, PathBuf};

const GOOD: &str = r#"(
    scene: (
        meters_per_pixel: 1.0,
        layers: [
            (kind: Density, path: "d.png"),
            (kind: Static, path: "s.png", weight: 0.5), // the park
        ],
    ),
    walkers: 100,
    standers: 10,
    patch_side_m: 8.0,
    period_s: 20.0,
    radius_m: 0.3,
    seed: 1,
    output: "build",
)"#;

fn parse(text: &str) -> Result<PipelineFile> {
    PipelineFile::parse(Path::new("p.ron"), text.to_string())
}

#[test]
fn a_good_pipeline_parses_with_defaults() {
    let p = parse(GOOD).unwrap().pipeline;
    assert_eq!(p.scene.layers[0].weight, 1.0);
    assert_eq!(p.scene.layers[1].weight, 0.5);
    assert_eq!(p.graph, GraphSettings::default());
}

#[test]
fn fields_are_located_by_their_dotted_path() {
    let f = parse(GOOD).unwrap();
    assert_eq!(
        f.place_of("patch_side_m"),
        Some(LineCol { line: 11, col: 5 })
    );
    assert_eq!(
        f.place_of("scene.layers[1].path"),
        Some(LineCol { line: 6, col: 28 })
    );
    assert_eq!(f.place_of("graph.empty_below"), None);
}

#[test]
fn paths_resolve_against_the_pipeline_folder() {
    let f = PipelineFile::parse(Path::new("assets/pipelines/p.ron"), GOOD.to_string()).unwrap();
    assert_eq!(
        f.resolve(Path::new("../../build/x")),
        PathBuf::from("build/x")
    );
    assert_eq!(
        f.resolve(Path::new("../../../shared/a.png")),
        PathBuf::from("../shared/a.png")
    );
    assert_eq!(
        f.resolve(Path::new("/abs/a.png")),
        PathBuf::from("/abs/a.png")
    );
}

#[test]
fn a_misspelt_field_suggests_the_nearest_name() {
    let text = GOOD.replace("period_s", "periode_s");
    let err = parse(&text).unwrap_err().to_string();
    assert!(err.starts_with("p.ron:12:"), "{err}");
    assert!(err.contains("did you mean `period_s`?"), "{err}");
}

#[test]
fn a_zero_patch_side_names_its_line() {
    let text = GOOD.replace("patch_side_m: 8.0", "patch_side_m: 0.0");
    let err = parse(&text).unwrap_err().to_string();
    assert!(err.starts_with("p.ron:11:5: `patch_side_m` is 0"), "{err}");
}

#[test]
fn export_keeps_keyframes_within_0_75_mm_unless_told_and_refuses_a_negative_distance() {
    assert_eq!(parse(GOOD).unwrap().pipeline.export.simplify_mm, 0.75);
    let text = GOOD.replace("output:", "export: (simplify_mm: -1.0),\n    output:");
    let err = parse(&text).unwrap_err().to_string();
    assert!(err.starts_with("p.ron:15:14: "), "{err}");
    assert!(err.contains("`export.simplify_mm` is -1"), "{err}");
    assert!(err.contains("expected a distance in millimetres"), "{err}");
}

/// GOOD with one stage section added, e.g. `optimize: (patience: 0)`.
fn with_section(section: &str) -> String {
    GOOD.replace("output:", &format!("{section},\n    output:"))
}

#[test]
fn each_settings_struct_refuses_what_its_stage_cannot_use() {
    for (section, field, expected) in [
        (
            "merge: (obstacle_threshold: NaN)",
            "merge.obstacle_threshold",
            "in (0, 1]",
        ),
        (
            "graph: (empty_below: -1.0)",
            "graph.empty_below",
            "0 or more",
        ),
        (
            "graph: (blocked_above: 0.0)",
            "graph.blocked_above",
            "in (0, 1]",
        ),
        (
            "graph: (direction_min_weight: NaN)",
            "graph.direction_min_weight",
            "0 or more",
        ),
        (
            "graph: (min_opening_m: Some(0.0))",
            "graph.min_opening_m",
            "positive width",
        ),
        (
            "optimize: (rho_max: inf)",
            "optimize.rho_max",
            "positive density",
        ),
        (
            "optimize: (max_iterations: 0)",
            "optimize.max_iterations",
            "from 1 to 10000",
        ),
        (
            "optimize: (max_iterations: 10001)",
            "optimize.max_iterations",
            "from 1 to 10000",
        ),
        (
            "optimize: (tolerance: NaN)",
            "optimize.tolerance",
            "0 or more",
        ),
        (
            "optimize: (tolerance: -0.1)",
            "optimize.tolerance",
            "0 or more",
        ),
        (
            "optimize: (patience: 0)",
            "optimize.patience",
            "from 1 to 10000",
        ),
        (
            "match: (min_speed: NaN)",
            "match.min_speed",
            "positive speed",
        ),
        (
            "match: (max_speed: inf)",
            "match.max_speed",
            "positive speed",
        ),
        (
            "match: (comfort_speed: 2.0)",
            "match.comfort_speed",
            "min_speed < comfort_speed",
        ),
        (
            "match: (min_speed: 1.5)",
            "match.comfort_speed",
            "min_speed < comfort_speed",
        ),
        (
            "match: (direction_gain: NaN)",
            "match.direction_gain",
            "0 or more",
        ),
        (
            "match: (direction_gain: -3.0)",
            "match.direction_gain",
            "0 or more",
        ),
        ("match: (turn_depth: 0.5)", "match.turn_depth", "(0, 0.5)"),
        (
            "collide: (max_iterations: 0)",
            "collide.max_iterations",
            "from 1 to 1000000",
        ),
        (
            "collide: (max_iterations: 1000001)",
            "collide.max_iterations",
            "from 1 to 1000000",
        ),
        (
            "smooth: (tack_spacing_s: 0.0)",
            "smooth.tack_spacing_s",
            "positive",
        ),
        (
            "smooth: (tolerance_m: NaN)",
            "smooth.tolerance_m",
            "positive",
        ),
        (
            "smooth: (max_displacement_m: Some(-1.0))",
            "smooth.max_displacement_m",
            "positive",
        ),
        ("export: (simplify_mm: NaN)", "export.simplify_mm", "from 0"),
        (
            "export: (gltf_region: Some((10.0, 0.0, 5.0, 8.0)))",
            "export.gltf_region",
            "x0 < x1",
        ),
        (
            "export: (gltf_region: Some((0.0, NaN, 5.0, 8.0)))",
            "export.gltf_region",
            "y0 < y1",
        ),
    ] {
        let err = parse(&with_section(section)).unwrap_err().to_string();
        assert!(err.starts_with("p.ron:15:"), "{section}: {err}");
        assert!(err.contains(&format!("`{field}` is ")), "{section}: {err}");
        assert!(err.contains(expected), "{section}: {err}");
    }
}

#[test]
fn zero_tolerance_and_direction_gain_are_allowed() {
    let text = with_section("optimize: (tolerance: 0.0), match: (direction_gain: 0.0)");
    let p = parse(&text).unwrap().pipeline;
    assert_eq!(p.optimize.tolerance, 0.0);
    assert_eq!(p.matching.direction_gain, 0.0);
}

#[test]
fn a_layer_weight_of_nan_is_refused() {
    let text = GOOD.replace("weight: 0.5", "weight: NaN");
    let err = parse(&text).unwrap_err().to_string();
    assert!(err.contains("`scene.layers[1].weight` is NaN"), "{err}");
}

/// Settings that parse, each legal alone, that size the work beyond what a build can do: the
/// issue's hostile table (an abort allocating, minutes of work, a panic, an empty crowd), each
/// refused before any stage runs, naming the setting, its value as written and its range.
#[test]
fn settings_that_size_the_work_are_checked_against_each_other() {
    for (from, to, field, expected) in [
        (
            "period_s: 20.0",
            "period_s: 1e300",
            "period_s",
            "is 1e300; expected from 1 to 600",
        ),
        (
            "period_s: 20.0",
            "period_s: 1e5",
            "period_s",
            "is 100000; expected from 1 to 600",
        ),
        ("period_s: 20.0", "period_s: 1e-9", "period_s", "is 1e-9;"),
        ("period_s: 20.0", "period_s: 20.00005", "period_s", "0.1 ms"),
        (
            "patch_side_m: 8.0",
            "patch_side_m: 1.0",
            "patch_side_m",
            "from 2.4 to 100 m",
        ),
        (
            "patch_side_m: 8.0",
            "patch_side_m: 200.0",
            "patch_side_m",
            "from 2.4 to 100 m",
        ),
        (
            "radius_m: 0.3",
            "radius_m: 2.0",
            "patch_side_m",
            "from 16 to 100 m",
        ),
        (
            "weight: 0.5",
            "weight: 1e39",
            "scene.layers[1].weight",
            "is 1e39;",
        ),
    ] {
        let text = GOOD.replace(from, to);
        assert_ne!(text, GOOD, "{from}");
        let err = parse(&text).unwrap_err().to_string();
        assert!(err.contains(&format!("`{field}` ")), "{to}: {err}");
        assert!(err.contains(expected), "{to}: {err}");
    }
    for (section, field, expected) in [
        (
            "smooth: (tack_spacing_s: 1e-9)",
            "smooth.tack_spacing_s",
            "from 0.05 s to the period",
        ),
        (
            "smooth: (tack_spacing_s: 30.0)",
            "smooth.tack_spacing_s",
            "from 0.05 s to the period",
        ),
        (
            "graph: (min_opening_m: Some(1e300))",
            "graph.min_opening_m",
            "at most the patch side",
        ),
    ] {
        let err = parse(&with_section(section)).unwrap_err().to_string();
        assert!(err.starts_with("p.ron:15:"), "{section}: {err}");
        assert!(err.contains(&format!("`{field}` is ")), "{section}: {err}");
        assert!(err.contains(expected), "{section}: {err}");
    }
}
