//! Where a walker faces: the one heading model of `library.crowd`'s players and `world.glb`.
//!
//! A walker faces the way it walks, turns at most `rate` radians a second, and holds its
//! heading while it stands, turning once, as late as it can, to face the way it walks off.
//! On a walking piece it turns from the piece's start towards the piece's direction (a corner
//! turns the character over the first moments of the new piece); on a standing piece it holds
//! and ends the turn as it leaves. A loop's headings are periodic: the heading at the loop's
//! end is the heading at its start, so a character shows no turn at its seam.
//!
//! [`loop_headings`] gives the heading at every key of a loop; [`Piece::at`] the heading inside
//! a piece from its two keys' headings, so a player needs only the key headings and the rate.
//! Over any interval the heading changes by at most `rate` times its length, so any samples of
//! it, joined by the shorter turn between each two, turn no faster than `rate`.

use std::f64::consts::{PI, TAU};

/// A person's turning speed, and the default of `export.turn_rate_deg_s`: 360 degrees a second.
pub const DEFAULT_TURN_RATE_DEG_S: f64 = 360.0;
/// A piece slower than this (m/s) is standing: it does not turn the character (a creep of a
/// few tenths of a millimetre, the rounding of a pause's points, would turn it round).
pub const WALKING_M_S: f64 = 0.05;

/// Whether a piece `metres` long lasting `seconds` walks (else it stands).
pub fn walks(metres: f64, seconds: f64) -> bool {
    metres > 1e-9 && metres > WALKING_M_S * seconds
}

/// The most a heading turns over one piece, radians: a little short of half a turn, so that
/// which way a piece turns is the same whoever reads its two ends, rounded to the library's
/// 65536ths of a turn or not (a turn back of exactly half a turn went one way in the runtime's
/// sampler and the other in `world.glb`). The rest of a turn back runs on the next piece.
const MAX_PIECE_TURN: f64 = PI - 1e-3;

/// `a - b` as the shorter turn, in (-pi, pi].
pub fn turn_between(a: f64, b: f64) -> f64 {
    let mut d = a - b;
    // Headings are within a turn or two of each other: a step or two, not `fmod` (which was a
    // tenth of loading painting's headings).
    if d.abs() > 4.0 * TAU {
        d = d.rem_euclid(TAU);
    }
    while d > PI {
        d -= TAU;
    }
    while d <= -PI {
        d += TAU;
    }
    d
}

/// The heading `from`, turned towards `to` by at most `step` radians (the shorter way).
fn towards(from: f64, to: f64, step: f64) -> f64 {
    let d = turn_between(to, from);
    from + d.clamp(-step, step)
}

/// One piece of a loop as the heading model sees it: its times, whether it walks, and the
/// headings at its two keys (from [`loop_headings`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Piece {
    pub t0: f64,
    pub t1: f64,
    pub walks: bool,
    pub h0: f64,
    pub h1: f64,
}

impl Piece {
    /// The turn over the piece, radians (signed, the shorter way).
    pub fn turn(&self) -> f64 {
        turn_between(self.h1, self.h0)
    }

    /// When the piece's turn runs, at `rate`: from its start on a walking piece, up to its end
    /// on a standing one (and over the whole piece when it is shorter than the turn).
    pub fn turning(&self, rate: f64) -> (f64, f64) {
        let needs = (self.turn().abs() / rate).min(self.t1 - self.t0);
        if self.walks {
            (self.t0, self.t0 + needs)
        } else {
            (self.t1 - needs, self.t1)
        }
    }

    /// The heading at time `t` inside the piece, at `rate`.
    pub fn at(&self, t: f64, rate: f64) -> f64 {
        let (start, end) = self.turning(rate);
        let turn = self.turn();
        if t <= start || end <= start {
            return if t >= end { self.h0 + turn } else { self.h0 };
        }
        let s = ((t - start) / (end - start)).clamp(0.0, 1.0);
        self.h0 + turn * s
    }
}

/// The heading (radians, `atan2(dy, dx)`, world axes) at every key of a closed loop: `times`
/// (seconds) increase from the loop's start, `points` are world metres, `rate` is rad/s, and the last key is the first
/// one a loop later (the same place). Headings are periodic: the last equals the first.
/// A loop that never walks faces +y.
pub fn loop_headings(times: &[f64], points: &[[f64; 2]], rate: f64) -> Vec<f64> {
    let walking: Vec<bool> = (1..times.len())
        .map(|k| {
            let (a, b) = (points[k - 1], points[k]);
            walks((b[0] - a[0]).hypot(b[1] - a[1]), times[k] - times[k - 1])
        })
        .collect();
    loop_headings_walking(times, points, &walking, rate)
}

/// [`loop_headings`] with whether each piece walks given (`walking[k]`: from key `k` to
/// `k + 1`), as the library's quantised points say ([`piece_walks`]).
pub fn loop_headings_walking(
    times: &[f64],
    points: &[[f64; 2]],
    walking: &[bool],
    rate: f64,
) -> Vec<f64> {
    let n = times.len();
    if n < 2 {
        return vec![PI / 2.0; n];
    }
    // Each piece's direction, NaN where it stands (8 bytes a piece: painting's longest loop
    // has 5.6 million, and its first touch of fresh memory was a third of the time).
    // On every core for a long loop where the caller has threads (painting's longest: 0.11 s
    // of `atan2` on one).
    let directions: Vec<f64> =
        map_indices(n - 1, |k| direction(points[k], points[k + 1], walking[k]));
    headings_from(times, &directions, rate)
}

/// The direction of a piece from `a` to `b` (world metres), radians; NaN where it stands.
fn direction(a: [f64; 2], b: [f64; 2], walks: bool) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    if walks { dy.atan2(dx) } else { f64::NAN }
}

/// [`loop_headings_walking`] of each piece's [`direction`] (`directions[k]`: from key `k` to
/// `k + 1`).
fn headings_from(times: &[f64], directions: &[f64], rate: f64) -> Vec<f64> {
    let n = times.len();
    if n < 2 {
        return vec![PI / 2.0; n];
    }
    let Some(first_walk) = directions.iter().copied().find(|d| !d.is_nan()) else {
        return vec![PI / 2.0; n];
    };
    let length = times[n - 1] - times[0];
    // Walk the loop from its first walking direction until the heading at the loop's start
    // repeats: a heading that catches up with its target once forgets where it started, so
    // two laps settle any loop that walks straight for as long as a turn takes. Headings are
    // kept within a turn (`turn_between(.., 0)`), so a lap that meets the lap before it at a
    // key, to the bit, is that lap from there on (each key's heading is a function of the
    // one before it alone): it stops there, and a loop of 5 million keys is walked about once,
    // not twice (and no heading drifts by whole turns, whose `fmod` was a tenth of the time).
    // A lap writes over the one before in place, comparing each key before it writes it.
    let mut h = vec![0.0; n];
    let lap = |h: &mut [f64], h0: f64, again: bool| {
        h[0] = h0;
        // The walk a standing piece aims at: the next walking piece round the loop (found
        // once for a run of standing pieces), and when it starts (a loop later past the last).
        let mut walk: Option<(usize, f64, f64)> = None;
        for k in 0..n - 1 {
            let piece = (k, directions[k], times[k], times[k + 1]);
            let ahead = || next_walk(directions, times, k, length);
            let next = piece_end(h[k], piece, rate, &mut walk, ahead);
            if again && h[k + 1].to_bits() == next.to_bits() {
                break;
            }
            h[k + 1] = next;
        }
    };
    settle(&mut h, first_walk, lap);
    h
}

/// The heading at a piece's end (`(t0, t1)` its times, `d` its direction, NaN where it
/// stands) from `from` at its start, kept within a turn; `ahead` gives a standing piece the
/// walk it turns towards (its piece, direction and start), found once for a run of standing
/// pieces and kept in `walk`.
fn piece_end(
    from: f64,
    (k, d, t0, t1): (usize, f64, f64, f64),
    rate: f64,
    walk: &mut Option<(usize, f64, f64)>,
    ahead: impl FnOnce() -> Option<(usize, f64, f64)>,
) -> f64 {
    let next = if !d.is_nan() {
        towards(from, d, (rate * (t1 - t0)).min(MAX_PIECE_TURN))
    } else {
        if walk.is_none_or(|(j, _, _)| j < k) {
            *walk = ahead();
        }
        let (_, d, walk_off) = walk.expect("a loop that walks has a walk ahead");
        // Standing: the run's one turn ends as it walks off; this piece turns only for the
        // part of it that falls inside the piece.
        let starts = walk_off - turn_between(d, from).abs() / rate;
        let step = (rate * (t1 - starts.max(t0)).max(0.0)).min(MAX_PIECE_TURN);
        towards(from, d, step)
    };
    turn_between(next, 0.0)
}

/// A loop's headings `h` settled from its first walking direction: `lap(h, h0, again)` walks
/// a lap from heading `h0` (stopping where it meets the lap before, when `again`), until the
/// heading at the loop's start repeats; then the loop's end is its start.
fn settle(h: &mut [f64], first_walk: f64, lap: impl FnMut(&mut [f64], f64, bool)) {
    let n = h.len();
    settle_laps(h, first_walk, lap);
    // A loop that never caught up keeps its last lap's start.
    for a in h.iter_mut() {
        *a = turn_between(*a, 0.0);
    }
    h[n - 1] = h[0];
}

/// [`settle`]'s laps, into any [`LapStore`]: from the first walking direction, then from
/// where the lap before ended, until the heading at the loop's start repeats (at most 8 laps
/// more).
fn settle_laps<S: LapStore + ?Sized>(
    store: &mut S,
    first_walk: f64,
    mut lap: impl FnMut(&mut S, f64, bool),
) {
    lap(store, first_walk, false);
    for _ in 0..8 {
        let (start, end) = store.ends();
        if turn_between(end, start).abs() <= 1e-12 {
            break;
        }
        lap(store, end, true);
    }
}

