//! The common way on: a walker steps onto the next piece of its trajectory and that piece
//! holds the frame's time. Such steps are gathered column by column, so that their motions
//! (a division each) are computed in one tight loop the compiler vectorises. Headings come
//! from the loops' table afterwards (`Loops::face`).

use super::BLOCK;
use super::walker::{Scale, Walkers, per_tick, step};
use crate::format::Library;

/// A step taken: whose, and where its new piece ends.
#[derive(Debug, Clone, Copy, Default)]
struct Taken {
    id: u32,
    x: f32,
    y: f32,
}

/// A block's steps (at most one per walker), in fixed arrays: taking one is a few stores at
/// one count, not a length and capacity per column.
#[derive(Debug, Clone)]
pub(super) struct Steps {
    n: usize,
    taken: Box<[Taken; BLOCK]>,
    /// The pieces' [`step`]s, column by column for [`Steps::finish`]'s packed loops.
    dx: Box<[f32; BLOCK]>,
    dy: Box<[f32; BLOCK]>,
    ticks: Box<[f32; BLOCK]>,
    /// Computed by [`Steps::finish`].
    per_tick: Box<[f32; BLOCK]>,
}

impl Default for Steps {
    fn default() -> Steps {
        Steps {
            n: 0,
            taken: Box::new([Taken::default(); BLOCK]),
            dx: Box::new([0.0; BLOCK]),
            dy: Box::new([0.0; BLOCK]),
            ticks: Box::new([0.0; BLOCK]),
            per_tick: Box::new([0.0; BLOCK]),
        }
    }
}

impl Steps {
    pub fn clear(&mut self) {
        self.n = 0;
    }

    /// Steps walker `id` onto its next piece, if that is all it needs to reach tick `whole`
    /// after the epoch (its motion is written by [`Steps::finish`]); false if it needs more.
    #[inline]
    pub fn take(
        &mut self,
        lib: &Library,
        scale: &Scale,
        id: u32,
        w: &mut Walkers,
        whole: u32,
    ) -> bool {
        let (f, l) = (&mut w.fours[id as usize / 4], id as usize % 4);
        // The last piece of its trajectory, or so many left that only the cursor knows (or,
        // which a block cannot have, more steps than walkers).
        let (left, n) = (f.left[l], self.n);
        if left == 0 || left == u16::MAX || n >= BLOCK {
            return false;
        }
        let at = f.at[l] as usize;
        let (a, b) = (lib.points[at], lib.points[at + 1]);
        let end = f.end[l].wrapping_add(b.t.wrapping_sub(a.t));
        if whole >= end {
            return false;
        }
        let [dx, dy, ticks] = step(a, b);
        let [x, y] = scale.world(f.col[l], f.row[l], b);
        self.taken[n] = Taken { id, x, y };
        (self.dx[n], self.dy[n], self.ticks[n]) = (dx, dy, ticks);
        self.n = n + 1;
        f.at[l] += 1;
        f.left[l] = left - 1;
        f.end[l] = end;
        true
    }

    /// Computes every step's motion and writes it into the walkers' records: each part of
    /// `walker::motion` is its own loop over plain columns, which the compiler turns into packed
    /// arithmetic (a loop over whole motions it leaves scalar).
    pub fn finish(&mut self, quantum: f32, w: &mut Walkers) {
        let n = self.n;
        let (dx, dy, ticks) = (&self.dx[..n], &self.dy[..n], &self.ticks[..n]);
        for (p, &t) in self.per_tick[..n].iter_mut().zip(ticks) {
            *p = per_tick(t, quantum);
        }
        for (i, t) in self.taken[..n].iter().enumerate() {
            let (f, l) = (&mut w.fours[t.id as usize / 4], t.id as usize % 4);
            let per = self.per_tick[i];
            (f.x[l], f.y[l]) = (t.x, t.y);
            (f.vx[l], f.vy[l]) = (dx[i] * per, dy[i] * per);
        }
    }
}
