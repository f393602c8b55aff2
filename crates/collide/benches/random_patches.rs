//! Ramirez et al. Figure 6, our way: 1000 random patches (16 m x 16 m, period 10 s, 1 to 50
//! entry/exit pairs at random places and times), matched by stage 4 and cleared by stage 5.
//! Prints pushes, time and failures per band of pair counts.
//!
//! The points are drawn at random under the rule stage 3 keeps on every border
//! (`crowd_core::spacing::CrossingRule`: clear of the corners, band pieces apart): two
//! characters crossing one spot at one moment could not be separated by anyone, and our own
//! patterns never ask for it.
//!
//! `cargo bench -p crowd-collide --bench random_patches` (one thread per patch batch is not
//! needed: patches run one after another here, on one core).

use crowd_collide::path::Path;
use crowd_collide::repair::Patch;
use crowd_core::config::MatchSettings;
use crowd_core::patterns::{Crossing, Side, Way};
use crowd_core::spacing::CrossingRule;
use crowd_match::{Endpoint, PatchContext};
use glam::DVec2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::time::Instant;

fn main() {
    let (side, period, radius) = (16.0, 10.0, 0.3);
    let settings = MatchSettings::default();
    let ctx = PatchContext {
        side_m: side,
        period_s: period,
        comfort_speed: settings.comfort_speed,
        direction: None,
        obstacles: &[],
        radius_m: radius,
        settings: &settings,
    };
    let sides = [Side::West, Side::East, Side::South, Side::North];
    let rule = CrossingRule::new(radius);
    let mut rng = ChaCha8Rng::seed_from_u64(2014);
    // (pairs, pushes, seconds, converged)
    let mut rows: Vec<(usize, u32, f64, bool)> = Vec::new();
    for i in 0..1000 {
        let n = 1 + i % 50;
        // Crossings drawn so far, per side, as stage 3 would see them on that border.
        let mut placed: [Vec<Crossing>; 4] = Default::default();
        let mut point = |rng: &mut ChaCha8Rng, entering: bool| loop {
            let k = rng.random_range(0..4);
            let side_of = sides[k];
            let s = rng.random_range(rule.corner..side - rule.corner);
            let t = rng.random_range(0.0..period);
            let inward = side_of.inward();
            let velocity = if entering { inward } else { -inward } * settings.comfort_speed;
            let c = Crossing {
                border: k as u32,
                way: if entering { Way::AToB } else { Way::BToA },
                s,
                t,
                velocity,
            };
            if placed[k]
                .iter()
                .all(|o| rule.compatible(&c, o, inward.abs(), period))
            {
                placed[k].push(c);
                let pos = match side_of {
                    Side::West => DVec2::new(0.0, s),
                    Side::East => DVec2::new(side, s),
                    Side::South => DVec2::new(s, 0.0),
                    Side::North => DVec2::new(s, side),
                };
                break Endpoint {
                    crossing: 0,
                    pos,
                    t,
                    side: side_of,
                    velocity,
                };
            }
        };
        let entries: Vec<_> = (0..n).map(|_| point(&mut rng, true)).collect();
        let exits: Vec<_> = (0..n).map(|_| point(&mut rng, false)).collect();
        let mut paths: Vec<Path> = crowd_match::trajectories(&entries, &exits, &ctx)
            .iter()
            .map(Path::from_trajectory)
            .collect();
        let patch = Patch {
            side_m: side,
            period_s: period,
            radius_m: radius,
            obstacles: &[],
            standers: &[],
        };
        let mut patch_rng = ChaCha8Rng::seed_from_u64(i as u64);
        let start = Instant::now();
        let outcome = crowd_collide::with_restarts(&mut paths, &patch, 30_000, &mut patch_rng);
        rows.push((
            n,
            outcome.iterations,
            start.elapsed().as_secs_f64(),
            outcome.worst.is_none(),
        ));
    }
    println!("| pairs | patches | pushes (mean / max) | ms per patch (mean / max) | failures |");
    println!("| --- | ---: | ---: | ---: | ---: |");
    for band in 0..5 {
        let (lo, hi) = (band * 10 + 1, band * 10 + 10);
        let in_band: Vec<_> = rows.iter().filter(|r| r.0 >= lo && r.0 <= hi).collect();
        let count = in_band.len() as f64;
        let pushes = in_band.iter().map(|r| r.1 as f64).sum::<f64>() / count;
        let max_pushes = in_band.iter().map(|r| r.1).max().unwrap_or(0);
        let ms = in_band.iter().map(|r| r.2 * 1e3).sum::<f64>() / count;
        let max_ms = in_band.iter().map(|r| r.2 * 1e3).fold(0.0, f64::max);
        let failures = in_band.iter().filter(|r| !r.3).count();
        println!(
            "| {lo}-{hi} | {} | {pushes:.0} / {max_pushes} | {ms:.2} / {max_ms:.1} | {failures} |",
            in_band.len()
        );
    }
    let fifty: Vec<_> = rows.iter().filter(|r| r.0 == 50).collect();
    let ms50 = fifty.iter().map(|r| r.2 * 1e3).sum::<f64>() / fifty.len().max(1) as f64;
    println!(
        "\n50-pair patches: {ms50:.2} ms on average; failures in all: {}",
        rows.iter().filter(|r| !r.3).count()
    );
}
