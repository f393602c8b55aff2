//! The paper's five experiments (Allain section 6), each a scene, its constraints and its
//! descent, run and measured the way the paper's figures measure them. `crowd edit
//! --experiment NAME` writes what `run` returns.

mod density;
mod flow;
mod letters;
mod rendez_vous;
mod scenes;
mod vorticity;

use crate::cost::Problem;
use crate::descent::{Descent, Iteration, Kind, Stop, solve};
use crate::error::EditError;
use crate::world::Rect;
use glam::DVec2;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::time::Instant;

pub use scenes::{clearance, paper_problem, positions_at};

/// The experiments' names, in the paper's order.
pub const NAMES: [&str; 5] = ["rendez-vous", "letters", "density", "vorticity", "flow"];

/// The most descent iterations `--iterations` accepts: 50 times the paper's 200, a few minutes
/// for the largest experiment, where more would look like a hang.
pub const MAX_ITERATIONS: usize = 10_000;

/// What a user may change from the command line; `None` keeps the experiment's own value.
#[derive(Clone, Debug, Default)]
pub struct Overrides {
    pub iterations: Option<usize>,
    pub descent: Option<Descent>,
    /// Every constraint's R.
    pub r: Option<f64>,
    /// Q_u.
    pub q_velocity: Option<f64>,
    /// The rendez-vous' meeting point and time.
    pub meet: Option<DVec2>,
    pub meet_time: Option<f64>,
}

/// Something the pictures mark: a meeting point or a constraint's area, with its window.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub enum Mark {
    Point { at: DVec2, time: f64 },
    Area { rect: Rect, from: f64, to: f64 },
    Targets { points: Vec<DVec2>, time: f64 },
}

/// An experiment ready to run.
pub struct Setup {
    pub name: &'static str,
    pub problem: Problem,
    pub descent: Descent,
    pub iterations: usize,
    /// Named groups of characters (colours in the pictures, figures per group).
    pub groups: Vec<(String, Vec<usize>)>,
    pub marks: Vec<Mark>,
    /// Extra per-iteration figures of the experiment (name, value from the states).
    pub per_iteration: Vec<(String, PerIteration)>,
}

/// A figure computed from the iterate's trajectory.
pub type PerIteration = Box<dyn Fn(&Problem, &[f64]) -> f64>;

/// What `run` measured.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Figures {
    pub experiment: String,
    pub characters: usize,
    pub steps: usize,
    pub dt: f64,
    pub descent: Descent,
    pub iterations: usize,
    /// Why the descent ended before its last iteration (converged, or stalled), if it did.
    pub stop: Stop,
    pub seconds: f64,
    pub cost_before: f64,
    pub cost_after: f64,
    /// Per constraint: the root mean square of H(X) - Y before and after.
    pub residuals: Vec<Residual>,
    /// The smallest gap between two characters' discs, m (negative: they overlap), and how
    /// many (pair, step) overlaps there are, before and after.
    pub clearance_before: f64,
    pub clearance_after: f64,
    pub overlaps_before: usize,
    pub overlaps_after: usize,
    /// The experiment's own figures (distances to a meeting point, arrival times, ...).
    pub extra: BTreeMap<String, f64>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Residual {
    pub constraint: String,
    pub before: f64,
    pub after: f64,
}

/// One row of the per-iteration table.
#[derive(Clone, Debug)]
pub struct Row {
    pub iteration: Iteration,
    pub extra: Vec<f64>,
}

/// A per-time-step series (the flow experiment's normalised RMS per method).
#[derive(Clone, Debug)]
pub struct Series {
    pub name: String,
    pub values: Vec<f64>,
}

/// Everything an experiment produced.
pub struct Report {
    pub setup: Setup,
    pub before: Vec<f64>,
    pub after: Vec<f64>,
    pub rows: Vec<Row>,
    pub extra_columns: Vec<String>,
    pub per_step: Vec<Series>,
    pub figures: Figures,
}

/// The experiment called `name`, with `overrides` applied and checked.
pub fn setup(name: &str, overrides: &Overrides) -> Result<Setup, EditError> {
    if (overrides.meet.is_some() || overrides.meet_time.is_some()) && name != "rendez-vous" {
        return Err(EditError::NotForExperiment {
            option: "--meet / --meet-time".to_string(),
            experiment: name.to_string(),
        });
    }
    if let Some(n) = overrides
        .iterations
        .filter(|n| !(1..=MAX_ITERATIONS).contains(n))
    {
        return Err(EditError::Setting {
            what: "--iterations".to_string(),
            value: n as f64,
            expected: format!("1 to {MAX_ITERATIONS} (the paper runs 200)"),
        });
    }
    let mut setup = match name {
        "rendez-vous" => rendez_vous::setup(overrides)?,
        "letters" => letters::setup(overrides)?,
        "density" => density::setup(overrides)?,
        "vorticity" => vorticity::setup(overrides)?,
        "flow" => flow::setup(overrides)?,
        _ => {
            return Err(EditError::UnknownExperiment {
                name: name.to_string(),
                known: NAMES.join(", "),
            });
        }
    };
    if let Some(q) = overrides.q_velocity {
        setup.problem.covariances.q_velocity = q;
    }
    if let Some(d) = overrides.descent {
        setup.descent = d;
    }
    if let Some(i) = overrides.iterations {
        setup.iterations = i;
    }
    setup.problem.validate()?;
    Ok(setup)
}

