//! The local and global gradient descents of Allain section 4.2.2 and their alternation
//! (section 4.3), each with a backtracking line search.
//!
//! Both move the errors along the paper's update, d eps = Q lambda (eq. 9) and d eps_0 =
//! B lambda(t_0) / (t_f - t_0) (eq. 10), taken here with the current errors' own penalty so
//! that it is the steepest descent of J in the metric of Q and B: d = -(eps + Q grad_obs / dt).
//! - Global (eq. 14-15): eps += rho d and the full model is run again, so trajectories may
//!   jump between solutions (through a group instead of round it).
//! - Local (eq. 11-13): the tangent-linear model turns rho d into a trajectory offset dX and
//!   X += dX, without running the model.
//!
//! The step rho: the paper takes rho = 1, which overshoots by orders of magnitude when R is
//! small next to Q (a 10 m miss under R = 10 m^2 and Q_u = 100 m^2/s^4 asks for tens of metres
//! of correction). Each iteration therefore tries twice its last accepted step (1 at first)
//! and halves it until J falls by the Armijo condition (1e-4 of the predicted decrease), so J
//! never rises within a descent; one model run (global) or a few observation evaluations
//! (local) per trial.

use crate::cost::{CostParts, Problem};
use crate::integrate::Run;
use crate::model::{Linearisation, Model};
use crate::quasi_newton::Memory;
use serde::{Deserialize, Serialize};
use std::cell::OnceCell;

/// Which descent each iteration takes.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Descent {
    Local,
    /// The paper's global descent: eq. 14-15 along d eps = Q lambda.
    Global,
    /// The global descent along L-BFGS directions started from the paper's (`quasi_newton`).
    QuasiNewton,
    /// `local` local iterations, then `global` global ones, and again.
    Alternating {
        local: usize,
        global: usize,
    },
}

