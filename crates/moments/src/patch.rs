//! One patch edited: its problem (the characters of `plan.rs` following their plans under a
//! social-force repulsion, the constraints of `targets.rs` and a soft speed limit), the
//! descent (L-BFGS on eq. 6 whole), and the edited trajectories: each walker's plan plus the
//! descent's displacement times its mask, so that entry, exit and border bands stay exactly as
//! they were. A walker whose edited walk is too fast or leaves the patch takes half of its
//! displacement, then a quarter, ...; one that (measured exactly, as stage 5 measures) comes
//! closer to anyone or anything than its plan did is held on its plan round that moment, up to
//! [`HOLDS`] moments, then walks its plan.

use crate::plan::{Copy, DT, RAMP_S, copies, plans};
use crate::targets::{Local, Measure, Residual, constrain, residual};
use crowd_core::trajectories::{ControlPoint, PatchMotion, PointKind, Trajectory, position_at};
use crowd_edit::cost::Sample;
use crowd_edit::descent::{Descent, solve};
use crowd_edit::model::{Character, Linearisation, Model, Plan, Repulsion};
use crowd_edit::observe::{Apart, Blend, Limited, SpeedLimit};
use crowd_edit::{Constraint, Covariances, Objective, Problem, Rect, Timeline, World};
use crowd_geometry::{Ladder, Patch, keep_clear};
use glam::DVec2;

/// Descent iterations per patch at most (each descent also stops when converged).
pub const ITERATIONS: usize = 200;
/// How fast a walker returns to its plan once no edit pushes it, 1/s (`Model::tracking`).
pub const PULL_RATE: f64 = 1.0;
/// The social repulsion of the edit's model: softer and longer than the paper's (a = 1000 N,
/// b = 0.08 m), whose stiffness, felt as a difference from the plan's own where stage 5 left
/// walkers passing close, rang at 2 Hz and made edited walkers run (3.7 m/s where 1.87 m/s is
/// the limit). a = 1000 N at this range held the edits back (density on `city`'s busiest
/// patch: RMS 0.133 -> 0.127 instead of -> 0.104). The exact check, not the repulsion, is what
/// keeps walkers apart.
pub const REPULSION: Repulsion = Repulsion {
    strength: 140.0,
    range: 0.3,
    cutoff: 3.0,
};

/// Encounters a walker is held on its plan round before it walks its plan unedited.
pub const HOLDS: u32 = 8;

/// The largest velocity change between two pieces of an edited walk, m/s, unless its plan
/// already changes more: the bound `world.glb`'s handovers keep (`tests/export_clip.rs`).
/// Without it, a hurried walker on a dense patch jolted by 4.3 m/s from one frame to the next
/// (1.9 m/s unedited); most edited walks keep well within it.
pub const MAX_JOLT: f64 = 0.6;

/// Halvings of a walker's displacement before it walks its plan unedited.
pub const HALVINGS: u32 = 6;

/// What editing one patch gave.
pub struct Edited {
    pub motion: PatchMotion,
    /// Per local edit (in the order given): its residual before and after.
    pub residuals: Vec<(Residual, Residual)>,
    pub iterations: usize,
    /// Walkers whose walk changed.
    pub walkers: usize,
}

/// What the stage knows of a patch besides its motion.
pub struct Context<'a> {
    pub patch: Patch<'a>,
    pub obstacles: &'a [crowd_core::Rect],
    /// The fastest a walker may walk, m/s.
    pub max_speed: f64,
    /// Q_u, m^2/s^4.
    pub q: f64,
}

