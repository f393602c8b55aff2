//! `crowd check`: the tiled world as an engine plays it, checked without sampling gaps.
//!
//! Every trajectory of every patch is put into world coordinates; every pair of walkers (and
//! every walker with every stander and obstacle) that come near each other in space is checked
//! with the analytic closest approach of their segments, over every copy a whole number of
//! periods apart (all measured by `crowd_geometry`; the core is `world.rs`). A spatial grid
//! keeps this near linear in the number of segments. Pairs in different patches are checked
//! exactly like pairs in one patch, so collisions across borders are found too.
//!
//! [`check`] judges a stage file's trajectories; [`library::figures`] and [`glb::figures`]
//! judge what ships, read as an engine reads it (`products.rs` holds their figures).

pub mod glb;
pub mod library;
pub mod memo;
pub mod motion;
mod part;
pub mod products;
mod strips;
mod world;

use crowd_core::patterns::Crossings;
use crowd_core::trajectories::PatchMotion;
use crowd_core::{Hash, PatchGraph};
use crowd_geometry::BoxGrid;
use glam::DVec2;
use memo::{Own, Recalled};
pub use part::check_part;
pub use products::{ProductFigures, Sampled};
use rayon::prelude::*;
use std::borrow::Cow;
use world::{Ends, Repeat, Scene};

/// What the check found.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CheckReport {
    /// Pairs of characters that come closer than the sum of their radii at some time (walker
    /// pairs, walker-stander pairs), and walkers closer than their radius to an obstacle.
    pub collisions: u64,
    /// Of those, pairs whose two characters are in different patches when closest.
    pub across_borders: u64,
    /// Smallest distance minus the clearance needed, over everything checked.
    pub min_clearance_m: f64,
    /// Where and when the worst one happens (world metres, seconds in the period).
    pub worst_at: Option<(f64, f64, f64)>,
    pub walkers: u64,
    pub segments: u64,
    /// The stage whose trajectories were checked (`match`, `collide`, `smooth`).
    #[serde(default)]
    pub stage: String,
    /// Exactness, continuity and motion quality (when the patterns were at hand).
    #[serde(default)]
    pub motion: Option<motion::MotionFigures>,
    /// The same guarantees on what ships, read as an engine reads it: `library.crowd` through
    /// `crowd-runtime`, and `world.glb` through the `gltf` crate.
    #[serde(default)]
    pub library: Option<ProductFigures>,
    #[serde(default)]
    pub gltf: Option<ProductFigures>,
    /// The hash of everything the check read and of its settings (`crowd build` skips a check
    /// whose inputs are unchanged).
    #[serde(default)]
    pub input_hash: Option<crowd_core::Hash>,
}

/// The check's version: part of its input hash, bumped when what `check.ron` holds changes.
pub const VERSION: u32 = 11;

/// Checks the whole world of `motion` (per patch, in patch order) laid out by `graph`.
pub fn check(graph: &PatchGraph, motion: &[PatchMotion], period_s: f64) -> CheckReport {
    check_world(graph, &motion, period_s, None).expect("motion in memory is always at hand")
}

/// A world's motion, patch by patch, as the check asks for it: a strip at a time.
pub trait Source: Sync {
    /// Patch `p`'s motion (an error when it cannot be read: a damaged file).
    fn patch(&self, p: usize) -> crowd_core::Result<Cow<'_, PatchMotion>>;
}

impl Source for &[PatchMotion] {
    fn patch(&self, p: usize) -> crowd_core::Result<Cow<'_, PatchMotion>> {
        Ok(Cow::Borrowed(&self[p]))
    }
}

impl Source for crowd_core::trajectories::LazyMotion {
    fn patch(&self, p: usize) -> crowd_core::Result<Cow<'_, PatchMotion>> {
        crowd_core::trajectories::LazyMotion::patch(self, p).map(Cow::Owned)
    }
}

