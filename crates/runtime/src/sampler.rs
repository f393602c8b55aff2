//! Playing a library: where every character is at a time, frame after frame.
//!
//! A frame is 100k records to read and 100k samples to write. So a frame streams 32 bytes per
//! walker, kept four walkers to two cache lines field by field ([`walker::Four`]) so that four
//! walkers are placed at once ([`place`]), and, for the one walker in twenty whose piece ends
//! in a frame at 60 frames a second, nearly always steps it onto its next piece with nothing
//! else but that piece's point. Ended walkers are found a block ahead, so that those points
//! are fetched together while the block before is moved on and written out.
//!
//! Time is kept in whole ticks (`TICK_S`), so a piece is the same bits whether the sampler
//! walked to it or searched for it: a frame depends only on its time.

mod place;
mod steps;
mod turning;
mod walker;

pub(crate) use walker::WALKS;
pub use walker::{PackedHeadings, packed_heading};

use crate::format::{Library, TICK_S};
use place::place;
use steps::Steps;
use turning::Turning;
use walker::{Cursor, Loops, Scale, Walkers};

/// One character seen in a frame: world metres (x east, y north), heading in radians
/// counter-clockwise from east (the direction it walks, or last walked), within 5e-5 rad.
/// Four 4-byte fields in this order (`repr(C)`), so a frame's samples can be copied as they
/// are into an instance buffer.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[repr(C)]
pub struct Sample {
    pub id: u32,
    pub x: f32,
    pub y: f32,
    pub heading: f32,
}

/// Samples a library's characters. Walkers have ids `0 .. walkers` (loop by loop, lap by lap),
/// standers the ids after them.
#[derive(Debug, Clone)]
pub struct Sampler<'a> {
    lib: &'a Library,
    /// Shared by the sampler's clones: a clone plays the same loops from its own walkers'
    /// state (the check plays a period in runs on every core; each clone held the million's
    /// 270 MB of loop tables again).
    loops: std::sync::Arc<Loops>,
    scale: Scale,
    walkers: Walkers,
    cursors: Vec<Cursor>,
    standers: Vec<Sample>,
    /// Absolute tick that `Hot::end` counts from, and the last frame's time in ticks (None
    /// before the first frame).
    epoch: i64,
    last: Option<f64>,
    /// The walkers whose piece has ended, of the block being scanned and of the one before.
    ended: [Vec<u32>; 2],
    /// Those of them that need more than a [`Steps`] step.
    slow: Vec<u32>,
    steps: Steps,
    /// Walkers whose piece's turn is under way or still to come ([`crate::turn`]): their
    /// samples' headings are set from these after placing.
    turning: Turning,
}

/// Walkers per block: their records stay in L1 from finding the ended pieces to writing the
/// samples, and a block's ended walkers (about 40) are enough fetches in flight.
const BLOCK: usize = 512;
/// `Hot::end` must stay below 2^32 ticks after the epoch: the epoch moves on by whole steps of
/// this many ticks (30 hours) once time is two steps past it.
const EPOCH_STEP: i64 = 1 << 30;
const TICKS_PER_S: f64 = 1.0 / TICK_S;