impl Descent {
    fn kind(&self, iteration: usize) -> Kind {
        match *self {
            Descent::Local => Kind::Local,
            Descent::Global | Descent::QuasiNewton => Kind::Global,
            Descent::Alternating { local, global } => {
                if iteration % (local + global).max(1) < local {
                    Kind::Local
                } else {
                    Kind::Global
                }
            }
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Kind {
    Start,
    Local,
    Global,
}

/// What one iteration reached.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Iteration {
    pub index: usize,
    pub kind: Kind,
    pub cost: CostParts,
    /// The step rho taken (0 at the start).
    pub step: f64,
    /// Per constraint, the root mean square of H(X) - Y over its samples.
    pub residuals: Vec<f64>,
}

/// The edited trajectory and how the descent got there.
pub struct Outcome {
    /// The model run with no edit.
    pub before: Run,
    /// The edited trajectory (states at every step, one state after another).
    pub states: Vec<f64>,
    pub controls: Vec<f64>,
    pub shift: Vec<f64>,
    pub log: Vec<Iteration>,
    /// Why the descent ended.
    pub stop: Stop,
}

/// Why a descent ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Stop {
    /// It ran every iteration it was given.
    Iterations,
    /// The objective fell by less than [`CONVERGED`] (relative) over the last
    /// [`CONVERGED_OVER`] iterations: a minimum, or a tangle no direction leads out of
    /// (section 4.3); more iterations would only repeat steps of 1e-13.
    Converged { at: usize },
    /// At this iteration no step along any direction lowered the objective.
    Stalled { at: usize },
}

/// See [`Stop::Converged`].
pub const CONVERGED: f64 = 1e-6;
pub const CONVERGED_OVER: usize = 3;

/// The current errors and the trajectory they give.
struct Iterate {
    shift: Vec<f64>,
    controls: Vec<f64>,
    states: Vec<f64>,
    /// The model's run of these errors, when `states` is one (not after a local step).
    run: Option<Run>,
    cost: CostParts,
}

/// Shorter steps tried before a line search gives up.
const MAX_HALVINGS: usize = 30;
/// Shorter steps an L-BFGS direction gets before the paper's direction is tried instead: a
/// quasi-Newton step that must be cut to under 1/16 of its length is off, and every trial is
/// a model run.
const MEMORY_HALVINGS: usize = 5;
/// Shorter steps the radial linearisation's direction gets when the exact one is tried after
/// it: a factor 4,096 below twice the last step. Past that the radial gradient has stopped
/// leading down (a tangle), and each further halving would be one more model run.
const RADIAL_HALVINGS: usize = 12;
const ARMIJO: f64 = 1e-4;
/// How much deeper than the unedited crowd a global step may push two characters into each
/// other, m.
const GLOBAL_OVERLAP: f64 = 0.02;

/// Runs `iterations` descents; `each(iteration, states)` sees every iterate.
pub fn solve(
    problem: &Problem,
    descent: Descent,
    iterations: usize,
    mut each: impl FnMut(&Iteration, &[f64]),
) -> Outcome {
    let n = problem.n();
    let zeros = vec![0.0; n];
    let controls = vec![0.0; problem.timeline.steps * n];
    let before = problem.run(&zeros, &controls);
    let mut it = Iterate {
        cost: problem.cost(&zeros, &controls, &before.states),
        shift: zeros,
        controls,
        states: before.states.clone(),
        run: Some(before.clone()),
    };
    let mut log = vec![record(problem, 0, Kind::Start, &it, 0.0)];
    each(&log[0], &it.states);
    let mut step = 1.0;
    let mut stop = Stop::Iterations;
    // No global step may push two characters into each other deeper than the unedited crowd
    // has them (less 2 cm): the model's repulsion is a force, not a guarantee, and a strong
    // enough control overpowers it. (Measured from the unedited run, not from each iterate, or
    // the 2 cm would add up over the iterations.)
    let floor = match problem.keep_apart {
        true => before.smallest_gap(problem.timeline.steps).min(0.0) - GLOBAL_OVERLAP,
        false => f64::NEG_INFINITY,
    };
    let mut memory = Memory::default();
    let quasi_newton = descent == Descent::QuasiNewton;
    for index in 1..=iterations {
        let mut kind = descent.kind(index - 1);
        let mut taken = match kind {
            Kind::Global => global(problem, &mut it, floor, step, &mut memory, quasi_newton),
            _ => {
                memory.clear();
                local(problem, &mut it, step)
            }
        };
        // Alternating: a local step that finds no way down hands over to a global one, which
        // may jump to another solution (section 4.3).
        if taken.is_none() && kind == Kind::Local && descent != Descent::Local {
            kind = Kind::Global;
            taken = global(problem, &mut it, floor, step, &mut memory, false);
        }
        let Some(taken) = taken else {
            stop = Stop::Stalled { at: index };
            break;
        };
        step = 2.0 * taken;
        log.push(record(problem, index, kind, &it, taken));
        each(log.last().unwrap(), &it.states);
        if converged(&log, problem) {
            stop = Stop::Converged { at: index };
            break;
        }
    }
    Outcome {
        before,
        states: it.states,
        controls: it.controls,
        shift: it.shift,
        log,
        stop,
    }
}

/// Whether the objective fell by less than [`CONVERGED`] over the last [`CONVERGED_OVER`]
/// iterations.
fn converged(log: &[Iteration], problem: &Problem) -> bool {
    let Some(then) = log.len().checked_sub(CONVERGED_OVER + 1) else {
        return false;
    };
    let objective = |k: usize| log[k].cost.objective(problem.objective);
    let now = objective(log.len() - 1);
    objective(then) - now <= CONVERGED * now.abs()
}

fn record(problem: &Problem, index: usize, kind: Kind, it: &Iterate, step: f64) -> Iteration {
    let n = problem.n();
    Iteration {
        index,
        kind,
        cost: it.cost,
        step,
        residuals: problem
            .constraints
            .iter()
            .map(|c| c.misfit(&it.states, n).1)
            .collect(),
    }
}

/// The descent direction in the metric of Q and B, and J's slope along it.
struct Direction {
    controls: Vec<f64>,
    shift: Vec<f64>,
    slope: f64,
}

/// The paper's direction d eps = Q lambda, d eps_0 = B lambda(t_0) / T (steepest descent in
/// the metric of Q and B) or, given a memory, its L-BFGS correction.
fn direction(
    problem: &Problem,
    model: &Model,
    run: &Run,
    it: &Iterate,
    memory: Option<&mut Memory>,
) -> Direction {
    let g = problem.gradient_with(model, run, &it.shift, &it.controls);
    let n = problem.n();
    let c = &problem.covariances;
    let (dt, t) = (problem.timeline.dt, problem.timeline.duration());
    let h0: Vec<f64> = (0..g.controls.len())
        .map(|m| c.q(m % n) / dt)
        .chain((0..g.initial.len()).map(|m| c.b(m) / t))
        .collect();
    let gradient: Vec<f64> = g.controls.iter().chain(&g.initial).copied().collect();
    let steepest = || -> Vec<f64> { gradient.iter().zip(&h0).map(|(g, h)| -h * g).collect() };
    let mut d = match memory {
        Some(memory) => {
            let x: Vec<f64> = it.controls.iter().chain(&it.shift).copied().collect();
            memory.direction(&x, &gradient, &h0)
        }
        None => steepest(),
    };
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(a, b)| a * b).sum::<f64>();
    let mut slope = dot(&gradient, &d);
    if slope >= 0.0 || slope.is_nan() {
        d = steepest();
        slope = dot(&gradient, &d);
    }
    let shift = d.split_off(g.controls.len());
    Direction {
        controls: d,
        shift,
        slope,
    }
}

