//! The rescue of a patch the pushes leave stalled: one walker of the worst pair is planned
//! anew through space and time around everyone else, then the pushes go on.
//!
//! Pushes are local: where a few walkers keep pushing each other back (a dense spot, a walker
//! that must pass another's whole pause), no sequence of small moves found by the greedy
//! repair gets out. A plan in space-time sees the whole way at once. The patch is a grid of
//! cells (at most [`CELL`] wide) and the walker's time between its band ends is cut into
//! layers (at most [`LAYER`] apart); a cell of a layer is free when it is clear of the walls,
//! the standers and every other walker at that moment (by a safety margin, since the grid
//! sees moments, not intervals). Sweeping forward, the cells the walker can be in at each
//! layer are those next to a reachable cell of the layer before, and free: if the exit band's
//! start is reachable at its time, a way exists on the grid. It is read backwards, at each
//! layer taking the reachable cell nearest to where the walker used to be, and straightened
//! wherever the straight walk is clear by the exact closest approach.

use crate::path::{Free, Path};
use crate::repair::{self, Outcome, Patch, Speeds};
use crowd_core::trajectories::{ControlPoint, PointKind, split_at_periods};
use crowd_geometry::{self as geometry, Segment};
use glam::DVec2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Largest grid cell, m (smaller where a step of one cell per [`LAYER`] would be faster than
/// `match.max_speed`).
const CELL: f64 = 0.2;
/// Largest time between layers, s.
const LAYER: f64 = 0.1;

/// How strictly the grid keeps a walker from the others.
#[derive(Debug, Clone, Copy)]
pub struct GridRule {
    /// Kept free around others beyond the clearance they need, m: between two layers a walker
    /// moves at most a diagonal cell and the others about as much.
    margin: f64,
    /// Time next to a band end when the grid ignores the other walkers, s: the way cannot
    /// bend there anyway (stage 5 holds a path a quarter second from its band), and who passes
    /// by then is the patterns' business.
    held: f64,
}

/// The first try: a margin for the moments between layers.
pub const STRICT: GridRule = GridRule {
    margin: 0.12,
    held: 0.25,
};
/// The second, where someone passes close by a band end: no margin, and free to leave the
/// band for longer; the exact check that follows decides.
pub const LOOSE: GridRule = GridRule {
    margin: 0.0,
    held: 0.6,
};
/// What a straightened piece keeps beyond the clearance, m.
const STRAIGHT_MARGIN: f64 = 0.02;
/// Longest straight piece tried when straightening, in layers.
const LONGEST: usize = 60;

/// Rounds of a rescue in a row that may leave its best state unbettered before it gives up:
/// on the shared scenes and the soak's hardest paintings, a rescue that cleared its patch had
/// bettered its best within 10 rounds every time, while most that failed never bettered their
/// start at all and ran all [`crate::RESCUE_ROUNDS`] (the settings of a long-period painting
/// spent 90 % of a 470 s stage 5 so).
pub const RESCUE_PATIENCE: u32 = 12;

/// Plans one walker of the worst pair anew, then pushes for `pushes` more, up to `rounds`
/// times, until the patch is clear or [`RESCUE_PATIENCE`] rounds in a row brought nothing
/// better; keeps the best state seen (by the worst margin). Its random draws are its own
/// (seeded by one draw of `rng`), so how long it runs does not change the tries after it.
pub fn rescue(
    paths: &mut [Path],
    patch: &Patch,
    speeds: Speeds,
    rounds: u32,
    pushes: u32,
    rng: &mut ChaCha8Rng,
) -> Outcome {
    let rng = &mut ChaCha8Rng::seed_from_u64(rng.random());
    let margin = |o: &Outcome| o.worst.map_or(f64::INFINITY, |w| w.margin);
    let mut outcome = repair::remove_collisions(paths, patch, speeds, 0, rng);
    let mut best = (paths.to_vec(), outcome);
    let (mut iterations, mut bettered) = (0, 0);
    for round in 0..rounds {
        let Some(w) = outcome.worst else { break };
        if round - bettered >= RESCUE_PATIENCE {
            break;
        }
        let mut walkers = vec![w.a];
        if let repair::Other::Walker { b, .. } = w.other
            && b != w.a
        {
            walkers.push(b);
        }
        // Alternate which of the two goes first, so that a walker that cannot find a way
        // round the other does not block the round.
        if round % 2 == 1 {
            walkers.reverse();
        }
        let tries = walkers.iter().flat_map(|&p| [(p, STRICT), (p, LOOSE)]);
        for (p, grid) in tries {
            if let Some(free) = plan(paths, p, patch, grid, speeds.bend_limit()) {
                paths[p].free = free;
                break;
            }
        }
        outcome = repair::remove_collisions(paths, patch, speeds, pushes, rng);
        iterations += outcome.iterations + 1;
        if margin(&outcome) > margin(&best.1) {
            best = (paths.to_vec(), outcome);
            bettered = round + 1;
        }
    }
    if outcome.worst.is_some() {
        paths.clone_from_slice(&best.0);
        outcome = best.1;
    }
    Outcome {
        iterations,
        ..outcome
    }
}

/// The grid of a patch: `n` x `n` cells of side `h`, row by row from the south-west.
struct Grid {
    n: usize,
    h: f64,
}

impl Grid {
    fn centre(&self, c: usize) -> DVec2 {
        DVec2::new((c % self.n) as f64 + 0.5, (c / self.n) as f64 + 0.5) * self.h
    }

    fn cell_of(&self, p: DVec2) -> usize {
        let i = |v: f64| ((v / self.h).floor().max(0.0) as usize).min(self.n - 1);
        i(p.y) * self.n + i(p.x)
    }

    /// The cell and its four edge neighbours: a step of one cell between two layers is the
    /// farthest a walker goes, so that no piece of a planned way (a straight line joins
    /// steps, no longer than their sum) is faster than a cell per layer.
    fn around(&self, c: usize) -> impl Iterator<Item = usize> + '_ {
        let (x, y) = ((c % self.n) as i64, (c / self.n) as i64);
        let n = self.n as i64;
        [(0, 0), (-1, 0), (1, 0), (0, -1), (0, 1)]
            .into_iter()
            .map(move |(dx, dy)| (x + dx, y + dy))
            .filter(move |&(x, y)| x >= 0 && y >= 0 && x < n && y < n)
            .map(move |(x, y)| (y * n + x) as usize)
    }

    /// Whether cell `c` or one of its edge neighbours ([`Grid::around`]) is set in `prev`.
    fn reached(&self, prev: &[bool], c: usize) -> bool {
        let (x, y, n) = (c % self.n, c / self.n, self.n);
        prev[c]
            || (x > 0 && prev[c - 1])
            || (x + 1 < n && prev[c + 1])
            || (y > 0 && prev[c - n])
            || (y + 1 < n && prev[c + n])
    }

    /// One layer of the reachability sweep: `next[c]` is set where `c` is not `blocked` and
    /// [`Grid::reached`] from `prev`. Row by row over slices, without a division or a bounds
    /// check per cell: it is most of a plan's time.
    fn sweep(&self, prev: &[bool], blocked: &[bool], next: &mut [bool]) {
        let n = self.n;
        for y in 0..n {
            let row = y * n..(y + 1) * n;
            let (here, out) = (&prev[row.clone()], &mut next[row.clone()]);
            out.copy_from_slice(here);
            for (o, &h) in out[1..].iter_mut().zip(&here[..n - 1]) {
                *o |= h;
            }
            for (o, &h) in out[..n - 1].iter_mut().zip(&here[1..]) {
                *o |= h;
            }
            if y > 0 {
                for (o, &h) in out.iter_mut().zip(&prev[row.start - n..row.start]) {
                    *o |= h;
                }
            }
            if y + 1 < n {
                for (o, &h) in out.iter_mut().zip(&prev[row.end..row.end + n]) {
                    *o |= h;
                }
            }
            for (o, &b) in out.iter_mut().zip(&blocked[row]) {
                *o &= !b;
            }
        }
    }

    /// Marks every cell whose centre is within `reach` of `q`.
    fn mark_disc(&self, cells: &mut [bool], q: DVec2, reach: f64) {
        let lo = |v: f64| (((v - reach) / self.h - 0.5).ceil().max(0.0)) as usize;
        let hi = |v: f64| ((((v + reach) / self.h - 0.5).floor()) as i64).min(self.n as i64 - 1);
        let (x1, y1) = (hi(q.x), hi(q.y));
        if x1 < 0 || y1 < 0 {
            return;
        }
        for y in lo(q.y)..=y1 as usize {
            for x in lo(q.x)..=x1 as usize {
                let c = y * self.n + x;
                if self.centre(c).distance_squared(q) < reach * reach {
                    cells[c] = true;
                }
            }
        }
    }
}

