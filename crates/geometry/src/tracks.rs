//! Every walker's pieces in a patch, kept with the box that holds them and the time span over
//! which each changed: what the encounter test reads, and what lets [`crate::rows::refresh`]
//! measure again only what changed.

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
    pub(crate) changed: Vec<Option<Span>>,
}

/// A time span `[start, end]`, s.
pub(crate) type Span = (f64, f64);
pub(crate) const ALWAYS: Span = (f64::NEG_INFINITY, f64::INFINITY);

impl Tracks {
    pub fn new(segs: Vec<Vec<Segment>>) -> Tracks {
        let boxes = segs.iter().map(|s| bounds(s)).collect();
        let changed = vec![None; segs.len()];
        Tracks {
            segs,
            boxes,
            changed,
        }
    }

    /// Walker `p` now walks `segs`.
    pub fn set(&mut self, p: usize, segs: Vec<Segment>) {
        if let Some(span) = changed_span(&self.segs[p], &segs) {
            self.changed[p] =
                Some(self.changed[p].map_or(span, |c| (c.0.min(span.0), c.1.max(span.1))));
        }
        self.boxes[p] = bounds(&segs);
        self.segs[p] = segs;
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
/// that differs to the end of the last (`None`: the same pieces).
fn changed_span(old: &[Segment], new: &[Segment]) -> Option<Span> {
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
    Some((start.min(end), start.max(end)))
}

/// The corners of the box that holds a path.
fn bounds(segs: &[Segment]) -> (DVec2, DVec2) {
    segs.iter().fold(
        (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)),
        |(lo, hi), s| (lo.min(s.p0).min(s.p1), hi.max(s.p0).max(s.p1)),
    )
}