/// Checks the world of `graph` whose motion `source` gives, one patch for each of the graph's,
/// and with `crossings`, its motion figures as well. The world is taken a strip at a time
/// (`strips.rs`): every patch is read once for where its characters go, then each strip's with
/// the patches within reach of it; the figures are the same bytes as one scene of the whole
/// world would give.
pub fn check_world(
    graph: &PatchGraph,
    source: &dyn Source,
    period_s: f64,
    crossings: Option<Crossings<'_>>,
) -> crowd_core::Result<CheckReport> {
    let world = World {
        graph,
        source,
        period_s,
        crossings,
    };
    let none = None::<&mut memo::StageWriter<std::io::Sink>>;
    let judged = judge(
        &world,
        None,
        &Recalled::default(),
        strips::STRIP_PIECES,
        none,
    )?;
    Ok(judged.report)
}

/// What a check of a stage file is given.
pub struct World<'a> {
    pub graph: &'a PatchGraph,
    pub source: &'a dyn Source,
    pub period_s: f64,
    /// The patterns' crossings: with them, the motion figures as well.
    pub crossings: Option<Crossings<'a>>,
}

/// A stage file's check, and what of it a later check may take.
pub struct Judged {
    pub report: CheckReport,
    /// The pairs each patch owns, by key (none without the stage's keys): the end of the
    /// memo's stage part, whose own shares the check wrote as it took them.
    pub pairs: memo::OwnedPairs,
    /// Patches whose own share, and whose pairs, were judged again (not taken from the memo).
    pub redone: (usize, usize),
}

/// [`check_world`], taking from `memo` every patch whose share is unchanged ([`shares`], then
/// [`pairs`]), with strips of about `budget` pieces.
fn judge<W: std::io::Write>(
    w: &World,
    keys: Option<&[Hash]>,
    memo: &Recalled,
    budget: u64,
    out: Option<&mut memo::StageWriter<W>>,
) -> crowd_core::Result<Judged> {
    let shares = shares(w, keys, memo, out)?;
    pairs_in(w, shares, memo, budget)
}

/// A stage file's own shares, taken ([`shares`]): all that its pairs are then judged with
/// ([`pairs`]), the crossings let go.
pub struct Shares {
    own: OwnTaken,
    own_keys: Option<Vec<Hash>>,
    motion: Option<motion::MotionFigures>,
}

/// A check of a stage file that takes from `memo` every patch whose share is unchanged, its
/// first half: with `keys` (the stage's patch keys, which pin each patch's motion and
/// crossings), a patch's own share is found by its key; each is written to `out` as it is
/// taken (a memo begun for every patch of the graph with `keys`, for none without), and the
/// motion figures are made. The world's crossings are read no more after it (the million's:
/// 92 MB, which the strips' pairs need not hold).
pub fn shares<W: std::io::Write>(
    w: &World,
    keys: Option<&[Hash]>,
    memo: &Recalled,
    mut out: Option<&mut memo::StageWriter<W>>,
) -> crowd_core::Result<Shares> {
    let graph = w.graph;
    let n = graph.patches.len();
    let tables = w
        .crossings
        .map(|c| crowd_core::patch_keys::Seen::new(graph, c).tables);
    let own_keys = keys.map(|k| own_keys(w, k));
    if let Some(out) = &out {
        let shares = if own_keys.is_some() { n } else { 0 };
        assert_eq!(
            out.own_left(),
            shares,
            "a memo begun for every patch's own share"
        );
    }
    // The motion figures are added up as each patch's share is taken, in patch order.
    let mut measure = w.crossings.map(|c| motion::Measure::new(c.numbers()));
    let own = own_shares(w, tables.as_deref(), own_keys.as_deref(), memo, |p, o| {
        if let (Some(m), Some(t), Some(tally)) = (&mut measure, &tables, &o.tally) {
            let tally = tally
                .unpack()
                .expect("a tally packed here or checked in its memo");
            m.add(p, &tally, &t[p]);
        }
        if let (Some(out), Some(k)) = (out.as_deref_mut(), &own_keys) {
            out.own(k[p].as_bytes(), o);
        }
    })?;
    Ok(Shares {
        own,
        own_keys,
        motion: measure.map(motion::Measure::finish),
    })
}

