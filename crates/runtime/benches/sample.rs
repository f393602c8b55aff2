//! One frame of `Sampler::sample` over a real library: the painting with 100k walkers
//! (100,642), built by `cargo xtask build-crowd --pipeline assets/bench/painting-100k.ron` (or
//! any library named by CROWD_LIBRARY, such as `build/painting/library.crowd`, 94,388). Time
//! runs forward at 60 frames a second, as in a game; the whole world is in view (every
//! character is written out), then a quarter of it; and, for the floor, a frame at a time that
//! does not move. And the headings a player makes as it loads the library.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use crowd_runtime::{Library, Sampler};
use std::path::PathBuf;

fn library() -> Library {
    let path = std::env::var_os("CROWD_LIBRARY").map_or_else(
        || {
            PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join("../../build/painting-100k/library.crowd")
        },
        PathBuf::from,
    );
    let bytes = std::fs::read(&path).unwrap_or_else(|e| {
        panic!(
            "{}: {e}; build it first: cargo xtask build-crowd --pipeline assets/bench/painting-100k.ron",
            path.display()
        )
    });
    Library::from_bytes(&bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn frames(c: &mut Criterion) {
    let lib = library();
    let side = lib.world.patch_side_m;
    let (w, h) = (lib.world.cols as f32 * side, lib.world.rows as f32 * side);
    let mut group = c.benchmark_group("sample");
    let walkers = lib.walkers();
    group.throughput(Throughput::Elements(walkers));
    for (name, view) in [
        ("whole world", [0.0, 0.0, w, h]),
        ("a quarter", [0.0, 0.0, w / 2.0, h / 2.0]),
    ] {
        let mut sampler = Sampler::new(&lib);
        let mut out = Vec::with_capacity(sampler.characters());
        let mut t = 0.0;
        group.bench_function(format!("{walkers} walkers, {name} in view"), |b| {
            b.iter(|| {
                t += 1.0 / 60.0;
                sampler.sample(t, view, &mut out);
                out.len()
            })
        });
    }
    // The floor: time stands still, so nobody walks on and a frame only streams the cursors.
    let mut sampler = Sampler::new(&lib);
    let mut out = Vec::with_capacity(sampler.characters());
    group.bench_function(format!("{walkers} walkers, time standing still"), |b| {
        b.iter(|| {
            sampler.sample(5.0, [0.0, 0.0, w, h], &mut out);
            out.len()
        })
    });
    // The memory floor of any sampler whose records are this size: a loop that only streams
    // 32 bytes in and writes a 16-byte sample out per walker, as `Sampler` does at least.
    let records: Vec<[f32; 8]> = (0..walkers)
        .map(|i| [0.0, 0.0, i as f32, 1.0, 0.5, 0.25, 1.0, 0.0])
        .collect();
    let mut streamed: Vec<[f32; 4]> = Vec::with_capacity(records.len());
    let mut dt = 0.0f32;
    group.bench_function(format!("{walkers} records streamed (the floor)"), |b| {
        b.iter(|| {
            dt += 1e-3;
            streamed.clear();
            streamed.extend(
                records
                    .iter()
                    .map(|r| [r[2] + r[4] * dt, r[3] + r[5] * dt, r[6], r[7]]),
            );
            streamed.len()
        })
    });
    group.finish();
}

/// What a player pays for the headings when it loads the library (`Sampler::new`): every
/// loop's, and the longest loop's alone (painting's has 5.6 million points, on one core).
fn headings(c: &mut Criterion) {
    let lib = library();
    let mut group = c.benchmark_group("headings");
    group.sample_size(10);
    group.throughput(Throughput::Elements(lib.points.len() as u64));
    group.bench_function(format!("{} points", lib.points.len()), |b| {
        b.iter(|| crowd_runtime::turn::library_headings(&lib).heading.len())
    });
    let longest = (lib.characters.iter())
        .max_by_key(|ch| ch.trajectories)
        .expect("a loop");
    group.bench_function("the longest loop", |b| {
        b.iter(|| {
            crowd_runtime::turn::character_headings(&lib, longest)
                .heading
                .len()
        })
    });
    group.finish();
}

criterion_group!(benches, frames, headings);
criterion_main!(benches);
