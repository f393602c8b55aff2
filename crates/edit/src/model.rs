//! The social-force crowd model of Allain section 5 (after Helbing et al. 2000), its right-hand
//! side f(X) = -M(X) (eq. 16-26), and the products of its Jacobian with a vector (the
//! tangent-linear model, eq. 11) and of its transpose (the adjoint, eq. 27-29).
//!
//! The state holds, per character, `[y.x, y.y, u.x, u.y]`: position then velocity.

use crate::neighbours::Pairs;
use crate::world::World;
use glam::DVec2;
use serde::{Deserialize, Serialize};

/// Numbers per character in a state vector.
pub const PER_CHARACTER: usize = 4;

/// One character's coefficients (the paper's m_i, r_i, alpha_i, k_i) and the goal it heads for.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Character {
    /// kg (70 in the paper).
    pub mass: f64,
    /// m (drawn in [0.25, 0.35]).
    pub radius: f64,
    /// The will's strength alpha, N (140).
    pub will: f64,
    /// The fatigue coefficient k, kg/s (140).
    pub fatigue: f64,
    /// Index into the world's goals.
    pub goal: usize,
}

impl Character {
    /// The paper's homogeneous character (section 5.1) of radius `radius`.
    pub fn standard(radius: f64, goal: usize) -> Character {
        Character {
            mass: 70.0,
            radius,
            will: 140.0,
            fatigue: 140.0,
            goal,
        }
    }
}

/// The repulsion between characters (eq. 21) and from obstacles (eq. 25).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Repulsion {
    /// a, N (1000).
    pub strength: f64,
    /// b, m (0.08).
    pub range: f64,
    /// Characters farther apart than this are not connected (3 m).
    pub cutoff: f64,
}

/// A repulsion weaker than this is not evaluated, N: a hundred-millionth of the will (140 N),
/// it moves no one by a micrometre over a minute, and skipping it saves the exponential of
/// every connected pair more than about 1.7 m beyond contact (40 % of them in a crowd).
pub const NEGLIGIBLE_FORCE: f64 = 1e-6;

impl Repulsion {
    /// (d - r) / b beyond which a * exp(-(d - r) / b) is below [`NEGLIGIBLE_FORCE`].
    fn negligible(&self) -> f64 {
        (self.strength / NEGLIGIBLE_FORCE).ln()
    }

    /// How far apart two characters whose radii sum at most to `radii` still push each other
    /// more than negligibly: the pair search looks no farther (3 m: 2.4 m for the paper's
    /// radii, which halves the candidates).
    fn reach(&self, radii: f64) -> f64 {
        self.cutoff.min(radii + self.range * self.negligible())
    }
}

impl Default for Repulsion {
    fn default() -> Self {
        Repulsion {
            strength: 1000.0,
            range: 0.08,
            cutoff: 3.0,
        }
    }
}

/// The crowd model: who walks, where, and how they push each other.
#[derive(Clone, Debug)]
pub struct Model {
    pub characters: Vec<Character>,
    pub world: World,
    pub repulsion: Repulsion,
    /// Which Jacobian `jvp` and `vjp` use (the forces are the same either way).
    pub linearisation: Linearisation,
    /// Set when the characters follow planned motions rather than head for goals
    /// ([`Tracks`]: stage 7's walkers); the experiments' crowds have none.
    pub tracks: Option<Tracks>,
}

/// Where in the timeline a model evaluation is: in Runge-Kutta step `step`, at half step
/// `half` (time half dt / 2), one of 2 step, 2 step + 1 (the two middle stages) and
/// 2 step + 2. Only tracked characters' forces depend on it: their plans are read at `half`,
/// and who is present or controlled at the step's start, so that a character enters or
/// leaves between steps, never inside one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Instant {
    pub step: usize,
    pub half: usize,
}

impl Instant {
    /// Runge-Kutta stage `s` (0-3) of step `k`.
    pub fn stage(k: usize, s: usize) -> Instant {
        Instant {
            step: k,
            half: 2 * k + [0, 1, 1, 2][s],
        }
    }

    /// The state at step `k` (the first stage of step k).
    pub fn state(k: usize) -> Instant {
        Instant::stage(k, 0)
    }
}

/// What a tracked character should do at one half step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Plan {
    pub pos: DVec2,
    pub vel: DVec2,
    pub acc: DVec2,
    /// In the scene at all: an absent character feels and exerts nothing, is counted by no
    /// operator, and stands still in the state until it enters.
    pub present: bool,
    /// Its model error may be non-zero here (stage 7: inside the patch, off the border
    /// bands); elsewhere the control is held at zero.
    pub editable: bool,
}

