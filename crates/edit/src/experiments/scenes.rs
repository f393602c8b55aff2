//! What the experiments' scenes share: groups standing in blocks, the paper's characters
//! (radii drawn in [0.25, 0.35] m), the check that a constraint lies in the walkable world, and
//! the project's collision measure.

use crate::Timeline;
use crate::cost::{Constraint, Covariances, Objective, Problem};
use crate::error::EditError;
use crate::model::{Character, position};
use crate::model::{Linearisation, Model, Repulsion};
use crate::world::World;
use glam::DVec2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The experiments' random draws, the same on every run.
pub fn rng(experiment: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(0xA11A_1200 + experiment)
}

/// `count` places on a grid of `columns` around `centre`, `spacing` apart, each moved by up to
/// `jitter` so that the group is not a lattice; the grid's corners are dropped first when it
/// holds more places than `count`.
pub fn block(
    rng: &mut ChaCha8Rng,
    centre: DVec2,
    count: usize,
    columns: usize,
    spacing: f64,
    jitter: f64,
) -> Vec<DVec2> {
    let rows = count.div_ceil(columns);
    let mut places: Vec<(usize, usize)> = (0..rows)
        .flat_map(|r| (0..columns).map(move |c| (c, r)))
        .collect();
    let (cc, cr) = ((columns - 1) as f64 / 2.0, (rows - 1) as f64 / 2.0);
    // Drop the places farthest from the centre (the corners) until `count` remain.
    places.sort_by(|a, b| {
        let d = |(c, r): (usize, usize)| (c as f64 - cc).powi(2) + (r as f64 - cr).powi(2);
        d(*a).total_cmp(&d(*b)).then(a.cmp(b))
    });
    places.truncate(count);
    places.sort_by_key(|&(c, r)| (r, c));
    places
        .into_iter()
        .map(|(c, r)| {
            let offset = DVec2::new(c as f64 - cc, r as f64 - cr) * spacing;
            let wobble = DVec2::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            centre + offset + wobble * jitter
        })
        .collect()
}

/// The paper's character with a radius drawn in [0.25, 0.35] m.
pub fn drawn(rng: &mut ChaCha8Rng, goal: usize) -> Character {
    Character::standard(rng.random_range(0.25..0.35), goal)
}

/// A state with everyone standing at `places`.
pub fn at_rest(places: &[DVec2]) -> Vec<f64> {
    places.iter().flat_map(|p| [p.x, p.y, 0.0, 0.0]).collect()
}

/// The editing problem as the paper's section 6 poses it: everyone standing at `places` at
/// t = 0, the paper's repulsion, the model error on velocities only (Q_y = 0, Q_u =
/// `q_velocity`, B = 0), the paper's updates (`Objective::Constraints`), and the radial
/// linearisation that keeps crossings tractable (`model::Linearisation`).
pub fn paper_problem(
    characters: Vec<Character>,
    world: World,
    timeline: Timeline,
    places: &[DVec2],
    q_velocity: f64,
    constraints: Vec<Constraint>,
) -> Problem {
    Problem {
        model: Model {
            characters,
            world,
            repulsion: Repulsion::default(),
            linearisation: Linearisation::Radial,
            tracks: None,
        },
        timeline,
        initial: at_rest(places),
        covariances: Covariances::velocity_only(q_velocity),
        objective: Objective::Constraints,
        constraints,
        keep_apart: true,
    }
}

/// Refuses a constraint place outside the walkable world.
pub fn check_place(world: &World, constraint: &str, p: DVec2) -> Result<(), EditError> {
    if world.is_free(p) {
        return Ok(());
    }
    Err(EditError::PlaceOutside {
        constraint: constraint.to_string(),
        x: p.x,
        y: p.y,
        min_x: world.bounds.min.x,
        min_y: world.bounds.min.y,
        max_x: world.bounds.max.x,
        max_y: world.bounds.max.y,
    })
}

/// Everyone's position at step `k` of a trajectory.
pub fn positions_at(problem: &Problem, states: &[f64], k: usize) -> Vec<DVec2> {
    let n = problem.n();
    let x = &states[k * n..(k + 1) * n];
    (0..problem.model.len()).map(|i| position(x, i)).collect()
}

/// The smallest gap between two characters' discs at any step and the overlaps
/// ([`Model::clearance`](crate::model::Model::clearance)).
pub fn clearance(problem: &Problem, states: &[f64]) -> (f64, usize) {
    problem.model.clearance(states)
}
