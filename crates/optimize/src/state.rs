//! The optimiser's state: crossings per border, and each patch's measured density and
//! direction, kept up to date patch by patch.

use crate::spacing::Spacing;
use crowd_core::PatchGraph;
use crowd_core::config::MatchSettings;
use crowd_core::patterns::{Crossing, Measured, Way};
use crowd_match::{Endpoint, PatchContext};
use glam::DVec2;
use rayon::prelude::*;

/// Names a crossing by its border and its place in the border's list, for the endpoints of a
/// patch (a border holds far fewer than 4096 crossings: spacing allows a few hundred).
pub fn key(border: usize, index: usize) -> u32 {
    debug_assert!(index < 1 << 12);
    ((border as u32) << 12) | index as u32
}

/// The border and index a [`key`] names.
pub fn unkey(key: u32) -> (usize, usize) {
    ((key >> 12) as usize, (key & 0xfff) as usize)
}

/// A way out of a patch: through `border`, towards patch `to`, crossing `way`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Link {
    pub to: usize,
    pub border: usize,
    pub way: Way,
}

pub struct State<'a> {
    pub graph: &'a PatchGraph,
    pub settings: &'a MatchSettings,
    pub period_s: f64,
    pub spacing: Spacing,
    /// Per patch, its neighbours through open borders whose crossings may change.
    pub links: Vec<Vec<Link>>,
    /// Per patch, its ways through held borders (a region's seams): their crossings count in
    /// the patch's measurement, but no cycle, turn or re-timing changes them.
    pub fixed: Vec<Vec<Link>>,
    /// Per border, whether its crossings are held.
    pub held: Vec<bool>,
    /// Per patch, whether it is optimised here (a region's own patches; the patches across its
    /// seams are there only to carry the seams' crossings, and are never measured).
    pub own: Vec<bool>,
    /// Per border, its crossings.
    pub crossings: Vec<Vec<Crossing>>,
    /// Standing characters per patch (fixed: they follow the static density).
    pub standers: Vec<u32>,
    pub measured: Vec<Measured>,
    /// Requested total density per patch (walkers + standers), characters per m2.
    pub requested: Vec<f64>,
    /// Per patch, the pair scores of its last measurement (a lock each, so that patches are
    /// measured in parallel; no two threads measure one patch at once).
    scores: Vec<std::sync::Mutex<crowd_match::ScoreCache>>,
}

