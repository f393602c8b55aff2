//! Every derivative the descent uses, checked on small random crowds as the optimal crowd
//! editing issue asks: the tangent-linear model against central finite differences (relative
//! agreement 1e-5 or better) and the adjoint against the tangent-linear by the identity
//! <M' dx, y> = <dx, M'* y> (to 1e-10), for the model's right-hand side, a Runge-Kutta run,
//! each observation operator, and the cost's gradient.

use crowd_edit::cost::Objective;
use crowd_edit::integrate::{Run, Timeline};
use crowd_edit::model::{Character, Instant, Linearisation, Model, Plan, Repulsion};
use crowd_edit::neighbours::Pairs;
use crowd_edit::observe::{
    Apart, Blend, Counted, Density, EulerGrid, Limited, Observe, Positions, SpeedLimit, Velocity,
    Vorticity, Within,
};
use crowd_edit::{Constraint, Covariances, Problem, Rect, World};
use glam::DVec2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A crowd of `n` in a 12 x 10 m room with a pillar, heading for two goals: everyone within a
/// few metres of everyone, close enough that the repulsion, the pillar and the walls all act.
fn random_crowd(seed: u64, n: usize) -> (Model, Vec<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let bounds = Rect::new(DVec2::ZERO, DVec2::new(12.0, 10.0));
    let pillar = Rect::new(DVec2::new(6.0, 4.0), DVec2::new(7.0, 5.0));
    let goals = vec![
        Rect::new(DVec2::new(11.5, 0.0), DVec2::new(12.0, 10.0)),
        Rect::new(DVec2::new(0.0, 9.5), DVec2::new(12.0, 10.0)),
    ];
    let world = World::new(bounds, vec![pillar], goals);
    let mut characters = Vec::new();
    let mut x: Vec<f64> = Vec::new();
    while characters.len() < n {
        let p = DVec2::new(rng.random_range(3.5..9.0), rng.random_range(2.0..7.5));
        let clear =
            (0..characters.len()).all(|i| (DVec2::new(x[4 * i], x[4 * i + 1]) - p).length() > 0.45);
        if !clear || !world.is_free(p) || pillar_gap(p) < 0.3 {
            continue;
        }
        let mut c = Character::standard(rng.random_range(0.25..0.35), rng.random_range(0..2));
        c.mass *= rng.random_range(0.9..1.1);
        c.will *= rng.random_range(0.9..1.1);
        c.fatigue *= rng.random_range(0.9..1.1);
        characters.push(c);
        x.extend_from_slice(&[
            p.x,
            p.y,
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        ]);
    }
    let model = Model {
        characters,
        world,
        repulsion: Repulsion::default(),
        linearisation: Linearisation::Exact,
        tracks: None,
    };
    (model, x)
}

fn pillar_gap(p: DVec2) -> f64 {
    let d = (p - DVec2::new(6.5, 4.5)).abs() - DVec2::splat(0.5);
    d.max(DVec2::ZERO).length()
}

fn random_vector(rng: &mut ChaCha8Rng, len: usize) -> Vec<f64> {
    (0..len).map(|_| rng.random_range(-1.0..1.0)).collect()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}

/// |a - b| / |b|, the relative disagreement of two vectors.
fn relative(a: &[f64], b: &[f64]) -> f64 {
    let diff: Vec<f64> = a.iter().zip(b).map(|(a, b)| a - b).collect();
    norm(&diff) / norm(b).max(1e-300)
}

fn agree_to(a: f64, b: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs()).max(1e-300)
}

/// Central differences of `f` along `v` at `x`.
fn finite_difference(
    x: &[f64],
    v: &[f64],
    h: f64,
    mut f: impl FnMut(&[f64]) -> Vec<f64>,
) -> Vec<f64> {
    let plus: Vec<f64> = x.iter().zip(v).map(|(x, v)| x + h * v).collect();
    let minus: Vec<f64> = x.iter().zip(v).map(|(x, v)| x - h * v).collect();
    let (a, b) = (f(&plus), f(&minus));
    a.iter().zip(&b).map(|(a, b)| (a - b) / (2.0 * h)).collect()
}

