//! `library.crowd` read as an engine reads it, through `crowd-runtime`: every trajectory
//! rebuilt as the engine plays it (its quantised points in world metres, its ticks from its
//! start), then the figures of [`ProductFigures`]: collisions by the same exact closest
//! approach as the stage files' check (every copy a period apart, across borders, against
//! standers and the build's obstacles), speeds and key jumps, every trajectory's handover to
//! its `next` (a border) and every loop's end to its start (the seam), and the runtime's own
//! `Sampler` played frame after frame.

mod sampled;
mod source;

pub(crate) use sampled::Played;
pub use sampled::sample;
pub use source::{FILE_BUDGET, Held, InFile, Source};

use crate::memo::{self, Recalled};
use crate::products::{OPEN_GAP_M, ProductFigures, Seams, Tally, shown, velocity};
use crate::strips::{self, Extent};
use crate::world::{Clearance, Ends, Pairs, Repeat, Scene};
use crowd_core::Hash;
use crowd_geometry::BoxGrid;
use crowd_runtime::{Library, LoadError, Point, TICK_S};
use glam::DVec2;
use rayon::prelude::*;
use std::borrow::Cow;

/// What the library check needs besides the library.
#[derive(Debug, Clone)]
pub struct Inputs<'a> {
    /// Obstacle boxes in world metres (the build's graph; the library holds none).
    pub walls: &'a [crate::Wall],
    /// `match.max_speed` x 1.05 (`products::SPEED_MARGIN`), m/s.
    pub speed_limit_m_s: f64,
    /// Play the runtime's sampler every this many seconds over one period (None: do not).
    pub sample_step_s: Option<f64>,
}

/// Trajectory `i`'s points as the engine plays them: world metres, seconds from the period's
/// start (the trajectory's `start` plus the point's ticks). Made when asked, never all at
/// once (a million walkers' were 2.3 GB).
pub fn path(lib: &Library, i: usize) -> Vec<(DVec2, f64)> {
    path_of(lib, i, lib.points_of(&lib.trajectories[i]))
}

/// [`path`] of trajectory `i`, whose points are `points`.
fn path_of(lib: &Library, i: usize, points: &[Point]) -> Vec<(DVec2, f64)> {
    (0..points.len())
        .map(|k| point(lib, i, points, k))
        .collect()
}

/// Point `k` of trajectory `i` (whose points are `points`), as [`path`] makes it.
fn point(lib: &Library, i: usize, points: &[Point], k: usize) -> (DVec2, f64) {
    let t = &lib.trajectories[i];
    let p = points[k];
    let [x, y] = lib.world_position(&lib.patches[t.patch as usize], p);
    let ticks = u64::from(t.start) + u64::from(p.t);
    (DVec2::new(x, y), ticks as f64 * TICK_S)
}

/// Libraries of fewer points than this have their pairs judged and their walkers played at
/// once (painting's has 9.3 million; the million's 96.5 million, one after the other), when
/// they are held whole: one judged from its file a part at a time is judged so to hold less,
/// and its two parts at once held two parts' worth (the quarter's gathered check, 24 million
/// points: 1.03 GB).
const POINTS_PLAYED_BESIDE_PAIRS: usize = 32 << 20;

/// The figures of `lib`.
pub fn figures(lib: &Library, inputs: &Inputs) -> ProductFigures {
    figures_memo(lib, inputs, &Recalled::default()).figures
}

/// The library's figures, and what of them a later check may take.
pub struct Judged {
    pub figures: ProductFigures,
    pub memo: memo::LibraryPart,
    /// Patches whose pairs were judged again (not taken from the memo).
    pub redone: usize,
    /// Walkers the sampler played again (not taken from the memo).
    pub replayed: usize,
}

/// [`figures`], taking from `memo` the pairs of every patch whose key is unchanged: the hash
/// of the library's bytes of it and of the patches within reach (their crossings named by
/// order of appearance, not by number: a change elsewhere renumbers them), and of the
/// obstacles there. The figures are the same bytes as a check of the whole library.
pub fn figures_memo(lib: &Library, inputs: &Inputs, memo: &Recalled) -> Judged {
    judge(lib, inputs, memo).expect("a library in memory is at hand")
}