/// Where the pieces `segs` (in time order) are at time `t`, if they exist then.
fn position(segs: &[Segment], t: f64) -> Option<DVec2> {
    let (first, last) = (segs.first()?, segs.last()?);
    (t >= first.t0 && t <= last.t1).then(|| geometry::at_time(segs, t))?
}

/// Everyone walker `p` must keep clear of, as pieces: every other walker, and `p`'s own copies
/// whole periods away, each with the time shift that places it (`shift` added to its times).
fn others(segs: &[Vec<Segment>], p: usize, span: (f64, f64), period: f64) -> Vec<(usize, f64)> {
    let mut out = Vec::new();
    for (b, sb) in segs.iter().enumerate() {
        let (Some(first), Some(last)) = (sb.first(), sb.last()) else {
            continue;
        };
        for k in geometry::copies(span, (first.t0, last.t1), period) {
            if b == p && k == 0 {
                continue;
            }
            out.push((b, k as f64 * period));
        }
    }
    out
}

/// A new way for walker `p` between its band ends, clear of everyone on the grid and
/// straightened where the exact check allows; `None` when the grid holds no way.
pub fn plan(
    paths: &[Path],
    p: usize,
    patch: &Patch,
    how: GridRule,
    max_speed: f64,
) -> Option<Vec<Free>> {
    let r = patch.radius_m;
    let (start, end) = paths[p].fixed_ends();
    let (ts, te) = (start.t(), end.t());
    let segs: Vec<Vec<Segment>> = paths.iter().map(Path::segments).collect();
    let others = others(&segs, p, (ts, te), patch.period_s);
    // A step to a neighbouring cell between two layers keeps to `max_speed` ([`Grid::around`]).
    let cell = CELL.min(max_speed * LAYER);
    let n = (patch.side_m / cell).ceil() as usize;
    let grid = Grid {
        n,
        h: patch.side_m / n as f64,
    };
    let cells = n * n;
    // Cells no moment can use: out of [r, side - r]^2 (the bands' zone), near walls, near
    // standers.
    let mut fixed = vec![false; cells];
    for (c, blocked) in fixed.iter_mut().enumerate() {
        let q = grid.centre(c);
        let inside = q.cmpge(DVec2::splat(r + 1e-3)).all()
            && q.cmple(DVec2::splat(patch.side_m - r - 1e-3)).all();
        let near_wall = patch
            .obstacles
            .iter()
            .any(|o| (q.clamp(o.min, o.max) - q).length() < r + how.margin);
        *blocked = !inside || near_wall;
    }
    for &s in patch.standers {
        grid.mark_disc(&mut fixed, s, 2.0 * r + how.margin);
    }
    let layers = ((te - ts) / LAYER).ceil().max(2.0) as usize;
    let dt = (te - ts) / layers as f64;
    let time = |k: usize| ts + dt * k as f64;
    let (from, to) = (grid.cell_of(start.pos()), grid.cell_of(end.pos()));
    // reach[k][c]: the walker can be in cell c at layer k.
    let mut reach: Vec<Vec<bool>> = Vec::with_capacity(layers + 1);
    let mut first = vec![false; cells];
    first[from] = true;
    reach.push(first);
    let mut blocked = vec![false; cells];
    for k in 1..=layers {
        let t = time(k);
        blocked.copy_from_slice(&fixed);
        let held = t - ts < how.held || te - t < how.held;
        for &(b, shift) in others.iter().filter(|_| !held) {
            if let Some(q) = position(&segs[b], t - shift) {
                grid.mark_disc(&mut blocked, q, 2.0 * r + how.margin);
            }
        }
        let prev = &reach[k - 1];
        let mut next = vec![false; cells];
        if k == layers {
            // The last layer is the band's start itself, wherever it is.
            next[to] = grid.reached(prev, to);
        } else {
            grid.sweep(prev, &blocked, &mut next);
        }
        if !next.contains(&true) {
            return None;
        }
        reach.push(next);
    }
    // Backwards from the band's start: at each layer the reachable neighbour nearest to where
    // the walker was (its way stays close to the one stage 4 and the pushes gave it).
    let mut way = vec![to; layers + 1];
    for k in (1..layers).rev() {
        let want = geometry::at_time(&segs[p], time(k)).expect("the walker's pieces");
        way[k] = grid
            .around(way[k + 1])
            .filter(|&d| reach[k][d])
            .min_by(|&a, &b| {
                grid.centre(a)
                    .distance_squared(want)
                    .total_cmp(&grid.centre(b).distance_squared(want))
            })
            .expect("a reachable cell has a reachable neighbour in the layer before");
    }
    let mut points: Vec<(DVec2, f64)> = (0..=layers)
        .map(|k| (grid.centre(way[k]), time(k)))
        .collect();
    points[0] = (start.pos(), ts);
    points[layers] = (end.pos(), te);
    let kept = straighten(&points, &segs, &others, patch);
    Some(free_points(&kept, patch.period_s))
}

