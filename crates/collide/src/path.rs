//! A walker's path with boundary points that cannot move: the type has no way to move them.
//!
//! Neither can the ends of its border bands: from a boundary point to its band end the walker
//! walks straight at the crossing velocity, as stage 4 drew it from the patterns. The path's
//! [`Path::segments`] add the band pieces the walker walks in the neighbouring patch (its
//! ghosts: the same straight walk before the entry and after the exit), so that the encounters
//! of this patch include everyone near its borders.

use crowd_geometry::{Segment, at_time, entry_ghost, exit_ghost};

// Where stage 5's callers found it before it moved to the shared geometry.
use crowd_core::trajectories::{ControlPoint, PointKind, Trajectory};
pub use crowd_geometry::trajectory_segments;
use glam::DVec2;

/// An entry or exit point, fixed by the patterns. Its fields are private and it has no
/// method that changes it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Anchor {
    pos: DVec2,
    t: f64,
}

impl Anchor {
    pub fn pos(&self) -> DVec2 {
        self.pos
    }

    pub fn t(&self) -> f64 {
        self.t
    }
}

/// The shortest time a piece of a re-timed walk takes, s: points keep strictly increasing
/// times.
const MIN_PIECE_S: f64 = 1e-3;

/// No bend is made closer than this (seconds) to a split point: export drops a keyframe that
/// the walk passes within `export.simplify_mm` of, so a corner a moment from the period would
/// be a corner at the loop seam.
const SPLIT_GAP_S: f64 = 0.05;

/// A control point between the anchors, free to move in space (its time stays).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Free {
    pub pos: DVec2,
    pub t: f64,
    pub kind: PointKind,
}

/// A trajectory as stage 5 edits it.
#[derive(Debug, Clone, PartialEq)]
pub struct Path {
    entry: Anchor,
    exit: Anchor,
    /// The fixed points of the entry's border band (split points on it, then its end), if
    /// the trajectory has one; likewise the exit's (its start, then split points).
    entry_band: Vec<(Anchor, PointKind)>,
    exit_band: Vec<(Anchor, PointKind)>,
    /// Sorted by time, strictly between the band ends' times.
    pub free: Vec<Free>,
    pub entry_crossing: u32,
    pub exit_crossing: u32,
}

impl Path {
    pub fn from_trajectory(tr: &Trajectory) -> Path {
        let n = tr.points.len();
        let (first, last) = (tr.points[0], tr.points[n - 1]);
        let anchor = |p: &ControlPoint| Anchor { pos: p.pos, t: p.t };
        let (e, x) = crowd_core::trajectories::band_ends(&tr.points);
        let fixed = |range: std::ops::Range<usize>| -> Vec<(Anchor, PointKind)> {
            tr.points[range]
                .iter()
                .map(|p| (anchor(p), p.kind))
                .collect()
        };
        let entry_band = e.map_or_else(Vec::new, |e| fixed(1..e + 1));
        let exit_band = x.map_or_else(Vec::new, |x| fixed(x..n - 1));
        let inner = e.map_or(1, |e| e + 1)..x.unwrap_or(n - 1);
        let mut path = Path {
            entry: anchor(&first),
            exit: anchor(&last),
            entry_band,
            exit_band,
            free: tr.points[inner]
                .iter()
                .map(|p| Free {
                    pos: p.pos,
                    t: p.t,
                    kind: p.kind,
                })
                .collect(),
            entry_crossing: tr.entry,
            exit_crossing: tr.exit,
        };
        path.settle_splits();
        path
    }

    pub fn to_trajectory(&self) -> Trajectory {
        let fixed = |a: &Anchor, kind| ControlPoint {
            pos: a.pos,
            t: a.t,
            kind,
        };
        let mut points = vec![fixed(&self.entry, PointKind::Entry)];
        points.extend(self.entry_band.iter().map(|(a, k)| fixed(a, *k)));
        points.extend(self.free.iter().map(|f| ControlPoint {
            pos: f.pos,
            t: f.t,
            kind: f.kind,
        }));
        points.extend(self.exit_band.iter().map(|(a, k)| fixed(a, *k)));
        points.push(fixed(&self.exit, PointKind::Exit));
        Trajectory {
            entry: self.entry_crossing,
            exit: self.exit_crossing,
            points,
        }
    }