/// Where a lap keeps the headings it makes at a loop's keys. A lap stops where it meets the
/// lap before (the same bits at a key it compares): each key's heading is a function of the
/// one before alone, so from there on the lap before is this lap.
trait LapStore {
    /// A lap begins at key 0 with heading `h0`.
    fn begin(&mut self, h0: f64);
    /// Keeps heading `v` at key `k` (1 or more), unless `again` and the lap before left the
    /// same bits there, where it may compare (then true: the lap stops, keeping nothing).
    fn meets(&mut self, k: usize, v: f64, again: bool) -> bool;
    /// The headings at the loop's first key and its last, as the laps left them.
    fn ends(&self) -> (f64, f64);
}

/// Every key's heading in full, compared at every key.
impl LapStore for [f64] {
    fn begin(&mut self, h0: f64) {
        self[0] = h0;
    }

    fn meets(&mut self, k: usize, v: f64, again: bool) -> bool {
        if again && self[k].to_bits() == v.to_bits() {
            return true;
        }
        self[k] = v;
        false
    }

    fn ends(&self) -> (f64, f64) {
        (self[0], self[self.len() - 1])
    }
}

/// Where a long loop's laps keep the heading in full, to compare a lap with the lap before:
/// at every [`Marks::every`]th key and the last (and the first lap's start). A lap then stops
/// at the first mark after it meets the lap before, not at the key itself: what it writes
/// between the two are the lap before's bits again.
struct Marks {
    marks: Vec<f64>,
    every: usize,
    keys: usize,
    first: f64,
    last: f64,
}

impl Marks {
    fn new(keys: usize, every: usize) -> Marks {
        let every = every.max(1);
        Marks {
            marks: vec![0.0; keys / every + 1],
            every,
            keys,
            first: 0.0,
            last: 0.0,
        }
    }

    /// [`LapStore::meets`] where key `k` is marked; else false (the caller keeps `v`).
    fn meets(&mut self, k: usize, v: f64, again: bool) -> bool {
        let kept = if k + 1 == self.keys {
            &mut self.last
        } else if k.is_multiple_of(self.every) {
            &mut self.marks[k / self.every]
        } else {
            return false;
        };
        if again && kept.to_bits() == v.to_bits() {
            return true;
        }
        *kept = v;
        false
    }

    /// The settled heading at the loop's first key and its last (the same place a loop
    /// later), as [`settle`] leaves it: within a turn.
    fn settled_first(&self) -> f64 {
        turn_between(self.first, 0.0)
    }
}

/// A long loop's headings kept packed, two bytes a key ([`crate::packed_heading`], the walk
/// bit that of the piece from the key), in full only at its [`Marks`].
struct PackedLaps {
    keys: Vec<u16>,
    marks: Marks,
}

impl PackedLaps {
    /// Room for `n` keys, each facing east and not walking until a walk through and the laps
    /// set them.
    fn new(n: usize, every: usize) -> PackedLaps {
        PackedLaps {
            keys: vec![crate::packed_heading(0.0, false); n],
            marks: Marks::new(n, every),
        }
    }

    /// The settled headings.
    fn settled(mut self) -> Vec<u16> {
        let n = self.keys.len();
        let first = self.marks.settled_first();
        for k in [0, n - 1] {
            let walks = self.keys[k] & crate::sampler::WALKS != 0;
            self.keys[k] = crate::packed_heading(first, walks);
        }
        self.keys
    }
}

impl LapStore for PackedLaps {
    fn begin(&mut self, h0: f64) {
        self.marks.first = h0;
    }

    fn meets(&mut self, k: usize, v: f64, again: bool) -> bool {
        if self.marks.meets(k, v, again) {
            return true;
        }
        // Headings after a piece are within a turn already (`piece_end`).
        let walks = self.keys[k] & crate::sampler::WALKS != 0;
        self.keys[k] = crate::packed_heading(v, walks);
        false
    }

    fn ends(&self) -> (f64, f64) {
        (self.marks.first, self.marks.last)
    }
}

/// A long loop's headings kept in full only over some stretches of its keys (and at its
/// [`Marks`]): what `world.glb` reads of a loop whose walkers mostly stand outside its region.
struct StretchLaps {
    /// Each stretch's keys, `from..to`, sorted and apart, and the headings there.
    stretches: Vec<(std::ops::Range<usize>, Vec<f64>)>,
    /// The stretch a lap is in or before (laps go forward through the keys).
    at: usize,
    marks: Marks,
}

impl StretchLaps {
    fn new(n: usize, stretches: &[std::ops::Range<usize>], every: usize) -> StretchLaps {
        StretchLaps {
            stretches: (stretches.iter())
                .map(|r| (r.clone(), vec![0.0; r.len()]))
                .collect(),
            at: 0,
            marks: Marks::new(n, every),
        }
    }

    /// The settled headings of each stretch.
    fn settled(mut self) -> Vec<Vec<f64>> {
        let n = self.marks.keys;
        let first = self.marks.settled_first();
        for (keys, h) in &mut self.stretches {
            for k in [0, n - 1] {
                if keys.contains(&k) {
                    h[k - keys.start] = first;
                }
            }
        }
        self.stretches.into_iter().map(|(_, h)| h).collect()
    }
}

impl LapStore for StretchLaps {
    fn begin(&mut self, h0: f64) {
        self.marks.first = h0;
        self.at = 0;
    }

    fn meets(&mut self, k: usize, v: f64, again: bool) -> bool {
        if self.marks.meets(k, v, again) {
            return true;
        }
        while self.stretches.get(self.at).is_some_and(|(r, _)| r.end <= k) {
            self.at += 1;
        }
        if let Some((keys, h)) = self.stretches.get_mut(self.at)
            && keys.contains(&k)
        {
            h[k - keys.start] = v;
        }
        false
    }

    fn ends(&self) -> (f64, f64) {
        (self.marks.first, self.marks.last)
    }
}

/// The first walking piece after standing piece `k` of a loop (`directions` NaN where a piece
/// stands), its direction and the time it starts; past the loop's last walk, its first walk
/// a loop (`length`) later. The index is `usize::MAX` for the wrapped walk (it is ahead of
/// every piece after the last walk).
fn next_walk(
    directions: &[f64],
    times: &[f64],
    k: usize,
    length: f64,
) -> Option<(usize, f64, f64)> {
    match (k + 1..directions.len()).find(|&j| !directions[j].is_nan()) {
        Some(j) => Some((j, directions[j], times[j])),
        None => {
            let j = directions.iter().position(|d| !d.is_nan())?;
            Some((usize::MAX, directions[j], times[j] + length))
        }
    }
}

/// Whether the piece of `lib` from point `a` to the next, `b`, walks ([`walks`], on the
/// quantised points as the library holds them).
fn piece_walks(lib: &crate::Library, a: crate::Point, b: crate::Point) -> bool {
    // Whole steps: their squares add up exactly, and the root is rounded once (`hypot` was a
    // twentieth of loading a library's headings).
    let (dx, dy) = (
        f64::from(i32::from(b.x) - i32::from(a.x)),
        f64::from(i32::from(b.y) - i32::from(a.y)),
    );
    let steps = (dx * dx + dy * dy).sqrt();
    let metres = steps * f64::from(lib.world.patch_side_m) / crate::format::QUANT_STEPS;
    walks(metres, f64::from(b.t.wrapping_sub(a.t)) * crate::TICK_S)
}

/// What the heading model says of every point of a library ([`library_headings`]).
#[derive(Debug, Clone, PartialEq)]
pub struct PointHeadings {
    /// The heading at each point, radians.
    pub heading: Vec<f64>,
    /// Whether the piece from each point to the next of its trajectory walks ([`walks`], on
    /// the quantised points; false at a trajectory's last point).
    pub walks: Vec<bool>,
}

/// Every point's heading in `lib` (radians), at the library's turn rate: [`loop_headings`]
/// over each loop's points (a trajectory's first point is its predecessor's last), and
/// whether the piece from it walks. Stage 8 takes `world.glb`'s headings from here and the
/// runtime's sampler its own, so the glTF and the runtime face the same way.
pub fn library_headings(lib: &crate::Library) -> PointHeadings {
    let mut out = PointHeadings::for_points(lib);
    for ch in &lib.characters {
        out.take(lib, ch, &character_headings(lib, ch));
    }
    out
}

impl PointHeadings {
    /// Room for every point of `lib`, to [`PointHeadings::take`] each character's into (a
    /// reader with threads makes the characters' in parallel, then takes them in).
    pub fn for_points(lib: &crate::Library) -> PointHeadings {
        PointHeadings {
            heading: vec![0.0; lib.points.len()],
            walks: vec![false; lib.points.len()],
        }
    }

    /// Takes in character `ch`'s share, `one` ([`character_headings`]), at its points.
    pub fn take(&mut self, lib: &crate::Library, ch: &crate::Character, one: &PointHeadings) {
        let (mut heading, mut walks) = (one.heading.iter(), one.walks.iter());
        let mut at = ch.first_trajectory;
        for _ in 0..ch.trajectories {
            let tr = &lib.trajectories[at as usize];
            let first = tr.first_point as usize;
            for i in 0..tr.points as usize {
                self.heading[first + i] = *heading.next().expect("a heading per point");
                if i > 0 {
                    self.walks[first + i - 1] = *walks.next().expect("one per piece");
                }
            }
            at = tr.next;
        }
    }
}

