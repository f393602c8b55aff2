//! What each edit asks of one patch: its place in patch-local metres and its window on the
//! patch problem's clock, turned into the paper's constraints (positions for a meeting, the
//! Eulerian density, velocity or vorticity on a grid over the part of its rectangle inside the
//! patch), and the residual that says how near the edit came.

use crate::gather::{Square, gather};
use crate::plan::{Copy, DT};
use crowd_core::config::{Edit, EditKind};
use crowd_core::flow_map::VelocityMap;
use crowd_edit::cost::Sample;
use crowd_edit::observe::{
    Counted, Density, EulerGrid, Observe, Positions, Velocity, Vorticity, Within,
};
use crowd_edit::{Constraint, Rect};
use glam::DVec2;
use std::sync::Arc;

/// R of a density edit's gathering ([`crate::gather`]), m^2: a walker 1 m outside its
/// rectangle through a 2 s window costs 2 / R.
pub const GATHER_R: f64 = 0.01;

/// How long before a meeting its walkers must already be free to move, s.
pub const MEET_NOTICE_S: f64 = 3.0;

/// The Eulerian grids' cells, m, and their kernel's standard deviation, m.
pub const CELL_M: f64 = 1.0;
pub const SIGMA_M: f64 = 1.0;

/// An edit as one patch takes it.
#[derive(Clone, Debug)]
pub struct Local {
    /// Its index in the pipeline's `edits`.
    pub edit: usize,
    pub kind: LocalKind,
    /// On the problem's clock, s.
    pub window: (f64, f64),
    pub r: f64,
}

#[derive(Clone, Debug)]
pub enum LocalKind {
    Meet {
        at: DVec2,
        people: usize,
        radius: Option<f64>,
    },
    Density {
        rect: Rect,
        target: f64,
    },
    Flow {
        rect: Rect,
        goal: FlowGoal,
    },
    Vorticity {
        rect: Rect,
        per_s: f64,
    },
}

/// The velocity a flow edit asks for: one vector, or a painted map's at each cell.
#[derive(Clone, Debug)]
pub enum FlowGoal {
    Uniform(DVec2),
    /// The map, and the world position of the patch's south-west corner.
    Map {
        map: Arc<VelocityMap>,
        origin: DVec2,
    },
}

impl FlowGoal {
    /// The velocity asked of the patch-local square `[min, max)`, if any: a map's cells whose
    /// pixels are mostly unpainted (mean alpha under a half) ask nothing.
    fn over(&self, min: DVec2, max: DVec2) -> Option<DVec2> {
        match self {
            FlowGoal::Uniform(v) => Some(*v),
            FlowGoal::Map { map, origin } => map
                .mean_over(*origin + min, *origin + max)
                .filter(|&(_, weight)| weight >= 0.5)
                .map(|(v, _)| v),
        }
    }
}

/// `edit` as the patch whose south-west corner is `origin` (side `side`) takes it, its window
/// starting at `from` on the problem's clock; `None` when it does not reach the patch (a
/// meeting belongs to the patch its point is in).
pub fn localise(
    edit: &Edit,
    index: usize,
    origin: DVec2,
    side: f64,
    from: f64,
    map: Option<&Arc<VelocityMap>>,
) -> Option<Local> {
    let (x0, y0, x1, y1) = edit.kind.rect();
    let (w0, w1) = edit.kind.window();
    let window = (from, from + (w1 - w0));
    let r = edit.r.unwrap_or_else(|| edit.kind.default_r());
    let local = |x: f64, y: f64| DVec2::new(x, y) - origin;
    let kind = match edit.kind {
        EditKind::Meet {
            at,
            people,
            radius_m,
            ..
        } => {
            let p = local(at.0, at.1);
            let inside = p.cmpge(DVec2::ZERO).all() && p.cmplt(DVec2::splat(side)).all();
            if !inside {
                return None;
            }
            LocalKind::Meet {
                at: p,
                people: people as usize,
                radius: radius_m,
            }
        }
        _ => {
            let min = local(x0, y0).max(DVec2::ZERO);
            let max = local(x1, y1).min(DVec2::splat(side));
            if !(max.cmpgt(min).all()) {
                return None;
            }
            let rect = Rect::new(min, max);
            match edit.kind {
                EditKind::Density { people_per_m2, .. } => LocalKind::Density {
                    rect,
                    target: people_per_m2,
                },
                EditKind::Flow { velocity_m_s, .. } => LocalKind::Flow {
                    rect,
                    goal: FlowGoal::Uniform(DVec2::new(velocity_m_s.0, velocity_m_s.1)),
                },
                EditKind::FlowMap { .. } => LocalKind::Flow {
                    rect,
                    goal: FlowGoal::Map {
                        map: Arc::clone(
                            map.expect("the caller decodes every FlowMap edit's map (Inputs)"),
                        ),
                        origin,
                    },
                },
                EditKind::Vorticity { per_s, .. } => LocalKind::Vorticity { rect, per_s },
                EditKind::Meet { .. } => unreachable!("handled above"),
            }
        }
    };
    Some(Local {
        edit: index,
        kind,
        window,
        r,
    })
}

