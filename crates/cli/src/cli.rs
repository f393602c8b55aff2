//! Command-line arguments and what each subcommand does.

use crate::driver::{self, BuildOptions, GRAPH_FILE, MERGE_FILE};
use crate::ui::Ui;
use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use crowd_core::PatchGraph;
use crowd_core::config::PipelineFile;
use crowd_core::files::{read_bytes, write_all};
use crowd_core::patterns::Patterns;
use crowd_core::trajectories::TrajectoriesFile;
use std::path::PathBuf;

#[derive(Debug, Parser)]
#[command(
    name = "crowd",
    version,
    about = "The crowd-patches asset compiler: painted layers in, endless collision-free crowds out."
)]
pub struct Cli {
    /// Print nothing but results and errors; no progress bars.
    #[arg(long, short, global = true)]
    pub quiet: bool,
    /// Worker threads (default: one per core). Outputs are identical for any count.
    #[arg(long, global = true, value_name = "N")]
    pub threads: Option<usize>,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run every stage in order, skipping the ones whose output is up to date.
    Build {
        #[arg(long, default_value = "pipeline.ron", value_name = "FILE")]
        pipeline: PathBuf,
        /// Rebuild every stage even when its output is up to date.
        #[arg(long)]
        force: bool,
        /// Write the stage files here instead of the pipeline's `output` folder.
        #[arg(long, short, value_name = "DIR")]
        output: Option<PathBuf>,
        /// Stop after this stage.
        #[arg(long, value_enum, value_name = "STAGE")]
        until: Option<driver::Stage>,
    },
    /// Stage 1: merge the painted layers into grids.
    Merge {
        #[arg(long, default_value = "pipeline.ron", value_name = "FILE")]
        pipeline: PathBuf,
        /// Output file (default: `merge.ron` in the pipeline's output folder).
        #[arg(long, short, value_name = "FILE")]
        output: Option<PathBuf>,
    },
    /// Stage 2: cut the merged grids into the patch graph.
    Graph {
        #[arg(long, default_value = "pipeline.ron", value_name = "FILE")]
        pipeline: PathBuf,
        /// Stage 1's file (default: `merge.ron` in the pipeline's output folder).
        #[arg(long, short, value_name = "FILE")]
        input: Option<PathBuf>,
        /// Output file (default: `graph.ron` in the pipeline's output folder).
        #[arg(long, short, value_name = "FILE")]
        output: Option<PathBuf>,
    },
    /// Stage 3: place the crossings of every border (reads the graph).
    Optimize {
        #[arg(long, default_value = "pipeline.ron", value_name = "FILE")]
        pipeline: PathBuf,
        /// Stage 2's file (default: `graph.ron` in the pipeline's output folder).
        #[arg(long, short, value_name = "FILE")]
        input: Option<PathBuf>,
        /// Output file (default: `patterns.ron` in the pipeline's output folder).
        #[arg(long, short, value_name = "FILE")]
        output: Option<PathBuf>,
    },
    /// Stage 4: match entries with exits, straight lines and standers (reads the graph and the
    /// patterns beside the input).
    Match {
        #[arg(long, default_value = "pipeline.ron", value_name = "FILE")]
        pipeline: PathBuf,
        /// Stage 3's file (default: `patterns.ron` in the pipeline's output folder); the graph
        /// is read from `graph.ron` beside it.
        #[arg(long, short, value_name = "FILE")]
        input: Option<PathBuf>,
        /// Output file (default: `trajectories.ron` in the pipeline's output folder).
        #[arg(long, short, value_name = "FILE")]
        output: Option<PathBuf>,
    },
    /// Stage 5: push walkers apart (reads the trajectories and the graph beside them).
    Collide {
        #[arg(long, default_value = "pipeline.ron", value_name = "FILE")]
        pipeline: PathBuf,
        /// Stage 4's file (default: `trajectories.ron` in the pipeline's output folder); the
        /// graph is read from `graph.ron` beside it.
        #[arg(long, short, value_name = "FILE")]
        input: Option<PathBuf>,
        /// Output file (default: `collided.ron` in the pipeline's output folder).
        #[arg(long, short, value_name = "FILE")]
        output: Option<PathBuf>,
    },
    /// Stage 6: smooth the walkers' paths (reads the collided trajectories, and the graph and
    /// patterns beside them).
    Smooth {
        #[arg(long, default_value = "pipeline.ron", value_name = "FILE")]
        pipeline: PathBuf,
        /// Stage 5's file (default: `collided.ron` in the pipeline's output folder); the graph
        /// and patterns are read from `graph.ron` and `patterns.ron` beside it.
        #[arg(long, short, value_name = "FILE")]
        input: Option<PathBuf>,
        /// Output file (default: `smoothed.ron` in the pipeline's output folder).
        #[arg(long, short, value_name = "FILE")]
        output: Option<PathBuf>,
    },
    /// Stage 8: export the final trajectories as a binary patch library for crowd-runtime
    /// (reads the smoothed trajectories, and the graph and patterns beside them).
    Export {
        #[arg(long, default_value = "pipeline.ron", value_name = "FILE")]
        pipeline: PathBuf,
        /// Stage 6's file (default: `smoothed.ron` in the pipeline's output folder); the graph
        /// and patterns are read from `graph.ron` and `patterns.ron` beside it.
        #[arg(long, short, value_name = "FILE")]
        input: Option<PathBuf>,
        /// Output manifest (default: `export.ron` in the pipeline's output folder); the
        /// library (`library.crowd`) is written beside it.
        #[arg(long, short, value_name = "FILE")]
        output: Option<PathBuf>,
        /// Put only this part of the world (world metres) in `world.glb`, in place of the
        /// pipeline's `export.gltf_region`: DCC tools slow down with tens of thousands of
        /// animated nodes. The library always holds the whole world.
        #[arg(long, value_name = "X0,Y0,X1,Y1", value_parser = parse_region)]
        region: Option<(f64, f64, f64, f64)>,
    },
    /// A readable summary of any stage file.
    Inspect { file: PathBuf },
    /// A picture of a stage file as PNG: merged maps, patch graph, error map and convergence,
    /// one patch's patterns and lines.
    Render {
        file: PathBuf,
        #[arg(long, short, value_name = "OUT.png")]
        output: PathBuf,
        /// For trajectories: the patch to draw (default: the busiest).
        #[arg(long, value_name = "ID")]
        patch: Option<u32>,
    },
    /// Check a build folder's world as an engine plays it: every pair, every time, across
    /// borders too; writes `check.ron` beside the stage files.
    Check {
        dir: PathBuf,
        /// The stage whose trajectories to check: match, collide or smooth (default: the latest
        /// in the folder).
        #[arg(long, value_name = "STAGE")]
        stage: Option<crate::driver::Stage>,
    },
    /// The figures of a build folder (`--json` for one JSON object).
    Report {
        /// Build folders (one for text and JSON; several for `--table`).
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        #[arg(long, conflicts_with = "table")]
        json: bool,
        /// One markdown row per build folder, in the shape of Crowd Art's Table 1.
        #[arg(long)]
        table: bool,
        /// Write `report.md` and its pictures into the folder, as `crowd build` does (for a
        /// folder built stage by stage).
        #[arg(long, conflicts_with_all = ["table", "json"])]
        markdown: bool,
    },
}

