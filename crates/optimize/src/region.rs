//! Stage 3 by region: the world is cut into square blocks of `region_patches` x
//! `region_patches` patches, optimised apart.
//!
//! A border between two regions (a seam) gets its crossings once, from the start rule alone
//! (as many each way as its two patches need, placed with a random stream of the border's own),
//! and every region holds them: they count in its seam patches' measurements, but no cycle,
//! turn or re-timing of either region changes them. So a region's result depends only on its
//! own patches, the patches across its seams and the settings ([`Region::hash`]): a brush
//! stroke re-optimises the regions it touches and no other, a build from scratch gives the
//! same bytes, and regions run in parallel (or on other machines) in any order.

use crate::state::State;
use crowd_core::config::{MatchSettings, OptimizeSettings};
use crowd_core::patch_graph::{Component, Dropped};
use crowd_core::patterns::{Crossing, Measured, Regression};
use crowd_core::{Cell, Hash, Hasher, PatchGraph, PatchId};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeMap;

/// Which region a cell is in: its block of `side` x `side` cells.
pub fn block_of(cell: Cell, side: u32) -> Cell {
    Cell {
        col: cell.col / side,
        row: cell.row / side,
    }
}

/// One region as a problem of its own: its patches and the patches across its seams (ghosts,
/// which carry the seams' crossings and are never optimised), numbered row by row.
pub struct Region {
    pub block: Cell,
    pub graph: PatchGraph,
    /// Per local patch, whether it is the region's own.
    pub own: Vec<bool>,
    /// Per local border, whether it is a seam (its crossings held).
    pub held: Vec<bool>,
    /// Per local patch, its index in the world's graph.
    pub patches: Vec<usize>,
    /// Per local border, its index in the world's graph.
    pub borders: Vec<usize>,
    /// Per local patch, its standing characters (none on ghosts).
    pub standers: Vec<u32>,
    /// Per local border, the held crossings of a seam (in local numbering).
    pub seams: Vec<Vec<Crossing>>,
}

/// Which patches and borders each region holds, before its problem is built.
pub struct Cut {
    pub side: u32,
    /// Per region, row by row of blocks: its own patches (world indices, in order) and the
    /// borders it sees (its own and its seams).
    pub regions: Vec<(Cell, Vec<usize>, Vec<usize>)>,
}

impl Cut {
    /// Regions of `side` patches a side; `None`: the whole world is one.
    pub fn new(graph: &PatchGraph, side: Option<u32>) -> Cut {
        let whole = graph.world.cols.max(graph.world.rows).max(1);
        let side = side.unwrap_or(whole).max(1);
        let mut by_block: BTreeMap<(u32, u32), (Vec<usize>, Vec<usize>)> = BTreeMap::new();
        let key = |c: Cell| {
            let b = block_of(c, side);
            (b.row, b.col)
        };
        for (i, p) in graph.patches.iter().enumerate() {
            by_block.entry(key(p.cell)).or_default().0.push(i);
        }
        for (k, b) in graph.borders.iter().enumerate() {
            let (ka, kb) = (key(graph.patch(b.a).cell), key(graph.patch(b.b).cell));
            if let Some(r) = by_block.get_mut(&ka) {
                r.1.push(k);
            }
            if ka != kb
                && !b.open.is_empty()
                && let Some(r) = by_block.get_mut(&kb)
            {
                r.1.push(k);
            }
        }
        let regions = by_block
            .into_iter()
            .map(|((row, col), (own, borders))| (Cell { col, row }, own, borders))
            .collect();
        Cut { side, regions }
    }

    /// Whether a border joins two regions.
    pub fn is_seam(&self, graph: &PatchGraph, border: usize) -> bool {
        let b = &graph.borders[border];
        block_of(graph.patch(b.a).cell, self.side) != block_of(graph.patch(b.b).cell, self.side)
    }
}

/// Standing characters per patch: the requested stander densities rounded so that each
/// region's own add up to its requested number (rounding the running total, patch by patch in
/// each region), so that a change in one region moves no stander of another.
pub fn stander_counts(graph: &PatchGraph, cut: &Cut) -> Vec<u32> {
    let area = graph.patch_area();
    let mut counts = vec![0; graph.patches.len()];
    for (_, own, _) in &cut.regions {
        let (mut total, mut placed) = (0.0, 0i64);
        for &p in own {
            total += graph.patches[p].stander_density * area;
            let n = total.round() as i64 - placed;
            placed += n;
            counts[p] = n.max(0) as u32;
        }
    }
    counts
}

