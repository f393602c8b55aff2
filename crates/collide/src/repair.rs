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
}

impl Speeds {
    pub fn of(settings: &MatchSettings) -> Speeds {
        Speeds {
            comfort: settings.comfort_speed,
            max: settings.max_speed,
        }
    }

    /// Whether these are the defaults (1.33 and 1.8 m/s), which stage 5 used before it read
    /// the pipeline's.
    pub fn is_default(&self) -> bool {
        *self == Speeds::default()
    }
}

impl Default for Speeds {
    fn default() -> Speeds {
        Speeds::of(&MatchSettings::default())
    }
}

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
    for path in paths.iter_mut() {
        for f in &mut path.free {
            f.pos = patch.keep_inside(f.pos);
        }
        path.settle_splits();
    }
    let walls = patch.walls();
    let mut tracks = Tracks::new(paths.iter().map(Path::segments).collect());
    let mut rows = rows(&tracks, patch);
    let worst = |rows: &[Vec<Encounter>]| {
        rows.iter()
            .flatten()
            .copied()
            .min_by(|x, y| x.margin.total_cmp(&y.margin))
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
        let touched = push_apart(paths, &tracks, patch, speeds, &w, rng);
        for &p in &touched {
            paths[p].reroute(&walls, patch.radius_m, patch.side_m);
            paths[p].settle_splits();
        }
        for &p in &touched {
            tracks.set(p, paths[p].segments());
        }
        refresh(&mut rows, &mut tracks, &touched, patch);
    }
}
