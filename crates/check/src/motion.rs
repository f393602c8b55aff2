//! Exactness, continuity and motion quality of the shipped trajectories (DESIGN.md's figures).
//!
//! Acceleration and turning rate are measured as a player shows the motion: positions sampled
//! every 0.1 s, second differences of consecutive frames (and the change of velocity where a
//! character crosses a border, over one frame). A polyline's corner is then the sharp change it
//! is on screen; weighting its vertices by the time around them instead would spread a corner
//! over seconds and reward coarse paths. Percentiles are over frames, so by time.

use crowd_core::PatchGraph;
use crowd_core::patterns::{Crossing, Way, border_point};
use crowd_core::trajectories::{PatchMotion, Trajectory, position_at};
use crowd_geometry::Segment;
use glam::DVec2;
use rayon::prelude::*;

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
/// Patches tallied together on one thread (a tally holds two histograms of `BINS` bins).
const CHUNK: usize = 64;

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

#[derive(Clone)]
struct Tally {
    walking: f64,
    in_band: f64,
    accel: Vec<f64>,
    turn: Vec<f64>,
    fastest: (f64, Option<(u32, u32, f64)>),
}

impl Tally {
    fn new() -> Tally {
        Tally {
            walking: 0.0,
            in_band: 0.0,
            accel: vec![0.0; BINS],
            turn: vec![0.0; BINS],
            fastest: (0.0, None),
        }
    }

    /// A stand-in while a tally is moved out (no histograms).
    fn empty() -> Tally {
        Tally {
            walking: 0.0,
            in_band: 0.0,
            accel: Vec::new(),
            turn: Vec::new(),
            fastest: (0.0, None),
        }
    }

    fn add(mut self, o: Tally) -> Tally {
        self.walking += o.walking;
        self.in_band += o.in_band;
        for (a, b) in self.accel.iter_mut().zip(&o.accel) {
            *a += b;
        }
        for (a, b) in self.turn.iter_mut().zip(&o.turn) {
            *a += b;
        }
        // The first of equals, in patch order.
        if o.fastest.0 > self.fastest.0 {
            self.fastest = o.fastest;
        }
        self
    }

    /// Tallies trajectory `at.1` of patch `at.0`.
    fn trajectory(&mut self, tr: &Trajectory, at: (u32, u32)) {
        let pts = &tr.points;
        for w in pts.windows(2).filter(|w| w[1].t > w[0].t) {
            let dt = w[1].t - w[0].t;
            let speed = w[1].pos.distance(w[0].pos) / dt;
            if speed > self.fastest.0 {
                self.fastest = (speed, Some((at.0, at.1, w[0].t)));
            }
            if speed > STANDING {
                self.walking += dt;
                if (SPEED_BAND.0..=SPEED_BAND.1).contains(&speed) {
                    self.in_band += dt;
                }
            }
        }
        // Frames every FRAME_S from the entry, as a player samples the path.
        let (t0, t1) = (pts[0].t, pts[pts.len() - 1].t);
        let frames = ((t1 - t0) / FRAME_S).floor() as usize;
        let samples: Vec<DVec2> = (0..=frames)
            .map(|i| position_at(pts, t0 + i as f64 * FRAME_S))
            .collect();
        for w in samples.windows(3) {
            let (v1, v2) = ((w[1] - w[0]) / FRAME_S, (w[2] - w[1]) / FRAME_S);
            self.vertex(v1, v2, FRAME_S);
        }
    }

    /// A change of velocity from `v1` to `v2` over `window` seconds.
    fn vertex(&mut self, v1: DVec2, v2: DVec2, window: f64) {
        let bin = |x: f64| ((x / BIN) as usize).min(BINS - 1);
        self.accel[bin((v2 - v1).length() / window)] += window;
        if v1.length() > STANDING && v2.length() > STANDING {
            let angle = v1.perp_dot(v2).atan2(v1.dot(v2)).abs();
            self.turn[bin(angle / window)] += window;
        }
    }
}

/// The value below which 95 % of the weight lies.
fn p95(hist: &[f64]) -> f64 {
    let total: f64 = hist.iter().sum();
    let mut seen = 0.0;
    for (i, w) in hist.iter().enumerate() {
        seen += w;
        if seen >= 0.95 * total {
            return (i as f64 + 1.0) * BIN;
        }
    }
    0.0
}

/// The motion figures of `motion` (per patch, in patch order) against its crossings.
pub fn figures(
    graph: &PatchGraph,
    crossings: &[Crossing],
    motion: &[PatchMotion],
    period_s: f64,
) -> MotionFigures {
    let mut m = Measure::new(graph, crossings, period_s);
    m.add(0, motion);
    m.finish()
}

