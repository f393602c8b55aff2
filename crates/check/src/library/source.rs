//! Where the library's check reads the points: all of them in a library loaded whole, or a part
//! at a time from its file (`crowd_runtime::LibraryFile`), so that the check of a large library
//! holds a part of its points and not the world's (the million's: 0.77 GB, besides the
//! headings and keys made from them).

use crowd_runtime::{
    Library, LibraryFile, LoadError, LoopPart, LoopSkeleton, PackedHeadings, Point, Window,
};
use std::borrow::Cow;
use std::ops::Range;

/// A library as the check reads it.
pub trait Source: Sync {
    /// Every record; the points only when they are all in memory.
    fn lib(&self) -> &Library;
    /// How many points it has.
    fn points(&self) -> usize;
    /// The points of trajectories `trajectories` (a library in memory: all).
    fn window(&self, trajectories: Range<usize>) -> Result<Held<'_>, LoadError>;
    /// The library of loops `characters` alone ([`Library::loops`]; a library in memory is
    /// asked only for all of them, itself).
    fn loops(&self, characters: Range<usize>) -> Result<Cow<'_, Library>, LoadError>;
    /// About how many points the check holds at once (a library in memory: all of them).
    fn budget(&self) -> usize;
    /// Loop `c`'s headings packed at its keys (`crowd_runtime::turn::packed_keys_in`), made
    /// without holding the loop's points.
    fn loop_keys(&self, c: usize) -> Result<Vec<u16>, LoadError>;
    /// Trajectory `i`'s points.
    fn trajectory_points(&self, i: usize) -> Result<Vec<Point>, LoadError>;
    /// Trajectory `i`'s last tick (its duration).
    fn last_tick(&self, i: usize) -> u32;

    /// The loop of `skeleton` with the points of trajectories `kept` (by index here), the
    /// others standing in, and its `keys` at the points held (`LoopSkeleton::part`).
    fn loop_part<'s>(
        &self,
        skeleton: &'s mut LoopSkeleton,
        kept: &[u32],
        keys: &[u16],
    ) -> Result<(LoopPart<'s>, PackedHeadings), LoadError> {
        let read = |i: usize, _: &crowd_runtime::Trajectory| self.trajectory_points(i);
        skeleton.part((self.lib(), kept), keys, read)
    }
}

/// The points at hand: a library's own, or a window read from its file.
pub enum Held<'a> {
    All(&'a Library),
    Window(&'a Library, Window),
}

impl Held<'_> {
    /// Trajectory `i`'s points, when they are at hand.
    pub fn points_of(&self, i: usize) -> Option<&[Point]> {
        match self {
            Held::All(lib) => Some(lib.points_of(&lib.trajectories[i])),
            Held::Window(lib, w) => w.points_of(i, &lib.trajectories[i]),
        }
    }

    /// Trajectory `i`'s points, which must be at hand.
    pub fn of(&self, i: usize) -> &[Point] {
        self.points_of(i).expect("a trajectory of the window")
    }
}

impl Source for Library {
    fn lib(&self) -> &Library {
        self
    }

    fn points(&self) -> usize {
        self.points.len()
    }

    fn window(&self, _: Range<usize>) -> Result<Held<'_>, LoadError> {
        Ok(Held::All(self))
    }

    fn loops(&self, characters: Range<usize>) -> Result<Cow<'_, Library>, LoadError> {
        Ok(if characters == (0..self.characters.len()) {
            Cow::Borrowed(self)
        } else {
            Cow::Owned(Library::loops(self, characters))
        })
    }

    fn budget(&self) -> usize {
        usize::MAX
    }

    fn loop_keys(&self, c: usize) -> Result<Vec<u16>, LoadError> {
        let ch = &self.characters[c];
        Ok(crowd_runtime::turn::packed_keys_in(
            self,
            &self.points[..],
            ch,
        ))
    }

    fn trajectory_points(&self, i: usize) -> Result<Vec<Point>, LoadError> {
        Ok(self.points_of(&self.trajectories[i]).to_vec())
    }

    fn last_tick(&self, i: usize) -> u32 {
        self.duration_ticks(&self.trajectories[i])
    }
}