/// How an edit's residual is read off a trajectory (states at every step).
#[derive(Clone, Debug)]
pub enum Measure {
    /// The largest distance of a meeting walker from its place round the point, m.
    Meet {
        step: usize,
        who: Vec<usize>,
        places: Vec<DVec2>,
    },
    /// The root mean square of H(X) - Y over the window (the constraints' indices).
    Rms { indices: Vec<usize> },
    /// A density edit's root mean square, and the people counted in its rectangle: at each
    /// step of the window, those present (`counted`); what the patch could show
    /// ([`crate::gather::Gathering::people`]).
    Density {
        indices: Vec<usize>,
        rect: Rect,
        counted: Vec<(usize, Vec<usize>)>,
        reachable: f64,
    },
}

/// The grid over `rect` with `margin` cells more on every side.
fn grid_over(rect: Rect, margin: usize) -> EulerGrid {
    let size = rect.max - rect.min;
    let m = margin as f64 * CELL_M;
    EulerGrid {
        origin: rect.min - DVec2::splat(m),
        cell: CELL_M,
        nx: (size.x / CELL_M).ceil().max(1.0) as usize + 2 * margin,
        ny: (size.y / CELL_M).ceil().max(1.0) as usize + 2 * margin,
        sigma: SIGMA_M,
    }
}

/// The cells of `grid` off its `margin` border cells.
fn inner(grid: &EulerGrid, margin: usize) -> Vec<usize> {
    (margin..grid.ny - margin)
        .flat_map(|j| (margin..grid.nx - margin).map(move |i| j * grid.nx + i))
        .collect()
}

/// The steps of `window` on a clock that starts at `start`.
fn steps_of(window: (f64, f64), start: f64, steps: usize) -> std::ops::RangeInclusive<usize> {
    let at = |t: f64| (((t - start) / DT).round().max(0.0) as usize).min(steps);
    at(window.0)..=at(window.1)
}

