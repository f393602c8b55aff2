//! `crowd-paintings`: writes the random painting of a seed (`write`), or builds many through
//! the real `crowd` binary and holds each to the guarantees (`soak`, run by `cargo xtask soak`).
//! A failing scene's folder is kept and its seed printed, so anyone can rebuild it.

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use crowd_paintings::{Limits, brush, random, verdict};
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

#[derive(Parser)]
#[command(about = "Random paintings for tests and soaks")]
struct Cli {
    #[command(subcommand)]
    command: Task,
}

#[derive(Subcommand)]
enum Task {
    /// Write the painting of a seed (layers and pipeline.ron) into a folder.
    Write {
        #[arg(long)]
        seed: u64,
        #[arg(long, default_value_t = 12)]
        max_patches: u32,
        #[arg(long)]
        out: PathBuf,
    },
    /// Paint one brush stroke into a gray layer, in place: a full disc (what an artist's
    /// round brush leaves), to time the rebuild it causes.
    Stroke {
        /// The gray PNG layer to paint on.
        #[arg(long)]
        layer: PathBuf,
        /// The disc's centre, in pixels from the top-left corner: `X,Y`.
        #[arg(long, value_parser = parse_point)]
        at: (f64, f64),
        /// The disc's radius, in pixels.
        #[arg(long)]
        radius: f64,
        /// The gray level painted, 0-255.
        #[arg(long, default_value_t = 255)]
        level: u8,
    },
    /// Build the paintings of seeds FROM.. FROM+SCENES-1 and check every guarantee.
    Soak {
        /// The `crowd` binary to run.
        #[arg(long)]
        crowd: PathBuf,
        #[arg(long, default_value_t = 200)]
        scenes: u64,
        #[arg(long, default_value_t = 1)]
        from: u64,
        #[arg(long, default_value_t = 12)]
        max_patches: u32,
        /// Where the scenes are written; failing ones stay there.
        #[arg(long)]
        out: PathBuf,
    },
}

fn main() -> Result<()> {
    match Cli::parse().command {
        Task::Write {
            seed,
            max_patches,
            out,
        } => {
            let pipeline = random(seed, Limits { max_patches }).write(&out)?;
            println!("{}", pipeline.display());
            Ok(())
        }
        Task::Stroke {
            layer,
            at,
            radius,
            level,
        } => {
            let mut image = image::open(&layer)
                .with_context(|| format!("{}: not a readable image", layer.display()))?
                .to_luma8();
            let painted = brush::disc(&mut image, at.0, at.1, radius, level);
            image
                .save(&layer)
                .with_context(|| format!("{}: cannot write", layer.display()))?;
            println!("{}: {painted} pixels painted", layer.display());
            Ok(())
        }
        Task::Soak {
            crowd,
            scenes,
            from,
            max_patches,
            out,
        } => soak(&crowd, from..from + scenes, Limits { max_patches }, &out),
    }
}

/// `X,Y` as two numbers.
fn parse_point(text: &str) -> std::result::Result<(f64, f64), String> {
    let (x, y) = text
        .split_once(',')
        .ok_or_else(|| format!("expected X,Y, got {text:?}"))?;
    let number = |v: &str| {
        v.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("expected a number, got {v:?}"))
    };
    Ok((number(x)?, number(y)?))
}

/// What became of one painting.
enum Outcome {
    Kept,
    Refused(String),
    /// Built, with warnings on stderr for what it could not meet; no guarantee broken but the
    /// speed where a warning names the patch (its walkers had to hurry).
    Warned(Vec<String>),
    Broke(Vec<String>),
}

