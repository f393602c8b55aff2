//! The optimal crowd editing experiments, each whole (setup, descent, figures), and one forward
//! and one adjoint integration of the `density` crowd: `cargo bench -p crowd-edit --bench
//! experiments`. One thread, as the targets are set. Figures go to BENCHMARKS.md.

use criterion::{Criterion, criterion_group, criterion_main};
use crowd_edit::experiments::{self, NAMES, Overrides};
use std::hint::black_box;
use std::time::Duration;

fn integrations(c: &mut Criterion) {
    let setup = experiments::setup("density", &Overrides::default()).unwrap();
    let p = &setup.problem;
    let n = p.n();
    let (shift, controls) = (vec![0.0; n], vec![0.0; p.timeline.steps * n]);
    let mut group = c.benchmark_group("density crowd (64 characters, 250 steps)");
    group.bench_function("forward (RK4)", |b| {
        b.iter(|| black_box(p.run(&shift, &controls)))
    });
    let run = p.run(&shift, &controls);
    group.bench_function("adjoint (RK4, with the observations' forcing)", |b| {
        b.iter(|| black_box(p.gradient(&run, &shift, &controls)))
    });
    group.finish();
}

fn whole(c: &mut Criterion) {
    let mut group = c.benchmark_group("experiment");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(20));
    for name in NAMES {
        group.bench_function(name, |b| {
            b.iter(|| black_box(experiments::run(name, &Overrides::default(), |_, _| {}).unwrap()))
        });
    }
    group.finish();
}

criterion_group!(benches, integrations, whole);
criterion_main!(benches);