/// The second half of [`shares`]' check: the pairs each patch owns, found by its key and
/// those of the patches within reach or judged a strip at a time, and the report, the same
/// bytes as a check of the whole world ([`check_world`]). `w`'s crossings are not read (they
/// may be `None`).
pub fn pairs(w: &World, shares: Shares, memo: &Recalled) -> crowd_core::Result<Judged> {
    pairs_in(w, shares, memo, strips::STRIP_PIECES)
}

/// [`pairs`] with strips of about `budget` pieces.
fn pairs_in(w: &World, s: Shares, memo: &Recalled, budget: u64) -> crowd_core::Result<Judged> {
    let graph = w.graph;
    let n = graph.patches.len();
    let Shares {
        own,
        own_keys,
        motion,
    } = s;
    let extents = &own.extents[..];
    let walls = walls(graph);
    let reach = 2.0 * graph.radius_m + 1.0 + 1e-6;
    let near = strips::within_reach(extents, reach, graph.world.patch_side_m);
    let pair_keys = own_keys
        .as_ref()
        .map(|k| pair_keys(graph, k, (extents, &near), (&walls, reach)));
    let known: Vec<Option<world::Pairs>> = match &pair_keys {
        Some(k) => k.iter().map(|k| memo.pairs(k)).collect(),
        None => vec![None; n],
    };
    let (pairs, judged_pairs) = owned_pairs(w, (extents, &near), &walls, known, budget)?;
    let total = pairs
        .iter()
        .fold(world::Pairs::default(), |a, b| a.merge(*b));
    let c = total.clearance(graph.radius_m, w.period_s);
    let report = CheckReport {
        collisions: c.collisions,
        across_borders: c.across_borders,
        min_clearance_m: c.min_clearance_m,
        worst_at: c.worst_at,
        walkers: own.walkers,
        segments: extents.iter().map(|e| e.pieces).sum(),
        stage: String::new(),
        motion,
        library: None,
        gltf: None,
        input_hash: None,
    };
    let pairs = match pair_keys {
        Some(pk) => memo::OwnedPairs(
            (pk.iter().zip(pairs))
                .map(|(k, p)| (*k.as_bytes(), p))
                .collect(),
        ),
        None => memo::OwnedPairs::default(),
    };
    Ok(Judged {
        report,
        pairs,
        redone: (own.measured, judged_pairs),
    })
}

/// What a check keeps of the patches' own shares once each is handed on: where each patch's
/// characters go, how many walk, and how many shares were measured (not taken from the memo).
struct OwnTaken {
    extents: Vec<strips::Extent>,
    walkers: u64,
    measured: usize,
}

/// Patches whose own shares are taken at once (in parallel), then handed on in patch order:
/// the world's were held until its pairs were judged (the million's: 0.2 GB).
const OWN_RUN: usize = 4096;

/// Every patch's own share, from `memo` by its key or measured, handed to `each` in patch
/// order a run of patches at a time.
fn own_shares(
    w: &World,
    tables: Option<&[crowd_core::patch_keys::Table]>,
    own_keys: Option<&[Hash]>,
    memo: &Recalled,
    mut each: impl FnMut(usize, &Own),
) -> crowd_core::Result<OwnTaken> {
    let n = w.graph.patches.len();
    let mut taken = OwnTaken {
        extents: Vec::with_capacity(n),
        walkers: 0,
        measured: 0,
    };
    for start in (0..n).step_by(OWN_RUN) {
        let run = start..(start + OWN_RUN).min(n);
        let shares = in_order(run.clone().into_par_iter().map(|p| {
            if let Some(o) = own_keys.and_then(|k| memo.take_own(&k[p])) {
                return Ok((o, false));
            }
            Ok((own_share(w, tables, p)?, true))
        }))?;
        for (p, (o, measured)) in run.zip(shares) {
            taken.extents.push(o.extent);
            taken.walkers += o.walkers;
            taken.measured += usize::from(measured);
            each(p, &o);
        }
    }
    Ok(taken)
}

