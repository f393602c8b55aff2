//! Exactness, continuity and motion quality of the shipped trajectories (DESIGN.md's figures).
//!
//! Acceleration and turning rate are measured as a player shows the motion: positions sampled
//! every 0.1 s, second differences of consecutive frames (and the change of velocity where a
//! character crosses a border, over one frame). A polyline's corner is then the sharp change it
//! is on screen; weighting its vertices by the time around them instead would spread a corner
//! over seconds and reward coarse paths. Percentiles are over frames, so by time.

use crate::memo::{Bytes, Reader};
use crowd_core::PatchGraph;
use crowd_core::patch_keys::Table;
use crowd_core::patterns::{Crossings, Way, border_point};
use crowd_core::trajectories::{PatchMotion, position_on};
use crowd_geometry::Segment;
use glam::DVec2;

/// DESIGN.md's band of walking speeds, m/s.
pub const SPEED_BAND: (f64, f64) = (0.5, 1.8);
/// Slower than this is standing (pauses are left out of the speed share and turning).
const STANDING: f64 = 0.05;
/// Frame step of the motion figures, seconds: acceleration and turning are measured on
/// positions sampled at 10 frames per second, as a player shows them.
const FRAME_S: f64 = 0.1;
/// Histogram resolution of accelerations (m/s2) and turning rates (rad/s), and their range.
const BIN: f64 = 0.005;
const BINS: usize = 20_000;

/// Motion figures of a set of trajectories.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MotionFigures {
    /// Share of walking time (pauses excepted) at speeds within 0.5-1.8 m/s.
    pub speed_in_band: f64,
    /// 95th percentile (by time) of acceleration, m/s2, and of turning rate, rad/s.
    pub accel_p95: f64,
    pub turn_rate_p95: f64,
    /// Largest change of velocity where a character crosses from one patch to the next, m/s.
    pub max_border_velocity_jump: f64,
    /// Largest distance (m) and time difference (s, modulo the period) between a trajectory's
    /// end and the crossing it starts or ends at.
    pub max_boundary_error_m: f64,
    pub max_boundary_time_error_s: f64,
    /// Crossings not entered by exactly one trajectory and left by exactly one.
    pub unmatched_crossings: u64,
    /// The fastest piece of any trajectory, m/s, and where: (patch, trajectory, time).
    #[serde(default)]
    pub max_speed_m_s: f64,
    #[serde(default)]
    pub max_speed_at: Option<(u32, u32, f64)>,
}

/// Walking time is summed in whole [`TIME_UNIT`]s (2^-24 s, 60 ns): integers add up to the same
/// figure in any order, so a patch's tally can be kept between builds and added to the others
/// in whatever order the work was cut (floating-point sums depend on their order).
const TIME_UNITS_PER_S: f64 = (1u64 << 24) as f64;

/// `dt` seconds in whole time units.
fn units(dt: f64) -> u64 {
    (dt * TIME_UNITS_PER_S).round() as u64
}

/// The world's tally: walking time, and frames per bin of acceleration and turning rate (each
/// frame weighs [`FRAME_S`], so counting them is exact).
struct Tally {
    walking: u64,
    in_band: u64,
    accel: Vec<u64>,
    turn: Vec<u64>,
    fastest: Fastest,
}

/// The fastest piece, m/s, and where: (patch, trajectory, time). Of equals, the first in
/// (patch, trajectory, time) order, whatever order they were met in.
type Fastest = (f64, Option<(u32, u32, f64)>);

fn faster(a: Fastest, b: Fastest) -> Fastest {
    let first = |x: &Fastest, y: &Fastest| match (x.1, y.1) {
        (Some(p), Some(q)) => (p.0, p.1, p.2)
            .partial_cmp(&(q.0, q.1, q.2))
            .is_some_and(|o| o.is_lt()),
        (Some(_), None) => true,
        _ => false,
    };
    if b.0 > a.0 || (b.0 == a.0 && first(&b, &a)) {
        b
    } else {
        a
    }
}

impl Tally {
    fn new() -> Tally {
        Tally {
            walking: 0,
            in_band: 0,
            accel: vec![0; BINS],
            turn: vec![0; BINS],
            fastest: (0.0, None),
        }
    }

