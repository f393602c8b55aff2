//! The density experiment (Allain section 6.2, Figure 10): 64 heterogeneous people (radius in
//! [0.25, 0.35] m, mass proportional to it with 70 kg at 0.3 m, will and fatigue 140 +- 10 %)
//! stand still, then head right; three 8 m x 8 m areas away from their path ask for
//! 1.1 people/m^2 for one second around t = 7, 14.5 and 22 s (slightly more than 64 people can
//! give: the paper over-constrains on purpose). Q_u = 0.1 m^2/s^4, R = 10 people^2/m^4, global
//! descent, 200 iterations.

use super::scenes::{block, check_place, paper_problem, rng};
use super::{Mark, Overrides, Setup};
use crate::cost::Constraint;
use crate::descent::Descent;
use crate::error::EditError;
use crate::integrate::Timeline;
use crate::model::Character;
use crate::observe::{Counted, Density, EulerGrid};
use crate::world::{Rect, World};
use glam::DVec2;
use rand::Rng;

const PEOPLE: usize = 64;
const TARGET: f64 = 1.1;

/// The areas' centres and times.
const AREAS: [(f64, f64, f64); 3] = [(12.0, 7.0, 7.0), (20.0, 11.0, 14.5), (28.0, 7.0, 22.0)];

pub fn setup(o: &Overrides) -> Result<Setup, EditError> {
    let mut rng = rng(3);
    let bounds = Rect::new(DVec2::new(0.0, -8.0), DVec2::new(40.0, 22.0));
    let goal = Rect::new(DVec2::new(39.5, -8.0), DVec2::new(40.0, 22.0));
    let world = World::new(bounds, vec![], vec![goal]);
    let places = block(&mut rng, DVec2::new(6.0, 0.0), PEOPLE, 8, 1.0, 0.1);
    let characters = (0..PEOPLE)
        .map(|_| {
            let radius = rng.random_range(0.25..0.35);
            Character {
                mass: 70.0 * radius / 0.3,
                radius,
                will: 140.0 * rng.random_range(0.9..1.1),
                fatigue: 140.0 * rng.random_range(0.9..1.1),
                goal: 0,
            }
        })
        .collect();
    let timeline = Timeline {
        dt: 0.1,
        steps: 250,
    };
    let grid = EulerGrid {
        origin: bounds.min,
        cell: 1.0,
        nx: 40,
        ny: 30,
        sigma: 1.5,
    };
    let r = o.r.unwrap_or(10.0);
    let mut constraints = Vec::new();
    let mut marks = Vec::new();
    for (k, &(x, y, t)) in AREAS.iter().enumerate() {
        let name = format!("area {} at {t} s", k + 1);
        let rect = Rect::centred(DVec2::new(x, y), 8.0, 8.0);
        for corner in [rect.min, rect.max] {
            check_place(&world, &name, corner)?;
        }
        let cells = grid.cells_in(rect.min, rect.max);
        let target = vec![TARGET; cells.len()];
        let operator = Box::new(Density {
            grid,
            cells,
            counted: Counted::All,
        });
        let window = (t - 0.5, t + 0.5);
        constraints.push(Constraint::over_window(
            &name,
            operator,
            timeline,
            window,
            r,
            |_| target.clone(),
        )?);
        marks.push(Mark::Area {
            rect,
            from: window.0,
            to: window.1,
        });
    }
    let problem = paper_problem(characters, world, timeline, &places, 0.1, constraints);
    Ok(Setup {
        name: "density",
        problem,
        descent: Descent::Global,
        iterations: 200,
        groups: vec![("crowd".into(), (0..PEOPLE).collect())],
        marks,
        per_iteration: vec![],
    })
}
