//! Playing a library: where every character is at a time, frame after frame.

use crate::format::{Library, TICK_S};

/// One character seen in a frame: world metres (x east, y north), heading in radians
/// counter-clockwise from east (the direction it walks, or last walked).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    pub id: u32,
    pub x: f32,
    pub y: f32,
    pub heading: f32,
}

/// Where one walking character is on its loop: the straight piece it walks now, in world
/// time and world space, so that a frame inside the piece is a multiply-add.
#[derive(Debug, Clone, Copy)]
struct Cursor {
    /// World-time span of the piece.
    t0: f64,
    t1: f64,
    x0: f32,
    y0: f32,
    vx: f32,
    vy: f32,
    heading: f32,
    /// The piece: points `point`, `point + 1` of trajectory `traj`.
    traj: u32,
    point: u32,
    /// World time at which `traj` started, for this character's current pass.
    traj_start: f64,
    character: u32,
    lap: u32,
}

/// Samples a library's characters. Walkers have ids `0 .. walkers` (loop by loop, lap by lap),
/// standers the ids after them.
#[derive(Debug, Clone)]
pub struct Sampler<'a> {
    lib: &'a Library,
    cursors: Vec<Cursor>,
    standers: Vec<Sample>,
}

impl<'a> Sampler<'a> {
    /// A sampler with every character placed at time 0.
    pub fn new(lib: &'a Library) -> Sampler<'a> {
        let mut cursors = Vec::with_capacity(lib.walkers() as usize);
        for (c, ch) in lib.characters.iter().enumerate() {
            for lap in 0..ch.laps {
                let mut cursor = Cursor {
                    t0: 0.0,
                    t1: 0.0,
                    x0: 0.0,
                    y0: 0.0,
                    vx: 0.0,
                    vy: 0.0,
                    heading: 0.0,
                    traj: ch.first_trajectory,
                    point: 0,
                    traj_start: 0.0,
                    character: c as u32,
                    lap,
                };
                seek(lib, &mut cursor, 0.0);
                cursors.push(cursor);
            }
        }
        let first_stander = cursors.len() as u32;
        let standers = lib
            .patches
            .iter()
            .flat_map(|p| {
                let first = p.first_stander as usize;
                lib.standers[first..first + p.standers as usize]
                    .iter()
                    .map(move |s| lib.world_position(p, *s))
            })
            .enumerate()
            .map(|(i, [x, y])| Sample {
                id: first_stander + i as u32,
                x: x as f32,
                y: y as f32,
                heading: 0.0,
            })
            .collect();
        Sampler {
            lib,
            cursors,
            standers,
        }
    }

    /// Walkers plus standers.
    pub fn characters(&self) -> usize {
        self.cursors.len() + self.standers.len()
    }

    /// Every character inside `view` (`[x0, y0, x1, y1]`, world metres, x0 <= x < x1 and
    /// y0 <= y < y1) at world time `t` seconds, into `out` (cleared first), in id order.
    /// Any `t` is allowed; moving forward by less than a piece costs no search.
    pub fn sample(&mut self, t: f64, view: [f32; 4], out: &mut Vec<Sample>) {
        out.clear();
        let lib = self.lib;
        for (id, c) in self.cursors.iter_mut().enumerate() {
            if !(t >= c.t0 && t < c.t1) {
                advance(lib, c, t);
            }
            let dt = (t - c.t0) as f32;
            let (x, y) = (c.x0 + c.vx * dt, c.y0 + c.vy * dt);
            if x >= view[0] && x < view[2] && y >= view[1] && y < view[3] {
                out.push(Sample {
                    id: id as u32,
                    x,
                    y,
                    heading: c.heading,
                });
            }
        }
        out.extend(
            self.standers
                .iter()
                .filter(|s| s.x >= view[0] && s.x < view[2] && s.y >= view[1] && s.y < view[3]),
        );
    }
}

/// Moves `c` to the piece that holds `t`: forward piece by piece while that is short, else a
/// fresh search.
fn advance(lib: &Library, c: &mut Cursor, t: f64) {
    let period = lib.period_s();
    if t < c.t0 || t - c.t1 > period {
        seek(lib, c, t);
        return;
    }
    while t >= c.t1 {
        let tr = &lib.trajectories[c.traj as usize];
        if c.point + 2 < tr.points {
            c.point += 1;
        } else {
            c.traj_start += f64::from(lib.duration_ticks(tr)) * TICK_S;
            c.traj = tr.next;
            c.point = 0;
        }
        load_piece(lib, c);
    }
}

/// Places `c` on its loop at world time `t` by search: the loop's trajectories in order, then
/// a binary search of the points.
fn seek(lib: &Library, c: &mut Cursor, t: f64) {
    let ch = &lib.characters[c.character as usize];
    let period = lib.period_s();
    let first = &lib.trajectories[ch.first_trajectory as usize];
    let start = f64::from(first.start) * TICK_S + f64::from(c.lap) * period;
    let length = f64::from(ch.laps) * period;
    let tau = (t - start).rem_euclid(length);
    let mut traj = ch.first_trajectory;
    let mut offset = 0.0;
    for _ in 0..ch.trajectories {
        let tr = &lib.trajectories[traj as usize];
        let d = f64::from(lib.duration_ticks(tr)) * TICK_S;
        if tau < offset + d {
            break;
        }
        offset += d;
        traj = tr.next;
    }
    let tr = &lib.trajectories[traj as usize];
    let local = ((tau - offset) / TICK_S).max(0.0);
    let pts = lib.points_of(tr);
    let k = pts.partition_point(|p| f64::from(p.t) <= local);
    c.traj = traj;
    c.point = (k.max(1) - 1).min(pts.len() - 2) as u32;
    c.traj_start = t - (tau - offset);
    load_piece(lib, c);
    // Rounding may leave t a hair outside; the forward walk settles it.
    if t >= c.t1 {
        advance(lib, c, t);
    }
}

/// Fills the piece fields of `c` from its trajectory and point.
fn load_piece(lib: &Library, c: &mut Cursor) {
    let tr = &lib.trajectories[c.traj as usize];
    let patch = &lib.patches[tr.patch as usize];
    let pts = lib.points_of(tr);
    let (a, b) = (pts[c.point as usize], pts[c.point as usize + 1]);
    let (pa, pb) = (lib.world_position(patch, a), lib.world_position(patch, b));
    c.t0 = c.traj_start + f64::from(a.t) * TICK_S;
    c.t1 = c.traj_start + f64::from(b.t) * TICK_S;
    c.x0 = pa[0] as f32;
    c.y0 = pa[1] as f32;
    if c.t1 > c.t0 {
        let dt = c.t1 - c.t0;
        let (vx, vy) = ((pb[0] - pa[0]) / dt, (pb[1] - pa[1]) / dt);
        c.vx = vx as f32;
        c.vy = vy as f32;
    } else {
        c.vx = 0.0;
        c.vy = 0.0;
    }
    c.heading = heading(lib, patch, pts, c.point as usize);
}

/// The direction of piece `k` of `pts`; standing, the direction of the last piece walked
/// before (else the next one): a pure function of the piece, whatever way time came to it.
fn heading(lib: &Library, patch: &crate::Patch, pts: &[crate::Point], k: usize) -> f32 {
    let moving = |i: usize| {
        let (a, b) = (
            lib.world_position(patch, pts[i]),
            lib.world_position(patch, pts[i + 1]),
        );
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        (dx * dx + dy * dy > 1e-12).then(|| dy.atan2(dx) as f32)
    };
    (0..=k)
        .rev()
        .chain(k + 1..pts.len() - 1)
        .find_map(moving)
        .unwrap_or(0.0)
}