impl<'a> Sampler<'a> {
    /// A sampler whose first frame may be at any time.
    pub fn new(lib: &'a Library) -> Sampler<'a> {
        Sampler::with_headings(lib, crate::turn::library_packed_headings(lib))
    }

    /// [`Sampler::new`] with the library's headings made already: `headings` must be
    /// [`crate::turn::library_headings`] of `lib` (made, say, a character per thread).
    pub fn with_headings(lib: &'a Library, headings: impl Into<PackedHeadings>) -> Sampler<'a> {
        let mut cursors = Vec::with_capacity(lib.walkers() as usize);
        for (c, ch) in lib.characters.iter().enumerate() {
            for lap in 0..ch.laps {
                cursors.push(Cursor {
                    character: c as u32,
                    lap,
                    ..Cursor::default()
                });
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
        Sampler::of(lib, headings.into(), cursors, standers)
    }

    /// A sampler of only the walkers `walkers` (ids below `lib.walkers()`, each at most once),
    /// and no standers: a sample's `id` is then the walker's place in `walkers`. Each walker is
    /// placed exactly as [`Sampler::new`] places it, so a reader can play again only the
    /// walkers whose part of the library changed (`crowd check` after a brush stroke).
    ///
    /// Returns `None` when an id is not a walker of `lib`.
    pub fn playing(
        lib: &'a Library,
        headings: impl Into<PackedHeadings>,
        walkers: &[u32],
    ) -> Option<Sampler<'a>> {
        // Each loop's first walker id, to find a walker's loop by a binary search.
        let firsts: Vec<u32> = (lib.characters.iter())
            .scan(0u32, |next, ch| {
                let first = *next;
                *next += ch.laps;
                Some(first)
            })
            .collect();
        let cursors = walkers
            .iter()
            .map(|&id| {
                let character = firsts.partition_point(|&f| f <= id).checked_sub(1)?;
                let lap = id - firsts[character];
                (lap < lib.characters[character].laps).then_some(Cursor {
                    character: character as u32,
                    lap,
                    ..Cursor::default()
                })
            })
            .collect::<Option<Vec<Cursor>>>()?;
        Some(Sampler::of(lib, headings.into(), cursors, Vec::new()))
    }

    fn of(
        lib: &'a Library,
        headings: PackedHeadings,
        cursors: Vec<Cursor>,
        standers: Vec<Sample>,
    ) -> Sampler<'a> {
        Sampler {
            lib,
            loops: std::sync::Arc::new(Loops::new(lib, headings)),
            scale: Scale::of(lib),
            walkers: Walkers::new(cursors.len()),
            cursors,
            standers,
            epoch: 0,
            last: None,
            ended: [Vec::with_capacity(BLOCK), Vec::with_capacity(BLOCK)],
            steps: Steps::default(),
            slow: Vec::with_capacity(BLOCK),
            turning: Turning::default(),
        }
    }

    /// Walkers plus standers.
    pub fn characters(&self) -> usize {
        self.cursors.len() + self.standers.len()
    }

    /// Every character inside `view` (`[x0, y0, x1, y1]`, world metres, x0 <= x < x1 and
    /// y0 <= y < y1) at world time `t` seconds, into `out` (cleared first), in id order.
    /// Any `t` is allowed. Moving forward costs no search; going back, or forward by more than
    /// a period, searches each walker's loop.
    pub fn sample(&mut self, t: f64, view: [f32; 4], out: &mut Vec<Sample>) {
        out.clear();
        out.reserve(self.characters());
        let now = t * TICKS_PER_S;
        self.settle_epoch(now);
        let rel = now - self.epoch as f64;
        let whole = rel.floor() as u32;
        let frac = (rel - f64::from(whole)) as f32;
        let blocks = self.walkers.len().div_ceil(BLOCK);
        for b in 0..=blocks {
            if b < blocks {
                self.scan(b, whole);
            }
            if b > 0 {
                self.walk_on_ended(b - 1, now, whole);
                self.write(b - 1, whole, frac, view, out);
            }
        }
        self.turning.apply(now, out);
        out.extend(
            self.standers
                .iter()
                .filter(|s| s.x >= view[0] && s.x < view[2] && s.y >= view[1] && s.y < view[3]),
        );
    }

    /// Block `b`'s range of walker ids.
    fn block(&self, b: usize) -> std::ops::Range<usize> {
        b * BLOCK..((b + 1) * BLOCK).min(self.walkers.len())
    }

    /// Finds block `b`'s walkers whose piece ended by tick `whole` (after the epoch), and asks
    /// for the points they walk on to (and, leaving their trajectory, their cursors), all at
    /// once.
    fn scan(&mut self, b: usize, whole: u32) {
        let range = self.block(b);
        let ended = &mut self.ended[b % 2];
        ended.clear();
        let w = &self.walkers;
        place::ended(w, range, whole, ended);
        for &id in ended.iter() {
            let (f, l) = (&w.fours[id as usize / 4], id as usize % 4);
            prefetch(self.lib.points.as_ptr().wrapping_add(f.at[l] as usize + 1));
            prefetch(self.loops.headings.as_ptr().wrapping_add(f.at[l] as usize));
            if f.left[l] == 0 {
                // Leaving its trajectory: the cursor now, its way onward when it has come.
                let traj = self.cursors[id as usize].traj as usize;
                prefetch(self.loops.onward.as_ptr().wrapping_add(traj));
            }
        }
    }

    /// Moves block `b`'s ended walkers on to the piece that holds absolute tick `now`
    /// (`whole` ticks after the epoch, rounded down): most as [`Steps`], the rest one by one.
    fn walk_on_ended(&mut self, b: usize, now: f64, whole: u32) {
        let (lib, loops, epoch) = (self.lib, &self.loops, self.epoch);
        let period = f64::from(lib.world.period_ticks);
        self.steps.clear();
        // The first points of the trajectories those leaving theirs walk on to: asked for
        // before the steps below, used after them.
        for &id in &self.ended[b % 2] {
            let (f, l) = (&self.walkers.fours[id as usize / 4], id as usize % 4);
            if f.left[l] == 0 {
                let traj = self.cursors[id as usize].traj as usize;
                let first = loops.onward[traj].next.first as usize;
                prefetch(lib.points.as_ptr().wrapping_add(first));
            }
        }
        self.slow.clear();
        for &id in &self.ended[b % 2] {
            if !self
                .steps
                .take(lib, &self.scale, id, &mut self.walkers, whole)
            {
                self.slow.push(id);
            }
        }
        for &id in &self.slow {
            let w = &mut self.walkers;
            let (c, mut h) = (&mut self.cursors[id as usize], w.get(id as usize));
            if now - (epoch + i64::from(h.end)) as f64 > period {
                walker::seek(lib, loops, c, &mut h, now, epoch);
            } else {
                walker::walk_on(lib, loops, c, &mut h, now, epoch);
            }
            w.set(id as usize, &h);
        }
        self.steps.finish(self.scale.quantum, &mut self.walkers);
        for &id in &self.ended[b % 2] {
            let four = (&mut self.walkers.fours[id as usize / 4], id as usize % 4);
            if let Some(t) = loops.face(lib, four, id, now, epoch) {
                self.turning.add(t, now);
            }
        }
    }

    /// Appends block `b`'s walkers inside `view` at `whole` ticks and `frac` of a tick after
    /// the epoch.
    fn write(&self, b: usize, whole: u32, frac: f32, view: [f32; 4], out: &mut Vec<Sample>) {
        let range = self.block(b);
        place(&self.walkers, range, whole, frac, view, out);
    }

    /// Keeps `Hot::end` in range of its u32: before the first frame, after time went back or
    /// leapt ahead, every walker is placed afresh; when time has merely run long, the epoch
    /// moves on and every record with it.
    fn settle_epoch(&mut self, now: f64) {
        let step = EPOCH_STEP as f64;
        let fresh = match self.last {
            None => true,
            Some(last) => now < last || now - last >= step,
        };
        if fresh {
            self.epoch = (now / step).floor() as i64 * EPOCH_STEP;
            let (lib, loops, epoch) = (self.lib, &self.loops, self.epoch);
            let w = &mut self.walkers;
            self.turning.clear();
            for (id, c) in self.cursors.iter_mut().enumerate() {
                let mut h = w.get(id);
                walker::seek(lib, loops, c, &mut h, now, epoch);
                w.set(id, &h);
                let four = (&mut w.fours[id / 4], id % 4);
                if let Some(t) = loops.face(lib, four, id as u32, now, epoch) {
                    self.turning.add(t, now);
                }
            }
        } else if let Some(last) = self.last
            && now - self.epoch as f64 >= 2.0 * step
        {
            // Every piece ends after the last frame, so after the new epoch: no record wraps.
            let epoch = (last / step).floor() as i64 * EPOCH_STEP;
            let shift = (epoch - self.epoch) as u32;
            self.walkers.shift_ends(shift);
            self.epoch = epoch;
        }
        self.last = Some(now);
    }
}

/// A hint that `p` will be read soon; nothing is read now, so any address is harmless.
#[inline(always)]
pub(crate) fn prefetch<T>(p: *const T) {
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