    pub fn entry(&self) -> Anchor {
        self.entry
    }

    pub fn exit(&self) -> Anchor {
        self.exit
    }

    /// The straight pieces of the path in time order, with the band pieces it walks in the
    /// neighbouring patches before its entry and after its exit (see
    /// [`crowd_geometry::ghosts`]).
    pub fn segments(&self) -> Vec<Segment> {
        let mut out = Vec::new();
        self.segments_into(&mut out);
        out
    }

    /// [`Path::segments`] written into `out` (cleared first), the same pieces as
    /// [`crowd_geometry::ghosts`] makes of the path's points, without a list of points:
    /// positions and speeds are asked for several times a push.
    pub fn segments_into(&self, out: &mut Vec<Segment>) {
        let at = |a: &Anchor| (a.pos, a.t);
        let points = std::iter::once(at(&self.entry))
            .chain(self.entry_band.iter().map(|(a, _)| at(a)))
            .chain(self.free.iter().map(|f| (f.pos, f.t)))
            .chain(self.exit_band.iter().map(|(a, _)| at(a)))
            .chain(std::iter::once(at(&self.exit)));
        out.clear();
        out.reserve(self.entry_band.len() + self.free.len() + self.exit_band.len() + 3);
        let entry_band = self.entry_band.last().map(|(a, _)| at(a));
        let exit_band = self.exit_band.first().map(|(a, _)| at(a));
        if let Some(band) = entry_band {
            out.push(entry_ghost(at(&self.entry), band));
        }
        let mut last: Option<(DVec2, f64)> = None;
        for (p1, t1) in points {
            if let Some((p0, t0)) = last {
                out.push(Segment { p0, t0, p1, t1 });
            }
            last = Some((p1, t1));
        }
        if let Some(band) = exit_band {
            out.push(exit_ghost(at(&self.exit), band));
        }
    }

    /// Runs `f` on the path's [`Path::segments`], kept in a buffer of the thread.
    fn with_segments<R>(&self, f: impl FnOnce(&[Segment]) -> R) -> R {
        thread_local! {
            static SCRATCH: std::cell::RefCell<Vec<Segment>> = const { std::cell::RefCell::new(Vec::new()) };
        }
        SCRATCH.with(|cell| {
            let mut segs = cell.take();
            self.segments_into(&mut segs);
            let r = f(&segs);
            cell.replace(segs);
            r
        })
    }

    /// The part of the path that may change: between the band ends (or the anchors, for a path
    /// without bands).
    pub fn span(&self) -> (f64, f64) {
        let (start, end) = self.fixed_ends();
        (start.t, end.t)
    }

    /// Where the changeable part starts and ends.
    pub fn fixed_ends(&self) -> (Anchor, Anchor) {
        (
            self.entry_band.last().map_or(self.entry, |b| b.0),
            self.exit_band.first().map_or(self.exit, |b| b.0),
        )
    }

    pub fn position(&self, t: f64) -> DVec2 {
        self.with_segments(|segs| at_time(segs, t).unwrap_or(self.entry.pos))
    }

    /// Speed around time `t`.
    pub fn speed(&self, t: f64) -> f64 {
        self.with_segments(|segs| {
            segs.iter()
                .find(|s| t <= s.t1)
                .map_or(0.0, |s| s.velocity().length())
        })
    }

    /// The pause the walker is in at time `t`, as the indices of its two pause points (with
    /// only points at the same place between them: split points, where a pause passes the
    /// period). A moment within 0.05 s of the pause counts: closest approaches are often
    /// found at its ends, to within rounding.
    pub fn pause_at(&self, t: f64) -> Option<(usize, usize)> {
        const NEAR: f64 = 0.05;
        let f = &self.free;
        (0..f.len()).find_map(|i| {
            if f[i].kind != PointKind::Pause || f[i].t > t + NEAR {
                return None;
            }
            let j = (i + 1..f.len())
                .take_while(|&j| f[j].pos.distance(f[i].pos) < 1e-9)
                .find(|&j| f[j].kind == PointKind::Pause)?;
            (t <= f[j].t + NEAR).then_some((i, j))
        })
    }

