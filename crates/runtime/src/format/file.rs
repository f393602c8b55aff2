//! A library left in its file ([`LibraryFile`]): every record but the points in memory, checked
//! by the same rules as a library read whole, and the points read when asked, a run of
//! trajectories ([`LibraryFile::window`]) or a run of loops ([`LibraryFile::loops`]) at a time.
//! A reader that judges every point of a large library a part at a time (`crowd check` of the
//! million: 0.77 GB of points) holds the part, not the world.

use super::container::POINTS;
use super::read::{FromFile, PIECE_RECORDS, decode};
use super::records::{Character, Library, Patch, Point, Trajectory};
use super::rules::{Shape, invalid};
use crate::error::LoadError;
use std::io::{Read, Seek, SeekFrom};
use std::sync::Mutex;

/// Points [`LibraryFile::loops`] reads at a time.
const BLOCK_POINTS: usize = 1 << 17;

/// A library whose points stay in its file.
#[derive(Debug)]
pub struct LibraryFile<F> {
    /// Every record but the points: `index.points` is empty.
    index: Library,
    file: Mutex<F>,
    /// Where PNTS starts in the file, and how many points it holds.
    points_at: u64,
    points: u64,
    /// Each trajectory's last tick, as the rules checked it.
    last: Vec<u32>,
    /// The first read through `LoopPoints` that failed (which cannot say so itself).
    failed: crate::turn::FirstFailure<LoadError>,
}

/// The points of a run of trajectories, read from a [`LibraryFile`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Window {
    /// The trajectories whose points it holds.
    trajectories: std::ops::Range<usize>,
    /// PNTS index of `points[0]`.
    first: usize,
    points: Vec<Point>,
}

impl Window {
    /// The points of trajectory `i` of the library, when the window holds them.
    pub fn points_of(&self, i: usize, t: &Trajectory) -> Option<&[Point]> {
        if !self.trajectories.contains(&i) {
            return None;
        }
        let first = t.first_point as usize - self.first;
        Some(&self.points[first..first + t.points as usize])
    }

    /// The trajectories whose points it holds.
    pub fn trajectories(&self) -> std::ops::Range<usize> {
        self.trajectories.clone()
    }
}

impl<F: Read + Seek> LibraryFile<F> {
    /// Opens a library, checking what [`Library::read_from`] checks, in the same order: the
    /// same error for a file it refuses. Holds every record but the points, and each
    /// trajectory's last tick.
    pub fn open(file: F) -> Result<LibraryFile<F>, LoadError> {
        let mut src = FromFile::open(file)?;
        let mut span = 0..0;
        let index = decode(&mut src, |src| {
            span = src.check_through((POINTS, "PNTS"), Point::BYTES)?;
            Ok(Vec::new())
        })?;
        let (points_at, points) = (span.start as u64, (span.len() / Point::BYTES) as u64);
        let shapes = shapes(&mut src.file, (points_at, points), &index.trajectories)?;
        index.validate_with(points, |i| shapes[i], |i| shapes[i].last)?;
        Ok(LibraryFile {
            last: shapes.iter().map(|s| s.last).collect(),
            index,
            file: Mutex::new(src.file),
            points_at,
            points,
            failed: Default::default(),
        })
    }

    /// Every record but the points (`points` is empty: read them with [`LibraryFile::window`]
    /// or [`LibraryFile::loops`]).
    pub fn index(&self) -> &Library {
        &self.index
    }

    /// How many points the file holds.
    pub fn points(&self) -> u64 {
        self.points
    }

    /// The points of trajectories `trajectories` (of the library's order), read from the
    /// file at once: every point from the first of theirs to the last (all of a run of
    /// patches, as stage 8 writes them). Refused if the file no longer holds what it held
    /// when it was opened.
    pub fn window(&self, trajectories: std::ops::Range<usize>) -> Result<Window, LoadError> {
        let ts = &self.index.trajectories[trajectories.clone()];
        let first = ts.iter().map(|t| t.first_point as usize).min().unwrap_or(0);
        let end = (ts.iter())
            .map(|t| t.first_point as usize + t.points as usize)
            .max()
            .unwrap_or(first);
        let points = self.read(first, end - first)?;
        let window = Window {
            trajectories,
            first,
            points,
        };
        for i in window.trajectories() {
            let t = &self.index.trajectories[i];
            let points = window.points_of(i, t).expect("a trajectory of the window");
            self.unchanged(i, points)?;
        }
        Ok(window)
    }

