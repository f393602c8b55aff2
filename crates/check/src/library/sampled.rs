//! The runtime's `Sampler` played over one period, a walker at a time as far as its figures go:
//! each walker's fastest step, fastest turn and jumps are kept in the memo by the hash of
//! everything the sampler reads to play it ([`window_keys`]), so a check after a brush stroke
//! plays again only the walkers whose stretch of loop the stroke reached.
//!
//! Over one period a walker walks one period's stretch of its loop (its window): a lap of a
//! loop of `laps` periods. What the sampler shows of it then depends only on the trajectories
//! of that stretch (their points, their patch's place, the headings at their points) and on
//! where the stretch begins against the frames' times, with the library's period, turn rate
//! and patch side. The figures are maxima and a count, so the walkers' shares give the same
//! bits whichever were played again.

use super::Source;
use crate::memo::Recalled;
use crate::products::Sampled;
use crowd_core::Hash;
use crowd_runtime::{Library, LoadError, PackedHeadings, Sample, Sampler, TICK_S};
use rayon::prelude::*;

/// One walker's share of the sampler's figures over the period.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Played {
    /// Its longest step between two frames, squared (m^2; infinite when it went missing).
    pub max_step2: f64,
    /// Its fastest turn between two frames, rad/s.
    pub max_turn: f64,
    /// Its steps longer than the fastest piece of its stretch of loop allows.
    pub jumps: u64,
}

impl Played {
    fn merge(&mut self, other: &Played) {
        self.max_step2 = self.max_step2.max(other.max_step2);
        self.max_turn = self.max_turn.max(other.max_turn);
        self.jumps += other.jumps;
    }
}

/// The sampler's figures, each walker's share by its key (in id order), and how many walkers
/// were played again.
pub(crate) struct SampledShares {
    pub sampled: Sampled,
    pub kept: Vec<([u8; 32], Played)>,
    pub replayed: usize,
}

/// Everywhere.
const EVERYWHERE: [f32; 4] = [f32::MIN, f32::MIN, f32::MAX, f32::MAX];

/// Runs of frames per thread in [`sample_memo`]: the period is cut into this many runs a
/// thread, each played by its own sampler in parallel (a run's first frame searches each
/// walker's loop, the others step on: runs of 125 frames were 8 searches of painting's 98,865
/// walkers on 2 threads, a twentieth of its check).
const RUNS_PER_THREAD: u64 = 2;

/// Plays `lib` through the runtime's sampler every `step` seconds over one period (every
/// walker then walks each of its loop's periods once over all its laps): the longest step of
/// any character between frames, and how many are longer than the walker's fastest piece
/// allows (of the stretch of loop it walks over the period: a jump of a slow walker is one,
/// whoever else runs). The frames are played in runs ([`RUNS_PER_THREAD`]), each by its own
/// sampler, in parallel (the same figures for any thread count: a maximum and a count).
pub fn sample(lib: &Library, step: f64) -> Sampled {
    let played = sample_memo(lib, step, &Recalled::default());
    played.expect("a library in memory is at hand").sampled
}

/// [`sample`], taking from `memo` the share of every walker whose key ([`window_keys`]) it
/// holds and playing only the others; a run of loops at a time (the library of those loops
/// alone, [`Source::loops`]), each walker's share the same as played among all.
pub(crate) fn sample_memo<S: Source>(
    src: &S,
    step: f64,
    memo: &Recalled,
) -> Result<SampledShares, LoadError> {
    let frames = (src.lib().period_s() / step).round().max(1.0) as u64;
    let mut whole = Played::default();
    let mut kept = Vec::with_capacity(src.lib().walkers() as usize);
    let mut replayed = 0;
    for (run, long) in loop_runs(src) {
        let (shares, played) = if long {
            sample_long_loop(src, run.start, (step, frames), memo)?
        } else {
            let lib = src.loops(run)?;
            let headings = headings(&lib);
            sample_loops(&lib, headings, (step, frames), memo, None)
        };
        for (_, share) in &shares {
            whole.merge(share);
        }
        kept.extend(shares);
        replayed += played;
    }
    Ok(SampledShares {
        sampled: Sampled {
            step_s: step,
            frames,
            max_speed_m_s: whole.max_step2.sqrt() / step,
            jumps: whole.jumps,
            max_turn_rate_rad_s: Some(whole.max_turn),
        },
        kept,
        replayed,
    })
}

