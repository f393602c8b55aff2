//! Flow regulation with vorticity control (Allain section 6.2, Figures 6-9): four groups of 38
//! cross a cross-shaped corridor to the opposite exits and jam in the crossing; a homogeneous
//! positive vorticity is asked for in the crossing between 12 and 17 s, on a 32 x 32 grid over
//! the scene (R = 0.2 s^-2, Q_u = 100 m^2/s^4, global descent; the paper shows 25 iterations).
//! Figure 9's measure, the mean arrival time per group, is computed at every iteration.

use super::scenes::{block, drawn, paper_problem, positions_at, rng};
use super::{Mark, Overrides, PerIteration, Setup};
use crate::cost::{Constraint, Problem};
use crate::descent::Descent;
use crate::error::EditError;
use crate::integrate::Timeline;
use crate::observe::{Counted, EulerGrid, Vorticity};
use crate::world::{Rect, World};
use glam::DVec2;

const PER_GROUP: usize = 38;
const SIZE: f64 = 48.0;
/// The corridors are 10 m wide, centred on the scene.
const LOW: f64 = 19.0;
const HIGH: f64 = 29.0;
/// The vorticity asked for, 1/s: a whirl turning at 0.25 rad/s.
const TARGET: f64 = 0.5;
/// Where a group has arrived: this far along its way out.
const ARRIVED: f64 = 42.0;

/// Per group: where it starts, which way it goes (unit axis).
const GROUPS: [(&str, [f64; 2], [f64; 2]); 4] = [
    ("eastbound", [6.0, 24.0], [1.0, 0.0]),
    ("westbound", [42.0, 24.0], [-1.0, 0.0]),
    ("northbound", [24.0, 6.0], [0.0, 1.0]),
    ("southbound", [24.0, 42.0], [0.0, -1.0]),
];

pub fn setup(o: &Overrides) -> Result<Setup, EditError> {
    let mut rng = rng(4);
    let v = DVec2::new;
    let bounds = Rect::new(v(0.0, 0.0), v(SIZE, SIZE));
    let obstacles = vec![
        Rect::new(v(0.0, 0.0), v(LOW, LOW)),
        Rect::new(v(HIGH, 0.0), v(SIZE, LOW)),
        Rect::new(v(0.0, HIGH), v(LOW, SIZE)),
        Rect::new(v(HIGH, HIGH), v(SIZE, SIZE)),
    ];
    let goals = vec![
        Rect::new(v(SIZE - 1.0, LOW), v(SIZE, HIGH)),
        Rect::new(v(0.0, LOW), v(1.0, HIGH)),
        Rect::new(v(LOW, SIZE - 1.0), v(HIGH, SIZE)),
        Rect::new(v(LOW, 0.0), v(HIGH, 1.0)),
    ];
    let world = World::new(bounds, obstacles, goals);
    let mut places = Vec::new();
    let mut characters = Vec::new();
    let mut groups = Vec::new();
    for (g, (name, start, _)) in GROUPS.iter().enumerate() {
        let first = places.len();
        places.extend(block(
            &mut rng,
            DVec2::from(*start),
            PER_GROUP,
            6,
            0.95,
            0.08,
        ));
        characters.extend((0..PER_GROUP).map(|_| drawn(&mut rng, g)));
        groups.push((name.to_string(), (first..places.len()).collect::<Vec<_>>()));
    }
    let timeline = Timeline {
        dt: 0.1,
        steps: 450,
    };
    let grid = EulerGrid {
        origin: bounds.min,
        cell: SIZE / 32.0,
        nx: 32,
        ny: 32,
        sigma: 1.0,
    };
    let crossing = Rect::new(v(LOW, LOW), v(HIGH, HIGH));
    let cells = grid.cells_in(crossing.min, crossing.max);
    let target = vec![TARGET; cells.len()];
    let r = o.r.unwrap_or(0.2);
    let window = (12.0, 17.0);
    let operator = Box::new(Vorticity {
        grid,
        cells,
        counted: Counted::All,
    });
    let constraint = Constraint::over_window(
        "whirl in the crossing",
        operator,
        timeline,
        window,
        r,
        |_| target.clone(),
    )?;
    let problem = paper_problem(
        characters,
        world,
        timeline,
        &places,
        100.0,
        vec![constraint],
    );
    let per_iteration = groups
        .iter()
        .enumerate()
        .map(|(g, (name, members))| {
            let members = members.clone();
            let axis = DVec2::from(GROUPS[g].2);
            let f: PerIteration = Box::new(move |p: &Problem, states: &[f64]| {
                mean_arrival(p, states, &members, axis)
            });
            (format!("mean arrival {name}, s"), f)
        })
        .collect();
    Ok(Setup {
        name: "vorticity",
        problem,
        descent: Descent::Global,
        iterations: 25,
        groups,
        marks: vec![Mark::Area {
            rect: crossing,
            from: window.0,
            to: window.1,
        }],
        per_iteration,
    })
}

/// The mean time at which `members` get `ARRIVED` metres along `axis` from the scene's near
/// edge (those who never do count the whole simulation).
fn mean_arrival(problem: &Problem, states: &[f64], members: &[usize], axis: DVec2) -> f64 {
    let t = &problem.timeline;
    let along = |p: DVec2| {
        let d = p.dot(axis);
        if d < 0.0 { d + SIZE } else { d }
    };
    let mut arrival = vec![t.duration(); members.len()];
    for k in 0..=t.steps {
        let pos = positions_at(problem, states, k);
        for (a, &i) in arrival.iter_mut().zip(members) {
            if *a == t.duration() && along(pos[i]) >= ARRIVED {
                *a = k as f64 * t.dt;
            }
        }
    }
    arrival.iter().sum::<f64>() / members.len() as f64
}