#[test]
fn the_tangent_linear_model_is_the_derivative_of_the_forces() {
    for seed in 0..20 {
        let (model, x) = random_crowd(seed, 8);
        let mut rng = ChaCha8Rng::seed_from_u64(100 + seed);
        let v = random_vector(&mut rng, x.len());
        let mut pairs = Pairs::default();
        let mut jv = vec![0.0; x.len()];
        model.jvp(Instant::state(0), &x, &v, &mut pairs, &mut jv);
        let fd = finite_difference(&x, &v, 1e-6, |y| {
            let mut out = vec![0.0; y.len()];
            model.rhs(Instant::state(0), y, &mut Pairs::default(), &mut out);
            out
        });
        let err = relative(&fd, &jv);
        assert!(
            err < 1e-5,
            "seed {seed}: tangent vs finite differences {err:e}"
        );
    }
}

#[test]
fn the_adjoint_model_is_the_transpose_of_the_tangent() {
    for (seed, linearisation) in
        (0..20).flat_map(|s| [(s, Linearisation::Exact), (s, Linearisation::Radial)])
    {
        let (mut model, x) = random_crowd(seed, 8);
        model.linearisation = linearisation;
        let mut rng = ChaCha8Rng::seed_from_u64(200 + seed);
        let (v, w) = (
            random_vector(&mut rng, x.len()),
            random_vector(&mut rng, x.len()),
        );
        let mut pairs = Pairs::default();
        let (mut jv, mut jtw) = (vec![0.0; x.len()], vec![0.0; x.len()]);
        model.jvp(Instant::state(0), &x, &v, &mut pairs, &mut jv);
        model.vjp(Instant::state(0), &x, &w, &mut pairs, &mut jtw);
        let err = agree_to(dot(&jv, &w), dot(&v, &jtw));
        assert!(
            err < 1e-10,
            "seed {seed}, {linearisation:?}: <J v, w> vs <v, J^T w> {err:e}"
        );
    }
}

/// Central differences of a whole run from `x0` under `controls` along (dx0, de).
fn run_finite_difference(
    model: &Model,
    timeline: Timeline,
    (x0, controls): (&[f64], &[f64]),
    (dx0, de): (&[f64], &[f64]),
) -> Vec<f64> {
    let h = 1e-6;
    let shifted = |s: f64| {
        let x: Vec<f64> = x0.iter().zip(dx0).map(|(a, b)| a + s * b).collect();
        let e: Vec<f64> = controls.iter().zip(de).map(|(a, b)| a + s * b).collect();
        Run::forward(model, timeline, &x, &e).states
    };
    let (plus, minus) = (shifted(h), shifted(-h));
    plus.iter()
        .zip(&minus)
        .map(|(a, b)| (a - b) / (2.0 * h))
        .collect()
}

/// The adjoint of `run` forced by the weight `w` on every state (one state after another).
fn weighted_adjoint(run: &Run, model: &Model, w: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = run.n;
    run.adjoint(model, |k, _, mu| {
        for (m, v) in mu.iter_mut().zip(&w[k * n..(k + 1) * n]) {
            *m += v;
        }
    })
}

fn small_timeline() -> Timeline {
    Timeline { dt: 0.1, steps: 25 }
}

#[test]
fn a_runge_kutta_run_is_differentiated_exactly_by_its_tangent_and_adjoint() {
    for seed in 0..6 {
        let (model, x0) = random_crowd(seed, 6);
        let timeline = small_timeline();
        let n = x0.len();
        let mut rng = ChaCha8Rng::seed_from_u64(300 + seed);
        let controls: Vec<f64> = random_vector(&mut rng, timeline.steps * n);
        let run = Run::forward(&model, timeline, &x0, &controls);
        let (dx0, de) = (
            random_vector(&mut rng, n),
            random_vector(&mut rng, timeline.steps * n),
        );
        let dx = run.tangent(&model, &dx0, &de);
        let fd = run_finite_difference(&model, timeline, (&x0, &controls), (&dx0, &de));
        let err = relative(&fd, &dx);
        assert!(
            err < 1e-5,
            "seed {seed}: run tangent vs finite differences {err:e}"
        );
        // Adjoint identity with a random weight on every state of the run, for the exact and
        // the radial linearisation.
        let w = random_vector(&mut rng, (timeline.steps + 1) * n);
        let mut model = model;
        for linearisation in [Linearisation::Exact, Linearisation::Radial] {
            model.linearisation = linearisation;
            let dx = run.tangent(&model, &dx0, &de);
            let (mu0, ebar) = weighted_adjoint(&run, &model, &w);
            let lhs = dot(&dx, &w);
            let rhs = dot(&dx0, &mu0) + dot(&de, &ebar);
            let err = agree_to(lhs, rhs);
            assert!(
                err < 1e-10,
                "seed {seed}, {linearisation:?}: run adjoint identity {err:e}"
            );
        }
    }
}

