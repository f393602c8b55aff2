//! A long loop played a group of walkers at a time: the loop's records alone, every trajectory
//! standing in as two points ([`LoopSkeleton`]), and for each group the points of the
//! trajectories its walkers walk ([`LoopSkeleton::part`]). A character's loop threads through
//! much of the world (the million's longest holds 36 of its 96 million points): a reader that
//! plays its walkers a group at a time so holds the group's stretches of it, not the loop.

use super::file::loops_sized;
use super::records::{Library, Point, Trajectory};
use crate::error::LoadError;

/// Loop `c` of a library alone (as `LibraryFile::loops` makes it), each trajectory standing in
/// as its start and its last tick: the loop lasts as long, and a walker that never walks a
/// standing-in trajectory plays the same. Made once for a loop, then a part for each group.
#[derive(Debug, Clone)]
pub struct LoopSkeleton {
    lib: Library,
    /// Each trajectory: its index in the whole library, its index in `lib`, and its first key
    /// in the loop's keys (a trajectory's first point is the one before's last key); sorted
    /// by the whole library's index.
    trajectories: Vec<(u32, u32, usize)>,
}

impl LoopSkeleton {
    /// Loop `c` of `whole` (its records: the points are not read), each trajectory's last
    /// tick told by `last` (by its index in `whole`).
    pub fn new(whole: &Library, c: usize, last: impl Fn(usize) -> u32) -> LoopSkeleton {
        let size = |_, t: &Trajectory| 2.min(t.points as usize);
        let stand_in = |i: usize, t: &Trajectory| {
            let ends = [
                Point { x: 0, y: 0, t: 0 },
                Point {
                    x: 0,
                    y: 0,
                    t: last(i),
                },
            ];
            Ok::<_, LoadError>(ends[..size(i, t)].to_vec())
        };
        let lib = loops_sized(whole, c..c + 1, size, stand_in).expect("standing in reads nothing");
        let (ch, part_ch) = (&whole.characters[c], &lib.characters[0]);
        let mut trajectories = Vec::with_capacity(ch.trajectories as usize);
        let (mut at, mut part_at, mut key) = (ch.first_trajectory, part_ch.first_trajectory, 0);
        for j in 0..ch.trajectories {
            key -= usize::from(j > 0);
            trajectories.push((at, part_at, key));
            let t = &whole.trajectories[at as usize];
            key += t.points as usize;
            (at, part_at) = (t.next, lib.trajectories[part_at as usize].next);
        }
        trajectories.sort_unstable();
        LoopSkeleton { lib, trajectories }
    }

    /// The loop with the points of trajectories `kept` (by their index in `whole`, the library
    /// the skeleton was made of) as `read` reads them, the others standing in; and the loop's
    /// headings packed at its keys, `keys` (`crate::turn::packed_keys_in`), at the points
    /// held, as `crate::turn::take_packed_headings` puts them (no walk bit at a trajectory's
    /// last point). Made in the skeleton itself, which it is again once the part is dropped: a
    /// copy of the loop's records for each group was the million's 52 MB.
    pub fn part(
        &mut self,
        (whole, kept): (&Library, &[u32]),
        keys: &[u16],
        mut read: impl FnMut(usize, &Trajectory) -> Result<Vec<Point>, LoadError>,
    ) -> Result<(LoopPart<'_>, crate::PackedHeadings), LoadError> {
        let mut part = LoopPart {
            points: self.lib.points.len(),
            saved: Vec::with_capacity(kept.len()),
            skeleton: self,
        };
        // Each trajectory held: where its points are in the library, how many, its first key.
        let mut held = Vec::with_capacity(kept.len());
        for &i in kept {
            let trajectories = &part.skeleton.trajectories;
            let at = trajectories.binary_search_by_key(&i, |e| e.0);
            let (_, k, key) = trajectories[at.expect("a trajectory of the loop")];
            let points = read(i as usize, &whole.trajectories[i as usize])?;
            let lib = &mut part.skeleton.lib;
            let tr = &mut lib.trajectories[k as usize];
            part.saved.push((k, tr.first_point, tr.points));
            (tr.first_point, tr.points) = (lib.points.len() as u32, points.len() as u32);
            held.push((lib.points.len(), points.len(), key));
            lib.points.extend(points);
        }
        let mut headings = crate::PackedHeadings::for_points(&part);
        for (first, n, key) in held {
            crate::turn::leg_keys(&keys[key..key + n], &mut headings.packed[first..first + n]);
        }
        Ok((part, headings))
    }
}

/// A part of a [`LoopSkeleton`] ([`LoopSkeleton::part`]): the skeleton's library with some of
/// its trajectories' points, made the skeleton again when dropped.
pub struct LoopPart<'a> {
    skeleton: &'a mut LoopSkeleton,
    /// The skeleton's points before the part's were added, and each trajectory given its own
    /// points with where its stand-ins were.
    points: usize,
    saved: Vec<(u32, u32, u32)>,
}

impl std::ops::Deref for LoopPart<'_> {
    type Target = Library;

    fn deref(&self) -> &Library {
        &self.skeleton.lib
    }
}

impl Drop for LoopPart<'_> {
    fn drop(&mut self) {
        let lib = &mut self.skeleton.lib;
        for &(k, first_point, points) in &self.saved {
            let tr = &mut lib.trajectories[k as usize];
            (tr.first_point, tr.points) = (first_point, points);
        }
        lib.points.truncate(self.points);
    }
}
