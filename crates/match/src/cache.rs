//! Stage 3 measures a patch again and again after adding, removing or turning a crossing or
//! two; [`ScoreCache`] keeps what does not change between those measurements, so that one
//! costs its new pairs, not the patch's n^2.
//!
//! Every entry and exit lives in a slot that keeps its pair scores while it stays in the set,
//! and for a while after it leaves (the polish's next try often puts it back). Each entry's
//! slot also keeps its best exit, so the stable matching of `stable.rs` (the least free pair of
//! the order (score, entry, exit), again and again) starts from the entries' bests and scans a
//! row again only when its best is taken: a heap of rows instead of the rows' n^2 scans. The
//! figures are exactly [`crate::measure_patch`]'s: `tests.rs` holds them to it, and the
//! matching to [`crate::stable::gale_shapley`].

use crate::{Endpoint, PatchContext, plan, score};
use crowd_core::patterns::Measured;
use glam::DVec2;
use std::cmp::Reverse;

/// What a pair's score and duration depend on at one end: where, when, how fast and on which
/// side (the bits of x, y, t, vx, vy and the side; the patch's context being fixed).
type PointKey = [u64; 6];

fn point_keys(points: &[Endpoint]) -> Vec<PointKey> {
    points
        .iter()
        .map(|e| {
            let [x, y, t, vx, vy] =
                [e.pos.x, e.pos.y, e.t, e.velocity.x, e.velocity.y].map(f64::to_bits);
            [x, y, t, vx, vy, e.side as u64]
        })
        .collect()
}

/// A pair score as an integer in the same order as `<` reads the score (-0 as +0), so that
/// comparisons are exact and cheap.
fn order_key(s: f64) -> u64 {
    let bits = (s + 0.0).to_bits();
    if bits >> 63 == 1 {
        !bits
    } else {
        bits | 1 << 63
    }
}

/// Points that left the set whose slots keep their scores, at most, per side.
const KEEP_LEFT: usize = 8;

/// Exits kept in order per entry when its best is taken (see [`ScoreCache::shortlist`]).
const SHORTLIST: usize = 8;

thread_local! {
    /// The matching's shortlists, one buffer per thread rather than per patch.
    static SHORTLISTS: std::cell::Cell<Vec<u128>> = const { std::cell::Cell::new(Vec::new()) };
}

/// Endpoint sets a [`ScoreCache`] remembers the figures of, at most; it forgets them all
/// when full (a patch measured many times over keeps the recent ones).
pub const MEMO_SIZE: usize = 64;

/// Not in the current set.
const GONE: u32 = u32::MAX;

/// The slots of one side (entries or exits). Measurements are counted (epochs): the scores of
/// two slots are those of their points when both have held them since a measurement that had
/// both.
#[derive(Debug, Clone, Default)]
struct Slots {
    /// Per slot: its point, its place in the current set ([`GONE`] when not in it), the epoch
    /// since which it has been in the set, the one at which it last left (0: it never held its
    /// point before), and a number that changes whenever it takes a new point.
    key: Vec<PointKey>,
    pos: Vec<u32>,
    since: Vec<u64>,
    left_at: Vec<u64>,
    generation: Vec<u32>,
    /// The current set's points and slots, by place.
    keys: Vec<PointKey>,
    at: Vec<u32>,
    /// Slots whose points left, oldest first (at most [`KEEP_LEFT`]), and slots free to take.
    left: Vec<u32>,
    free: Vec<u32>,
}

/// Old places looked at ahead of the last one found, for each new point.
const LOOK_AHEAD: usize = 4;

/// Where each of `new` was in `old`, if it was, in order: the lists come from the same borders
/// in the same order, so each key is looked for in the few old places after the last one found.
/// A point that stays but is not found there (many left before it, or the order changed) reads
/// as one that left and came back, and takes its slot back with its scores (`Slots::back`).
fn old_places(old: &[PointKey], new: &[PointKey]) -> Vec<Option<usize>> {
    let mut from = 0;
    new.iter()
        .map(|key| {
            let window = &old[from.min(old.len())..(from + LOOK_AHEAD).min(old.len())];
            let found = window.iter().position(|k| k == key).map(|k| from + k);
            if let Some(g) = found {
                from = g + 1;
            }
            found
        })
        .collect()
}

