//! Command-line arguments and what each subcommand does.

use crate::driver::{self, BuildOptions};
use crate::stage::{self, Stage};
use crate::stages::{self, STAGES};
use crate::ui::{Ui, out};
use anyhow::{Context, Result};
use clap::{Arg, ArgMatches, FromArgMatches, Parser, Subcommand};
use crowd_core::config::PipelineFile;
use std::path::PathBuf;

/// What the exit codes mean, for build systems (`--help`, README.md).
pub const EXIT_CODES: &str = "Exit codes:
  0  done: every guarantee held (or, for other commands, the command did its job)
  1  error: a file, setting or painting refused, or a stage that could not finish; the message
     names the file, the place and what was expected, and no output was changed
  2  the command line itself is wrong (an unknown flag, a missing argument)
  3  done, but guarantees broken: `crowd check` found collisions, speeds over the limit, jumps
     or open loops in what ships, or `crowd build --deny-warnings` had warnings";

/// A build or check that ran to the end and found guarantees broken: exit code 3.
#[derive(Debug)]
pub struct Broken(pub String);

impl std::fmt::Display for Broken {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Broken {}

#[derive(Debug, Parser)]
#[command(
    name = "crowd",
    version,
    about = "The crowd-patches asset compiler: painted layers in, endless collision-free crowds out.",
    after_help = EXIT_CODES
)]
pub struct Cli {
    /// Print nothing but results and errors; no progress bars.
    #[arg(long, short, global = true)]
    pub quiet: bool,
    /// Worker threads (default: one per core; more than the cores are clamped to them).
    /// Outputs are identical for any count.
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
        #[arg(long, value_name = "STAGE", value_parser = stage::parser())]
        until: Option<&'static Stage>,
        /// Do not check the build after stage 8 (`crowd check`: the final trajectories,
        /// `library.crowd` and `world.glb`, into `check.ron` and `report.md`).
        #[arg(long)]
        no_check: bool,
        /// Fail (exit 1, after writing everything) when the build has warnings: parts of the
        /// painting it could not meet, listed on stderr and in `report.md`.
        #[arg(long)]
        deny_warnings: bool,
        /// The most memory the build may take (512M, 4G, ...; default: this machine's). A
        /// pipeline estimated to need more is refused before any stage runs.
        #[arg(long, value_name = "SIZE", value_parser = crate::budget::parse_size)]
        max_memory: Option<u64>,
        /// Do shard I of N (0 <= I < N) of the stages that split: stages 1-3 here, then this
        /// shard's patches of stages 4 to 6 into `shards/` (`match-I-of-N.ron`,
        /// `collide-I-of-N.ron`, `smooth-I-of-N.ron` and their `.bin`), and no more. Copy every shard's `shards/`
        /// into one folder and `--gather` there. With `--until optimize`, only this shard's
        /// regions of stage 3 (`optimize-I-of-N.ron`): run that for every I first and put every
        /// shard's `optimize-*` files in each shard's `shards/`, and no shard solves stage 3
        /// whole.
        #[arg(long, value_name = "I/N", value_parser = |s: &str| s.parse::<crowd_core::Shard>(),
              conflicts_with_all = ["gather", "force"])]
        shard: Option<crowd_core::Shard>,
        /// Put stages 4 to 6 (and 3, from its region files, if not made) together from the shard
        /// files in `shards/` (every shard of one count, made from this painting and settings),
        /// then build the rest: the same bytes as one process's build.
        #[arg(long)]
        gather: bool,
    },
    /// The stages one at a time: `crowd merge`, `crowd graph`, ... (one subcommand per entry
    /// of the stage table).
    #[command(flatten)]
    Stage(StageCommand),
    /// A readable summary of any stage file.
    Inspect { file: PathBuf },
    /// A picture of a stage file as PNG: merged maps, patch graph, error map and convergence,
    /// one patch's patterns and lines.
    Render {
        file: PathBuf,
        #[arg(long, short, value_name = "OUT.png")]
        output: PathBuf,
        /// For trajectories: the patch to draw (default: the busiest).
        #[arg(long, value_name = "ID", conflicts_with = "edit")]
        patch: Option<u32>,
        /// For stage 7's file: the edit to draw, before and after, in every patch it covers.
        #[arg(long, value_name = "NAME")]
        edit: Option<String>,
        /// With `--edit`: the pipeline that asks for it.
        #[arg(
            long,
            value_name = "FILE",
            default_value = "pipeline.ron",
            requires = "edit"
        )]
        pipeline: PathBuf,
    },
    /// Check a build folder's world as an engine plays it: every pair, every time, across
    /// borders too, on the latest trajectories and on what ships (`library.crowd`,
    /// `world.glb`); writes `check.ron` beside the stage files.
    Check {
        dir: PathBuf,
        /// The stage whose trajectories to check (default: the latest in the folder).
        #[arg(long, value_name = "STAGE", value_parser = stage::parser_among(&stages::TRAJECTORY_STAGES))]
        stage: Option<&'static Stage>,
        /// The build's pipeline, for its `match.max_speed` (default: 1.8 m/s); shipped speeds
        /// are held to 5 % above it.
        #[arg(long, value_name = "FILE")]
        pipeline: Option<PathBuf>,
    },
    /// Stage 7: edit the pipeline's moments into the patches they cover (reads the smoothed
    /// trajectories, and the graph beside them); or, with `--experiment`, run one of the
    /// optimal crowd editing paper's experiments (Allain et al. 2014) and write its
    /// per-iteration CSV, plots, trajectories before and after, and result.ron.
    #[command(after_long_help = crate::edit_pictures::LEGEND)]
    Edit(EditArgs),
    /// Watch a build in a browser: serves the folder and the viewer page on 127.0.0.1 (a free
    /// port unless `--port`), prints the address and opens a browser where there is one;
    /// Ctrl-C stops it. The page plays `library.crowd` over the painted ground, with the patch
    /// grid, densities, directions, obstacles, the check's findings and the edits as toggles.
    View {
        /// The build folder (it has `library.crowd`).
        dir: PathBuf,
        #[arg(long)]
        port: Option<u16>,
        /// Print the address only; open no browser.
        #[arg(long)]
        no_open: bool,
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

/// Stage 7 alone, or one of the optimal crowd editing paper's experiments (see `crowd-edit`).
#[derive(Debug, clap::Args)]
pub struct EditArgs {
    /// The experiment to run: rendez-vous, letters, density, vorticity or flow. Without it,
    /// stage 7 runs on the pipeline's build.
    #[arg(long, value_name = "NAME")]
    pub experiment: Option<String>,
    /// Stage 7: the pipeline, with its `edits`.
    #[arg(
        long,
        value_name = "FILE",
        default_value = "pipeline.ron",
        conflicts_with = "experiment"
    )]
    pub pipeline: PathBuf,
    /// Stage 7: the smoothed trajectories it reads (default: `smoothed.ron` in the pipeline's
    /// output folder); graph.ron read beside it.
    #[arg(long, short, value_name = "FILE", conflicts_with = "experiment")]
    pub input: Option<PathBuf>,
    /// Stage 7: the file to write (default: `edited.ron` in the pipeline's output folder;
    /// edited.bin beside it). An experiment: the folder for its CSV, pictures and result.ron
    /// (default: edit-NAME).
    #[arg(long, short, value_name = "PATH")]
    pub output: Option<PathBuf>,
    /// Descent iterations (default: the experiment's, as in the paper).
    #[arg(long, value_name = "N", requires = "experiment")]
    pub iterations: Option<usize>,
    /// local, global, quasi-newton (global along L-BFGS directions) or alternating (5 local
    /// iterations then 5 global, section 4.3) (default: the experiment's).
    #[arg(long, value_name = "DESCENT", value_parser = parse_descent, requires = "experiment")]
    pub descent: Option<crowd_edit::Descent>,
    /// Every constraint's covariance R (default: the paper's for the experiment).
    #[arg(
        long,
        value_name = "R",
        allow_negative_numbers = true,
        requires = "experiment"
    )]
    pub r: Option<f64>,
    /// The model covariance Q_u, m^2/s^4 (default: the paper's for the experiment).
    #[arg(
        long,
        value_name = "Q",
        allow_negative_numbers = true,
        requires = "experiment"
    )]
    pub q: Option<f64>,
    /// rendez-vous only: the meeting point, metres.
    #[arg(long, value_name = "X,Y", value_parser = parse_point, allow_negative_numbers = true, requires = "experiment")]
    pub meet: Option<(f64, f64)>,
    /// rendez-vous only: the meeting time, seconds.
    #[arg(
        long,
        value_name = "T",
        allow_negative_numbers = true,
        requires = "experiment"
    )]
    pub meet_time: Option<f64>,
}