    /// Moves the pause `(i, j)` (see [`Path::pause_at`]) whole by `force`, if `allowed`
    /// accepts where it ends, as [`Path::push_at`] moves one point. The walks to and from it
    /// stay under `max_speed`.
    pub fn push_pause(
        &mut self,
        (i, j): (usize, usize),
        force: DVec2,
        max_speed: f64,
        keep_inside: impl Fn(DVec2) -> DVec2,
        allowed: impl Fn(DVec2) -> bool,
    ) -> bool {
        let target = keep_inside(self.free[i].pos + force);
        let Some(target) = nearest_allowed(target, &keep_inside, &allowed) else {
            return false;
        };
        // The walks to and from the new spot keep to the speed limit: the pause starts later
        // and ends sooner if it must, but never past a point inside it.
        let (prev, next) = self.neighbours(i, j);
        let t0 = self.free[i]
            .t
            .max(prev.1 + prev.0.distance(target) / max_speed);
        let t1 = self.free[j]
            .t
            .min(next.1 - next.0.distance(target) / max_speed);
        let inner_ok = (i + 1 < j)
            .then(|| (self.free[i + 1].t, self.free[j - 1].t))
            .is_none_or(|(a, b)| t0 <= a && t1 >= b);
        if t0 >= t1 || !inner_ok {
            return false;
        }
        for f in &mut self.free[i..=j] {
            f.pos = target;
        }
        self.free[i].t = t0;
        self.free[j].t = t1;
        true
    }

    /// The points just before free point `i` and just after free point `j` that shape the
    /// walk (a band end or an anchor where there is no free point): split points lie on the
    /// walk between them ([`Path::settle_splits`]).
    pub fn neighbours(&self, i: usize, j: usize) -> ((DVec2, f64), (DVec2, f64)) {
        let (start, end) = self.fixed_ends();
        let shapes = |f: &&Free| f.kind != PointKind::Split;
        let prev = self.free[..i]
            .iter()
            .rev()
            .find(shapes)
            .map_or((start.pos, start.t), |f| (f.pos, f.t));
        let next = self
            .free
            .get(j + 1..)
            .and_then(|rest| rest.iter().find(shapes))
            .map_or((end.pos, end.t), |f| (f.pos, f.t));
        (prev, next)
    }

    /// Puts every free split point where the walk between the points around it passes at its
    /// time. A split point marks the period; it is never pushed, so that the walk has no
    /// corner at the loop seam, where a player hands a character from one node to the next.
    pub fn settle_splits(&mut self) {
        for i in 0..self.free.len() {
            if self.free[i].kind != PointKind::Split {
                continue;
            }
            let ((a, ta), (b, tb)) = self.neighbours(i, i);
            let t = self.free[i].t;
            self.free[i].pos = if a == b || tb <= ta {
                a
            } else {
                a.lerp(b, ((t - ta) / (tb - ta)).clamp(0.0, 1.0))
            };
        }
    }

