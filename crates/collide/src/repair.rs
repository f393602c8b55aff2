//! Ramirez et al. Algorithm 2 in one patch: while some pair is too close, push the closest
//! pair apart at the moment they are closest.

use crate::geometry::{self, Segment};
use crate::path::Path;
use crowd_core::Rect;
use glam::DVec2;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// Walking speed to and from a moved pause, m/s (the comfort speed).
const WALK_SPEED: f64 = 1.33;

/// What a patch holds besides its walkers.
pub struct Patch<'a> {
    pub side_m: f64,
    pub period_s: f64,
    pub radius_m: f64,
    pub obstacles: &'a [Rect],
    pub standers: &'a [DVec2],
}

impl Patch<'_> {
    /// What a walker's path is routed round (`Path::reroute`): the patch's own obstacles (off
    /// the border bands, a walker is a radius or more from any wall across a border already)
    /// and every stander as a square of half-side r (a path a radius clear of the square is a
    /// diameter clear of the stander).
    pub fn walls(&self) -> Vec<Rect> {
        let side = self.side_m;
        let r = DVec2::splat(self.radius_m);
        self.obstacles
            .iter()
            .filter(|o| o.max.x > 0.0 && o.max.y > 0.0 && o.min.x < side && o.min.y < side)
            .copied()
            .chain(self.standers.iter().map(|&s| Rect {
                min: s - r,
                max: s + r,
            }))
            .collect()
    }

    /// The nearest place to `p` out of the border bands: a walker is within a radius of a
    /// border only on its own band pieces, so two patches' walkers off their bands are always
    /// a diameter apart.
    pub fn keep_inside(&self, p: DVec2) -> DVec2 {
        let edge = self.radius_m + 1e-3;
        p.clamp(DVec2::splat(edge), DVec2::splat(self.side_m - edge))
    }
}

/// Who is too close to walker `a`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Other {
    /// Walker `b` (maybe `a` itself one or more periods later), shifted by `shift` seconds.
    Walker {
        b: usize,
        shift: f64,
    },
    Stander(usize),
    Obstacle(usize),
}

/// The closest encounter of walker `a`: how far, when (in `a`'s time), with whom.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Encounter {
    /// Distance minus the clearance the pair needs: negative is a collision.
    pub margin: f64,
    pub distance: f64,
    pub t: f64,
    pub a: usize,
    pub other: Other,
}

/// How the repair of a patch ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outcome {
    pub iterations: u32,
    /// The worst encounter left (None: nobody is closer than they may be).
    pub worst: Option<Encounter>,
}

/// Every walker's straight pieces (see [`Path::segments`]) with the box that holds them, kept
/// together so that the broad phase of [`pair`] never measures a path twice, and the time span
/// each changed over since the last [`refresh`].
#[derive(Debug, Clone)]
pub struct Tracks {
    segs: Vec<Vec<Segment>>,
    boxes: Vec<(DVec2, DVec2)>,
    changed: Vec<Option<Span>>,
}

/// A time span `[start, end]`, s.
type Span = (f64, f64);
const ALWAYS: Span = (f64::NEG_INFINITY, f64::INFINITY);

impl Tracks {
    pub fn new(segs: Vec<Vec<Segment>>) -> Tracks {
        let boxes = segs.iter().map(|s| bounds(s)).collect();
        let changed = vec![None; segs.len()];
        Tracks {
            segs,
            boxes,
            changed,
        }
    }

    /// Walker `p` now walks `segs`.
    pub fn set(&mut self, p: usize, segs: Vec<Segment>) {
        if let Some(span) = changed_span(&self.segs[p], &segs) {
            self.changed[p] =
                Some(self.changed[p].map_or(span, |c| (c.0.min(span.0), c.1.max(span.1))));
        }
        self.boxes[p] = bounds(&segs);
        self.segs[p] = segs;
    }

    pub fn get(&self, p: usize) -> &[Segment] {
        &self.segs[p]
    }

    pub fn len(&self) -> usize {
        self.segs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.segs.is_empty()
    }
}

