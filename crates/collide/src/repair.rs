//! Ramirez et al. Algorithm 2 in one patch: while some pair is too close, push the closest
//! pair apart at the moment they are closest ([`crate::push`]), and measure again only what
//! the push changed (the distance matrix of `crowd_geometry::rows`).

use crate::path::Path;
use crate::push::push_apart;
use crowd_core::config::MatchSettings;
use rand_chacha::ChaCha8Rng;

// The encounter test is shared geometry; stage 5's API speaks of it.
pub use crowd_geometry::{Encounter, Other, Patch, Tracks, refresh, rows};

/// How fast stage 5 lets a walker walk where it changes a path's timing, m/s: to and from a
/// pause it moves, at the comfort speed when there is time; never faster than the largest
/// speed in a time move or a walk to a moved pause. The pipeline's `match.comfort_speed` and
/// `match.max_speed`, the speeds stage 4 drew the lines with.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Speeds {
    pub comfort: f64,
    pub max: f64,
    /// The fastest a bend or a planned way may make a walker walk ([`Speeds::bend_limit`]),
    /// as a share of `max`.
    #[serde(skip)]
    pub bend_share: f64,
}

impl Speeds {
    pub fn of(settings: &MatchSettings) -> Speeds {
        Speeds {
            comfort: settings.comfort_speed,
            max: settings.max_speed,
            bend_share: BEND_SHARE,
        }
    }

    /// The speeds of a second try at a patch the first leaves stalled: bends up to
    /// [`SECOND_SHARE`] of `max` (still within what ships).
    pub fn second(&self) -> Speeds {
        Speeds {
            bend_share: SECOND_SHARE,
            ..*self
        }
    }

    /// The speeds of a patch that cannot be cleared at [`Speeds::bend_limit`]: its bends may
    /// hurry up to [`HURRY_M_S`]. Collision-free comes first; the build says which patches
    /// hurried.
    pub fn hurried(&self) -> Speeds {
        Speeds {
            bend_share: (HURRY_M_S / self.max).max(BEND_SHARE),
            ..*self
        }
    }

    /// The fastest a bend or a planned way may make a walker walk: `max` plus 3 % ([`BEND_SHARE`]). The shipped
    /// files are held to `max` plus 5 %; stage 6's curves may take 1 % more, export's dropped
    /// keyframes a little. Without the 3 %, a walker that must pass behind another at the
    /// last moment found no way at exactly `max` on the rescue's grid (ring, patch 222).
    pub fn bend_limit(&self) -> f64 {
        self.max * self.bend_share
    }
}

impl Default for Speeds {
    fn default() -> Speeds {
        Speeds::of(&MatchSettings::default())
    }
}

/// See [`Speeds::bend_limit`].
pub const BEND_SHARE: f64 = 1.03;
/// See [`Speeds::second`]: stalls are chancy (ring's patches 222 and 226 each cleared at one
/// of 1.03 and 1.045, not at the other). No more than stage 6's curves may take: the library's
/// rounding of a short piece adds up to about 1 % (random painting 47: a 1.881 m/s polyline
/// shipped at 1.896 m/s with a second try at 1.045).
pub const SECOND_SHARE: f64 = 1.04;
/// See [`Speeds::hurried`]: a brief run (before speeds were kept, every patch's pushes were
/// capped so; without a cap, a point pushed again and again ran off at 20 m/s).
pub const HURRY_M_S: f64 = 4.0;

/// How the repair of a patch ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outcome {
    pub iterations: u32,
    /// The worst encounter left (None: nobody is closer than they may be).
    pub worst: Option<Encounter>,
}

/// Removes collisions from the walkers of one patch. Boundary points never move (the paths'
/// anchors cannot); free points move within the patch and out of obstacles.
pub fn remove_collisions(
    paths: &mut [Path],
    patch: &Patch,
    speeds: Speeds,
    max_iterations: u32,
    rng: &mut ChaCha8Rng,
) -> Outcome {
    let limit = speeds.bend_limit();
    // Whether each walk fits its time at the limit: a move that would make one that fits too
    // long for its time (a pause moved behind a wall, a detour) is taken back.
    let mut fits: Vec<bool> = paths
        .iter_mut()
        .map(|path| {
            for f in &mut path.free {
                f.pos = patch.keep_inside(f.pos);
            }
            path.settle_splits();
            // Stage 4's lines keep to the speed limit on average; between its band ends a
            // walk may not (a slow band leaves the middle less time).
            path.limit_speed(limit)
        })
        .collect();
    let walls = patch.walls();
    let mut tracks = Tracks::indexed(paths.iter().map(Path::segments).collect(), patch);
    let mut rows = rows(&tracks, patch);
    let worst = |rows: &[Vec<Encounter>]| {
        rows.iter()
            .flatten()
            .min_by(|x, y| x.margin.total_cmp(&y.margin))
            .copied()
    };
    let mut iterations = 0;
    loop {
        let w = worst(&rows);
        let Some(w) = w.filter(|w| w.margin < 0.0) else {
            return Outcome {
                iterations,
                worst: w.filter(|w| w.margin < 0.0),
            };
        };
        if iterations >= max_iterations {
            return Outcome {
                iterations,
                worst: Some(w),
            };
        }
        iterations += 1;
        let mut pair = vec![w.a];
        if let Other::Walker { b, .. } = w.other
            && b != w.a
        {
            pair.push(b);
        }
        // A push changes only free points (anchors and bands have no setter).
        let saved: Vec<(usize, Vec<crate::path::Free>)> =
            pair.iter().map(|&p| (p, paths[p].free.clone())).collect();
        let touched = push_apart(paths, &tracks, patch, speeds, &w, rng);
        for &p in &touched {
            paths[p].reroute(&walls, patch.radius_m, patch.side_m);
            let now = paths[p].limit_speed(limit);
            paths[p].settle_splits();
            if !now && fits[p] {
                if let Some((_, old)) = saved.iter().find(|(q, _)| *q == p) {
                    paths[p].free.clone_from(old);
                }
            } else {
                fits[p] = now;
            }
        }
        for &p in &touched {
            tracks.set(p, paths[p].segments());
        }
        refresh(&mut rows, &mut tracks, &touched, patch);
    }
}