/// Patch `p`'s own share, measured: where its characters go, how many walk, and (with the
/// crossings) its motion tally.
fn own_share(
    w: &World,
    tables: Option<&[crowd_core::patch_keys::Table]>,
    p: usize,
) -> crowd_core::Result<Own> {
    let graph = w.graph;
    let m = w.source.patch(p)?;
    let tally = (w.crossings.zip(tables))
        .map(|(c, t)| motion::patch_tally((graph, c, w.period_s), p, &m, &t[p]).pack());
    Ok(Own {
        extent: strips::Extent::of(graph, p, &m),
        walkers: m.trajectories.len() as u64,
        tally,
    })
}

/// Each patch's pairs key ([`memo::pairs_key`]).
fn pair_keys(
    graph: &PatchGraph,
    own_keys: &[Hash],
    (extents, near): (&[strips::Extent], &[Vec<u32>]),
    (walls, reach): (&[Wall], f64),
) -> Vec<Hash> {
    let grid = BoxGrid::new(walls.iter().copied(), 4.0, reach);
    (0..graph.patches.len())
        .into_par_iter()
        .map(|p| {
            let wall = (walls, &grid, reach);
            memo::pairs_key("check pairs", (own_keys, p), &near[p], &extents[p], wall)
        })
        .collect()
}

/// The pairs each patch owns: those `known` (from the memo), and the rest judged a strip at a
/// time; with how many patches were judged.
fn owned_pairs(
    w: &World,
    (extents, near): (&[strips::Extent], &[Vec<u32>]),
    walls: &[Wall],
    known: Vec<Option<world::Pairs>>,
    budget: u64,
) -> crowd_core::Result<(Vec<world::Pairs>, usize)> {
    strips::judge_pairs(known, (extents, near, budget), |strip, held| {
        let motion = in_order(held.par_iter().map(|&p| w.source.patch(p)))?;
        Ok(strip_scene(
            w.graph,
            held,
            &motion,
            strip,
            (w.period_s, walls),
        ))
    })
}

/// Each patch's own key: its stage key, where it lies, and what the check measures it with.
fn own_keys(w: &World, keys: &[Hash]) -> Vec<Hash> {
    let graph = w.graph;
    let setting = memo::bytes_of(&[
        w.period_s.to_bits(),
        graph.radius_m.to_bits(),
        graph.world.patch_side_m.to_bits(),
        u64::from(w.crossings.is_some()),
    ]);
    (0..graph.patches.len())
        .into_par_iter()
        .map(|p| {
            let cell = graph.patches[p].cell;
            let mut h = crowd_core::Hasher::new("check own", VERSION);
            h.part("stage key", keys[p].as_bytes())
                .part("cell", &memo::bytes_of(&[cell.col.into(), cell.row.into()]))
                .part("settings", &setting);
            h.finish()
        })
        .collect()
}

/// The results of a parallel iterator in its order, or the first error in that order.
fn in_order<T: Send>(
    results: impl IndexedParallelIterator<Item = crowd_core::Result<T>>,
) -> crowd_core::Result<Vec<T>> {
    let all: Vec<crowd_core::Result<T>> = results.collect();
    all.into_iter().collect()
}