    /// Steps aside during the pause `(i, j)`: the part of the pause from time `t` on (or up to
    /// `t`, when `t` is in its first half) moves by `force`, with a short walk from one spot to
    /// the other, so the walker waits at two spots. A pause too short to split moves whole
    /// ([`Path::push_pause`]). The walk to or from the part that moves stays under
    /// `max_speed`. Returns whether anything moved.
    pub fn split_pause(
        &mut self,
        (i, j): (usize, usize),
        t: f64,
        force: DVec2,
        max_speed: f64,
        keep_inside: impl Fn(DVec2) -> DVec2,
        allowed: impl Fn(DVec2) -> bool,
    ) -> bool {
        let (t0, t1, here) = (self.free[i].t, self.free[j].t, self.free[i].pos);
        let Some(there) = nearest_allowed(keep_inside(here + force), &keep_inside, &allowed) else {
            return false;
        };
        let walk = (here.distance(there) / 1.0).max(0.2);
        let later = t - t0 >= t1 - t;
        if t1 - t0 < 2.0 * walk + 2.0 {
            return self.push_pause((i, j), force, max_speed, keep_inside, allowed);
        }
        // Each part keeps at least a second, and the walk between them fits.
        let cut = if later {
            t.clamp(t0 + walk + 1.0, t1 - 1.0)
        } else {
            t.clamp(t0 + 1.0, t1 - walk - 1.0)
        };
        let (a, b) = if later {
            (cut - walk, cut)
        } else {
            (cut, cut + walk)
        };
        // The walk to or from the part that moves keeps to the speed limit.
        let (prev, next) = self.neighbours(i, j);
        let (mut t0, mut t1) = (t0, t1);
        if later {
            t1 = t1.min(next.1 - next.0.distance(there) / max_speed);
            if t1 < b + 0.5 || self.free[i..j].iter().any(|f| f.t > t1) {
                return false;
            }
        } else {
            t0 = t0.max(prev.1 + prev.0.distance(there) / max_speed);
            if t0 > a - 0.5 || self.free[i + 1..=j].iter().any(|f| f.t < t0) {
                return false;
            }
        }
        self.free[i].t = t0;
        self.free[j].t = t1;
        let (pos_a, pos_b) = if later { (here, there) } else { (there, here) };
        for f in &mut self.free[i..=j] {
            // A split point in the walk goes where the walker is then.
            f.pos = if f.t <= a {
                pos_a
            } else if f.t >= b {
                pos_b
            } else {
                pos_a.lerp(pos_b, (f.t - a) / (b - a))
            };
        }
        let pause = |pos, t| Free {
            pos,
            t,
            kind: PointKind::Pause,
        };
        // Each in its place in time (a split point of the walk lies between them).
        for (pos, t) in [(pos_b, b), (pos_a, a)] {
            let at = self.free.partition_point(|f| f.t < t);
            self.free.insert(at, pause(pos, t));
        }
        true
    }

    /// Whether the walker can be moved at time `t`: not within `window` of an anchor.
    pub fn movable_at(&self, t: f64, window: f64) -> bool {
        let (t0, t1) = self.span();
        t - t0 >= window && t1 - t >= window
    }

    /// Makes the walker reach where it is at time `t` `dt` seconds later (or sooner, for a
    /// negative `dt`): a time move, the walker slowing down or hurrying up along the same path
    /// (Ramirez's pushes move points in space only; two walkers whose paths cross can often
    /// only pass one after the other). The move is cut short so that the walker never walks
    /// faster than `max_speed` and its points keep their order; split points and pauses keep
    /// their times. Returns whether anything moved.
    pub fn retime_at(&mut self, t: f64, dt: f64, window: f64, max_speed: f64) -> bool {
        let Some(i) = self.free_point_at(t, window) else {
            return false;
        };
        let Free { pos, t: t0, kind } = self.free[i];
        if matches!(kind, PointKind::Split | PointKind::Pause) {
            return false;
        }
        let (prev, next) = self.neighbours(i, i);
        // Earliest and latest times that keep the order and the speed limit on both pieces.
        let lo = (prev.1 + prev.0.distance(pos) / max_speed).max(prev.1 + 0.05);
        let hi = (next.1 - next.0.distance(pos) / max_speed).min(next.1 - 0.05);
        // Nor past, or within SPLIT_GAP_S of, a split point next to it, whose time stays.
        let gap = |f: &Free| {
            if f.kind == PointKind::Split {
                SPLIT_GAP_S
            } else {
                0.0
            }
        };
        let lo = i
            .checked_sub(1)
            .map_or(lo, |k| lo.max(self.free[k].t + gap(&self.free[k])));
        let hi = self.free.get(i + 1).map_or(hi, |f| hi.min(f.t - gap(f)));
        if lo > hi {
            return false;
        }
        let moved = (t0 + dt).clamp(lo, hi);
        if (moved - t0).abs() < 1e-6 {
            return false;
        }
        self.free[i].t = moved;
        true
    }