/// Edits one patch: `locals` are the edits that reach it, `span` the problem's time span
/// (absolute seconds, at most a period) that holds their windows with room before and after.
pub fn edit_patch(
    motion: &PatchMotion,
    locals: &[Local],
    span: (f64, f64),
    cx: &Context,
) -> Edited {
    let period = cx.patch.period_s;
    let copies = copies(motion, period, span);
    let steps = ((span.1 - span.0) / DT).round().max(1.0) as usize;
    let (plan, x0) = plans(&copies, motion, span, steps);
    let n = copies.len();
    let positions = |k: usize, i: usize| plan[2 * k * n + i].pos;
    let mut constraints = Vec::new();
    let measures: Vec<Measure> = locals
        .iter()
        .map(|l| {
            constrain(
                l,
                &copies,
                span,
                steps,
                &positions,
                cx.patch.radius_m,
                &mut constraints,
            )
        })
        .collect();
    limit_speeds(
        &copies,
        motion,
        span,
        steps,
        cx.max_speed,
        &plan,
        &mut constraints,
    );
    keep_apart(&copies, span, steps, cx.patch.radius_m, &mut constraints);
    let side = cx.patch.side_m;
    let world = World::new(
        Rect::new(DVec2::ZERO, DVec2::splat(side)),
        cx.obstacles
            .iter()
            .map(|o| Rect::new(o.min, o.max))
            .collect(),
        vec![],
    );
    let character = Character::standard(cx.patch.radius_m, 0);
    let model = Model {
        characters: vec![character; n],
        world,
        repulsion: REPULSION,
        linearisation: Linearisation::Exact,
        tracks: None,
    }
    .tracking(plan, PULL_RATE);
    let problem = Problem {
        model,
        timeline: Timeline { dt: DT, steps },
        initial: x0,
        covariances: Covariances::velocity_only(cx.q),
        constraints,
        objective: Objective::Cost,
        keep_apart: false,
    };
    let outcome = solve(&problem, Descent::QuasiNewton, ITERATIONS, |_, _| {});
    let iterations = outcome.log.len() - 1;
    let displacement = |i: usize, k: usize| {
        let at = |s: &[f64]| DVec2::new(s[k * 4 * n + 4 * i], s[k * 4 * n + 4 * i + 1]);
        at(&outcome.states) - at(&outcome.before.states)
    };
    let shape = Shape {
        copies: &copies,
        span,
        steps,
    };
    let before = &motion.trajectories;
    // Walker j with 2^-level of its displacement, if that walk keeps to the speed limit (or
    // to its plan's fastest piece), changes velocity between pieces no more than
    // [`MAX_JOLT`] (or its plan's roughest change) and stays in the patch: drawn through
    // the steps alone, or, if that fails, through every point of the plan as well.
    // Each walker's limits, from its plan (measured once, not at every attempt).
    let limits: Vec<(f64, f64)> = before
        .iter()
        .map(|tr| {
            let allowed = cx.max_speed.max(fastest(tr)) + 1e-9;
            (allowed, MAX_JOLT.max(roughest(tr)) + 1e-9)
        })
        .collect();
    let attempt = |j: usize, level: u32, held: &[f64]| -> Option<Trajectory> {
        let scale = 0.5f64.powi(level as i32);
        let (allowed, jolt) = limits[j];
        [Points::Steps, Points::Plan]
            .into_iter()
            .find_map(|points| {
                let d = |i, k| displacement(i, k) * scale;
                let tr = shape.edited(&before[j], j, &d, held, points);
                (fastest(&tr) <= allowed && roughest(&tr) <= jolt && inside(&tr, side))
                    .then_some(tr)
            })
    };
    // The first allowed walk from `level` on; the plan after the last halving.
    // Held on its plan round `held` times, at the largest allowed scale: the walk keeps the
    // edit away from the encounters that refused it.
    let candidate = |j: usize, held: &[f64]| -> Trajectory {
        (0..=HALVINGS)
            .find_map(|level| attempt(j, level, held))
            .unwrap_or_else(|| before[j].clone())
    };
    let edited: Vec<Trajectory> = (0..before.len()).map(|j| candidate(j, &[])).collect();
    let ladder = Ladder {
        levels: 0,
        halvings: 0,
        holds: HOLDS,
    };
    let chosen = keep_clear(before, edited, &cx.patch, ladder, |j, _, held| {
        candidate(j, held)
    });
    let walkers = chosen.iter().zip(before).filter(|(a, b)| a != b).count();
    let shipped = PatchMotion {
        standers: motion.standers.clone(),
        trajectories: chosen,
    };
    let states_of = |m: &PatchMotion| shape.states(m);
    let (was, now) = (states_of(motion), states_of(&shipped));
    let residuals = measures
        .iter()
        .map(|m| {
            (
                residual(m, &problem.constraints, &was, 4 * n),
                residual(m, &problem.constraints, &now, 4 * n),
            )
        })
        .collect();
    Edited {
        motion: shipped,
        residuals,
        iterations,
        walkers,
    }
}

/// R of the speed limit, (m/s)^2: a soft guard against walks far too fast to ship (the ladder
/// then halves them, and the walkers the model kept apart from them collide). Stronger
/// (0.005) it held the edits back more than the ladder did (density: RMS 0.133 -> 0.134
/// instead of -> 0.104 on `city`'s busiest patch).
pub const SPEED_R: f64 = 0.002;

/// How far under its limit the model keeps a walker: the walk shipped is sampled from it, and
/// its pieces' speeds come out a little above the model's.
pub const SPEED_MARGIN: f64 = 0.95;

