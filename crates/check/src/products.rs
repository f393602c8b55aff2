//! The figures of a shipped file (`library.crowd`, `world.glb`), DESIGN.md's guarantees
//! measured on the keyed paths an engine plays: straight walks at constant velocity from one
//! key to the next. [`Tally`] measures speeds and the velocity jumps at keys path by path;
//! [`Seams`] the handovers from one path to the one that continues it (a library's borders and
//! loop seams, a glTF node's clip end).

use glam::DVec2;
use rayon::prelude::*;
use std::borrow::Cow;

/// Slower than this is standing, m/s (as the stage-file figures count it).
pub const STANDING: f64 = 0.05;
/// DESIGN.md's guarantee: no walk faster than `match.max_speed` + 5 %.
pub const SPEED_MARGIN: f64 = 1.05;
/// A handover farther apart than this is a loop that does not close, metres.
pub const OPEN_GAP_M: f64 = 0.01;

impl ProductFigures {
    /// The figures both readers measure the same way: collisions (`clearance`), speeds and key
    /// jumps (`tally`, held to `limit`), handovers (`seams`). The fields only one file has
    /// (borders, turning, the sampler) are left empty for the reader to fill.
    pub(crate) fn measured(
        file: &str,
        (walkers, standers, pieces, loops): (u64, u64, u64, u64),
        clearance: &crate::world::Clearance,
        tally: &Tally,
        seams: &Seams,
        limit: f64,
    ) -> ProductFigures {
        ProductFigures {
            file: file.into(),
            walkers,
            standers,
            pieces,
            collisions: clearance.collisions,
            min_clearance_m: clearance.min_clearance_m,
            worst_at: clearance.worst_at,
            max_speed_m_s: tally.max_speed,
            max_speed_at: tally.max_speed_at,
            speed_limit_m_s: limit,
            share_above_limit: tally.share_above(),
            max_key_velocity_jump: tally.max_jump,
            max_border_velocity_jump: None,
            max_border_gap_m: None,
            max_seam_velocity_jump: seams.max_jump,
            max_seam_heading_jump_rad: seams.max_heading,
            max_seam_gap_m: seams.max_gap,
            loops,
            open_loops: seams.open,
            max_turn_rate_rad_s: None,
            turn_rate_limit_rad_s: None,
            sampled: None,
            unlike_manifest: None,
        }
    }
}

/// DESIGN.md's guarantees on one shipped file.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ProductFigures {
    /// The file read (`library.crowd`, `world.glb`).
    pub file: String,
    /// Walking characters (library: its walkers; glTF: animated nodes), standers, and the
    /// straight pieces checked.
    pub walkers: u64,
    pub standers: u64,
    pub pieces: u64,
    /// Pairs closer than 2r at some time (walkers, walker-stander; walkers closer than r to an
    /// obstacle of the build's graph), exact closest approach of the pieces.
    pub collisions: u64,
    pub min_clearance_m: f64,
    /// Where and when the worst pair is closest (world metres, seconds in the period).
    pub worst_at: Option<(f64, f64, f64)>,
    /// The fastest piece, m/s (a piece within one 0.1 ms tick counts as lasting one), and where
    /// and when it starts.
    pub max_speed_m_s: f64,
    pub max_speed_at: Option<(f64, f64, f64)>,
    /// `match.max_speed` x 1.05, and the share of walking time faster than that.
    pub speed_limit_m_s: f64,
    pub share_above_limit: f64,
    /// Largest change of velocity at a key inside a path (a library trajectory, a glTF node's
    /// track), m/s.
    pub max_key_velocity_jump: f64,
    /// Library: largest change of velocity and of position where a trajectory hands over to
    /// the one in the next patch (its `next`), loop seams left out.
    pub max_border_velocity_jump: Option<f64>,
    pub max_border_gap_m: Option<f64>,
    /// Where a path hands over to itself or another after its last key (library: a loop's last
    /// trajectory to its first; glTF: a node at the clip's end to the node that starts where
    /// it ends): largest change of velocity (m/s), of heading (rad) and of position (m).
    pub max_seam_velocity_jump: f64,
    pub max_seam_heading_jump_rad: f64,
    pub max_seam_gap_m: f64,
    /// Loops (glTF: animated nodes), and those whose end is more than 1 cm from where they
    /// should go on (glTF: from every node's clip start).
    pub loops: u64,
    pub open_loops: u64,
    /// glTF: the fastest turn between two rotation keys; library: between two frames of its
    /// sampler, rad/s.
    pub max_turn_rate_rad_s: Option<f64>,
    /// `export.turn_rate_deg_s` in rad/s, plus the keys' rounding (1 %): no turn may be faster.
    #[serde(default)]
    pub turn_rate_limit_rad_s: Option<f64>,
    /// Library: the runtime's `Sampler` played frame after frame.
    pub sampled: Option<Sampled>,
    /// How the file differs from the one `export.ron` names (its size and hash), if it does:
    /// what is judged here is then not what stage 8 wrote.
    #[serde(default)]
    pub unlike_manifest: Option<String>,
}