    /// Adds patch `p`'s tally.
    fn add(&mut self, p: u32, o: &PatchTally) {
        self.walking += o.walking;
        self.in_band += o.in_band;
        for &(bin, n) in &o.accel {
            self.accel[bin as usize] += u64::from(n);
        }
        for &(bin, n) in &o.turn {
            self.turn[bin as usize] += u64::from(n);
        }
        let here = (o.fastest.0, o.fastest.1.map(|(i, t)| (p, i, t)));
        self.fastest = faster(self.fastest, here);
    }

    /// A frame's change of velocity from `v1` to `v2` (the frame that straddles a border).
    fn vertex(&mut self, v1: DVec2, v2: DVec2) {
        let (accel, turn) = vertex_bins(v1, v2);
        self.accel[accel as usize] += 1;
        if let Some(turn) = turn {
            self.turn[turn as usize] += 1;
        }
    }
}

/// The bins of a change of velocity from `v1` to `v2` over a frame: acceleration, and turning
/// rate (none when either is standing).
fn vertex_bins(v1: DVec2, v2: DVec2) -> (u32, Option<u32>) {
    let bin = |x: f64| ((x / BIN) as usize).min(BINS - 1) as u32;
    let accel = bin((v2 - v1).length() / FRAME_S);
    let turn = (v1.length() > STANDING && v2.length() > STANDING).then(|| {
        let angle = v1.perp_dot(v2).atan2(v1.dot(v2)).abs();
        bin(angle / FRAME_S)
    });
    (accel, turn)
}

/// One patch's share of the motion figures: its walking time, its frames' bins (sparse:
/// (bin, frames)), its fastest piece (trajectory, time), and its trajectories' ends.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct PatchTally {
    walking: u64,
    in_band: u64,
    accel: Vec<(u32, u32)>,
    turn: Vec<(u32, u32)>,
    fastest: (f64, Option<(u32, f64)>),
    ends: Vec<End>,
    /// The largest distance (m) and time difference (s) of an end from its crossing.
    pos_err: f64,
    time_err: f64,
}

/// A trajectory's end at a crossing: the crossing as the patch numbers it
/// (`patch_keys::Table`), whether it enters there, and the velocity there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct End {
    local: u32,
    entry: bool,
    v: DVec2,
}

/// A patch's tally as a check holds it and its memo keeps it: bytes, the bins as the gap from
/// the last bin and the count, the ends as their crossing and whether they enter, each a
/// LEB128 number (mostly a byte), the velocities and errors as they are. As structs the
/// million's 167,545 tallies held 1.3 GB for the whole check (bins 8 bytes each, in vectors
/// grown by doubling); packed they hold a quarter of their memo's bytes.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PackedTally(Box<[u8]>);

impl PatchTally {
    pub fn pack(&self) -> PackedTally {
        let mut o = Bytes(Vec::new());
        o.varint(self.walking);
        o.varint(self.in_band);
        for bins in [&self.accel, &self.turn] {
            o.varint(bins.len() as u64);
            let mut last = 0;
            for &(bin, n) in bins {
                o.varint(u64::from(bin - last));
                o.varint(u64::from(n));
                last = bin;
            }
        }
        o.f64(self.fastest.0);
        o.option(&self.fastest.1, |o, &(i, t)| {
            o.varint(u64::from(i));
            o.f64(t);
        });
        o.varint(self.ends.len() as u64);
        for e in &self.ends {
            o.varint(u64::from(e.local) << 1 | u64::from(e.entry));
            o.vec2(e.v);
        }
        o.f64(self.pos_err);
        o.f64(self.time_err);
        PackedTally(o.0.into_boxed_slice())
    }
}