/// The scene of patches `held` (in order, their `motion`), counting the pairs of `strip`'s.
fn strip_scene(
    graph: &PatchGraph,
    held: &[usize],
    motion: &[Cow<'_, PatchMotion>],
    strip: &[usize],
    (period_s, walls): (f64, &[Wall]),
) -> Scene {
    let trajectories = || motion.iter().flat_map(|m| &m.trajectories);
    let pieces = trajectories()
        .map(|t| t.points.len().saturating_sub(1))
        .sum();
    let mut scene = Scene {
        radius: graph.radius_m,
        repeat: Repeat::Periodic(period_s),
        pieces: Vec::with_capacity(pieces),
        ends: Vec::with_capacity(trajectories().count()),
        standers: Vec::new(),
        walls: walls.to_vec(),
        owned: world::Owned::only(strip, graph.patches.len()),
    };
    let mut walker = 0u32;
    for (&p, m) in held.iter().zip(motion) {
        let origin = graph.world_from_patch(graph.patches[p].cell);
        for tr in &m.trajectories {
            let (first, last) = (tr.points[0].t, tr.points[tr.points.len() - 1].t);
            let world = tr.points.iter().map(|p| (origin + p.pos, p.t));
            scene.push_path(walker, p as u32, world);
            scene.ends.push(Ends {
                entry: (tr.entry, first),
                exit: (tr.exit, last),
            });
            walker += 1;
        }
        scene
            .standers
            .extend(m.standers.iter().map(|s| origin + *s));
    }
    scene
}

/// An obstacle box in world metres: its lowest and highest corners.
pub type Wall = (DVec2, DVec2);

/// Every obstacle box of `graph`'s patches, in world metres.
pub fn walls(graph: &PatchGraph) -> Vec<Wall> {
    graph
        .patches
        .iter()
        .flat_map(|p| {
            let origin = graph.world_from_patch(p.cell);
            p.obstacles
                .iter()
                .map(move |o| (origin + o.min, origin + o.max))
        })
        .collect()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crowd_core::trajectories::{ControlPoint, PointKind, Trajectory};
    use crowd_core::{Grid, Hash, MergedMaps};

    /// `cols` x `rows` 8 m patches painted full, asking for `walkers`.
    pub(crate) fn painted_full(cols: u32, rows: u32, walkers: u64) -> PatchGraph {
        let mut maps = MergedMaps::empty(8 * cols, 8 * rows, 1.0);
        maps.walkers = Grid::filled(8 * cols, 8 * rows, 1.0);
        let inputs = crowd_graph::GraphInputs::counted(walkers, 8.0);
        crowd_graph::build_graph(&maps, &inputs, Hash::of(b"t"), &()).unwrap()
    }

    /// Two 8 m patches side by side.
    pub(crate) fn two_patches() -> PatchGraph {
        painted_full(2, 1, 10)
    }

    fn walk(entry: u32, exit: u32, from: (f64, f64, f64), to: (f64, f64, f64)) -> Trajectory {
        let point = |(x, y, t): (f64, f64, f64), kind| ControlPoint {
            pos: DVec2::new(x, y),
            t,
            kind,
        };
        Trajectory {
            entry,
            exit,
            points: vec![point(from, PointKind::Entry), point(to, PointKind::Exit)],
        }
    }

    /// A patch holding one walker.
    fn alone(tr: Trajectory) -> PatchMotion {
        PatchMotion {
            standers: vec![],
            trajectories: vec![tr],
        }
    }

    /// Random walkers and standers in every patch of `graph`, some straying a little past
    /// their patch's sides (a damaged or edited file may hold anything).
    pub(crate) fn random_motion(graph: &PatchGraph, seed: u64) -> Vec<PatchMotion> {
        let mut state = seed | 1;
        let mut next = move |lo: f64, hi: f64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            lo + (hi - lo) * (state >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..graph.patches.len())
            .map(|_| {
                let trajectories = (0..next(0.0, 6.0) as usize)
                    .map(|_| {
                        let mut t = next(-20.0, 20.0);
                        let points = (0..2 + next(0.0, 3.0) as usize)
                            .map(|_| {
                                t += next(0.5, 8.0);
                                ControlPoint {
                                    pos: DVec2::new(next(-1.5, 9.5), next(-1.5, 9.5)),
                                    t,
                                    kind: PointKind::Sample,
                                }
                            })
                            .collect();
                        let (entry, exit) = (next(0.0, 9.0) as u32, next(0.0, 9.0) as u32);
                        Trajectory {
                            entry,
                            exit,
                            points,
                        }
                    })
                    .collect();
                let standers = (0..next(0.0, 1.6) as usize)
                    .map(|_| DVec2::new(next(0.0, 8.0), next(0.0, 8.0)))
                    .collect();
                PatchMotion {
                    standers,
                    trajectories,
                }
            })
            .collect()
    }

    /// A check of a stage file in a test: its report, what it judged again, and the bytes of
    /// the memo it wrote.
    pub(crate) struct TestJudged {
        pub report: CheckReport,
        pub redone: (usize, usize),
        pub memo: Vec<u8>,
    }

    /// `motion` checked by strips of `budget` pieces, with `keys` and `memo`.
    pub(crate) fn judged(
        graph: &PatchGraph,
        motion: &[PatchMotion],
        keys: Option<&[Hash]>,
        memo: &Recalled,
        budget: u64,
    ) -> TestJudged {
        let world = World {
            graph,
            source: &motion,
            period_s: 20.0,
            crossings: Some((&[][..]).into()),
        };
        let shares = keys.map_or(0, <[Hash]>::len);
        let mut out = memo::StageWriter::start(Vec::new(), shares);
        let judged = judge(&world, keys, memo, budget, Some(&mut out)).unwrap();
        let memo = (out.pairs(&judged.pairs).unwrap().finish(None)).unwrap();
        TestJudged {
            report: judged.report,
            redone: judged.redone,
            memo,
        }
    }

    /// Each patch's key: the hash of its motion's bytes.
    pub(crate) fn content_keys(motion: &[PatchMotion]) -> Vec<Hash> {
        motion
            .iter()
            .map(|m| {
                Hash::of(&crowd_core::trajectories::encode_motion(
                    std::slice::from_ref(m),
                ))
            })
            .collect()
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(6))]

        /// Cut into strips, each checked with the patches around it present but not counted,
        /// the world gives the same figures, to the bit, as one scene of all of it.
        #[test]
        fn strips_give_the_figures_of_one_scene(seed in proptest::prelude::any::<u64>()) {
            let graph = painted_full(12, 12, 1440);
            let motion = random_motion(&graph, seed);
            let none = Recalled::default();
            let whole = judged(&graph, &motion, None, &none, u64::MAX).report;
            proptest::prop_assert!(whole.collisions > 0 && whole.across_borders > 0, "{whole:?}");
            for budget in [0, 40, 300] {
                let cut = judged(&graph, &motion, None, &none, budget).report;
                proptest::prop_assert_eq!(&cut, &whole, "strips of {} pieces", budget);
            }
        }

        /// A check that takes every unchanged patch from the memo of the last one (through its
        /// file's bytes) and judges only the rest gives the figures of a whole check, to the
        /// bit, and judges again only what a change reached.
        #[test]
        fn a_memo_gives_the_figures_of_a_whole_check(seed in proptest::prelude::any::<u64>()) {
            let graph = painted_full(12, 12, 1440);
            let before = random_motion(&graph, seed);
            let other = random_motion(&graph, seed ^ 0x9e37_79b9);
            // A stroke: patches 50, 51 and 63 are walked otherwise.
            let mut after = before.clone();
            for p in [50, 51, 63] {
                after[p] = other[p].clone();
            }
            let none = Recalled::default();
            let first = judged(&graph, &before, Some(&content_keys(&before)), &none, 300);
            let memo = memo::Memo::from_bytes(&first.memo).unwrap().recall();
            let again = judged(&graph, &after, Some(&content_keys(&after)), &memo, 300);
            let whole = judged(&graph, &after, None, &none, u64::MAX);
            proptest::prop_assert_eq!(&again.report, &whole.report);
            let changed = [50, 51, 63].iter().filter(|&&p| before[p] != after[p]).count();
            proptest::prop_assert_eq!(again.redone.0, changed);
            proptest::prop_assert!(again.redone.1 >= 3 && again.redone.1 < 40, "{:?}", again.redone);
            // Nothing changed: nothing judged again.
            let memo = memo::Memo::from_bytes(&again.memo).unwrap().recall();
            let same = judged(&graph, &after, Some(&content_keys(&after)), &memo, 0);
            proptest::prop_assert_eq!(&same.report, &whole.report);
            proptest::prop_assert_eq!(same.redone, (0, 0));
        }
    }

    /// A memo cut short or damaged anywhere is no memo, never a panic (nor a damaged figure
    /// read as a judged one).
    #[test]
    fn a_damaged_memo_is_refused_never_a_panic() {
        let graph = painted_full(6, 6, 360);
        let motion = random_motion(&graph, 7);
        let first = judged(
            &graph,
            &motion,
            Some(&content_keys(&motion)),
            &Recalled::default(),
            0,
        );
        let bytes = first.memo;
        assert!(memo::Memo::from_bytes(&bytes).is_some());
        let cuts = (0..bytes.len())
            .step_by(37)
            .chain(bytes.len() - 64..bytes.len());
        for cut in cuts {
            assert!(
                memo::Memo::from_bytes(&bytes[..cut]).is_none(),
                "cut at {cut}"
            );
        }
        for at in (0..bytes.len()).step_by(11) {
            let mut damaged = bytes.clone();
            damaged[at] ^= 0xA5;
            assert!(
                memo::Memo::from_bytes(&damaged).is_none(),
                "byte {at} damaged"
            );
        }
    }

    #[test]
    fn a_character_crossing_a_border_does_not_collide_with_itself() {
        let graph = two_patches();
        // Crossing 1 is the shared border: the walker leaves patch 0 and enters patch 1 at t = 6.
        let motion = vec![
            alone(walk(0, 1, (0.0, 4.0, 0.0), (8.0, 4.0, 6.0))),
            alone(walk(1, 2, (0.0, 4.0, 6.0), (8.0, 4.0, 12.0))),
        ];
        let report = check(&graph, &motion, 20.0);
        assert_eq!(report.collisions, 0, "{report:?}");
    }

    #[test]
    fn two_characters_meeting_at_a_border_are_a_collision_across_it() {
        let graph = two_patches();
        // One walks east along y = 4 and leaves patch 0 at t = 6; another, in patch 1, walks
        // along the border's other side and passes the same spot at t = 6.
        let motion = vec![
            alone(walk(0, 1, (0.0, 4.0, 0.0), (8.0, 4.0, 6.0))),
            alone(walk(5, 6, (0.3, 0.0, 2.0), (0.3, 8.0, 10.0))),
        ];
        let report = check(&graph, &motion, 20.0);
        assert_eq!(
            (report.collisions, report.across_borders),
            (1, 1),
            "{report:?}"
        );
        assert!(report.min_clearance_m < -0.2);
    }

    #[test]
    fn a_walker_through_a_stander_is_one_collision_however_finely_its_path_is_cut() {
        let graph = two_patches();
        let mut tr = walk(0, 1, (0.0, 4.0, 0.0), (8.0, 4.0, 8.0));
        // Ten pieces of 0.8 m; the stander at (4, 4) is within reach of several of them.
        tr.points = (0..=10)
            .map(|i| ControlPoint {
                pos: DVec2::new(0.8 * i as f64, 4.0),
                t: 0.8 * i as f64,
                kind: PointKind::Sample,
            })
            .collect();
        let motion = vec![
            PatchMotion {
                standers: vec![DVec2::new(4.0, 4.0)],
                trajectories: vec![tr],
            },
            PatchMotion::default(),
        ];
        let report = check(&graph, &motion, 20.0);
        assert_eq!(report.collisions, 1, "{report:?}");
        assert!((report.min_clearance_m + 0.6).abs() < 1e-9);
    }
}