/// One character's share of [`library_headings`], in its loop's order: the heading at every
/// point of each of its trajectories in turn (a trajectory's first point included, though it
/// is its predecessor's last), and whether each piece walks. Each character's is its own, so
/// a reader that needs a few characters (stage 8's `world.glb` of a region) need not pay for
/// all.
pub fn character_headings(lib: &crate::Library, ch: &crate::Character) -> PointHeadings {
    // Its trajectories in walking order first, so that every list below is made at its size
    // (growing them, and the fresh memory each growth touched, was a third of the time), and
    // so that each trajectory's points can be asked for ahead of their turn: the loop goes
    // from patch to patch, each trajectory's points a miss of the cache.
    let legs = loop_legs(lib, ch);
    let lib = Source::held(lib);
    let runs = loop_runs(lib, &legs);
    legs_headings(lib, &legs, (&runs.0, runs.1, runs.2))
}

/// [`character_headings`] of a loop's `legs`, cut into `runs` ([`loop_runs`]).
fn legs_headings<P: LoopPoints + ?Sized>(
    lib: Source<P>,
    legs: &[Leg],
    (runs, keys, pieces): (&[Run], usize, usize),
) -> PointHeadings {
    let rate = f64::from(lib.world.turn_rate_deg_s).to_radians();
    let (h, walking) = if keys < STREAM_KEYS {
        // The keys' times and pieces' directions, and no more: each list a loop long.
        let LoopKeys {
            times,
            directions,
            walking,
        } = loop_keys(lib, legs, (runs, keys, pieces));
        (headings_from(&times, &directions, rate), walking)
    } else {
        // A long loop's keys made a window of runs at a time, each lap (the million's longest
        // has 36 million keys: its lists held 25 bytes a key beside the headings); its
        // headings made with room for every point, which they are spread to below (grown
        // there, the longest loop's were copied, 0.29 GB twice over).
        let points = legs.iter().map(|l| l.points as usize).sum();
        streamed_headings(lib, legs, (runs, keys, pieces), (rate, points), WINDOW_RUNS)
    };
    PointHeadings {
        heading: key_headings_at_points(h, legs),
        walks: walking,
    }
}

/// Every point's heading in `lib` packed as the sampler keeps them ([`crate::PackedHeadings`]):
/// [`library_headings`] packed, made a character at a time ([`take_packed_headings`]), never
/// every point's in full (nine bytes a point: the million's library, 0.87 GB, where the
/// packed ones are 0.19 GB).
pub fn library_packed_headings(lib: &crate::Library) -> crate::PackedHeadings {
    let mut out = crate::PackedHeadings::for_points(lib);
    for ch in &lib.characters {
        take_packed_headings(lib, ch, &mut out);
    }
    out
}

/// Character `ch`'s headings packed at its points of `out` (the bits of
/// [`crate::PackedHeadings::take`] of [`character_headings`]); a long loop's made packed a
/// window of runs at a time ([`streamed_packed`]), never its headings in full.
pub fn take_packed_headings(
    lib: &crate::Library,
    ch: &crate::Character,
    out: &mut crate::PackedHeadings,
) {
    let legs = loop_legs(lib, ch);
    let held = Source::held(lib);
    let (runs, keys, pieces) = loop_runs(held, &legs);
    if keys < STREAM_KEYS {
        out.take(lib, ch, &legs_headings(held, &legs, (&runs, keys, pieces)));
        return;
    }
    let rate = f64::from(lib.world.turn_rate_deg_s).to_radians();
    let runs = (&runs[..], keys, pieces);
    let packed = streamed_packed(held, &legs, runs, (rate, WINDOW_RUNS), MARK_EVERY);
    packed_at_points(&packed, &legs, &mut out.packed);
}

/// The headings (radians) at the keys `stretches` of character `ch`'s loop, and whether the
/// piece from each key of a stretch but its last walks: the bits of [`character_headings`]
/// there. A loop's keys are its trajectories' points in walking order, each trajectory's
/// first point left out but for the loop's first (it is the one before's last). The
/// stretches are in order and apart. A long loop's are made a window of runs at a time and
/// kept in full only over the stretches ([`StretchLaps`]): `world.glb` of a region reads a
/// few walkers' stretches of the million's longest loop, whose headings are 0.29 GB.
pub fn stretch_headings(
    lib: &crate::Library,
    ch: &crate::Character,
    stretches: &[std::ops::Range<usize>],
) -> Vec<(Vec<f64>, Vec<bool>)> {
    stretch_headings_in(lib, &lib.points[..], ch, stretches)
}

/// [`stretch_headings`] of a library whose points are read from `points` (`lib.points` is
/// not read): the same bits, however they are read.
pub fn stretch_headings_in<P: LoopPoints + ?Sized>(
    lib: &crate::Library,
    points: &P,
    ch: &crate::Character,
    stretches: &[std::ops::Range<usize>],
) -> Vec<(Vec<f64>, Vec<bool>)> {
    debug_assert!(stretches.windows(2).all(|w| w[0].end <= w[1].start));
    let legs = loop_legs(lib, ch);
    let lib = Source { lib, points };
    let (runs, keys, pieces) = loop_runs(lib, &legs);
    let runs = (&runs[..], keys, pieces);
    let rate = f64::from(lib.world.turn_rate_deg_s).to_radians();
    if keys < points.stream_keys() {
        let at_once = loop_keys(lib, &legs, runs);
        let h = headings_from(&at_once.times, &at_once.directions, rate);
        return (stretches.iter())
            .map(|r| (h[r.clone()].to_vec(), pieces_of(&at_once.walking, r)))
            .collect();
    }
    streamed_stretches(
        lib,
        &legs,
        runs,
        (rate, WINDOW_RUNS),
        (stretches, MARK_EVERY),
    )
}

/// Character `ch`'s headings packed at each key of its loop, the walk bit that of the piece
/// from the key (the bits [`take_packed_headings`] puts at its points), made a window of runs
/// at a time through `points`, never the loop's points or headings in full: a reader that
/// plays a long loop a part at a time puts each part's at its points
/// (`LoopSkeleton::part`).
pub fn packed_keys_in<P: LoopPoints + ?Sized>(
    lib: &crate::Library,
    points: &P,
    ch: &crate::Character,
) -> Vec<u16> {
    let legs = loop_legs(lib, ch);
    let lib = Source { lib, points };
    let (runs, keys, pieces) = loop_runs(lib, &legs);
    let rate = f64::from(lib.world.turn_rate_deg_s).to_radians();
    let runs = (&runs[..], keys, pieces);
    streamed_packed(lib, &legs, runs, (rate, WINDOW_RUNS), MARK_EVERY)
}

/// The pieces from the keys of `keys` but its last (piece `k` goes from key `k` to the next).
fn pieces(keys: &std::ops::Range<usize>) -> std::ops::Range<usize> {
    keys.start..keys.end.saturating_sub(1).max(keys.start)
}

/// The walk flags of [`pieces`] of `keys`, of a loop's `walking` (a flag per piece).
fn pieces_of(walking: &[bool], keys: &std::ops::Range<usize>) -> Vec<bool> {
    let p = pieces(keys);
    walking[p.start.min(walking.len())..p.end.min(walking.len())].to_vec()
}

/// [`stretch_headings`] of a long loop: its laps through [`StretchLaps`] (the headings in full
/// over the stretches and at every `every`th key) and its walk flags kept over the
/// stretches as the first walk through finds them.
fn streamed_stretches<P: LoopPoints + ?Sized>(
    lib: Source<P>,
    legs: &[Leg],
    runs: (&[Run], usize, usize),
    (rate, window): (f64, usize),
    (stretches, every): (&[std::ops::Range<usize>], usize),
) -> Vec<(Vec<f64>, Vec<bool>)> {
    let n = runs.1;
    let upright = |r: &std::ops::Range<usize>| vec![PI / 2.0; r.len()];
    if n < 2 {
        let walking = loop_keys(lib, legs, runs).walking;
        return (stretches.iter())
            .map(|r| (upright(r), pieces_of(&walking, r)))
            .collect();
    }
    let mut walking: Vec<Vec<bool>> = vec![Vec::new(); stretches.len()];
    let mut piece = 0;
    let through = walk_through(lib, legs, runs, window, |w| {
        let run = piece..piece + w.len();
        for (r, kept) in stretches.iter().zip(&mut walking) {
            let want = pieces(r);
            let (a, b) = (want.start.max(run.start), want.end.min(run.end));
            if a < b {
                kept.extend_from_slice(&w[a - piece..b - piece]);
            }
        }
        piece = run.end;
    });
    let headings = match through {
        Some(through) => {
            let mut store = StretchLaps::new(n, stretches, every);
            streamed_laps(lib, legs, runs, (rate, window), &through, &mut store);
            store.settled()
        }
        None => stretches.iter().map(upright).collect(),
    };
    headings.into_iter().zip(walking).collect()
}

/// Keys between the full headings [`streamed_packed`] keeps to compare laps with (a lap goes
/// on at most this far past where it meets the lap before).
const MARK_EVERY: usize = 4096;

/// A loop's packed key headings ([`streamed_packed`]) put at the points of its `legs` in
/// `out` (a library's): a trajectory's first point is the one before's last key, and a
/// trajectory's last point has no piece from it, so no walk bit.
fn packed_at_points(keys: &[u16], legs: &[Leg], out: &mut [u16]) {
    let mut key = 0usize;
    for (j, leg) in legs.iter().enumerate() {
        key -= usize::from(j > 0);
        let (first, n) = (leg.first as usize, leg.points as usize);
        leg_keys(&keys[key..key + n], &mut out[first..first + n]);
        key += n;
    }
}