impl Slots {
    /// Takes in the new set, `places` being where each point was in the last one. Returns the
    /// places of the points that came in (new or back).
    fn take(&mut self, keys: Vec<PointKey>, places: &[Option<usize>], epoch: u64) -> Vec<usize> {
        let mut stays = vec![false; self.at.len()];
        for p in places.iter().flatten() {
            stays[*p] = true;
        }
        for (&s, _) in self.at.iter().zip(&stays).filter(|(_, stays)| !**stays) {
            self.pos[s as usize] = GONE;
            self.left_at[s as usize] = epoch;
            self.left.push(s);
        }
        let mut at = Vec::with_capacity(keys.len());
        let mut came = Vec::new();
        for (i, (key, place)) in keys.iter().zip(places).enumerate() {
            at.push(match place {
                Some(p) => self.at[*p],
                None => {
                    came.push(i);
                    self.back(key).unwrap_or(GONE)
                }
            });
        }
        let overflow = self.left.len().saturating_sub(KEEP_LEFT);
        self.free.extend(self.left.drain(..overflow));
        for &i in &came {
            if at[i] == GONE {
                at[i] = self.fresh(keys[i]);
            }
            self.since[at[i] as usize] = epoch;
        }
        for (i, &s) in at.iter().enumerate() {
            self.pos[s as usize] = i as u32;
        }
        self.at = at;
        self.keys = keys;
        came
    }

    /// The slot that held `key` before it left (maybe just now), taken back: the latest to
    /// leave first, among the last few (a set that changed whole, as after re-timing, would
    /// otherwise compare n^2 keys for nothing).
    fn back(&mut self, key: &PointKey) -> Option<u32> {
        let from = self.left.len().saturating_sub(2 * KEEP_LEFT);
        let k = self.left[from..].iter().rposition(|&s| {
            let other = &self.key[s as usize];
            other[2] == key[2] && other == key
        })?;
        Some(self.left.remove(from + k))
    }

    /// A slot for a point it never held.
    fn fresh(&mut self, key: PointKey) -> u32 {
        match self.free.pop() {
            Some(s) => {
                let i = s as usize;
                self.key[i] = key;
                self.left_at[i] = 0;
                self.generation[i] = self.generation[i].wrapping_add(1);
                s
            }
            None => {
                self.key.push(key);
                self.pos.push(GONE);
                self.since.push(0);
                self.left_at.push(0);
                self.generation.push(0);
                (self.key.len() - 1) as u32
            }
        }
    }
}

/// A patch's pair scores and matched pairs, kept between measurements (see the module
/// comment). The figures are exactly those [`crate::measure_patch`] computes.
///
/// It also remembers the figures of the patch's recent endpoint sets ([`MEMO_SIZE`] at most):
/// stage 3's polish tries many changes along cycles that share a border with the patch, and a
/// third of ring's measurements were of a set measured before (the same crossing removed or
/// turned by another cycle).
#[derive(Debug, Clone, Default)]
pub struct ScoreCache {
    memo: foldhash::HashMap<u128, Measured>,
    epoch: u64,
    entries: Slots,
    exits: Slots,
    /// Scores as [`order_key`]s, `[entry slot * width + exit slot]`.
    scores: Vec<u64>,
    width: usize,
    /// Per entry slot, its least (score, place) exit slot in the set.
    best: Vec<u32>,
    /// Per entry slot, the exit slot (and its generation) it was last matched with, and the
    /// pair's duration.
    matched: Vec<Option<(u32, u32, f64)>>,
}