    /// Moves the walker at time `t` by `force` (the free point at `t`, see
    /// [`Path::free_point_at`]), if `allowed` accepts where it ends and the walk still fits its
    /// time at `max_speed`. Returns whether it moved.
    pub fn push_at(
        &mut self,
        t: f64,
        force: DVec2,
        window: f64,
        max_speed: f64,
        keep_inside: impl Fn(DVec2) -> DVec2,
        allowed: impl Fn(DVec2) -> bool,
    ) -> bool {
        let Some(i) = self.free_point_at(t, window) else {
            return false;
        };
        let pos = self.free[i].pos;
        // Nor may it leave the walk too long for its time at `max_speed` (or longer than it
        // already was): [`Path::limit_speed`] then spreads the walk's time so that no piece is
        // faster. A bend needs no hurried piece where the walk has time to spare elsewhere.
        let run = self.run_around(i);
        let cost = run.cost(max_speed);
        let need = |p: DVec2| cost.least_time(p);
        let budget = run.time().max(need(pos));
        let walkable = |p: DVec2| need(p) <= budget + 1e-9;
        // A push towards the border slides along it instead; a push into an obstacle stops at
        // the nearest place clear of it.
        let target = keep_inside(pos + force);
        match nearest_allowed(target, &keep_inside, &|p| allowed(p) && walkable(p)) {
            Some(target) => {
                self.free[i].pos = target;
                true
            }
            None => false,
        }
    }

    /// Gives the walker one more period in the patch: its exit band and exit a period later
    /// (the same place, the same time modulo the period, so the tiling holds), the split
    /// points laid again. The walker then has time to let others pass first; the repair
    /// decides where it spends it. Returns whether it could (a path without room between its
    /// band ends cannot).
    pub fn add_period(&mut self, period: f64) -> bool {
        let tr = self.to_trajectory();
        let Some(x) = crowd_core::trajectories::band_ends(&tr.points).1 else {
            return false;
        };
        let exit_band_t = tr.points[x].t;
        let points: Vec<ControlPoint> = tr
            .points
            .iter()
            .filter(|p| p.kind != PointKind::Split)
            .map(|p| ControlPoint {
                t: if p.t >= exit_band_t {
                    p.t + period
                } else {
                    p.t
                },
                ..*p
            })
            .collect();
        let points = crowd_core::trajectories::split_at_periods(points, period);
        *self = Path::from_trajectory(&Trajectory { points, ..tr });
        true
    }

    /// The points that shape the walk from one fixed end to the other: (where, when, index in
    /// `free` or `None` for an end, whether its time is fixed). Split points are marks on the
    /// walk, not shape; pause points and the ends keep their times, the rest may be re-timed.
    fn shape(&self) -> Vec<(DVec2, f64, Option<usize>, bool)> {
        let (start, end) = self.fixed_ends();
        let mut shape = Vec::with_capacity(self.free.len() + 2);
        shape.push((start.pos, start.t, None, true));
        for (i, f) in self.free.iter().enumerate() {
            if f.kind != PointKind::Split {
                shape.push((f.pos, f.t, Some(i), f.kind == PointKind::Pause));
            }
        }
        shape.push((end.pos, end.t, None, true));
        shape
    }

    /// Whether a piece of [`Path::shape`] is faster than `max_speed` or runs back in time, as
    /// [`Path::limit_speed`] tests it: most walks need no re-timing, and this needs no list.
    fn any_too_fast(&self, max_speed: f64) -> bool {
        let (start, end) = self.fixed_ends();
        let shape = std::iter::once((start.pos, start.t))
            .chain(
                self.free
                    .iter()
                    .filter(|f| f.kind != PointKind::Split)
                    .map(|f| (f.pos, f.t)),
            )
            .chain(std::iter::once((end.pos, end.t)));
        let mut last: Option<(DVec2, f64)> = None;
        for (p, t) in shape {
            if let Some((q, s)) = last {
                let (l, d) = (q.distance(p), t - s);
                if l > max_speed * d + 1e-9 || d < 0.0 {
                    return true;
                }
            }
            last = Some((p, t));
        }
        false
    }