/// A trajectory's packed key headings put at its points `at`: a trajectory's last point has
/// no piece from it, so no walk bit.
pub(crate) fn leg_keys(keys: &[u16], at: &mut [u16]) {
    at.copy_from_slice(keys);
    if let Some(last) = at.last_mut() {
        *last &= !crate::sampler::WALKS;
    }
}

/// The headings at every key of a loop, `h`, made the headings at every point of its `legs`
/// in turn (a trajectory's first point is the one before's last key), in place: from the last
/// point back, each written at or after the key it reads, once the keys there are read.
fn key_headings_at_points(mut h: Vec<f64>, legs: &[Leg]) -> Vec<f64> {
    // Each leg's first key.
    let mut key = 0usize;
    let starts: Vec<usize> = (legs.iter().enumerate())
        .map(|(j, leg)| {
            key -= usize::from(j > 0);
            let start = key;
            key += leg.points as usize;
            start
        })
        .collect();
    let points: usize = legs.iter().map(|l| l.points as usize).sum();
    let keys = h.len();
    h.resize(points.max(keys), 0.0);
    let mut point = points;
    for (leg, &start) in legs.iter().zip(&starts).rev() {
        let n = leg.points as usize;
        point -= n;
        h.copy_within(start..start + n, point);
    }
    h.truncate(points);
    h
}

/// Where the heading model reads a loop's points: the library's own list, or a file that
/// holds them, read a trajectory at a time (stage 8 of a gathering build, which never holds
/// the world's points: the million's longest loop alone is 0.34 GB of them).
pub trait LoopPoints: Sync {
    /// `read` of the `n` points from point `first` (a trajectory's).
    fn with<R>(&self, first: u32, n: u32, read: impl FnOnce(&[crate::Point]) -> R) -> R;

    /// Asks for the points from `first` ahead of their turn: a loop goes from patch to patch,
    /// each trajectory's points a miss of the cache.
    fn prefetch(&self, _first: u32) {}

    /// Loops of this many keys or more are made a window of runs at a time, never their keys
    /// all at once (25 bytes a key).
    fn stream_keys(&self) -> usize {
        STREAM_KEYS
    }

    /// Ticks from trajectory `t`'s start to its end (`Library::duration_ticks`): its last
    /// point's.
    fn duration_ticks(&self, t: &crate::Trajectory) -> u32 {
        match t.points {
            0 => 0,
            n => self.with(t.first_point + n - 1, 1, |p| p[0].t),
        }
    }
}

impl LoopPoints for [crate::Point] {
    fn with<R>(&self, first: u32, n: u32, read: impl FnOnce(&[crate::Point]) -> R) -> R {
        read(&self[first as usize..(first + n) as usize])
    }

    fn prefetch(&self, first: u32) {
        crate::sampler::prefetch(self.as_ptr().wrapping_add(first as usize));
    }
}

/// The first failed read of a [`LoopPoints`] over a reader that can fail (a file), which the
/// heading model cannot be told of: it is handed zeros in the read's place, and the reader's
/// owner refuses what was made once the walk is over ([`FirstFailure::take`]).
#[derive(Debug)]
pub struct FirstFailure<E>(std::sync::Mutex<Option<E>>);

impl<E> Default for FirstFailure<E> {
    fn default() -> Self {
        FirstFailure(std::sync::Mutex::new(None))
    }
}

impl<E> FirstFailure<E> {
    /// `read` of the `n` points `points` read, or of zeros where the read failed (the failure
    /// kept, unless one came before it).
    pub fn hand<R>(
        &self,
        points: Result<Vec<crate::Point>, E>,
        n: u32,
        read: impl FnOnce(&[crate::Point]) -> R,
    ) -> R {
        match points {
            Ok(points) => read(&points),
            Err(e) => {
                self.lock().get_or_insert(e);
                read(&vec![crate::Point { x: 0, y: 0, t: 0 }; n as usize])
            }
        }
    }

