//! Hostile settings, one at a time, as a studio's unattended build would meet them: the real
//! binary under a 6 GiB address-space cap and a time limit. Each case ends with the exit code
//! it should, a first line that names the setting, no panic, and no output folder left behind
//! when it is refused; a legal extreme finishes within the limit.
//!
//! `cargo test --test tests hostile -- --nocapture` prints the table (case, exit code, first
//! line of the message).

use crate::settings::broken;
use crate::util::*;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// The address space the binary may take (`ulimit -v`, KiB): 6 GiB.
const MEMORY_KIB: u64 = 6 << 20;
/// A case still running after this long is a failure (each takes well under a second today).
const TIME_LIMIT: Duration = Duration::from_secs(60);

const BANDS: &str = "assets/pipelines/bands.ron";

/// Runs `crowd args` under the memory cap, killed at the time limit (`None` then).
fn capped(args: &[&str]) -> Option<Output> {
    let script = format!("ulimit -v {MEMORY_KIB} && exec \"$0\" \"$@\"");
    let mut child = Command::new("sh")
        .arg("-c")
        .arg(script)
        .arg(env!("CARGO_BIN_EXE_crowd"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("sh runs");
    let start = Instant::now();
    while child.try_wait().expect("waitable").is_none() {
        if start.elapsed() > TIME_LIMIT {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    Some(child.wait_with_output().expect("output"))
}

/// One case: a pipeline (written into `dir`) and extra arguments before `build`.
struct Case {
    name: &'static str,
    /// The shipped pipeline with one field set, or with one text replaced.
    change: Change,
    threads: Option<&'static str>,
    /// Flags of `crowd build`.
    flags: &'static [&'static str],
    code: i32,
    /// What the message's first line must hold (for a refusal), or what stderr holds.
    said: &'static str,
}

enum Change {
    Field(&'static str, &'static str),
    Text(&'static str, &'static str),
}

fn case(name: &'static str, field: &'static str, value: &'static str, said: &'static str) -> Case {
    Case {
        name,
        change: Change::Field(field, value),
        threads: None,
        flags: &[],
        code: 1,
        said,
    }
}

fn cases() -> Vec<Case> {
    vec![
        case(
            "period_s: 1e300",
            "period_s",
            "1e300",
            "`period_s` is 1e300",
        ),
        case("period_s: 1e5", "period_s", "1e5", "`period_s` is 100000"),
        case("period_s: 1e-9", "period_s", "1e-9", "`period_s` is 1e-9"),
        case(
            "smooth: (tack_spacing_s: 1e-9)",
            "smooth.tack_spacing_s",
            "1e-9",
            "`smooth.tack_spacing_s` is 1e-9",
        ),
        case(
            "patch_side_m: 1.0",
            "patch_side_m",
            "1.0",
            "`patch_side_m` is 1",
        ),
        case(
            "patch_side_m: 100.0 (maps 160 x 80 m)",
            "patch_side_m",
            "100.0",
            "smaller than one patch of 100 m",
        ),
        case(
            "radius_m: 2.0",
            "radius_m",
            "2.0",
            "`patch_side_m` is 8; expected from 16 to 100 m",
        ),
        case(
            "walkers: 1e9",
            "walkers",
            "1000000000",
            "`walkers` is 1000000000: with 0 standers over a 20 s period the build needs",
        ),
        case(
            "optimize: (tolerance: NaN)",
            "optimize.tolerance",
            "NaN",
            "`optimize.tolerance` is NaN",
        ),
        case(
            "optimize: (max_iterations: 4e9)",
            "optimize.max_iterations",
            "4000000000",
            "`optimize.max_iterations` is 4000000000",
        ),
        case(
            "collide: (max_iterations: 4e9)",
            "collide.max_iterations",
            "4000000000",
            "`collide.max_iterations` is 4000000000",
        ),
        case(
            "graph: (min_opening_m: Some(1e300))",
            "graph.min_opening_m",
            "Some(1e300)",
            "`graph.min_opening_m` is 1e300",
        ),
        case(
            "export: (gltf_region: NaN)",
            "export.gltf_region",
            "Some((NaN, 0.0, 10.0, 10.0))",
            "`export.gltf_region` is (NaN, 0, 10, 10)",
        ),
        case(
            "export: (gltf_region: inverted)",
            "export.gltf_region",
            "Some((10.0, 0.0, 0.0, 10.0))",
            "`export.gltf_region` is (10, 0, 0, 10)",
        ),
        case(
            "export: (gltf_region: off the map)",
            "export.gltf_region",
            "Some((1000.0, 1000.0, 1010.0, 1010.0))",
            "`export.gltf_region`",
        ),
        case(
            "scene: (meters_per_pixel: 8.0): too sparse",
            "scene.meters_per_pixel",
            "8.0",
            "stage 3 placed no walker",
        ),
        Case {
            name: "a layer with weight: 1e39",
            change: Change::Text("density.png\")", "density.png\", weight: 1e39)"),
            threads: None,
            flags: &[],
            code: 1,
            said: "`scene.layers[0].weight` is 1e39",
        },
        Case {
            name: "--threads 1000",
            change: Change::Field("walkers", "1100"),
            threads: Some("1000"),
            flags: &[],
            code: 0,
            said: "note: --threads 1000: using",
        },
        Case {
            name: "--max-memory 50M",
            change: Change::Field("walkers", "1100"),
            threads: None,
            flags: &["--max-memory", "50M"],
            code: 1,
            said: "`walkers` is 1100: with 0 standers over a 20 s period the build needs about",
        },
    ]
}

/// Runs one case in `dir`; the row of the table, or what went wrong.
fn run(c: &Case, dir: &Path) -> Result<String, String> {
    let (pipeline, _) = match c.change {
        Change::Field(field, value) => broken(dir, BANDS, field, value),
        Change::Text(from, to) => {
            let (path, line) = broken(dir, BANDS, "walkers", "1100");
            let text = std::fs::read_to_string(&path).unwrap();
            assert!(text.contains(from), "{}: no {from:?} in {text}", c.name);
            std::fs::write(&path, text.replace(from, to)).unwrap();
            (path, line)
        }
    };
    let mut args: Vec<&str> = Vec::new();
    if let Some(n) = c.threads {
        args.extend(["--threads", n]);
    }
    args.extend(["build", "--pipeline", s(&pipeline)]);
    args.extend(c.flags);
    let Some(out) = capped(&args) else {
        return Err(format!("{}: still running after {TIME_LIMIT:?}", c.name));
    };
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    // The message (progress lines of the stages that ran come before it).
    let first = stderr
        .lines()
        .find(|l| l.starts_with("error: ") || l.starts_with("note: "))
        .unwrap_or_default()
        .to_string();
    let code = out.status.code();
    let wrong = |why: &str| {
        Err(format!(
            "{}: {why}; exit {code:?}, stderr:\n{stderr}",
            c.name
        ))
    };
    if code != Some(c.code) {
        return wrong(&format!("expected exit {}", c.code));
    }
    if stderr.contains("panicked") {
        return wrong("panicked");
    }
    if c.code == 1 {
        if !(first.starts_with("error: ") && first.contains(c.said)) {
            return wrong(&format!("expected a first line with {:?}", c.said));
        }
        if dir.join("out").exists() {
            return wrong("refused, but its output folder was left");
        }
    } else if !stderr.contains(c.said) {
        return wrong(&format!("expected {:?}", c.said));
    }
    let shown: String = first.chars().take(110).collect();
    Ok(format!("| {} | {} | {} |", c.name, c.code, shown))
}

#[test]
fn hostile_settings_end_in_a_clear_error_or_a_crowd_within_time_and_memory() {
    let mut rows = vec![
        "| case | exit | first line |".to_string(),
        "| --- | ---: | --- |".to_string(),
    ];
    let mut failed = Vec::new();
    for c in cases() {
        let dir = tempfile::tempdir().unwrap();
        match run(&c, dir.path()) {
            Ok(row) => rows.push(row),
            Err(e) => failed.push(e),
        }
    }
    println!("{}", rows.join("\n"));
    assert!(failed.is_empty(), "{}", failed.join("\n\n"));
}

/// Settings drawn anywhere in their documented ranges, on a small painting (bands' density at
/// a quarter metre a pixel: 40 x 20 m): whatever the validator accepts builds within the time
/// limit and the memory cap, and whatever it refuses is refused with an error, never a panic.
mod any_settings {
    use super::*;
    use proptest::prelude::*;

    /// A pipeline text: the settings, over bands' density.
    #[allow(clippy::too_many_arguments)]
    fn pipeline(
        (period, side, radius, walkers): (f64, f64, f64, u32),
        (rho_max, opt_iterations, patience, tolerance): (f64, u32, u32, f64),
        pushes: u32,
        (tack, max_speed): (f64, f64),
    ) -> String {
        let layer = shared_scenes().join("bands/density.png");
        format!(
            "(\n    scene: (meters_per_pixel: 0.25, layers: [(kind: Density, path: {:?})]),\n    \
             walkers: {walkers},\n    standers: 0,\n    patch_side_m: {side},\n    \
             period_s: {period},\n    radius_m: {radius},\n    seed: 3,\n    output: \"out\",\n    \
             optimize: (rho_max: {rho_max}, max_iterations: {opt_iterations}, patience: \
             {patience}, tolerance: {tolerance}),\n    match: (max_speed: {max_speed}),\n    \
             collide: (max_iterations: {pushes}),\n    smooth: (tack_spacing_s: {tack}),\n)\n",
            s(&layer)
        )
    }

    proptest! {
        // Each case is a real build of up to a minute: no shrinking (it would rerun them).
        #![proptest_config(ProptestConfig {
            cases: 8,
            max_shrink_iters: 0,
            // A fixed draw in CI (`CROWD_SETTINGS_SEED` draws others).
            rng_seed: proptest::test_runner::RngSeed::Fixed(
                std::env::var("CROWD_SETTINGS_SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(2026),
            ),
            failure_persistence: None,
            ..ProptestConfig::default()
        })]
        #[test]
        fn accepted_settings_build_in_bounded_time_and_refused_ones_say_why(
            // Whole pixels of a patch side, as the graph asks.
            top in (1u32..=6000, 10u32..48, 0.15f64..0.5, 1u32..400)
                .prop_map(|(p, px, r, w)| (f64::from(p) / 10.0, f64::from(px) / 4.0, r, w)),
            opt in (0.05f64..1.0, 1u32..=600, 1u32..=100, 0.0f64..0.05),
            pushes in 1u32..=20_000,
            smooth in (0.05f64..2.0, 1.5f64..3.0),
        ) {
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("pipeline.ron");
            let text = pipeline(top, opt, pushes, smooth);
            std::fs::write(&path, &text).unwrap();
            let start = Instant::now();
            let out = capped(&["build", "-q", "--no-check", "--pipeline", s(&path)]);
            let took = start.elapsed();
            let Some(out) = out else {
                return Err(TestCaseError::fail(format!("still running after {TIME_LIMIT:?}:\n{text}")));
            };
            let stderr = String::from_utf8_lossy(&out.stderr);
            println!("{:?} in {:.1} s: {}", out.status.code(), took.as_secs_f64(),
                stderr.lines().find(|l| !l.starts_with(' ')).unwrap_or_default());
            prop_assert!(!stderr.contains("panicked"), "{}", stderr);
            match out.status.code() {
                Some(0) | Some(3) => {}
                Some(1) => prop_assert!(stderr.lines().any(|l| l.starts_with("error: ")), "{}", stderr),
                other => prop_assert!(false, "exit {:?} after {:?}: {}", other, took, stderr),
            }
        }
    }
}
