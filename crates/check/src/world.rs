//! The collision core of every check: walkers' pieces in world coordinates, standers and
//! obstacle boxes, and the exact closest approach of every pair that comes near (a spatial
//! grid of 4 m cells, `crowd_geometry::PieceGrid`), each pair counted once at its closest.
//!
//! Two ways walkers repeat in time: trajectories of a tiled world ([`Repeat::Periodic`]: every
//! copy a whole number of periods apart, and a trajectory meets the one that continues it only
//! at other shifts than the one where they are the same character), and the nodes of a looping
//! clip ([`Repeat::Clip`]: every node plays over the same clip time, so pairs are compared at
//! equal times only and a node never meets itself).

use crowd_geometry::{self as geometry, BoxGrid, PieceGrid, Segment};
use glam::DVec2;
use rayon::prelude::*;
use std::collections::HashMap;

/// One straight piece of a walker's path, in world metres and seconds.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Piece {
    pub seg: Segment,
    pub walker: u32,
    pub patch: u32,
}

/// The crossings a walker's trajectory enters and leaves by, and when (unwrapped).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Ends {
    pub entry: (u32, f64),
    pub exit: (u32, f64),
}

/// How the walkers of a scene repeat in time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Repeat {
    /// Every walker forever, a period apart (the tiled world of the stage files and library).
    Periodic(f64),
    /// Every walker over one clip of this length, all at the same clip time (`world.glb`).
    Clip(f64),
}

impl Repeat {
    fn period(self) -> f64 {
        match self {
            Repeat::Periodic(p) | Repeat::Clip(p) => p,
        }
    }
}

/// Everything that takes up room in a world.
#[derive(Debug)]
pub(crate) struct Scene {
    pub radius: f64,
    pub repeat: Repeat,
    pub pieces: Vec<Piece>,
    /// Each walker's ends, by walker ([`Repeat::Periodic`] only).
    pub ends: Vec<Ends>,
    pub standers: Vec<DVec2>,
    /// Obstacle boxes, world metres (min, max).
    pub walls: Vec<crate::Wall>,
    /// The patches whose pairs this scene counts. A pair of walkers belongs to the lower of
    /// their two patches, a walker's pairs with what stands still to its own: a strip of the
    /// world is checked with the patches around it present but not counted, and every pair is
    /// counted in exactly one strip.
    pub owned: Owned,
}

/// The patches whose pairs a [`Scene`] counts.
#[derive(Debug, Clone, PartialEq)]
pub enum Owned {
    Every,
    /// Patch `p` is counted when `set[p]`.
    Only(Vec<bool>),
}

impl Owned {
    /// `patches` of a world of `of` patches.
    pub fn only(patches: &[usize], of: usize) -> Owned {
        let mut set = vec![false; of];
        patches.iter().for_each(|&p| set[p] = true);
        Owned::Only(set)
    }

    #[inline]
    pub fn contains(&self, patch: u32) -> bool {
        match self {
            Owned::Every => true,
            Owned::Only(set) => set.get(patch as usize).copied().unwrap_or(false),
        }
    }
}

/// The pairs a scene (or a strip of one) counts: collisions, and the nearest approaches,
/// kept apart so that strips add up to what the whole scene gives ([`Pairs::merge`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Pairs {
    collisions: u64,
    across_borders: u64,
    nearest_walkers: Option<Near>,
    nearest_fixed: Option<Margin>,
}

impl Pairs {
    /// Both parts' pairs (parts that count disjoint pairs, in any order).
    pub fn merge(self, o: Pairs) -> Pairs {
        Pairs {
            collisions: self.collisions + o.collisions,
            across_borders: self.across_borders + o.across_borders,
            nearest_walkers: nearer(self.nearest_walkers, o.nearest_walkers),
            nearest_fixed: nearer(self.nearest_fixed, o.nearest_fixed),
        }
    }