/// The library played by `crowd_runtime::Sampler`, as an engine embeds it: every character,
/// every `step_s` over one period.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Sampled {
    pub step_s: f64,
    pub frames: u64,
    /// The longest step between two frames over the step's time, m/s.
    pub max_speed_m_s: f64,
    /// Steps longer than the walker's fastest piece allows (of the stretch of loop it walks
    /// over the period; plus 1 mm of f32 rounding).
    pub jumps: u64,
    /// The fastest turn of any character between two frames, rad/s (None: checked before
    /// headings were).
    #[serde(default)]
    pub max_turn_rate_rad_s: Option<f64>,
}

/// Speeds and key jumps of paths, summed in path order.
#[derive(Debug, Clone, Default)]
pub(crate) struct Tally {
    walking: f64,
    above: f64,
    pub max_speed: f64,
    pub max_speed_at: Option<(f64, f64, f64)>,
    pub max_jump: f64,
}

/// The velocity of the straight walk from `a` to `b`, a walk shorter than `min_dt` taken to
/// last `min_dt` (an engine shows it within that long).
pub(crate) fn velocity(a: (DVec2, f64), b: (DVec2, f64), min_dt: f64) -> DVec2 {
    let d = b.0 - a.0;
    if d == DVec2::ZERO {
        DVec2::ZERO
    } else {
        d / (b.1 - a.1).max(min_dt)
    }
}

/// The pieces of a path an engine shows: consecutive points but those repeated at the same
/// time and place (a split point on an entry, say), which last no time and go nowhere.
/// The slowest speed from `a` to `b` that their float32 positions and times allow: each
/// coordinate and time may be half a float32 step off. Keys 2 us apart (a float32 step of time
/// near 20 s) whose positions 1.6 km from the origin round to one float32 step (0.12 mm) apart
/// read 61 m/s, though the walk between them is 0.004 mm: a player never shows it, and the
/// glTF cannot say it better.
pub(crate) fn float32_speed(a: (DVec2, f64), b: (DVec2, f64), min_dt: f64) -> f64 {
    let step = |x: f64| {
        let f = x.abs() as f32;
        f64::from(f32::from_bits(f.to_bits() + 1) - f)
    };
    let far = a.0.abs().max(b.0.abs()).max_element();
    let moved = ((b.0 - a.0).length() - std::f64::consts::SQRT_2 * step(far)).max(0.0);
    let time = b.1 - a.1 + step(a.1.abs().max(b.1.abs()));
    if moved == 0.0 {
        0.0
    } else {
        moved / time.max(min_dt)
    }
}

/// Paths [`Tally::of_made`] makes at once.
const PATHS_AT_ONCE: usize = 1 << 16;

pub(crate) fn pieces(
    pts: &[(DVec2, f64)],
) -> impl DoubleEndedIterator<Item = ((DVec2, f64), (DVec2, f64))> + '_ {
    pts.windows(2)
        .map(|w| (w[0], w[1]))
        .filter(|&(a, b)| shown(a, b))
}

/// Whether the piece from `a` to `b` is one an engine shows ([`pieces`]).
pub(crate) fn shown(a: (DVec2, f64), b: (DVec2, f64)) -> bool {
    a.1 < b.1 || a.0 != b.0
}

/// The velocities a path starts and ends with (its first and last pieces that are shown;
/// standing when it has none).
pub(crate) fn end_velocities(pts: &[(DVec2, f64)], min_dt: f64) -> (DVec2, DVec2) {
    let v = |p: Option<((DVec2, f64), (DVec2, f64))>| {
        p.map_or(DVec2::ZERO, |(a, b)| velocity(a, b, min_dt))
    };
    (v(pieces(pts).next()), v(pieces(pts).next_back()))
}