    /// The stretch of walk around free point `i` between the nearest points whose times are
    /// fixed.
    fn run_around(&self, i: usize) -> Run {
        let shape = self.shape();
        let k = shape
            .iter()
            .position(|s| s.2 == Some(i))
            .expect("a shape point");
        let a = (0..k)
            .rev()
            .find(|&j| shape[j].3)
            .expect("the start is fixed");
        let b = (k + 1..shape.len())
            .find(|&j| shape[j].3)
            .expect("the end is fixed");
        Run {
            points: shape[a..=b].iter().map(|s| s.0).collect(),
            at: k - a,
            t0: shape[a].1,
            t1: shape[b].1,
        }
    }

    /// Re-times the walk so that no piece is faster than `max_speed`: between two points whose
    /// times are fixed (the band ends, a pause's ends), the pieces too fast for their length
    /// get the time they need and the others give it up in proportion to their own, so that
    /// the walker takes a bend or a detour at walking pace and makes up the time where it
    /// has some to spare. Where a stretch is too long for its time at `max_speed`, the walker
    /// walks it at one speed, the least there is. Returns whether every stretch fits.
    pub fn limit_speed(&mut self, max_speed: f64) -> bool {
        if !self.any_too_fast(max_speed) {
            return true;
        }
        let mut shape = self.shape();
        let mut fits = true;
        let mut changed = false;
        let mut a = 0;
        while a + 1 < shape.len() {
            let b = (a + 1..shape.len())
                .find(|&j| shape[j].3)
                .expect("the end is fixed");
            let lengths: Vec<f64> = (a..b)
                .map(|j| shape[j].0.distance(shape[j + 1].0))
                .collect();
            let times: Vec<f64> = (a..b).map(|j| shape[j + 1].1 - shape[j].1).collect();
            let fast = |(l, d): (&f64, &f64)| *l > max_speed * d + 1e-9 || *d < 0.0;
            if lengths.iter().zip(&times).any(fast) {
                let (new, ok) = fit_times(&lengths, &times, shape[b].1 - shape[a].1, max_speed);
                fits &= ok;
                let mut t = shape[a].1;
                for (j, d) in (a + 1..b).zip(new) {
                    t += d;
                    shape[j].1 = t;
                }
                changed = true;
            }
            a = b;
        }
        if changed {
            for &(_, t, i, _) in &shape {
                if let Some(i) = i {
                    self.free[i].t = t;
                }
            }
            // Split points keep their times: the re-timed points go round them.
            self.free.sort_by(|x, y| x.t.total_cmp(&y.t));
            self.settle_splits();
        }
        fits
    }

    /// Sends every piece of the path that cuts through a static obstacle round it (the
    /// shortest way past the obstacles grown by `radius`, see `crowd_geometry::route`), keeping the
    /// times of the points it has: the corners share the piece's time by length.
    pub fn reroute(&mut self, obstacles: &[crowd_core::Rect], radius: f64, side: f64) {
        if obstacles.is_empty() {
            return;
        }
        let (start, end) = self.fixed_ends();
        // The walk's shape, without its split points (marks on it, put back after).
        let (splits, shape): (Vec<Free>, Vec<Free>) =
            self.free.iter().partition(|f| f.kind == PointKind::Split);
        let mut points: Vec<(DVec2, f64, Option<PointKind>)> =
            Vec::with_capacity(self.free.len() + 2);
        points.push((start.pos, start.t, None));
        points.extend(shape.iter().map(|f| (f.pos, f.t, Some(f.kind))));
        points.push((end.pos, end.t, None));
        let mut free = Vec::with_capacity(self.free.len());
        for w in points.windows(2) {
            let ((p0, t0, _), (p1, t1, kind1)) = (w[0], w[1]);
            let corners = crowd_geometry::route::route(p0, p1, obstacles, radius, side);
            if corners.len() > 2 {
                let length: f64 = corners.windows(2).map(|c| c[0].distance(c[1])).sum();
                let mut walked = 0.0;
                for c in corners.windows(2).take(corners.len() - 2) {
                    walked += c[0].distance(c[1]);
                    let t = t0 + (t1 - t0) * walked / length.max(1e-12);
                    // Out of the border bands, like every free point.
                    let edge = DVec2::splat(radius + 1e-3);
                    free.push(Free {
                        pos: c[1].clamp(edge, DVec2::splat(side) - edge),
                        t,
                        kind: PointKind::Detour,
                    });
                }
            }
            if let Some(kind) = kind1 {
                free.push(Free {
                    pos: p1,
                    t: t1,
                    kind,
                });
            }
        }
        for split in splits {
            let at = free.partition_point(|f| f.t <= split.t);
            free.insert(at, split);
        }
        self.free = free;
        self.settle_splits();
    }

