//! One walker's state and how it moves on: the rare paths (a new trajectory, a pause, several
//! pieces in one frame, a search) one walker at a time; [`super::steps`] batches the common one.

use super::turning::Turn;
use crate::format::{Library, Point, QUANT_STEPS};

/// One walker's state for placing it and for stepping it onto the next piece of its
/// trajectory with nothing else but that piece's point. The sampler keeps these four walkers
/// to a [`Four`] ([`Walkers`]); the rare paths work on one walker's copy.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Hot {
    /// Ticks after the sampler's epoch at which the piece ends.
    pub end: u32,
    /// The point the piece ends at.
    pub at: u32,
    /// World position at `end`.
    pub x: f32,
    pub y: f32,
    /// Metres per tick.
    pub vx: f32,
    pub vy: f32,
    /// In 65536ths of a turn ([`turns`]).
    pub heading: u16,
    /// Pieces left in the trajectory after this one, up to `u16::MAX` (at which the cursor
    /// knows the rest).
    pub left: u16,
    /// The patch's place in the grid: its origin without a lookup.
    pub col: u16,
    pub row: u16,
}

/// Four walkers' [`Hot`], a lane each, field by field: two cache lines. Placing four walkers
/// is then six packed loads with nothing to rearrange, finding the ended ones one load, and a
/// step reads and writes one walker's lanes of the same two lines.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(64))]
pub(super) struct Four {
    pub end: [u32; 4],
    pub x: [f32; 4],
    pub y: [f32; 4],
    pub vx: [f32; 4],
    pub vy: [f32; 4],
    pub heading: [u16; 4],
    pub left: [u16; 4],
    pub at: [u32; 4],
    pub col: [u16; 4],
    pub row: [u16; 4],
}

/// Every walker's [`Hot`] in [`Four`]s (32 bytes a walker). The lanes after the last walker
/// end at `u32::MAX`, so they never end a piece, and are never placed.
#[derive(Debug, Clone)]
pub(super) struct Walkers {
    pub fours: Vec<Four>,
    len: usize,
}

impl Walkers {
    pub fn new(len: usize) -> Walkers {
        let empty = Four {
            end: [u32::MAX; 4],
            x: [0.0; 4],
            y: [0.0; 4],
            vx: [0.0; 4],
            vy: [0.0; 4],
            heading: [0; 4],
            left: [0; 4],
            at: [0; 4],
            col: [0; 4],
            row: [0; 4],
        };
        Walkers {
            fours: vec![empty; len.div_ceil(4)],
            len,
        }
    }

    pub fn len(&self) -> usize {
        self.len
    }

    pub fn get(&self, i: usize) -> Hot {
        let (f, l) = (&self.fours[i / 4], i % 4);
        Hot {
            end: f.end[l],
            at: f.at[l],
            x: f.x[l],
            y: f.y[l],
            vx: f.vx[l],
            vy: f.vy[l],
            heading: f.heading[l],
            left: f.left[l],
            col: f.col[l],
            row: f.row[l],
        }
    }

    pub fn set(&mut self, i: usize, h: &Hot) {
        let (f, l) = (&mut self.fours[i / 4], i % 4);
        f.end[l] = h.end;
        f.at[l] = h.at;
        f.x[l] = h.x;
        f.y[l] = h.y;
        f.vx[l] = h.vx;
        f.vy[l] = h.vy;
        f.heading[l] = h.heading;
        f.left[l] = h.left;
        f.col[l] = h.col;
        f.row[l] = h.row;
    }

    /// Moves every walker's `end` back by `shift` ticks (the epoch moved on by as much).
    pub fn shift_ends(&mut self, shift: u32) {
        for i in 0..self.len {
            self.fours[i / 4].end[i % 4] -= shift;
        }
    }
}

/// What a walker needs only when it leaves its trajectory or is searched for.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Cursor {
    /// Absolute ticks at which `traj` started on this walker's current pass.
    pub traj_start: i64,
    pub traj: u32,
    /// The last point of `traj`.
    pub last: u32,
    pub character: u32,
    /// Which of its loop's `laps` walkers it is: it walks the loop this many periods behind
    /// the first.
    pub lap: u32,
}

/// Every loop's trajectories in walking order, with the tick each starts at from the loop's
/// start: a search is a binary search, not a walk round the loop.
#[derive(Debug, Clone)]
pub(super) struct Loops {
    /// Per loop, where its trajectories begin in `trajectories` and `starts`.
    first: Vec<usize>,
    trajectories: Vec<u32>,
    starts: Vec<u64>,
    /// Per trajectory, what a walker leaving it needs: one record, so that leaving is one
    /// fetch (which the sampler asks for a block ahead), not a chain of four.
    pub onward: Vec<Onward>,
    /// Per point, the heading there ([`crate::turn::library_headings`]) in 65536ths of a turn
    /// ([`turns`]), its lowest bit ([`WALKS`]) whether the piece from it walks: a step onto a
    /// piece reads two of these, which the sampler asks for a block ahead.
    pub headings: Vec<u16>,
    /// The library's turn rate, radians per tick.
    rate: f64,
}