    /// The library of loops `characters` alone, as [`Library::from_bytes`] would take it:
    /// their trajectories (in the library's order) and points, the crossings they enter and
    /// leave by, every patch with its range of them (and no standers), each loop's record
    /// pointing at its own. A reader plays or judges every loop a run at a time so.
    pub fn loops(&self, characters: std::ops::Range<usize>) -> Result<Library, LoadError> {
        // Their trajectories are asked for in the file's order (as stage 8 writes it): read a
        // block at a time, not a read a trajectory.
        let mut block: (usize, Vec<Point>) = (0, Vec::new());
        loops_of(&self.index, characters, |i, t| {
            let (first, n) = (t.first_point as usize, t.points as usize);
            if first < block.0 || first + n > block.0 + block.1.len() {
                let len = n.max(BLOCK_POINTS).min(self.points as usize - first);
                block = (first, self.read(first, len)?);
            }
            let read = &block.1[first - block.0..first - block.0 + n];
            self.unchanged(i, read)?;
            Ok(read.to_vec())
        })
    }

    /// Trajectory `i`'s last tick (its duration), as the rules checked it.
    pub fn last_tick(&self, i: usize) -> u32 {
        self.last[i]
    }

    /// Trajectory `i`'s points read from the file, refused if they are not what they were when
    /// it was opened (a long loop's part, `LoopSkeleton::part`, reads them so).
    pub fn trajectory_points(&self, i: usize) -> Result<Vec<Point>, LoadError> {
        let t = &self.index.trajectories[i];
        let read = self.read(t.first_point as usize, t.points as usize)?;
        self.unchanged(i, &read)?;
        Ok(read)
    }

    /// `count` points from PNTS index `first`.
    fn read(&self, first: usize, count: usize) -> Result<Vec<Point>, LoadError> {
        let mut bytes = vec![0u8; count * Point::BYTES];
        let mut file = self.file.lock().unwrap_or_else(|e| e.into_inner());
        file.seek(SeekFrom::Start(
            self.points_at + (first * Point::BYTES) as u64,
        ))
        .map_err(LoadError::read)?;
        file.read_exact(&mut bytes).map_err(LoadError::read)?;
        Ok(bytes
            .chunks_exact(Point::BYTES)
            .map(Point::from_le_bytes)
            .collect())
    }

    /// Whether trajectory `i`'s points read now are as the rules checked them at opening.
    fn unchanged(&self, i: usize, points: &[Point]) -> Result<(), LoadError> {
        let shape = Shape::of(points);
        if shape.ordered && shape.last == self.last[i] {
            Ok(())
        } else {
            Err(invalid(
                "PNTS",
                i as u64,
                "the points its trajectory had when the library was opened",
            ))
        }
    }
}

impl Library {
    /// The library of loops `characters` alone, as [`LibraryFile::loops`] reads it from a
    /// file.
    pub fn loops(&self, characters: std::ops::Range<usize>) -> Library {
        let points = |_, t: &Trajectory| Ok::<_, LoadError>(self.points_of(t).to_vec());
        loops_of(self, characters, points).expect("points in memory are at hand")
    }
}

/// The library of loops `characters` of `lib` alone (see [`LibraryFile::loops`]), each
/// trajectory's points (by its index in `lib`) as `read` reads them.
fn loops_of<E>(
    lib: &Library,
    characters: std::ops::Range<usize>,
    read: impl FnMut(usize, &Trajectory) -> Result<Vec<Point>, E>,
) -> Result<Library, E> {
    loops_sized(lib, characters, |_, t| t.points as usize, read)
}

