//! Every setting a stage cannot use is refused before any work: a copy of a shipped pipeline
//! with one field changed to a bad value (NaN as RON writes it, a negative, a zero where it
//! means nothing, a minimum above its maximum) makes `crowd build` fail with an error naming the
//! file, the line of the field, the field and what was expected, and write no output at all.

use crate::util::*;
use std::path::{Path, PathBuf};

/// A copy of the shipped pipeline `name` (`pipeline.ron`, or one of `assets/pipelines/`) in
/// `dir`, its layer paths made absolute and its output `dir/out`, with `field` (`period_s`, or
/// `section.key`) set to `value`. Returns the copy and the line the field is written on.
pub(crate) fn broken(dir: &Path, name: &str, field: &str, value: &str) -> (PathBuf, usize) {
    let shipped = root().join(name);
    let folder = shipped.parent().unwrap();
    let text = std::fs::read_to_string(&shipped).unwrap();
    let mut lines: Vec<String> = text
        .lines()
        .map(|line| match line.split_once("path: \"") {
            Some((before, rest)) => {
                let (path, after) = rest.split_once('"').unwrap();
                let absolute = folder.join(path).canonicalize().unwrap();
                format!("{before}path: {:?}{after}", s(&absolute))
            }
            None if line.trim_start().starts_with("output:") => "    output: \"out\",".into(),
            None => line.to_string(),
        })
        .collect();
    let at = match field.split_once('.') {
        // A top-level field: the shipped file writes it; change its line.
        None => {
            let at = lines
                .iter()
                .position(|l| l.starts_with(&format!("    {field}:")))
                .unwrap_or_else(|| panic!("{name} has no `{field}`"));
            lines[at] = format!("    {field}: {value},");
            at
        }
        Some((section, key)) => {
            match lines.iter().position(|l| l == &format!("    {section}: (")) {
                // A section the file writes: change the key's line, or add it.
                Some(start) => {
                    let end = start + lines[start..].iter().position(|l| l == "    ),").unwrap();
                    let line = format!("        {key}: {value},");
                    match (start..end).find(|&i| lines[i].starts_with(&format!("        {key}:"))) {
                        Some(i) => {
                            lines[i] = line;
                            i
                        }
                        None => {
                            lines.insert(start + 1, line);
                            start + 1
                        }
                    }
                }
                // Otherwise add the section before the closing parenthesis.
                None => {
                    let close = lines.iter().rposition(|l| l == ")").unwrap();
                    lines.insert(close, format!("    {section}: ({key}: {value}),"));
                    close
                }
            }
        }
    };
    let path = dir.join(Path::new(name).file_name().unwrap());
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    (path, at + 1)
}

/// Builds `name` with `field` set to `value`; `Err` says how the refusal fell short.
fn refused(name: &str, field: &str, value: &str, expected: &str) -> Result<(), String> {
    refused_as(name, field, value, field, expected)
}

