//! A walker's path with boundary points that cannot move: the type has no way to move them.

use crate::geometry::Segment;
use crowd_core::trajectories::{ControlPoint, PointKind, Trajectory};
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
    /// Sorted by time, strictly between the anchors' times.
    pub free: Vec<Free>,
    pub entry_crossing: u32,
    pub exit_crossing: u32,
}

impl Path {
    pub fn from_trajectory(tr: &Trajectory) -> Path {
        let (first, last) = (tr.points[0], tr.points[tr.points.len() - 1]);
        Path {
            entry: Anchor {
                pos: first.pos,
                t: first.t,
            },
            exit: Anchor {
                pos: last.pos,
                t: last.t,
            },
            free: tr.points[1..tr.points.len() - 1]
                .iter()
                .map(|p| Free {
                    pos: p.pos,
                    t: p.t,
                    kind: p.kind,
                })
                .collect(),
            entry_crossing: tr.entry,
            exit_crossing: tr.exit,
        }
    }

    pub fn to_trajectory(&self) -> Trajectory {
        let mut points = vec![ControlPoint {
            pos: self.entry.pos,
            t: self.entry.t,
            kind: PointKind::Entry,
        }];
        points.extend(self.free.iter().map(|f| ControlPoint {
            pos: f.pos,
            t: f.t,
            kind: f.kind,
        }));
        points.push(ControlPoint {
            pos: self.exit.pos,
            t: self.exit.t,
            kind: PointKind::Exit,
        });
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

    /// The straight pieces of the path, in time order.
    pub fn segments(&self) -> Vec<Segment> {
        let (entry, exit) = ((self.entry.pos, self.entry.t), (self.exit.pos, self.exit.t));
        let free = self.free.iter().map(|f| (f.pos, f.t));
        crate::geometry::pieces(
            std::iter::once(entry)
                .chain(free)
                .chain(std::iter::once(exit)),
        )
    }

    pub fn span(&self) -> (f64, f64) {
        (self.entry.t, self.exit.t)
    }

    pub fn position(&self, t: f64) -> DVec2 {
        self.segments()
            .iter()
            .find(|s| t <= s.t1)
            .or(self.segments().last())
            .map_or(self.entry.pos, |s| s.at(t.clamp(s.t0, s.t1)))
    }

    /// Speed around time `t`.
    pub fn speed(&self, t: f64) -> f64 {
        self.segments()
            .iter()
            .find(|s| t <= s.t1)
            .map_or(0.0, |s| s.velocity().length())
    }

    /// The pause the walker is in at time `t`, as the indices of its two pause points.
    pub fn pause_at(&self, t: f64) -> Option<(usize, usize)> {
        self.free
            .windows(2)
            .position(|w| {
                w[0].kind == PointKind::Pause
                    && w[1].kind == PointKind::Pause
                    && w[0].pos == w[1].pos
                    && w[0].t <= t
                    && t <= w[1].t
            })
            .map(|i| (i, i + 1))
    }

    /// Whether the walker can be moved at time `t`: not within `window` of an anchor.
    pub fn movable_at(&self, t: f64, window: f64) -> bool {
        let (t0, t1) = self.span();
        t - t0 >= window && t1 - t >= window
    }

    /// Moves the walker at time `t` by `force` (the free point at `t`, see
    /// [`Path::free_point_at`]), if `allowed` accepts where it ends. Returns whether it moved.
    pub fn push_at(
        &mut self,
        t: f64,
        force: DVec2,
        window: f64,
        keep_inside: impl Fn(DVec2) -> DVec2,
        allowed: impl Fn(DVec2) -> bool,
    ) -> bool {
        match self.free_point_at(t, window) {
            Some(point) => {
                // A push towards the border slides along it instead; a push into an obstacle
                // stops at the nearest place clear of it.
                let target = keep_inside(point.pos + force);
                match nearest_allowed(target, &keep_inside, &allowed) {
                    Some(target) => {
                        point.pos = target;
                        true
                    }
                    None => false,
                }
            }
            None => false,
        }
    }

    /// Sends every piece of the path that cuts through a static obstacle round it (the
    /// shortest way past the obstacles grown by `radius`, see `crowd_match::route`), keeping the
    /// times of the points it has: the corners share the piece's time by length.
    pub fn reroute(&mut self, obstacles: &[crowd_core::Rect], radius: f64, side: f64) {
        if obstacles.is_empty() {
            return;
        }
        let mut points: Vec<(DVec2, f64, Option<PointKind>)> =
            Vec::with_capacity(self.free.len() + 2);
        points.push((self.entry.pos, self.entry.t, None));
        points.extend(self.free.iter().map(|f| (f.pos, f.t, Some(f.kind))));
        points.push((self.exit.pos, self.exit.t, None));
        let mut free = Vec::with_capacity(self.free.len());
        for w in points.windows(2) {
            let ((p0, t0, _), (p1, t1, kind1)) = (w[0], w[1]);
            let corners = crowd_match::route::route(p0, p1, obstacles, radius, side);
            if corners.len() > 2 {
                let length: f64 = corners.windows(2).map(|c| c[0].distance(c[1])).sum();
                let mut walked = 0.0;
                for c in corners.windows(2).take(corners.len() - 2) {
                    walked += c[0].distance(c[1]);
                    let t = t0 + (t1 - t0) * walked / length.max(1e-12);
                    free.push(Free {
                        pos: c[1],
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
        self.free = free;
    }

    /// The free point at time `t`: an existing one within `window` seconds, or a new one on
    /// the path. Near an anchor (anchors never move) the point is taken `window` away from it;
    /// `None` only when the whole path is shorter than two windows.
    pub fn free_point_at(&mut self, t: f64, window: f64) -> Option<&mut Free> {
        let (t0, t1) = self.span();
        if t1 - t0 <= 2.0 * window {
            return None;
        }
        let t = t.clamp(t0 + window, t1 - window);
        if let Some(i) = self
            .free
            .iter()
            .enumerate()
            .filter(|(_, f)| (f.t - t).abs() <= window && f.kind != PointKind::Pause)
            .min_by(|a, b| (a.1.t - t).abs().total_cmp(&(b.1.t - t).abs()))
            .map(|(i, _)| i)
        {
            return Some(&mut self.free[i]);
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
        Some(&mut self.free[at])
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
    (1..=20).find_map(|ring| {
        let radius = 0.1 * ring as f64;
        (0..16)
            .map(|k| {
                keep_inside(
                    target + DVec2::from_angle(k as f64 * std::f64::consts::TAU / 16.0) * radius,
                )
            })
            .find(|&p| allowed(p))
    })
}
