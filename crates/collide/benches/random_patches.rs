//! Ramirez et al. Figure 6, our way: 1000 random patches (16 m x 16 m, period 10 s, 1 to 50
//! entry/exit pairs at random places and times), matched by stage 4 and cleared by stage 5.
//! Prints pushes, time and failures per band of pair counts.
//!
//! The points are drawn at random under the rule stage 3 keeps on every border
//! (`crowd_match::random`).
//!
//! `cargo bench -p crowd-collide --bench random_patches` (one thread per patch batch is not
//! needed: patches run one after another here, on one core).

use crowd_collide::path::Path;
use crowd_collide::repair::{Patch, Speeds};
use crowd_match::random::{Shape, walkers};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::time::Instant;

fn main() {
    let shape = Shape {
        side_m: 16.0,
        period_s: 10.0,
        radius_m: 0.3,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(2014);
    // (pairs, pushes, seconds, converged)
    let mut rows: Vec<(usize, u32, f64, bool)> = Vec::new();
    for i in 0..1000 {
        let n = 1 + i % 50;
        let mut paths: Vec<Path> = walkers(n, shape, &mut rng)
            .iter()
            .map(Path::from_trajectory)
            .collect();
        let patch = Patch {
            side_m: shape.side_m,
            period_s: shape.period_s,
            radius_m: shape.radius_m,
            obstacles: &[],
            standers: &[],
        };
        let mut patch_rng = ChaCha8Rng::seed_from_u64(i as u64);
        let start = Instant::now();
        let outcome = crowd_collide::with_restarts(
            &mut paths,
            &patch,
            Speeds::default(),
            30_000,
            &mut patch_rng,
        );
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