/// `--region x0,y0,x1,y1`: four numbers, x0 < x1 and y0 < y1.
fn parse_region(text: &str) -> Result<(f64, f64, f64, f64), String> {
    let numbers: Vec<f64> = text
        .split(',')
        .map(|n| n.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("expected four numbers x0,y0,x1,y1 in metres: {e}"))?;
    match numbers[..] {
        [x0, y0, x1, y1] if x0 < x1 && y0 < y1 => Ok((x0, y0, x1, y1)),
        [_, _, _, _] => Err("expected x0 < x1 and y0 < y1".into()),
        _ => Err(format!(
            "expected four numbers x0,y0,x1,y1 in metres, found {}",
            numbers.len()
        )),
    }
}

/// A trajectories file (of `stage` at `version`) and the graph and patterns beside it, with
/// their bytes for the input hash: what stages 6 and 8 read.
struct Beside {
    graph_bytes: Vec<u8>,
    graph: crowd_core::PatchGraph,
    patterns_bytes: Vec<u8>,
    crossings: Vec<crowd_core::patterns::Crossing>,
    file: TrajectoriesFile,
    motion: Vec<crowd_core::trajectories::PatchMotion>,
    input_bytes: Vec<u8>,
}

impl Beside {
    fn load(input: &std::path::Path, stage: &str, version: u32) -> Result<Beside> {
        let (graph_bytes, graph) = graph_beside(input)?;
        let patterns_path = input.with_file_name(driver::PATTERNS_FILE);
        let (_, crossings) = Patterns::load_for(&patterns_path, &graph)?;
        let patterns_bytes = read_bytes(&patterns_path)?;
        let (file, motion) =
            TrajectoriesFile::load_for(input, stage, version, graph.patches.len())?;
        let input_bytes = read_bytes(input)?;
        Ok(Beside {
            graph_bytes,
            graph,
            patterns_bytes,
            crossings,
            file,
            motion,
            input_bytes,
        })
    }
}

