//! Density against the number of entry points, measured on random patches of the scene's size
//! and period with our own matching (Crowd Art section 3.3, Figure 4). The optimiser starts
//! every patch with the number of points this fit predicts for its requested density.

use crowd_core::config::MatchSettings;
use crowd_core::patterns::{Regression, Side};
use crowd_match::{Endpoint, PatchContext};
use glam::DVec2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Fits density = slope x entries + intercept over random patches with 1 to `max_entries`
/// entries (and as many exits) placed at random on the four sides, each exit a comfortable
/// walk after an entry.
pub fn fit(
    side_m: f64,
    period_s: f64,
    settings: &MatchSettings,
    max_entries: u32,
    seed: u64,
) -> Regression {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5EED_F164);
    let ctx = PatchContext {
        side_m,
        period_s,
        comfort_speed: settings.comfort_speed,
        direction: None,
        obstacles: &[],
        radius_m: 0.3,
        settings,
    };
    let sides = [Side::West, Side::East, Side::South, Side::North];
    let random_point = |rng: &mut ChaCha8Rng| {
        let side = sides[rng.random_range(0..4)];
        let s = rng.random_range(0.5..side_m - 0.5);
        let pos = match side {
            Side::West => DVec2::new(0.0, s),
            Side::East => DVec2::new(side_m, s),
            Side::South => DVec2::new(s, 0.0),
            Side::North => DVec2::new(s, side_m),
        };
        Endpoint {
            crossing: 0,
            pos,
            t: rng.random_range(0.0..period_s),
            side,
            velocity: side.inward() * settings.comfort_speed,
        }
    };
    let mut samples = Vec::new();
    for n in 1..=max_entries {
        for _ in 0..4 {
            // Walkers threaded as the optimiser threads them: each exit a comfortable walk
            // after its entry (see `retime`).
            let entries: Vec<_> = (0..n).map(|_| random_point(&mut rng)).collect();
            let exits: Vec<_> = entries
                .iter()
                .map(|e| {
                    let mut x = random_point(&mut rng);
                    x.velocity = -x.velocity;
                    x.t =
                        (e.t + e.pos.distance(x.pos) / settings.comfort_speed).rem_euclid(period_s);
                    x
                })
                .collect();
            let m = crowd_match::measure_patch(&entries, &exits, 0, &ctx);
            samples.push((n as f64, m.density));
        }
    }
    least_squares(&samples)
}

fn least_squares(samples: &[(f64, f64)]) -> Regression {
    let n = samples.len() as f64;
    let (sx, sy) = samples
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
    let (mx, my) = (sx / n, sy / n);
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for (x, y) in samples {
        sxx += (x - mx) * (x - mx);
        sxy += (x - mx) * (y - my);
        syy += (y - my) * (y - my);
    }
    let slope = sxy / sxx;
    let intercept = my - slope * mx;
    let r2 = if syy > 0.0 {
        sxy * sxy / (sxx * syy)
    } else {
        1.0
    };
    Regression {
        slope,
        intercept,
        r2,
        samples: samples.len() as u32,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn density_grows_with_the_number_of_points() {
        let r = fit(8.0, 20.0, &MatchSettings::default(), 40, 1);
        assert!(r.slope > 0.003 && r.slope < 0.01, "{r:?}");
        assert!(r.r2 > 0.9, "{r:?}");
    }
}
