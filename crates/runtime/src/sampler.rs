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
    /// The piece: points `at`, `at + 1` of the library (of trajectory `traj`, in `patch`,
    /// whose last point is `last`): walking on needs no other record.
    at: u32,
    last: u32,
    patch: u32,
    traj: u32,
    /// World time at which `traj` started, for this character's current pass.
    traj_start: f64,
    character: u32,
    lap: u32,
}

/// What a frame reads of a character that stays on its piece: 40 bytes, so that a frame
/// streams 4 MB for 100k characters and touches [`Cursor`] only for those that walk on.
#[derive(Debug, Clone, Copy)]
struct Hot {
    t0: f64,
    /// Seconds the piece lasts.
    dur: f32,
    x0: f32,
    y0: f32,
    vx: f32,
    vy: f32,
    heading: f32,
    /// The point the next piece ends at, to prefetch.
    then: u32,
}

impl Hot {
    fn of(c: &Cursor) -> Hot {
        Hot {
            t0: c.t0,
            dur: (c.t1 - c.t0) as f32,
            x0: c.x0,
            y0: c.y0,
            vx: c.vx,
            vy: c.vy,
            heading: c.heading,
            then: c.at + 2,
        }
    }
}

/// Samples a library's characters. Walkers have ids `0 .. walkers` (loop by loop, lap by lap),
/// standers the ids after them.
#[derive(Debug, Clone)]
pub struct Sampler<'a> {
    lib: &'a Library,
    loops: Loops,
    hot: Vec<Hot>,
    cursors: Vec<Cursor>,
    standers: Vec<Sample>,
}

/// Every loop's trajectories in walking order, with the tick each starts at from the loop's
/// start: a search is a binary search, not a walk round the loop.
#[derive(Debug, Clone)]
struct Loops {
    /// Per loop, where its trajectories begin in `trajectories` and `starts`.
    first: Vec<usize>,
    trajectories: Vec<u32>,
    starts: Vec<u64>,
}

impl Loops {
    fn new(lib: &Library) -> Loops {
        let mut loops = Loops {
            first: Vec::with_capacity(lib.characters.len() + 1),
            trajectories: Vec::with_capacity(lib.trajectories.len()),
            starts: Vec::with_capacity(lib.trajectories.len()),
        };
        for ch in &lib.characters {
            loops.first.push(loops.trajectories.len());
            let (mut at, mut tick) = (ch.first_trajectory, 0u64);
            for _ in 0..ch.trajectories {
                let tr = &lib.trajectories[at as usize];
                loops.trajectories.push(at);
                loops.starts.push(tick);
                tick += u64::from(lib.duration_ticks(tr));
                at = tr.next;
            }
        }
        loops.first.push(loops.trajectories.len());
        loops
    }
}

