//! Letter constraints (Allain section 6.1, Figure 4): two groups walk towards each other, cross,
//! and are asked to stand as the letters "S" and "G" once past each other (positions observed
//! as in eq. 31-32, R = 10 m^2, Q_u = 100 m^2/s^4, global descent, at most 200 iterations; the
//! RMS per group per iteration is Figure 4c). The global descent runs along L-BFGS directions:
//! it reaches the lowest RMS of the descents tried, before the crossing tangles and no
//! direction leads down (BENCHMARKS.md).
//!
//! Who stands where on a letter: the paper does not say. Each letter point goes to the group
//! member nearest to it in the unedited run (greedily, the closest remaining couple first), so
//! the edit moves people as little as the letter allows.

use super::scenes::{block, check_place, drawn, paper_problem, positions_at, rng};
use super::{Mark, Overrides, Setup};
use crate::cost::Constraint;
use crate::descent::Descent;
use crate::error::EditError;
use crate::integrate::Timeline;
use crate::observe::Positions;
use crate::world::{Rect, World};
use glam::DVec2;

const PER_GROUP: usize = 30;
const LETTER_TIME: f64 = 26.0;

/// The letters as polylines in a 5 m x 8 m box centred on the origin.
fn letter(shape: char) -> Vec<DVec2> {
    let p = |x: f64, y: f64| DVec2::new(x, y);
    match shape {
        'S' => vec![
            p(2.5, 4.0),
            p(-2.5, 4.0),
            p(-2.5, 0.0),
            p(2.5, 0.0),
            p(2.5, -4.0),
            p(-2.5, -4.0),
        ],
        _ => vec![
            p(2.5, 4.0),
            p(-2.5, 4.0),
            p(-2.5, -4.0),
            p(2.5, -4.0),
            p(2.5, 0.0),
            p(0.0, 0.0),
        ],
    }
}

/// `count` points evenly spaced along a polyline, ends included.
fn along(polyline: &[DVec2], count: usize) -> Vec<DVec2> {
    let lengths: Vec<f64> = polyline
        .windows(2)
        .map(|w| (w[1] - w[0]).length())
        .collect();
    let total: f64 = lengths.iter().sum();
    (0..count)
        .map(|k| {
            let mut s = total * k as f64 / (count - 1) as f64;
            for (k, (w, l)) in polyline.windows(2).zip(&lengths).enumerate() {
                if s <= *l || k + 1 == lengths.len() {
                    return w[0] + (w[1] - w[0]) * (s / l).min(1.0);
                }
                s -= l;
            }
            *polyline.last().unwrap()
        })
        .collect()
}

/// Greedy assignment: the closest remaining (member, point) couple first.
fn assign(members: &[usize], at: &[DVec2], points: &[DVec2]) -> Vec<DVec2> {
    let mut couples: Vec<(f64, usize, usize)> = members
        .iter()
        .enumerate()
        .flat_map(|(m, &i)| {
            points
                .iter()
                .enumerate()
                .map(move |(p, q)| ((at[i] - *q).length(), m, p))
        })
        .collect();
    couples.sort_by(|a, b| a.0.total_cmp(&b.0).then((a.1, a.2).cmp(&(b.1, b.2))));
    let mut target = vec![None; members.len()];
    let mut taken = vec![false; points.len()];
    for (_, m, p) in couples {
        if target[m].is_none() && !taken[p] {
            target[m] = Some(points[p]);
            taken[p] = true;
        }
    }
    target
        .into_iter()
        .map(|t| t.expect("as many points as members"))
        .collect()
}

pub fn setup(o: &Overrides) -> Result<Setup, EditError> {
    let mut rng = rng(2);
    let bounds = Rect::new(DVec2::new(0.0, 0.0), DVec2::new(44.0, 20.0));
    let east = Rect::new(DVec2::new(43.5, 0.0), DVec2::new(44.0, 20.0));
    let west = Rect::new(DVec2::new(0.0, 0.0), DVec2::new(0.5, 20.0));
    let world = World::new(bounds, vec![], vec![east, west]);
    let mut places = block(&mut rng, DVec2::new(6.0, 10.0), PER_GROUP, 5, 0.95, 0.08);
    places.extend(block(
        &mut rng,
        DVec2::new(38.0, 10.0),
        PER_GROUP,
        5,
        0.95,
        0.08,
    ));
    let characters = (0..2 * PER_GROUP)
        .map(|i| drawn(&mut rng, i / PER_GROUP))
        .collect();
    let timeline = Timeline {
        dt: 0.1,
        steps: 280,
    };
    let mut problem = paper_problem(characters, world, timeline, &places, 100.0, vec![]);
    // Where each group would be, unedited, when the letters are asked for.
    let free = problem.run(
        &vec![0.0; problem.n()],
        &vec![0.0; timeline.steps * problem.n()],
    );
    let k = timeline.step_at(LETTER_TIME);
    let at = positions_at(&problem, &free.states, k);
    let r = o.r.unwrap_or(10.0);
    let mut marks = Vec::new();
    let mut groups = Vec::new();
    for (g, (name, shape, centre)) in [
        ("eastbound forms G", 'G', DVec2::new(31.5, 10.0)),
        ("westbound forms S", 'S', DVec2::new(12.5, 10.0)),
    ]
    .into_iter()
    .enumerate()
    {
        let members: Vec<usize> = (g * PER_GROUP..(g + 1) * PER_GROUP).collect();
        let points: Vec<DVec2> = along(&letter(shape), PER_GROUP)
            .into_iter()
            .map(|p| p + centre)
            .collect();
        for &p in &points {
            check_place(&problem.model.world, name, p)?;
        }
        let targets = assign(&members, &at, &points);
        let flat: Vec<f64> = targets.iter().flat_map(|p| [p.x, p.y]).collect();
        let operator = Box::new(Positions {
            who: members.clone(),
        });
        problem.constraints.push(Constraint::over_window(
            name,
            operator,
            timeline,
            (LETTER_TIME, LETTER_TIME),
            r,
            |_| flat.clone(),
        )?);
        marks.push(Mark::Targets {
            points,
            time: LETTER_TIME,
        });
        groups.push((name.to_string(), members));
    }
    Ok(Setup {
        name: "letters",
        problem,
        descent: Descent::QuasiNewton,
        iterations: 200,
        groups,
        marks,
        per_iteration: vec![],
    })
}