    /// For a memo (`memo.rs`).
    pub fn put(&self, o: &mut crate::memo::Bytes) {
        o.u64(self.collisions);
        o.u64(self.across_borders);
        o.option(&self.nearest_walkers, |o, n| {
            o.f64(n.0);
            o.f64(n.1);
            o.vec2(n.2);
            o.u8(u8::from(n.3));
        });
        o.option(&self.nearest_fixed, |o, m| {
            o.f64(m.0);
            o.f64(m.1);
            o.vec2(m.2);
        });
    }

    pub fn get(r: &mut crate::memo::Reader) -> Option<Pairs> {
        Some(Pairs {
            collisions: r.u64()?,
            across_borders: r.u64()?,
            nearest_walkers: r.option(|r| Some((r.f64()?, r.f64()?, r.vec2()?, r.u8()? != 0)))?,
            nearest_fixed: r.option(|r| Some((r.f64()?, r.f64()?, r.vec2()?)))?,
        })
    }

    /// The figures of the pairs, for characters of `radius` repeating every `period`.
    pub fn clearance(self, radius: f64, period: f64) -> Clearance {
        let mut c = Clearance {
            collisions: self.collisions,
            across_borders: self.across_borders,
            min_clearance_m: f64::INFINITY,
            worst_at: None,
        };
        let mut note = |margin: f64, at: DVec2, t: f64| {
            if margin < c.min_clearance_m {
                c.min_clearance_m = margin;
                c.worst_at = Some((at.x, at.y, t.rem_euclid(period)));
            }
        };
        if let Some((d, t, at, _)) = self.nearest_walkers {
            note(d - 2.0 * radius, at, t);
        }
        if let Some((margin, t, at)) = self.nearest_fixed {
            note(margin, at, t);
        }
        c
    }
}

/// How close the characters of a scene come.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Clearance {
    pub collisions: u64,
    pub across_borders: u64,
    pub min_clearance_m: f64,
    pub worst_at: Option<(f64, f64, f64)>,
}

/// The period shifts at which `b`'s trajectory continues `a`'s or `a`'s continues `b`'s (the
/// same character going on through the crossing between them; both when it goes back and
/// forth).
fn continuations(a: &Ends, b: &Ends, period: f64) -> [Option<i64>; 2] {
    let shift = |x: f64, y: f64| Some(((x - y) / period).round() as i64);
    [
        if a.exit.0 == b.entry.0 {
            shift(a.exit.1, b.entry.1)
        } else {
            None
        },
        if b.exit.0 == a.entry.0 {
            shift(a.entry.1, b.exit.1)
        } else {
            None
        },
    ]
}

/// A pair's closest approach: distance, time, place, and whether in different patches.
type Near = (f64, f64, DVec2, bool);
/// A piece in a cell's time sweep: start and end (modulo the period when walkers repeat), its
/// index, and its path's box.
type Span = (f64, f64, u32, DVec2, DVec2);

/// `x`'s bits as an integer in `f64::total_cmp`'s order.
fn ordered_bits(x: f64) -> u64 {
    let bits = x.to_bits();
    if bits >> 63 == 1 {
        !bits
    } else {
        bits | 1 << 63
    }
}

/// A walker's closest approach to something standing still: clearance margin, time, place.
type Margin = (f64, f64, DVec2);
/// Pairs that collide, each at its closest, and the nearest approach of any pair per patch that
/// owns it (a patch may come more than once; [`Nearest::of`] keeps its nearest).
type Found<K, V> = (Vec<(K, V)>, Vec<(u32, V)>);

/// Notes approach `v` of a pair owned by `owner` in `list`, which a cell or a piece fills in
/// patch runs (only its last entry is looked at: a repeat further back is kept apart and
/// folded later).
fn note<V: Copy + Closer>(list: &mut Vec<(u32, V)>, owner: u32, v: V) {
    match list.last_mut() {
        Some(last) if last.0 == owner => {
            if v.closer(&last.1) {
                last.1 = v;
            }
        }
        _ => list.push((owner, v)),
    }
}