/// [`figures_memo`] of a library wherever its points are ([`Source`]): one left in its file
/// ([`InFile`]) is judged a part of its points at a time (runs of trajectories, of patches
/// and of loops of about its budget), to the same bytes; refused if its file cannot be read
/// or changed since it was opened.
pub fn judge<S: Source>(src: &S, inputs: &Inputs, memo: &Recalled) -> Result<Judged, LoadError> {
    let lib = src.lib();
    let tally = tally(src, inputs.speed_limit_m_s)?;
    let extents = extents(src)?;
    // The world's pairs and the played frames at once: the pairs' serial parts (the pieces,
    // the grid) left a core idle, and the sampler holds little (painting's check -1 s). But
    // one after the other for a large library: the sampler holds every point's packed heading
    // and makes a run of loops' headings at a time (the million's: 0.2 GB, and 0.3 GB more for
    // its longest loop), beside a strip's pairs.
    let pairs = || clearance(src, &extents, inputs.walls, memo);
    let played = || {
        let sampled = (inputs.sample_step_s)
            .map(|step| sampled::sample_memo(src, step, memo))
            .transpose()?;
        Ok::<_, LoadError>((handovers(src)?, sampled))
    };
    let held_whole = src.points() <= src.budget();
    let (pairs, played) = if src.points() < POINTS_PLAYED_BESIDE_PAIRS && held_whole {
        rayon::join(pairs, played)
    } else {
        (pairs(), played())
    };
    let ((clearance, kept, redone), ((borders, seams), sampled)) = (pairs?, played?);
    let (sampled, played, replayed) = match sampled {
        Some(s) => (Some(s.sampled), s.kept, s.replayed),
        None => (None, Vec::new(), 0),
    };
    let counts = (
        lib.walkers(),
        lib.standers.len() as u64,
        extents.iter().map(|e| e.pieces).sum(),
        lib.characters.len() as u64,
    );
    let figures = ProductFigures {
        max_border_velocity_jump: Some(borders.max_jump),
        max_border_gap_m: Some(borders.max_gap),
        max_turn_rate_rad_s: sampled.as_ref().and_then(|s| s.max_turn_rate_rad_s),
        sampled,
        ..ProductFigures::measured(
            "library.crowd",
            counts,
            &clearance,
            &tally,
            &seams,
            inputs.speed_limit_m_s,
        )
    };
    Ok(Judged {
        figures,
        memo: memo::LibraryPart {
            pairs: kept,
            played,
        },
        redone,
        replayed,
    })
}

/// The speeds and walking time of every trajectory, a run of them at a time, added one path
/// after another in the library's order (the same sums whatever the runs).
fn tally<S: Source>(src: &S, limit: f64) -> Result<Tally, LoadError> {
    let lib = src.lib();
    let mut tally = Tally::default();
    for run in source::trajectory_runs(lib, src.budget()) {
        let held = src.window(run.clone())?;
        let path = |k: usize| Cow::Owned(path_of(lib, run.start + k, held.of(run.start + k)));
        tally = tally.then_made(run.len(), path, limit, (TICK_S, false), lib.period_s());
    }
    Ok(tally)
}

/// Each library patch's extent: where its trajectories go and its standers stand, and its
/// pieces. Made a patch at a time, each trajectory's path let go as soon as it is measured:
/// every trajectory's ends and box held at once were 0.6 GB of the million's check.
fn extents<S: Source>(src: &S) -> Result<Vec<Extent>, LoadError> {
    let lib = src.lib();
    let mut extents = Vec::with_capacity(lib.patches.len());
    for run in source::patch_runs(lib, src.budget()) {
        let held = src.window(source::trajectories_of(lib, run.clone()))?;
        extents.par_extend(run.into_par_iter().map(|p| {
            let patch = &lib.patches[p];
            let first = patch.first_trajectory as usize;
            let mut e = Extent::EMPTY;
            for i in first..first + patch.trajectories as usize {
                let path = path_of(lib, i, held.of(i));
                path.iter().for_each(|q| e.grow(q.0));
                e.pieces += path.len().saturating_sub(1) as u64;
            }
            standers(lib, p).for_each(|q| e.grow(q));
            e
        }));
    }
    Ok(extents)
}

/// Where trajectory `i` starts and the velocity of its first piece an engine shows
/// (standing when it has none), or with `last`, where it ends and its last's: what
/// [`crate::products::end_velocities`] finds on its whole path, from the points at that end alone.
fn end_of(lib: &Library, i: usize, points: &[Point], last: bool) -> End {
    let n = points.len();
    let at = |k: usize| point(lib, i, points, if last { n - 1 - k } else { k });
    let end = at(0);
    let mut a = end;
    for k in 1..n {
        let b = at(k);
        let (from, to) = if last { (b, a) } else { (a, b) };
        if shown(from, to) {
            return (end.0, velocity(from, to, TICK_S));
        }
        a = b;
    }
    (end.0, DVec2::ZERO)
}

/// Where a trajectory starts or ends, and the velocity an engine shows there.
type End = (DVec2, DVec2);

/// Each patch's pairs, by their key.
type KeptPairs = Vec<([u8; 32], Pairs)>;