/// A set of endpoints, as a 128-bit hash of every figure a measurement reads (two 64-bit
/// hashes with fixed seeds, of the points and the standers: the same on every machine and run, and a collision within one
/// patch's [`MEMO_SIZE`] sets is out of reach).
fn set_key(entries: &[PointKey], exits: &[PointKey], standers: u32) -> u128 {
    use std::hash::BuildHasher;
    // Each list is hashed as one run of bytes (foldhash's fast path for long inputs).
    let half = |seed: u64| {
        foldhash::quality::FixedState::with_seed(seed).hash_one((
            standers,
            entries.as_flattened(),
            exits.as_flattened(),
        ))
    };
    (u128::from(half(0x243f_6a88_85a3_08d3)) << 64) | u128::from(half(0x1319_8a2e_0370_7344))
}

impl ScoreCache {
    /// Takes in this measurement's endpoints: slots for the points that came, their scores
    /// with the others where not kept, and every entry's best exit.
    fn update(
        &mut self,
        (entry_keys, exit_keys): (Vec<PointKey>, Vec<PointKey>),
        entries: &[Endpoint],
        exits: &[Endpoint],
        ctx: &PatchContext,
    ) {
        if entry_keys == self.entries.keys && exit_keys == self.exits.keys {
            return;
        }
        let entry_places = old_places(&self.entries.keys, &entry_keys);
        let exit_places = old_places(&self.exits.keys, &exit_keys);
        self.epoch += 1;
        let came_entries = self.entries.take(entry_keys, &entry_places, self.epoch);
        let came_exits = self.exits.take(exit_keys, &exit_places, self.epoch);
        self.make_room();
        let mut came = vec![false; entries.len()];
        for &i in &came_entries {
            came[i] = true;
        }
        let bars = self.bars();
        for (i, &came) in came.iter().enumerate() {
            if came {
                self.score_row(i, entries, exits, ctx, &bars);
            } else {
                self.score_new_exits(i, &came_exits, entries, exits, ctx, &bars);
            }
        }
    }

    /// Room in the score table for every slot; no last match for entry slots with new points.
    fn make_room(&mut self) {
        let (rows, cols) = (self.entries.key.len(), self.exits.key.len());
        if cols > self.width {
            let width = cols + 4;
            let mut scores = vec![0; rows * width];
            for (r, row) in self.scores.chunks_exact(self.width.max(1)).enumerate() {
                scores[r * width..r * width + self.width].copy_from_slice(row);
            }
            self.scores = scores;
            self.width = width;
        }
        self.scores.resize(rows * self.width, 0);
        self.best.resize(rows, GONE);
        self.matched.resize(rows, None);
        for &r in &self.entries.at {
            let r = r as usize;
            if self.entries.since[r] == self.epoch && self.entries.left_at[r] == 0 {
                self.matched[r] = None;
            }
        }
    }

    /// Whether the scores of entry slot `r` with exit slot `c` are still those of their points.
    fn kept(&self, r: u32, c: u32) -> bool {
        let (r, c) = (r as usize, c as usize);
        let (e_since, x_since) = (self.entries.since[r], self.exits.since[c]);
        match (e_since < self.epoch, x_since < self.epoch) {
            (true, true) => true,
            (true, false) => e_since < self.exits.left_at[c],
            (false, true) => x_since < self.entries.left_at[r],
            (false, false) => false,
        }
    }

    fn row(&self, r: u32) -> &[u64] {
        let base = r as usize * self.width;
        &self.scores[base..base + self.width]
    }

    /// Scores entry `i` with exit `o` in their slots, unless the score kept there still holds.
    fn rescore(
        &mut self,
        i: usize,
        o: usize,
        (entries, exits): (&[Endpoint], &[Endpoint]),
        ctx: &PatchContext,
    ) {
        let (r, c) = (self.entries.at[i], self.exits.at[o]);
        if !self.kept(r, c) {
            let s = score::score(&entries[i], &exits[o], ctx);
            self.scores[r as usize * self.width + c as usize] = order_key(s);
        }
    }