impl Scene {
    /// Whether the pair of `a` and `b` is counted here (it belongs to the lower patch).
    fn owns_pair(&self, a: &Piece, b: &Piece) -> bool {
        self.owned.contains(a.patch.min(b.patch))
    }

    /// Files one walker's path (world metres and seconds, in time order) as pieces. Callers
    /// reserve the pieces first: grown by doubling, painting's 16 M pieces were copied and
    /// first-touched twice over (a tenth of the check's page faults).
    pub(crate) fn push_path(
        &mut self,
        walker: u32,
        patch: u32,
        mut points: impl Iterator<Item = (DVec2, f64)>,
    ) {
        let Some(mut prev) = points.next() else {
            return;
        };
        for next in points {
            let seg = Segment {
                p0: prev.0,
                t0: prev.1,
                p1: next.0,
                t1: next.1,
            };
            self.pieces.push(Piece { seg, walker, patch });
            prev = next;
        }
    }

    /// The closest approach of pieces `a` and `b` over the copies that can meet, if any.
    fn pair(&self, a: &Piece, b: &Piece) -> Option<(f64, f64, DVec2)> {
        let (ks, skip) = match self.repeat {
            Repeat::Clip(_) if a.walker == b.walker => return None,
            Repeat::Clip(_) => (0..=0, [None; 3]),
            Repeat::Periodic(period) => {
                // A walker meets only its own copies a period or more apart, and the
                // trajectory that continues it across a border (itself, when it leaves by the
                // crossing it entered by) only at other shifts than the one where it is the
                // same character going on.
                let ends = |p: &Piece| &self.ends[p.walker as usize];
                let [x, y] = continuations(ends(a), ends(b), period);
                let skip = [(a.walker == b.walker).then_some(0), x, y];
                let ks = geometry::copies((a.seg.t0, a.seg.t1), (b.seg.t0, b.seg.t1), period);
                (ks, skip)
            }
        };
        let period = self.repeat.period();
        ks.filter(|&k| !skip.contains(&Some(k)))
            .filter_map(|k| {
                let s = b.seg.shifted(k as f64 * period);
                geometry::closest(&a.seg, &s).map(|(d, t)| (d, t, a.seg.at(t)))
            })
            .min_by(|x, y| x.0.total_cmp(&y.0))
    }

    /// Piece `i`'s time span (its start modulo the period when walkers repeat, widened by a
    /// nanosecond so that rounding in the modulo never drops a pair that [`Scene::pair`] would
    /// compare) and path box. Made cell by cell: kept for the whole world, painting's 9 M
    /// pieces held half a gigabyte more at the check's peak.
    fn span(&self, i: u32) -> Span {
        const WIDEN: f64 = 1e-9;
        let (period, periodic) = self.periodicity();
        let s = &self.pieces[i as usize].seg;
        let start = if periodic {
            s.t0.rem_euclid(period)
        } else {
            s.t0
        };
        let (lo, hi) = (s.p0.min(s.p1), s.p0.max(s.p1));
        (start, start + (s.t1 - s.t0) + WIDEN, i, lo, hi)
    }

    fn periodicity(&self) -> (f64, bool) {
        match self.repeat {
            Repeat::Periodic(p) => (p, true),
            Repeat::Clip(p) => (p, false),
        }
    }