/// The random stream of a region or seam: the build's seed mixed with where it is, so that it
/// does not depend on how the world around is numbered. The first region's is the seed
/// itself, so a world of one region is optimised as a whole world always was.
pub fn seed_at(seed: u64, cell: Cell, salt: u64) -> u64 {
    let mut h = 0u64;
    for v in [cell.col as u64, cell.row as u64, salt] {
        h = (h ^ v).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        h ^= h >> 31;
    }
    seed ^ h
}

/// What places the seams' crossings.
pub struct SeamRule<'a> {
    pub regression: &'a Regression,
    pub rho_max: f64,
    pub matching: &'a MatchSettings,
    pub period_s: f64,
    pub seed: u64,
}

/// The held crossings of every seam (world numbering; empty for other borders): as many each
/// way as the start gives any border, placed in a two-patch problem with the seam's own random
/// stream.
pub fn seam_crossings(graph: &PatchGraph, cut: &Cut, rule: &SeamRule) -> Vec<Vec<Crossing>> {
    use rayon::prelude::*;
    let mut open = vec![0usize; graph.patches.len()];
    for b in graph.borders.iter().filter(|b| !b.open.is_empty()) {
        open[b.a.0 as usize] += 1;
        open[b.b.0 as usize] += 1;
    }
    let need = |p: usize| {
        crate::pairs_for(
            graph.patches[p].walker_density,
            rule.regression,
            rule.rho_max,
        ) / open[p].max(1) as f64
    };
    (0..graph.borders.len())
        .into_par_iter()
        .map(|k| {
            let b = &graph.borders[k];
            if b.open.is_empty() || !cut.is_seam(graph, k) {
                return Vec::new();
            }
            let (a, c) = (b.a.0 as usize, b.b.0 as usize);
            let pairs = ((need(a) + need(c)) / 2.0).round() as u32;
            let two = sub_graph(graph, &[a, c], &[k], &[true, true]);
            let mut state = State::with_held(
                &two,
                rule.matching,
                rule.period_s,
                vec![0, 0],
                vec![false, false],
                vec![false],
            );
            let axis = b.axis as u64;
            let mut rng =
                ChaCha8Rng::seed_from_u64(seed_at(rule.seed, graph.patches[a].cell, 1 + axis));
            crate::mutate::add_pairs(&mut state, 0, pairs, &mut rng);
            let mut placed = std::mem::take(&mut state.crossings[0]);
            for c in &mut placed {
                c.border = k as u32;
            }
            placed
        })
        .collect()
}

/// A graph of some patches of the world (`patches`, row by row) and `borders` between them,
/// numbered in the order given; patches not `own` keep only their place and obstacles (no
/// density, direction or component of their own), so that nothing optimises them.
fn sub_graph(graph: &PatchGraph, patches: &[usize], borders: &[usize], own: &[bool]) -> PatchGraph {
    let local = |global: PatchId| {
        PatchId(
            patches
                .binary_search(&(global.0 as usize))
                .expect("a patch of the region") as u32,
        )
    };
    let mut components: Vec<u32> = patches
        .iter()
        .zip(own)
        .filter(|(_, o)| **o)
        .map(|(&p, _)| graph.patches[p].component)
        .collect();
    components.sort_unstable();
    components.dedup();
    let ghost_component = components.len() as u32;
    let sub_patches = patches
        .iter()
        .zip(own)
        .enumerate()
        .map(|(i, (&p, &own))| {
            let mut patch = graph.patches[p].clone();
            patch.id = PatchId(i as u32);
            if own {
                patch.component =
                    components.binary_search(&patch.component).expect("listed") as u32;
            } else {
                patch.walker_density = 0.0;
                patch.stander_density = 0.0;
                patch.direction = None;
                patch.component = ghost_component;
            }
            patch
        })
        .collect();
    let sub_borders = borders
        .iter()
        .map(|&k| {
            let b = &graph.borders[k];
            crowd_core::Border {
                a: local(b.a),
                b: local(b.b),
                ..b.clone()
            }
        })
        .collect();
    PatchGraph {
        header: crowd_core::files::Header::new(
            PatchGraph::STAGE,
            PatchGraph::VERSION,
            Hash::of(&[]),
        ),
        world: graph.world.clone(),
        walkers_requested: 0,
        standers_requested: 0,
        radius_m: graph.radius_m,
        dropped: Dropped {
            empty: Vec::new(),
            blocked: Vec::new(),
            uncovered_strip_m: glam::DVec2::ZERO,
        },
        components: (0..=ghost_component)
            .map(|id| Component {
                id,
                patches: 0,
                walkers: 0.0,
                standers: 0.0,
            })
            .collect(),
        patches: sub_patches,
        borders: sub_borders,
    }
}