/// [`loops_of`], where `read` hands over `size` points for each trajectory (by its index in
/// `lib`): its own, or fewer standing in for them ([`LoopSkeleton`](super::part::LoopSkeleton)).
pub(super) fn loops_sized<E>(
    lib: &Library,
    characters: std::ops::Range<usize>,
    size: impl Fn(usize, &Trajectory) -> usize,
    mut read: impl FnMut(usize, &Trajectory) -> Result<Vec<Point>, E>,
) -> Result<Library, E> {
    let mut mine: Vec<u32> = Vec::new();
    for ch in &lib.characters[characters.clone()] {
        let mut at = ch.first_trajectory;
        for _ in 0..ch.trajectories {
            mine.push(at);
            at = lib.trajectories[at as usize].next;
        }
    }
    // In the library's order, so that each patch's are one range (the rules hold each
    // trajectory to its patch's range) and their points are read in the file's order.
    let order = |&i: &u32| (lib.trajectories[i as usize].patch, i);
    mine.sort_unstable_by_key(order);
    let local = |i: u32| {
        let at = mine.binary_search_by_key(&order(&i), order);
        at.expect("a loop's trajectories lead on to its own") as u32
    };
    let mut crossings: Vec<u32> = (mine.iter())
        .flat_map(|&i| {
            let t = &lib.trajectories[i as usize];
            [t.entry, t.exit]
        })
        .collect();
    crossings.sort_unstable();
    crossings.dedup();
    let crossing = |c: u32| crossings.binary_search(&c).expect("a crossing of theirs") as u32;
    let mut patches: Vec<Patch> = (lib.patches.iter())
        .map(|p| Patch {
            first_trajectory: 0,
            trajectories: 0,
            first_stander: 0,
            standers: 0,
            ..*p
        })
        .collect();
    let mut trajectories = Vec::with_capacity(mine.len());
    // Made at its size: grown, the million's longest loop's (36 million points) were held
    // twice over as they were copied.
    let count = (mine.iter())
        .map(|&i| size(i as usize, &lib.trajectories[i as usize]))
        .sum();
    let mut points = Vec::with_capacity(count);
    for (k, &i) in mine.iter().enumerate() {
        let t = lib.trajectories[i as usize];
        let p = &mut patches[t.patch as usize];
        if p.trajectories == 0 {
            p.first_trajectory = k as u32;
        }
        p.trajectories += 1;
        let read = read(i as usize, &t)?;
        trajectories.push(Trajectory {
            entry: crossing(t.entry),
            exit: crossing(t.exit),
            next: local(t.next),
            first_point: points.len() as u32,
            points: read.len() as u32,
            ..t
        });
        points.extend(read);
    }
    Ok(Library {
        world: lib.world,
        patches,
        standers: Vec::new(),
        crossings: crossings
            .iter()
            .map(|&c| lib.crossings[c as usize])
            .collect(),
        trajectories,
        points,
        characters: (lib.characters[characters].iter())
            .map(|ch| Character {
                first_trajectory: local(ch.first_trajectory),
                ..*ch
            })
            .collect(),
    })
}

/// Each trajectory's [`Shape`] (the default for one whose points are not inside PNTS's
/// `count` points at `at`), read in one pass through the file: the trajectories in the order
/// of their first points, the points read ahead a piece at a time and let go once behind.
fn shapes<F: Read + Seek>(
    file: &mut F,
    (at, count): (u64, u64),
    trajectories: &[Trajectory],
) -> Result<Vec<Shape>, LoadError> {
    let inside =
        |t: &Trajectory| t.points >= 2 && u64::from(t.first_point) + u64::from(t.points) <= count;
    let mut order: Vec<u32> = (0..trajectories.len() as u32)
        .filter(|&i| inside(&trajectories[i as usize]))
        .collect();
    order.sort_unstable_by_key(|&i| trajectories[i as usize].first_point);
    let mut shapes = vec![Shape::default(); trajectories.len()];
    // `held` is PNTS from index `lo` on, from `skip` in it.
    let (mut held, mut lo, mut skip): (Vec<Point>, u64, usize) = (Vec::new(), 0, 0);
    let mut bytes = Vec::new();
    for i in order {
        let t = &trajectories[i as usize];
        let a = u64::from(t.first_point);
        let b = a + u64::from(t.points);
        if a >= lo + (held.len() - skip) as u64 {
            // Past all that is held: start again there.
            (held, lo, skip) = (Vec::new(), a, 0);
            file.seek(SeekFrom::Start(at + a * Point::BYTES as u64))
                .map_err(LoadError::read)?;
        } else {
            skip += (a - lo) as usize;
            lo = a;
            if skip > held.len() / 2 {
                held.drain(..skip);
                skip = 0;
            }
        }
        while lo + ((held.len() - skip) as u64) < b {
            let end = lo + (held.len() - skip) as u64;
            let n = (count - end).min(PIECE_RECORDS as u64) as usize;
            bytes.resize(n * Point::BYTES, 0);
            file.read_exact(&mut bytes).map_err(LoadError::read)?;
            held.extend(bytes.chunks_exact(Point::BYTES).map(Point::from_le_bytes));
        }
        shapes[i as usize] = Shape::of(&held[skip..skip + t.points as usize]);
    }
    Ok(shapes)
}

impl<F: Read + Seek + Send> LibraryFile<F> {
    /// Loop `c`'s headings packed at its keys ([`crate::turn::packed_keys_in`]), its points read
    /// from the file a trajectory at a time as the heading model walks the loop: never the
    /// loop's points (the million's longest: 36 million, 0.29 GB).
    pub fn packed_loop_keys(&self, c: usize) -> Result<Vec<u16>, LoadError> {
        let keys = crate::turn::packed_keys_in(&self.index, self, &self.index.characters[c]);
        self.failed.take().map(|()| keys)
    }
}

/// A library's points read from its file a trajectory at a time, for the heading model
/// ([`LibraryFile::packed_loop_keys`]); a read that fails is kept for it to report.
impl<F: Read + Seek + Send> crate::turn::LoopPoints for LibraryFile<F> {
    fn with<R>(&self, first: u32, n: u32, read: impl FnOnce(&[Point]) -> R) -> R {
        (self.failed).hand(self.read(first as usize, n as usize), n, read)
    }
}