fn parse_descent(text: &str) -> Result<crowd_edit::Descent, String> {
    match text {
        "local" => Ok(crowd_edit::Descent::Local),
        "global" => Ok(crowd_edit::Descent::Global),
        "quasi-newton" => Ok(crowd_edit::Descent::QuasiNewton),
        "alternating" => Ok(crowd_edit::Descent::Alternating {
            local: 5,
            global: 5,
        }),
        _ => Err("expected local, global, quasi-newton or alternating".to_string()),
    }
}

fn parse_point(text: &str) -> Result<(f64, f64), String> {
    let numbers: Vec<f64> = text
        .split(',')
        .map(|s| s.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("expected X,Y in metres: {e}"))?;
    match numbers[..] {
        [x, y] => Ok((x, y)),
        _ => Err(format!("expected two numbers X,Y, found {}", numbers.len())),
    }
}

/// One stage run alone: `crowd <stage> [--pipeline FILE] [-i INPUT] [-o OUTPUT]`. Its
/// subcommands are made from the stage table, so a new stage gets one without code here.
#[derive(Debug, Clone)]
pub struct StageCommand {
    pub stage: &'static Stage,
    pub pipeline: PathBuf,
    /// The stage file it reads (default: in the pipeline's output folder); the other files it
    /// reads are read beside it.
    pub input: Option<PathBuf>,
    /// Its file (default: in the pipeline's output folder).
    pub output: Option<PathBuf>,
    /// Stage 8 only: the part of the world put in `world.glb`.
    pub region: Option<(f64, f64, f64, f64)>,
}

