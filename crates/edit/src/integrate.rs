//! Fourth-order Runge-Kutta integration of the controlled model dX/dt = f(X) + eps(t)
//! (Allain eq. 3; section 6: "all time integrations were performed using the fourth-order
//! Runge-Kutta method"), and its exact discrete tangent-linear and adjoint.
//!
//! The model error eps is held constant over each step. Differentiating the scheme itself
//! (rather than discretising the continuous adjoint, eq. 8) makes the gradient the exact
//! gradient of the cost the descent evaluates, which the finite-difference tests check.

use crate::model::{Instant, Model};
use crate::neighbours::Pairs;

/// Step length and count: states at t_k = k dt, k = 0..=steps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timeline {
    pub dt: f64,
    pub steps: usize,
}

impl Timeline {
    pub fn duration(&self) -> f64 {
        self.dt * self.steps as f64
    }

    /// The step nearest to time `t`.
    pub fn step_at(&self, t: f64) -> usize {
        ((t / self.dt).round().max(0.0) as usize).min(self.steps)
    }
}

/// A trajectory X_0..X_K with, for each step, the Runge-Kutta stage states Z2, Z3, Z4 the
/// tangent-linear and adjoint models linearise at (Z1 is X_k).
#[derive(Clone, Debug)]
pub struct Run {
    pub n: usize,
    pub timeline: Timeline,
    pub states: Vec<f64>,
    stages: Vec<f64>,
    /// Per state, the smallest gap between two characters (`Model::rhs_and_gap`), minus
    /// infinity for a state that is not finite; NaN where unknown (a run `along` states).
    gaps: Vec<f64>,
    /// The last step integrated (`timeline.steps` once the run is whole); the states after it
    /// are zero until `finish`.
    reached: usize,
}

impl Run {
    pub fn state(&self, k: usize) -> &[f64] {
        &self.states[k * self.n..(k + 1) * self.n]
    }

    fn stage(&self, k: usize, s: usize) -> &[f64] {
        if s == 0 {
            return self.state(k);
        }
        let at = (3 * k + s - 1) * self.n;
        &self.stages[at..at + self.n]
    }

    /// The run of the model from `x0` under `controls` (one state-sized block per step).
    pub fn forward(model: &Model, timeline: Timeline, x0: &[f64], controls: &[f64]) -> Run {
        Run::forward_until(model, timeline, x0, controls, timeline.steps)
    }

    /// The run up to step `until` only: what a cost whose last constraint is there needs (a
    /// line search's trials), `finish` doing the rest for the step it keeps.
    pub fn forward_until(
        model: &Model,
        timeline: Timeline,
        x0: &[f64],
        controls: &[f64],
        until: usize,
    ) -> Run {
        let n = x0.len();
        let mut run = Run::blank(n, timeline);
        run.states[..n].copy_from_slice(x0);
        run.integrate(model, controls, until.min(timeline.steps));
        run
    }

    /// Integrates the rest of the timeline.
    pub fn finish(&mut self, model: &Model, controls: &[f64]) {
        self.integrate(model, controls, self.timeline.steps);
    }

    fn integrate(&mut self, model: &Model, controls: &[f64], until: usize) {
        let n = self.n;
        let mut work = Work::new(n);
        for k in self.reached..until {
            let (done, rest) = self.states.split_at_mut((k + 1) * n);
            let stages = &mut self.stages[3 * k * n..3 * (k + 1) * n];
            let e = &controls[k * n..(k + 1) * n];
            let x = &done[k * n..];
            let gap = step(
                model,
                (k, self.timeline.dt),
                x,
                e,
                stages,
                &mut rest[..n],
                &mut work,
            );
            self.gaps[k] = finite_or(x, gap);
        }
        let last = self.state(until);
        self.gaps[until] = finite_or(
            last,
            model.smallest_gap(Instant::state(until), last, &mut work.pairs),
        );
        self.reached = self.reached.max(until);
    }