/// As [`refused`], where the error names `named` (the middle field of a pair out of order).
fn refused_as(
    name: &str,
    field: &str,
    value: &str,
    named: &str,
    expected: &str,
) -> Result<(), String> {
    let dir = tempfile::tempdir().unwrap();
    let (pipeline, line) = broken(dir.path(), name, field, value);
    let out = crowd(&["build", "-q", "--pipeline", s(&pipeline)]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let case = format!("{name} with `{field}: {value}`");
    if out.status.success() {
        return Err(format!("{case}: built, expected a refusal"));
    }
    if dir.path().join("out").exists() {
        return Err(format!("{case}: refused after writing its output folder"));
    }
    let place = format!("error: {}:{line}:", s(&pipeline));
    for part in [place.as_str(), &format!("`{named}` is "), expected] {
        if !stderr.contains(part) || stderr.contains("panicked") {
            return Err(format!("{case}: expected {part:?} in:\n{stderr}"));
        }
    }
    Ok(())
}

/// Runs every case and lists each one that was not refused as it should be.
fn all_refused(cases: &[(&str, &str, &str, &str)]) {
    let failed: Vec<String> = cases
        .iter()
        .filter_map(|(name, field, value, expected)| refused(name, field, value, expected).err())
        .collect();
    assert!(failed.is_empty(), "{}", failed.join("\n\n"));
}

const CITY: &str = "pipeline.ron";
const BANDS: &str = "assets/pipelines/bands.ron";
const RING: &str = "assets/pipelines/ring.ron";

#[test]
fn top_level_sizes_refuse_nan() {
    let metres = "a positive number of metres";
    all_refused(&[
        (CITY, "scene.meters_per_pixel", "NaN", metres),
        (BANDS, "period_s", "NaN", "a positive number of seconds"),
        (RING, "radius_m", "NaN", metres),
        (BANDS, "patch_side_m", "inf", metres),
    ]);
}

#[test]
fn merge_settings_refuse_what_merge_cannot_use() {
    all_refused(&[
        (CITY, "merge.obstacle_threshold", "NaN", "a value in (0, 1]"),
        (CITY, "merge.obstacle_threshold", "0.0", "a value in (0, 1]"),
    ]);
}

#[test]
fn graph_settings_refuse_what_the_graph_cannot_use() {
    let (more, share) = ("expected 0 or more", "a share of the patch in (0, 1]");
    let width = "a positive width in metres";
    all_refused(&[
        (CITY, "graph.empty_below", "NaN", more),
        (CITY, "graph.empty_below", "-0.1", more),
        (CITY, "graph.blocked_above", "NaN", share),
        (CITY, "graph.blocked_above", "1.5", share),
        (CITY, "graph.direction_min_weight", "NaN", more),
        (CITY, "graph.direction_min_weight", "-1.0", more),
        (BANDS, "graph.min_opening_m", "Some(NaN)", width),
        (BANDS, "graph.min_opening_m", "Some(0.0)", width),
    ]);
}

#[test]
fn optimize_settings_refuse_what_the_optimiser_cannot_use() {
    let (rho, tolerance) = ("a positive density", "a gain in E of 0 or more");
    all_refused(&[
        (BANDS, "optimize.rho_max", "NaN", rho),
        (BANDS, "optimize.rho_max", "-0.35", rho),
        (BANDS, "optimize.tolerance", "NaN", tolerance),
        (BANDS, "optimize.tolerance", "-0.001", tolerance),
        (RING, "optimize.tolerance", "inf", tolerance),
        (BANDS, "optimize.patience", "0", "from 1 to 10000 steps"),
        (
            BANDS,
            "optimize.patience",
            "4000000000",
            "from 1 to 10000 steps",
        ),
        (
            BANDS,
            "optimize.max_iterations",
            "0",
            "from 1 to 10000 optimisation",
        ),
        (
            BANDS,
            "optimize.max_iterations",
            "10001",
            "from 1 to 10000 optimisation",
        ),
        (BANDS, "optimize.region_patches", "Some(0)", "a region side"),
        (
            BANDS,
            "optimize.region_patches",
            "Some(1)",
            "all its borders), or None",
        ),
        (
            BANDS,
            "optimize.region_patches",
            "Some(5000)",
            "a region side",
        ),
    ]);
}

/// A painting read as people per m2 takes no totals, and no density it cannot mean.
#[test]
fn people_per_square_metre_refuses_totals_and_bad_densities() {
    let per_m2 = |w: &str| format!("0,\n    people: PerSquareMetre(walkers: {w}, standers: 0.0)");
    all_refused(&[(
        BANDS,
        "walkers",
        "500,\n    people: PerSquareMetre(walkers: 0.1, standers: 0.0)",
        "leave `walkers` out",
    )]);
    for bad in ["-0.1", "NaN", "11.0"] {
        let dir = tempfile::tempdir().unwrap();
        let (pipeline, _) = broken(dir.path(), BANDS, "walkers", &per_m2(bad));
        let err = crowd_err(&["build", "-q", "--pipeline", s(&pipeline)]);
        assert!(
            err.contains("`people.walkers` is ") && err.contains("people per m2"),
            "{bad}: {err}"
        );
        assert!(!dir.path().join("out").exists());
    }
    // Nobody at all, and more than the machine could hold, are refused before any stage too.
    for (densities, expected, extra) in [
        (
            "walkers: 0.0, standers: 0.0",
            "asks for no walker and no stander",
            vec![],
        ),
        (
            "walkers: 0.3, standers: 0.0",
            "`people` asks for about",
            vec!["--max-memory", "1000000"],
        ),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let value = format!("0,\n    people: PerSquareMetre({densities})");
        let (pipeline, _) = broken(dir.path(), BANDS, "walkers", &value);
        let mut args = vec!["build", "-q", "--pipeline", s(&pipeline)];
        args.extend(extra);
        let err = crowd_err(&args);
        assert!(err.contains(expected), "{densities}: {err}");
        assert!(!dir.path().join("out").exists());
    }
}

#[test]
fn match_settings_refuse_what_matching_cannot_use() {
    let (gain, speed) = ("a weight of 0 or more", "a positive speed in m/s");
    let depth = "a share of the patch side in (0, 0.5)";
    all_refused(&[
        (BANDS, "match.direction_gain", "NaN", gain),
        (BANDS, "match.direction_gain", "-3.0", gain),
        (BANDS, "match.min_speed", "NaN", speed),
        (BANDS, "match.comfort_speed", "NaN", speed),
        (BANDS, "match.max_speed", "NaN", speed),
        (BANDS, "match.max_speed", "inf", speed),
        (BANDS, "match.min_speed", "-0.5", speed),
        (BANDS, "match.turn_depth", "NaN", depth),
        (BANDS, "match.turn_depth", "0.0", depth),
    ]);
}

#[test]
fn match_speeds_out_of_order_are_refused() {
    // The middle speed is named, at the line of the `match` section when it is left at its
    // default.
    let order = "0 < min_speed < comfort_speed < max_speed";
    for (name, field, value) in [
        (BANDS, "match.comfort_speed", "2.0"),
        (RING, "match.min_speed", "1.5"),
        (BANDS, "match.max_speed", "1.0"),
    ] {
        refused_as(name, field, value, "match.comfort_speed", order).unwrap();
    }
}

/// A push budget bounds the work of a patch that stalls: none, or one that would let it run
/// for hours, is refused.
#[test]
fn collide_settings_refuse_no_push_budget_and_an_unbounded_one() {
    let pushes = "from 1 to 1000000 pushes per patch";
    all_refused(&[
        (BANDS, "collide.max_iterations", "0", pushes),
        (BANDS, "collide.max_iterations", "4000000000", pushes),
    ]);
}

#[test]
fn smooth_settings_refuse_what_smoothing_cannot_use() {
    let positive = "a positive number";
    all_refused(&[
        (BANDS, "smooth.tack_spacing_s", "NaN", positive),
        (BANDS, "smooth.tack_spacing_s", "0.0", positive),
        (BANDS, "smooth.tolerance_m", "NaN", positive),
        (BANDS, "smooth.tolerance_m", "-0.01", positive),
        (BANDS, "smooth.max_displacement_m", "Some(NaN)", positive),
        (BANDS, "smooth.max_displacement_m", "Some(0.0)", positive),
    ]);
}

#[test]
fn a_region_off_the_painted_maps_is_refused_before_any_stage() {
    // bands' maps are 160 x 80 m.
    let inside = "inside (0, 0, 160, 80)";
    all_refused(&[
        (
            BANDS,
            "export.gltf_region",
            "Some((200.0, 0.0, 240.0, 80.0))",
            inside,
        ),
        (
            BANDS,
            "export.gltf_region",
            "Some((-40.0, 0.0, 40.0, 80.0))",
            inside,
        ),
        (
            BANDS,
            "export.gltf_region",
            "Some((0.0, 0.0, 40.0, 1e9))",
            inside,
        ),
    ]);
}

#[test]
fn export_settings_refuse_an_empty_region_a_bad_distance_and_a_bad_turn_rate() {
    let (mm, region) = ("a distance in millimetres", "with x0 < x1 and y0 < y1");
    let turn = "a turning speed in degrees a second from 30 to 3600";
    all_refused(&[
        (BANDS, "export.simplify_mm", "NaN", mm),
        (BANDS, "export.simplify_mm", "-1.0", mm),
        (BANDS, "export.turn_rate_deg_s", "0.0", turn),
        (BANDS, "export.turn_rate_deg_s", "NaN", turn),
        (BANDS, "export.turn_rate_deg_s", "1e30", turn),
        (
            BANDS,
            "export.gltf_region",
            "Some((40.0, 0.0, 10.0, 80.0))",
            region,
        ),
        (
            BANDS,
            "export.gltf_region",
            "Some((0.0, 80.0, 40.0, 80.0))",
            region,
        ),
        (
            BANDS,
            "export.gltf_region",
            "Some((0.0, NaN, 40.0, 80.0))",
            region,
        ),
    ]);
}