/// Characters that follow planned motions (stage 7: the walkers of a patch, as stages 4-6
/// made them). The will of eq. 19 becomes a critically damped pull towards the plan,
///
///   F_will = m (a_plan + 2 w (v_plan - u) + w^2 (p_plan - y)),
///
/// which replaces the fatigue term too, and the repulsions count only as far as they differ
/// from those the plan itself feels (its walkers pass each other closer than the repulsion's
/// range, as stage 5 allows), so that the unedited model walks the plan and an edit meets the
/// repulsion only where it brings people closer than planned.
#[derive(Clone, Debug)]
pub struct Tracks {
    /// `plans[h * n + i]` for character i at half step h.
    plans: Vec<Plan>,
    n: usize,
    /// w, 1/s.
    pub rate: f64,
    /// The repulsion (social and obstacle) the plan feels, per character at each of step k's
    /// half steps 2k, 2k + 1, 2k + 2 (slots 3k, 3k + 1, 3k + 2: half step 2k + 2 is both the
    /// end of step k and the start of step k + 1, whose characters may differ).
    planned_push: Vec<DVec2>,
}

impl Tracks {
    /// Character `i`'s plan at half step `half`.
    pub fn plan(&self, half: usize, i: usize) -> &Plan {
        &self.plans[half * self.n + i]
    }

    /// Half steps planned (2 steps + 1).
    pub fn half_steps(&self) -> usize {
        self.plans.len() / self.n.max(1)
    }
}

/// The Jacobian the tangent-linear and adjoint models use.
///
/// The pair force's derivative has two parts: along the line between the two (s / b, a stiff
/// spring that keeps them apart) and across it (-s / d, a negative stiffness: a pushed pair
/// turns away from its push). The second makes the linearised dynamics of a pressed crowd
/// grow as exp(t sqrt(s / (d m))), so over the tens of seconds of an edit the exact gradient
/// of a crossing or a jam is dominated by sensitivities of 10^5 and more (the paper's
/// "tangling issue", section 4.3): the line search then only accepts steps of 1e-10. `Radial`
/// keeps only the spring: the gradient of a smoothed, non-chaotic linearisation, which the
/// descent uses as its direction while the line search judges the true cost.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Linearisation {
    #[default]
    Exact,
    Radial,
}

/// Read and write one character's position and velocity in a state vector.
pub fn position(x: &[f64], i: usize) -> DVec2 {
    DVec2::new(x[4 * i], x[4 * i + 1])
}
pub fn velocity(x: &[f64], i: usize) -> DVec2 {
    DVec2::new(x[4 * i + 2], x[4 * i + 3])
}
fn add(x: &mut [f64], at: usize, v: DVec2) {
    x[at] += v.x;
    x[at + 1] += v.y;
}

/// A 2 x 2 matrix as its two rows.
#[derive(Clone, Copy, Debug)]
struct Mat2([DVec2; 2]);

impl Mat2 {
    fn mul(&self, v: DVec2) -> DVec2 {
        DVec2::new(self.0[0].dot(v), self.0[1].dot(v))
    }
    fn mul_transpose(&self, v: DVec2) -> DVec2 {
        self.0[0] * v.x + self.0[1] * v.y
    }
}

/// What one character feels from the fields at its position: force and its Jacobian.
struct FieldForce {
    force: DVec2,
    jacobian: Mat2,
}

/// What a connected pair feels: the force on the first (the second gets its opposite) and the
/// symmetric derivative K of that force by the pair's offset y_j - y_i.
struct PairForce {
    force: DVec2,
    k: Mat2,
}

impl Model {
    pub fn len(&self) -> usize {
        self.characters.len()
    }