impl PackedTally {
    /// The tally; `None` when the bytes are not one (a memo's are checked as it is read).
    pub fn unpack(&self) -> Option<PatchTally> {
        let mut r = Reader(&self.0);
        let u32 = |r: &mut Reader| u32::try_from(r.varint()?).ok();
        let bins = |r: &mut Reader| {
            let n = usize::try_from(r.varint()?).ok()?.min(BINS);
            let mut out = Vec::with_capacity(n);
            let mut last = 0u32;
            for _ in 0..n {
                last = last.checked_add(u32(r)?).filter(|&b| b < BINS as u32)?;
                out.push((last, u32(r)?));
            }
            Some(out)
        };
        let (walking, in_band) = (r.varint()?, r.varint()?);
        let (accel, turn) = (bins(&mut r)?, bins(&mut r)?);
        let fastest = (r.f64()?, r.option(|r| Some((u32(r)?, r.f64()?)))?);
        let n = usize::try_from(r.varint()?).ok()?;
        let ends = (0..n)
            .map(|_| {
                let c = r.varint()?;
                Some(End {
                    local: u32::try_from(c >> 1).ok()?,
                    entry: c & 1 == 1,
                    v: r.vec2()?,
                })
            })
            .collect::<Option<Vec<End>>>()?;
        let tally = PatchTally {
            walking,
            in_band,
            accel,
            turn,
            fastest,
            ends,
            pos_err: r.f64()?,
            time_err: r.f64()?,
        };
        r.0.is_empty().then_some(tally)
    }

    /// For a memo (`memo.rs`).
    pub fn put(&self, o: &mut Bytes) {
        o.blob(&self.0);
    }

    /// A memo's tally, checked to unpack.
    pub fn get(r: &mut Reader) -> Option<PackedTally> {
        let packed = PackedTally(r.blob()?.into());
        packed.unpack().map(|_| packed)
    }
}

/// Counts of each bin in `bins`, by bin.
fn sparse(mut bins: Vec<u32>) -> Vec<(u32, u32)> {
    bins.sort_unstable();
    let mut out: Vec<(u32, u32)> = Vec::new();
    for b in bins {
        match out.last_mut() {
            Some(last) if last.0 == b => last.1 += 1,
            _ => out.push((b, 1)),
        }
    }
    out
}