    /// The failure kept, if a read failed since the last time this was asked.
    pub fn take(&self) -> Result<(), E> {
        self.lock().take().map_or(Ok(()), Err)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Option<E>> {
        self.0
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

/// A library's records (trajectories, patches, world), and where its points are read from.
struct Source<'a, P: ?Sized> {
    lib: &'a crate::Library,
    points: &'a P,
}

impl<P: ?Sized> Clone for Source<'_, P> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<P: ?Sized> Copy for Source<'_, P> {}

impl<'a> Source<'a, [crate::Point]> {
    /// A library whose points are its own.
    fn held(lib: &'a crate::Library) -> Self {
        Source {
            lib,
            points: &lib.points[..],
        }
    }
}

impl<P: ?Sized> std::ops::Deref for Source<'_, P> {
    type Target = crate::Library;

    fn deref(&self) -> &crate::Library {
        self.lib
    }
}

/// The trajectories of `ch`'s loop in walking order.
fn loop_legs(lib: &crate::Library, ch: &crate::Character) -> Vec<Leg> {
    let mut legs = Vec::with_capacity(ch.trajectories as usize);
    let mut at = ch.first_trajectory;
    for _ in 0..ch.trajectories {
        let tr = &lib.trajectories[at as usize];
        legs.push(Leg {
            first: tr.first_point,
            points: tr.points,
            patch: tr.patch,
        });
        at = tr.next;
    }
    legs
}

/// One trajectory of a loop, as [`loop_keys`] reads it: its points and its patch.
#[derive(Debug, Clone, Copy)]
struct Leg {
    first: u32,
    points: u32,
    patch: u32,
}

/// A loop's keys as the heading model reads them: times (seconds from the loop's start),
/// and each piece's [`direction`] (from the world places of its keys) and whether it walks.
struct LoopKeys {
    times: Vec<f64>,
    directions: Vec<f64>,
    walking: Vec<bool>,
}

/// Where each run of [`LEGS_PER_RUN`] trajectories of the loop `legs` starts, and the loop's
/// keys and pieces (a trajectory's first point is its predecessor's last: one key for both).
fn loop_runs<P: LoopPoints + ?Sized>(lib: Source<P>, legs: &[Leg]) -> (Vec<Run>, usize, usize) {
    // Where each run of legs starts: its first leg, key, piece and tick, and the place of the
    // key before it (a trajectory's first piece starts at the one before's last key).
    let mut runs = Vec::new();
    let (mut key, mut piece, mut tick) = (0usize, 0usize, 0u64);
    let mut place = None;
    for (j, leg) in legs.iter().enumerate() {
        if j % LEGS_PER_RUN == 0 {
            runs.push(Run {
                leg: j,
                key,
                piece,
                tick,
                before: place,
            });
        }
        let n = leg.points as usize;
        let last = (n > 0).then(|| lib.points.with(leg.first + leg.points - 1, 1, |p| p[0]));
        if let Some(last) = last.filter(|_| n >= 2 || j == 0) {
            place = Some(lib.world_position(&lib.patches[leg.patch as usize], last));
        }
        key += if j == 0 { n } else { n.saturating_sub(1) };
        piece += n.saturating_sub(1);
        // Its duration: its last point's ticks (`Library::duration_ticks`).
        tick += u64::from(last.map_or(0, |l| l.t));
    }
    (runs, key, piece)
}

/// The keys of the loop of trajectories `legs`, cut into `runs` ([`loop_runs`]), each run
/// writing its own part of the lists, on every core where the caller has threads (painting's
/// longest loop: 0.12 s on one).
fn loop_keys<P: LoopPoints + ?Sized>(
    lib: Source<P>,
    legs: &[Leg],
    (runs, key, piece): (&[Run], usize, usize),
) -> LoopKeys {
    let mut out = LoopKeys {
        times: vec![0.0; key],
        directions: vec![0.0; piece],
        walking: vec![false; piece],
    };
    // Each run's share of the lists, cut off in order.
    let mut parts = Vec::with_capacity(runs.len());
    let (mut times, mut directions, mut walking) = (
        &mut out.times[..],
        &mut out.directions[..],
        &mut out.walking[..],
    );
    for (r, run) in runs.iter().enumerate() {
        let next = runs.get(r + 1);
        let keys = next.map_or(key, |n| n.key) - run.key;
        let pieces = next.map_or(piece, |n| n.piece) - run.piece;
        let (t, t_rest) = std::mem::take(&mut times).split_at_mut(keys);
        let (d, d_rest) = std::mem::take(&mut directions).split_at_mut(pieces);
        let (w, w_rest) = std::mem::take(&mut walking).split_at_mut(pieces);
        (times, directions, walking) = (t_rest, d_rest, w_rest);
        let end = next.map_or(legs.len(), |n| n.leg);
        parts.push((&legs[run.leg..end], run, (t, d, w)));
    }
    let fill = |(legs, run, (t, d, w)): (&[Leg], &Run, KeysPart)| {
        fill_keys(lib, legs, run, (t, d, w));
    };
    #[cfg(feature = "rayon")]
    if key >= PARALLEL_KEYS {
        use rayon::prelude::*;
        parts.into_par_iter().for_each(fill);
        return out;
    }
    parts.into_iter().for_each(fill);
    out
}

/// Loops of this many keys or more have their headings made by [`streamed_headings`] (their
/// lists would hold 200 MB). Painting's longest loop, 5.6 million keys, is made at once: made
/// a window at a time, once more for its first walks and again each lap, its export and check
/// took 0.1 s longer.
const STREAM_KEYS: usize = 1 << 23;

/// Runs whose keys [`streamed_headings`] makes at once (on every core where the caller has
/// threads): about 2.6 million keys, 44 MB.
const WINDOW_RUNS: usize = 64;

/// One run's share of a loop's keys ([`LoopKeys`]): the times of its keys, and the directions
/// and walk flags of the pieces that end at them.
fn run_keys<P: LoopPoints + ?Sized>(
    lib: Source<P>,
    legs: &[Leg],
    (runs, keys, pieces): (&[Run], usize, usize),
    r: usize,
) -> LoopKeys {
    let (run, next) = (&runs[r], runs.get(r + 1));
    let mut out = LoopKeys {
        times: vec![0.0; next.map_or(keys, |n| n.key) - run.key],
        directions: vec![0.0; next.map_or(pieces, |n| n.piece) - run.piece],
        walking: vec![false; next.map_or(pieces, |n| n.piece) - run.piece],
    };
    let end = next.map_or(legs.len(), |n| n.leg);
    let part = (
        &mut out.times[..],
        &mut out.directions[..],
        &mut out.walking[..],
    );
    fill_keys(lib, &legs[run.leg..end], run, part);
    out
}

/// `each` of every run's keys in order ([`run_keys`]), `window` runs made at once; stops
/// when `each` says so (false).
fn each_run_keys<P: LoopPoints + ?Sized>(
    lib: Source<P>,
    legs: &[Leg],
    runs: (&[Run], usize, usize),
    window: usize,
    mut each: impl FnMut(usize, &LoopKeys) -> bool,
) {
    let count = runs.0.len();
    for from in (0..count).step_by(window.max(1)) {
        let to = (from + window.max(1)).min(count);
        let made = map_indices_at_all(to - from, |i| run_keys(lib, legs, runs, from + i));
        for (i, keys) in made.iter().enumerate() {
            if !each(from + i, keys) {
                return;
            }
        }
    }
}

/// [`headings_from`] of a loop's keys made a window of runs at a time, never all at once: a
/// first walk through finds where each run first walks (what a standing piece turns towards
/// may be runs ahead) and the walk flags, then each lap makes the keys again. The same bits
/// as [`headings_from`] of [`loop_keys`], with the walk flags; the headings' list has room
/// for `room` of them.
fn streamed_headings<P: LoopPoints + ?Sized>(
    lib: Source<P>,
    legs: &[Leg],
    runs: (&[Run], usize, usize),
    (rate, room): (f64, usize),
    window: usize,
) -> (Vec<f64>, Vec<bool>) {
    let (_, n, pieces) = runs;
    if n < 2 {
        let walking = loop_keys(lib, legs, runs).walking;
        return (vec![PI / 2.0; n], walking);
    }
    let mut walking = Vec::with_capacity(pieces);
    let through = walk_through(lib, legs, runs, window, |w| walking.extend_from_slice(w));
    let Some(through) = through else {
        return (vec![PI / 2.0; n], walking);
    };
    let mut h = Vec::with_capacity(room.max(n));
    h.resize(n, 0.0);
    streamed_laps(lib, legs, runs, (rate, window), &through, &mut h[..]);
    for a in h.iter_mut() {
        *a = turn_between(*a, 0.0);
    }
    h[n - 1] = h[0];
    (h, walking)
}

/// [`streamed_headings`] packed ([`crate::packed_heading`]: two bytes a key, the walk bit
/// that of the piece from the key), the headings in full kept only at every `every`th key
/// ([`PackedLaps`]): the million's longest loop, 36 million keys, held 0.29 GB of headings
/// and 36 MB of walk flags beside its packed ones, and now holds those alone (72 MB). The
/// same bits as [`streamed_headings`]' packed.
fn streamed_packed<P: LoopPoints + ?Sized>(
    lib: Source<P>,
    legs: &[Leg],
    runs: (&[Run], usize, usize),
    (rate, window): (f64, usize),
    every: usize,
) -> Vec<u16> {
    let (_, n, _) = runs;
    let upright = |walks: bool| crate::packed_heading(PI / 2.0, walks);
    if n < 2 {
        return vec![upright(false); n];
    }
    let mut store = PackedLaps::new(n, every);
    let mut piece = 0;
    let through = walk_through(lib, legs, runs, window, |w| {
        for &walks in w {
            store.keys[piece] = crate::packed_heading(0.0, walks);
            piece += 1;
        }
    });
    let Some(through) = through else {
        for k in &mut store.keys {
            *k = upright(*k & crate::sampler::WALKS != 0);
        }
        return store.keys;
    };
    streamed_laps(lib, legs, runs, (rate, window), &through, &mut store);
    store.settled()
}

/// What a first walk through a long loop's keys finds: where each run first walks (piece,
/// direction, the time it starts), the loop's first walk, and its length in seconds.
struct Through {
    first_walks: Vec<Option<(usize, f64, f64)>>,
    first_walk: (f64, f64),
    length: f64,
}

/// The first walk through a loop's keys, a window of runs at a time ([`Through`]), handing
/// each run's walk flags to `walking` in order; `None` when the loop never walks.
fn walk_through<P: LoopPoints + ?Sized>(
    lib: Source<P>,
    legs: &[Leg],
    runs: (&[Run], usize, usize),
    window: usize,
    mut walking: impl FnMut(&[bool]),
) -> Option<Through> {
    let list = runs.0;
    let mut first_walks: Vec<Option<(usize, f64, f64)>> = Vec::with_capacity(list.len());
    let (mut first_time, mut last_time) = (0.0, 0.0);
    each_run_keys(lib, legs, runs, window, |r, keys| {
        let run = &list[r];
        if r == 0 {
            first_time = keys.times[0];
        }
        let start = |p: usize| key_time(keys, run, last_time, p);
        let walk = (keys.directions.iter().position(|d| !d.is_nan()))
            .map(|i| (run.piece + i, keys.directions[i], start(run.piece + i)));
        first_walks.push(walk);
        walking(&keys.walking);
        last_time = keys.times.last().copied().unwrap_or(last_time);
        true
    });
    let (_, first_walk, first_walk_t) = first_walks.iter().flatten().next().copied()?;
    Some(Through {
        first_walks,
        first_walk: (first_walk, first_walk_t),
        length: last_time - first_time,
    })
}

/// A long loop's laps ([`settle_laps`]), piece by piece through its runs' keys made a window
/// of runs at a time, as `headings_from`'s, into `store`.
fn streamed_laps<S: LapStore + ?Sized, P: LoopPoints + ?Sized>(
    lib: Source<P>,
    legs: &[Leg],
    runs: (&[Run], usize, usize),
    (rate, window): (f64, usize),
    through: &Through,
    store: &mut S,
) {
    let list = runs.0;
    let (first_walk, first_walk_t) = through.first_walk;
    // The first walk after run `r`: in a run after it, or a loop later.
    let walk_after = |r: usize| {
        (through.first_walks[r + 1..]
            .iter()
            .flatten()
            .next()
            .copied())
        .unwrap_or((usize::MAX, first_walk, first_walk_t + through.length))
    };
    let lap = |store: &mut S, h0: f64, again: bool| {
        store.begin(h0);
        // The heading at the key the next piece starts from.
        let mut from = h0;
        let mut walk: Option<(usize, f64, f64)> = None;
        let mut before = 0.0;
        each_run_keys(lib, legs, runs, window, |r, keys| {
            let run = &list[r];
            let time = |k| key_time(keys, run, before, k);
            for (i, &d) in keys.directions.iter().enumerate() {
                let k = run.piece + i;
                // The walk ahead: in this run, or in one after it, or a loop later.
                let ahead = || {
                    let rest = keys.directions[i + 1..].iter().position(|d| !d.is_nan());
                    Some(rest.map_or_else(
                        || walk_after(r),
                        |j| (k + 1 + j, keys.directions[i + 1 + j], time(k + 1 + j)),
                    ))
                };
                let next = piece_end(from, (k, d, time(k), time(k + 1)), rate, &mut walk, ahead);
                if store.meets(k + 1, next, again) {
                    return false;
                }
                from = next;
            }
            before = keys.times.last().copied().unwrap_or(before);
            true
        });
    };
    settle_laps(store, first_walk, lap);
}

/// The time of key `k` of a loop, from run `run`'s keys, or `before` (the last key of the run
/// before) for the key just before the run's first.
fn key_time(keys: &LoopKeys, run: &Run, before: f64, k: usize) -> f64 {
    if k >= run.key {
        keys.times[k - run.key]
    } else {
        before
    }
}

/// Where a run of a loop's legs starts (see [`loop_keys`]).
struct Run {
    leg: usize,
    key: usize,
    piece: usize,
    tick: u64,
    /// The world place of the key before the run's first (none before the loop's first).
    before: Option<[f64; 2]>,
}

/// A run's share of [`LoopKeys`]' lists.
type KeysPart<'a> = (&'a mut [f64], &'a mut [f64], &'a mut [bool]);

/// Writes the keys of `legs`, a run of a loop that starts at `run`, into its share.
fn fill_keys<P: LoopPoints + ?Sized>(
    lib: Source<P>,
    legs: &[Leg],
    run: &Run,
    (times, directions, walking): KeysPart,
) {
    let (mut key, mut piece, mut tick) = (0usize, 0usize, run.tick);
    let mut last = run.before.unwrap_or_default();
    for (j, leg) in legs.iter().enumerate() {
        if let Some(ahead) = legs.get(j + PREFETCH_LEGS) {
            lib.points.prefetch(ahead.first);
        }
        let patch = &lib.patches[leg.patch as usize];
        let loop_first = run.leg + j == 0;
        let duration = lib.points.with(leg.first, leg.points, |pts| {
            for (i, p) in pts.iter().enumerate() {
                if i > 0 || loop_first {
                    times[key] = (tick + u64::from(p.t)) as f64 * crate::TICK_S;
                    let place = lib.world_position(patch, *p);
                    if i > 0 {
                        // From the key before: this trajectory's last point, or the one
                        // before's last, in that trajectory's patch.
                        let walks = piece_walks(&lib, pts[i - 1], *p);
                        walking[piece] = walks;
                        directions[piece] = direction(last, place, walks);
                        piece += 1;
                    }
                    last = place;
                    key += 1;
                }
            }
            pts.last().map_or(0, |p| p.t)
        });
        tick += u64::from(duration);
    }
}

