//! Every walker's pieces in a patch, kept with the box that holds them and the time span over
//! which each changed: what the encounter test reads, and what lets [`crate::rows::refresh`]
//! measure again only what changed.

use crate::encounter::box_gap_squared;
use crate::occupancy::{Kept, Occupancy, Walkers};
use crate::patch::Patch;
use crate::segment::Segment;
use glam::DVec2;

/// Every walker's straight pieces (its path with its ghosts, see [`crate::trajectory::ghosts`])
/// with the box that holds them, kept together so that the broad phase of
/// [`crate::encounter::pair`] never measures a path twice, and the time span each changed over
/// since the last [`crate::rows::refresh`].
#[derive(Debug, Clone)]
pub struct Tracks {
    segs: Vec<Vec<Segment>>,
    pub(crate) boxes: Vec<(DVec2, DVec2)>,
    /// Every path cut into runs of [`CHUNK`] pieces, each with its time span and box: the
    /// middle level of the broad phase, so that two paths that cross the same patch but are
    /// near each other only for a moment are measured piece by piece only around it.
    pub(crate) chunks: Vec<Vec<Chunk>>,
    pub(crate) changed: Vec<Option<Span>>,
    /// Where each walker comes, by slot, for tracks made [`Tracks::indexed`]; kept up to
    /// date by [`Tracks::set`].
    occupancy: Option<Occupancy>,
}

/// Pieces per [`Chunk`]: long enough that a chunk's box is worth testing, short enough that
/// a sampled curve's chunk (stage 6's curves hold a point every few tenths of a second) covers
/// a few metres at most.
pub(crate) const CHUNK: usize = 8;

/// A run of consecutive pieces of one path: `start..end` in its pieces, from `t0` to `t1`,
/// inside the box `lo`-`hi`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Chunk {
    pub t0: f64,
    pub t1: f64,
    pub lo: DVec2,
    pub hi: DVec2,
    pub start: u32,
    pub end: u32,
}

/// Who may come within reach of a walker over a stretch of its time ([`Tracks::near`]).
pub(crate) enum Near {
    /// The walkers that share a slot with it (indexed tracks).
    Sharing(Walkers),
    /// Those whose whole path's box comes within the reach of its box over the stretch (none
    /// where it has no piece there).
    Boxed(Option<(DVec2, DVec2)>, f64),
}

impl Near {
    pub(crate) fn may_meet(&self, tracks: &Tracks, other: usize) -> bool {
        match self {
            Near::Sharing(walkers) => walkers.contains(other),
            Near::Boxed(moved, reach) => {
                moved.is_some_and(|b| box_gap_squared(b, tracks.boxes[other]) <= reach * reach)
            }
        }
    }
}

/// A time span `[start, end]`, s.
pub(crate) type Span = (f64, f64);
pub(crate) const ALWAYS: Span = (f64::NEG_INFINITY, f64::INFINITY);

impl Tracks {
    pub fn new(segs: Vec<Vec<Segment>>) -> Tracks {
        let boxes = segs.iter().map(|s| bounds(s)).collect();
        let chunks = segs.iter().map(|s| chunks(s)).collect();
        let changed = vec![None; segs.len()];
        Tracks {
            segs,
            boxes,
            chunks,
            changed,
            occupancy: None,
        }
    }

    /// [`Tracks::new`], indexed by place and moment of the loop (see [`crate::occupancy`]) so
    /// that [`crate::rows`] and [`crate::refresh`] measure only the walkers that may come
    /// within reach: worth its upkeep for stage 5's few-piece walks, pushed a million times on
    /// `painting`, not for stage 6's curves, whose pairs that share no slot are the cheap ones
    /// to measure (BENCHMARKS.md, twentieth part).
    pub fn indexed(segs: Vec<Vec<Segment>>, patch: &Patch) -> Tracks {
        let occupancy = Occupancy::new(&segs, 2.0 * patch.radius_m, patch.period_s);
        Tracks {
            occupancy: Some(occupancy),
            ..Tracks::new(segs)
        }
    }

    /// Who may come within `reach` of walker `p` during `span` of `p`'s time, in any period:
    /// the others surely do not.
    pub(crate) fn near(&self, p: usize, span: Span, reach: f64) -> Near {
        match &self.occupancy {
            Some(occupancy) => Near::Sharing(occupancy.near(p, span)),
            None => Near::Boxed(self.box_during(p, span), reach),
        }
    }

    /// Walker `p` now walks `segs`.
    pub fn set(&mut self, p: usize, segs: Vec<Segment>) {
        let Some((span, kept)) = changed_span(&self.segs[p], &segs) else {
            return;
        };
        self.changed[p] =
            Some(self.changed[p].map_or(span, |c| (c.0.min(span.0), c.1.max(span.1))));
        if let Some(occupancy) = &mut self.occupancy {
            occupancy.remark(p, &segs, kept, self.segs[p].len());
        }
        self.boxes[p] = bounds(&segs);
        self.chunks[p] = chunks(&segs);
        self.segs[p] = segs;
    }

    /// The box that holds walker `p`'s pieces that overlap `span` (a run's box where the run
    /// overlaps it: a little larger, never smaller); `None` where no piece does.
    fn box_during(&self, p: usize, (lo, hi): Span) -> Option<(DVec2, DVec2)> {
        let chunks = &self.chunks[p];
        let first = chunks.partition_point(|c| c.t1 < lo);
        chunks[first..]
            .iter()
            .take_while(|c| c.t0 <= hi)
            .map(|c| (c.lo, c.hi))
            .reduce(|(lo, hi), (l, h)| (lo.min(l), hi.max(h)))
    }

    pub fn get(&self, p: usize) -> &[Segment] {
        &self.segs[p]
    }

    pub fn len(&self) -> usize {
        self.segs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.segs.is_empty()
    }
}

/// The time span over which two versions of a path differ: from the start of the first piece
/// that differs to the end of the last (`None`: the same pieces); and how many pieces at
/// either end are the same.
fn changed_span(old: &[Segment], new: &[Segment]) -> Option<(Span, Kept)> {
    let n = old.len().min(new.len());
    let head = (0..n).take_while(|&i| old[i] == new[i]).count();
    if head == old.len() && head == new.len() {
        return None;
    }
    let tail = (0..n - head)
        .take_while(|&i| old[old.len() - 1 - i] == new[new.len() - 1 - i])
        .count();
    let first = |v: &[Segment]| v.get(head).map_or(f64::INFINITY, |s| s.t0);
    let last = |v: &[Segment]| {
        if v.len() > head + tail {
            v[v.len() - 1 - tail].t1
        } else {
            f64::NEG_INFINITY
        }
    };
    let (start, end) = (first(old).min(first(new)), last(old).max(last(new)));
    Some(((start.min(end), start.max(end)), Kept { head, tail }))
}

/// The corners of the box that holds a path.
fn bounds(segs: &[Segment]) -> (DVec2, DVec2) {
    segs.iter().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(lo, hi), s| (lo.min(s.p0).min(s.p1), hi.max(s.p0).max(s.p1)),
    )
}

/// A path's pieces in runs of [`CHUNK`].
fn chunks(segs: &[Segment]) -> Vec<Chunk> {
    segs.chunks(CHUNK)
        .enumerate()
        .map(|(k, run)| {
            let (lo, hi) = bounds(run);
            let start = k * CHUNK;
            Chunk {
                t0: run[0].t0,
                t1: run[run.len() - 1].t1,
                lo,
                hi,
                start: start as u32,
                end: (start + run.len()) as u32,
            }
        })
        .collect()
}