/// The operators of the paper's constraints over the random room.
fn operators(n_characters: usize) -> Vec<(&'static str, Box<dyn Observe>)> {
    let grid = EulerGrid {
        origin: DVec2::new(2.0, 1.0),
        cell: 1.0,
        nx: 9,
        ny: 8,
        sigma: 0.8,
    };
    let all: Vec<usize> = (0..grid.cells()).collect();
    let inner = grid.cells_in(DVec2::new(4.0, 3.0), DVec2::new(8.0, 7.0));
    vec![
        (
            "apart",
            Box::new(Apart {
                clearance: 1.2,
                who: (0..n_characters).filter(|i| i % 4 != 2).collect(),
            }),
        ),
        (
            "speed limit",
            Box::new(SpeedLimit {
                who: (0..n_characters)
                    .map(|i| Limited {
                        character: i,
                        limit: 0.3 + 0.1 * i as f64,
                        // Every other one a walk shipped as a blend with a plan.
                        blend: (i % 2 == 1).then_some(Blend {
                            mask: 0.3 + 0.05 * i as f64,
                            slope: 1.5 - 0.2 * i as f64,
                            plan_pos: DVec2::new(4.0 + 0.5 * i as f64, 3.0),
                            plan_vel: DVec2::new(0.4, -0.2 * i as f64),
                        }),
                    })
                    .collect(),
            }),
        ),
        (
            "within",
            Box::new(Within {
                rect: crowd_edit::Rect::new(DVec2::new(4.0, 3.0), DVec2::new(6.0, 5.0)),
                who: (0..n_characters).filter(|i| i % 3 != 1).collect(),
            }),
        ),
        (
            "positions",
            Box::new(Positions {
                who: (0..n_characters).step_by(2).collect(),
            }),
        ),
        (
            "density",
            Box::new(Density {
                grid,
                cells: all.clone(),
                counted: Counted::All,
            }),
        ),
        (
            "velocity",
            Box::new(Velocity {
                grid,
                cells: all.clone(),
                counted: Counted::All,
            }),
        ),
        (
            "vorticity",
            Box::new(Vorticity {
                grid,
                cells: all,
                counted: Counted::All,
            }),
        ),
        (
            "vorticity (inner cells)",
            Box::new(Vorticity {
                grid,
                cells: inner,
                counted: Counted::Only((0..n_characters).filter(|i| i % 3 != 1).collect()),
            }),
        ),
    ]
}

#[test]
fn every_observation_operator_has_an_exact_tangent_and_adjoint() {
    for seed in 0..10 {
        let (_, x) = random_crowd(seed, 10);
        let mut rng = ChaCha8Rng::seed_from_u64(400 + seed);
        for (name, op) in operators(10) {
            let dx = random_vector(&mut rng, x.len());
            let mut tangent = vec![0.0; op.len()];
            op.tangent(&x, &dx, &mut tangent);
            let fd = finite_difference(&x, &dx, 1e-6, |y| {
                let mut out = vec![0.0; op.len()];
                op.observe(y, &mut out);
                out
            });
            let err = relative(&fd, &tangent);
            assert!(
                err < 1e-5,
                "seed {seed}, {name}: tangent vs finite differences {err:e}"
            );
            let dy = random_vector(&mut rng, op.len());
            let mut adjoint = vec![0.0; x.len()];
            op.adjoint_add(&x, &dy, &mut adjoint);
            let err = agree_to(dot(&tangent, &dy), dot(&dx, &adjoint));
            assert!(err < 1e-10, "seed {seed}, {name}: adjoint identity {err:e}");
            // A constraint's forcing, made in one pass, is the adjoint of its misfit.
            let mut h = vec![0.0; op.len()];
            op.observe(&x, &mut h);
            let scaled: Vec<f64> = h.iter().zip(&dy).map(|(h, y)| 0.3 * (h - y)).collect();
            let (mut apart, mut together) = (vec![0.0; x.len()], vec![0.0; x.len()]);
            op.adjoint_add(&x, &scaled, &mut apart);
            op.misfit_adjoint(&x, &dy, 0.3, &mut together);
            let err = relative(&together, &apart);
            assert!(err < 1e-12, "seed {seed}, {name}: misfit adjoint {err:e}");
        }
    }
}