/// Collisions over the whole tiled world: each trajectory a walker with its copies a period
/// apart, continued through its exit crossing by its `next` (the same character). Counted a
/// strip of the library's patches at a time, as the stage files' check is (`strips.rs`), for
/// the patches whose pairs `memo` does not hold; with each patch's pairs by their key, and how
/// many patches were judged again.
fn clearance<S: Source>(
    src: &S,
    extents: &[Extent],
    walls: &[crate::Wall],
    memo: &Recalled,
) -> Result<(Clearance, KeptPairs, usize), LoadError> {
    let lib = src.lib();
    let radius = f64::from(lib.world.radius_m);
    let reach = 2.0 * radius + 1.0 + 1e-6;
    let near = strips::within_reach(extents, reach, f64::from(lib.world.patch_side_m));
    let keys = pair_keys(src, (extents, &near), walls, reach)?;
    let known = keys.iter().map(|k| memo.library_pairs(k)).collect();
    let (pairs, judged) = strips::judge_pairs(
        known,
        (extents, &near, strips::STRIP_PIECES),
        |strip, held| strip_scene(src, held, strip, walls),
    )?;
    let total = pairs.iter().fold(Pairs::default(), |a, b| a.merge(*b));
    let kept = keys.iter().map(|k| *k.as_bytes()).zip(pairs).collect();
    Ok((total.clearance(radius, lib.period_s()), kept, judged))
}

/// The scene of library patches `held` (in order), counting the pairs of `strip`'s.
fn strip_scene<S: Source>(
    src: &S,
    held: &[usize],
    strip: &[usize],
    walls: &[crate::Wall],
) -> Result<Scene, LoadError> {
    let lib = src.lib();
    let mut is_held = vec![false; lib.patches.len()];
    held.iter().for_each(|&p| is_held[p] = true);
    let mut scene = Scene {
        radius: f64::from(lib.world.radius_m),
        repeat: Repeat::Periodic(lib.period_s()),
        pieces: Vec::new(),
        ends: Vec::new(),
        standers: held.iter().flat_map(|&p| standers(lib, p)).collect(),
        walls: walls.to_vec(),
        owned: crate::world::Owned::only(strip, lib.patches.len()),
    };
    // In the library's order of trajectories, as one scene of the world would hold them
    // (a pair's closest place is its lower piece's). Each trajectory lies in its patch's
    // range: the held patches' ranges hold them all.
    let range = source::trajectories_of(lib, held.iter().copied());
    let window = src.window(range.clone())?;
    let held: Vec<(usize, Vec<(DVec2, f64)>)> = range
        .into_par_iter()
        .filter(|&i| is_held[lib.trajectories[i].patch as usize])
        .map(|i| (i, path_of(lib, i, window.of(i))))
        .collect();
    let pieces = held.iter().map(|(_, p)| p.len().saturating_sub(1)).sum();
    scene.pieces.reserve_exact(pieces);
    for (walker, (i, path)) in held.iter().enumerate() {
        let t = &lib.trajectories[*i];
        let (first, last) = (path[0].1, path[path.len() - 1].1);
        scene.push_path(walker as u32, t.patch, path.iter().copied());
        scene.ends.push(Ends {
            entry: (t.entry, first),
            exit: (t.exit, last),
        });
    }
    Ok(scene)
}

/// Each library patch's pairs key: the library's bytes of it and of every patch within
/// `reach` (where, the trajectories' starts and points, the standers), their crossings named
/// by order of first appearance among them, and the obstacles within reach.
fn pair_keys<S: Source>(
    src: &S,
    (extents, near): (&[Extent], &[Vec<u32>]),
    walls: &[crate::Wall],
    reach: f64,
) -> Result<Vec<Hash>, LoadError> {
    let lib = src.lib();
    let n = lib.patches.len();
    let mut by_patch: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (i, t) in lib.trajectories.iter().enumerate() {
        by_patch[t.patch as usize].push(i);
    }
    let mut own: Vec<Hash> = Vec::with_capacity(n);
    for run in source::patch_runs(lib, src.budget()) {
        let held = src.window(source::trajectories_of(lib, run.clone()))?;
        let hash = |p: usize| library_patch_hash(lib, &held, p, &by_patch[p]);
        own.par_extend(run.into_par_iter().map(hash));
    }
    let grid = BoxGrid::new(walls.iter().copied(), 4.0, reach);
    let setting = memo::bytes_of(&[
        u64::from(lib.world.period_ticks),
        u64::from(lib.world.radius_m.to_bits()),
        u64::from(lib.world.patch_side_m.to_bits()),
    ]);
    let keys = (0..n)
        .into_par_iter()
        .map(|p| {
            let mut h = crowd_core::Hasher::new("library pairs", crate::VERSION);
            h.part("settings", &setting);
            h.part(
                "near",
                memo::pairs_key(
                    "library near",
                    (&own, p),
                    &near[p],
                    &extents[p],
                    (walls, &grid, reach),
                )
                .as_bytes(),
            );
            // Crossings by order of first appearance: which trajectory continues which.
            let mut seen: std::collections::HashMap<u32, u32> = std::collections::HashMap::new();
            let mut named = Vec::new();
            for &q in &near[p] {
                for &i in &by_patch[q as usize] {
                    let t = &lib.trajectories[i];
                    for c in [t.entry, t.exit] {
                        let next = seen.len() as u32;
                        named.push(u64::from(*seen.entry(c).or_insert(next)));
                    }
                }
            }
            h.part("crossings", &memo::bytes_of(&named));
            h.finish()
        })
        .collect();
    Ok(keys)
}