fn moved(a: &[f64], d: &[f64], rho: f64) -> Vec<f64> {
    a.iter().zip(d).map(|(a, d)| a + rho * d).collect()
}

/// Backtracks from `rho`, halving, until `trial(rho)` lowers J enough; `None` when no step
/// does. (A parabolic step, Nocedal and Wright section 3.5, took fewer trials on `density` but
/// on `letters`, whose cost jumps as trajectories swap sides, it ran 3,615 model runs to a
/// worse result than halving's 300: BENCHMARKS.md.)
fn line_search<T>(
    start: f64,
    slope: f64,
    rho: f64,
    halvings: usize,
    mut trial: impl FnMut(f64, f64) -> (f64, T),
) -> Option<(f64, T)> {
    if slope >= 0.0 || !slope.is_finite() {
        return None;
    }
    let mut rho = rho;
    for _ in 0..halvings {
        let enough = start + ARMIJO * rho * slope;
        let (value, extra) = trial(rho, enough);
        if value.is_finite() && value <= enough {
            return Some((rho, extra));
        }
        rho *= 0.5;
    }
    None
}

/// The directions a global iteration tries, in turn.
#[derive(Clone, Copy)]
enum Try {
    /// L-BFGS from the curvature pairs so far (the paper's direction while there are none).
    Memory,
    /// The paper's direction, d eps = Q lambda.
    Paper,
    /// The paper's direction from the exact linearisation's gradient.
    Exact,
}