/// Each walker's share, by its key, in id order.
type Shares = Vec<([u8; 32], Played)>;

/// The library's loops in runs of about the check's budget of points
/// (`source::loop_runs`), a loop of more alone and told so (true).
fn loop_runs<S: Source>(src: &S) -> Vec<(std::ops::Range<usize>, bool)> {
    let lib = src.lib();
    let long = |c: usize| super::source::loop_points(lib, &lib.characters[c]) > src.budget();
    let mut out = Vec::new();
    for run in super::source::loop_runs(lib, src.budget()) {
        let mut start = run.start;
        for c in run.clone().filter(|&c| long(c)) {
            if start < c {
                out.push((start..c, false));
            }
            out.push((c..c + 1, true));
            start = c + 1;
        }
        if start < run.end {
            out.push((start..run.end, false));
        }
    }
    out
}

/// Loop `c` of `src`, longer than the check's budget, played a group of its walkers at a
/// time: each group with a library of the loop whose trajectories hold their points only
/// where the group's walkers walk over the period (their windows, [`lap_window`]), the others
/// standing in (`LibraryFile::loop_part`), and the loop's headings made once without its
/// points. A loop threads through much of the world (the million's longest holds 36 million
/// of its 96 million points): played whole, it was the gather's peak (0.36 GB of points
/// besides its headings). Each walker's share is the bits it has played among all.
fn sample_long_loop<S: Source>(
    src: &S,
    c: usize,
    (step, frames): (f64, u64),
    memo: &Recalled,
) -> Result<(Shares, usize), LoadError> {
    let index = src.lib();
    let ch = &index.characters[c];
    let keys = src.loop_keys(c)?;
    let order = loop_order_with(index, ch, |i| src.last_tick(i as usize));
    let span = window_span(step, frames);
    let windows: Vec<std::ops::Range<usize>> = (0..ch.laps)
        .map(|lap| lap_window(index, ch, lap, &order, span).1)
        .collect();
    let points = |k: usize| index.trajectories[order[k % order.len()].0 as usize].points as usize;
    let mut skeleton = crowd_runtime::LoopSkeleton::new(index, c, |i| src.last_tick(i));
    let (mut kept, mut played) = (Vec::with_capacity(ch.laps as usize), 0);
    for laps in lap_groups(&windows, points, src.budget()) {
        // The trajectories the group walks, in the library's (and the file's) order.
        let mut walked: Vec<u32> = (laps.clone())
            .flat_map(|lap| windows[lap as usize].clone())
            .map(|k| order[k % order.len()].0)
            .collect();
        walked.sort_unstable();
        walked.dedup();
        let (part, headings) = src.loop_part(&mut skeleton, &walked, &keys)?;
        let (shares, n) = sample_loops(&part, headings, (step, frames), memo, Some(laps));
        kept.extend(shares);
        played += n;
    }
    Ok((kept, played))
}

/// Consecutive laps whose windows hold about `budget` points together (at least one lap a
/// group): a group's windows are one stretch of the loop, a lap's a period before the last's.
fn lap_groups(
    windows: &[std::ops::Range<usize>],
    points: impl Fn(usize) -> usize,
    budget: usize,
) -> Vec<std::ops::Range<u32>> {
    let mut groups = Vec::new();
    let (mut start, mut held) = (0u32, 0usize);
    for (lap, window) in windows.iter().enumerate() {
        held += window.clone().map(&points).sum::<usize>();
        if held >= budget {
            groups.push(start..lap as u32 + 1);
            (start, held) = (lap as u32 + 1, 0);
        }
    }
    if (start as usize) < windows.len() {
        groups.push(start..windows.len() as u32);
    }
    groups
}