    /// Calls `visit` with the pairs of pieces `ids` whose times overlap, modulo the period
    /// when walkers repeat ([`Scene::span`]). A piece's span is swept against
    /// the others' starts (sorted, as integers: a comparison of floats made the sort a tenth
    /// of the check), so a cell's pieces are not all compared with all: they are spread over
    /// the whole period. Pairs whose paths are `reach` or farther apart along an axis are left
    /// out; `visit` is told how far apart the two are along the axis where they are farthest
    /// (negative where their boxes overlap: never more than their distance). A pair may come
    /// twice (a span that wraps past the period meets one both ways), which the callers'
    /// keyed minima do not mind: sorting a dense cell's pairs to drop the few twins cost more
    /// than measuring them (a quarter of the check).
    fn coexisting(&self, ids: &[u32], reach: f64, mut visit: impl FnMut(u32, u32, f64)) {
        let (period, periodic) = self.periodicity();
        let mut cell: Vec<Span> = ids.iter().map(|&i| self.span(i)).collect();
        cell.sort_unstable_by_key(|s| (ordered_bits(s.0), s.2));
        // The box test is written out in each loop, `visit` called only past it: as a
        // closure called for every pair, it was a call per pair (a sixth of the check). One
        // loop over the runs chained, or flattened, took 3-4 % more of the check's time.
        for (x, &(start, end, i, lo, hi)) in cell.iter().enumerate() {
            if periodic && end - start >= period {
                for o in cell.iter().filter(|o| o.2 != i) {
                    let apart = (o.3 - hi).max(lo - o.4).max_element();
                    if apart < reach {
                        visit(i, o.2, apart);
                    }
                }
                continue;
            }
            // Those starting during this one: after it in order, and from the period's start
            // again when it runs past the period's end.
            for o in cell[x + 1..].iter().take_while(|o| o.0 <= end) {
                let apart = (o.3 - hi).max(lo - o.4).max_element();
                if apart < reach {
                    visit(i, o.2, apart);
                }
            }
            if periodic && end > period {
                for o in cell[..x].iter().take_while(|o| o.0 <= end - period) {
                    let apart = (o.3 - hi).max(lo - o.4).max_element();
                    if apart < reach {
                        visit(i, o.2, apart);
                    }
                }
            }
        }
    }

    /// Every walker pair closer than the clearance, at its closest, in pair order; and the
    /// closest approach of any pair (`None` when no two come within reach). Only those are
    /// kept: a painting's pairs within reach ran to gigabytes.
    fn walker_pairs(&self) -> Found<(u32, u32), Near> {
        self.walker_pairs_with(true)
    }

    /// [`Scene::walker_pairs`], measuring every pair of pieces that come within reach when
    /// not `prune` (the reference its tests hold it to).
    fn walker_pairs_with(&self, prune: bool) -> Found<(u32, u32), Near> {
        let r = self.radius;
        let grid = PieceGrid::new(self.pieces.iter().map(|p| &p.seg), 4.0, 2.0 * r);
        let reach = 2.0 * r + 1.0;
        // Found once each: in the cell holding the lower corner of their overlap.
        let found = grid
            .cells()
            .par_iter()
            .map(|(k, ids)| {
                let mut out = Vec::new();
                let mut nearest: Vec<(u32, Near)> = Vec::new();
                // The nearest distance found so far in this cell, per owning patch.
                let mut so_far: Vec<(u32, f64)> = Vec::new();
                self.coexisting(ids, reach, |i, j, apart| {
                    if !grid.owns(*k, i, j) {
                        return;
                    }
                    // In index order, as the pair's closest place is the lower one's.
                    let (a, b) = (
                        &self.pieces[i.min(j) as usize],
                        &self.pieces[i.max(j) as usize],
                    );
                    if !self.owns_pair(a, b) {
                        return;
                    }
                    let owner = a.patch.min(b.patch);
                    let found = so_far.iter().position(|s| s.0 == owner);
                    // Pieces farther apart than the clearance and than the nearest pair of
                    // their patch so far can be neither a collision nor its nearest pair
                    // (not measuring them took 7 % off the check's time on `painting`).
                    if prune && apart >= 2.0 * r && found.is_some_and(|f| apart > so_far[f].1) {
                        return;
                    }
                    if let Some((d, t, at)) = self.pair(a, b)
                        && d < reach
                    {
                        match found {
                            Some(f) => so_far[f].1 = so_far[f].1.min(d),
                            None => so_far.push((owner, d)),
                        }
                        let near = (d, t, at, a.patch != b.patch);
                        note(&mut nearest, owner, near);
                        if d - 2.0 * r < -COLLISION_M {
                            let key = (a.walker.min(b.walker), a.walker.max(b.walker));
                            out.push((key, near));
                        }
                    }
                });
                (out, nearest)
            })
            .reduce(|| (Vec::new(), Vec::new()), merge);
        gathered(found)
    }