/// The time span over which two versions of a path differ: from the start of the first piece
/// that differs to the end of the last (`None`: the same pieces).
fn changed_span(old: &[Segment], new: &[Segment]) -> Option<Span> {
    let n = old.len().min(new.len());
    let head = (0..n).take_while(|&i| old[i] == new[i]).count();
    if head == old.len() && head == new.len() {
        return None;
    }
    let tail = (0..n - head)
        .take_while(|&i| old[old.len() - 1 - i] == new[new.len() - 1 - i])
        .count();
    let first = |v: &[Segment]| v.get(head).map_or(f64::INFINITY, |s| s.t0);
    let last = |v: &[Segment]| {
        if v.len() > head + tail {
            v[v.len() - 1 - tail].t1
        } else {
            f64::NEG_INFINITY
        }
    };
    let (start, end) = (first(old).min(first(new)), last(old).max(last(new)));
    Some((start.min(end), start.max(end)))
}

/// The closest encounter of walkers `a` and `b` (or `a` with its own copies a period or more
/// later when `a == b`), if they ever coexist within reach (2r) of each other.
fn pair(tracks: &Tracks, a: usize, b: usize, patch: &Patch) -> Option<Encounter> {
    pair_in(tracks, a, b, patch, ALWAYS, ALWAYS)
}

/// [`pair`], over the pieces of `a` that overlap `wa` (in `a`'s time) and of `b` that overlap
/// `wb` (in `b`'s own time) only.
fn pair_in(
    tracks: &Tracks,
    a: usize,
    b: usize,
    patch: &Patch,
    wa: Span,
    wb: Span,
) -> Option<Encounter> {
    let period = patch.period_s;
    let (sa, sb) = (tracks.get(a), tracks.get(b));
    let (a0, a1) = (sa.first()?.t0, sa.last()?.t1);
    let (b0, b1) = (sb.first()?.t0, sb.last()?.t1);
    // Broad phase: walkers whose whole paths stay farther apart than they need never meet.
    let reach = 2.0 * patch.radius_m;
    let ((amin, amax), (bmin, bmax)) = (tracks.boxes[a], tracks.boxes[b]);
    let gap = (bmin - amax).max(amin - bmax).max(DVec2::ZERO);
    if gap.length() > reach {
        return None;
    }
    // Copies of b that overlap a in time: b shifted by k periods.
    let mut best: Option<(f64, f64, f64)> = None;
    for k in geometry::copies((a0, a1), (b0, b1), period) {
        if b == a && k <= 0 {
            continue;
        }
        let shift = k as f64 * period;
        // Both paths run forward in time: one sweep visits every pair of segments that
        // overlap in time, from the first moment both exist to the last.
        let lo = a0.max(b0 + shift).max(wa.0).max(wb.0 + shift);
        let hi = a1.min(b1 + shift).min(wa.1).min(wb.1 + shift);
        if lo > hi {
            continue;
        }
        let mut i = sa.partition_point(|s| s.t1 < lo);
        let mut j = sb.partition_point(|s| s.t1 + shift < lo);
        while i < sa.len() && j < sb.len() && sa[i].t0 <= hi && sb[j].t0 + shift <= hi {
            let x = sb[j].shifted(shift);
            // Two pieces whose boxes are farther apart than the closest so far (or than reach)
            // cannot bring it down: most pairs end here, without the exact approach.
            let limit = best.map_or(reach, |(bd, _, _)| bd.min(reach));
            let (lo_a, hi_a) = (sa[i].p0.min(sa[i].p1), sa[i].p0.max(sa[i].p1));
            let (lo_b, hi_b) = (x.p0.min(x.p1), x.p0.max(x.p1));
            let gap = (lo_b - hi_a).max(lo_a - hi_b).max(DVec2::ZERO);
            if gap.length_squared() <= limit * limit
                && let Some((d, t)) = geometry::closest(&sa[i], &x)
                && best.is_none_or(|(bd, _, _)| d < bd)
            {
                best = Some((d, t, shift));
            }
            if sa[i].t1 <= x.t1 {
                i += 1;
            } else {
                j += 1;
            }
        }
    }
    // Pairs never within reach have no entry: only a collision matters to the repair.
    best.filter(|&(d, _, _)| d < reach)
        .map(|(d, t, shift)| Encounter {
            margin: d - 2.0 * patch.radius_m,
            distance: d,
            t,
            a,
            other: Other::Walker { b, shift },
        })
}