/// A library left in its file, read a part of about `budget` points at a time.
pub struct InFile<F> {
    pub file: LibraryFile<F>,
    pub budget: usize,
}

/// Points a check of a library in its file holds at once, about (64 MB of them; the longest
/// loop's, when it has more: a loop is played whole).
pub const FILE_BUDGET: usize = 8 << 20;

impl<F: std::io::Read + std::io::Seek + Send> Source for InFile<F> {
    fn lib(&self) -> &Library {
        self.file.index()
    }

    fn points(&self) -> usize {
        self.file.points() as usize
    }

    fn window(&self, trajectories: Range<usize>) -> Result<Held<'_>, LoadError> {
        Ok(Held::Window(self.lib(), self.file.window(trajectories)?))
    }

    fn loops(&self, characters: Range<usize>) -> Result<Cow<'_, Library>, LoadError> {
        self.file.loops(characters).map(Cow::Owned)
    }

    fn budget(&self) -> usize {
        self.budget
    }

    fn loop_keys(&self, c: usize) -> Result<Vec<u16>, LoadError> {
        self.file.packed_loop_keys(c)
    }

    fn trajectory_points(&self, i: usize) -> Result<Vec<Point>, LoadError> {
        self.file.trajectory_points(i)
    }

    fn last_tick(&self, i: usize) -> u32 {
        self.file.last_tick(i)
    }
}

/// The library's trajectories in runs of about `budget` points (at least one trajectory each).
pub fn trajectory_runs(lib: &Library, budget: usize) -> Vec<Range<usize>> {
    runs(lib.trajectories.len(), budget, |i| {
        lib.trajectories[i].points as usize
    })
}

/// The library's patches in runs of about `budget` points (at least one patch each).
pub fn patch_runs(lib: &Library, budget: usize) -> Vec<Range<usize>> {
    runs(lib.patches.len(), budget, |p| {
        let patch = &lib.patches[p];
        let first = patch.first_trajectory as usize;
        (lib.trajectories[first..first + patch.trajectories as usize].iter())
            .map(|t| t.points as usize)
            .sum()
    })
}

/// The library's loops in runs of about `budget` points (at least one loop each).
pub fn loop_runs(lib: &Library, budget: usize) -> Vec<Range<usize>> {
    runs(lib.characters.len(), budget, |c| {
        loop_points(lib, &lib.characters[c])
    })
}

/// The points of loop `ch`'s trajectories.
pub fn loop_points(lib: &Library, ch: &crowd_runtime::Character) -> usize {
    let mut at = ch.first_trajectory as usize;
    (0..ch.trajectories).fold(0, |n, _| {
        let t = &lib.trajectories[at];
        at = t.next as usize;
        n + t.points as usize
    })
}

/// `0..n` in runs whose `size`s add up to about `budget` (the first to reach it ends one).
fn runs(n: usize, budget: usize, size: impl Fn(usize) -> usize) -> Vec<Range<usize>> {
    if budget == usize::MAX {
        return std::iter::once(0..n).collect();
    }
    let mut out = Vec::new();
    let (mut start, mut held) = (0, 0);
    for i in 0..n {
        held += size(i);
        if held >= budget {
            out.push(start..i + 1);
            (start, held) = (i + 1, 0);
        }
    }
    if start < n {
        out.push(start..n);
    }
    out
}

/// The trajectories of patches `patches`: from the first of their ranges to the last (each
/// trajectory lies in its patch's range).
pub fn trajectories_of(lib: &Library, patches: impl IntoIterator<Item = usize>) -> Range<usize> {
    let (mut lo, mut hi) = (usize::MAX, 0);
    for p in patches {
        let patch = &lib.patches[p];
        if patch.trajectories > 0 {
            lo = lo.min(patch.first_trajectory as usize);
            hi = hi.max((patch.first_trajectory + patch.trajectories) as usize);
        }
    }
    if lo > hi { 0..0 } else { lo..hi }
}