/// The edit's constraints on the patch's problem (appended to `out`) and how to measure it.
/// `positions(k, i)` is where character `i` is planned at step `k`; `radius` the characters'.
pub fn constrain(
    local: &Local,
    copies: &[Copy],
    span: (f64, f64),
    steps: usize,
    positions: &dyn Fn(usize, usize) -> DVec2,
    radius: f64,
    out: &mut Vec<Constraint>,
) -> Measure {
    let start = span.0;
    let present = |k: usize| -> Vec<usize> {
        let t = start + k as f64 * DT;
        (0..copies.len())
            .filter(|&i| copies[i].present(t))
            .collect()
    };
    let walkers = |k: usize| -> Vec<usize> {
        present(k)
            .into_iter()
            .filter(|&i| copies[i].trajectory.is_some())
            .collect()
    };
    let name = format!("edit {}", local.edit);
    let mut push = |operator: Box<dyn Observe>, k: usize, target: Vec<f64>, r: f64| {
        out.push(Constraint {
            name: name.clone(),
            operator,
            samples: vec![Sample {
                step: k,
                target,
                weight: DT,
            }],
            r,
        });
        out.len() - 1
    };
    match local.kind {
        LocalKind::Meet {
            at,
            people,
            radius: given,
        } => {
            let k = *steps_of(local.window, start, steps).start();
            // Those who can come: walkers the edit may move fully at the meeting, and for
            // [`MEET_NOTICE_S`] before it (not about to leave, not on a border band).
            let t = start + k as f64 * DT;
            let free = |i: usize| {
                let c = &copies[i];
                (0..=10).all(|s| c.mask(t - MEET_NOTICE_S * s as f64 / 10.0, span) >= 1.0)
            };
            let mut who: Vec<usize> = walkers(k).into_iter().filter(|&i| free(i)).collect();
            who.sort_by(|&a, &b| {
                let d = |i: usize| positions(k, i).distance_squared(at);
                d(a).total_cmp(&d(b)).then(a.cmp(&b))
            });
            who.truncate(people);
            let places = ring(
                at,
                &who,
                |i| positions(k, i),
                given,
                radius_of(who.len(), radius),
            );
            let target = places.iter().flat_map(|p| [p.x, p.y]).collect();
            // One instant: weight 1 (as `Constraint::over_window`), not a step's DT.
            let c = push(Box::new(Positions { who: who.clone() }), k, target, local.r);
            out[c].samples[0].weight = 1.0;
            Measure::Meet {
                step: k,
                who,
                places,
            }
        }
        LocalKind::Density { rect, target } => {
            let grid = grid_over(rect, 0);
            let cells = inner(&grid, 0);
            let window = steps_of(local.window, start, steps);
            let square = Square { rect, target };
            let gathering = gather(&square, window.clone(), copies, span, positions);
            let indices = window
                .clone()
                .zip(gathering.who)
                .map(|(k, who)| {
                    let op = Density {
                        grid,
                        cells: cells.clone(),
                        counted: Counted::Only(present(k)),
                    };
                    let c = push(Box::new(op), k, vec![target; cells.len()], local.r);
                    if !who.is_empty() {
                        let zeros = vec![0.0; who.len()];
                        let within = Within {
                            rect: gathering.inside,
                            who,
                        };
                        push(Box::new(within), k, zeros, GATHER_R);
                    }
                    c
                })
                .collect();
            Measure::Density {
                indices,
                rect,
                counted: window.map(|k| (k, present(k))).collect(),
                reachable: gathering.people,
            }
        }
        LocalKind::Flow { rect, ref goal } => {
            let grid = grid_over(rect, 0);
            let half = DVec2::splat(grid.cell / 2.0);
            let (cells, y): (Vec<usize>, Vec<f64>) = inner(&grid, 0)
                .into_iter()
                .filter_map(|c| {
                    let at = grid.centre(c);
                    goal.over(at - half, at + half).map(|v| (c, v))
                })
                .fold((Vec::new(), Vec::new()), |(mut cells, mut y), (c, v)| {
                    cells.push(c);
                    y.extend([v.x, v.y]);
                    (cells, y)
                });
            let indices = match cells.is_empty() {
                true => Vec::new(),
                false => steps_of(local.window, start, steps)
                    .map(|k| {
                        let op = Velocity {
                            grid,
                            cells: cells.clone(),
                            counted: Counted::Only(present(k)),
                        };
                        push(Box::new(op), k, y.clone(), local.r)
                    })
                    .collect(),
            };
            Measure::Rms { indices }
        }
        LocalKind::Vorticity { rect, per_s } => {
            let grid = grid_over(rect, 1);
            let cells = inner(&grid, 1);
            let indices = steps_of(local.window, start, steps)
                .map(|k| {
                    let op = Vorticity {
                        grid,
                        cells: cells.clone(),
                        counted: Counted::Only(present(k)),
                    };
                    push(Box::new(op), k, vec![per_s; cells.len()], local.r)
                })
                .collect();
            Measure::Rms { indices }
        }
    }
}

/// The ring a meeting stands on, unless the edit gives its own: round the point with `people`
/// bodies of `radius` [`MEET_GAP_M`] apart.
fn radius_of(people: usize, radius: f64) -> f64 {
    match people {
        0 | 1 => 0.0,
        n => (radius + MEET_GAP_M / 2.0) / (std::f64::consts::PI / n as f64).sin(),
    }
}

/// How far apart people who meet stand, body to body, m: near enough to talk, far enough that
/// the repulsion (range 8 cm) lets them stand still.
pub const MEET_GAP_M: f64 = 0.2;

/// Each walker's place on the ring round `at`: evenly spaced, in the order of the walkers'
/// bearings from the point, the first where it already is (so nobody crosses the others).
fn ring(
    at: DVec2,
    who: &[usize],
    position: impl Fn(usize) -> DVec2,
    given: Option<f64>,
    fitting: f64,
) -> Vec<DVec2> {
    let radius = given.unwrap_or(fitting);
    let bearing = |i: usize| {
        let d = position(i) - at;
        d.y.atan2(d.x)
    };
    let mut order: Vec<usize> = (0..who.len()).collect();
    order.sort_by(|&a, &b| bearing(who[a]).total_cmp(&bearing(who[b])));
    let first = order.first().map_or(0.0, |&o| bearing(who[o]));
    let mut places = vec![at; who.len()];
    let n = who.len().max(1) as f64;
    for (slot, &o) in order.iter().enumerate() {
        let angle = first + std::f64::consts::TAU * slot as f64 / n;
        places[o] = at + DVec2::new(angle.cos(), angle.sin()) * radius;
    }
    places
}