/// The corners of the box that holds a path.
fn bounds(segs: &[Segment]) -> (DVec2, DVec2) {
    segs.iter().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(lo, hi), s| (lo.min(s.p0).min(s.p1), hi.max(s.p0).max(s.p1)),
    )
}

/// Every encounter within reach in a patch, by walker: row `a` holds walker `a`'s encounters
/// with every later walker (and its own later copies), with the standers and the obstacles.
pub fn rows(tracks: &Tracks, patch: &Patch) -> Vec<Vec<Encounter>> {
    (0..tracks.len()).map(|a| row(tracks, a, patch)).collect()
}

/// Brings [`rows`] up to date after the paths of the walkers `touched` changed (through
/// [`Tracks::set`]): their own rows anew, and in every other row only the entries with them.
///
/// Exact, but cheap: where a pair's closest encounter lies outside the span over which one
/// walker changed, it still stands, and only the changed span can bring it down.
pub fn refresh(rows: &mut [Vec<Encounter>], tracks: &mut Tracks, touched: &[usize], patch: &Patch) {
    let changed = |p: usize| tracks.changed[p].unwrap_or(ALWAYS);
    let outside = |t: f64, (lo, hi): Span| t < lo - 1e-9 || t > hi + 1e-9;
    // The pair (a, b) after one of them, `moved`, changed over `span`.
    let update = |old: Option<Encounter>, a: usize, b: usize, a_moved: bool| {
        let span = changed(if a_moved { a } else { b });
        let (wa, wb) = if a_moved {
            (span, ALWAYS)
        } else {
            (ALWAYS, span)
        };
        match old {
            Some(e) => {
                let Other::Walker { shift, .. } = e.other else {
                    unreachable!("a walker entry")
                };
                let when = if a_moved { e.t } else { e.t - shift };
                if outside(when, span) {
                    match pair_in(tracks, a, b, patch, wa, wb) {
                        Some(n) if n.distance < e.distance => Some(n),
                        _ => Some(e),
                    }
                } else {
                    pair(tracks, a, b, patch)
                }
            }
            None => pair_in(tracks, a, b, patch, wa, wb),
        }
    };
    let entry = |encounters: &[Encounter], b: usize| {
        encounters
            .iter()
            .find(|e| matches!(e.other, Other::Walker { b: x, .. } if x == b))
            .copied()
    };
    for (a, encounters) in rows.iter_mut().enumerate() {
        if touched.contains(&a) {
            let mut fresh: Vec<Encounter> = (a..tracks.len())
                .filter_map(|b| {
                    if b == a || touched.contains(&b) {
                        pair(tracks, a, b, patch)
                    } else {
                        update(entry(encounters, b), a, b, true)
                    }
                })
                .collect();
            fresh.extend(fixed_row(tracks, a, patch));
            *encounters = fresh;
        } else {
            for &b in touched.iter().filter(|&&b| b > a) {
                let old = entry(encounters, b);
                encounters.retain(|e| !matches!(e.other, Other::Walker { b: x, .. } if x == b));
                encounters.extend(update(old, a, b, false));
            }
        }
    }
    for &p in touched {
        tracks.changed[p] = None;
    }
}

/// Every encounter of walker `a` with walkers `b >= a`, standers and obstacles.
fn row(tracks: &Tracks, a: usize, patch: &Patch) -> Vec<Encounter> {
    let mut out: Vec<Encounter> = (a..tracks.len())
        .filter_map(|b| pair(tracks, a, b, patch))
        .collect();
    out.extend(fixed_row(tracks, a, patch));
    out
}

/// Every encounter of walker `a` with the standers and the obstacles.
fn fixed_row(tracks: &Tracks, a: usize, patch: &Patch) -> Vec<Encounter> {
    let r = patch.radius_m;
    let mut out = Vec::new();
    for (s, &q) in patch.standers.iter().enumerate() {
        let best = tracks
            .get(a)
            .iter()
            .filter_map(|sa| geometry::closest(sa, &Segment::standing(q, sa.t0, sa.t1)))
            .min_by(|x, y| x.0.total_cmp(&y.0));
        if let Some((d, t)) = best {
            out.push(Encounter {
                margin: d - 2.0 * r,
                distance: d,
                t,
                a,
                other: Other::Stander(s),
            });
        }
    }
    for (o, rect) in patch.obstacles.iter().enumerate() {
        let best = tracks
            .get(a)
            .iter()
            .map(|sa| geometry::to_rect(sa, rect.min, rect.max))
            .min_by(|x, y| x.0.total_cmp(&y.0));
        if let Some((d, t, _)) = best {
            out.push(Encounter {
                margin: d - r,
                distance: d,
                t,
                a,
                other: Other::Obstacle(o),
            });
        }
    }
    out
}