impl Tally {
    /// Tallies `paths` (world points and seconds each), in parallel and added in order.
    #[cfg(test)]
    pub fn of(paths: &[Vec<(DVec2, f64)>], limit: f64, min_dt: f64, period: f64) -> Tally {
        let path = |i: usize| Cow::Borrowed(&paths[i][..]);
        Tally::of_made(paths.len(), path, limit, (min_dt, false), period)
    }

    /// [`Tally::of`] of paths read from float32 positions and times (`world.glb`): a piece
    /// is judged at the slowest speed its float32 ends allow ([`float32_speed`]).
    pub fn of_float32(paths: &[Vec<(DVec2, f64)>], limit: f64, min_dt: f64, period: f64) -> Tally {
        let path = |i: usize| Cow::Borrowed(&paths[i][..]);
        Tally::of_made(paths.len(), path, limit, (min_dt, true), period)
    }

    /// [`Tally::of`] of `n` paths that `path` makes when asked (path `i`), a run of
    /// [`PATHS_AT_ONCE`] at a time: a million walkers' paths held at once were 2.3 GB.
    pub fn of_made<'p>(
        n: usize,
        path: impl Fn(usize) -> Cow<'p, [(DVec2, f64)]> + Sync,
        limit: f64,
        timing: (f64, bool),
        period: f64,
    ) -> Tally {
        Tally::default().then_made(n, path, limit, timing, period)
    }

    /// This tally, then [`Tally::of_made`]'s paths added one after another: the same sums as
    /// all the paths of both in one tally.
    pub fn then_made<'p>(
        self,
        n: usize,
        path: impl Fn(usize) -> Cow<'p, [(DVec2, f64)]> + Sync,
        limit: f64,
        (min_dt, float32): (f64, bool),
        period: f64,
    ) -> Tally {
        let mut total = self;
        for start in (0..n).step_by(PATHS_AT_ONCE) {
            let run = start..(start + PATHS_AT_ONCE).min(n);
            let tallies: Vec<Tally> = run
                .into_par_iter()
                .map(|i| {
                    let mut t = Tally::default();
                    t.path(&path(i), limit, (min_dt, float32), period);
                    t
                })
                .collect();
            // Added one path after another, whatever the runs: the same sums.
            total = tallies.into_iter().fold(total, Tally::add);
        }
        total
    }

    fn path(
        &mut self,
        pts: &[(DVec2, f64)],
        limit: f64,
        (min_dt, float32): (f64, bool),
        period: f64,
    ) {
        let mut before: Option<DVec2> = None;
        for w in pieces(pts) {
            let w = [w.0, w.1];
            let v = velocity(w[0], w[1], min_dt);
            let (speed, dt) = (v.length(), w[1].1 - w[0].1);
            let judged = if float32 {
                float32_speed(w[0], w[1], min_dt)
            } else {
                speed
            };
            if speed > STANDING {
                self.walking += dt;
                if judged > limit {
                    self.above += dt;
                }
            }
            let speed = judged;
            if speed > self.max_speed {
                self.max_speed = speed;
                let (p, t) = w[0];
                self.max_speed_at = Some((p.x, p.y, t.rem_euclid(period)));
            }
            if let Some(u) = before {
                self.max_jump = self.max_jump.max((v - u).length());
            }
            before = Some(v);
        }
    }

    fn add(mut self, o: Tally) -> Tally {
        self.walking += o.walking;
        self.above += o.above;
        if o.max_speed > self.max_speed {
            self.max_speed = o.max_speed;
            self.max_speed_at = o.max_speed_at;
        }
        self.max_jump = self.max_jump.max(o.max_jump);
        self
    }

    /// Share of walking time faster than the limit.
    pub fn share_above(&self) -> f64 {
        if self.walking > 0.0 {
            self.above / self.walking
        } else {
            0.0
        }
    }
}

/// The handovers of paths to the paths that continue them.
#[derive(Debug, Clone, Default)]
pub(crate) struct Seams {
    pub max_jump: f64,
    pub max_heading: f64,
    pub max_gap: f64,
    pub open: u64,
}

impl Seams {
    /// A handover from velocity `v_in` at `end` to `v_out` at `start`, with the headings
    /// shown on both sides (None: taken from the velocities, when both walk).
    pub fn note(&mut self, (end, v_in): (DVec2, DVec2), (start, v_out): (DVec2, DVec2)) {
        let heading = if v_in.length() > STANDING && v_out.length() > STANDING {
            v_in.angle_to(v_out).abs()
        } else {
            0.0
        };
        self.note_with_heading(end.distance(start), (v_out - v_in).length(), heading);
    }

