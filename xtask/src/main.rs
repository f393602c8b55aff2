//! `cargo xtask`: the project's own commands (matklad's cargo-xtask pattern).
//!
//! - `cargo xtask build-crowd [--pipeline FILE] [crowd build flags]`: builds the crowd described
//!   by `pipeline.ron` (or FILE) with the release `crowd` binary.
//! - `cargo xtask bench`: runs the criterion benchmarks.
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
  bench [criterion args]
      run the benchmarks (figures go to BENCHMARKS.md by hand)
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
        Some("bench") => {
            command.arg("bench").arg("--manifest-path").arg(&manifest);
            command.args(["--package", "crowd", "--bench", "pipeline", "--"]);
            command.args(&rest);
        }
        Some("scenes") => return scenes(&cargo, &root),
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

/// Builds every scene pipeline with `--force` and prints the table of their figures.
fn scenes(cargo: &str, root: &std::path::Path) -> ExitCode {
    let status = Command::new(cargo)
        .args([
            "build",
            "--release",
            "--quiet",
            "--bin",
            "crowd",
            "--manifest-path",
        ])
        .arg(root.join("Cargo.toml"))
        .status();
    if !status.is_ok_and(|s| s.success()) {
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
