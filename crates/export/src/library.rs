//! The binary patch library: stage 6's trajectories quantised for `crowd-runtime`.
//!
//! Positions are patch-local in steps of side / 65535 (within side / 131,070 of the exact
//! point); times are whole ticks of 0.1 ms from each trajectory's start, which is itself in
//! ticks of the period (within 0.05 ms). Where a trajectory ends, its time is snapped to the
//! start of the one that continues it, a whole number of periods on, so that every loop lasts
//! exactly its laps x the period and the runtime's links are exact.

use crate::ExportError;
use crate::characters::{LinkError, Links};
use crate::motion::{Motion, Summaries};
use crowd_core::PatchGraph;
use crowd_core::patterns::Crossing;
use crowd_core::trajectories::PatchMotion;
use crowd_runtime::{Character, Library, Point, TICK_S, World};
use glam::DVec2;
use rayon::prelude::*;

/// Worst-case quantisation error of positions, as a share of the patch side.
pub const POSITION_ERROR_SHARE: f64 = 0.5 / 65535.0;

/// Why a library cannot be made.
#[derive(Debug, Clone, PartialEq)]
pub enum LibraryError {
    Links(LinkError),
    /// The period is not a whole number of ticks, so loops could not close exactly.
    Period(f64),
    /// More of something than the format's 32-bit counts hold.
    TooMany(&'static str),
}

impl std::fmt::Display for LibraryError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LibraryError::Links(e) => e.fmt(f),
            LibraryError::Period(p) => write!(
                f,
                "period {p} s is not a whole number of 0.1 ms ticks; expected e.g. 20.0 or 17.5"
            ),
            LibraryError::TooMany(what) => write!(f, "more {what} than a library holds (2^32)"),
        }
    }
}

impl std::error::Error for LibraryError {}

/// Patches quantised at once: a run's records are made in parallel and then appended, so that
/// a gathering build holds a run's records twice, not the world's.
const PATCHES_PER_RUN: usize = 1024;

/// The library of a build: `motion` (the final motion, thinned), its `summaries` and `links`.
#[allow(clippy::too_many_arguments)]
pub fn build<M: Motion + ?Sized>(
    graph: &PatchGraph,
    crossings: &[Crossing],
    motion: &M,
    summaries: &Summaries,
    links: &Links,
    period_s: f64,
    seed: u64,
    input_hash: [u8; 8],
) -> Result<(Library, f64), ExportError> {
    let made = (graph, crossings, motion, summaries, links);
    // At its size: grown by doubling, the million's 0.77 GB of points took 0.99 GB, and twice
    // that while each growth copied them (export's peak).
    let mut points = Vec::with_capacity(summaries.trajectories.iter().map(|s| s.points).sum());
    let (library, eased_m) = build_into(made, (period_s, seed, input_hash), &mut points)?;
    Ok((Library { points, ..library }, eased_m))
}

/// Where [`build_into`] puts the library's points, a run of patches' at a time.
pub trait PointSink {
    /// How many it holds.
    fn held(&self) -> usize;
    /// Takes `points` after those it holds.
    fn take(&mut self, points: &[Point]) -> Result<(), ExportError>;
}

impl PointSink for Vec<Point> {
    fn held(&self) -> usize {
        self.len()
    }

    fn take(&mut self, points: &[Point]) -> Result<(), ExportError> {
        self.extend_from_slice(points);
        Ok(())
    }
}

