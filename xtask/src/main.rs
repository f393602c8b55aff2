//! `cargo xtask`: the project's own commands (matklad's cargo-xtask pattern).
//!
//! - `cargo xtask build-crowd [--pipeline FILE] [crowd build flags]`: builds the crowd described
//!   by `pipeline.ron` (or FILE) with the release `crowd` binary.
//! - `cargo xtask bench [pipeline|collide|runtime|all] [criterion args]`: runs one criterion
//!   benchmark, or all three in turn (the default).
//!
//! - `cargo xtask soak [--scenes N] [--from SEED] [--max-patches P]`: random paintings through
//!   the whole pipeline, each held to every guarantee (`crowd-paintings soak`).
//!
//! - `cargo xtask fuzz [--minutes N]`: each fuzz target of `tests/fuzz.rs` (the pipeline
//!   parser, every stage file's reader, the library and the glTF) for N minutes.
//!
//! Kept light on purpose: no dependencies, cargo is found through the `CARGO` variable.

#[cfg(test)]
mod tidy;

use std::env;
use std::path::PathBuf;
use std::process::{Command, ExitCode};

const HELP: &str = "\
usage: cargo xtask <task> [args]

tasks:
  build-crowd [--pipeline FILE] [--force] [--quiet] [--threads N]
      build the crowd of pipeline.ron (or FILE) with the release `crowd` binary;
      stages whose output is up to date are skipped
  bench [pipeline|collide|runtime|all] [criterion args]
      run a criterion benchmark (figures go to BENCHMARKS.md by hand):
        pipeline  merge + graph of painting and city, in memory (crates/cli/benches)
        collide   stage 5 on 1000 random patches (crates/collide/benches)
        runtime   one frame of the runtime over painting's 100k walkers (crates/runtime/benches);
                  build its library first: cargo xtask build-crowd --pipeline
                  assets/bench/painting-100k.ron (BENCHMARKS.md pins it to one core with taskset)
        all       the three in turn (the default)
  bench viewer [BUILD_DIR]
      time `crowd view`'s sampler over BUILD_DIR's library (default build/painting, built
      from assets/pipelines/painting.ron when missing): in Node (viewer/test/bench.mjs), then
      in headless Chromium with software GL (viewer/test/e2e.mjs bench); prints both as JSON
      (needs the viewer's npm packages and /usr/bin/chromium, as .ci/run installs them)
  soak [--scenes N] [--from SEED] [--max-patches P]
      build N random paintings (default 200, seeds SEED.., up to P x P patches, default 12)
      with the release `crowd`, check each and hold it to every guarantee; failing scenes stay
      in target/soak/seed-N and their seeds are printed
  fuzz [--minutes N]
      run each proptest fuzz target of tests/fuzz.rs (pipeline.ron, every stage file, the
      library, the glTF world) for N minutes (default 10), four at a time; prints the cases run
  scenes
      build every pipeline of assets/pipelines/ from scratch (release) and print the
      Table 1 figures of each as markdown
";

fn main() -> ExitCode {
    let mut args = env::args().skip(1);
    let task = args.next();
    let rest: Vec<String> = args.collect();
    let cargo = env::var("CARGO").unwrap_or_else(|_| "cargo".to_string());
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("xtask lives in the workspace")
        .to_path_buf();
    let mut command = Command::new(&cargo);
    let manifest = root.join("Cargo.toml");
    match task.as_deref() {
        Some("build-crowd") => {
            // Relative paths given by the user stay relative to where they ran the command;
            // the default pipeline is the workspace's own.
            command.arg("run").arg("--manifest-path").arg(&manifest);
            command.args(["--release", "--quiet", "--bin", "crowd", "--", "build"]);
            if !rest
                .iter()
                .any(|a| a == "--pipeline" || a.starts_with("--pipeline="))
            {
                command.arg("--pipeline").arg(root.join("pipeline.ron"));
            }
            command.args(&rest);
        }
        Some("bench") => return bench(&cargo, &manifest, &rest),
        Some("scenes") => return scenes(&cargo, &root),
        Some("soak") => return soak(&cargo, &root, &rest),
        Some("fuzz") => {
            let minutes: u64 = match rest.as_slice() {
                [] => 10,
                [flag, n] if flag == "--minutes" && n.parse::<u64>().is_ok() => {
                    n.parse().expect("checked")
                }
                _ => {
                    eprint!("usage: cargo xtask fuzz [--minutes N]\n\n{HELP}");
                    return ExitCode::FAILURE;
                }
            };
            command.arg("test").arg("--manifest-path").arg(&manifest);
            command.args(["--release", "--test", "tests", "fuzz::", "--"]);
            command.args(["--nocapture", "--test-threads", "4"]);
            command.env("CROWD_FUZZ_SECONDS", (minutes * 60).to_string());
        }
        Some("help" | "--help" | "-h") => {
            print!("{HELP}");
            return ExitCode::SUCCESS;
        }
        other => {
            eprint!("unknown task {other:?}\n\n{HELP}");
            return ExitCode::FAILURE;
        }
    }
    match command.status() {
        Ok(status) if status.success() => ExitCode::SUCCESS,
        Ok(status) => ExitCode::from(status.code().unwrap_or(1).clamp(1, 255) as u8),
        Err(e) => {
            eprintln!("cannot run cargo: {e}");
            ExitCode::FAILURE
        }
    }
}

/// The criterion benchmarks: a name for `cargo xtask bench`, its package and its bench target.
const BENCHES: &[(&str, &str, &str)] = &[
    ("pipeline", "crowd", "pipeline"),
    ("collide", "crowd-collide", "random_patches"),
    ("runtime", "crowd-runtime", "sample"),
];

/// Runs the benchmark named by the first argument (all of them if it names none), passing the
/// other arguments to criterion.
fn bench(cargo: &str, manifest: &std::path::Path, args: &[String]) -> ExitCode {
    if args.first().is_some_and(|a| a == "viewer") {
        let root = manifest.parent().expect("the manifest is in the workspace");
        return bench_viewer(cargo, root, args.get(1).map(PathBuf::from));
    }
    let (which, criterion) = match args.first().map(String::as_str) {
        Some("all") => (None, &args[1..]),
        Some(name) if !name.starts_with('-') => {
            if !BENCHES.iter().any(|(n, _, _)| *n == name) {
                eprint!("unknown benchmark {name:?}\n\n{HELP}");
                return ExitCode::FAILURE;
            }
            (Some(name), &args[1..])
        }
        _ => (None, args),
    };
    for (name, package, target) in BENCHES {
        if which.is_some_and(|w| w != *name) {
            continue;
        }
        eprintln!("bench {name}: cargo bench --package {package} --bench {target}");
        let status = Command::new(cargo)
            .arg("bench")
            .arg("--manifest-path")
            .arg(manifest)
            .args(["--package", package, "--bench", target, "--"])
            .args(criterion)
            .status();
        match status {
            Ok(s) if s.success() => {}
            Ok(s) => return ExitCode::from(s.code().unwrap_or(1).clamp(1, 255) as u8),
            Err(e) => {
                eprintln!("cannot run cargo: {e}");
                return ExitCode::FAILURE;
            }
        }
    }
    ExitCode::SUCCESS
}

/// `cargo xtask bench viewer`: the page's sampler in Node and in headless Chromium.
fn bench_viewer(cargo: &str, root: &std::path::Path, dir: Option<PathBuf>) -> ExitCode {
    if !build_release_crowd(cargo, root) {
        eprintln!("cannot build crowd");
        return ExitCode::FAILURE;
    }
    let crowd = root.join("target/release/crowd");
    let dir = dir.unwrap_or_else(|| root.join("build/painting"));
    if !dir.join("library.crowd").exists() {
        eprintln!("building {}", dir.display());
        let built = Command::new(&crowd)
            .args(["build", "--quiet", "--pipeline"])
            .arg(root.join("assets/pipelines/painting.ron"))
            .arg("--output")
            .arg(&dir)
            .status()
            .is_ok_and(|s| s.success());
        if !built {
            eprintln!("cannot build {}", dir.display());
            return ExitCode::FAILURE;
        }
    }
    let node = |args: &[&std::ffi::OsStr]| {
        Command::new("node")
            .args(args)
            .current_dir(root.join("viewer"))
            .status()
            .is_ok_and(|s| s.success())
    };
    let library = dir.join("library.crowd");
    eprintln!("sampling in Node (600 frames at 60 fps of crowd time)");
    if !node(&[
        "test/bench.mjs".as_ref(),
        library.as_os_str(),
        "600".as_ref(),
    ]) {
        eprintln!("node viewer/test/bench.mjs failed (run npm ci --prefix viewer first)");
        return ExitCode::FAILURE;
    }
    let mut server = match Command::new(&crowd)
        .args(["view", "--no-open"])
        .arg(&dir)
        .stdout(std::process::Stdio::piped())
        .spawn()
    {
        Ok(child) => child,
        Err(e) => {
            eprintln!("cannot start crowd view: {e}");
            return ExitCode::FAILURE;
        }
    };
    // Its first line names the address it serves.
    let mut line = String::new();
    let stdout = server.stdout.take().expect("piped");
    let _ = std::io::BufRead::read_line(&mut std::io::BufReader::new(stdout), &mut line);
    let address = line.split_whitespace().find(|w| w.starts_with("http://"));
    let ok = match address {
        Some(address) => {
            eprintln!("sampling and drawing in headless Chromium at {address}");
            node(&[
                "test/e2e.mjs".as_ref(),
                "bench".as_ref(),
                address.as_ref(),
                "240".as_ref(),
            ])
        }
        None => {
            eprintln!("crowd view printed no address: {line:?}");
            false
        }
    };
    let _ = server.kill();
    let _ = server.wait();
    if ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}

/// Builds every scene pipeline with `--force` and prints the table of their figures.
fn scenes(cargo: &str, root: &std::path::Path) -> ExitCode {
    if !build_release_crowd(cargo, root) {
        eprintln!("cannot build crowd");
        return ExitCode::FAILURE;
    }
    let crowd = root.join("target/release/crowd");
    let mut pipelines: Vec<PathBuf> = match std::fs::read_dir(root.join("assets/pipelines")) {
        Ok(dir) => dir.filter_map(|e| e.ok().map(|e| e.path())).collect(),
        Err(e) => {
            eprintln!("assets/pipelines: {e}");
            return ExitCode::FAILURE;
        }
    };
    pipelines.sort();
    let mut dirs = Vec::new();
    for p in &pipelines {
        let name = p
            .file_stem()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned();
        let out = root.join("build").join(&name);
        eprintln!("building {name}");
        let ok = Command::new(&crowd)
            .args(["build", "--force", "--quiet", "--pipeline"])
            .arg(p)
            .arg("--output")
            .arg(&out)
            .status()
            .is_ok_and(|s| s.success());
        if !ok {
            eprintln!("{name}: build failed");
            return ExitCode::FAILURE;
        }
        dirs.push(out);
    }
    let ok = Command::new(&crowd)
        .args(["report", "--table"])
        .args(&dirs)
        .status()
        .is_ok_and(|s| s.success());
    if ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}

/// `cargo xtask soak`: the release `crowd` over many random paintings (`crowd-paintings soak`).
fn soak(cargo: &str, root: &std::path::Path, rest: &[String]) -> ExitCode {
    let manifest = root.join("Cargo.toml");
    if !build_release_crowd(cargo, root) {
        eprintln!("cannot build crowd");
        return ExitCode::FAILURE;
    }
    let ok = Command::new(cargo)
        .args([
            "run",
            "--release",
            "--quiet",
            "-p",
            "crowd-paintings",
            "--manifest-path",
        ])
        .arg(&manifest)
        .args(["--", "soak", "--crowd"])
        .arg(root.join("target/release/crowd"))
        .arg("--out")
        .arg(root.join("target/soak"))
        .args(rest)
        .status()
        .is_ok_and(|s| s.success());
    if ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}

/// Builds the release `crowd` binary (`target/release/crowd`); whether it succeeded.
fn build_release_crowd(cargo: &str, root: &std::path::Path) -> bool {
    Command::new(cargo)
        .args([
            "build",
            "--release",
            "--quiet",
            "--bin",
            "crowd",
            "--manifest-path",
        ])
        .arg(root.join("Cargo.toml"))
        .status()
        .is_ok_and(|s| s.success())
}
