//! The trajectories side file's codec: every stage from 4 on writes one and the next build
//! reads it back (painting's stage 6 file is 425 MB, 17 million points, on every brush stroke).
//! `cargo bench -p crowd-core --bench side_file`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use crowd_core::trajectories::{
    ControlPoint, MotionIndex, PatchMotion, PointKind, Trajectory, encode_motion,
};
use glam::DVec2;
use std::hint::black_box;
use std::path::Path;

/// 1,000 patches of 12 trajectories of 80 points (960,000 points, 24 MB), made the same way
/// every run.
fn motion() -> Vec<PatchMotion> {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..1_000)
        .map(|_| PatchMotion {
            standers: (0..3)
                .map(|_| DVec2::new(next() * 8.0, next() * 8.0))
                .collect(),
            trajectories: (0..12)
                .map(|k| Trajectory {
                    entry: k,
                    exit: k + 1,
                    points: (0..80)
                        .map(|i| ControlPoint {
                            pos: DVec2::new(next() * 8.0, next() * 8.0),
                            t: f64::from(i) * 0.2 + next() * 0.1,
                            kind: if i % 7 == 0 {
                                PointKind::Band
                            } else {
                                PointKind::Sample
                            },
                        })
                        .collect(),
                })
                .collect(),
        })
        .collect()
}

fn codec(c: &mut Criterion) {
    let motion = motion();
    let bytes = encode_motion(&motion);
    let mut group = c.benchmark_group("side file");
    group.throughput(Throughput::Bytes(bytes.len() as u64));
    group.sample_size(20);
    group.bench_function("encode_motion", |b| {
        b.iter(|| encode_motion(black_box(&motion)))
    });
    let index = MotionIndex::of(Path::new("bench.bin"), &bytes).unwrap();
    group.bench_function("decode_all", |b| {
        b.iter(|| {
            index
                .decode_all(Path::new("bench.bin"), black_box(&bytes))
                .unwrap()
        })
    });
    group.finish();
}

criterion_group!(benches, codec);
criterion_main!(benches);