/// [`build`], its points handed to `sink` as they are made: the library it returns holds none.
pub fn build_into<M: Motion + ?Sized>(
    (graph, crossings, motion, summaries, links): (
        &PatchGraph,
        &[Crossing],
        &M,
        &Summaries,
        &Links,
    ),
    (period_s, seed, input_hash): (f64, u64, [u8; 8]),
    points: &mut impl PointSink,
) -> Result<(Library, f64), ExportError> {
    let period_ticks = (period_s / TICK_S).round();
    if (period_ticks * TICK_S - period_s).abs() > 1e-9 || period_ticks < 1.0 {
        return Err(LibraryError::Period(period_s).into());
    }
    let period_ticks = period_ticks as u64;
    let count = |n: usize, what| u32::try_from(n).map_err(|_| LibraryError::TooMany(what));
    let side = graph.world.patch_side_m;
    let ticks = |t: f64| (t / TICK_S).round() as i64;
    let pt = period_ticks as i64;

    let world = World {
        patch_side_m: side as f32,
        period_ticks: count(period_ticks as usize, "ticks in a period")?,
        radius_m: graph.radius_m as f32,
        cols: graph.world.cols,
        rows: graph.world.rows,
        seed,
        input_hash,
        turn_rate_deg_s: crowd_runtime::turn::DEFAULT_TURN_RATE_DEG_S as f32,
    };
    // Starts first: a trajectory's end is snapped to its successor's start.
    let start_of = |i: usize| ticks(summaries.trajectories[i].start_s).rem_euclid(pt);
    let quantised = Quantised {
        side,
        period_ticks: pt,
        start_of: &start_of,
    };
    // Patches are quantised in parallel (painting's 9 million points were most of a brush
    // stroke's library on one core), a run at a time, then laid end to end in patch order.
    let mut patches = Vec::with_capacity(motion.patches());
    let mut standers = Vec::new();
    let mut trajectories = Vec::with_capacity(links.refs.len());
    // Each trajectory's last tick, which its loop's laps are counted from.
    let mut last_ticks = Vec::with_capacity(links.refs.len());
    let mut eased_m = 0.0f64;
    for run in (0..motion.patches()).step_by(PATCHES_PER_RUN) {
        let end = (run + PATCHES_PER_RUN).min(motion.patches());
        let parts: Vec<Result<PatchPart, ExportError>> = (run..end)
            .into_par_iter()
            .map(|p| quantised.patch(p, &*motion.patch(p)?, summaries.firsts[p], links))
            .collect();
        for (p, part) in (run..end).zip(parts) {
            let part = part?;
            let cell = graph.patches[p].cell;
            patches.push(crowd_runtime::Patch {
                col: cell.col,
                row: cell.row,
                first_trajectory: count(trajectories.len(), "trajectories")?,
                trajectories: count(part.trajectories.len(), "trajectories")?,
                first_stander: count(standers.len(), "standers")?,
                standers: count(part.standers.len(), "standers")?,
            });
            standers.extend(part.standers);
            let offset = count(points.held(), "points")?;
            for mut t in part.trajectories {
                last_ticks.push(part.points[(t.first_point + t.points - 1) as usize].t);
                t.first_point = offset
                    .checked_add(t.first_point)
                    .ok_or(LibraryError::TooMany("points"))?;
                trajectories.push(t);
            }
            count(points.held() + part.points.len(), "points")?;
            points.take(&part.points)?;
            eased_m = eased_m.max(part.eased_m);
        }
    }
    let characters = links
        .loops
        .iter()
        .map(|lp| {
            let total: u64 = lp.iter().map(|&i| u64::from(last_ticks[i])).sum();
            Ok(Character {
                first_trajectory: count(lp[0], "trajectories")?,
                trajectories: count(lp.len(), "trajectories")?,
                laps: count((total / period_ticks) as usize, "laps")?,
            })
        })
        .collect::<Result<Vec<_>, LibraryError>>()?;
    let crossing_records = crossings
        .iter()
        .map(|c| {
            let (from, to) = c.ends(graph);
            let origin = graph.world_from_patch(graph.patches[to.patch.0 as usize].cell);
            let at = origin + to.pos;
            crowd_runtime::Crossing {
                from_patch: from.patch.0,
                to_patch: to.patch.0,
                x: at.x as f32,
                y: at.y as f32,
                t: (ticks(c.t).rem_euclid(pt)) as u32,
                vx: c.velocity.x as f32,
                vy: c.velocity.y as f32,
            }
        })
        .collect();
    let library = Library {
        world,
        patches,
        standers,
        crossings: crossing_records,
        trajectories,
        points: Vec::new(),
        characters,
    };
    Ok((library, eased_m))
}

/// What quantises a patch's motion for the library: the patch side, the period in ticks, and
/// each trajectory's start in ticks (by its index in the library).
struct Quantised<'a, F: Fn(usize) -> i64> {
    side: f64,
    period_ticks: i64,
    start_of: &'a F,
}

/// One patch's records, its trajectories' `first_point` counted from its own first point.
struct PatchPart {
    standers: Vec<Point>,
    trajectories: Vec<crowd_runtime::Trajectory>,
    points: Vec<Point>,
    eased_m: f64,
}