    /// The index of the free point at time `t`: an existing one within `window` seconds, or a
    /// new one on the path. Near an anchor or band end (they never move) the point is taken
    /// `window` away from it; `None` when the changeable part is shorter than two windows or
    /// `t` is at a pause's end.
    pub fn free_point_at(&mut self, t: f64, window: f64) -> Option<usize> {
        let (t0, t1) = self.span();
        if t1 - t0 <= 2.0 * window {
            return None;
        }
        let t = t.clamp(t0 + window, t1 - window);
        // A pause's ends stay where the pause is: a bend at the same moment would be a jump.
        if self
            .free
            .iter()
            .any(|f| f.kind == PointKind::Pause && (f.t - t).abs() < 0.05)
        {
            return None;
        }
        // Nor at the period: a bend within SPLIT_GAP_S of a split point is taken that far
        // from it (on the same side), so that the walk has no corner at the loop seam.
        let near_split = |t: f64| {
            self.free
                .iter()
                .find(|f| f.kind == PointKind::Split && (f.t - t).abs() < SPLIT_GAP_S)
                .map(|f| f.t)
        };
        let t = match near_split(t) {
            Some(s) if t >= s => s + SPLIT_GAP_S,
            Some(s) => s - SPLIT_GAP_S,
            None => t,
        };
        if t < t0 + window || t > t1 - window || near_split(t).is_some() {
            return None;
        }
        if let Some(i) = self
            .free
            .iter()
            .enumerate()
            .filter(|(_, f)| {
                (f.t - t).abs() <= window
                    && !matches!(f.kind, PointKind::Pause | PointKind::Split)
                    && near_split(f.t).is_none()
            })
            .min_by(|a, b| (a.1.t - t).abs().total_cmp(&(b.1.t - t).abs()))
            .map(|(i, _)| i)
        {
            return Some(i);
        }
        let pos = self.position(t);
        let at = self.free.partition_point(|f| f.t < t);
        self.free.insert(
            at,
            Free {
                pos,
                t,
                kind: PointKind::Bend,
            },
        );
        Some(at)
    }
}

/// A stretch of walk between two points whose times are fixed, with one point that may move.
struct Run {
    points: Vec<DVec2>,
    at: usize,
    t0: f64,
    t1: f64,
}

impl Run {
    fn time(&self) -> f64 {
        self.t1 - self.t0
    }

    /// What [`RunCost::least_time`] needs: the pieces that do not touch the moving point
    /// measured once (a push tries up to 320 places for it).
    fn cost(&self, max_speed: f64) -> RunCost {
        let n = self.points.len();
        let piece = |j: usize| piece_time(self.points[j - 1], self.points[j], max_speed);
        RunCost {
            before: (1..self.at.min(n)).map(piece).sum(),
            after: (self.at + 2..n).map(piece).collect(),
            prev: self.at.checked_sub(1).map(|j| self.points[j]),
            next: self.points.get(self.at + 1).copied(),
            max_speed,
        }
    }
}

/// The least time of a piece from `a` to `b` at `max_speed` (and [`MIN_PIECE_S`]).
fn piece_time(a: DVec2, b: DVec2, max_speed: f64) -> f64 {
    (a.distance(b) / max_speed).max(MIN_PIECE_S)
}

/// A [`Run`] measured for [`RunCost::least_time`]: the sum of the pieces before the moving
/// point, and the pieces after it, added in the same order as a sum over the whole stretch
/// (so the same bits).
struct RunCost {
    before: f64,
    after: Vec<f64>,
    prev: Option<DVec2>,
    next: Option<DVec2>,
    max_speed: f64,
}