    pub fn note_with_heading(&mut self, gap: f64, jump: f64, heading: f64) {
        self.max_gap = self.max_gap.max(gap);
        self.max_jump = self.max_jump.max(jump);
        self.max_heading = self.max_heading.max(heading);
    }

    /// Both `self`'s handovers and `o`'s (maxima and a count: the same in any grouping).
    pub fn merge(mut self, o: Seams) -> Seams {
        self.note_with_heading(o.max_gap, o.max_jump, o.max_heading);
        self.open += o.open;
        self
    }
}

#[cfg(test)]
mod tests {
    /// Two float32 keys one float32 step apart in place and time, 1.58 km from the origin,
    /// are no walk at all; a real metre in a tenth of a second is 10 m/s however far out.
    #[test]
    fn float32_rounding_is_not_speed_but_a_fast_walk_is() {
        let f = |x: f64| f64::from(x as f32);
        let x = f(1581.0);
        let x1 = f64::from(f32::from_bits((x as f32).to_bits() + 1));
        let t = f(19.999);
        let t1 = f64::from(f32::from_bits((t as f32).to_bits() + 1));
        let (a, b) = ((DVec2::new(x, f(300.0)), t), (DVec2::new(x1, f(300.0)), t1));
        assert!(velocity(a, b, 2e-6).length() > 50.0);
        assert_eq!(float32_speed(a, b, 2e-6), 0.0);
        let c = (DVec2::new(f(x + 1.0), f(300.0)), f(t + 0.1));
        assert!((float32_speed(a, c, 2e-6) - 10.0).abs() < 0.01);
    }

    use super::*;

    fn path(pts: &[(f64, f64, f64)]) -> Vec<(DVec2, f64)> {
        pts.iter().map(|&(x, y, t)| (DVec2::new(x, y), t)).collect()
    }

    #[test]
    fn a_fast_piece_sets_the_speed_and_its_share_of_walking_time() {
        // 1 m/s for 3 s, then 4 m/s for 1 s: a quarter of the walking time above 1.89 m/s,
        // and a 3 m/s jump at the key between.
        let p = path(&[(0.0, 0.0, 0.0), (3.0, 0.0, 3.0), (7.0, 0.0, 4.0)]);
        let t = Tally::of(&[p], 1.89, 1e-4, 20.0);
        assert!((t.max_speed - 4.0).abs() < 1e-12);
        assert_eq!(t.max_speed_at, Some((3.0, 0.0, 3.0)));
        assert!((t.share_above() - 0.25).abs() < 1e-12);
        assert!((t.max_jump - 3.0).abs() < 1e-12);
    }

    #[test]
    fn a_move_within_no_time_is_a_move_within_the_smallest_step() {
        let p = path(&[(0.0, 0.0, 0.0), (1.0, 0.0, 1.0), (1.5, 0.0, 1.0)]);
        let t = Tally::of(&[p], 1.89, 1e-4, 20.0);
        assert!((t.max_speed - 5000.0).abs() < 1e-6, "{}", t.max_speed);
    }

    #[test]
    fn a_point_repeated_at_the_same_time_and_place_is_no_stop() {
        let p = path(&[
            (0.0, 0.0, 0.0),
            (0.0, 0.0, 0.0),
            (1.0, 0.0, 1.0),
            (1.0, 0.0, 1.0),
        ]);
        let t = Tally::of(std::slice::from_ref(&p), 1.89, 1e-4, 20.0);
        assert_eq!(t.max_jump, 0.0);
        assert_eq!(end_velocities(&p, 1e-4), (DVec2::X, DVec2::X));
    }

    #[test]
    fn a_seam_turning_round_jumps_in_heading_and_velocity() {
        let mut s = Seams::default();
        let (x, y) = (DVec2::X, DVec2::Y);
        s.note((DVec2::ZERO, x), (DVec2::new(0.0, 0.02), -x));
        assert!((s.max_heading - std::f64::consts::PI).abs() < 1e-12);
        assert!((s.max_jump - 2.0).abs() < 1e-12 && (s.max_gap - 0.02).abs() < 1e-12);
        // Standing on one side: no heading to compare.
        s.note((DVec2::ZERO, y * 0.01), (DVec2::ZERO, y));
        assert!((s.max_heading - std::f64::consts::PI).abs() < 1e-12);
    }
}