fn soak(crowd: &Path, seeds: std::ops::Range<u64>, limits: Limits, out: &Path) -> Result<()> {
    let bar = if std::io::stderr().is_terminal() {
        ProgressBar::new(seeds.end - seeds.start)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(ProgressStyle::with_template(
        "{bar:40} {pos}/{len} {elapsed} {msg}",
    )?);
    let (started, mut failed, mut refused, mut largest) = (Instant::now(), Vec::new(), 0, 0);
    let mut warned = 0;
    // A hidden bar drops its `println`s: without a terminal, lines go to stderr as they are.
    let say = |line: String| {
        if bar.is_hidden() {
            eprintln!("{line}");
        } else {
            bar.println(line);
        }
    };
    for seed in seeds.clone() {
        let painting = random(seed, limits);
        let dir = out.join(format!("seed-{seed}"));
        let pipeline = painting.write(&dir)?;
        let patches = painting.patches.0 * painting.patches.1;
        let t = Instant::now();
        let outcome = build_and_judge(crowd, &pipeline, &dir.join("out"))?;
        let line = format!(
            "seed {seed}: {} x {} patches, {} walkers, {:.1} s",
            painting.patches.0,
            painting.patches.1,
            painting.walkers,
            t.elapsed().as_secs_f64()
        );
        match outcome {
            Outcome::Kept => {
                largest = largest.max(patches);
                std::fs::remove_dir_all(&dir).ok();
            }
            Outcome::Refused(why) => {
                refused += 1;
                say(format!("{line}: refused: {why}"));
            }
            Outcome::Warned(what) => {
                warned += 1;
                largest = largest.max(patches);
                say(format!("{line}: warned\n  {}", what.join("\n  ")));
            }
            Outcome::Broke(what) => {
                say(format!("{line}: FAILED\n  {}", what.join("\n  ")));
                failed.push(seed);
            }
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    let n = seeds.end - seeds.start;
    println!(
        "{n} paintings in {:.0} s: {} kept every guarantee, {warned} said on stderr what they \
         could not meet, {refused} refused with an error, {} failed {failed:?}; largest built: \
         {largest} patches",
        started.elapsed().as_secs_f64(),
        n as usize - refused - warned - failed.len(),
        failed.len()
    );
    if !failed.is_empty() {
        bail!(
            "rebuild a failure with `crowd-paintings write --seed N --max-patches {} --out DIR` \
             and `crowd build --pipeline DIR/pipeline.ron`",
            limits.max_patches
        );
    }
    Ok(())
}

/// Builds, checks and judges one painting. A build that stops with a clear error is refused; a
/// panic, a crash or a broken guarantee is a failure.
fn build_and_judge(crowd: &Path, pipeline: &Path, out: &Path) -> Result<Outcome> {
    let run = |args: &[&str]| {
        Command::new(crowd)
            .args(args)
            .output()
            .with_context(|| format!("cannot run {}", crowd.display()))
    };
    let p = pipeline.to_str().context("utf-8 paths")?;
    let o = out.to_str().context("utf-8 paths")?;
    // `--force`: a folder left by an earlier soak (its failing and warned paintings stay) would
    // otherwise be up to date whenever a stage changed without its version, and the soak would
    // judge the old build (it did: a soak of 2026-12-04 reported two refused paintings as warned).
    let build = run(&["build", "-q", "--force", "--pipeline", p])?;
    let stderr = String::from_utf8_lossy(&build.stderr).into_owned();
    if !build.status.success() {
        let clear =
            stderr.lines().any(|l| l.starts_with("error: ")) && !stderr.contains("panicked");
        return Ok(if clear {
            Outcome::Refused(stderr.lines().next().unwrap_or("").to_string())
        } else {
            Outcome::Broke(vec![format!("the build crashed: {stderr}")])
        });
    }
    // `crowd build` checked what it shipped (`check.ron`).
    let report = run(&["report", "--json", o])?;
    let figures: serde_json::Value =
        serde_json::from_slice(&report.stdout).context("crowd report --json prints JSON")?;
    let broken = verdict::broken(&figures);
    let warnings: Vec<String> = stderr
        .lines()
        .filter(|l| l.starts_with("warning: "))
        .map(str::to_string)
        .collect();
    Ok(if broken.is_empty() && warnings.is_empty() {
        Outcome::Kept
    } else if verdict::excused(&broken, &stderr) {
        Outcome::Warned(warnings)
    } else {
        Outcome::Broke(broken.into_iter().chain(warnings).collect())
    })
}