/// One global iteration (eq. 14-15): returns the step taken. Tries, in turn, until one lowers
/// the cost: the L-BFGS direction (when `quasi_newton` and it has curvature pairs), the paper's
/// direction, and the paper's direction from the exact linearisation (always a way down for a
/// short enough step, however short).
fn global(
    problem: &Problem,
    it: &mut Iterate,
    floor: f64,
    rho: f64,
    memory: &mut Memory,
    quasi_newton: bool,
) -> Option<f64> {
    let run = match it.run.take() {
        Some(run) => run,
        None => {
            // After local steps: the model itself under the errors found so far.
            let run = problem.run(&it.shift, &it.controls);
            it.cost = problem.cost(&it.shift, &it.controls, &run.states);
            it.states = run.states.clone();
            run
        }
    };
    let (horizon, steps) = (problem.horizon(), problem.timeline.steps);
    // The exact linearisation's model (a copy of the world's fields) is made only when the
    // cheaper directions have failed.
    let exact: OnceCell<Model> = OnceCell::new();
    let mut tries = Vec::new();
    if quasi_newton {
        tries.push(Try::Memory);
    } else {
        memory.clear();
    }
    tries.push(Try::Paper);
    if problem.model.linearisation != Linearisation::Exact {
        tries.push(Try::Exact);
    }
    let paper_halvings = match problem.model.linearisation {
        Linearisation::Exact => MAX_HALVINGS,
        Linearisation::Radial => RADIAL_HALVINGS,
    };
    // Set when the memory's direction was the paper's (no curvature pairs yet).
    let mut paper_tried = false;
    for attempt in tries {
        let model = match attempt {
            Try::Exact => exact.get_or_init(|| Model {
                linearisation: Linearisation::Exact,
                ..problem.model.clone()
            }),
            _ => &problem.model,
        };
        let (d, first, halvings) = match attempt {
            Try::Memory => {
                let d = direction(problem, model, &run, it, Some(&mut *memory));
                // With curvature pairs the direction is scaled: its whole length comes first.
                paper_tried = memory.is_empty();
                match paper_tried {
                    true => (d, rho, paper_halvings),
                    false => (d, 1.0, MEMORY_HALVINGS),
                }
            }
            Try::Paper if paper_tried => continue,
            Try::Paper => {
                memory.clear();
                (
                    direction(problem, model, &run, it, None),
                    rho,
                    paper_halvings,
                )
            }
            Try::Exact => {
                memory.clear();
                (direction(problem, model, &run, it, None), rho, MAX_HALVINGS)
            }
        };
        let start = it.cost.objective(problem.objective);
        let found = line_search(start, d.slope, first, halvings, |rho, enough| {
            let shift = moved(&it.shift, &d.shift, rho);
            let controls = moved(&it.controls, &d.controls, rho);
            let mut run = problem.run_to_horizon(&shift, &controls);
            let cost = problem.cost(&shift, &controls, &run.states);
            let mut value = if run.smallest_gap(horizon) >= floor {
                cost.objective(problem.objective)
            } else {
                f64::INFINITY
            };
            if value <= enough {
                // A step the search would take: after the last constraint the model alone
                // moves everyone, and the velocities the edit left may still carry two into
                // each other.
                run.finish(&problem.model, &controls);
                if run.smallest_gap(steps) < floor {
                    value = f64::INFINITY;
                }
            }
            (value, (shift, controls, run, cost))
        });
        if let Some((rho, (shift, controls, mut run, cost))) = found {
            run.finish(&problem.model, &controls);
            it.shift = shift;
            it.controls = controls;
            it.states = run.states.clone();
            it.run = Some(run);
            it.cost = cost;
            return Some(rho);
        }
    }
    it.run = Some(run);
    None
}

/// One local iteration (eq. 11-13): returns the step taken.
fn local(problem: &Problem, it: &mut Iterate, rho: f64) -> Option<f64> {
    let from_model = it.run.is_some();
    let run = match it.run.take() {
        Some(run) => run,
        None => Run::along(problem.timeline, it.states.clone()),
    };
    let d = direction(problem, &problem.model, &run, it, None);
    let dx = run.tangent(&problem.model, &d.shift, &d.controls);
    let gap = problem.model.clearance(&it.states).0;
    let start = it.cost.objective(problem.objective);
    let found = line_search(start, d.slope, rho, MAX_HALVINGS, |rho, _| {
        let shift = moved(&it.shift, &d.shift, rho);
        let controls = moved(&it.controls, &d.controls, rho);
        let states = moved(&it.states, &dx, rho);
        let cost = problem.cost(&shift, &controls, &states);
        // The tangent-linear model holds only while characters keep apart: a step that brings
        // two of them closer than the repulsion's range b (or than they already are) is too
        // long. Squeezed pairs make the linearised dynamics unstable across them (a pushed
        // pair's sideways mode grows as exp(t sqrt(s / (d m)))), and the next gradient with it.
        let floor = gap.min(problem.model.repulsion.range);
        let value = if problem.model.clearance(&states).0 >= floor {
            cost.objective(problem.objective)
        } else {
            f64::INFINITY
        };
        (value, (shift, controls, states, cost))
    });
    let Some((rho, (shift, controls, states, cost))) = found else {
        // Only the model's own run is kept: a global step after this one needs it.
        if from_model {
            it.run = Some(run);
        }
        return None;
    };
    it.shift = shift;
    it.controls = controls;
    it.states = states;
    it.run = None;
    it.cost = cost;
    Some(rho)
}