/// What the motion figures take of patch `p` (motion `m`, its crossings numbered by `table`).
pub(crate) fn patch_tally(
    world: (&PatchGraph, Crossings<'_>, f64),
    p: usize,
    m: &PatchMotion,
    table: &Table,
) -> PatchTally {
    let (mut accel, mut turn) = (Vec::new(), Vec::new());
    let mut t = PatchTally::default();
    for (i, tr) in m.trajectories.iter().enumerate() {
        let pts = &tr.points;
        for w in pts.windows(2).filter(|w| w[1].t > w[0].t) {
            let dt = w[1].t - w[0].t;
            let speed = w[1].pos.distance(w[0].pos) / dt;
            if speed > t.fastest.0 {
                t.fastest = (speed, Some((i as u32, w[0].t)));
            }
            if speed > STANDING {
                t.walking += units(dt);
                if (SPEED_BAND.0..=SPEED_BAND.1).contains(&speed) {
                    t.in_band += units(dt);
                }
            }
        }
        // Frames every FRAME_S from the entry, as a player samples the path.
        let (t0, t1) = (pts[0].t, pts[pts.len() - 1].t);
        let frames = ((t1 - t0) / FRAME_S).floor() as usize;
        // The piece that holds each frame's time, found walking on from the last frame's
        // (`position_at`'s search for every frame was a tenth of a check from nothing).
        let mut k = 0;
        let samples: Vec<DVec2> = (0..=frames)
            .map(|i| {
                let t = t0 + i as f64 * FRAME_S;
                while k < pts.len() && pts[k].t <= t {
                    k += 1;
                }
                position_on(pts, k.clamp(1, pts.len() - 1), t)
            })
            .collect();
        for w in samples.windows(3) {
            let (v1, v2) = ((w[1] - w[0]) / FRAME_S, (w[2] - w[1]) / FRAME_S);
            let (a, r) = vertex_bins(v1, v2);
            accel.push(a);
            turn.extend(r);
        }
    }
    t.accel = sparse(accel);
    t.turn = sparse(turn);
    ends(world, p, m, table, &mut t);
    t
}

/// Where each end of patch `p`'s trajectories lies against its crossing, and the velocity
/// there (every crossing is then seen from both sides, [`Measure::finish`]).
fn ends(
    (graph, crossings, period_s): (&PatchGraph, Crossings<'_>, f64),
    p: usize,
    m: &PatchMotion,
    table: &Table,
    t: &mut PatchTally,
) {
    let side = graph.world.patch_side_m;
    for tr in &m.trajectories {
        let pts = &tr.points;
        let ends = [
            (tr.entry, pts[0], pts[1], true),
            (tr.exit, pts[pts.len() - 1], pts[pts.len() - 2], false),
        ];
        for (c, end, next, entry) in ends {
            let Some(crossing) = crossings.get(c) else {
                continue;
            };
            let border = &graph.borders[crossing.border as usize];
            let (a, b) = border_point(border, side, crossing.s);
            // The crossing goes a -> b when its way is AToB.
            let (from, to) = match crossing.way {
                Way::AToB => (a, b),
                Way::BToA => (b, a),
            };
            let here = if entry { to } else { from };
            if here.patch.0 as usize != p {
                t.pos_err = f64::INFINITY;
                continue;
            }
            t.pos_err = t.pos_err.max(end.pos.distance(here.pos));
            let dt = (end.t - crossing.t).rem_euclid(period_s);
            t.time_err = t.time_err.max(dt.min(period_s - dt));
            let (a, b) = if entry { (end, next) } else { (next, end) };
            let v = Segment {
                p0: a.pos,
                t0: a.t,
                p1: b.pos,
                t1: b.t,
            }
            .velocity();
            t.ends.push(End {
                local: table.local(c),
                entry,
                v,
            });
        }
    }
}

/// The value below which 95 % of the frames lie.
fn p95(hist: &[u64]) -> f64 {
    let total: u64 = hist.iter().sum();
    let mut seen = 0u64;
    for (i, w) in hist.iter().enumerate() {
        seen += w;
        if seen as f64 >= 0.95 * total as f64 {
            return (i as f64 + 1.0) * BIN;
        }
    }
    0.0
}

/// The motion figures of `motion` (per patch, in patch order) against its crossings.
pub fn figures<'a>(
    graph: &PatchGraph,
    crossings: impl Into<Crossings<'a>>,
    motion: &[PatchMotion],
    period_s: f64,
) -> MotionFigures {
    let crossings = crossings.into();
    let tables = crowd_core::patch_keys::Seen::new(graph, crossings).tables;
    let mut m = Measure::new(crossings.numbers());
    for (p, pm) in motion.iter().enumerate() {
        let t = patch_tally((graph, crossings, period_s), p, pm, &tables[p]);
        m.add(p, &t, &tables[p]);
    }
    m.finish()
}

/// The motion figures of a world taken a patch at a time ([`Measure::add`], in any order):
/// what they hold is a tally, and a slot for each crossing one of whose two patches is taken
/// so far, not the motion. A crossing is judged once both of its patches are: taken in patch
/// order, a row of patches' crossings are open at a time (a slot for every crossing of the
/// world was the million's 0.11 GB, at its gathering check's peak).
pub struct Measure {
    tally: Tally,
    /// The crossings measured (the world's numbers).
    held: std::ops::Range<u32>,
    open: std::collections::HashMap<u32, Slot>,
    /// Crossings entered once and left once, judged so far, and the largest change of velocity
    /// there.
    matched: u64,
    jump: f64,
    pos_err: f64,
    time_err: f64,
}

/// A crossing while its patches are taken: how many of them are, and the trajectories that
/// enter (leave) by it with the velocity there.
#[derive(Default)]
struct Slot {
    patches: u8,
    entered: (u32, DVec2),
    left: (u32, DVec2),
}

impl Measure {
    /// A measure of the crossings `held` (the world's numbers: all of them in a whole check).
    pub fn new(held: std::ops::Range<u32>) -> Measure {
        Measure {
            tally: Tally::new(),
            held,
            open: std::collections::HashMap::new(),
            matched: 0,
            jump: 0.0,
            pos_err: 0.0,
            time_err: 0.0,
        }
    }

    /// Adds patch `p`'s share (its crossings numbered by `table`, which lists all of them).
    pub(crate) fn add(&mut self, p: usize, t: &PatchTally, table: &Table) {
        self.tally.add(p as u32, t);
        self.pos_err = self.pos_err.max(t.pos_err);
        self.time_err = self.time_err.max(t.time_err);
        for e in &t.ends {
            let c = table.global(e.local);
            if !self.held.contains(&c) {
                continue;
            }
            let slot = self.open.entry(c).or_default();
            let end = if e.entry {
                &mut slot.entered
            } else {
                &mut slot.left
            };
            // A crossing entered (left) once has one velocity there, whatever the order.
            end.0 += 1;
            end.1 = e.v;
        }
        // Each crossing lies on one border, in the tables of its two patches.
        let held = self.held.clone();
        for &(start, count) in &table.0 {
            for c in (start..start + count).filter(|c| held.contains(c)) {
                let slot = self.open.entry(c).or_default();
                slot.patches += 1;
                if slot.patches >= 2
                    && let Some(done) = self.open.remove(&c)
                {
                    self.judge(&done);
                }
            }
        }
    }

    /// A crossing whose trajectories are all taken: matched when entered once and left once,
    /// and then a vertex of the character's world path like any other (its turn and change of
    /// speed count in the percentiles too, as the frame that straddles the border).
    fn judge(&mut self, s: &Slot) {
        if s.entered.0 != 1 || s.left.0 != 1 {
            return;
        }
        self.matched += 1;
        self.jump = self.jump.max((s.entered.1 - s.left.1).length());
        self.tally.vertex(s.left.1, s.entered.1);
    }

    /// The figures, once every patch was added.
    pub fn finish(mut self) -> MotionFigures {
        // Crossings one of whose patches was never taken (a check of part of the world).
        let open: Vec<Slot> = std::mem::take(&mut self.open).into_values().collect();
        for s in &open {
            self.judge(s);
        }
        let tally = self.tally;
        let unmatched = self.held.len() as u64 - self.matched;
        let jump = self.jump;
        MotionFigures {
            speed_in_band: if tally.walking > 0 {
                tally.in_band as f64 / tally.walking as f64
            } else {
                1.0
            },
            accel_p95: p95(&tally.accel),
            turn_rate_p95: p95(&tally.turn),
            max_border_velocity_jump: jump,
            max_boundary_error_m: self.pos_err,
            max_boundary_time_error_s: self.time_err,
            unmatched_crossings: unmatched,
            max_speed_m_s: tally.fastest.0,
            max_speed_at: tally.fastest.1,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn tally() -> impl Strategy<Value = PatchTally> {
        let bins = || {
            proptest::collection::btree_map(0..BINS as u32, 1..u32::MAX, 0..300)
                .prop_map(|m| m.into_iter().collect::<Vec<_>>())
        };
        let end =
            (any::<u32>(), any::<bool>(), any::<(f64, f64)>()).prop_map(|(local, entry, v)| End {
                local,
                entry,
                v: DVec2::new(v.0, v.1),
            });
        (
            (any::<u64>(), any::<u64>(), bins(), bins()),
            (
                any::<f64>(),
                proptest::option::of((any::<u32>(), any::<f64>())),
            ),
            (
                proptest::collection::vec(end, 0..40),
                any::<f64>(),
                any::<f64>(),
            ),
        )
            .prop_map(
                |((walking, in_band, accel, turn), fastest, (ends, pos_err, time_err))| {
                    PatchTally {
                        walking,
                        in_band,
                        accel,
                        turn,
                        fastest,
                        ends,
                        pos_err,
                        time_err,
                    }
                },
            )
    }

    /// Bit for bit, NaNs too: `PartialEq` on the floats would not say.
    fn bits(t: &PatchTally) -> String {
        format!("{t:?}")
    }

    proptest! {
        /// A packed tally is the tally, to the bit, and its bytes cut short are none, never a
        /// panic.
        #[test]
        fn a_packed_tally_is_the_tally(t in tally()) {
            let packed = t.pack();
            let back = packed.unpack().expect("unpacks");
            prop_assert_eq!(bits(&back), bits(&t));
            for cut in 0..packed.0.len() {
                prop_assert!(PackedTally(packed.0[..cut].into()).unpack().is_none(), "cut at {}", cut);
            }
        }
    }

    /// A world of `cols` x `rows` patches in a row-major grid, a border between each two side
    /// by side, with `per_border[b]` crossings on border `b` (numbered border after border):
    /// each patch's table, its runs in border order.
    fn grid_tables(cols: u32, rows: u32, per_border: &[u32]) -> (Vec<Table>, Vec<(u32, u32)>) {
        let mut borders = Vec::new();
        for r in 0..rows {
            for c in 0..cols {
                let p = r * cols + c;
                if c + 1 < cols {
                    borders.push((p, p + 1));
                }
                if r + 1 < rows {
                    borders.push((p, p + cols));
                }
            }
        }
        let mut tables = vec![Table::default(); (cols * rows) as usize];
        let mut first = 0;
        for (b, &(a, z)) in borders.iter().enumerate() {
            let count = per_border[b % per_border.len()];
            for p in [a, z] {
                tables[p as usize].0.push((first, count));
            }
            first += count;
        }
        (tables, borders)
    }

    proptest! {
        /// The border figures are the same whatever order the patches are taken in, and are
        /// those of every crossing judged at once: matched when entered once and left once
        /// (by either of its patches), the largest change of velocity among those, and every
        /// other crossing held unmatched, a crossing never walked included. A patch never
        /// taken (a part of the world) leaves its crossings to be judged at the end.
        #[test]
        fn measured_in_any_order_the_crossings_are_judged_as_all_at_once(
            (cols, rows) in (1u32..5, 1u32..5),
            per_border in proptest::collection::vec(0u32..4, 1..5),
            ends in proptest::collection::vec((0u32..64, any::<bool>(), any::<bool>(), -3i8..4, -3i8..4), 0..120),
            order_seed in any::<u64>(),
            window in (0u32..8, 0u32..80),
            untaken in 0usize..40,
        ) {
            let (tables, borders) = grid_tables(cols, rows, &per_border);
            let world: u32 = (0..borders.len()).map(|b| per_border[b % per_border.len()]).sum();
            prop_assume!(world > 0);
            // Each end at a crossing, from one of its border's two patches.
            let border_of = |c: u32| {
                let mut first = 0;
                (0..borders.len())
                    .find(|&b| {
                        first += per_border[b % per_border.len()];
                        c < first
                    })
                    .expect("a crossing of a border")
            };
            let mut tallies: Vec<PatchTally> = (0..tables.len())
                .map(|_| PatchTally::default())
                .collect();
            let mut counts = vec![(0u32, DVec2::ZERO, 0u32, DVec2::ZERO); world as usize];
            for &(c, side, entry, vx, vy) in &ends {
                let c = c % world;
                let (a, z) = borders[border_of(c)];
                let p = if side { a } else { z } as usize;
                let v = DVec2::new(f64::from(vx), f64::from(vy));
                let local = tables[p].local(c);
                tallies[p].ends.push(End { local, entry, v });
                if p == untaken {
                    continue;
                }
                let k = &mut counts[c as usize];
                if entry { (k.0, k.1) = (k.0 + 1, v) } else { (k.2, k.3) = (k.2 + 1, v) }
            }
            let held = window.0.min(world)..(window.0 + window.1).min(world);
            let measured = |order: &[usize]| {
                let mut m = Measure::new(held.clone());
                for &p in order {
                    m.add(p, &tallies[p], &tables[p]);
                }
                m.finish()
            };
            let in_order: Vec<usize> = (0..tables.len()).filter(|&p| p != untaken).collect();
            let mut shuffled = in_order.clone();
            let mut state = order_seed | 1;
            for i in (1..shuffled.len()).rev() {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                shuffled.swap(i, (state % (i as u64 + 1)) as usize);
            }
            let figures = measured(&in_order);
            prop_assert_eq!(&measured(&shuffled), &figures);
            let matched: Vec<&(u32, DVec2, u32, DVec2)> = (held.clone())
                .map(|c| &counts[c as usize])
                .filter(|k| k.0 == 1 && k.2 == 1)
                .collect();
            prop_assert_eq!(figures.unmatched_crossings, held.len() as u64 - matched.len() as u64);
            let jump = matched.iter().map(|k| (k.1 - k.3).length()).fold(0.0, f64::max);
            prop_assert_eq!(figures.max_border_velocity_jump, jump);
        }
    }

    #[test]
    fn a_tally_packs_in_a_few_bytes_a_bin() {
        let t = PatchTally {
            walking: 1 << 30,
            in_band: 1 << 29,
            accel: (0..200).map(|b| (b * 2, 3)).collect(),
            turn: (0..200).map(|b| (b + 100, 40)).collect(),
            fastest: (1.8, Some((3, 2.5))),
            ends: Vec::new(),
            pos_err: 0.0,
            time_err: 0.0,
        };
        let packed = t.pack();
        assert!(packed.0.len() < 2 * 400 + 64, "{} bytes", packed.0.len());
        assert_eq!(packed.unpack(), Some(t));
    }
}