/// Leaving a trajectory: how long it lasted, and its successor.
#[derive(Debug, Clone, Copy)]
pub(super) struct Onward {
    pub duration: u32,
    pub next: Entry,
}

/// Entering a trajectory: its first and last point, and its patch's place in the grid.
#[derive(Debug, Clone, Copy)]
pub(super) struct Entry {
    pub traj: u32,
    pub first: u32,
    pub last: u32,
    pub col: u16,
    pub row: u16,
}

impl Entry {
    pub fn of(lib: &Library, traj: u32) -> Entry {
        let tr = &lib.trajectories[traj as usize];
        let patch = &lib.patches[tr.patch as usize];
        Entry {
            traj,
            first: tr.first_point,
            last: tr.first_point + tr.points - 1,
            // The loader keeps the grid within 65536 patches across and up.
            col: patch.col as u16,
            row: patch.row as u16,
        }
    }
}

/// Every point's [`packed_heading`], as the sampler keeps it: what a reader that makes the
/// headings a character at a time takes them into ([`PackedHeadings::take`]), a quarter of
/// [`crate::turn::PointHeadings`]' size (the million's library: 0.2 GB, not 0.9).
#[derive(Debug, Clone, PartialEq)]
pub struct PackedHeadings {
    pub packed: Vec<u16>,
}

impl PackedHeadings {
    /// Room for every point of `lib` (each facing as [`crate::turn::PointHeadings::for_points`]
    /// leaves it).
    pub fn for_points(lib: &Library) -> PackedHeadings {
        PackedHeadings {
            packed: vec![packed_heading(0.0, false); lib.points.len()],
        }
    }

    /// Takes in character `ch`'s share, `one` ([`crate::turn::character_headings`]), at its
    /// points, as [`crate::turn::PointHeadings::take`] does.
    pub fn take(&mut self, lib: &Library, ch: &crate::Character, one: &crate::turn::PointHeadings) {
        self.take_packed(lib, ch, &Self::character(lib, ch, one));
    }

    /// Character `ch`'s share, `one`, packed in its walking order (its loop's trajectories
    /// from `first_trajectory`, each trajectory's points): two bytes a point, not nine, for a
    /// reader that makes many characters' at once before it takes them in
    /// ([`PackedHeadings::take_packed`]).
    pub fn character(
        lib: &Library,
        ch: &crate::Character,
        one: &crate::turn::PointHeadings,
    ) -> Vec<u16> {
        let (mut heading, mut walks) = (one.heading.iter(), one.walks.iter());
        let mut packed = Vec::with_capacity(one.heading.len());
        each_leg(lib, ch, |_, n| {
            for i in 0..n {
                let h = *heading.next().expect("a heading per point");
                // Whether the piece from point i walks (none from the last).
                let w = i + 1 < n && *walks.next().expect("one per piece");
                packed.push(packed_heading(h, w));
            }
        });
        packed
    }

    /// Takes in character `ch`'s share packed by [`PackedHeadings::character`], at its points.
    pub fn take_packed(&mut self, lib: &Library, ch: &crate::Character, packed: &[u16]) {
        let mut from = 0;
        each_leg(lib, ch, |first, n| {
            self.packed[first..first + n].copy_from_slice(&packed[from..from + n]);
            from += n;
        });
    }
}

/// Each trajectory of `ch`'s loop in walking order, as (its first point, its points).
fn each_leg(lib: &Library, ch: &crate::Character, mut leg: impl FnMut(usize, usize)) {
    let mut at = ch.first_trajectory;
    for _ in 0..ch.trajectories {
        let tr = &lib.trajectories[at as usize];
        leg(tr.first_point as usize, tr.points as usize);
        at = tr.next;
    }
}

impl From<crate::turn::PointHeadings> for PackedHeadings {
    fn from(model: crate::turn::PointHeadings) -> PackedHeadings {
        PackedHeadings {
            packed: (model.heading.iter().zip(&model.walks))
                .map(|(&h, &walks)| packed_heading(h, walks))
                .collect(),
        }
    }
}

