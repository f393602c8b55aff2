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
        let mut force = w * c.will;
        let mut rows = [jw[0] * c.will, jw[1] * c.will];
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

    /// f(X): dy/dt = u, du/dt = F(y, u) / m (eq. 16-18, 26).
    pub fn rhs(&self, x: &[f64], pairs: &mut Pairs, out: &mut [f64]) {
        self.rhs_and_gap(x, pairs, out);
    }

    /// f(X), and the smallest gap d - (r_i + r_j) at X between two connected characters
    /// (infinite when none is): the integration reads the project's collision measure off the
    /// distances the forces need anyway, rather than searching pairs again (`clearance`).
    pub fn rhs_and_gap(&self, x: &[f64], pairs: &mut Pairs, out: &mut [f64]) -> f64 {
        pairs.near(x, self.search_radius());
        for (i, c) in self.characters.iter().enumerate() {
            let (p, u) = (position(x, i), velocity(x, i));
            let f = self.field_force(i, p).force - u * c.fatigue;
            out[4 * i..4 * i + 2].copy_from_slice(&[u.x, u.y]);
            out[4 * i + 2..4 * i + 4].copy_from_slice(&[f.x, f.y]);
        }
        let mut gap = f64::INFINITY;
        for &(i, j) in pairs.list() {
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
    pub fn smallest_gap(&self, x: &[f64], pairs: &mut Pairs) -> f64 {
        pairs.near(x, self.search_radius());
        pairs
            .list()
            .iter()
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
    pub fn jvp(&self, x: &[f64], v: &[f64], pairs: &mut Pairs, out: &mut [f64]) {
        pairs.near(x, self.search_radius());
        for (i, c) in self.characters.iter().enumerate() {
            let (dp, du) = (position(v, i), velocity(v, i));
            let df = self.field_force(i, position(x, i)).jacobian.mul(dp) - du * c.fatigue;
            out[4 * i..4 * i + 2].copy_from_slice(&[du.x, du.y]);
            out[4 * i + 2..4 * i + 4].copy_from_slice(&[df.x, df.y]);
        }
        for &(i, j) in pairs.list() {
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
    pub fn vjp(&self, x: &[f64], w: &[f64], pairs: &mut Pairs, out: &mut [f64]) {
        pairs.near(x, self.search_radius());
        // a = w_u / m is what the forces' derivatives are transposed against.
        let a = |i: usize| velocity(w, i) / self.characters[i].mass;
        for (i, c) in self.characters.iter().enumerate() {
            let ai = a(i);
            let dp = self
                .field_force(i, position(x, i))
                .jacobian
                .mul_transpose(ai);
            let du = position(w, i) - ai * c.fatigue;
            out[4 * i..4 * i + 4].copy_from_slice(&[dp.x, dp.y, du.x, du.y]);
        }
        for &(i, j) in pairs.list() {
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
        for x in states.chunks_exact(self.state_len()) {
            if !x.iter().all(|v| v.is_finite()) {
                return (f64::NEG_INFINITY, overlaps + 1);
            }
            pairs.find(x, 1.0);
            for &(i, j) in pairs.list() {
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