/// The motion figures of a world taken a run of patches at a time ([`Measure::add`]), in patch
/// order: what they hold is a tally and a slot per crossing, not the motion.
pub struct Measure<'a> {
    graph: &'a PatchGraph,
    crossings: &'a [Crossing],
    period_s: f64,
    tally: Tally,
    /// Per crossing: trajectories that enter (leave) by it, and the velocity there.
    entered: Vec<(u32, DVec2)>,
    left: Vec<(u32, DVec2)>,
    pos_err: f64,
    time_err: f64,
}

impl<'a> Measure<'a> {
    pub fn new(graph: &'a PatchGraph, crossings: &'a [Crossing], period_s: f64) -> Measure<'a> {
        Measure {
            graph,
            crossings,
            period_s,
            tally: Tally::new(),
            entered: vec![(0u32, DVec2::ZERO); crossings.len()],
            left: vec![(0u32, DVec2::ZERO); crossings.len()],
            pos_err: 0.0,
            time_err: 0.0,
        }
    }

    /// Patches `first..first + motion.len()`, after every patch before `first` was added.
    /// `first` is a multiple of [`STRIP_ALIGN`] (the figures are then the same bytes however
    /// the world was cut).
    pub fn add<M: std::borrow::Borrow<PatchMotion> + Sync>(&mut self, first: usize, motion: &[M]) {
        assert_eq!(first % STRIP_ALIGN, 0, "runs start at whole chunks");
        // Floating-point sums depend on their order: each run of CHUNK patches is tallied on
        // one thread, and the tallies are added in patch order, so the figures are the same
        // bytes whatever the thread count (a parallel `reduce` pairs them by how the work was
        // split).
        let tallies = motion
            .par_chunks(CHUNK)
            .enumerate()
            .map(|(c, chunk)| {
                let mut t = Tally::new();
                for (p, m) in chunk.iter().enumerate() {
                    let (patch, m) = ((first + c * CHUNK + p) as u32, m.borrow());
                    for (i, tr) in m.trajectories.iter().enumerate() {
                        t.trajectory(tr, (patch, i as u32));
                    }
                }
                t
            })
            .collect::<Vec<Tally>>();
        let tally = std::mem::replace(&mut self.tally, Tally::empty());
        self.tally = tallies.into_iter().fold(tally, Tally::add);
        for (p, m) in motion.iter().enumerate() {
            self.ends(first + p, m.borrow());
        }
    }

    /// Every crossing seen from both sides: where each end of patch `p`'s trajectories lies,
    /// and the velocity there.
    fn ends(&mut self, p: usize, m: &PatchMotion) {
        let side = self.graph.world.patch_side_m;
        for tr in &m.trajectories {
            let pts = &tr.points;
            let ends = [
                (tr.entry, pts[0], pts[1], true),
                (tr.exit, pts[pts.len() - 1], pts[pts.len() - 2], false),
            ];
            for (c, end, next, entry) in ends {
                let Some(crossing) = self.crossings.get(c as usize) else {
                    continue;
                };
                let border = &self.graph.borders[crossing.border as usize];
                let (a, b) = border_point(border, side, crossing.s);
                // The crossing goes a -> b when its way is AToB.
                let (from, to) = match crossing.way {
                    Way::AToB => (a, b),
                    Way::BToA => (b, a),
                };
                let here = if entry { to } else { from };
                if here.patch.0 as usize != p {
                    self.pos_err = f64::INFINITY;
                    continue;
                }
                self.pos_err = self.pos_err.max(end.pos.distance(here.pos));
                let dt = (end.t - crossing.t).rem_euclid(self.period_s);
                self.time_err = self.time_err.max(dt.min(self.period_s - dt));
                let (a, b) = if entry { (end, next) } else { (next, end) };
                let v = Segment {
                    p0: a.pos,
                    t0: a.t,
                    p1: b.pos,
                    t1: b.t,
                }
                .velocity();
                let slot = if entry {
                    &mut self.entered
                } else {
                    &mut self.left
                };
                slot[c as usize].0 += 1;
                slot[c as usize].1 = v;
            }
        }
    }

    /// The figures, once every patch was added.
    pub fn finish(self) -> MotionFigures {
        let mut unmatched = 0;
        let mut jump = 0.0f64;
        // A border is a vertex of the character's world path like any other: its turn and
        // change of speed count in the percentiles too, as the frame that straddles it.
        let mut tally = self.tally;
        for (e, l) in self.entered.iter().zip(&self.left) {
            if e.0 != 1 || l.0 != 1 {
                unmatched += 1;
                continue;
            }
            jump = jump.max((e.1 - l.1).length());
            tally.vertex(l.1, e.1, FRAME_S);
        }
        MotionFigures {
            speed_in_band: if tally.walking > 0.0 {
                tally.in_band / tally.walking
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

/// What the start of a run given to [`Measure::add`] is a multiple of.
pub const STRIP_ALIGN: usize = CHUNK;