impl Loops {
    pub fn new(lib: &Library, model: PackedHeadings) -> Loops {
        let mut loops = Loops {
            first: Vec::with_capacity(lib.characters.len() + 1),
            trajectories: Vec::with_capacity(lib.trajectories.len()),
            starts: Vec::with_capacity(lib.trajectories.len()),
            onward: lib
                .trajectories
                .iter()
                .map(|tr| Onward {
                    duration: lib.duration_ticks(tr),
                    next: Entry::of(lib, tr.next),
                })
                .collect(),
            headings: Vec::new(),
            rate: f64::from(lib.world.turn_rate_deg_s).to_radians() * crate::TICK_S,
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
        loops.headings = model.packed;
        loops
    }

    /// Faces walker `id` (lane `l` of four `f`, just put on a piece that ends `f.end` ticks
    /// after `epoch`): the heading it holds for most of the piece (walking: the one it turns
    /// to; standing: the one it turns from), and the piece's turn when it is not over by
    /// absolute tick `now`. Reads the two ends' entries of [`Loops::headings`] and, for a turn,
    /// their ticks.
    #[inline]
    pub fn face(
        &self,
        lib: &Library,
        (f, l): (&mut Four, usize),
        id: u32,
        now: f64,
        epoch: i64,
    ) -> Option<Turn> {
        let at = f.at[l] as usize;
        let (k0, k1) = (self.headings[at - 1], self.headings[at]);
        let walks = k0 & WALKS != 0;
        let (h0, h1) = (k0 & !WALKS, k1 & !WALKS);
        f.heading[l] = if walks { h1 } else { h0 };
        if h0 == h1 {
            return None;
        }
        let turn = f64::from(h1.wrapping_sub(h0) as i16) * (std::f64::consts::TAU / 65536.0);
        let t1 = (epoch + i64::from(f.end[l])) as f64;
        let t0 = t1 - f64::from(lib.points[at].t.wrapping_sub(lib.points[at - 1].t));
        let needs = (turn.abs() / self.rate).min(t1 - t0);
        let (from, to) = if walks {
            (t0, t0 + needs)
        } else {
            (t1 - needs, t1)
        };
        (to > now).then_some(Turn {
            id,
            from,
            to,
            h0: radians(h0),
            turn: turn as f32,
        })
    }
}

/// The bit of a [`Loops::headings`] entry that says the piece from that point walks (the
/// heading keeps 32768ths of a turn, 2e-4 rad).
pub(crate) const WALKS: u16 = 1;

/// A point's entry of [`Loops::headings`]: its heading (radians, [`crate::turn`]) in 65536ths
/// of a turn, the lowest bit whether the piece from it walks. What the sampler plays of a
/// heading, so a reader that keys what it played hashes these.
pub fn packed_heading(heading: f64, walks: bool) -> u16 {
    (turns(heading as f32) & !WALKS) | if walks { WALKS } else { 0 }
}

/// A heading in radians as 65536ths of a turn (within 5e-5 rad).
#[inline(always)]
pub(super) fn turns(radians: f32) -> u16 {
    // Adding 1.5 x 2^23 rounds to the nearest whole number (|v| <= 32768) and leaves it, in
    // two's complement, in the low bits of the sum: no conversion, so a loop of these packs.
    const ROUND: f32 = 12_582_912.0;
    let v = radians * (65536.0 / std::f32::consts::TAU);
    (v + ROUND).to_bits() as u16
}

/// [`turns`] back to radians, in [-pi, pi).
pub(super) fn radians(turns: u16) -> f32 {
    f32::from(turns as i16) * (std::f32::consts::TAU / 65536.0)
}

/// The library's lengths, computed once, so that a step onto a new piece does not divide.
#[derive(Debug, Clone, Copy)]
pub(super) struct Scale {
    side: f64,
    /// Metres per position step.
    step: f64,
    /// The same, as the motions are computed with it.
    pub quantum: f32,
}

impl Scale {
    pub fn of(lib: &Library) -> Scale {
        let side = f64::from(lib.world.patch_side_m);
        let step = side / QUANT_STEPS;
        Scale {
            side,
            step,
            quantum: step as f32,
        }
    }

