//! `cargo xtask`: the project's own commands (matklad's cargo-xtask pattern).
//!
//! - `cargo xtask build-crowd [--pipeline FILE] [crowd build flags]`: builds the crowd described
//!   by `pipeline.ron` (or FILE) with the release `crowd` binary.
//! - `cargo xtask bench`: runs the criterion benchmarks.
//!
//! Kept light on purpose: no dependencies, cargo is found through the `CARGO` variable.

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
    let mut command = Command::new(cargo);
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
