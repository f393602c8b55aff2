//! `crowd edit --experiment NAME`: runs one of the optimal crowd editing paper's experiments
//! (`crowd-edit`) and writes what it measured: the per-iteration table (CSV and plot), the
//! trajectories before and after (a top view), `result.ron`, and for `flow` the per-step
//! comparison with the baselines.

use crate::ui::Ui;
use anyhow::{Context, Result};
use crowd_core::Progress;
use crowd_core::files::write_atomic;
use crowd_edit::experiments::{self, Overrides, Report};
use crowd_edit::{CONVERGED, CONVERGED_OVER, Stop};
use std::path::{Path, PathBuf};

/// What `crowd edit` was asked for.
pub struct EditCommand {
    pub experiment: String,
    pub output: Option<PathBuf>,
    pub overrides: Overrides,
}

/// Runs the experiment and writes its files into the output folder (default `edit-NAME`).
pub fn run(command: &EditCommand, ui: &Ui) -> Result<PathBuf> {
    let name = command.experiment.as_str();
    let dir = command
        .output
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("edit-{name}")));
    // Refuse bad input before any work or any file.
    experiments::setup(name, &command.overrides)?;
    let bar = ui.stage_bar("edit");
    let mut begun = false;
    let report = experiments::run(name, &command.overrides, |done, total| {
        if !begun {
            bar.begin(name, total as u64);
            begun = true;
        }
        if done > 0 {
            bar.advance(1);
        }
    })?;
    drop(bar);
    let f = &report.figures;
    if f.iterations == 0 {
        // Writing the unedited crowd as the edit would be an empty result that looks like one.
        anyhow::bail!(
            "experiment `{name}`: the descent found no step that lowers the cost from the \
             unedited crowd (cost {:.4e}), so nothing was edited and nothing written; R or Q \
             is likely out of scale (the experiment's own values work: drop --r and --q)",
            f.cost_before
        );
    }
    write(&report, &dir)?;
    ui.say(format!(
        "{name}: {} characters, {} iterations in {:.2} s; cost {:.4e} -> {:.4e}; closest gap {:.3} m ({} overlaps) -> {:.3} m ({} overlaps)",
        f.characters,
        f.iterations,
        f.seconds,
        f.cost_before,
        f.cost_after,
        f.clearance_before,
        f.overlaps_before,
        f.clearance_after,
        f.overlaps_after
    ));
    for r in &f.residuals {
        ui.say(format!(
            "  {}: RMS {:.4} -> {:.4}",
            r.constraint, r.before, r.after
        ));
    }
    for (k, v) in &f.extra {
        ui.say(format!("  {k}: {v:.3}"));
    }
    match f.stop {
        Stop::Iterations => {}
        Stop::Converged { at } => ui.say(format!(
            "  converged at iteration {at}: the cost fell by less than {CONVERGED:e} over the last {CONVERGED_OVER}"
        )),
        Stop::Stalled { at } => ui.say(format!(
            "  note: the descent stopped at iteration {at}: no step along any direction lowered the cost"
        )),
    }
    ui.say("  pictures: iterations.png, trajectories.png (what they show: crowd edit --help)");
    Ok(dir)
}

/// The experiment's files, each written whole (a failed run leaves none half-written).
fn write(report: &Report, dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    write_atomic(&dir.join("iterations.csv"), report.csv().as_bytes())?;
    if let Some(csv) = report.per_step_csv() {
        write_atomic(&dir.join("per-step.csv"), csv.as_bytes())?;
    }
    let pretty = ron::ser::PrettyConfig::new().struct_names(true);
    let text = ron::ser::to_string_pretty(&report.figures, pretty)?;
    write_atomic(&dir.join("result.ron"), format!("{text}\n").as_bytes())?;
    crate::edit_pictures::write(report, dir)?;
    Ok(())
}