impl RunCost {
    /// The least time the stretch takes with its point moved to `p`.
    fn least_time(&self, p: DVec2) -> f64 {
        let mut sum = self.before;
        if let Some(a) = self.prev {
            sum += piece_time(a, p, self.max_speed);
        }
        if let Some(b) = self.next {
            sum += piece_time(p, b, self.max_speed);
        }
        self.after.iter().fold(sum, |s, x| s + x)
    }
}

/// New times for pieces of `lengths` that took `times` and must take `total` together: each at
/// least its length at `max_speed` (and [`MIN_PIECE_S`]); the rest of the time shared in
/// proportion to the times they took (water-filling: a piece that its share leaves too fast
/// gets its least time, and the others share what is left). When the least times add up to
/// more than `total`, every piece at one speed; the flag says whether the times fit.
fn fit_times(lengths: &[f64], times: &[f64], total: f64, max_speed: f64) -> (Vec<f64>, bool) {
    let least: Vec<f64> = lengths
        .iter()
        .map(|l| (l / max_speed).max(MIN_PIECE_S))
        .collect();
    if least.iter().sum::<f64>() > total {
        let weight: Vec<f64> = lengths
            .iter()
            .map(|l| l + MIN_PIECE_S * max_speed)
            .collect();
        let sum: f64 = weight.iter().sum();
        return (weight.iter().map(|w| total * w / sum).collect(), false);
    }
    let mut pinned = vec![false; lengths.len()];
    loop {
        let spare = total
            - least
                .iter()
                .zip(&pinned)
                .filter(|(_, p)| **p)
                .map(|(l, _)| l)
                .sum::<f64>();
        let share: f64 = times
            .iter()
            .zip(&pinned)
            .filter(|(_, p)| !**p)
            .map(|(d, _)| d.max(0.0))
            .sum();
        let new: Vec<f64> = (0..lengths.len())
            .map(|j| {
                if pinned[j] {
                    least[j]
                } else if share > 0.0 {
                    spare * times[j].max(0.0) / share
                } else {
                    0.0
                }
            })
            .collect();
        let short: Vec<usize> = (0..lengths.len())
            .filter(|&j| !pinned[j] && new[j] < least[j])
            .collect();
        if short.is_empty() {
            return (new, true);
        }
        for j in short {
            pinned[j] = true;
        }
    }
}

/// The allowed place nearest `target`, searched on rings of growing radius (up to 2 m).
fn nearest_allowed(
    target: DVec2,
    keep_inside: &impl Fn(DVec2) -> DVec2,
    allowed: &impl Fn(DVec2) -> bool,
) -> Option<DVec2> {
    if allowed(target) {
        return Some(target);
    }
    static AROUND: std::sync::LazyLock<[DVec2; 16]> = std::sync::LazyLock::new(|| {
        std::array::from_fn(|k| DVec2::from_angle(k as f64 * std::f64::consts::TAU / 16.0))
    });
    (1..=20).find_map(|ring| {
        let radius = 0.1 * ring as f64;
        AROUND
            .iter()
            .map(|&d| keep_inside(target + d * radius))
            .find(|&p| allowed(p))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The least time measured once for all places of the moving point is the sum over
        /// the whole stretch, to the bit.
        #[test]
        fn a_runs_cost_is_its_whole_sum(
            xs in proptest::collection::vec((0.0f64..8.0, 0.0f64..8.0), 2..12),
            at in 0usize..12,
            (px, py) in (0.0f64..8.0, 0.0f64..8.0),
        ) {
            let points: Vec<DVec2> = xs.iter().map(|&(x, y)| DVec2::new(x, y)).collect();
            let at = at % points.len();
            let run = Run { points: points.clone(), at, t0: 0.0, t1: 10.0 };
            let p = DVec2::new(px, py);
            let moved = |j: usize| if j == at { p } else { points[j] };
            let whole: f64 = (1..points.len()).map(|j| piece_time(moved(j - 1), moved(j), 1.85)).sum();
            prop_assert_eq!(run.cost(1.85).least_time(p).to_bits(), whole.to_bits());
        }
    }
}