impl<'a> Sampler<'a> {
    /// A sampler with every character placed at time 0.
    pub fn new(lib: &'a Library) -> Sampler<'a> {
        let loops = Loops::new(lib);
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
                    at: 0,
                    last: 0,
                    patch: 0,
                    traj: ch.first_trajectory,
                    traj_start: 0.0,
                    character: c as u32,
                    lap,
                };
                seek(lib, &loops, &mut cursor, 0.0);
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
            loops,
            hot: cursors.iter().map(Hot::of).collect(),
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
        let (lib, loops) = (self.lib, &self.loops);
        let (hot, cursors) = (&mut self.hot, &mut self.cursors);
        for id in 0..hot.len() {
            // A character a few places on that will walk onto its next piece: ask for that
            // piece's point now, so the memory fetches of several characters overlap.
            if let Some(ahead) = hot.get(id + PREFETCH_AHEAD)
                && t - ahead.t0 >= f64::from(ahead.dur)
            {
                prefetch(lib.points.as_ptr().wrapping_add(ahead.then as usize));
                prefetch(cursors.as_ptr().wrapping_add(id + PREFETCH_AHEAD));
            }
            let h = &mut hot[id];
            let since = t - h.t0;
            if !(since >= 0.0 && since < f64::from(h.dur)) {
                advance(lib, loops, &mut cursors[id], t);
                *h = Hot::of(&cursors[id]);
            }
            let dt = (t - h.t0) as f32;
            let (x, y) = (h.x0 + h.vx * dt, h.y0 + h.vy * dt);
            if x >= view[0] && x < view[2] && y >= view[1] && y < view[3] {
                out.push(Sample {
                    id: id as u32,
                    x,
                    y,
                    heading: h.heading,
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
fn advance(lib: &Library, loops: &Loops, c: &mut Cursor, t: f64) {
    let period = lib.period_s();
    if t < c.t0 || t - c.t1 > period {
        seek(lib, loops, c, t);
        return;
    }
    while t >= c.t1 {
        if c.at + 1 < c.last {
            c.at += 1;
            load_piece(lib, c);
        } else {
            c.traj_start += f64::from(lib.points[c.last as usize].t) * TICK_S;
            let next = lib.trajectories[c.traj as usize].next;
            enter(lib, c, next, 0);
        }
    }
}

/// Puts `c` on piece `point` of trajectory `traj`.
fn enter(lib: &Library, c: &mut Cursor, traj: u32, point: u32) {
    let tr = &lib.trajectories[traj as usize];
    c.traj = traj;
    c.patch = tr.patch;
    c.at = tr.first_point + point;
    c.last = tr.first_point + tr.points - 1;
    load_piece(lib, c);
}

/// How many characters ahead [`Sampler::sample`] prefetches.
const PREFETCH_AHEAD: usize = 32;

/// A hint that `p` will be read soon; nothing is read now, so any address is harmless.
#[inline(always)]
fn prefetch<T>(p: *const T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        // SAFETY: a prefetch reads and writes nothing, whatever the address; SSE is part of
        // every x86_64 processor.
        unsafe { _mm_prefetch::<_MM_HINT_T0>(p.cast()) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// Places `c` on its loop at world time `t` by search: a binary search of the loop's
/// trajectories, then of the trajectory's points.
fn seek(lib: &Library, loops: &Loops, c: &mut Cursor, t: f64) {
    let ch = &lib.characters[c.character as usize];
    let period = lib.period_s();
    let first = &lib.trajectories[ch.first_trajectory as usize];
    let start = f64::from(first.start) * TICK_S + f64::from(c.lap) * period;
    let length = f64::from(ch.laps) * period;
    let tau = (t - start).rem_euclid(length);
    let range = loops.first[c.character as usize]..loops.first[c.character as usize + 1];
    let starts = &loops.starts[range.clone()];
    let tau_ticks = tau / TICK_S;
    let k = starts.partition_point(|&s| s as f64 <= tau_ticks).max(1) - 1;
    let traj = loops.trajectories[range.start + k];
    let offset = starts[k] as f64 * TICK_S;
    let tr = &lib.trajectories[traj as usize];
    let local = ((tau - offset) / TICK_S).max(0.0);
    let pts = lib.points_of(tr);
    let k = pts.partition_point(|p| f64::from(p.t) <= local);
    c.traj_start = t - (tau - offset);
    enter(lib, c, traj, (k.max(1) - 1).min(pts.len() - 2) as u32);
    // Rounding may leave t a hair outside; the forward walk settles it.
    if t >= c.t1 {
        advance(lib, loops, c, t);
    }
}

/// Fills the piece fields of `c` from its points.
fn load_piece(lib: &Library, c: &mut Cursor) {
    let patch = &lib.patches[c.patch as usize];
    let (a, b) = (lib.points[c.at as usize], lib.points[c.at as usize + 1]);
    let (pa, pb) = (lib.world_position(patch, a), lib.world_position(patch, b));
    c.t0 = c.traj_start + f64::from(a.t) * TICK_S;
    c.t1 = c.traj_start + f64::from(b.t) * TICK_S;
    c.x0 = pa[0] as f32;
    c.y0 = pa[1] as f32;
    let (dx, dy) = (pb[0] - pa[0], pb[1] - pa[1]);
    if c.t1 > c.t0 {
        let dt = c.t1 - c.t0;
        c.vx = (dx / dt) as f32;
        c.vy = (dy / dt) as f32;
    } else {
        c.vx = 0.0;
        c.vy = 0.0;
    }
    c.heading = if dx * dx + dy * dy > 1e-12 {
        (dy as f32).atan2(dx as f32)
    } else {
        standing_heading(lib, c)
    };
}

/// Standing: the direction of the last piece walked before in the trajectory (else the next
/// one), a pure function of the piece, whatever way time came to it.
fn standing_heading(lib: &Library, c: &Cursor) -> f32 {
    let tr = &lib.trajectories[c.traj as usize];
    let patch = &lib.patches[c.patch as usize];
    let pts = lib.points_of(tr);
    let k = (c.at - tr.first_point) as usize;
    let moving = |i: usize| {
        let (a, b) = (
            lib.world_position(patch, pts[i]),
            lib.world_position(patch, pts[i + 1]),
        );
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        (dx * dx + dy * dy > 1e-12).then(|| (dy as f32).atan2(dx as f32))
    };
    (0..=k)
        .rev()
        .chain(k + 1..pts.len() - 1)
        .find_map(moving)
        .unwrap_or(0.0)
}