/// Trajectories in a run of [`loop_keys`].
const LEGS_PER_RUN: usize = 1024;

/// Keys from which a loop's lists are made on every core (where the `rayon` feature is on).
#[cfg(feature = "rayon")]
const PARALLEL_KEYS: usize = 1 << 16;

/// `f` of every index below `n`, in order: on every core for a long list where the `rayon`
/// feature is on (the same values: each is its own).
fn map_indices<T: Send>(n: usize, f: impl Fn(usize) -> T + Sync + Send) -> Vec<T> {
    #[cfg(feature = "rayon")]
    if n >= PARALLEL_KEYS {
        use rayon::prelude::*;
        return (0..n).into_par_iter().map(f).collect();
    }
    (0..n).map(f).collect()
}

/// `f` of every index below `n`, in order, on every core where the `rayon` feature is on.
fn map_indices_at_all<T: Send>(n: usize, f: impl Fn(usize) -> T + Sync + Send) -> Vec<T> {
    #[cfg(feature = "rayon")]
    {
        use rayon::prelude::*;
        (0..n).into_par_iter().map(f).collect()
    }
    #[cfg(not(feature = "rayon"))]
    (0..n).map(f).collect()
}

/// How many trajectories ahead [`character_headings`] asks for the points of.
const PREFETCH_LEGS: usize = 4;

#[cfg(test)]
mod tests {
    use super::*;