/// Each of `lib`'s walkers' share (by its key, in id order) over `frames` frames `step` apart,
/// from `memo` or played, with `headings` (`lib`'s); and how many were played. Only the
/// walkers `only` where it says (a group of a long loop's, whose windows alone `lib` holds).
fn sample_loops(
    lib: &Library,
    headings: PackedHeadings,
    (step, frames): (f64, u64),
    memo: &Recalled,
    only: Option<std::ops::Range<u32>>,
) -> (Shares, usize) {
    let (keys, fastest) = window_keys(lib, &headings, (step, frames));
    let ids = only.unwrap_or(0..keys.len() as u32);
    let known: Vec<Option<Played>> = ids
        .clone()
        .map(|w| memo.played(&keys[w as usize]))
        .collect();
    let todo: Vec<u32> = ids
        .clone()
        .filter(|&w| known[(w - ids.start) as usize].is_none())
        .collect();
    let played = if todo.is_empty() {
        Vec::new()
    } else {
        let sampler = Sampler::playing(lib, headings, &todo).expect("every id is a walker");
        // Squared steps against squared jump thresholds: no root (or `hypot`, a sixth of the
        // check once) per character and frame.
        let jump2: Vec<f64> = (todo.iter())
            .map(|&w| (fastest[w as usize] * step + 1e-3).powi(2))
            .collect();
        play_all(&sampler, step, &jump2, frames)
    };
    let mut fresh = todo.iter().zip(played);
    let kept: Shares = (ids.zip(known))
        .map(|(w, known)| {
            let share = known.unwrap_or_else(|| {
                let (&id, p) = fresh.next().expect("a share for every walker played");
                debug_assert_eq!(id, w);
                p
            });
            (keys[w as usize], share)
        })
        .collect();
    (kept, todo.len())
}

/// The library's headings as the sampler keeps them, made a character per thread (serially
/// they were a second of painting's check), a run of characters of about [`RUN_POINTS`]
/// points at a time, each taken in as the run is done: all characters' made at once, and
/// taken into every point's heading in radians, were the library's headings nine times over
/// (the million's: 1.7 GB more). A loop of [`RUN_POINTS`] or more is a run of its own, made
/// packed where it is kept (`take_packed_headings`: a long loop's made a window at a time,
/// on every core): the million's longest, 36 million points, held 0.29 GB of headings in
/// full and two copies of its packed ones beside them.
fn headings(lib: &Library) -> PackedHeadings {
    let mut headings = PackedHeadings::for_points(lib);
    let points = |ch| super::source::loop_points(lib, ch);
    let mut start = 0;
    while start < lib.characters.len() {
        if points(&lib.characters[start]) >= RUN_POINTS {
            let ch = &lib.characters[start];
            crowd_runtime::turn::take_packed_headings(lib, ch, &mut headings);
            start += 1;
            continue;
        }
        let (mut end, mut held) = (start, 0);
        while end < lib.characters.len() && held < RUN_POINTS {
            let more = points(&lib.characters[end]);
            if more >= RUN_POINTS {
                break;
            }
            held += more;
            end += 1;
        }
        let run = &lib.characters[start..end];
        // Each packed as soon as it is made (two bytes a point, not nine).
        let made: Vec<Vec<u16>> = (run.par_iter())
            .map(|ch| {
                let one = crowd_runtime::turn::character_headings(lib, ch);
                PackedHeadings::character(lib, ch, &one)
            })
            .collect();
        for (ch, one) in run.iter().zip(made) {
            headings.take_packed(lib, ch, &one);
        }
        start = end;
    }
    headings
}

/// Points of the characters whose headings [`headings`] makes at once (the first that
/// reaches it ends a run).
const RUN_POINTS: usize = 1 << 23;

/// Every frame `0 ..= frames` (`step` apart) of `sampler`'s walkers, in runs in parallel:
/// each walker's share, with its squared jump threshold from `jump2`.
fn play_all(sampler: &Sampler, step: f64, jump2: &[f64], frames: u64) -> Vec<Played> {
    let threads = rayon::current_num_threads() as u64;
    let per_run = frames.div_ceil(RUNS_PER_THREAD * threads).max(1);
    let runs: Vec<(u64, u64)> = (0..frames.div_ceil(per_run))
        .map(|r| (r * per_run, ((r + 1) * per_run).min(frames)))
        .collect();
    let n = sampler.characters();
    runs.par_iter()
        .map(|&(first, last)| play(sampler.clone(), step, jump2, first..=last))
        .reduce(
            || vec![Played::default(); n],
            |mut a, b| {
                a.iter_mut().zip(&b).for_each(|(a, b)| a.merge(b));
                a
            },
        )
}

