//! The guarantees every build of any painting must keep, read from its figures (`crowd report
//! --json` after `crowd check`), as one list the tests and the soak share.

use serde_json::Value;

/// A figure and the most (or least) it may be.
struct Bound {
    key: &'static str,
    limit: f64,
    at_most: bool,
    what: &'static str,
}

const fn at_most(key: &'static str, limit: f64, what: &'static str) -> Bound {
    Bound {
        key,
        limit,
        at_most: true,
        what,
    }
}

const fn at_least(key: &'static str, limit: f64, what: &'static str) -> Bound {
    Bound {
        key,
        limit,
        at_most: false,
        what,
    }
}

/// The guarantees of DESIGN.md that hold for any painting the config accepts.
const GUARANTEES: [Bound; 13] = [
    at_most(
        "collisions",
        0.0,
        "no collision anywhere in the tiled world",
    ),
    at_least("min_clearance_m", -1e-6, "no pair closer than their radii"),
    at_most("unconverged_patches", 0.0, "every patch converges"),
    at_most("unmatched_crossings", 0.0, "every crossing is walked"),
    at_most(
        "max_boundary_error_m",
        1e-6,
        "trajectories pass their crossings exactly",
    ),
    at_most(
        "max_border_velocity_jump",
        1e-6,
        "no velocity jump at a border",
    ),
    // What ships, read as an engine reads it.
    at_most("library_collisions", 0.0, "no collision in library.crowd"),
    at_most("gltf_collisions", 0.0, "no collision in world.glb"),
    at_most(
        "library_share_above_speed_limit",
        0.0,
        "no walker in library.crowd faster than match.max_speed + 5 %",
    ),
    at_most(
        "gltf_share_above_speed_limit",
        0.0,
        "no walker in world.glb faster than match.max_speed + 5 %",
    ),
    at_most(
        "library_open_loops",
        0.0,
        "every loop of library.crowd closes",
    ),
    at_most("gltf_open_loops", 0.0, "every node of world.glb hands over"),
    at_most(
        "library_sampler_jumps",
        0.0,
        "the runtime's sampler shows no jump",
    ),
];

/// Figures that the check writes as `null` when no pair came within reach of each other: kept
/// by a sparse painting (random painting 138 of `--max-patches 12`: 4 walkers in 20 patches).
const NULL_WHEN_NOBODY_NEAR: [&str; 1] = ["min_clearance_m"];

/// Every guarantee the figures break, each as one line; empty when the build keeps them all.
/// A figure that is missing breaks its guarantee: a check that did not run proves nothing.
/// (A clearance measured as `null` is not missing: nobody came near anybody.)
pub fn broken(figures: &Value) -> Vec<String> {
    GUARANTEES
        .iter()
        .filter_map(|b| {
            let figure = figures.get(b.key);
            if figure.is_some_and(Value::is_null) && NULL_WHEN_NOBODY_NEAR.contains(&b.key) {
                return None;
            }
            let Some(v) = figure.and_then(Value::as_f64) else {
                return Some(format!("{}: missing ({})", b.key, b.what));
            };
            let ok = if b.at_most {
                v <= b.limit
            } else {
                v >= b.limit
            };
            (!ok).then(|| {
                let rel = if b.at_most { "at most" } else { "at least" };
                format!("{} = {v} ({}: {rel} {})", b.key, b.what, b.limit)
            })
        })
        .collect()
}

/// Whether the broken guarantees are all excused by the build's warnings (its stderr): only
/// the speed limit, where a warning names a patch whose walkers had to hurry. A painting that
/// asks for more than walking pace allows may be met so, if the build says where.
pub fn excused(broken: &[String], stderr: &str) -> bool {
    let only_speed = broken.iter().all(|b| b.contains("share_above_speed_limit"));
    let hurried = stderr
        .lines()
        .any(|l| l.starts_with("warning: ") && l.contains(" runs at "));
    broken.is_empty() || (only_speed && hurried)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn clean() -> Value {
        json!({
            "collisions": 0, "min_clearance_m": 0.001, "unconverged_patches": 0,
            "unmatched_crossings": 0, "max_boundary_error_m": 0.0,
            "max_border_velocity_jump": 1e-12,
            "library_collisions": 0, "gltf_collisions": 0,
            "library_share_above_speed_limit": 0.0, "gltf_share_above_speed_limit": 0.0,
            "library_open_loops": 0, "gltf_open_loops": 0, "library_sampler_jumps": 0,
        })
    }

    #[test]
    fn a_clean_build_keeps_every_guarantee() {
        assert!(broken(&clean()).is_empty(), "{:?}", broken(&clean()));
    }

    #[test]
    fn each_broken_or_missing_figure_is_named() {
        for (key, bad) in [
            ("collisions", json!(2)),
            ("min_clearance_m", json!(-0.2)),
            ("unconverged_patches", json!(1)),
            ("max_border_velocity_jump", json!(0.5)),
            ("library_collisions", json!(3)),
            ("gltf_share_above_speed_limit", json!(0.001)),
            ("gltf_open_loops", json!(4)),
        ] {
            let mut figures = clean();
            figures[key] = bad;
            let b = broken(&figures);
            assert!(b.len() == 1 && b[0].starts_with(key), "{key}: {b:?}");
            figures.as_object_mut().unwrap().remove(key);
            assert!(broken(&figures)[0].contains("missing"));
        }
    }

    #[test]
    fn a_painting_where_nobody_comes_near_anybody_keeps_the_clearance() {
        let mut figures = clean();
        figures["min_clearance_m"] = Value::Null;
        assert!(broken(&figures).is_empty(), "{:?}", broken(&figures));
        // Not measured at all is still missing, and a null that means nothing is refused.
        figures.as_object_mut().unwrap().remove("min_clearance_m");
        assert!(broken(&figures)[0].contains("missing"));
        let mut figures = clean();
        figures["collisions"] = Value::Null;
        assert!(broken(&figures)[0].contains("missing"));
    }
}
