//! Stage benchmarks on the shared scenes: `cargo xtask bench pipeline` (or `cargo bench --bench pipeline`).
//! Figures go to BENCHMARKS.md with the command that produced them.

use criterion::{Criterion, criterion_group, criterion_main};
use crowd_core::Hash;
use crowd_core::config::PipelineFile;
use std::path::PathBuf;
use std::time::Duration;

fn pipeline(scene: &str) -> PipelineFile {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("assets/pipelines")
        .join(format!("{scene}.ron"));
    PipelineFile::load(&path).expect("the scene pipelines load")
}

fn stages(c: &mut Criterion) {
    for scene in ["painting", "city"] {
        let p = pipeline(scene);
        let layers = crowd_merge::read_layers(&p).unwrap();
        let decoded = crowd_merge::decode(&layers).unwrap();
        let mpp = p.pipeline.scene.meters_per_pixel;
        let maps = crowd_merge::merge(&decoded, &p.pipeline.merge, mpp, &());
        let inputs = crowd_graph::inputs(&p);

        let mut group = c.benchmark_group(scene);
        group
            .sample_size(20)
            .measurement_time(Duration::from_secs(8));
        group.bench_function("merge (read + decode + merge)", |b| {
            b.iter(|| {
                let layers = crowd_merge::read_layers(&p).unwrap();
                let decoded = crowd_merge::decode(&layers).unwrap();
                crowd_merge::merge(&decoded, &p.pipeline.merge, mpp, &())
            })
        });
        group.bench_function("graph (from merged maps)", |b| {
            b.iter(|| crowd_graph::build_graph(&maps, &inputs, Hash::of(b""), &()).unwrap())
        });
        group.bench_function("merge + graph", |b| {
            b.iter(|| {
                let layers = crowd_merge::read_layers(&p).unwrap();
                let decoded = crowd_merge::decode(&layers).unwrap();
                let maps = crowd_merge::merge(&decoded, &p.pipeline.merge, mpp, &());
                crowd_graph::build_graph(&maps, &inputs, Hash::of(b""), &()).unwrap()
            })
        });
        group.finish();
    }
}

criterion_group!(benches, stages);
criterion_main!(benches);
