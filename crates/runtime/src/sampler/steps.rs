//! The common way on: a walker steps onto the next piece of its trajectory and that piece
//! holds the frame's time. Such steps are gathered column by column, so that their motions
//! (a division and an arctangent each) are computed in one tight loop the compiler vectorises.

use super::walker::{Scale, Walkers, heading, per_tick, step};
use crate::format::Library;

#[derive(Debug, Clone, Default)]
pub(super) struct Steps {
    id: Vec<u32>,
    /// World position at the new piece's end.
    x: Vec<f32>,
    y: Vec<f32>,
    /// The piece's [`step`].
    dx: Vec<f32>,
    dy: Vec<f32>,
    ticks: Vec<f32>,
    /// The heading before, which a standing piece keeps.
    keep: Vec<u16>,
    /// Computed by [`Steps::finish`].
    per_tick: Vec<f32>,
    heading: Vec<u16>,
}

impl Steps {
    pub fn clear(&mut self) {
        for v in [
            &mut self.x,
            &mut self.y,
            &mut self.dx,
            &mut self.dy,
            &mut self.ticks,
        ] {
            v.clear();
        }
        self.id.clear();
        self.keep.clear();
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
        // The last piece of its trajectory, or so many left that only the cursor knows.
        let left = f.left[l];
        if left == 0 || left == u16::MAX {
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
        self.id.push(id);
        self.x.push(x);
        self.y.push(y);
        self.dx.push(dx);
        self.dy.push(dy);
        self.ticks.push(ticks);
        self.keep.push(f.heading[l]);
        f.at[l] += 1;
        f.left[l] = left - 1;
        f.end[l] = end;
        true
    }

    /// Computes every step's motion and writes it into the walkers' records: each part of
    /// [`motion`] is its own loop over plain columns, which the compiler turns into packed
    /// arithmetic (a loop over whole motions it leaves scalar).
    pub fn finish(&mut self, quantum: f32, w: &mut Walkers) {
        let n = self.id.len();
        let (dx, dy, ticks) = (&self.dx[..n], &self.dy[..n], &self.ticks[..n]);
        self.per_tick.clear();
        self.per_tick
            .extend(ticks.iter().map(|&t| per_tick(t, quantum)));
        self.heading.clear();
        self.heading
            .extend(dy.iter().zip(dx).map(|(&dy, &dx)| heading(dy, dx)));
        for (i, &id) in self.id.iter().enumerate() {
            let (f, l) = (&mut w.fours[id as usize / 4], id as usize % 4);
            let per = self.per_tick[i];
            (f.x[l], f.y[l]) = (self.x[i], self.y[i]);
            (f.vx[l], f.vy[l]) = (dx[i] * per, dy[i] * per);
            let moving = dx[i] != 0.0 || dy[i] != 0.0;
            f.heading[l] = if moving {
                self.heading[i]
            } else {
                self.keep[i]
            };
        }
    }
}