    /// This model with its characters following `plans` (`plans[h * n + i]`, one per half
    /// step of the timeline) at pull rate `rate` (1/s). The plans' own repulsions are measured
    /// here, once.
    pub fn tracking(mut self, plans: Vec<Plan>, rate: f64) -> Model {
        let n = self.len();
        assert!(
            n > 0 && plans.len().is_multiple_of(n),
            "plans must hold one plan per character and half step"
        );
        self.tracks = None;
        let steps = plans.len() / n / 2;
        let mut planned_push = vec![DVec2::ZERO; (3 * steps + 1) * n];
        let mut pairs = Pairs::default();
        let mut x = vec![0.0; self.state_len()];
        for (slot, push) in planned_push.chunks_exact_mut(n).enumerate() {
            let (step, half) = (slot / 3, 2 * (slot / 3) + slot % 3);
            let plan = &plans[half * n..(half + 1) * n];
            // Who is there is read at the step's start, as the model reads it.
            let present = |i: usize| plans[2 * step * n + i].present;
            for (i, p) in plan.iter().enumerate() {
                x[4 * i..4 * i + 2].copy_from_slice(&[p.pos.x, p.pos.y]);
            }
            for (i, p) in plan.iter().enumerate().filter(|(i, _)| present(*i)) {
                push[i] = self.obstacle_force(i, p.pos).force;
            }
            pairs.near(&x, self.search_radius());
            for &(i, j) in pairs.list() {
                if !(present(i) && present(j)) {
                    continue;
                }
                let d = position(&x, j) - position(&x, i);
                if let Some(pf) = self.pair_force(d, self.radii(i, j)) {
                    push[i] += pf.force;
                    push[j] -= pf.force;
                }
            }
        }
        self.tracks = Some(Tracks {
            plans,
            n,
            rate,
            planned_push,
        });
        self
    }

    /// The plan of character `i` at the start of step `step`, when the characters follow
    /// plans.
    fn plan_at_step(&self, step: usize, i: usize) -> Option<&Plan> {
        self.tracks.as_ref().map(|t| t.plan(2 * step, i))
    }

    /// Whether character `i` is in the scene during `at`'s step (always, without plans).
    pub fn present(&self, at: Instant, i: usize) -> bool {
        self.plan_at_step(at.step, i).is_none_or(|p| p.present)
    }

    /// Whether character `i`'s model error may be non-zero in step `step`.
    pub fn controlled(&self, step: usize, i: usize) -> bool {
        self.plan_at_step(step, i)
            .is_none_or(|p| p.present && p.editable)
    }

    /// Whether both of a pair are in the scene at `at`.
    fn both_present(&self, at: Instant, i: usize, j: usize) -> bool {
        self.tracks.is_none() || (self.present(at, i) && self.present(at, j))
    }

    /// The distance within which pairs are searched.
    fn search_radius(&self) -> f64 {
        let largest = self.characters.iter().map(|c| c.radius).fold(0.0, f64::max);
        self.repulsion.reach(2.0 * largest)
    }

    pub fn is_empty(&self) -> bool {
        self.characters.is_empty()
    }

    pub fn state_len(&self) -> usize {
        PER_CHARACTER * self.len()
    }

    /// Will (eq. 19) and obstacle repulsion (eq. 25) on character `i` at `p`.
    fn field_force(&self, i: usize, p: DVec2) -> FieldForce {
        let c = &self.characters[i];
        let (w, jw) = self.world.will[c.goal].sample(p);
        let obstacle = self.obstacle_force(i, p);
        FieldForce {
            force: w * c.will + obstacle.force,
            jacobian: Mat2([
                jw[0] * c.will + obstacle.jacobian.0[0],
                jw[1] * c.will + obstacle.jacobian.0[1],
            ]),
        }
    }

    /// Obstacle repulsion (eq. 25) on character `i` at `p`.
    fn obstacle_force(&self, i: usize, p: DVec2) -> FieldForce {
        let c = &self.characters[i];
        let mut force = DVec2::ZERO;
        let mut rows = [DVec2::ZERO; 2];
        if self.world.obstacles.is_empty() {
            return FieldForce {
                force,
                jacobian: Mat2(rows),
            };
        }
        let (d, grad_d) = self.world.obstacle_distance.sample(p);
        let r = &self.repulsion;
        let reach = (d - c.radius) / r.range;
        if reach < r.negligible() {
            let s = r.strength * (-reach).exp();
            let (away, j_away) = self.world.obstacle_away.sample(p);
            force += away * s;
            // d/dp [s(d(p)) away(p)] = away (ds/dd grad d)^T + s J_away, ds/dd = -s / b.
            for (row, (a, ja)) in rows
                .iter_mut()
                .zip([(away.x, j_away[0]), (away.y, j_away[1])])
            {
                *row += grad_d * (-s / r.range * a) + ja * s;
            }
        }
        FieldForce {
            force,
            jacobian: Mat2(rows),
        }
    }

    /// The distance of a pair whose offset is `d`, when they are connected (closer than the
    /// cutoff, and not at the same spot, where the push has no direction).
    fn connected(&self, d: DVec2) -> Option<f64> {
        let n2 = d.length_squared();
        let cutoff = self.repulsion.cutoff;
        (n2 < cutoff * cutoff && n2 != 0.0).then(|| n2.sqrt())
    }