/// Removes collisions from the walkers of one patch. Boundary points never move (the paths'
/// anchors cannot); free points move within the patch and out of obstacles.
pub fn remove_collisions(
    paths: &mut [Path],
    patch: &Patch,
    max_iterations: u32,
    rng: &mut ChaCha8Rng,
) -> Outcome {
    for path in paths.iter_mut() {
        for f in &mut path.free {
            f.pos = patch.keep_inside(f.pos);
        }
    }
    let walls = patch.walls();
    let mut tracks = Tracks::new(paths.iter().map(Path::segments).collect());
    let mut rows = rows(&tracks, patch);
    let worst = |rows: &[Vec<Encounter>]| {
        rows.iter()
            .flatten()
            .copied()
            .min_by(|x, y| x.margin.total_cmp(&y.margin))
    };
    let mut iterations = 0;
    loop {
        let w = worst(&rows);
        let Some(w) = w.filter(|w| w.margin < 0.0) else {
            return Outcome {
                iterations,
                worst: w.filter(|w| w.margin < 0.0),
            };
        };
        if iterations >= max_iterations {
            return Outcome {
                iterations,
                worst: Some(w),
            };
        }
        iterations += 1;
        let touched = push_apart(paths, &tracks, patch, &w, rng);
        for &p in &touched {
            paths[p].reroute(&walls, patch.radius_m, patch.side_m);
        }
        for &p in &touched {
            tracks.set(p, paths[p].segments());
        }
        refresh(&mut rows, &mut tracks, &touched, patch);
    }
}