/// The soft speed limit at every step on the walkers that may be edited then: each at
/// `max_speed`, or its plan's fastest where that is faster already ([`SpeedLimit`]), on the
/// walk as it ships (the plan plus the displacement times the mask: [`Blend`]).
fn limit_speeds(
    copies: &[Copy],
    motion: &PatchMotion,
    span: (f64, f64),
    steps: usize,
    max_speed: f64,
    plan: &[Plan],
    out: &mut Vec<Constraint>,
) {
    let n = copies.len();
    let limits: Vec<f64> = copies
        .iter()
        .map(|c| {
            c.trajectory
                .map_or(0.0, |j| max_speed.max(fastest(&motion.trajectories[j])))
        })
        .collect();
    // The masks' slopes by central differences (a smoothstep over a second: 1e-4 s resolves
    // them to 1e-8).
    const H: f64 = 1e-4;
    for k in 0..=steps {
        let t = span.0 + k as f64 * DT;
        let who: Vec<Limited> = (0..n)
            .filter(|&i| copies[i].mask(t, span) > 0.0)
            .map(|i| {
                let c = &copies[i];
                let p = plan[2 * k * n + i];
                Limited {
                    character: i,
                    limit: SPEED_MARGIN * limits[i],
                    blend: Some(Blend {
                        mask: c.mask(t, span),
                        slope: (c.mask(t + H, span) - c.mask(t - H, span)) / (2.0 * H),
                        plan_pos: p.pos,
                        plan_vel: p.vel,
                    }),
                }
            })
            .collect();
        if who.is_empty() {
            continue;
        }
        out.push(Constraint {
            name: "speed limit".to_string(),
            samples: vec![Sample {
                step: k,
                target: vec![0.0; who.len()],
                weight: DT,
            }],
            operator: Box::new(SpeedLimit { who }),
            r: SPEED_R,
        });
    }
}

/// R of the soft collision rule, m^2: strong, since a collision the model leaves costs the
/// walkers in it their edit at the exact check.
pub const APART_R: f64 = 0.001;

/// How much farther apart than the exact check needs the model keeps everyone, m: the model
/// walks its plans to within a few centimetres (Runge-Kutta on polylines).
pub const APART_BUFFER_M: f64 = 0.05;

/// The soft collision rule at every step on everyone present ([`Apart`]): centres
/// 2 `radius` + [`APART_BUFFER_M`] apart.
fn keep_apart(
    copies: &[Copy],
    span: (f64, f64),
    steps: usize,
    radius: f64,
    out: &mut Vec<Constraint>,
) {
    for k in 0..=steps {
        let t = span.0 + k as f64 * DT;
        let who: Vec<usize> = (0..copies.len())
            .filter(|&i| copies[i].present(t))
            .collect();
        if who.len() < 2 {
            continue;
        }
        out.push(Constraint {
            name: "apart".to_string(),
            samples: vec![Sample {
                step: k,
                target: vec![0.0; who.len()],
                weight: DT,
            }],
            operator: Box::new(Apart {
                clearance: 2.0 * radius + APART_BUFFER_M,
                who,
            }),
            r: APART_R,
        });
    }
}

/// Which of its plan's points an edited walk goes through between the problem's steps.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Points {
    /// Splits and pauses only: the walk is drawn through the steps, which averages a plan's
    /// quick corners over [`DT`] (a 90-degree turn stage 6 makes in 0.15 s becomes one
    /// velocity change of 1.2 m/s, over [`MAX_JOLT`]).
    Steps,
    /// Every point of the plan, corners kept as they were; its short pieces, with the
    /// displacement's velocity added, are more often over the speed limit (on `city`'s
    /// square, the density edit reaches 83 % of its target this way, 89 % with `Steps` first).
    Plan,
}

/// The problem's copies and clock, to turn displacements into walks and walks into states.
struct Shape<'a> {
    copies: &'a [Copy],
    span: (f64, f64),
    steps: usize,
}