#[test]
fn the_gradient_of_the_cost_is_its_derivative() {
    for (seed, objective) in
        (0..4).flat_map(|s| [(s, Objective::Cost), (s, Objective::Constraints)])
    {
        let (model, x0) = random_crowd(seed, 6);
        let timeline = small_timeline();
        let n = x0.len();
        let covariances = Covariances {
            q_position: 0.5,
            q_velocity: 100.0,
            b_position: 2.0,
            b_velocity: 1.0,
        };
        let mut constraints = Vec::new();
        for (k, (name, op)) in operators(6).into_iter().enumerate() {
            let mut rng = ChaCha8Rng::seed_from_u64(500 + seed + k as u64);
            let len = op.len();
            let window = (0.2 + 0.2 * k as f64, 0.6 + 0.25 * k as f64);
            let target = move |_: f64| random_vector(&mut rng, len);
            constraints
                .push(Constraint::over_window(name, op, timeline, window, 0.7, target).unwrap());
        }
        let problem = Problem {
            model,
            timeline,
            initial: x0,
            covariances,
            constraints,
            objective,
            keep_apart: true,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(600 + seed);
        let shift = random_vector(&mut rng, n)
            .iter()
            .map(|v| 0.1 * v)
            .collect::<Vec<_>>();
        let controls = random_vector(&mut rng, timeline.steps * n);
        let run = problem.run(&shift, &controls);
        let g = problem.gradient(&run, &shift, &controls);
        let (ds, de) = (
            random_vector(&mut rng, n),
            random_vector(&mut rng, timeline.steps * n),
        );
        let predicted = dot(&g.initial, &ds) + dot(&g.controls, &de);
        let h = 1e-6;
        let cost = |s: f64| {
            let shift: Vec<f64> = shift.iter().zip(&ds).map(|(a, b)| a + s * b).collect();
            let controls: Vec<f64> = controls.iter().zip(&de).map(|(a, b)| a + s * b).collect();
            let run = problem.run(&shift, &controls);
            problem
                .cost(&shift, &controls, &run.states)
                .objective(objective)
        };
        let fd = (cost(h) - cost(-h)) / (2.0 * h);
        let err = agree_to(fd, predicted);
        assert!(
            err < 1e-5,
            "seed {seed}: gradient {predicted} vs finite differences {fd} ({err:e})"
        );
    }
}

/// A crowd following plans (stage 7's walkers) in the random crowd's room: lanes 1.1 m apart
/// walked east at 0.8-1.3 m/s, each bending with a small constant acceleration (so that no two
/// plans come closer than the repulsion allows, as stage 5 guarantees); each character is in
/// the scene over a random span of whole steps (a third throughout) and may be edited over part
/// of it. Returns the model, the state at t = 0 (everyone on their plan, or where they will
/// enter) and the plans.
fn tracked_crowd(seed: u64, n: usize, steps: usize) -> (Model, Vec<f64>, Vec<Plan>) {
    let (model, x) = random_crowd(seed, n);
    let mut rng = ChaCha8Rng::seed_from_u64(700 + seed);
    let dt = small_timeline().dt;
    let half_steps = 2 * steps + 1;
    let mut plans = vec![Plan::default(); half_steps * n];
    let mut x0 = x.clone();
    for i in 0..n {
        let start = DVec2::new(
            2.0 + rng.random_range(-0.3..0.3),
            1.0 + 1.1 * i as f64 + rng.random_range(-0.05..0.05),
        );
        let vel = DVec2::new(rng.random_range(0.8..1.3), rng.random_range(-0.05..0.05));
        let acc = DVec2::new(rng.random_range(-0.2..0.2), rng.random_range(-0.05..0.05));
        let (enter, leave) = if i % 3 == 0 {
            (0, steps)
        } else {
            let a = rng.random_range(0..steps / 2);
            (a, rng.random_range(a + 2..=steps))
        };
        let (edit_from, edit_to) = (enter + 1, leave.saturating_sub(1).max(enter + 1));
        for h in 0..half_steps {
            let t = h as f64 * dt / 2.0;
            plans[h * n + i] = Plan {
                pos: start + vel * t + acc * (t * t / 2.0),
                vel: vel + acc * t,
                acc,
                present: (2 * enter..=2 * leave).contains(&h),
                editable: (2 * edit_from..=2 * edit_to).contains(&h),
            };
        }
        let entry = plans[2 * enter * n + i];
        x0[4 * i..4 * i + 4].copy_from_slice(&[entry.pos.x, entry.pos.y, entry.vel.x, entry.vel.y]);
    }
    (model.tracking(plans.clone(), 1.5), x0, plans)
}

#[test]
fn a_tracked_model_is_differentiated_exactly() {
    for seed in 0..10 {
        let steps = small_timeline().steps;
        let (mut model, _, _) = tracked_crowd(seed, 8, steps);
        let (_, x) = random_crowd(seed, 8);
        let mut rng = ChaCha8Rng::seed_from_u64(800 + seed);
        for at in [
            (0, 0),
            (3, 7),
            (steps / 3, 2 * steps / 3 + 1),
            (steps, 2 * steps),
        ] {
            let at = Instant {
                step: at.0,
                half: at.1,
            };
            let absent = (0..8).filter(|&i| !model.present(at, i)).count();
            let v = random_vector(&mut rng, x.len());
            let w = random_vector(&mut rng, x.len());
            let mut pairs = Pairs::default();
            let mut jv = vec![0.0; x.len()];
            model.linearisation = Linearisation::Exact;
            model.jvp(at, &x, &v, &mut pairs, &mut jv);
            let fd = finite_difference(&x, &v, 1e-6, |y| {
                let mut out = vec![0.0; y.len()];
                model.rhs(at, y, &mut Pairs::default(), &mut out);
                out
            });
            let err = relative(&fd, &jv);
            assert!(
                err < 1e-5,
                "seed {seed}, {at:?} ({absent} absent): tangent vs finite differences {err:e}"
            );
            for linearisation in [Linearisation::Exact, Linearisation::Radial] {
                model.linearisation = linearisation;
                let (mut jv, mut jtw) = (vec![0.0; x.len()], vec![0.0; x.len()]);
                model.jvp(at, &x, &v, &mut pairs, &mut jv);
                model.vjp(at, &x, &w, &mut pairs, &mut jtw);
                let err = agree_to(dot(&jv, &w), dot(&v, &jtw));
                assert!(
                    err < 1e-10,
                    "seed {seed}, {at:?}, {linearisation:?}: adjoint identity {err:e}"
                );
            }
        }
    }
}

#[test]
fn a_tracked_run_with_masked_controls_is_differentiated_exactly() {
    for seed in 0..4 {
        let timeline = small_timeline();
        let (model, x0, _) = tracked_crowd(seed, 6, timeline.steps);
        let n = x0.len();
        let mut rng = ChaCha8Rng::seed_from_u64(900 + seed);
        let controls = random_vector(&mut rng, timeline.steps * n);
        let run = Run::forward(&model, timeline, &x0, &controls);
        let (dx0, de) = (
            random_vector(&mut rng, n),
            random_vector(&mut rng, timeline.steps * n),
        );
        let dx = run.tangent(&model, &dx0, &de);
        let fd = run_finite_difference(&model, timeline, (&x0, &controls), (&dx0, &de));
        let err = relative(&fd, &dx);
        assert!(
            err < 1e-5,
            "seed {seed}: run tangent vs finite differences {err:e}"
        );
        let w = random_vector(&mut rng, (timeline.steps + 1) * n);
        let (mu0, ebar) = weighted_adjoint(&run, &model, &w);
        let err = agree_to(dot(&dx, &w), dot(&dx0, &mu0) + dot(&de, &ebar));
        assert!(err < 1e-10, "seed {seed}: run adjoint identity {err:e}");
        // No gradient reaches a control the plan does not let act.
        for (k, e) in ebar.chunks_exact(n).enumerate() {
            for i in 0..n / 4 {
                if !model.controlled(k, i) {
                    assert!(e[4 * i..4 * i + 4].iter().all(|v| *v == 0.0));
                }
            }
        }
    }
}

#[test]
fn unedited_tracked_characters_walk_their_plans() {
    for seed in 0..6 {
        let timeline = small_timeline();
        let (model, x0, plans) = tracked_crowd(seed, 8, timeline.steps);
        let n = x0.len();
        let run = Run::forward(&model, timeline, &x0, &vec![0.0; timeline.steps * n]);
        let mut worst: f64 = 0.0;
        for k in 0..=timeline.steps {
            for i in 0..8 {
                let plan = plans[2 * k * 8 + i];
                if plan.present {
                    let x = run.state(k);
                    worst = worst.max((DVec2::new(x[4 * i], x[4 * i + 1]) - plan.pos).length());
                }
            }
        }
        // The pull and the repulsions' differences vanish on the plan, so only Runge-Kutta's
        // own error on the pull remains: of order (w dt)^5 / 5! (w = 1.5 /s, dt = 0.1 s).
        assert!(worst < 1e-5, "seed {seed}: {worst:e} m off the plan");
    }
}