/// Applies eq. 5-7 to the encounter: the two points at the moment of closest approach are
/// pushed apart by the clearance they need, shared by speed (the faster walker moves less), a
/// small random rotation against endless loops, and no push that would leave the patch or
/// enter an obstacle. Returns the walkers whose paths changed.
fn push_apart(
    paths: &mut [Path],
    tracks: &Tracks,
    patch: &Patch,
    e: &Encounter,
    rng: &mut ChaCha8Rng,
) -> Vec<usize> {
    let r = patch.radius_m;
    let window = 0.25;
    let pa = paths[e.a].position(e.t);
    let (q, need, other_walker) = match e.other {
        Other::Walker { b, shift } => (
            paths[b].position(e.t - shift),
            2.0 * r,
            Some((b, e.t - shift)),
        ),
        Other::Stander(s) => (patch.standers[s], 2.0 * r, None),
        Other::Obstacle(o) => {
            let rect = patch.obstacles[o];
            let q = pa.clamp(rect.min, rect.max);
            if q == pa {
                // Inside the obstacle: out through the nearest edge.
                let exits = [
                    (pa.x - rect.min.x, DVec2::NEG_X),
                    (rect.max.x - pa.x, DVec2::X),
                    (pa.y - rect.min.y, DVec2::NEG_Y),
                    (rect.max.y - pa.y, DVec2::Y),
                ];
                let (depth, out) = exits
                    .into_iter()
                    .min_by(|a, b| a.0.total_cmp(&b.0))
                    .expect("four");
                (pa - out * (depth + 1e-6), r + depth, None)
            } else {
                (q, r, None)
            }
        }
    };
    let mut dir = (pa - q).normalize_or_zero();
    if dir == DVec2::ZERO {
        let angle = rng.random_range(0.0..std::f64::consts::TAU);
        dir = DVec2::new(angle.cos(), angle.sin());
    }
    let (ua, ub) = match other_walker {
        Some((b, tb)) => (paths[e.a].speed(e.t), paths[b].speed(tb)),
        None => (0.0, 1.0),
    };
    // Shares by speed (eq. 6); a walker held by its anchor at that moment cannot take any.
    let a_free = paths[e.a].movable_at(e.t, window);
    let b_free = other_walker.is_some_and(|(b, tb)| paths[b].movable_at(tb, window));
    let share_a = match (other_walker.is_some(), a_free, b_free) {
        (false, _, _) => 1.0,
        (true, true, false) => 1.0,
        (true, false, true) => 0.0,
        _ if ua + ub > 1e-9 => ub / (ua + ub),
        _ => 0.5,
    };
    // Push by the missing clearance plus a little, at least a tenth of the clearance.
    let missing = match e.other {
        Other::Obstacle(_) => need - (pa - q).length().min(e.distance),
        _ => need - e.distance,
    };
    let push = (missing + 0.05).max(0.1 * need);
    let keep_inside = |p: DVec2| patch.keep_inside(p);
    let clear = |p: DVec2| {
        !patch
            .obstacles
            .iter()
            .any(|o| (p.clamp(o.min, o.max) - p).length() < r)
    };
    // A third of the time, a walker of the pair first tries to pass earlier or later instead.
    if let Some((b, tb)) = other_walker
        && rng.random_bool(1.0 / 3.0)
        && let Some(p) = time_move(paths, tracks, patch, e, (b, tb), push, window)
    {
        return vec![p];
    }
    let mut moves = vec![(e.a, e.t, dir, share_a)];
    if let Some((b, tb)) = other_walker {
        moves.push((b, tb, -dir, 1.0 - share_a));
    }
    let mut touched = Vec::new();
    for (p, t, d, share) in moves {
        if share <= 0.0 {
            continue;
        }
        // A walker caught pausing moves its whole pause to the clearest spot for its duration:
        // pushing one moment of a long pause only makes it zigzag.
        let phi = rng.random_range(-0.5..0.5);
        let force = DVec2::from_angle(phi).rotate(d) * push * share;
        if let Some(pause) = paths[p].pause_at(t) {
            // Else the walker steps aside for the part of the pause around the encounter (a
            // bend inside it would end the pause).
            if !relocate_pause(paths, p, pause, patch, (tracks, &touched)) {
                paths[p].split_pause(pause, t, force, keep_inside, clear);
            }
            touched.push(p);
            continue;
        }
        // Moved or not, a new free point may have been added: the row is recomputed.
        paths[p].push_at(t, force, window, keep_inside, clear);
        touched.push(p);
    }
    touched.sort_unstable();
    touched.dedup();
    touched
}

/// The best time move for the pair of `e` (either walker reaching the point of the encounter
/// `push` metres' walk earlier or later), applied if it leaves the two farther apart than
/// they are; returns the walker it moved.
fn time_move(
    paths: &mut [Path],
    tracks: &Tracks,
    patch: &Patch,
    e: &Encounter,
    (b, tb): (usize, f64),
    push: f64,
    window: f64,
) -> Option<usize> {
    let a = e.a;
    let mut best: Option<(f64, usize, Path)> = None;
    for (p, t) in [(a, e.t), (b, tb)] {
        let speed = paths[p].speed(t).max(0.3);
        for sign in [1.0, -1.0] {
            let mut moved = paths[p].clone();
            if !moved.retime_at(t, sign * push / speed, window, crate::path::MAX_WALK_SPEED) {
                continue;
            }
            // Only the moved walker's pieces change; the other's are the row's own.
            let (sa, sb) = if p == a {
                (moved.segments(), tracks.get(b).to_vec())
            } else {
                (tracks.get(a).to_vec(), moved.segments())
            };
            let two = Tracks::new(if a == b { vec![sa] } else { vec![sa, sb] });
            let distance =
                pair(&two, 0, (a != b) as usize, patch).map_or(f64::INFINITY, |x| x.distance);
            if distance > e.distance + 1e-3 && best.as_ref().is_none_or(|x| distance > x.0) {
                best = Some((distance, p, moved));
            }
        }
    }
    let (_, p, moved) = best?;
    paths[p] = moved;
    Some(p)
}