    /// World position of point `p` of the patch at (`col`, `row`), as every path computes it.
    pub fn world(&self, col: u16, row: u16, p: Point) -> [f32; 2] {
        [
            (f64::from(col) * self.side + f64::from(p.x) * self.step) as f32,
            (f64::from(row) * self.side + f64::from(p.y) * self.step) as f32,
        ]
    }
}

/// A piece's step from point `a` to point `b`: x and y in position steps, and ticks.
pub(super) fn step(a: Point, b: Point) -> [f32; 3] {
    [
        (i32::from(b.x) - i32::from(a.x)) as f32,
        (i32::from(b.y) - i32::from(a.y)) as f32,
        b.t.wrapping_sub(a.t) as f32,
    ]
}

/// A piece's velocity (metres per tick) from its [`step`]: one formula for every way to a
/// piece, so that a piece is the same bits however the sampler came to it.
#[inline(always)]
pub(super) fn motion([dx, dy, ticks]: [f32; 3], quantum: f32) -> [f32; 2] {
    let per = per_tick(ticks, quantum);
    [dx * per, dy * per]
}

/// Metres per tick per position step of a piece lasting `ticks`.
#[inline(always)]
pub(super) fn per_tick(ticks: f32, quantum: f32) -> f32 {
    if ticks > 0.0 { quantum / ticks } else { 0.0 }
}

/// Moves a walker on from its piece, piece by piece, to the one that holds absolute tick
/// `now`.
pub(super) fn walk_on(
    lib: &Library,
    loops: &Loops,
    c: &mut Cursor,
    h: &mut Hot,
    now: f64,
    epoch: i64,
) {
    loop {
        if h.at < c.last {
            piece(lib, c, h, epoch);
        } else {
            let o = loops.onward[c.traj as usize];
            c.traj_start += i64::from(o.duration);
            enter(c, h, o.next, 0);
            piece(lib, c, h, epoch);
        }
        if now < end_tick(lib, c, h) as f64 {
            return;
        }
    }
}

/// The absolute tick at which the current piece ends.
fn end_tick(lib: &Library, c: &Cursor, h: &Hot) -> i64 {
    c.traj_start + i64::from(lib.points[h.at as usize].t)
}

/// Puts a walker on trajectory `e` so that its next piece starts at the trajectory's point
/// `point`.
fn enter(c: &mut Cursor, h: &mut Hot, e: Entry, point: u32) {
    (c.traj, c.last) = (e.traj, e.last);
    (h.at, h.col, h.row) = (e.first + point, e.col, e.row);
}

/// Places a walker on its loop at absolute tick `now` by search: a binary search of the
/// loop's trajectories, then of the trajectory's points.
pub(super) fn seek(
    lib: &Library,
    loops: &Loops,
    c: &mut Cursor,
    h: &mut Hot,
    now: f64,
    epoch: i64,
) {
    let k = c.character as usize;
    let ch = &lib.characters[k];
    let period = i64::from(lib.world.period_ticks);
    let lap = i64::from(c.lap);
    let start = i64::from(lib.trajectories[ch.first_trajectory as usize].start) + lap * period;
    let length = i64::from(ch.laps) * period;
    // The loop began its current pass at a whole tick; `now` is somewhere in that pass.
    let whole = now.floor() as i64;
    let pass_start = whole - (whole - start).rem_euclid(length);
    let range = loops.first[k]..loops.first[k + 1];
    let starts = &loops.starts[range.clone()];
    let into = (now - pass_start as f64).max(0.0);
    let j = starts.partition_point(|&s| s as f64 <= into).max(1) - 1;
    let traj = loops.trajectories[range.start + j];
    c.traj_start = pass_start + starts[j] as i64;
    let pts = lib.points_of(&lib.trajectories[traj as usize]);
    let local = now - c.traj_start as f64;
    let p = pts.partition_point(|p| f64::from(p.t) <= local);
    enter(
        c,
        h,
        Entry::of(lib, traj),
        (p.max(1) - 1).min(pts.len() - 2) as u32,
    );
    piece(lib, c, h, epoch);
    // A piece that ends at or before `now` (the trajectory's last, or rounding): walk on.
    if now >= end_tick(lib, c, h) as f64 {
        walk_on(lib, loops, c, h, now, epoch);
    }
}

/// Makes the piece from point `h.at` to the next the current one (`h.at` moves on to its end).
/// Its heading is the sampler's to set ([`Loops::face`]).
fn piece(lib: &Library, c: &Cursor, h: &mut Hot, epoch: i64) {
    let (a, b) = (lib.points[h.at as usize], lib.points[h.at as usize + 1]);
    let scale = Scale::of(lib);
    let [vx, vy] = motion(step(a, b), scale.quantum);
    [h.x, h.y] = scale.world(h.col, h.row, b);
    (h.vx, h.vy) = (vx, vy);
    h.at += 1;
    h.left = (c.last - h.at).min(u32::from(u16::MAX)) as u16;
    // Wraps only for a piece that ends before the epoch, which the caller walks on from.
    h.end = (end_tick(lib, c, h) - epoch) as u32;
}

#[cfg(test)]
mod tests {
    use super::{radians, turns};
    use std::f32::consts::{PI, TAU};

    #[test]
    fn turns_rounds_a_heading_to_the_nearest_65536th_of_a_turn_and_back_within_5e_5_rad() {
        for i in 0..=200_000 {
            let a = -PI + TAU * i as f32 / 200_000.0;
            let v = a * (65536.0 / TAU);
            assert_eq!(turns(a), v.round_ties_even() as i32 as u16, "{a}");
            let d = (radians(turns(a)) - a).abs();
            assert!(d.min(TAU - d) < 5e-5, "{a}: {d}");
        }
    }
}