    /// Social repulsion (eq. 21) on the first of a pair whose offset is `d` = y_j - y_i.
    fn pair_force(&self, d: DVec2, radii: f64) -> Option<PairForce> {
        self.pair_force_at(d, self.connected(d)?, radii)
    }

    /// [`Model::pair_force`] of a connected pair `n` = |d| apart.
    fn pair_force_at(&self, d: DVec2, n: f64, radii: f64) -> Option<PairForce> {
        let r = &self.repulsion;
        let reach = (n - radii) / r.range;
        if reach >= r.negligible() {
            return None;
        }
        let e = d / n;
        let s = r.strength * (-reach).exp();
        // f = -s(n) e; df/dd = (s / b) e e^T - (s / n) (I - e e^T).
        let along = s / r.range;
        let across = match self.linearisation {
            Linearisation::Exact => s / n,
            Linearisation::Radial => 0.0,
        };
        let k = |a: f64, b: f64, delta: f64| (along + across) * a * b - across * delta;
        Some(PairForce {
            force: -e * s,
            k: Mat2([
                DVec2::new(k(e.x, e.x, 1.0), k(e.x, e.y, 0.0)),
                DVec2::new(k(e.y, e.x, 0.0), k(e.y, e.y, 1.0)),
            ]),
        })
    }

    fn radii(&self, i: usize, j: usize) -> f64 {
        self.characters[i].radius + self.characters[j].radius
    }

    /// f(X): dy/dt = u, du/dt = F(y, u) / m (eq. 16-18, 26), at half step `at`.
    pub fn rhs(&self, at: Instant, x: &[f64], pairs: &mut Pairs, out: &mut [f64]) {
        self.rhs_and_gap(at, x, pairs, out);
    }

    /// The force on character `i` from the fields, or from its plan: F_will + F_obstacle -
    /// fatigue, or [`Tracks`]' pull + F_obstacle - the plan's own repulsion. `None` when it is
    /// absent.
    fn own_force(&self, at: Instant, i: usize, p: DVec2, u: DVec2) -> Option<DVec2> {
        let c = &self.characters[i];
        let Some(tracks) = &self.tracks else {
            return Some(self.field_force(i, p).force - u * c.fatigue);
        };
        if !self.present(at, i) {
            return None;
        }
        let plan = tracks.plan(at.half, i);
        let w = tracks.rate;
        let pull = (plan.acc + (plan.vel - u) * (2.0 * w) + (plan.pos - p) * (w * w)) * c.mass;
        Some(
            pull + self.obstacle_force(i, p).force
                - tracks.planned_push[(at.step + at.half) * tracks.n + i],
        )
    }

    /// The Jacobian of [`Model::own_force`] by position and the coefficient of u (-k, or
    /// -2 m w for a tracked character).
    fn own_jacobian(&self, i: usize, p: DVec2) -> (Mat2, f64) {
        let c = &self.characters[i];
        match &self.tracks {
            None => (self.field_force(i, p).jacobian, -c.fatigue),
            Some(tracks) => {
                let w = tracks.rate;
                let mut j = self.obstacle_force(i, p).jacobian;
                j.0[0].x -= c.mass * w * w;
                j.0[1].y -= c.mass * w * w;
                (j, -2.0 * c.mass * w)
            }
        }
    }

    /// f(X), and the smallest gap d - (r_i + r_j) at X between two connected characters
    /// (infinite when none is): the integration reads the project's collision measure off the
    /// distances the forces need anyway, rather than searching pairs again (`clearance`).
    pub fn rhs_and_gap(&self, at: Instant, x: &[f64], pairs: &mut Pairs, out: &mut [f64]) -> f64 {
        pairs.near(x, self.search_radius());
        for i in 0..self.len() {
            let (p, u) = (position(x, i), velocity(x, i));
            let row = match self.own_force(at, i, p, u) {
                Some(f) => [u.x, u.y, f.x, f.y],
                None => [0.0; 4],
            };
            out[4 * i..4 * i + 4].copy_from_slice(&row);
        }
        let mut gap = f64::INFINITY;
        for &(i, j) in pairs.list() {
            if !self.both_present(at, i, j) {
                continue;
            }
            let d = position(x, j) - position(x, i);
            let radii = self.radii(i, j);
            if d == DVec2::ZERO {
                gap = gap.min(-radii);
            }
            let Some(n) = self.connected(d) else {
                continue;
            };
            gap = gap.min(n - radii);
            if let Some(pf) = self.pair_force_at(d, n, radii) {
                add(out, 4 * i + 2, pf.force);
                add(out, 4 * j + 2, -pf.force);
            }
        }
        self.divide_forces_by_mass(out);
        gap
    }