    /// Every walker against every stander and obstacle it comes closer to than it may (they
    /// stand still: no copies), each pair at its closest however many pieces of the walker come
    /// near: clearance margin, time, place; and the smallest margin of any within reach.
    fn fixed_pairs(&self) -> Found<(u32, Fixed), Margin> {
        let r = self.radius;
        let standers = BoxGrid::new(self.standers.iter().map(|&q| (q, q)), 4.0, 2.0 * r + 1.0);
        let walls = BoxGrid::new(self.walls.iter().copied(), 4.0, r + 1.0);
        let found = self
            .pieces
            .par_iter()
            .filter(|piece| self.owned.contains(piece.patch))
            .map(|piece| {
                let s = &piece.seg;
                let (lo, hi) = (s.p0.min(s.p1), s.p0.max(s.p1));
                let mut out = Vec::new();
                // The smallest margin found so far for this piece.
                let mut best = f64::INFINITY;
                standers.near(lo, hi, |i| {
                    let q = self.standers[i as usize];
                    if (q - hi).max(lo - q).max_element() >= 2.0 * r + 1.0 {
                        return;
                    }
                    if let Some((d, t)) = geometry::closest(s, &Segment::standing(q, s.t0, s.t1))
                        && d < 2.0 * r + 1.0
                    {
                        best = best.min(d - 2.0 * r);
                        out.push(((piece.walker, Fixed::Stander(i)), (d - 2.0 * r, t, s.at(t))));
                    }
                });
                walls.near(lo, hi, |i| {
                    let (min, max) = self.walls[i as usize];
                    if (min - hi).max(lo - max).max_element() > r + 1.0 {
                        return; // farther apart along an axis than the reach
                    }
                    // `to_rect`'s search never finds less than the exact distance: a wall
                    // beyond the nearest so far and clear of the body changes no figure, and
                    // its search was a twentieth of the check.
                    let exact = geometry::distance_to_rect(s, min, max) - r;
                    if exact >= 1.0 || (exact > best && exact >= -COLLISION_M) {
                        return;
                    }
                    let (d, t, _) = geometry::to_rect(s, min, max);
                    if d < r + 1.0 {
                        best = best.min(d - r);
                        out.push(((piece.walker, Fixed::Wall(i)), (d - r, t, s.at(t))));
                    }
                });
                let nearest = out.iter().map(|e| Some(e.1)).fold(None, nearer);
                out.retain(|e| e.1.0 < -COLLISION_M);
                (out, nearest.map(|n| (piece.patch, n)).into_iter().collect())
            })
            .reduce(|| (Vec::new(), Vec::new()), merge);
        gathered(found)
    }

    /// The pairs this scene counts ([`Scene::owned`]), added up in pair order.
    pub fn pairs(&self) -> Pairs {
        self.pairs_by_patch()
            .into_iter()
            .fold(Pairs::default(), |a, (_, b)| a.merge(b))
    }

    /// The pairs this scene counts, per patch that owns them (a pair of walkers belongs to the
    /// lower of their patches, a walker's pairs with what stands still to its own), in patch
    /// order: what a check keeps of a patch between builds.
    pub fn pairs_by_patch(&self) -> Vec<(u32, Pairs)> {
        let mut patch_of = vec![0u32; self.walker_count()];
        self.pieces
            .iter()
            .for_each(|p| patch_of[p.walker as usize] = p.patch);
        let (walkers, nearest_walkers) = self.walker_pairs();
        let (fixed, nearest_fixed) = self.fixed_pairs();
        let mut by: std::collections::BTreeMap<u32, Pairs> = std::collections::BTreeMap::new();
        for ((a, b), near) in walkers {
            let e = by
                .entry(patch_of[a as usize].min(patch_of[b as usize]))
                .or_default();
            e.collisions += 1;
            e.across_borders += u64::from(near.3);
        }
        for ((w, _), _) in fixed {
            by.entry(patch_of[w as usize]).or_default().collisions += 1;
        }
        for (owner, near) in nearest_walkers {
            by.entry(owner).or_default().nearest_walkers = Some(near);
        }
        for (owner, margin) in nearest_fixed {
            by.entry(owner).or_default().nearest_fixed = Some(margin);
        }
        by.into_iter().collect()
    }