/// The residual of `measure` on `states` (one state per step, `n` numbers each): its sum of
/// squares and count (root mean square kinds; a density edit also counts its people), or its
/// largest distance (a meeting).
pub fn residual(
    measure: &Measure,
    constraints: &[Constraint],
    states: &[f64],
    n: usize,
) -> Residual {
    let squares = |indices: &[usize]| {
        let (mut squares, mut count) = (0.0, 0usize);
        for &c in indices {
            let constraint = &constraints[c];
            let (_, rms) = constraint.misfit(states, n);
            let len = constraint.operator.len();
            squares += rms * rms * len as f64;
            count += len;
        }
        Squares { squares, count }
    };
    match measure {
        Measure::Meet { step, who, places } => {
            let x = &states[step * n..(step + 1) * n];
            let far = who
                .iter()
                .zip(places)
                .map(|(&i, p)| DVec2::new(x[4 * i], x[4 * i + 1]).distance(*p))
                .fold(0.0, f64::max);
            Residual::Largest(far)
        }
        Measure::Rms { indices } => Residual::Squares(squares(indices)),
        Measure::Density {
            indices,
            rect,
            counted,
            reachable,
        } => {
            let inside: usize = counted
                .iter()
                .map(|(k, who)| {
                    let x = &states[k * n..(k + 1) * n];
                    who.iter()
                        .filter(|&&i| rect.contains(DVec2::new(x[4 * i], x[4 * i + 1])))
                        .count()
                })
                .sum();
            Residual::Density {
                squares: squares(indices),
                people: People {
                    inside: inside as f64,
                    reachable: *reachable,
                    area_steps: rect.area() * counted.len() as f64,
                },
            }
        }
    }
}

/// Squares of H - Y over `count` numbers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Squares {
    pub squares: f64,
    pub count: usize,
}

impl std::ops::Add for Squares {
    type Output = Squares;
    fn add(self, o: Squares) -> Squares {
        Squares {
            squares: self.squares + o.squares,
            count: self.count + o.count,
        }
    }
}

/// People in a density edit's rectangle, summed over the window's steps: those there, those
/// who could be ([`crate::gather::Gathering::people`]), and the rectangle's area times the
/// steps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct People {
    pub inside: f64,
    pub reachable: f64,
    pub area_steps: f64,
}

impl std::ops::Add for People {
    type Output = People;
    fn add(self, o: People) -> People {
        People {
            inside: self.inside + o.inside,
            reachable: self.reachable + o.reachable,
            area_steps: self.area_steps + o.area_steps,
        }
    }
}

impl People {
    /// People per m2 in the rectangle, over the window.
    pub fn density(self) -> f64 {
        self.inside / self.area_steps.max(f64::MIN_POSITIVE)
    }

    /// The most the patches could show, people per m2.
    pub fn reachable(self) -> f64 {
        self.reachable / self.area_steps.max(f64::MIN_POSITIVE)
    }
}

/// A residual as patches add up: meetings keep their largest distance, the others their
/// squares (and density edits their people).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Residual {
    Largest(f64),
    Squares(Squares),
    Density { squares: Squares, people: People },
}

impl Residual {
    pub fn combine(self, other: Residual) -> Residual {
        match (self, other) {
            (Residual::Largest(a), Residual::Largest(b)) => Residual::Largest(a.max(b)),
            (Residual::Squares(a), Residual::Squares(b)) => Residual::Squares(a + b),
            (
                Residual::Density { squares, people },
                Residual::Density {
                    squares: s2,
                    people: p2,
                },
            ) => Residual::Density {
                squares: squares + s2,
                people: people + p2,
            },
            (a, _) => a,
        }
    }

    /// The figure the report shows: the distance, or the root mean square.
    pub fn value(self) -> f64 {
        match self {
            Residual::Largest(d) => d,
            Residual::Squares(s) | Residual::Density { squares: s, .. } => {
                (s.squares / s.count.max(1) as f64).sqrt()
            }
        }
    }

    /// A density edit's people (`None` for the other kinds).
    pub fn people(self) -> Option<People> {
        match self {
            Residual::Density { people, .. } => Some(people),
            _ => None,
        }
    }
}