    /// The smallest gap at X between two connected characters (as [`Model::rhs_and_gap`]).
    pub fn smallest_gap(&self, at: Instant, x: &[f64], pairs: &mut Pairs) -> f64 {
        pairs.near(x, self.search_radius());
        pairs
            .list()
            .iter()
            .filter(|&&(i, j)| self.both_present(at, i, j))
            .map(|&(i, j)| {
                let d = position(x, j) - position(x, i);
                let n = if d == DVec2::ZERO {
                    Some(0.0)
                } else {
                    self.connected(d)
                };
                n.map_or(f64::INFINITY, |n| n - self.radii(i, j))
            })
            .fold(f64::INFINITY, f64::min)
    }

    fn divide_forces_by_mass(&self, out: &mut [f64]) {
        for (i, c) in self.characters.iter().enumerate() {
            out[4 * i + 2] /= c.mass;
            out[4 * i + 3] /= c.mass;
        }
    }

    /// The tangent-linear model: J(X) v, J = [[0, I], [F_y / m, F_u / m]] (eq. 11).
    pub fn jvp(&self, at: Instant, x: &[f64], v: &[f64], pairs: &mut Pairs, out: &mut [f64]) {
        pairs.near(x, self.search_radius());
        for i in 0..self.len() {
            if !self.present(at, i) {
                out[4 * i..4 * i + 4].fill(0.0);
                continue;
            }
            let (dp, du) = (position(v, i), velocity(v, i));
            let (jy, ju) = self.own_jacobian(i, position(x, i));
            let df = jy.mul(dp) + du * ju;
            out[4 * i..4 * i + 4].copy_from_slice(&[du.x, du.y, df.x, df.y]);
        }
        for &(i, j) in pairs.list() {
            if !self.both_present(at, i, j) {
                continue;
            }
            let d = position(x, j) - position(x, i);
            if let Some(pf) = self.pair_force(d, self.radii(i, j)) {
                let dd = pf.k.mul(position(v, j) - position(v, i));
                add(out, 4 * i + 2, dd);
                add(out, 4 * j + 2, -dd);
            }
        }
        self.divide_forces_by_mass(out);
    }

    /// The adjoint model: J(X)^T w (eq. 27-29; the pair part is the symmetric Laplacian L).
    pub fn vjp(&self, at: Instant, x: &[f64], w: &[f64], pairs: &mut Pairs, out: &mut [f64]) {
        pairs.near(x, self.search_radius());
        // a = w_u / m is what the forces' derivatives are transposed against.
        let a = |i: usize| velocity(w, i) / self.characters[i].mass;
        for i in 0..self.len() {
            if !self.present(at, i) {
                out[4 * i..4 * i + 4].fill(0.0);
                continue;
            }
            let ai = a(i);
            let (jy, ju) = self.own_jacobian(i, position(x, i));
            let dp = jy.mul_transpose(ai);
            let du = position(w, i) + ai * ju;
            out[4 * i..4 * i + 4].copy_from_slice(&[dp.x, dp.y, du.x, du.y]);
        }
        for &(i, j) in pairs.list() {
            if !self.both_present(at, i, j) {
                continue;
            }
            let d = position(x, j) - position(x, i);
            if let Some(pf) = self.pair_force(d, self.radii(i, j)) {
                let dd = pf.k.mul_transpose(a(i) - a(j));
                add(out, 4 * j, dd);
                add(out, 4 * i, -dd);
            }
        }
    }

    /// The smallest gap d - (r_i + r_j) between any two characters at any state of
    /// `states` (one state after another), and how many (pair, state) couples overlap (gap
    /// below zero): the project's definition of a collision.
    pub fn clearance(&self, states: &[f64]) -> (f64, usize) {
        let mut pairs = Pairs::default();
        let (mut smallest, mut overlaps) = (f64::INFINITY, 0);
        for (k, x) in states.chunks_exact(self.state_len()).enumerate() {
            if !x.iter().all(|v| v.is_finite()) {
                return (f64::NEG_INFINITY, overlaps + 1);
            }
            pairs.find(x, 1.0);
            for &(i, j) in pairs.list() {
                if !self.both_present(Instant::state(k), i, j) {
                    continue;
                }
                let gap = (position(x, i) - position(x, j)).length() - self.radii(i, j);
                smallest = smallest.min(gap);
                if gap < 0.0 {
                    overlaps += 1;
                }
            }
        }
        (smallest, overlaps)
    }
}