/// The subcommand of one stage, with its help made from its table entry.
fn stage_subcommand(stage: &'static Stage) -> clap::Command {
    let mut command = clap::Command::new(stage.name).about(stage.about).arg(
        Arg::new("pipeline")
            .long("pipeline")
            .value_name("FILE")
            .default_value("pipeline.ron")
            .value_parser(clap::value_parser!(PathBuf))
            .help("The pipeline: layers and settings"),
    );
    if let Some(input) = stage.main_input() {
        let beside: Vec<&str> = stage
            .reads
            .iter()
            .copied()
            .filter(|r| *r != input)
            .collect();
        let beside = match beside.as_slice() {
            [] => String::new(),
            names => format!("; {} read beside it", names.join(" and ")),
        };
        command = command.arg(
            Arg::new("input")
                .long("input")
                .short('i')
                .value_name("FILE")
                .value_parser(clap::value_parser!(PathBuf))
                .help(format!(
                    "The file it reads (default: `{input}` in the pipeline's output folder){beside}"
                )),
        );
    }
    command = command.arg(
        Arg::new("output")
            .long("output")
            .short('o')
            .value_name("FILE")
            .value_parser(clap::value_parser!(PathBuf))
            .help(format!(
                "Output file (default: `{}` in the pipeline's output folder){}",
                stage.output,
                match stage.writes {
                    [] | [_] => String::new(),
                    [beside @ .., _] => format!("; {} written beside it", beside.join(", ")),
                }
            )),
    );
    if *stage == stages::EXPORT {
        command = command.arg(
            Arg::new("region")
                .long("region")
                .value_name("X0,Y0,X1,Y1")
                .value_parser(parse_region)
                .help(
                    "Put only this part of the world (world metres) in `world.glb`, in place of \
                     the pipeline's `export.gltf_region`: DCC tools slow down with tens of \
                     thousands of animated nodes. The library always holds the whole world.",
                ),
        );
    }
    command
}

impl FromArgMatches for StageCommand {
    fn from_arg_matches(matches: &ArgMatches) -> Result<Self, clap::Error> {
        let Some((name, args)) = matches.subcommand() else {
            return Err(clap::Error::new(clap::error::ErrorKind::MissingSubcommand));
        };
        let Some(stage) = stage::named(name) else {
            return Err(clap::Error::new(clap::error::ErrorKind::InvalidSubcommand));
        };
        let path = |id: &str| args.try_get_one::<PathBuf>(id).ok().flatten().cloned();
        Ok(StageCommand {
            stage,
            pipeline: path("pipeline").unwrap_or_else(|| PathBuf::from("pipeline.ron")),
            input: path("input"),
            output: path("output"),
            region: args
                .try_get_one::<(f64, f64, f64, f64)>("region")
                .ok()
                .flatten()
                .copied(),
        })
    }

