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
const GUARANTEES: [Bound; 6] = [
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
];

/// Every guarantee the figures break, each as one line; empty when the build keeps them all.
/// A figure that is missing breaks its guarantee: a check that did not run proves nothing.
pub fn broken(figures: &Value) -> Vec<String> {
    GUARANTEES
        .iter()
        .filter_map(|b| {
            let Some(v) = figures.get(b.key).and_then(Value::as_f64) else {
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

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn clean() -> Value {
        json!({
            "collisions": 0, "min_clearance_m": 0.001, "unconverged_patches": 0,
            "unmatched_crossings": 0, "max_boundary_error_m": 0.0,
            "max_border_velocity_jump": 1e-12,
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
        ] {
            let mut figures = clean();
            figures[key] = bad;
            let b = broken(&figures);
            assert!(b.len() == 1 && b[0].starts_with(key), "{key}: {b:?}");
            figures.as_object_mut().unwrap().remove(key);
            assert!(broken(&figures)[0].contains("missing"));
        }
    }
}