impl<F: Fn(usize) -> i64> Quantised<'_, F> {
    fn quant(&self, v: f64) -> u16 {
        ((v / self.side).clamp(0.0, 1.0) * 65535.0).round() as u16
    }

    /// Patch `p`'s standers, trajectories (the first numbered `first` in the library) and
    /// points.
    fn patch(
        &self,
        p: usize,
        m: &PatchMotion,
        first: usize,
        links: &Links,
    ) -> Result<PatchPart, ExportError> {
        let count = |n: usize, what| u32::try_from(n).map_err(|_| LibraryError::TooMany(what));
        let ticks = |t: f64| (t / TICK_S).round() as i64;
        let pt = self.period_ticks;
        let mut part = PatchPart {
            standers: (m.standers.iter())
                .map(|s| Point {
                    x: self.quant(s.x),
                    y: self.quant(s.y),
                    t: 0,
                })
                .collect(),
            trajectories: Vec::with_capacity(m.trajectories.len()),
            points: Vec::new(),
            eased_m: 0.0,
        };
        for (k, tr) in m.trajectories.iter().enumerate() {
            let i = first + k;
            let start = (self.start_of)(i);
            // Relative ticks as differences of absolute ones: each point's time is then within
            // half a tick of exact.
            let t0 = ticks(tr.points[0].t);
            let first_point = part.points.len();
            // The end, snapped: the successor's start a whole number of periods on.
            let succ = (self.start_of)(links.next[i] as usize);
            let exact = ticks(tr.points[tr.points.len() - 1].t) - t0;
            let gap = (succ - start).rem_euclid(pt);
            let mut end = gap + pt * ((exact - gap) as f64 / pt as f64).round() as i64;
            while end < 1 {
                end += pt;
            }
            if end > i64::from(crowd_runtime::MAX_PERIODS_PER_TRAJECTORY) * pt {
                return Err(LibraryError::TooMany("periods in one trajectory (64)").into());
            }
            let mut last = 0i64;
            for (k, cp) in tr.points.iter().enumerate() {
                let t = if k == 0 {
                    0
                } else if k + 1 == tr.points.len() {
                    end
                } else {
                    (ticks(cp.t) - t0).clamp(last, end)
                };
                last = t;
                part.points.push(Point {
                    x: self.quant(cp.pos.x),
                    y: self.quant(cp.pos.y),
                    t: u32::try_from(t).map_err(|_| LibraryError::TooMany("ticks in a walk"))?,
                });
            }
            part.eased_m = part.eased_m.max(ease_ticks(
                &mut part.points[first_point..],
                self.side,
                &tr.points,
            ));
            part.trajectories.push(crowd_runtime::Trajectory {
                patch: p as u32,
                entry: tr.entry,
                exit: tr.exit,
                next: links.next[i],
                first_point: count(first_point, "points")?,
                points: count(tr.points.len(), "points")?,
                start: start as u32,
            });
        }
        Ok(part)
    }
}

/// Moves a point's rounded time by a tick where the rounding made a short piece next to it
/// faster than either of its pieces was (a piece of a few milliseconds next to a band end or a
/// border gains up to 4 % from half a tick at each end: random paintings 20, 31 and 181 shipped
/// 1.91-2.44 m/s from 1.86-1.87 m/s lines). The first and last ticks stay (the handovers);
/// points keep their order. Returns the farthest a moved point's walker is from where it was
/// at the point's exact time (its pieces' speed times a tick), m, for the stated error.
fn ease_ticks(
    points: &mut [Point],
    side: f64,
    exact: &[crowd_core::trajectories::ControlPoint],
) -> f64 {
    let metres = |p: &Point| DVec2::new(f64::from(p.x), f64::from(p.y)) * (side / 65535.0);
    let speed = |a: &Point, b: &Point| {
        let ticks = f64::from(b.t.saturating_sub(a.t)).max(1.0);
        metres(a).distance(metres(b)) / (ticks * TICK_S)
    };
    let exact_speed = |k: usize| {
        let (a, b) = (&exact[k], &exact[k + 1]);
        a.pos.distance(b.pos) / (b.t - a.t).max(TICK_S)
    };
    if points.len() < 3 {
        return 0.0;
    }
    let mut eased = 0.0f64;
    // Each piece's speeds are made once and carried to the next point (they were half of a
    // stroke's library): the same values, so the same choices, as made afresh at each point.
    let (mut exact_before, mut before) = (exact_speed(0), speed(&points[0], &points[1]));
    for k in 1..points.len() - 1 {
        let exact_after = exact_speed(k);
        let after = speed(&points[k], &points[k + 1]);
        let allowed = exact_before.max(exact_after);
        exact_before = exact_after;
        if before.max(after) <= allowed {
            before = after;
            continue;
        }
        let worst = |points: &[Point]| {
            speed(&points[k - 1], &points[k]).max(speed(&points[k], &points[k + 1]))
        };
        let (lo, hi, now) = (points[k - 1].t, points[k + 1].t, points[k].t);
        let mut best = (worst(points), now);
        for shift in [-1i64, 1] {
            let Ok(t) = u32::try_from(i64::from(now) + shift) else {
                continue;
            };
            if t < lo || t > hi {
                continue;
            }
            points[k].t = t;
            let w = worst(points);
            if w < best.0 {
                best = (w, t);
            }
        }
        if best.1 != now {
            eased = eased.max(allowed * TICK_S);
        }
        points[k].t = best.1;
        before = speed(&points[k], &points[k + 1]);
    }
    eased
}