impl<'a> State<'a> {
    pub fn new(
        graph: &'a PatchGraph,
        settings: &'a MatchSettings,
        period_s: f64,
        standers: Vec<u32>,
    ) -> State<'a> {
        let n = graph.patches.len();
        let (own, held) = (vec![true; n], vec![false; graph.borders.len()]);
        State::with_held(graph, settings, period_s, standers, own, held)
    }

    /// A state whose `held` borders keep their crossings and whose patches not `own` are never
    /// measured (see [`crate::region`]).
    pub fn with_held(
        graph: &'a PatchGraph,
        settings: &'a MatchSettings,
        period_s: f64,
        standers: Vec<u32>,
        own: Vec<bool>,
        held: Vec<bool>,
    ) -> State<'a> {
        let n = graph.patches.len();
        let mut links = vec![Vec::new(); n];
        let mut fixed = vec![Vec::new(); n];
        for (k, b) in graph.borders.iter().enumerate() {
            if b.open.is_empty() {
                continue;
            }
            let (a, c) = (b.a.0 as usize, b.b.0 as usize);
            let links = if held[k] { &mut fixed } else { &mut links };
            links[a].push(Link {
                to: c,
                border: k,
                way: Way::AToB,
            });
            links[c].push(Link {
                to: a,
                border: k,
                way: Way::BToA,
            });
        }
        let area = graph.patch_area();
        let requested = graph
            .patches
            .iter()
            .zip(&standers)
            .map(|(p, &s)| p.walker_density + s as f64 / area)
            .collect();
        let mut state = State {
            graph,
            settings,
            period_s,
            spacing: Spacing::new(graph),
            links,
            fixed,
            held,
            own,
            crossings: vec![Vec::new(); graph.borders.len()],
            measured: vec![
                Measured {
                    density: 0.0,
                    direction: None,
                    standers: 0
                };
                n
            ],
            standers,
            requested,
            scores: (0..n).map(|_| Default::default()).collect(),
        };
        state.remeasure_all();
        state
    }

    /// A copy for trying changes on another thread: the same crossings and figures, its own
    /// (empty) score caches.
    pub fn fork(&self) -> State<'a> {
        State {
            graph: self.graph,
            settings: self.settings,
            period_s: self.period_s,
            spacing: self.spacing.clone(),
            links: self.links.clone(),
            fixed: self.fixed.clone(),
            held: self.held.clone(),
            own: self.own.clone(),
            crossings: self.crossings.clone(),
            standers: self.standers.clone(),
            measured: self.measured.clone(),
            requested: self.requested.clone(),
            scores: (0..self.scores.len()).map(|_| Default::default()).collect(),
        }
    }

    pub fn context(&self, patch: usize) -> PatchContext<'a> {
        PatchContext::new(self.graph, patch, self.settings, self.period_s)
    }

    /// Entries and exits of a patch, from the crossings of its borders.
    pub fn endpoints(&self, patch: usize) -> (Vec<Endpoint>, Vec<Endpoint>) {
        let ways = || self.links[patch].iter().chain(&self.fixed[patch]);
        let count: usize = ways().map(|l| self.crossings[l.border].len()).sum();
        let (mut entries, mut exits) = (Vec::with_capacity(count), Vec::with_capacity(count));
        let side = self.graph.world.patch_side_m;
        for link in ways() {
            let border = &self.graph.borders[link.border];
            for (i, c) in self.crossings[link.border].iter().enumerate() {
                let (a, b) = crowd_core::patterns::border_point(border, side, c.s);
                let here = if link.way == Way::AToB { a } else { b };
                let e = Endpoint {
                    crossing: key(link.border, i),
                    pos: here.pos,
                    t: c.t,
                    side: here.side,
                    velocity: c.velocity,
                };
                if c.way == link.way {
                    exits.push(e);
                } else {
                    entries.push(e);
                }
            }
        }
        (entries, exits)
    }

    pub fn measure(&self, patch: usize) -> Measured {
        let (entries, exits) = self.endpoints(patch);
        let mut cache = self.scores[patch]
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        crowd_match::measure_patch_cached(
            &entries,
            &exits,
            self.standers[patch],
            &self.context(patch),
            &mut cache,
        )
    }

    /// The exit of each entry of `patch` (as [`State::endpoints`] lists them), by the same
    /// matching as [`State::measure`] and its kept scores.
    pub fn pairs(&self, patch: usize, entries: &[Endpoint], exits: &[Endpoint]) -> Vec<usize> {
        let mut cache = self.scores[patch]
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        crowd_match::match_points_cached(entries, exits, &self.context(patch), &mut cache)
    }

    pub fn remeasure(&mut self, patches: &[usize]) {
        // A cycle's few patches are measured here, in turn: waking the pool costs more.
        const PARALLEL_FROM: usize = 16;
        let fresh: Vec<Measured> = if patches.len() < PARALLEL_FROM {
            patches.iter().map(|&p| self.measure(p)).collect()
        } else {
            patches.par_iter().map(|&p| self.measure(p)).collect()
        };
        for (&p, m) in patches.iter().zip(fresh) {
            self.measured[p] = m;
        }
    }

    /// Measures every patch optimised here.
    pub fn remeasure_all(&mut self) {
        let all = self.own_patches();
        self.remeasure(&all);
    }

    /// The patches optimised here, in order.
    pub fn own_patches(&self) -> Vec<usize> {
        (0..self.own.len()).filter(|&p| self.own[p]).collect()
    }

    /// Open borders of a patch, held or not.
    pub fn open_borders(&self, patch: usize) -> usize {
        self.links[patch].len() + self.fixed[patch].len()
    }

    /// Unit vector across a border in the way of the crossing.
    pub fn normal(&self, border: usize, way: Way) -> DVec2 {
        let n = self.graph.borders[border].across();
        if way == Way::AToB { n } else { -n }
    }

    /// The velocity of a new crossing: across the border at the comfort speed of the two
    /// patches, leaning along the border where their requested directions do.
    pub fn crossing_velocity(&self, border: usize, way: Way) -> DVec2 {
        let b = &self.graph.borders[border];
        let (pa, pb) = (
            &self.graph.patches[b.a.0 as usize],
            &self.graph.patches[b.b.0 as usize],
        );
        let density = (pa.walker_density + pb.walker_density) / 2.0;
        let speed = crowd_match::score::comfort_speed(self.settings.comfort_speed, density);
        let n = self.normal(border, way);
        let tangent = n.perp();
        let lean: f64 = [pa, pb]
            .iter()
            .filter_map(|p| p.direction)
            .map(|d| d.weight.min(1.0) * d.dir.dot(tangent) / 2.0)
            .sum();
        (n + tangent * lean.clamp(-0.6, 0.6)).normalize() * speed
    }

    pub fn crossing_count(&self) -> usize {
        self.crossings.iter().map(Vec::len).sum()
    }
}