    /// An entry that came: its scores with every exit where not kept, and its best.
    fn score_row(
        &mut self,
        i: usize,
        entries: &[Endpoint],
        exits: &[Endpoint],
        ctx: &PatchContext,
        bars: &[u64],
    ) {
        let r = self.entries.at[i];
        for o in 0..self.exits.at.len() {
            self.rescore(i, o, (entries, exits), ctx);
        }
        let (_, o) = self.best_free(r, bars);
        self.best[r as usize] = self.exits.at[o as usize];
    }

    /// An entry that stays: its scores with the exits that came where not kept, and its best
    /// among them and the best it had (scanned again if that one left).
    fn score_new_exits(
        &mut self,
        i: usize,
        came_exits: &[usize],
        entries: &[Endpoint],
        exits: &[Endpoint],
        ctx: &PatchContext,
        bars: &[u64],
    ) {
        let r = self.entries.at[i];
        for &o in came_exits {
            self.rescore(i, o, (entries, exits), ctx);
        }
        let b = self.best[r as usize];
        let stays = self.exits.pos[b as usize] != GONE && self.exits.since[b as usize] < self.epoch;
        if !stays {
            let (_, o) = self.best_free(r, bars);
            self.best[r as usize] = self.exits.at[o as usize];
            return;
        }
        let row = self.row(r);
        let mut best = (row[b as usize], self.exits.pos[b as usize]);
        for &o in came_exits {
            best = best.min((row[self.exits.at[o] as usize], o as u32));
        }
        self.best[r as usize] = self.exits.at[best.1 as usize];
    }

    /// Per exit slot, 0 when in the set, all ones when not: or-ed onto a score, it bars it.
    fn bars(&self) -> Vec<u64> {
        self.exits
            .pos
            .iter()
            .map(|&p| if p == GONE { u64::MAX } else { 0 })
            .collect()
    }

    /// Entry slot `r`'s least (score, place) among the exit slots not barred: a branchless
    /// pass over its row for the least score, and one for the first place that has it.
    fn best_free(&self, r: u32, bars: &[u64]) -> (u64, u32) {
        let row = &self.row(r)[..bars.len()];
        let least = row.iter().zip(bars).map(|(&s, &b)| s | b).min();
        let least = least.unwrap_or(u64::MAX);
        let place = row
            .iter()
            .zip(bars)
            .zip(&self.exits.pos)
            .filter(|((s, b), _)| **s | **b == least)
            .map(|(_, &p)| p)
            .min();
        (least, place.unwrap_or(GONE))
    }

    /// Entry slot `r`'s least [`SHORTLIST`] exits among those not barred, least first, as
    /// (score, place) packed in one integer.
    fn shortlist(&self, r: u32, bars: &[u64], out: &mut [u128]) -> usize {
        let row = &self.row(r)[..bars.len()];
        let mut len = 0;
        for ((&s, &b), &p) in row.iter().zip(bars).zip(&self.exits.pos) {
            let key = (u128::from(s) << 32) | u128::from(p);
            if b != 0 || (len == SHORTLIST && key >= out[len - 1]) {
                continue;
            }
            let mut k = len.min(SHORTLIST - 1);
            while k > 0 && out[k - 1] > key {
                out[k] = out[k - 1];
                k -= 1;
            }
            out[k] = key;
            len = (len + 1).min(SHORTLIST);
        }
        len
    }