    /// One more than the highest walker index of a piece (0 with none).
    fn walker_count(&self) -> usize {
        self.pieces
            .iter()
            .map(|p| p.walker as usize + 1)
            .max()
            .unwrap_or(0)
    }

    /// Collisions and the smallest clearance over every pair the scene counts.
    pub fn clearance(&self) -> Clearance {
        self.pairs().clearance(self.radius, self.repeat.period())
    }
}

/// Two parts' colliding pairs and nearest approaches as one.
fn merge<K, V: Copy + Closer>(mut a: Found<K, V>, b: Found<K, V>) -> Found<K, V> {
    a.0.extend(b.0);
    a.1.extend(b.1);
    a
}

/// The colliding pairs found, each once at its closest and in key order, and the nearest per
/// owning patch, in patch order.
fn gathered<K: Ord + std::hash::Hash + Copy, V: Copy + Closer>(
    (found, nearest): Found<K, V>,
) -> Found<K, V> {
    let mut per_patch: std::collections::BTreeMap<u32, V> = std::collections::BTreeMap::new();
    for (owner, v) in nearest {
        let e = per_patch.entry(owner).or_insert(v);
        if v.closer(e) {
            *e = v;
        }
    }
    (closest_per_key(found), per_patch.into_iter().collect())
}

/// How far inside the clearance a pair must come to count as a collision, m (rounding).
const COLLISION_M: f64 = 1e-6;

/// The nearer of two approaches, by [`Closer`] (so the result does not depend on the order the
/// parallel work met them in).
fn nearer<V: Copy + Closer>(a: Option<V>, b: Option<V>) -> Option<V> {
    match (a, b) {
        (Some(x), Some(y)) => Some(if y.closer(&x) { y } else { x }),
        (x, None) => x,
        (None, y) => y,
    }
}

/// The smallest-first entry of each key, sorted by key (so sums over them do not depend on
/// how the parallel work was split).
fn closest_per_key<K: Ord + std::hash::Hash + Copy, V: Copy + Closer>(
    found: Vec<(K, V)>,
) -> Vec<(K, V)> {
    let mut closest: HashMap<K, V> = HashMap::new();
    for (k, v) in found {
        let e = closest.entry(k).or_insert(v);
        if v.closer(e) {
            *e = v;
        }
    }
    let mut pairs: Vec<_> = closest.into_iter().collect();
    pairs.sort_by_key(|(k, _)| *k);
    pairs
}

/// Which of two approaches of one pair is kept: the smaller distance (or margin), then the
/// earlier time and the lower place, so that the kept one does not depend on the order they
/// were found in.
trait Closer {
    fn closer(&self, other: &Self) -> bool;
}

fn closer(a: (f64, f64, DVec2), b: (f64, f64, DVec2)) -> bool {
    let order = a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1));
    let order = order
        .then(a.2.x.total_cmp(&b.2.x))
        .then(a.2.y.total_cmp(&b.2.y));
    order.is_lt()
}

impl Closer for Near {
    fn closer(&self, o: &Self) -> bool {
        closer((self.0, self.1, self.2), (o.0, o.1, o.2))
    }
}

impl Closer for Margin {
    fn closer(&self, o: &Self) -> bool {
        closer(*self, *o)
    }
}