/// Runs an experiment: the descent, then the figures. `progress(done, total)` after each
/// iteration.
pub fn run(
    name: &str,
    overrides: &Overrides,
    mut progress: impl FnMut(usize, usize),
) -> Result<Report, EditError> {
    let setup = setup(name, overrides)?;
    let started = Instant::now();
    let total = setup.iterations;
    let mut rows = Vec::new();
    let outcome = solve(&setup.problem, setup.descent, total, |it, states| {
        let extra = setup
            .per_iteration
            .iter()
            .map(|(_, f)| f(&setup.problem, states))
            .collect();
        rows.push(Row {
            iteration: it.clone(),
            extra,
        });
        progress(it.index, total);
    });
    let seconds = started.elapsed().as_secs_f64();
    let p = &setup.problem;
    let (first, last) = (&outcome.log[0], outcome.log.last().unwrap());
    let residuals = p
        .constraints
        .iter()
        .enumerate()
        .map(|(k, c)| Residual {
            constraint: c.name.clone(),
            before: first.residuals[k],
            after: last.residuals[k],
        })
        .collect();
    let (clearance_before, overlaps_before) = clearance(p, &outcome.before.states);
    let (clearance_after, overlaps_after) = clearance(p, &outcome.states);
    let mut extra = BTreeMap::new();
    let mut per_step = Vec::new();
    match name {
        "rendez-vous" => rendez_vous::figures(&setup, &outcome, &mut extra),
        "flow" => per_step = flow::baselines(&setup, &outcome),
        _ => {}
    }
    for (k, (column, _)) in setup.per_iteration.iter().enumerate() {
        extra.insert(format!("{column} before"), rows[0].extra[k]);
        extra.insert(format!("{column} after"), rows.last().unwrap().extra[k]);
    }
    let figures = Figures {
        experiment: name.to_string(),
        characters: p.model.len(),
        steps: p.timeline.steps,
        dt: p.timeline.dt,
        descent: setup.descent,
        iterations: last.index,
        stop: outcome.stop,
        seconds,
        cost_before: first.cost.total(),
        cost_after: last.cost.total(),
        residuals,
        clearance_before,
        clearance_after,
        overlaps_before,
        overlaps_after,
        extra,
    };
    Ok(Report {
        extra_columns: setup.per_iteration.iter().map(|(c, _)| c.clone()).collect(),
        before: outcome.before.states.clone(),
        after: outcome.states.clone(),
        rows,
        per_step,
        figures,
        setup,
    })
}

impl Report {
    /// The per-iteration table as CSV: iteration, kind, step, the cost's terms, each
    /// constraint's RMS, then the experiment's own columns.
    pub fn csv(&self) -> String {
        let mut out = String::from("iteration,kind,step,cost,cost_model,cost_observation");
        for c in &self.setup.problem.constraints {
            out += &format!(",rms {}", c.name);
        }
        for c in &self.extra_columns {
            out += &format!(",{c}");
        }
        out.push('\n');
        for row in &self.rows {
            let it = &row.iteration;
            let kind = match it.kind {
                Kind::Start => "start",
                Kind::Local => "local",
                Kind::Global => "global",
            };
            out += &format!(
                "{},{kind},{:.6e},{:.8e},{:.8e},{:.8e}",
                it.index,
                it.step,
                it.cost.total(),
                it.cost.model + it.cost.initial,
                it.cost.observation
            );
            for r in it.residuals.iter().chain(&row.extra) {
                out += &format!(",{r:.8e}");
            }
            out.push('\n');
        }
        out
    }

    /// The per-time-step series as CSV (empty when the experiment has none).
    pub fn per_step_csv(&self) -> Option<String> {
        let first = self.per_step.first()?;
        let mut out = String::from("time");
        for s in &self.per_step {
            out += &format!(",{}", s.name);
        }
        out.push('\n');
        for k in 0..first.values.len() {
            out += &format!("{:.2}", k as f64 * self.setup.problem.timeline.dt);
            for s in &self.per_step {
                out += &format!(",{:.6}", s.values[k]);
            }
            out.push('\n');
        }
        Some(out)
    }
}