    /// [`loop_headings_walking`] as it was first written (a list grown per point, an
    /// `Option` per piece, a new list per lap), kept as the oracle the faster one must match
    /// to the bit.
    fn reference_loop_headings_walking(
        times: &[f64],
        points: &[[f64; 2]],
        walking: &[bool],
        rate: f64,
    ) -> Vec<f64> {
        let n = times.len();
        if n < 2 {
            return vec![PI / 2.0; n];
        }
        let direction = |k: usize| {
            let (a, b) = (points[k], points[k + 1]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            walking[k].then(|| dy.atan2(dx))
        };
        let directions: Vec<Option<f64>> = (0..n - 1).map(direction).collect();
        // Standing pieces aim at the next walk round the loop (the direction they walk off in),
        // and their run of standing ends when it starts (loop time, maybe a loop later).
        let length = times[n - 1] - times[0];
        let mut next_walk: Vec<Option<(f64, f64)>> = vec![None; n - 1];
        let mut ahead = (0..n - 1).find_map(|k| directions[k].map(|d| (d, times[k] + length)));
        for k in (0..n - 1).rev() {
            if let Some(d) = directions[k] {
                ahead = Some((d, times[k]));
            }
            next_walk[k] = ahead;
        }
        let Some(first_walk) = directions.iter().flatten().next().copied() else {
            return vec![PI / 2.0; n];
        };
        // Walk the loop from its first walking direction until the heading at the loop's start
        // repeats: a heading that catches up with its target once forgets where it started, so
        // two laps settle any loop that walks straight for as long as a turn takes. Headings are
        // kept within a turn (`turn_between(.., 0)`), so a lap that meets the lap before it at a
        // key, to the bit, is that lap from there on (each key's heading is a function of the
        // one before it alone): it stops there, and a loop of 5 million keys is walked about once,
        // not twice (and no heading drifts by whole turns, whose `fmod` was a tenth of the time).
        let lap = |h0: f64, before: Option<&[f64]>| {
            let mut h = Vec::with_capacity(n);
            h.push(h0);
            for k in 0..n - 1 {
                let (t0, t1) = (times[k], times[k + 1]);
                let from = h[k];
                let next = match (directions[k], next_walk[k]) {
                    (Some(d), _) => towards(from, d, (rate * (t1 - t0)).min(MAX_PIECE_TURN)),
                    // Standing: the run's one turn ends as it walks off; this piece turns only
                    // for the part of it that falls inside the piece.
                    (None, Some((d, walk_off))) => {
                        let starts = walk_off - turn_between(d, from).abs() / rate;
                        let step = (rate * (t1 - starts.max(t0)).max(0.0)).min(MAX_PIECE_TURN);
                        towards(from, d, step)
                    }
                    (None, None) => from,
                };
                let next = turn_between(next, 0.0);
                h.push(next);
                if let Some(b) = before
                    && b[k + 1].to_bits() == next.to_bits()
                {
                    h.extend_from_slice(&b[k + 2..]);
                    break;
                }
            }
            h
        };
        let mut h = lap(first_walk, None);
        for _ in 0..8 {
            let end = h[n - 1];
            if turn_between(end, h[0]).abs() <= 1e-12 {
                break;
            }
            h = lap(end, Some(&h));
        }
        // The loop's end is its start (a loop that never caught up keeps its last lap's start).
        let wrapped: Vec<f64> = h.iter().map(|&a| turn_between(a, 0.0)).collect();
        let mut out = wrapped;
        out[n - 1] = out[0];
        out
    }

    use proptest::prelude::*;

    const RATE: f64 = TAU; // 360 degrees a second

    fn pieces(times: &[f64], points: &[[f64; 2]]) -> Vec<Piece> {
        let h = loop_headings(times, points, RATE);
        (0..times.len() - 1)
            .map(|k| {
                let (a, b) = (points[k], points[k + 1]);
                Piece {
                    t0: times[k],
                    t1: times[k + 1],
                    walks: walks((b[0] - a[0]).hypot(b[1] - a[1]), times[k + 1] - times[k]),
                    h0: h[k],
                    h1: h[k + 1],
                }
            })
            .collect()
    }

    /// A square walked at 1 m/s, 4 m sides, with a 3 s stop at one corner.
    fn square_with_a_stop() -> (Vec<f64>, Vec<[f64; 2]>) {
        let times = vec![0.0, 4.0, 8.0, 11.0, 15.0, 19.0];
        let points = vec![
            [0.0, 0.0],
            [4.0, 0.0],
            [4.0, 4.0],
            [4.0, 4.0],
            [0.0, 4.0],
            [0.0, 0.0],
        ];
        (times, points)
    }

    #[test]
    fn a_corner_turns_at_the_rate_from_the_start_of_the_next_side() {
        let (times, points) = square_with_a_stop();
        let p = pieces(&times, &points);
        // East, then north from 4 s: a quarter turn takes 0.25 s.
        assert!((p[1].at(4.0, RATE) - 0.0).abs() < 1e-12);
        assert!((p[1].at(4.125, RATE) - PI / 4.0).abs() < 1e-12);
        assert!((p[1].at(4.25, RATE) - PI / 2.0).abs() < 1e-12);
        assert!((p[1].at(7.0, RATE) - PI / 2.0).abs() < 1e-12);
    }

    #[test]
    fn a_standing_walker_holds_then_turns_just_before_it_walks_off() {
        let (times, points) = square_with_a_stop();
        let p = pieces(&times, &points);
        // Stands 8-11 s facing north; walks off west at 11 s: turns over 10.75-11 s.
        assert!(!p[2].walks);
        assert!((p[2].at(8.0, RATE) - PI / 2.0).abs() < 1e-12);
        assert!((p[2].at(10.75, RATE) - PI / 2.0).abs() < 1e-12);
        assert!((p[2].at(11.0, RATE) - PI).abs() < 1e-12);
        assert!((p[3].at(11.0, RATE) - PI).abs() < 1e-12);
    }

    #[test]
    fn a_stop_cut_in_two_turns_once_at_its_end() {
        // Stands 8-11 s in two pieces (8-10.9, 10.9-11): the quarter turn runs 10.75-11 s.
        let times = vec![0.0, 4.0, 8.0, 10.9, 11.0, 15.0, 19.0];
        let points = vec![
            [0.0, 0.0],
            [4.0, 0.0],
            [4.0, 4.0],
            [4.0, 4.0],
            [4.0, 4.0],
            [0.0, 4.0],
            [0.0, 0.0],
        ];
        let p = pieces(&times, &points);
        assert!((p[2].at(10.75, RATE) - PI / 2.0).abs() < 1e-12);
        assert!((p[2].at(10.9, RATE) - (PI / 2.0 + 0.15 * RATE)).abs() < 1e-9);
        assert!((p[3].at(11.0, RATE) - PI).abs() < 1e-12);
    }

    #[test]
    fn a_loop_ends_facing_as_it_starts() {
        let (times, points) = square_with_a_stop();
        let h = loop_headings(&times, &points, RATE);
        assert_eq!(h[0], h[h.len() - 1]);
        // The last side walks south: the loop starts facing south and turns east over its
        // first quarter second.
        assert!((h[0] + PI / 2.0).abs() < 1e-12);
        let p = pieces(&times, &points);
        assert!((p[0].at(0.25, RATE) - 0.0).abs() < 1e-12);
    }

    fn any_loop() -> impl Strategy<Value = (Vec<f64>, Vec<[f64; 2]>)> {
        proptest::collection::vec(
            (0.001f64..3.0, -3.0f64..3.0, -3.0f64..3.0, any::<bool>()),
            1..20,
        )
        .prop_map(|steps| {
            let (mut times, mut points) = (vec![0.0], vec![[0.0, 0.0]]);
            for (dt, dx, dy, stands) in steps {
                let [x, y] = *points.last().unwrap();
                times.push(times.last().unwrap() + dt);
                points.push(if stands { [x, y] } else { [x + dx, y + dy] });
            }
            // Back to the start.
            times.push(times.last().unwrap() + 2.0);
            points.push([0.0, 0.0]);
            (times, points)
        })
    }

    #[test]
    fn a_turn_back_on_one_long_piece_turns_the_same_way_rounded_or_not() {
        // East for 2 s, then west for 3 s: half a turn at 2 rad/s fits in the piece. (The
        // runtime's sampler reads a turn of exactly half a turn as -pi, the glTF as +pi.)
        let times = [0.0, 2.0, 5.0, 7.0];
        let points = [[0.0, 0.0], [2.0, 0.0], [-1.0, 0.0], [0.0, 0.0]];
        let h = loop_headings(&times, &points, 2.0);
        assert!(turn_between(h[2], h[1]).abs() < PI - 1e-4);
    }

    /// A library of one loop of `legs` trajectories of 1 to 40 points each, in shuffled
    /// patches and places (not a valid library: only what [`character_headings`] reads).
    fn one_long_loop(legs: usize, seed: u64) -> (crate::Library, crate::Character) {
        one_long_loop_standing(legs, seed, 0)
    }

    /// [`one_long_loop`] whose points stay where the one before was `still` times in 1,000
    /// (the trajectories stand for long stretches, across runs of them).
    fn one_long_loop_standing(
        legs: usize,
        seed: u64,
        still: u64,
    ) -> (crate::Library, crate::Character) {
        use crate::{Patch, Point, Trajectory, World};
        let mut state = seed;
        let mut next = move |n: u64| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) % n
        };
        let patches: Vec<Patch> = (0..50)
            .map(|i| Patch {
                col: i % 7,
                row: i / 7,
                first_trajectory: 0,
                trajectories: 0,
                first_stander: 0,
                standers: 0,
            })
            .collect();
        let (mut trajectories, mut points) = (Vec::new(), Vec::new());
        // Trajectory j is stored at slot (j * 7) mod legs, and links to the next one's slot.
        let slot = |j: usize| (j * 7) % legs;
        let mut stored = vec![None; legs];
        for j in 0..legs {
            let n = 1 + next(40) as u32;
            let first = points.len() as u32;
            let mut t = 0;
            for i in 0..n {
                let stays = still > 0 && i > 0 && next(1000) < still;
                let (x, y) = if stays {
                    let p: &Point = points.last().expect("a point before");
                    (p.x, p.y)
                } else {
                    (next(65536) as u16, next(65536) as u16)
                };
                points.push(Point { x, y, t });
                // Now and then a pause: the same place a while.
                t += 1 + next(3000) as u32;
            }
            stored[slot(j)] = Some(Trajectory {
                patch: next(50) as u32,
                entry: 0,
                exit: 0,
                next: slot((j + 1) % legs) as u32,
                first_point: first,
                points: n,
                start: 0,
            });
        }
        trajectories.extend(stored.into_iter().map(|t| t.expect("every slot")));
        let lib = crate::Library {
            world: World {
                patch_side_m: 8.0,
                period_ticks: 200_000,
                radius_m: 0.3,
                cols: 7,
                rows: 8,
                seed,
                input_hash: [0; 8],
                turn_rate_deg_s: 360.0,
            },
            patches,
            standers: Vec::new(),
            crossings: Vec::new(),
            trajectories,
            points,
            characters: Vec::new(),
        };
        let ch = crate::Character {
            first_trajectory: 0,
            trajectories: legs as u32,
            laps: 1,
        };
        (lib, ch)
    }

    /// A loop's keys as the heading model first read them: times, world places and whether
    /// each piece walks.
    struct PlacedKeys {
        times: Vec<f64>,
        places: Vec<[f64; 2]>,
        walking: Vec<bool>,
    }

    /// A loop's keys walked in one go, a point at a time: the oracle of [`loop_keys`].
    fn keys_in_one_go(lib: &crate::Library, ch: &crate::Character) -> PlacedKeys {
        let (mut times, mut places, mut walking) = (Vec::new(), Vec::new(), Vec::new());
        let (mut at, mut tick) = (ch.first_trajectory as usize, 0u64);
        for j in 0..ch.trajectories {
            let tr = &lib.trajectories[at];
            let pts = lib.points_of(tr);
            for (i, p) in pts.iter().enumerate() {
                if i > 0 || j == 0 {
                    times.push((tick + u64::from(p.t)) as f64 * crate::TICK_S);
                    places.push(lib.world_position(&lib.patches[tr.patch as usize], *p));
                }
                if i > 0 {
                    walking.push(piece_walks(lib, pts[i - 1], *p));
                }
            }
            tick += u64::from(lib.duration_ticks(tr));
            at = tr.next as usize;
        }
        PlacedKeys {
            times,
            places,
            walking,
        }
    }

    /// A long loop's keys made in runs of trajectories (on every core where the `rayon`
    /// feature is on, as in the workspace's tests), and its headings, are the bits of walking
    /// it in one go.
    #[test]
    fn a_long_loop_made_in_runs_is_the_loop_walked_in_one_go() {
        for (legs, seed) in [(1, 1), (1023, 2), (1025, 3), (5000, 4)] {
            let (lib, ch) = one_long_loop(legs, seed);
            let legs_of = loop_legs(&lib, &ch);
            let runs = loop_runs(Source::held(&lib), &legs_of);
            let (runs, one) = (
                loop_keys(Source::held(&lib), &legs_of, (&runs.0, runs.1, runs.2)),
                keys_in_one_go(&lib, &ch),
            );
            let bits = |v: &[f64]| v.iter().map(|a| a.to_bits()).collect::<Vec<u64>>();
            assert_eq!(bits(&runs.times), bits(&one.times), "{legs} legs");
            assert_eq!(runs.walking, one.walking, "{legs} legs");
            let directions: Vec<f64> = (0..one.walking.len())
                .map(|k| direction(one.places[k], one.places[k + 1], one.walking[k]))
                .collect();
            assert_eq!(bits(&runs.directions), bits(&directions), "{legs} legs");
            let rate = f64::from(lib.world.turn_rate_deg_s).to_radians();
            let h = reference_loop_headings_walking(&one.times, &one.places, &one.walking, rate);
            let made = character_headings(&lib, &ch);
            // Every point's heading: a trajectory's first point is the one before's last key.
            let mut expected = Vec::new();
            let mut key = 0usize;
            for (j, leg) in legs_of.iter().enumerate() {
                key -= usize::from(j > 0);
                expected.extend_from_slice(&h[key..key + leg.points as usize]);
                key += leg.points as usize;
            }
            assert_eq!(bits(&made.heading), bits(&expected), "{legs} legs");
        }
    }

    /// A long loop of [`one_long_loop_standing`], cut into runs, with its keys and headings
    /// made at once at `rate`: what the streamed ways of making them are held to.
    struct AtOnce {
        lib: crate::Library,
        ch: crate::Character,
        legs: Vec<Leg>,
        runs: (Vec<Run>, usize, usize),
        keys: LoopKeys,
        headings: Vec<f64>,
    }

    impl AtOnce {
        fn new(legs: usize, seed: u64, still: u64, rate: f64) -> AtOnce {
            let (mut lib, ch) = one_long_loop_standing(legs, seed, still);
            lib.characters = vec![ch];
            let legs = loop_legs(&lib, &ch);
            let runs = loop_runs(Source::held(&lib), &legs);
            let keys = loop_keys(Source::held(&lib), &legs, (&runs.0, runs.1, runs.2));
            let headings = headings_from(&keys.times, &keys.directions, rate);
            AtOnce {
                lib,
                ch,
                legs,
                runs,
                keys,
                headings,
            }
        }

        fn runs(&self) -> (&[Run], usize, usize) {
            (&self.runs.0, self.runs.1, self.runs.2)
        }
    }

    /// A long loop's headings made a window of runs at a time, lap after lap, are the bits of
    /// its keys made at once: whatever the window, where the loop walks throughout, where it
    /// stands for runs on end (a standing piece turns towards a walk runs ahead, or a loop
    /// later), at a slow rate that takes several laps.
    #[test]
    fn a_long_loop_streamed_a_window_at_a_time_is_the_loop_made_at_once() {
        for (legs, seed, still, rate) in [
            (1, 11, 0, 6.0),
            (3000, 12, 0, 6.0),
            (3000, 13, 990, 6.0),
            (5000, 14, 999, 6.0),
            (2500, 15, 500, 0.02),
        ] {
            let made = AtOnce::new(legs, seed, still, rate);
            let bits = |v: &[f64]| v.iter().map(|a| a.to_bits()).collect::<Vec<u64>>();
            for window in [1, 2, 3, 64] {
                let (streamed, walking) = streamed_headings(
                    Source::held(&made.lib),
                    &made.legs,
                    made.runs(),
                    (rate, 0),
                    window,
                );
                let case = format!("{legs} legs, {still} still, rate {rate}, window {window}");
                assert_eq!(walking, made.keys.walking, "{case}");
                assert_eq!(bits(&streamed), bits(&made.headings), "{case}");
            }
        }
    }

    /// A long loop's headings made packed, a window of runs at a time and compared with the
    /// lap before only every few keys, are its headings made at once, packed at its points:
    /// whatever the window and however far apart the compared keys.
    #[test]
    fn a_long_loop_packed_a_window_at_a_time_is_its_headings_made_at_once_packed() {
        for (legs, seed, still, rate) in [
            (1, 31, 0, 6.0),
            (3000, 32, 0, 6.0),
            (3000, 33, 990, 6.0),
            (5000, 34, 999, 6.0),
            (2500, 35, 500, 0.02),
            (2500, 36, 1000, 6.0),
        ] {
            let at_once = AtOnce::new(legs, seed, still, rate);
            let (lib, legs_of) = (&at_once.lib, &at_once.legs);
            let model = PointHeadings {
                heading: key_headings_at_points(at_once.headings.clone(), legs_of),
                walks: at_once.keys.walking.clone(),
            };
            let mut expected = crate::PackedHeadings::for_points(lib);
            expected.take(lib, &at_once.ch, &model);
            for (window, every) in [(1, 1), (2, 7), (3, 4096), (64, 100), (64, MARK_EVERY)] {
                let runs = at_once.runs();
                let packed =
                    streamed_packed(Source::held(lib), legs_of, runs, (rate, window), every);
                let mut made = crate::PackedHeadings::for_points(lib);
                packed_at_points(&packed, legs_of, &mut made.packed);
                let case = format!("{legs} legs, {still} still, rate {rate}, window {window}");
                assert_eq!(made, expected, "{case}, every {every}");
            }
        }
    }

    /// A long loop's headings kept in full only over some stretches of its keys, a window of
    /// runs at a time, are those stretches of its headings made at once, and so are their
    /// walk flags; and a loop's stretches are its points' headings, each trajectory's first
    /// point left out but for the loop's first.
    #[test]
    fn stretches_of_a_long_loop_are_its_headings_made_at_once_there() {
        for (legs, seed, still, rate) in [
            (1, 41, 0, 6.0),
            (3000, 42, 0, 6.0),
            (3000, 43, 990, 6.0),
            (2500, 44, 500, 0.02),
            (2500, 45, 1000, 6.0),
        ] {
            let at_once = AtOnce::new(legs, seed, still, rate);
            let (lib, ch, legs_of) = (&at_once.lib, &at_once.ch, &at_once.legs);
            let keys = at_once.runs.1;
            let cut = |a: usize, b: usize| a.min(keys)..b.min(keys);
            let stretches = [
                std::iter::once(0..keys).collect(),
                vec![cut(0, 1), cut(5, 17), cut(100, 4000), cut(keys - 1, keys)],
                vec![cut(1, 2), cut(2, 2), cut(4096, 8193), cut(20_000, keys)],
            ];
            let bits = |v: &[f64]| v.iter().map(|a| a.to_bits()).collect::<Vec<_>>();
            for (window, every) in [(1, 1), (3, 7), (64, 4096)] {
                for wanted in &stretches {
                    let runs = at_once.runs();
                    let made = streamed_stretches(
                        Source::held(lib),
                        legs_of,
                        runs,
                        (rate, window),
                        (wanted, every),
                    );
                    let case = format!("{legs} legs, {still} still, rate {rate}, {wanted:?}");
                    for (r, (made, walking)) in wanted.iter().zip(made) {
                        let expected = &at_once.headings[r.clone()];
                        assert_eq!(bits(&made), bits(expected), "{case}, {window} {every}");
                        let flags = pieces_of(&at_once.keys.walking, r);
                        assert_eq!(walking, flags, "{case}");
                    }
                }
            }
            // The library's own rate, through the public way in: the points' headings.
            let all = character_headings(lib, ch);
            let whole = stretch_headings(lib, ch, std::slice::from_ref(&(0..keys)));
            let points = key_headings_at_points(whole[0].0.clone(), legs_of);
            assert_eq!(points, all.heading, "{legs} legs");
            assert_eq!(whole[0].1, all.walks, "{legs} legs");
        }
    }

    /// A library's points kept apart from its records, read a trajectory at a time, with loops
    /// of `stream` keys or more made a window at a time.
    struct Elsewhere {
        points: Vec<crate::Point>,
        stream: usize,
        reads: std::sync::atomic::AtomicUsize,
    }

    impl LoopPoints for Elsewhere {
        fn with<R>(&self, first: u32, n: u32, read: impl FnOnce(&[crate::Point]) -> R) -> R {
            self.reads
                .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            read(&self.points[first as usize..(first + n) as usize])
        }

        fn stream_keys(&self) -> usize {
            self.stream
        }
    }

    /// A loop's stretches made from points read elsewhere, a trajectory at a time (the records
    /// alone in the library: its own list of points emptied), are the bits of its own points'
    /// stretches, made at once or a window at a time.
    #[test]
    fn stretches_read_from_points_elsewhere_are_those_of_the_librarys_own_points() {
        for (legs, seed, still, rate) in
            [(1, 51, 0, 6.0), (3000, 52, 990, 6.0), (2500, 53, 500, 0.02)]
        {
            let at_once = AtOnce::new(legs, seed, still, rate);
            let keys = at_once.runs.1;
            let cut = |a: usize, b: usize| a.min(keys)..b.min(keys);
            let wanted = [cut(0, 1), cut(5, 17), cut(17.max(keys - 1), keys)];
            let mut lib = at_once.lib.clone();
            lib.world.turn_rate_deg_s = rate.to_degrees() as f32;
            let expected = stretch_headings(&lib, &at_once.ch, &wanted);
            let points = std::mem::take(&mut lib.points);
            for stream in [0, usize::MAX] {
                let elsewhere = Elsewhere {
                    points: points.clone(),
                    stream,
                    reads: Default::default(),
                };
                let made = stretch_headings_in(&lib, &elsewhere, &at_once.ch, &wanted);
                assert_eq!(
                    made, expected,
                    "{legs} legs, {still} still, streamed from {stream}"
                );
                let reads = elsewhere.reads.into_inner();
                assert!(reads >= legs, "{legs} legs read {reads} times");
            }
        }
    }

    /// A loop's key headings put at its points in place are the points' headings copied out.
    #[test]
    fn key_headings_put_at_points_in_place_are_the_copied_ones() {
        for (legs, seed) in [(1, 21), (8, 22), (1500, 23)] {
            let (lib, ch) = one_long_loop(legs, seed);
            let legs_of = loop_legs(&lib, &ch);
            let keys = loop_runs(Source::held(&lib), &legs_of).1;
            let h: Vec<f64> = (0..keys).map(|k| k as f64 * 0.5).collect();
            let mut expected = Vec::new();
            let mut key = 0usize;
            for (j, leg) in legs_of.iter().enumerate() {
                key -= usize::from(j > 0);
                expected.extend_from_slice(&h[key..key + leg.points as usize]);
                key += leg.points as usize;
            }
            assert_eq!(key_headings_at_points(h, &legs_of), expected, "{legs} legs");
        }
    }

    /// Headings taken in packed, a character at a time (what `crowd check` holds), are every
    /// point's headings packed after they are all made (what the sampler kept).
    #[test]
    fn headings_taken_in_packed_are_the_library_headings_packed() {
        for (legs, seed) in [(1, 5), (300, 6), (2000, 7)] {
            let (mut lib, ch) = one_long_loop(legs, seed);
            lib.characters = vec![ch];
            let whole = crate::PackedHeadings::from(library_headings(&lib));
            let mut taken = crate::PackedHeadings::for_points(&lib);
            taken.take(&lib, &ch, &character_headings(&lib, &ch));
            assert_eq!(taken, whole, "{legs} legs");
            assert_eq!(library_packed_headings(&lib), whole, "{legs} legs");
        }
    }

    proptest! {
        /// The headings made in place, lap over lap, are the first way's to the bit, at any
        /// rate (slow rates need several laps to settle).
        #[test]
        fn headings_in_place_are_the_first_way_s((times, points) in any_loop(), rate in 0.05f64..20.0) {
            let walking: Vec<bool> = (1..times.len())
                .map(|k| {
                    let (a, b) = (points[k - 1], points[k]);
                    walks((b[0] - a[0]).hypot(b[1] - a[1]), times[k] - times[k - 1])
                })
                .collect();
            let new = loop_headings_walking(&times, &points, &walking, rate);
            let old = reference_loop_headings_walking(&times, &points, &walking, rate);
            let bits = |h: &[f64]| h.iter().map(|a| a.to_bits()).collect::<Vec<u64>>();
            prop_assert_eq!(bits(&new), bits(&old));
        }
    }

    proptest! {
        /// Sampled anywhere, the heading turns no faster than the rate, does not turn while
        /// standing but for the turn that ends as it walks off, and loops.
        #[test]
        fn headings_turn_within_the_rate_and_loop((times, points) in any_loop(), k in 2usize..200) {
            let p = pieces(&times, &points);
            let end = *times.last().unwrap();
            let at = |t: f64| {
                let i = p.partition_point(|q| q.t1 < t).min(p.len() - 1);
                p[i].at(t, RATE)
            };
            let dt = end / k as f64;
            for i in 0..k {
                let (a, b) = (i as f64 * dt, (i + 1) as f64 * dt);
                let turned = turn_between(at(b), at(a)).abs();
                prop_assert!(turned <= RATE * (b - a) * (1.0 + 1e-9) + 1e-9, "{turned} in {}", b - a);
            }
            prop_assert!(turn_between(at(end), at(0.0)).abs() < 1e-9);
            // Short of half a turn on any piece, so that which way it turns does not hang on
            // rounding its ends to 65536ths of a turn.
            let q = std::f64::consts::TAU / 65536.0;
            let round = |h: f64| (h / q).round() * q;
            for piece in &p {
                prop_assert!(piece.turn().abs() <= MAX_PIECE_TURN + 1e-12);
                let rounded = turn_between(round(piece.h1), round(piece.h0));
                prop_assert!(rounded.signum() == piece.turn().signum() || piece.turn().abs() < q);
            }
            for q in p.iter().filter(|q| !q.walks) {
                let (start, stop) = q.turning(RATE);
                prop_assert!((stop - q.t1).abs() < 1e-12);
                prop_assert!(turn_between(q.at(start, RATE), q.h0).abs() < 1e-12);
            }
        }
    }
}