/// The library's bytes of patch `p` (trajectories `mine`): where it lies, its trajectories'
/// starts and points, its standers; not its crossings' numbers.
fn library_patch_hash(lib: &Library, held: &Held, p: usize, mine: &[usize]) -> Hash {
    let patch = &lib.patches[p];
    let mut words = vec![u64::from(patch.col), u64::from(patch.row)];
    for &i in mine {
        let t = &lib.trajectories[i];
        words.push(u64::from(t.start));
        words.push(u64::from(t.points));
        for q in held.of(i) {
            words.push(u64::from(q.x) | u64::from(q.y) << 16 | u64::from(q.t) << 32);
        }
    }
    let first = patch.first_stander as usize;
    for s in &lib.standers[first..first + patch.standers as usize] {
        words.push(u64::from(s.x) | u64::from(s.y) << 16);
    }
    Hash::of(&memo::bytes_of(&words))
}

/// Library patch `p`'s standers, world metres.
fn standers(lib: &Library, p: usize) -> impl Iterator<Item = DVec2> + '_ {
    let patch = &lib.patches[p];
    let first = patch.first_stander as usize;
    lib.standers[first..first + patch.standers as usize]
        .iter()
        .map(move |s| {
            let [x, y] = lib.world_position(patch, *s);
            DVec2::new(x, y)
        })
}

/// Every trajectory's handover to its `next`: at a border, or at its loop's seam (the last
/// trajectory of a loop, walked from its `first_trajectory`, to the first). A run of
/// trajectories at a time, each end found from the points there ([`end_of`]); the starts of
/// the `next`s outside a run read besides, runs of consecutive ones at a time.
fn handovers<S: Source>(src: &S) -> Result<(Seams, Seams), LoadError> {
    let lib = src.lib();
    let mut last_of_loop = vec![false; lib.trajectories.len()];
    for c in &lib.characters {
        let mut at = c.first_trajectory as usize;
        for _ in 1..c.trajectories {
            at = lib.trajectories[at].next as usize;
        }
        last_of_loop[at] = true;
    }
    let none = || (Seams::default(), Seams::default());
    let mut total = none();
    for run in source::trajectory_runs(lib, src.budget()) {
        let held = src.window(run.clone())?;
        let starts = starts_outside(src, &held, run.clone())?;
        let start_of = |j: usize| match held.points_of(j) {
            Some(points) => end_of(lib, j, points, false),
            None => starts[starts.binary_search_by_key(&j, |s| s.0).expect("read")].1,
        };
        let (borders, seams) = run
            .into_par_iter()
            .fold(none, |(mut borders, mut seams), i| {
                let next = lib.trajectories[i].next as usize;
                let (end, start) = (end_of(lib, i, held.of(i), true), start_of(next));
                if last_of_loop[i] {
                    seams.note(end, start);
                    seams.open += u64::from(end.0.distance(start.0) > OPEN_GAP_M);
                } else {
                    borders.note(end, start);
                }
                (borders, seams)
            })
            .reduce(none, |a, b| (a.0.merge(b.0), a.1.merge(b.1)));
        total = (total.0.merge(borders), total.1.merge(seams));
    }
    Ok(total)
}

/// The start ([`end_of`]) of every `next` of trajectories `run` whose points `held` does not
/// hold, by trajectory: read a run of consecutive trajectories at a time.
fn starts_outside<S: Source>(
    src: &S,
    held: &Held,
    run: std::ops::Range<usize>,
) -> Result<Vec<(usize, End)>, LoadError> {
    let lib = src.lib();
    let mut outside: Vec<usize> = run
        .map(|i| lib.trajectories[i].next as usize)
        .filter(|&j| held.points_of(j).is_none())
        .collect();
    outside.sort_unstable();
    outside.dedup();
    let mut starts = Vec::with_capacity(outside.len());
    let mut k = 0;
    while k < outside.len() {
        let mut end = k + 1;
        while end < outside.len() && outside[end] == outside[end - 1] + 1 && end - k < 4096 {
            end += 1;
        }
        let window = src.window(outside[k]..outside[end - 1] + 1)?;
        for &j in &outside[k..end] {
            starts.push((j, end_of(lib, j, window.of(j), false)));
        }
        k = end;
    }
    Ok(starts)
}

#[cfg(test)]
mod tests;