/// The fewest of `points` whose straight pieces stay clear: from each kept point, the farthest
/// later one (up to [`LONGEST`] layers on) that a straight walk reaches clear of everyone.
fn straighten(
    points: &[(DVec2, f64)],
    segs: &[Vec<Segment>],
    others: &[(usize, f64)],
    patch: &Patch,
) -> Vec<(DVec2, f64)> {
    let mut kept = vec![points[0]];
    let mut i = 0;
    while i + 1 < points.len() {
        let last = (i + LONGEST).min(points.len() - 1);
        let j = (i + 2..=last)
            .rev()
            .find(|&j| clear(points[i], points[j], segs, others, patch))
            .unwrap_or(i + 1);
        kept.push(points[j]);
        i = j;
    }
    kept
}

/// Whether a straight walk from `a` to `b` keeps the clearance (and a little) from everyone.
fn clear(
    a: (DVec2, f64),
    b: (DVec2, f64),
    segs: &[Vec<Segment>],
    others: &[(usize, f64)],
    patch: &Patch,
) -> bool {
    let r = patch.radius_m;
    let walk = Segment {
        p0: a.0,
        t0: a.1,
        p1: b.0,
        t1: b.1,
    };
    let need = 2.0 * r + STRAIGHT_MARGIN;
    let walls = patch
        .obstacles
        .iter()
        .all(|o| geometry::distance_to_rect(&walk, o.min, o.max) >= r + STRAIGHT_MARGIN);
    let standers = patch.standers.iter().all(|&s| {
        geometry::closest(&walk, &Segment::standing(s, a.1, b.1)).is_none_or(|(d, _)| d >= need)
    });
    walls
        && standers
        && others.iter().all(|&(o, shift)| {
            let sb = &segs[o];
            let lo = sb.partition_point(|s| s.t1 + shift < a.1);
            sb[lo..]
                .iter()
                .take_while(|s| s.t0 + shift <= b.1)
                .all(|s| geometry::closest(&walk, &s.shifted(shift)).is_none_or(|(d, _)| d >= need))
        })
}

/// The inner points of a planned way as free points: bends, pauses where it stands still for
/// a while, and a split point at every multiple of the period it passes.
fn free_points(kept: &[(DVec2, f64)], period: f64) -> Vec<Free> {
    let mut points: Vec<ControlPoint> = kept
        .iter()
        .map(|&(pos, t)| ControlPoint {
            pos,
            t,
            kind: PointKind::Bend,
        })
        .collect();
    // A stretch where it stands for 0.3 s or more is a pause (reached and left at rest when
    // smoothed). The ends are the band ends, never part of a pause.
    let n = points.len();
    for w in 1..n.saturating_sub(2) {
        if points[w].pos == points[w + 1].pos && points[w + 1].t - points[w].t >= 0.3 {
            points[w].kind = PointKind::Pause;
            points[w + 1].kind = PointKind::Pause;
        }
    }
    let points = split_at_periods(points, period);
    points[1..points.len() - 1]
        .iter()
        .map(|c| Free {
            pos: c.pos,
            t: c.t,
            kind: c.kind,
        })
        .collect()
}