/// [`sample`]'s frames `frames` (each compared with the one before it, the first only as
/// that): each character's fastest step, jumps and fastest turn (rad/s). Every character is
/// in view, so character `i` is sample `i` of each frame.
fn play(
    mut sampler: Sampler,
    step: f64,
    jump2: &[f64],
    frames: std::ops::RangeInclusive<u64>,
) -> Vec<Played> {
    let (mut before, mut now): (Vec<Sample>, Vec<Sample>) = (Vec::new(), Vec::new());
    let mut played = vec![Played::default(); sampler.characters()];
    sampler.sample(*frames.start() as f64 * step, EVERYWHERE, &mut before);
    for f in frames.skip(1) {
        sampler.sample(f as f64 * step, EVERYWHERE, &mut now);
        let pairs = before.iter().zip(&now).zip(played.iter_mut());
        for (((a, b), p), &jump2) in pairs.zip(jump2) {
            if a.id != b.id {
                p.max_step2 = f64::INFINITY; // a character missing from a frame
                p.jumps += 1;
                continue;
            }
            let (dx, dy) = (f64::from(b.x - a.x), f64::from(b.y - a.y));
            let d2 = dx * dx + dy * dy;
            p.max_step2 = p.max_step2.max(d2);
            p.jumps += u64::from(d2 > jump2);
            p.max_turn = p.max_turn.max(turn_between(a.heading, b.heading) / step);
        }
        if before.len() != now.len() {
            // A character missing from a frame: charged to the last, whose place it took.
            let last = played.last_mut().expect("a character per sample");
            last.max_step2 = f64::INFINITY;
            last.jumps += before.len().abs_diff(now.len()) as u64;
        }
        std::mem::swap(&mut before, &mut now);
    }
    played
}

/// The smaller angle between two headings (radians), whichever way round.
fn turn_between(from: f32, to: f32) -> f64 {
    use std::f64::consts::TAU;
    let mut turn = f64::from(to - from);
    if turn < 0.0 {
        turn += TAU;
    }
    if !(0.0..TAU).contains(&turn) {
        turn = turn.rem_euclid(TAU); // headings outside one turn
    }
    turn.min(TAU - turn)
}

/// Per walker, in id order, the hash of all the sampler reads to play it over frames
/// `0 ..= frames`, `step` seconds apart: the trajectories of its window (a period of its loop
/// from where it is at time 0, and the one after), each by [`trajectory_keys`], where the
/// window begins against time 0, and the library's period, turn rate and patch side and the
/// frames; and the fastest piece of its window, m/s.
fn window_keys(
    lib: &Library,
    headings: &PackedHeadings,
    (step, frames): (f64, u64),
) -> (Vec<[u8; 32]>, Vec<f64>) {
    let trajectories = trajectory_keys(lib, headings);
    let mut global = Vec::new();
    global.extend_from_slice(b"crowd-check sampled walker");
    global.extend_from_slice(&crate::VERSION.to_le_bytes());
    for bits in [step.to_bits(), frames] {
        global.extend_from_slice(&bits.to_le_bytes());
    }
    global.extend_from_slice(&lib.world.period_ticks.to_le_bytes());
    global.extend_from_slice(&lib.world.turn_rate_deg_s.to_bits().to_le_bytes());
    global.extend_from_slice(&lib.world.patch_side_m.to_bits().to_le_bytes());
    let span = window_span(step, frames);
    let per_character: Vec<Vec<([u8; 32], f64)>> = (lib.characters.par_iter())
        .map(|ch| {
            let order = loop_order(lib, ch);
            (0..ch.laps)
                .map(|lap| {
                    let window = lap_window(lib, ch, lap, &order, span);
                    window_key(&order, window, &trajectories, &global)
                })
                .collect()
        })
        .collect();
    per_character.into_iter().flatten().unzip()
}

/// The ticks a walker's window spans: to the last frame's tick, past which no walker is placed.
fn window_span(step: f64, frames: u64) -> u64 {
    (frames as f64 * step / TICK_S).ceil() as u64 + 1
}

/// A loop's trajectories in walking order, each with the tick it starts at from the loop's
/// start (as the sampler's `Loops` keeps them).
fn loop_order(lib: &Library, ch: &crowd_runtime::Character) -> Vec<(u32, u64)> {
    loop_order_with(lib, ch, |i| {
        lib.duration_ticks(&lib.trajectories[i as usize])
    })
}

/// [`loop_order`] with each trajectory's duration (its last tick) from `last`: the records
/// alone name the loop.
fn loop_order_with(
    lib: &Library,
    ch: &crowd_runtime::Character,
    last: impl Fn(u32) -> u32,
) -> Vec<(u32, u64)> {
    let (mut at, mut tick) = (ch.first_trajectory, 0u64);
    (0..ch.trajectories)
        .map(|_| {
            let this = (at, tick);
            tick += u64::from(last(at));
            at = lib.trajectories[at as usize].next;
            this
        })
        .collect()
}

