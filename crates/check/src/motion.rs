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
    // Floating-point sums depend on their order: each run of CHUNK patches is tallied on one
    // thread, and the tallies are added in patch order, so the figures are the same bytes
    // whatever the thread count (a parallel `reduce` pairs them by how the work was split).
    let tally = motion
        .par_chunks(CHUNK)
        .enumerate()
        .map(|(c, chunk)| {
            let mut t = Tally::new();
            for (p, m) in chunk.iter().enumerate() {
                let patch = (c * CHUNK + p) as u32;
                for (i, tr) in m.trajectories.iter().enumerate() {
                    t.trajectory(tr, (patch, i as u32));
                }
            }
            t
        })
        .collect::<Vec<Tally>>()
        .into_iter()
        .fold(Tally::new(), Tally::add);

    // Every crossing seen from both sides: where each end lies, and the velocity there.
    let side = graph.world.patch_side_m;
    // Per crossing: trajectories that enter (leave) by it, and the velocity there.
    let mut entered = vec![(0u32, DVec2::ZERO); crossings.len()];
    let mut left = vec![(0u32, DVec2::ZERO); crossings.len()];
    let (mut pos_err, mut time_err) = (0.0f64, 0.0f64);
    for (p, m) in motion.iter().enumerate() {
        for tr in &m.trajectories {
            let pts = &tr.points;
            let ends = [
                (tr.entry, pts[0], pts[1], true),
                (tr.exit, pts[pts.len() - 1], pts[pts.len() - 2], false),
            ];
            for (c, end, next, entry) in ends {
                let Some(crossing) = crossings.get(c as usize) else {
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
                    pos_err = f64::INFINITY;
                    continue;
                }
                pos_err = pos_err.max(end.pos.distance(here.pos));
                let dt = (end.t - crossing.t).rem_euclid(period_s);
                time_err = time_err.max(dt.min(period_s - dt));
                let (a, b) = if entry { (end, next) } else { (next, end) };
                let v = Segment {
                    p0: a.pos,
                    t0: a.t,
                    p1: b.pos,
                    t1: b.t,
                }
                .velocity();
                let slot = if entry { &mut entered } else { &mut left };
                slot[c as usize].0 += 1;
                slot[c as usize].1 = v;
            }
        }
    }
    let mut unmatched = 0;
    let mut jump = 0.0f64;
    // A border is a vertex of the character's world path like any other: its turn and change
    // of speed count in the percentiles too, as the frame that straddles it.
    let mut tally = tally;
    for (e, l) in entered.iter().zip(&left) {
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
        max_boundary_error_m: pos_err,
        max_boundary_time_error_s: time_err,
        unmatched_crossings: unmatched,
        max_speed_m_s: tally.fastest.0,
        max_speed_at: tally.fastest.1,
    }
}