/// Moves the pause `(i, j)` of walker `p` to the spot of the patch that stays farthest from
/// every other walker (and stander and obstacle) during the pause, if that is farther than
/// where it is. Returns whether it moved. `tracks` holds everyone's pieces except those of the
/// walkers `moved` in this push, whose paths have changed since.
fn relocate_pause(
    paths: &mut [Path],
    p: usize,
    (i, j): (usize, usize),
    patch: &Patch,
    (tracks, moved): (&Tracks, &[usize]),
) -> bool {
    let r = patch.radius_m;
    let (t0, t1) = (paths[p].free[i].t, paths[p].free[j].t);
    let here = paths[p].free[i].pos;
    // Where everyone else is during the pause, sampled every 0.2 s.
    let mut others: Vec<DVec2> = patch.standers.to_vec();
    let steps = ((t1 - t0) / 0.2).ceil().max(1.0) as usize;
    for (b, path) in paths.iter().enumerate() {
        // Everywhere the walker is near the patch: its bands and their ghosts too.
        let segs: std::borrow::Cow<[Segment]> = if moved.contains(&b) {
            path.segments().into()
        } else {
            tracks.get(b).into()
        };
        let (Some(first), Some(last)) = (segs.first(), segs.last()) else {
            continue;
        };
        let (b0, b1) = (first.t0, last.t1);
        for k in geometry::copies((t0, t1), (b0, b1), patch.period_s) {
            if b == p && k == 0 {
                continue;
            }
            let shift = k as f64 * patch.period_s;
            for s in 0..=steps {
                let t = t0 + (t1 - t0) * s as f64 / steps as f64 - shift;
                if t >= b0 && t <= b1 {
                    others.extend(geometry::at_time(&segs, t));
                }
            }
        }
    }
    let clearance = |q: DVec2| {
        // Distance from the nearest wall plus a radius, as if the wall were a walker's centre
        // a radius away from it; a spot inside or within a radius of a wall is never chosen.
        let walls = patch
            .obstacles
            .iter()
            .map(|o| {
                let d = (q.clamp(o.min, o.max) - q).length();
                if d < r + 0.05 {
                    f64::NEG_INFINITY
                } else {
                    d + r
                }
            })
            .fold(f64::INFINITY, f64::min);
        others.iter().map(|o| o.distance(q)).fold(walls, f64::min)
    };
    // Only spots the walker can reach and leave without walking faster than it may.
    // From where the walker comes and to where it goes: the band ends, not the border points,
    // when the pause is the first or last thing it does in the patch.
    let path = &paths[p];
    let (before, after) = path.neighbours(i, j);
    // The pause may start later and end sooner to leave time for the walk (a time move).
    // Points inside the pause (where it passes the period) keep their times: the walker must
    // be there by the first of them and stay until the last.
    let inner = (i + 1 < j).then(|| (path.free[i + 1].t, path.free[j - 1].t));
    let times = |q: DVec2| {
        let start = t0.max(before.1 + before.0.distance(q) / WALK_SPEED);
        let end = t1.min(after.1 - q.distance(after.0) / WALK_SPEED);
        let holds = inner.is_none_or(|(a, b)| start <= a && end >= b);
        (start <= end && holds).then_some((start, end))
    };
    // ... and in a straight line, clear of every wall (never into a part a wall cuts off).
    let clear_walk = |a: DVec2, b: DVec2| {
        let walk = Segment {
            p0: a,
            t0: 0.0,
            p1: b,
            t1: 1.0,
        };
        patch
            .obstacles
            .iter()
            .all(|o| geometry::to_rect(&walk, o.min, o.max).0 >= r)
    };
    let reachable =
        |q: DVec2| times(q).is_some() && clear_walk(before.0, q) && clear_walk(q, after.0);
    let margin = r + 0.3;
    let n = 9;
    let best = (0..n * n)
        .map(|k| {
            let f = |i: usize| margin + (patch.side_m - 2.0 * margin) * i as f64 / (n - 1) as f64;
            DVec2::new(f(k % n), f(k / n))
        })
        .filter(|&q| reachable(q))
        .map(|q| (clearance(q), q))
        .max_by(|a, b| a.0.total_cmp(&b.0));
    let Some(best) = best else { return false };
    if best.0 <= clearance(here) + 1e-9 {
        return false;
    }
    let (start, end) = times(best.1).expect("a reachable spot");
    let path = &mut paths[p];
    for f in &mut path.free[i..=j] {
        f.pos = best.1;
    }
    path.free[i].t = start;
    path.free[j].t = end;
    true
}