/// Lap `lap` of loop `ch`'s window: how far into its loop the walker is at tick 0 (where the
/// sampler's search puts it), and the positions in `order` of the trajectories it is on from
/// then until a `span` of ticks has passed, and one more (a position past the loop's last is
/// a pass round it later).
fn lap_window(
    lib: &Library,
    ch: &crowd_runtime::Character,
    lap: u32,
    order: &[(u32, u64)],
    span: u64,
) -> (u64, std::ops::Range<usize>) {
    let period = u64::from(lib.world.period_ticks);
    let length = (u64::from(ch.laps) * period).max(1);
    let start =
        u64::from(lib.trajectories[ch.first_trajectory as usize].start) + u64::from(lap) * period;
    let into = (length - start % length) % length;
    if order.is_empty() {
        return (into, 0..0);
    }
    let first = order.partition_point(|&(_, s)| s <= into).max(1) - 1;
    let end = into + span;
    // Every pass round the loop starts `length` later (so this ends, whatever the loop).
    let past = (first..)
        .find(|&k| (k / order.len()) as u64 * length + order[k % order.len()].1 > end)
        .expect("a pass round the loop starts past any tick");
    (into, first..past + 1)
}

/// A lap's window key and fastest piece (see [`window_keys`]), from its window in `order`
/// ([`lap_window`]): where the sampler's search puts it at tick 0, then the keys of the
/// trajectories of its window.
fn window_key(
    order: &[(u32, u64)],
    (into, window): (u64, std::ops::Range<usize>),
    trajectories: &[([u8; 32], f64)],
    global: &[u8],
) -> ([u8; 32], f64) {
    if order.is_empty() {
        return (*Hash::of(global).as_bytes(), 0.0);
    }
    let mut bytes = global.to_vec();
    bytes.extend_from_slice(&(into - order[window.start].1).to_le_bytes());
    let mut fastest = 0.0f64;
    for k in window {
        let (key, speed) = &trajectories[order[k % order.len()].0 as usize];
        bytes.extend_from_slice(key);
        fastest = fastest.max(*speed);
    }
    (*Hash::of(&bytes).as_bytes(), fastest)
}

/// Per trajectory, the hash of what the sampler reads of it: its patch's place in the grid,
/// its points and the headings there ([`crowd_runtime::packed_heading`]); and its fastest
/// piece (m/s; a piece of no time is a jump, not a speed).
fn trajectory_keys(lib: &Library, headings: &PackedHeadings) -> Vec<([u8; 32], f64)> {
    // Metres per position step per tick, to turn the fastest piece in steps a tick into m/s.
    let step_m_s = f64::from(lib.world.patch_side_m) / crowd_runtime::QUANT_STEPS / TICK_S;
    (lib.trajectories.par_iter())
        .map_init(Vec::new, |bytes, tr| {
            let patch = &lib.patches[tr.patch as usize];
            bytes.clear();
            bytes.extend_from_slice(&patch.col.to_le_bytes());
            bytes.extend_from_slice(&patch.row.to_le_bytes());
            let first = tr.first_point as usize;
            let points = lib.points_of(tr);
            // The fastest piece's squared steps a tick (whole steps: their squares add up
            // exactly, and one root is taken at the end).
            let mut fastest2 = 0.0f64;
            for (i, p) in points.iter().enumerate() {
                let at = first + i;
                let packed = headings.packed[at];
                bytes.extend_from_slice(&p.x.to_le_bytes());
                bytes.extend_from_slice(&p.y.to_le_bytes());
                bytes.extend_from_slice(&p.t.to_le_bytes());
                bytes.extend_from_slice(&packed.to_le_bytes());
                if let Some(a) = i.checked_sub(1).map(|k| points[k])
                    && p.t > a.t
                {
                    let dx = f64::from(i32::from(p.x) - i32::from(a.x));
                    let dy = f64::from(i32::from(p.y) - i32::from(a.y));
                    let dt = f64::from(p.t - a.t);
                    fastest2 = fastest2.max((dx * dx + dy * dy) / (dt * dt));
                }
            }
            (*Hash::of(bytes).as_bytes(), fastest2.sqrt() * step_m_s)
        })
        .collect()
}