/// What stands still in the world: a stander or an obstacle box, by index.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
enum Fixed {
    Stander(u32),
    Wall(u32),
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn scene(spans: &[(f64, f64)], repeat: Repeat) -> Scene {
        let pieces = spans
            .iter()
            .enumerate()
            .map(|(i, &(t0, dt))| Piece {
                seg: Segment::standing(DVec2::ZERO, t0, t0 + dt),
                walker: i as u32,
                patch: 0,
            })
            .collect();
        Scene {
            radius: 0.3,
            repeat,
            pieces,
            ends: vec![],
            standers: vec![],
            walls: vec![],
            owned: Owned::Every,
        }
    }

    /// Walkers crossing a 12 m square in a few straight pieces each, over a 20 s clip, each
    /// counted in one of four patches: crowded enough that many collide.
    fn crowd() -> impl Strategy<Value = Scene> {
        let walker = (
            proptest::collection::vec((0.0f64..12.0, 0.0f64..12.0), 2..6),
            0.0f64..10.0,
            0.5f64..3.0,
            0u32..4,
        );
        proptest::collection::vec(walker, 2..40).prop_map(|walkers| {
            let mut pieces = Vec::new();
            for (w, (points, start, step, patch)) in walkers.into_iter().enumerate() {
                for (k, pair) in points.windows(2).enumerate() {
                    let t0 = start + k as f64 * step;
                    pieces.push(Piece {
                        seg: Segment {
                            p0: DVec2::new(pair[0].0, pair[0].1),
                            t0,
                            p1: DVec2::new(pair[1].0, pair[1].1),
                            t1: t0 + step,
                        },
                        walker: w as u32,
                        patch,
                    });
                }
            }
            Scene {
                radius: 0.3,
                repeat: Repeat::Clip(20.0),
                pieces,
                ends: vec![],
                standers: vec![],
                walls: vec![],
                owned: Owned::Every,
            }
        })
    }

    proptest! {
        /// Leaving out the pieces farther apart than the clearance and than their patch's
        /// nearest pair so far finds every collision and every patch's nearest pair, exactly.
        #[test]
        fn pairs_left_out_change_no_collision_and_no_nearest(scene in crowd()) {
            prop_assert_eq!(scene.walker_pairs_with(true), scene.walker_pairs_with(false));
        }

        /// The sweep's integer sort orders starts as `f64::total_cmp` does.
        #[test]
        fn ordered_bits_order_as_floats(a in any::<f64>(), b in any::<f64>()) {
            prop_assert_eq!(ordered_bits(a).cmp(&ordered_bits(b)), a.total_cmp(&b));
        }

        /// The time sweep keeps every pair of pieces that exist at a common time (modulo the
        /// period, when walkers repeat): every pair `Scene::pair` would find a copy of.
        #[test]
        fn the_sweep_keeps_every_pair_that_coexists(
            spans in proptest::collection::vec((0.0f64..60.0, 0.0f64..25.0), 2..30),
            periodic in any::<bool>(),
        ) {
            let repeat = if periodic { Repeat::Periodic(20.0) } else { Repeat::Clip(20.0) };
            let s = scene(&spans, repeat);
            let ids: Vec<u32> = (0..spans.len() as u32).collect();
            let mut kept = std::collections::HashSet::new();
            s.coexisting(&ids, f64::INFINITY, |i, j, _| {
                kept.insert((i.min(j), i.max(j)));
            });
            for i in 0..spans.len() {
                for j in i + 1..spans.len() {
                    let (a, b) = (&s.pieces[i].seg, &s.pieces[j].seg);
                    let meet = if periodic {
                        !geometry::copies((a.t0, a.t1), (b.t0, b.t1), 20.0).is_empty()
                    } else {
                        a.t0.max(b.t0) <= a.t1.min(b.t1)
                    };
                    if meet {
                        prop_assert!(kept.contains(&(i as u32, j as u32)), "{} {}", i, j);
                    }
                }
            }
        }
    }
}
