//! "Perfect" rendez-vous (Allain section 6.1, Figure 3): 38 people walk together; two of them,
//! from the front of the group, are asked to meet at a point behind it at t = 20 s (positions
//! observed, eq. 31, R = 10 m^2 for the two and no constraint on the others, eq. 32; Q_u =
//! 100 m^2/s^4; local descent, on the radial linearisation (`model::Linearisation`): with the
//! exact one the pressed group's linearised dynamics grow without bound and the local descent
//! stalls 8.6 m short).

use super::scenes::{block, check_place, drawn, paper_problem, positions_at, rng};
use super::{Mark, Overrides, Setup};
use crate::cost::Constraint;
use crate::descent::{Descent, Outcome};
use crate::error::EditError;
use crate::integrate::Timeline;
use crate::observe::Positions;
use crate::world::{Rect, World};
use glam::DVec2;
use std::collections::BTreeMap;

const PEOPLE: usize = 38;
const MEET_TIME: f64 = 20.0;

pub fn setup(o: &Overrides) -> Result<Setup, EditError> {
    let mut rng = rng(1);
    let bounds = Rect::new(DVec2::new(0.0, 0.0), DVec2::new(50.0, 20.0));
    let goal = Rect::new(DVec2::new(49.5, 0.0), DVec2::new(50.0, 20.0));
    let world = World::new(bounds, vec![], vec![goal]);
    let places = block(&mut rng, DVec2::new(6.0, 10.0), PEOPLE, 6, 0.95, 0.08);
    let characters = (0..PEOPLE).map(|_| drawn(&mut rng, 0)).collect();
    // The two nearest the middle of the front row (largest x) must get through to the back.
    let mut front: Vec<usize> = (0..PEOPLE).collect();
    front.sort_by(|&a, &b| places[b].x.total_cmp(&places[a].x).then(a.cmp(&b)));
    let mut two: Vec<usize> = front[..6].to_vec();
    two.sort_by(|&a, &b| {
        let d = |i: usize| (places[i].y - 10.0).abs();
        d(a).total_cmp(&d(b)).then(a.cmp(&b))
    });
    let who = vec![two[0], two[1]];
    let timeline = Timeline {
        dt: 0.1,
        steps: 300,
    };
    let meet = o.meet.unwrap_or(DVec2::new(19.0, 10.0));
    let time = o.meet_time.unwrap_or(MEET_TIME);
    check_place(&world, "meet", meet)?;
    let target = vec![meet.x, meet.y, meet.x, meet.y];
    let operator = Box::new(Positions { who: who.clone() });
    let r = o.r.unwrap_or(10.0);
    let constraint = Constraint::over_window("meet", operator, timeline, (time, time), r, |_| {
        target.clone()
    })?;
    let problem = paper_problem(
        characters,
        world,
        timeline,
        &places,
        100.0,
        vec![constraint],
    );
    let others = (0..PEOPLE).filter(|i| !who.contains(i)).collect();
    Ok(Setup {
        name: "rendez-vous",
        problem,
        descent: Descent::Local,
        iterations: 60,
        groups: vec![("group".into(), others), ("the two".into(), who)],
        marks: vec![Mark::Point { at: meet, time }],
        per_iteration: vec![],
    })
}

/// Each of the two's distance to the meeting point at the meeting time, and the distance
/// between them, before and after.
pub fn figures(setup: &Setup, outcome: &Outcome, extra: &mut BTreeMap<String, f64>) {
    let p = &setup.problem;
    let Some(Mark::Point { at, time }) = setup.marks.first() else {
        return;
    };
    let k = p.timeline.step_at(*time);
    let two = &setup.groups[1].1;
    for (label, states) in [
        ("before", &outcome.before.states),
        ("after", &outcome.states),
    ] {
        let pos = positions_at(p, states, k);
        for (n, &i) in two.iter().enumerate() {
            extra.insert(
                format!(
                    "distance of walker {} to the meeting point {label}, m",
                    n + 1
                ),
                (pos[i] - *at).length(),
            );
        }
        extra.insert(
            format!("distance between the two {label}, m"),
            (pos[two[0]] - pos[two[1]]).length(),
        );
    }
}