impl Region {
    /// The problem of one region of `cut`.
    pub fn new(
        graph: &PatchGraph,
        (block, own_patches, borders): &(Cell, Vec<usize>, Vec<usize>),
        standers: &[u32],
        seams: &[Vec<Crossing>],
        side: u32,
    ) -> Region {
        let mut patches: Vec<usize> = own_patches.clone();
        for &k in borders {
            let b = &graph.borders[k];
            patches.extend([b.a.0 as usize, b.b.0 as usize]);
        }
        patches.sort_unstable();
        patches.dedup();
        let own: Vec<bool> = patches
            .iter()
            .map(|&p| block_of(graph.patches[p].cell, side) == *block)
            .collect();
        // Borders in the order of their patches' places, whatever the world's numbering.
        let mut borders = borders.clone();
        let place = |k: &usize| {
            let b = &graph.borders[*k];
            let (a, c) = (graph.patch(b.a).cell, graph.patch(b.b).cell);
            (a.row, a.col, c.row, c.col)
        };
        borders.sort_by_key(place);
        let sub = sub_graph(graph, &patches, &borders, &own);
        let held: Vec<bool> = borders
            .iter()
            .map(|&k| {
                let b = &graph.borders[k];
                block_of(graph.patch(b.a).cell, side) != block_of(graph.patch(b.b).cell, side)
            })
            .collect();
        let seams = borders
            .iter()
            .enumerate()
            .map(|(l, &k)| {
                seams[k]
                    .iter()
                    .map(|c| Crossing {
                        border: l as u32,
                        ..*c
                    })
                    .collect()
            })
            .collect();
        let standers = patches
            .iter()
            .zip(&own)
            .map(|(&p, &o)| if o { standers[p] } else { 0 })
            .collect();
        Region {
            block: *block,
            graph: sub,
            own,
            held,
            patches,
            borders,
            standers,
            seams,
        }
    }

    /// Everything the region's result depends on: its problem and stage 3's settings. Two
    /// builds whose region hashes agree optimise it to the same crossings.
    pub fn hash(&self, inputs: &RegionInputs) -> Hash {
        let mut h = Hasher::new("optimize region", crowd_core::patterns::Patterns::VERSION);
        h.value("block", &self.block)
            .value("world", &self.graph.world)
            .value("radius", &self.graph.radius_m)
            .value("patches", &self.graph.patches)
            .value("borders", &self.graph.borders)
            .value("own", &self.own)
            .value("held", &self.held)
            .value("standers", &self.standers)
            .value("seams", &self.seams)
            .value("inputs", inputs);
        h.finish()
    }
}

/// The settings every region is optimised with.
#[derive(serde::Serialize)]
pub struct RegionInputs<'a> {
    pub settings: &'a OptimizeSettings,
    pub matching: &'a MatchSettings,
    pub period_s: f64,
    pub seed: u64,
    pub regression: &'a Regression,
}

/// The error sums of some patches at one step, which add up over regions into the world's
/// figures.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Sums {
    pub squares: f64,
    pub patches: u64,
    pub direction: f64,
    pub directed: u64,
    pub crossings: u64,
}

impl std::ops::AddAssign for Sums {
    fn add_assign(&mut self, o: Sums) {
        self.squares += o.squares;
        self.patches += o.patches;
        self.direction += o.direction;
        self.directed += o.directed;
        self.crossings += o.crossings;
    }
}

/// One region's result, in the region's numbering.
#[derive(Debug, Clone, PartialEq)]
pub struct Solved {
    pub hash: Hash,
    /// The crossings of its borders that are not seams.
    pub crossings: Vec<Crossing>,
    /// Its own patches' figures, in order.
    pub measured: Vec<Measured>,
    pub log: Vec<Sums>,
    pub iterations: u32,
    pub converged: bool,
}