    /// The exit of every entry: the least free pair of (score, entry, exit), again and again
    /// (the stable matching of [`crate::stable`]). Each entry starts from its best; when that
    /// is taken, a scan of its row keeps its next [`SHORTLIST`], so most rescans read no row.
    fn stable_matching(&self) -> Vec<usize> {
        let n = self.entries.at.len();
        let mut taken = vec![false; n];
        let mut bars = self.bars();
        let mut exit_of = vec![0usize; n];
        // Room kept by the thread between matchings: only the first `len` of each shortlist
        // are read.
        let mut short = SHORTLISTS.take();
        if short.len() < n * SHORTLIST {
            short.resize(n * SHORTLIST, 0);
        }
        let (mut len, mut next) = (vec![0usize; n], vec![0usize; n]);
        let pair = |score: u64, i: usize, o: u32| {
            Reverse((u128::from(score) << 64) | ((i as u128) << 32) | u128::from(o))
        };
        let mut heap: std::collections::BinaryHeap<Reverse<u128>> = (0..n)
            .map(|i| {
                let r = self.entries.at[i];
                let c = self.best[r as usize];
                pair(self.row(r)[c as usize], i, self.exits.pos[c as usize])
            })
            .collect();
        while let Some(Reverse(key)) = heap.pop() {
            let (i, o) = ((key >> 32) as u32 as usize, key as u32 as usize);
            if !taken[o] {
                taken[o] = true;
                bars[self.exits.at[o] as usize] = u64::MAX;
                exit_of[i] = o;
                continue;
            }
            let list = &mut short[i * SHORTLIST..(i + 1) * SHORTLIST];
            while next[i] < len[i] && taken[list[next[i]] as u32 as usize] {
                next[i] += 1;
            }
            if next[i] == len[i] {
                len[i] = self.shortlist(self.entries.at[i], &bars, list);
                next[i] = 0;
            }
            let found = list[next[i]];
            heap.push(pair((found >> 32) as u64, i, found as u32));
        }
        SHORTLISTS.set(short);
        exit_of
    }

    /// The duration of entry `i` matched with exit `o`, kept if the pair was matched before.
    fn duration(
        &mut self,
        i: usize,
        o: usize,
        entry: &Endpoint,
        exit: &Endpoint,
        ctx: &PatchContext,
    ) -> f64 {
        let (r, c) = (self.entries.at[i], self.exits.at[o]);
        let generation = self.exits.generation[c as usize];
        match self.matched[r as usize] {
            Some((mc, g, d)) if mc == c && g == generation => d,
            _ => {
                let d = plan::duration(entry, exit, ctx);
                self.matched[r as usize] = Some((c, generation, d));
                d
            }
        }
    }
}

/// [`crate::match_points`] with the patch's scores kept in `cache` (see [`measure_patch_cached`]).
pub fn match_points_cached(
    entries: &[Endpoint],
    exits: &[Endpoint],
    ctx: &PatchContext,
    cache: &mut ScoreCache,
) -> Vec<usize> {
    let keys = (point_keys(entries), point_keys(exits));
    cache.matching(keys, entries, exits, ctx)
}

impl ScoreCache {
    fn matching(
        &mut self,
        keys: (Vec<PointKey>, Vec<PointKey>),
        entries: &[Endpoint],
        exits: &[Endpoint],
        ctx: &PatchContext,
    ) -> Vec<usize> {
        assert_eq!(
            entries.len(),
            exits.len(),
            "parity: as many entries as exits"
        );
        if entries.is_empty() {
            return Vec::new();
        }
        self.update(keys, entries, exits, ctx);
        self.stable_matching()
    }
}

/// [`crate::measure_patch`] with the patch's scores kept in `cache` between calls: the same
/// figures, with only the pairs that changed since the last call scored.
pub fn measure_patch_cached(
    entries: &[Endpoint],
    exits: &[Endpoint],
    standers: u32,
    ctx: &PatchContext,
    cache: &mut ScoreCache,
) -> Measured {
    let keys = (point_keys(entries), point_keys(exits));
    let key = set_key(&keys.0, &keys.1, standers);
    if let Some(m) = cache.memo.get(&key) {
        return *m;
    }
    let pairs = cache.matching(keys, entries, exits, ctx);
    let area = ctx.side_m * ctx.side_m;
    let mut time = 0.0;
    let mut direction = DVec2::ZERO;
    for (i, (e, &o)) in entries.iter().zip(&pairs).enumerate() {
        let x = &exits[o];
        let duration = cache.duration(i, o, e, x, ctx);
        time += duration;
        direction += duration * (x.pos - e.pos).normalize_or_zero();
    }
    let measured = Measured {
        density: standers as f64 / area + time / (area * ctx.period_s),
        direction: direction.try_normalize(),
        standers,
    };
    if cache.memo.len() >= MEMO_SIZE {
        cache.memo.clear();
    }
    cache.memo.insert(key, measured);
    measured
}