impl Shape<'_> {
    /// Trajectory `j` with its copies' displacements (`displacement(copy, step)`) added,
    /// each times its mask: a point at every step where a mask is positive, and the plan's
    /// points as they are where every mask is zero (entry, exit, border bands). Between
    /// steps, its splits and pauses (displaced) and, with [`Points::Plan`], every other point
    /// of the plan too.
    fn edited(
        &self,
        tr: &Trajectory,
        j: usize,
        displacement: &dyn Fn(usize, usize) -> DVec2,
        held: &[f64],
        through: Points,
    ) -> Trajectory {
        let mine: Vec<usize> = (0..self.copies.len())
            .filter(|&i| self.copies[i].trajectory == Some(j))
            .collect();
        // The offset at the trajectory's own time `tau`, and whether any mask is positive.
        let offset = |tau: f64| -> (DVec2, bool) {
            let mut sum = DVec2::ZERO;
            let mut edited = false;
            for &i in &mine {
                let c = &self.copies[i];
                let t = tau + c.shift;
                let w = c.mask(t, self.span);
                if w > 0.0 {
                    edited = true;
                    let f = ((t - self.span.0) / DT).clamp(0.0, self.steps as f64);
                    let k = (f.floor() as usize).min(self.steps.saturating_sub(1));
                    let a = f - k as f64;
                    let d = displacement(i, k) * (1.0 - a) + displacement(i, k + 1) * a;
                    sum += d * w;
                }
            }
            let keep = held.iter().map(|&h| 1.0 - notch(tau - h)).product::<f64>();
            (sum * keep, edited)
        };
        let mut points: Vec<ControlPoint> = Vec::with_capacity(tr.points.len());
        for p in &tr.points {
            let (d, edited) = offset(p.t);
            let kept = matches!(p.kind, PointKind::Split | PointKind::Pause);
            if !edited {
                points.push(*p);
            } else if kept || through == Points::Plan {
                points.push(ControlPoint {
                    pos: p.pos + d,
                    ..*p
                });
            }
        }
        for &i in &mine {
            let c = &self.copies[i];
            for k in 0..=self.steps {
                let tau = self.span.0 + k as f64 * DT - c.shift;
                if !(tr.points[0].t < tau && tau < tr.points[tr.points.len() - 1].t) {
                    continue;
                }
                let (d, edited) = offset(tau);
                if edited {
                    points.push(ControlPoint {
                        pos: position_at(&tr.points, tau) + d,
                        t: tau,
                        kind: PointKind::Sample,
                    });
                }
            }
        }
        points.sort_by(|a, b| a.t.total_cmp(&b.t));
        points.dedup_by(|b, a| b.t == a.t && b.kind == PointKind::Sample);
        Trajectory {
            entry: tr.entry,
            exit: tr.exit,
            points,
        }
    }

    /// The states (positions, and velocities by differences) of every copy at every step, as
    /// `motion` walks them: what the residuals are measured on.
    fn states(&self, motion: &PatchMotion) -> Vec<f64> {
        let n = 4 * self.copies.len();
        let mut out = vec![0.0; (self.steps + 1) * n];
        for k in 0..=self.steps {
            let t = self.span.0 + k as f64 * DT;
            for (i, c) in self.copies.iter().enumerate() {
                let p = c.position(motion, t);
                let v = (c.position(motion, t + DT / 2.0) - c.position(motion, t - DT / 2.0)) / DT;
                out[k * n + 4 * i..k * n + 4 * i + 4].copy_from_slice(&[p.x, p.y, v.x, v.y]);
            }
        }
        out
    }
}

/// 1 within [`HOLD_S`] of 0, falling smoothly to 0 over [`RAMP_S`] beyond: how much of its
/// plan a walker keeps round a time it was held at.
fn notch(x: f64) -> f64 {
    let s = ((HOLD_S + RAMP_S - x.abs()) / RAMP_S).clamp(0.0, 1.0);
    s * s * (3.0 - 2.0 * s)
}

/// Half the time round an encounter an edited walker is held on its plan, s.
pub const HOLD_S: f64 = 0.5;

/// The speed of a trajectory's fastest piece, m/s.
pub fn fastest(tr: &Trajectory) -> f64 {
    tr.points
        .windows(2)
        .filter(|w| w[1].t > w[0].t)
        .map(|w| w[0].pos.distance(w[1].pos) / (w[1].t - w[0].t))
        .fold(0.0, f64::max)
}

/// The largest velocity change from one piece of a trajectory to the next, m/s: what a player
/// shows as a jolt between two frames where the walk turns at a point.
pub fn roughest(tr: &Trajectory) -> f64 {
    let velocities = tr
        .points
        .windows(2)
        .filter(|w| w[1].t > w[0].t)
        .map(|w| (w[1].pos - w[0].pos) / (w[1].t - w[0].t));
    velocities
        .clone()
        .zip(velocities.skip(1))
        .map(|(a, b)| a.distance(b))
        .fold(0.0, f64::max)
}

/// Every point inside the patch square.
fn inside(tr: &Trajectory, side: f64) -> bool {
    tr.points
        .iter()
        .all(|p| p.pos.cmpge(DVec2::ZERO).all() && p.pos.cmple(DVec2::splat(side)).all())
}