    /// The smallest gap between two characters at any state up to step `last`: the project's
    /// collision measure (below zero, two discs overlap), minus infinity when a state is not
    /// finite. Pairs farther apart than the repulsion's reach are not measured, so a gap above
    /// about 1.6 m means only "more than that".
    pub fn smallest_gap(&self, last: usize) -> f64 {
        self.gaps[..=last.min(self.reached)]
            .iter()
            .map(|g| if g.is_nan() { f64::NEG_INFINITY } else { *g })
            .fold(f64::INFINITY, f64::min)
    }

    /// The linearisation points of an arbitrary trajectory (the local descent's, which the
    /// tangent-linear model has moved off the model's own solution): the continuous
    /// tangent-linear model (eq. 11) along it, integrated by the same Runge-Kutta scheme, reads
    /// the Jacobian at t_k, t_k + dt/2 (the mean of the step's two states) and t_k + dt.
    /// (Taking the Runge-Kutta stages from X_k instead would push them off the trajectory by
    /// dt^2 times the accumulated control, into each other.)
    pub fn along(timeline: Timeline, states: Vec<f64>) -> Run {
        let n = states.len() / (timeline.steps + 1);
        let mut run = Run::blank(n, timeline);
        for k in 0..timeline.steps {
            let (x, next) = (
                &states[k * n..(k + 1) * n],
                &states[(k + 1) * n..(k + 2) * n],
            );
            let stages = &mut run.stages[3 * k * n..3 * (k + 1) * n];
            for m in 0..n {
                let mid = 0.5 * (x[m] + next[m]);
                stages[m] = mid;
                stages[n + m] = mid;
                stages[2 * n + m] = next[m];
            }
        }
        run.states = states;
        run.reached = timeline.steps;
        run
    }

    fn blank(n: usize, timeline: Timeline) -> Run {
        Run {
            n,
            timeline,
            states: vec![0.0; (timeline.steps + 1) * n],
            stages: vec![0.0; 3 * timeline.steps * n],
            gaps: vec![f64::NAN; timeline.steps + 1],
            reached: 0,
        }
    }

    /// The tangent-linear model along this run: dX_k for every k from dX_0 and the controls'
    /// perturbations (eq. 11-12, discretised as the scheme).
    pub fn tangent(&self, model: &Model, dx0: &[f64], dcontrols: &[f64]) -> Vec<f64> {
        let (n, dt) = (self.n, self.timeline.dt);
        let mut out = vec![0.0; (self.timeline.steps + 1) * n];
        out[..n].copy_from_slice(dx0);
        let mut work = Work::new(n);
        let mut dk = vec![vec![0.0; n]; 4];
        let mut dz = vec![0.0; n];
        for k in 0..self.timeline.steps {
            let (done, rest) = out.split_at_mut((k + 1) * n);
            let dx = &done[k * n..];
            let de = &dcontrols[k * n..(k + 1) * n];
            let weights = [0.0, 0.5, 0.5, 1.0];
            for s in 0..4 {
                if s == 0 {
                    dz.copy_from_slice(dx);
                } else {
                    for m in 0..n {
                        dz[m] = dx[m] + weights[s] * dt * dk[s - 1][m];
                    }
                }
                let at = Instant::stage(k, s);
                model.jvp(at, self.stage(k, s), &dz, &mut work.pairs, &mut dk[s]);
                add_control(model, k, &mut dk[s], de);
            }
            let next = &mut rest[..n];
            for m in 0..n {
                next[m] =
                    dx[m] + dt / 6.0 * (dk[0][m] + 2.0 * dk[1][m] + 2.0 * dk[2][m] + dk[3][m]);
            }
        }
        out
    }

    /// The adjoint model along this run, backwards from the last step it reached:
    /// `forcing(k, X_k, mu)` adds d(cost)/dX_k to mu (a cost that reads no state after that
    /// step has a zero adjoint there). Returns d(cost)/dX_0 and d(cost)/d(eps_k) for every step.
    pub fn adjoint(
        &self,
        model: &Model,
        forcing: impl FnMut(usize, &[f64], &mut [f64]),
    ) -> (Vec<f64>, Vec<f64>) {
        self.adjoint_from(model, self.reached, forcing)
    }

