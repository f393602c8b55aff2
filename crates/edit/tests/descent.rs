//! The descents do what the paper says they do, on small random crowds: a constraint on two
//! walkers' positions pulls them to the point asked (section 6.1), the cost never rises along
//! a descent, and the edit pushes no one into anyone deeper than the unedited crowd.

use crowd_edit::experiments::paper_problem;
use crowd_edit::integrate::Timeline;
use crowd_edit::model::{Character, position};
use crowd_edit::observe::Positions;
use crowd_edit::{Constraint, Descent, Problem, Rect, World, solve};
use glam::DVec2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A loose group of 12 walking east in an open 30 x 12 m world; two of them are asked to be
/// 3 m behind where the group's centre would be at 8 s.
fn meeting(seed: u64) -> (Problem, DVec2, [usize; 2]) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let bounds = Rect::new(DVec2::ZERO, DVec2::new(30.0, 12.0));
    let goal = Rect::new(DVec2::new(29.5, 0.0), DVec2::new(30.0, 12.0));
    let world = World::new(bounds, vec![], vec![goal]);
    let mut places = Vec::new();
    let mut characters = Vec::new();
    for k in 0..12 {
        let p = DVec2::new(3.0 + (k % 4) as f64 * 1.1, 4.5 + (k / 4) as f64 * 1.1)
            + DVec2::new(rng.random_range(-0.15..0.15), rng.random_range(-0.15..0.15));
        places.push(p);
        characters.push(Character::standard(rng.random_range(0.25..0.35), 0));
    }
    let timeline = Timeline {
        dt: 0.1,
        steps: 100,
    };
    let target = DVec2::new(3.0 + 7.5 - 3.0, 6.0 + rng.random_range(-1.0..1.0));
    let who = [3, 7]; // front-row walkers
    let flat = vec![target.x, target.y, target.x, target.y];
    let constraint = Constraint::over_window(
        "meet",
        Box::new(Positions { who: who.to_vec() }),
        timeline,
        (8.0, 8.0),
        10.0,
        |_| flat.clone(),
    )
    .unwrap();
    let problem = paper_problem(
        characters,
        world,
        timeline,
        &places,
        100.0,
        vec![constraint],
    );
    (problem, target, who)
}

fn distances(problem: &Problem, states: &[f64], target: DVec2, who: [usize; 2]) -> [f64; 2] {
    let n = problem.n();
    let k = problem.timeline.step_at(8.0);
    let x = &states[k * n..(k + 1) * n];
    who.map(|i| (position(x, i) - target).length())
}

#[test]
fn a_meeting_constraint_pulls_the_two_walkers_to_the_point_without_pushing_into_anyone() {
    for seed in 0..3 {
        for descent in [Descent::Local, Descent::Global, Descent::QuasiNewton] {
            let (problem, target, who) = meeting(seed);
            let mut objective = Vec::new();
            let outcome = solve(&problem, descent, 25, |it, _| {
                objective.push(it.cost.objective(problem.objective))
            });
            let before = distances(&problem, &outcome.before.states, target, who);
            let after = distances(&problem, &outcome.states, target, who);
            for (b, a) in before.iter().zip(&after) {
                assert!(
                    *a < 0.35 * b && *a < 1.0,
                    "seed {seed}, {descent:?}: {before:?} m -> {after:?} m"
                );
            }
            assert!(
                objective.windows(2).all(|w| w[1] <= w[0]),
                "seed {seed}, {descent:?}: the cost rose: {objective:?}"
            );
            let (gap_before, _) = problem.model.clearance(&outcome.before.states);
            let (gap_after, _) = problem.model.clearance(&outcome.states);
            assert!(
                gap_after >= gap_before.min(0.0) - 0.02,
                "seed {seed}, {descent:?}: closest gap {gap_before} -> {gap_after} m"
            );
        }
    }
}