    fn update_from_arg_matches(&mut self, matches: &ArgMatches) -> Result<(), clap::Error> {
        *self = Self::from_arg_matches(matches)?;
        Ok(())
    }
}

impl Subcommand for StageCommand {
    fn augment_subcommands(command: clap::Command) -> clap::Command {
        // Stage 7's subcommand is `edit`, which also runs the paper's experiments.
        STAGES
            .iter()
            .filter(|s| ***s != stages::EDIT)
            .fold(command, |command, s| {
                command.subcommand(stage_subcommand(s))
            })
    }

    fn augment_subcommands_for_update(command: clap::Command) -> clap::Command {
        Self::augment_subcommands(command)
    }

    fn has_subcommand(name: &str) -> bool {
        stage::named(name).is_some_and(|s| *s != stages::EDIT)
    }
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

impl Cli {
    /// Whether this is a part of a build split over processes (`build --shard` or
    /// `--gather`), whose peak memory is what sizes the jobs that run it.
    pub fn is_split(&self) -> bool {
        matches!(
            &self.command,
            Command::Build { shard: Some(_), .. } | Command::Build { gather: true, .. }
        )
    }
}

pub fn run(cli: Cli) -> Result<()> {
    if let Some(asked) = cli.threads {
        // More threads than cores only contend (a 0.4 s build took 30 s at 1000); outputs are
        // the same for any count, so the extra ones are dropped with a note.
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let n = asked.clamp(1, cores);
        if n != asked && !cli.quiet {
            crate::ui::say(format!(
                "note: --threads {asked}: using {n} (this machine has {cores} cores)"
            ));
        }
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
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
            no_check,
            deny_warnings,
            max_memory,
            shard,
            gather,
        } => {
            let file = PipelineFile::load(&pipeline)?;
            let out = output.clone().unwrap_or_else(|| file.output_dir());
            if shard.is_some() && until.is_some_and(|u| *u != stages::OPTIMIZE) {
                // The command line is wrong: clap's message and exit code 2, nothing made.
                use clap::CommandFactory;
                Cli::command()
                    .error(
                        clap::error::ErrorKind::ArgumentConflict,
                        "--shard takes --until optimize (this shard's regions of stage 3) or \
                         no --until (its part of stages 4 to 6)",
                    )
                    .exit();
            }
            let split = match (shard, gather) {
                (Some(shard), _) => driver::Split::Shard(shard),
                (None, true) => driver::Split::Gather,
                (None, false) => driver::Split::Whole,
            };
            let options = BuildOptions {
                force,
                output,
                until,
                max_memory,
                split,
            };
            let (_, _lock) = driver::build(&pipeline, &options, &ui)?;
            if let Some(shard) = shard {
                let parts: &[&Stage] = match until {
                    Some(_) => &[&stages::OPTIMIZE],
                    None => &stages::SHARDED,
                };
                for stage in parts {
                    let path = crowd_core::shard::part_path(&out, stage.kind, shard);
                    ui.say(format!(
                        "   shard: {shard} of {} -> {}",
                        stage.name,
                        path.display()
                    ));
                }
                return Ok(());
            }
            if !no_check && stage::up_to(until).any(|s| *s == stages::EXPORT) {
                let limits = (
                    file.pipeline.matching.max_speed,
                    file.pipeline.export.turn_rate_deg_s,
                );
                crate::check::after_build(&out, limits, (force, gather), &ui)?;
            }
            // Made from the same files, the report stands: an up-to-date build writes nothing.
            let scope = crate::report::Scope { last: until };
            let report = crate::report_md::refresh(&out, scope)?;
            ui.say(format!("  report: {}", report.display()));
            let warnings = crate::warnings::gather(&out)?;
            for w in &warnings {
                crate::ui::say(format!("warning: {}", w.text));
            }
            if deny_warnings && !warnings.is_empty() {
                return Err(Broken(format!(
                    "{} warning(s), and --deny-warnings was given (see {})",
                    warnings.len(),
                    report.display()
                ))
                .into());
            }
        }
        Command::Stage(StageCommand {
            stage,
            pipeline,
            input,
            output,
            region,
        }) => {
            let mut p = PipelineFile::load(&pipeline)?;
            if region.is_some() {
                p.pipeline.export.gltf_region = region;
            }
            driver::run_stage(stage, &p, input, output, &ui)?;
        }
        Command::Edit(args) => {
            let Some(experiment) = args.experiment else {
                let experiment_only = [
                    ("--iterations", args.iterations.is_some()),
                    ("--descent", args.descent.is_some()),
                    ("--r", args.r.is_some()),
                    ("--q", args.q.is_some()),
                    ("--meet", args.meet.is_some()),
                    ("--meet-time", args.meet_time.is_some()),
                ];
                if let Some((flag, _)) = experiment_only.iter().find(|(_, given)| *given) {
                    anyhow::bail!(
                        "{flag} is a setting of the paper's experiments: give --experiment NAME \
                         (without it, `crowd edit` runs stage 7 with the pipeline's edits)"
                    );
                }
                let p = PipelineFile::load(&args.pipeline)?;
                return driver::run_stage(&stages::EDIT, &p, args.input, args.output, &ui);
            };
            let command = crate::edit::EditCommand {
                experiment,
                output: args.output,
                overrides: crowd_edit::experiments::Overrides {
                    iterations: args.iterations,
                    descent: args.descent,
                    r: args.r,
                    q_velocity: args.q,
                    meet: args.meet.map(|(x, y)| glam::DVec2::new(x, y)),
                    meet_time: args.meet_time,
                },
            };
            let dir = crate::edit::run(&command, &ui)?;
            ui.say(format!("  wrote {}", dir.display()));
        }
        Command::Inspect { file } => out(crate::inspect::inspect(&file)?)?,
        Command::Check {
            dir,
            stage,
            pipeline,
        } => out(crate::check::command(&dir, stage, pipeline.as_deref())?)?,
        Command::Render {
            file,
            output,
            patch,
            edit,
            pipeline,
        } => {
            let legend = match edit {
                Some(name) => {
                    let image = crate::edit_render::render_edit(&file, &name, &pipeline)?;
                    crowd_render::save_png(&image, &output)?;
                    crate::edit_render::EDIT_LEGEND
                }
                None => crate::inspect::render(&file, &output, patch)?,
            };
            ui.say(format!("wrote {}: {legend}", output.display()));
        }
        Command::View { dir, port, no_open } => {
            let server = crowd_view::Server::bind(&dir, port)?;
            // The address goes to stdout whatever `--quiet` says: it is the command's result.
            out(format!(
                "crowd view: serving {} at {} (Ctrl-C stops)\n",
                dir.display(),
                server.address
            ))?;
            if !no_open && !crowd_view::open_browser(&server.address) {
                ui.say("no browser to open here: open the address above in one");
            }
            server.run()?;
        }
        Command::Report {
            dirs,
            json,
            table,
            markdown,
        } => {
            if table {
                out(format!("{}\n", crate::report::TABLE_HEADER))?;
                for dir in &dirs {
                    let row = crate::report::Report::gather(dir)?.table_row(dir);
                    out(format!("{row}\n"))?;
                }
                return Ok(());
            }
            let [dir] = dirs.as_slice() else {
                anyhow::bail!("give one build folder, or `--table` for several");
            };
            if markdown {
                let written = crate::report_md::write(dir, Default::default())?;
                out(format!("{}\n", written.display()))?;
                return Ok(());
            }
            let report = crate::report::Report::gather(dir)?;
            if json {
                out(format!(
                    "{}\n",
                    serde_json::to_string_pretty(&report.to_json())?
                ))?;
            } else {
                out(report.to_text())?;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::Cli;
    use clap::Parser;

    #[test]
    fn only_a_shard_or_a_gather_is_a_build_split_over_processes() {
        let split = |args: &[&str]| Cli::try_parse_from(args).unwrap().is_split();
        assert!(split(&["crowd", "build", "--shard", "1/4"]));
        assert!(split(&["crowd", "build", "--gather"]));
        assert!(split(&[
            "crowd",
            "-q",
            "build",
            "--pipeline",
            "p.ron",
            "--gather"
        ]));
        assert!(!split(&["crowd", "build"]));
        assert!(!split(&["crowd", "build", "--force"]));
        assert!(!split(&["crowd", "check", "out"]));
    }
}
