//! The rules a loaded library keeps, checked once at load so the sampler can trust them:
//! every index inside its section, every range inside its records, times inside the period,
//! and every trajectory on exactly one character's loop that closes in its laps x the period.

use super::records::{Library, Point};
use super::{MAX_GRID, MAX_PERIODS_PER_TRAJECTORY};
use crate::error::LoadError;

/// What the rules read of a trajectory's points: whether their times start at 0 and never
/// decrease, and the last one's.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct Shape {
    pub ordered: bool,
    pub last: u32,
}

impl Shape {
    /// The shape of a trajectory's points (at least one).
    pub(super) fn of(points: &[Point]) -> Shape {
        Shape {
            ordered: points[0].t == 0 && points.windows(2).all(|w| w[1].t >= w[0].t),
            last: points[points.len() - 1].t,
        }
    }
}

impl Library {
    /// Every rule a sampler relies on.
    pub(super) fn validate(&self) -> Result<(), LoadError> {
        let shape = |i: usize| Shape::of(self.points_of(&self.trajectories[i]));
        let last = |i: usize| self.duration_ticks(&self.trajectories[i]);
        self.validate_with(self.points.len() as u64, shape, last)
    }

    /// [`Library::validate`] of a library whose `points` are elsewhere: `points` of them in
    /// all, trajectory `i`'s `shape(i)` and last tick `last(i)` (asked only of a trajectory
    /// whose points are inside them, and the same as [`Shape::of`] them).
    pub(super) fn validate_with(
        &self,
        points: u64,
        shape: impl Fn(usize) -> Shape,
        last: impl Fn(usize) -> u32,
    ) -> Result<(), LoadError> {
        let w = &self.world;
        if w.cols > MAX_GRID || w.rows > MAX_GRID {
            return Err(invalid("WRLD", 0, "at most 65536 patches across and up"));
        }
        let in_range =
            |first: u32, count: u32, len: usize| u64::from(first) + u64::from(count) <= len as u64;
        for (i, p) in self.patches.iter().enumerate() {
            let i = i as u64;
            if p.col >= w.cols || p.row >= w.rows {
                return Err(invalid("PTCH", i, "a cell inside the world's grid"));
            }
            if !in_range(p.first_trajectory, p.trajectories, self.trajectories.len()) {
                return Err(invalid("PTCH", i, "trajectories inside TRAJ"));
            }
            if !in_range(p.first_stander, p.standers, self.standers.len()) {
                return Err(invalid("PTCH", i, "standers inside STND"));
            }
        }
        for (i, c) in self.crossings.iter().enumerate() {
            let i = i as u64;
            let n = self.patches.len() as u32;
            if c.from_patch >= n || c.to_patch >= n || c.t >= w.period_ticks {
                return Err(invalid(
                    "CROS",
                    i,
                    "patches inside PTCH and a time in the period",
                ));
            }
            if ![c.x, c.y, c.vx, c.vy].iter().all(|v| v.is_finite()) {
                return Err(invalid("CROS", i, "finite position and velocity"));
            }
        }
        let n = self.trajectories.len();
        for (i, t) in self.trajectories.iter().enumerate() {
            let e = |expected| Err(invalid("TRAJ", i as u64, expected));
            if t.patch as usize >= self.patches.len()
                || t.entry as usize >= self.crossings.len()
                || t.exit as usize >= self.crossings.len()
                || t.next as usize >= n
            {
                return e("patch, crossings and next inside their sections");
            }
            let p = &self.patches[t.patch as usize];
            let first = u64::from(p.first_trajectory);
            if !(first..first + u64::from(p.trajectories)).contains(&(i as u64)) {
                return e("to lie in its patch's range of trajectories");
            }
            if t.points < 2 || u64::from(t.first_point) + u64::from(t.points) > points {
                return e("at least two points inside PNTS");
            }
            if t.start >= w.period_ticks {
                return e("a start in [0, period)");
            }
            let shape = shape(i);
            if !shape.ordered {
                return e("point times from 0, never decreasing");
            }
            let periods = u64::from(MAX_PERIODS_PER_TRAJECTORY) * u64::from(w.period_ticks);
            if u64::from(shape.last) > periods {
                return e("to last at most MAX_PERIODS_PER_TRAJECTORY (64) periods");
            }
            let next = &self.trajectories[t.next as usize];
            if next.entry != t.exit {
                return e("its next trajectory to enter by its exit");
            }
            let end = u64::from(t.start) + u64::from(shape.last);
            if end % u64::from(w.period_ticks) != u64::from(next.start) {
                return e("its end, modulo the period, to be its next trajectory's start");
            }
        }
        // Every trajectory lies on exactly one listed loop, walked by its `next` links.
        let mut seen = vec![false; n];
        for (i, c) in self.characters.iter().enumerate() {
            let e = |expected| Err(invalid("CHAR", i as u64, expected));
            if c.first_trajectory as usize >= n || c.trajectories == 0 || c.laps == 0 {
                return e("a first trajectory inside TRAJ, and at least one trajectory and lap");
            }
            let mut at = c.first_trajectory as usize;
            let mut ticks = 0u64;
            for _ in 0..c.trajectories {
                if seen[at] {
                    return e("a loop through trajectories of no other loop");
                }
                seen[at] = true;
                let t = &self.trajectories[at];
                ticks += u64::from(last(at));
                at = t.next as usize;
            }
            if at != c.first_trajectory as usize {
                return e("its trajectories' next links to come back to its first");
            }
            if ticks != u64::from(c.laps) * u64::from(w.period_ticks) {
                return e("its trajectories to last its laps x the period");
            }
        }
        if let Some(i) = seen.iter().position(|s| !s) {
            return Err(invalid("TRAJ", i as u64, "to lie on one of CHAR's loops"));
        }
        Ok(())
    }
}

pub(super) fn invalid(section: &'static str, index: u64, expected: &'static str) -> LoadError {
    LoadError::Invalid {
        section,
        index,
        expected,
    }
}