    /// The adjoint from step `last` back (no forcing after it: the adjoint is zero there).
    pub fn adjoint_from(
        &self,
        model: &Model,
        last: usize,
        mut forcing: impl FnMut(usize, &[f64], &mut [f64]),
    ) -> (Vec<f64>, Vec<f64>) {
        let (n, dt, steps) = (self.n, self.timeline.dt, self.timeline.steps);
        let last = last.min(self.reached);
        let mut mu = vec![0.0; n];
        let mut controls = vec![0.0; steps * n];
        forcing(last, self.state(last), &mut mu);
        let mut work = Work::new(n);
        let mut kbar = vec![vec![0.0; n]; 4];
        let mut zbar = vec![0.0; n];
        for k in (0..last).rev() {
            let ebar = &mut controls[k * n..(k + 1) * n];
            for (s, w) in [1.0, 2.0, 2.0, 1.0].into_iter().enumerate() {
                for m in 0..n {
                    kbar[s][m] = dt / 6.0 * w * mu[m];
                }
            }
            // Stages in reverse: Z_s = X + c_s dt k_{s-1}, k_s = f(Z_s) + eps.
            let weights = [0.0, 0.5, 0.5, 1.0];
            for s in (0..4).rev() {
                let at = Instant::stage(k, s);
                model.vjp(at, self.stage(k, s), &kbar[s], &mut work.pairs, &mut zbar);
                add_control(model, k, ebar, &kbar[s]);
                for m in 0..n {
                    mu[m] += zbar[m];
                }
                if s > 0 {
                    let c = weights[s] * dt;
                    for m in 0..n {
                        kbar[s - 1][m] += c * zbar[m];
                    }
                }
            }
            forcing(k, self.state(k), &mut mu);
        }
        (mu, controls)
    }
}

/// Buffers one Runge-Kutta step reuses.
struct Work {
    pairs: Pairs,
    k: Vec<Vec<f64>>,
}

impl Work {
    fn new(n: usize) -> Work {
        Work {
            pairs: Pairs::default(),
            k: vec![vec![0.0; n]; 4],
        }
    }
}

/// `gap`, or minus infinity when `x` is not finite (the pair search skips such states).
fn finite_or(x: &[f64], gap: f64) -> f64 {
    if x.iter().all(|v| v.is_finite()) {
        gap
    } else {
        f64::NEG_INFINITY
    }
}

/// Step `k` (of length `dt`) from `x` under control `e`: writes Z2, Z3, Z4 into `stages` and
/// the next state into `next`; returns the smallest gap between two characters at `x`.
fn step(
    model: &Model,
    (k, dt): (usize, f64),
    x: &[f64],
    e: &[f64],
    stages: &mut [f64],
    next: &mut [f64],
    work: &mut Work,
) -> f64 {
    let n = x.len();
    let weights = [0.5, 0.5, 1.0];
    let gap = model.rhs_and_gap(Instant::state(k), x, &mut work.pairs, &mut work.k[0]);
    add_control(model, k, &mut work.k[0], e);
    for s in 0..3 {
        let z = &mut stages[s * n..(s + 1) * n];
        for m in 0..n {
            z[m] = x[m] + weights[s] * dt * work.k[s][m];
        }
        model.rhs(
            Instant::stage(k, s + 1),
            z,
            &mut work.pairs,
            &mut work.k[s + 1],
        );
        add_control(model, k, &mut work.k[s + 1], e);
    }
    let k = &work.k;
    for m in 0..n {
        next[m] = x[m] + dt / 6.0 * (k[0][m] + 2.0 * k[1][m] + 2.0 * k[2][m] + k[3][m]);
    }
    gap
}

/// k += e for the characters whose model error may be non-zero in step `step`
/// (`Model::controlled`); also the adjoint's e_bar += k_bar, the same mask transposed.
fn add_control(model: &Model, step: usize, k: &mut [f64], e: &[f64]) {
    if model.tracks.is_none() {
        for (a, b) in k.iter_mut().zip(e) {
            *a += b;
        }
        return;
    }
    for (i, (k, e)) in k.chunks_exact_mut(4).zip(e.chunks_exact(4)).enumerate() {
        if model.controlled(step, i) {
            for (a, b) in k.iter_mut().zip(e) {
                *a += b;
            }
        }
    }
}