/// The pipeline of a single-stage command, its input file and its output file (defaults in the
/// pipeline's output folder), with the output's folder made ready.
fn stage_files(
    pipeline: &std::path::Path,
    input: Option<PathBuf>,
    output: Option<PathBuf>,
    default_input: &str,
    default_output: &str,
) -> Result<(PipelineFile, PathBuf, PathBuf)> {
    let p = PipelineFile::load(pipeline)?;
    let input = input.unwrap_or_else(|| p.output_dir().join(default_input));
    let out = output.unwrap_or_else(|| p.output_dir().join(default_output));
    driver::ensure_parent(&out)?;
    Ok((p, input, out))
}

/// The graph a stage file was built on (`graph.ron` beside it) and its bytes.
fn graph_beside(stage_file: &std::path::Path) -> Result<(Vec<u8>, PatchGraph)> {
    let path = stage_file.with_file_name(GRAPH_FILE);
    Ok((read_bytes(&path)?, PatchGraph::load(&path)?))
}

pub fn run(cli: Cli) -> Result<()> {
    if let Some(n) = cli.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n.max(1))
            .build_global()
            .context("cannot set up the worker threads")?;
    }
    let ui = Ui { quiet: cli.quiet };
    match cli.command {
        Command::Build {
            pipeline,
            force,
            output,
            until,
        } => {
            let out = match &output {
                Some(dir) => dir.clone(),
                None => PipelineFile::load(&pipeline)?.output_dir(),
            };
            let options = BuildOptions {
                force,
                output,
                until,
            };
            driver::build(&pipeline, &options, &ui)?;
            let report = crate::report_md::write(&out)?;
            ui.say(format!("  report: {}", report.display()));
        }
        Command::Merge { pipeline, output } => {
            let p = PipelineFile::load(&pipeline)?;
            let out = output.unwrap_or_else(|| p.output_dir().join(MERGE_FILE));
            driver::ensure_parent(&out)?;
            let bar = ui.stage_bar("merge");
            crowd_merge::run(&p, &out, &bar)?;
            ui.say(format!("merge: wrote {}", out.display()));
        }
        Command::Graph {
            pipeline,
            input,
            output,
        } => {
            let (p, input, out) = stage_files(&pipeline, input, output, MERGE_FILE, GRAPH_FILE)?;
            let bar = ui.stage_bar("graph");
            crowd_graph::run(&p, &input, &out, &bar)?;
            ui.say(format!("graph: wrote {}", out.display()));
        }
        Command::Optimize {
            pipeline,
            input,
            output,
        } => {
            let (p, input, out) =
                stage_files(&pipeline, input, output, GRAPH_FILE, driver::PATTERNS_FILE)?;
            let graph_bytes = read_bytes(&input)?;
            let graph = PatchGraph::load(&input)?;
            let inputs = crowd_optimize::inputs(&p);
            let hash = crowd_optimize::input_hash(&graph_bytes, &inputs);
            let (outcome, _, writes) = driver::optimize_stage(&graph, &inputs, hash, &out, &ui);
            write_all(&writes)?;
            ui.say(format!(
                "optimize: wrote {} (E = {:.4})",
                out.display(),
                outcome.error.e
            ));
        }
        Command::Match {
            pipeline,
            input,
            output,
        } => {
            let (p, input, out) = stage_files(
                &pipeline,
                input,
                output,
                driver::PATTERNS_FILE,
                driver::TRAJECTORIES_FILE,
            )?;
            let (graph_bytes, graph) = graph_beside(&input)?;
            let (patterns, crossings) = Patterns::load_for(&input, &graph)?;
            let patterns_bytes = read_bytes(&input)?;
            let inputs = crowd_match::inputs(&p);
            let hash = crowd_match::input_hash(&graph_bytes, &patterns_bytes, &inputs);
            let (_, writes) =
                driver::match_stage(&graph, &patterns, &crossings, &inputs, hash, &out, &ui);
            write_all(&writes)?;
            ui.say(format!("match: wrote {}", out.display()));
        }
        Command::Collide {
            pipeline,
            input,
            output,
        } => {
            let (p, input, out) = stage_files(
                &pipeline,
                input,
                output,
                driver::TRAJECTORIES_FILE,
                driver::COLLIDED_FILE,
            )?;
            let (graph_bytes, graph) = graph_beside(&input)?;
            let (stage, version) = (TrajectoriesFile::STAGE, TrajectoriesFile::VERSION);
            let (_, motion) =
                TrajectoriesFile::load_for(&input, stage, version, graph.patches.len())?;
            let trajectories_bytes = read_bytes(&input)?;
            let inputs = driver::collide_inputs(&p);
            let hash = crowd_collide::input_hash(&graph_bytes, &trajectories_bytes, &inputs);
            let (_, _, writes) = driver::collide_stage(&graph, &motion, &inputs, hash, &out, &ui);
            write_all(&writes)?;
            ui.say(format!("collide: wrote {}", out.display()));
        }
        Command::Smooth {
            pipeline,
            input,
            output,
        } => {
            let (p, input, out) = stage_files(
                &pipeline,
                input,
                output,
                driver::COLLIDED_FILE,
                driver::SMOOTHED_FILE,
            )?;
            let b = Beside::load(&input, crowd_collide::STAGE, crowd_collide::VERSION)?;
            let (graph_bytes, graph, crossings) = (b.graph_bytes, b.graph, b.crossings);
            let (patterns_bytes, collided, motion) = (b.patterns_bytes, b.file, b.motion);
            let collided_bytes = b.input_bytes;
            let inputs = driver::smooth_inputs(&p);
            let hash =
                crowd_smooth::input_hash(&graph_bytes, &patterns_bytes, &collided_bytes, &inputs);
            let (_, writes) = driver::smooth_stage(
                &graph, &crossings, &collided, &motion, &inputs, hash, &out, &ui,
            );
            write_all(&writes)?;
            ui.say(format!("smooth: wrote {}", out.display()));
        }
        Command::Export {
            pipeline,
            input,
            output,
            region,
        } => {
            let (p, input, out) = stage_files(
                &pipeline,
                input,
                output,
                driver::SMOOTHED_FILE,
                driver::EXPORT_FILE,
            )?;
            let b = Beside::load(&input, crowd_smooth::STAGE, crowd_smooth::VERSION)?;
            let (graph_bytes, graph, crossings) = (b.graph_bytes, b.graph, b.crossings);
            let (patterns_bytes, motion, smoothed_bytes) =
                (b.patterns_bytes, b.motion, b.input_bytes);
            let mut inputs = driver::export_inputs(&p);
            if region.is_some() {
                inputs.settings.gltf_region = region;
            }
            let hash =
                crowd_export::input_hash(&graph_bytes, &patterns_bytes, &smoothed_bytes, &inputs);
            write_all(&driver::export_stage(
                &graph, &crossings, &motion, &inputs, hash, &out,
            )?)?;
            ui.say(format!("export: wrote {}", out.display()));
        }
        Command::Inspect { file } => print!("{}", crate::inspect::inspect(&file)?),
        Command::Check { dir, stage } => {
            let report = crate::report::check(&dir, stage)?;
            crate::report_md::write(&dir)?;
            println!(
                "{} walkers, {} segments: {} collisions ({} across borders); smallest clearance {:+.3} m{}",
                report.walkers,
                report.segments,
                report.collisions,
                report.across_borders,
                report.min_clearance_m,
                report
                    .worst_at
                    .map(|(x, y, t)| format!(" at ({x:.2}, {y:.2}) m, t = {t:.2} s"))
                    .unwrap_or_default()
            );
            if let Some(m) = &report.motion {
                println!(
                    "{}: walking speed in 0.5-1.8 m/s {:.1} % of the time; acceleration p95 {:.3} m/s2; turning rate p95 {:.3} rad/s",
                    report.stage,
                    100.0 * m.speed_in_band,
                    m.accel_p95,
                    m.turn_rate_p95
                );
                println!(
                    "borders: largest velocity jump {:.3} m/s; ends off their crossings by at most {:.2e} m and {:.2e} s; {} crossings not entered and left once",
                    m.max_border_velocity_jump,
                    m.max_boundary_error_m,
                    m.max_boundary_time_error_s,
                    m.unmatched_crossings
                );
            }
        }
        Command::Render {
            file,
            output,
            patch,
        } => {
            let legend = crate::inspect::render(&file, &output, patch)?;
            ui.say(format!("wrote {}: {legend}", output.display()));
        }
        Command::Report {
            dirs,
            json,
            table,
            markdown,
        } => {
            if table {
                println!("{}", crate::report::TABLE_HEADER);
                for dir in &dirs {
                    println!("{}", crate::report::Report::gather(dir)?.table_row(dir));
                }
                return Ok(());
            }
            let [dir] = dirs.as_slice() else {
                anyhow::bail!("give one build folder, or `--table` for several");
            };
            if markdown {
                println!("{}", crate::report_md::write(dir)?.display());
                return Ok(());
            }
            let report = crate::report::Report::gather(dir)?;
            if json {
                println!("{}", serde_json::to_string_pretty(&report.to_json())?);
            } else {
                print!("{}", report.to_text());
            }
        }
    }
    Ok(())
}
