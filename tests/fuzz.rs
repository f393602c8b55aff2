//! Fuzzing with proptest: real files of a build (and the shipped pipelines), mutated (bytes
//! flipped, set, inserted, cut out or repeated, the file cut short, a number replaced with a
//! hostile one), go into every reader the pipeline has: the pipeline parser and its
//! validation, each stage file's reader and decoder (the side files' decoders too, behind their
//! hash checks), the library's loader and the glTF reader of `crowd check`. Each must end in a
//! value or an error, never a panic (`cargo xtask fuzz` has no sanitizer: out-of-bounds reads
//! are panics in safe Rust, and the readers are safe Rust).
//!
//! In `cargo test` each target runs [`CI_CASES`] cases; `CROWD_FUZZ_SECONDS=600` (what
//! `cargo xtask fuzz` sets) runs each for that long in batches of fresh seeds, and prints the
//! cases it ran.

use crate::util::*;
use crowd_core::trajectories::{TrajectoriesFile, check_motion, decode_motion};
use crowd_core::{MergedMaps, PatchGraph, patterns::Patterns};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestError, TestRng, TestRunner};
use std::path::Path;
use std::time::{Duration, Instant};

/// Cases per target in `cargo test`.
const CI_CASES: u32 = 96;

/// One change to a file's bytes.
#[derive(Debug, Clone)]
enum Mutation {
    Flip(usize, u8),
    Set(usize, u8),
    Insert(usize, Vec<u8>),
    Remove(usize, usize),
    Repeat(usize, usize),
    Truncate(usize),
    /// The `n`th number of a text file replaced (wrapping over the numbers there are).
    Number(usize, &'static str),
}

const HOSTILE: &[&str] = &[
    "NaN",
    "inf",
    "-inf",
    "1e300",
    "-1e300",
    "1e-300",
    "0",
    "-0.0",
    "-1",
    "4294967296",
    "18446744073709551616",
    "1e39",
    "0.00001",
    "600.00001",
    "99999999999",
];

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), 1u8..=255).prop_map(|(at, b)| Mutation::Flip(at, b)),
        (any::<usize>(), any::<u8>()).prop_map(|(at, b)| Mutation::Set(at, b)),
        (
            any::<usize>(),
            proptest::collection::vec(any::<u8>(), 1..12)
        )
            .prop_map(|(at, b)| Mutation::Insert(at, b)),
        (any::<usize>(), 1usize..64).prop_map(|(at, n)| Mutation::Remove(at, n)),
        (any::<usize>(), 1usize..64).prop_map(|(at, n)| Mutation::Repeat(at, n)),
        any::<usize>().prop_map(Mutation::Truncate),
        (any::<usize>(), proptest::sample::select(HOSTILE))
            .prop_map(|(n, v)| Mutation::Number(n, v)),
    ]
}

fn mutations() -> impl Strategy<Value = Vec<Mutation>> {
    proptest::collection::vec(mutation(), 1..6)
}

/// `base` with `changes` applied in turn.
fn mutate(base: &[u8], changes: &[Mutation]) -> Vec<u8> {
    let mut b = base.to_vec();
    for m in changes {
        let at = |i: usize, len: usize| if len == 0 { 0 } else { i % len };
        match m {
            Mutation::Flip(i, x) if !b.is_empty() => {
                let i = at(*i, b.len());
                b[i] ^= x;
            }
            Mutation::Set(i, x) if !b.is_empty() => {
                let i = at(*i, b.len());
                b[i] = *x;
            }
            Mutation::Insert(i, xs) => {
                let i = at(*i, b.len() + 1);
                b.splice(i..i, xs.iter().copied());
            }
            Mutation::Remove(i, n) if !b.is_empty() => {
                let i = at(*i, b.len());
                b.drain(i..(i + n).min(b.len()));
            }
            Mutation::Repeat(i, n) if !b.is_empty() => {
                let i = at(*i, b.len());
                let run: Vec<u8> = b[i..(i + n).min(b.len())].to_vec();
                b.splice(i..i, run);
            }
            Mutation::Truncate(i) => {
                let i = at(*i, b.len() + 1);
                b.truncate(i);
            }
            Mutation::Number(n, v) => {
                let numbers = numbers(&b);
                if !numbers.is_empty() {
                    let (s, e) = numbers[n % numbers.len()];
                    b.splice(s..e, v.bytes());
                }
            }
            _ => {}
        }
    }
    b
}

/// Where the numbers of a text are (runs of digits, with a sign, point or exponent).
fn numbers(b: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i].is_ascii_digit() {
            let s = if i > 0 && b[i - 1] == b'-' { i - 1 } else { i };
            let mut e = i;
            while e < b.len() && (b[e].is_ascii_alphanumeric() || b[e] == b'.' || b[e] == b'-') {
                e += 1;
            }
            out.push((s, e));
            i = e;
        } else {
            i += 1;
        }
    }
    out
}

/// Runs `test` on mutations of one of `bases` (the base's index and the mutated bytes):
/// [`CI_CASES`] cases, or batches of fresh seeds for `CROWD_FUZZ_SECONDS`. Panics with the
/// smallest failing mutation.
fn fuzz(name: &str, bases: &[Vec<u8>], test: impl Fn(usize, &[u8])) {
    let seconds: Option<u64> = std::env::var("CROWD_FUZZ_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok());
    let budget = seconds.map(Duration::from_secs);
    let start = Instant::now();
    let mut ran = 0u64;
    let mut batch = 0u64;
    loop {
        let mut seed = [0u8; 32];
        seed[..8].copy_from_slice(&batch.to_le_bytes());
        seed[8..16].copy_from_slice(&(name.len() as u64).to_le_bytes());
        let config = Config {
            cases: if budget.is_some() { 512 } else { CI_CASES },
            failure_persistence: None,
            ..Config::default()
        };
        let mut runner =
            TestRunner::new_with_rng(config, TestRng::from_seed(RngAlgorithm::ChaCha, &seed));
        let cases = (0..bases.len(), mutations());
        let result = runner.run(&cases, |(k, changes)| {
            let bytes = mutate(&bases[k], &changes);
            match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| test(k, &bytes))) {
                Ok(()) => Ok(()),
                Err(_) => Err(TestCaseError::fail("panicked")),
            }
        });
        ran += u64::from(runner.config().cases);
        if let Err(e) = result {
            match e {
                TestError::Fail(why, changes) => {
                    panic!("{name}: {why} on {changes:?} (seed batch {batch})")
                }
                TestError::Abort(why) => panic!("{name}: aborted: {why}"),
            }
        }
        batch += 1;
        if budget.is_none_or(|b| start.elapsed() >= b) {
            break;
        }
    }
    if budget.is_some() {
        println!(
            "{name}: {ran} cases in {:.0} s, no panic",
            start.elapsed().as_secs_f64()
        );
    }
}

/// A file with `bytes` as `name` in a fresh folder, given to `read`.
fn as_file(name: &str, bytes: &[u8], read: impl FnOnce(&Path)) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    read(&path);
}

#[test]
fn any_pipeline_text_parses_and_validates_or_is_refused_without_a_panic() {
    let mut texts = vec![std::fs::read(root().join("pipeline.ron")).unwrap()];
    for name in scene_names() {
        texts.push(std::fs::read(scene_pipeline(&name)).unwrap());
    }
    let path = root().join("assets/pipelines/fuzzed.ron");
    fuzz("pipeline.ron", &texts, |_, bytes| {
        let text = String::from_utf8_lossy(bytes).into_owned();
        if let Ok(file) = crowd_core::config::PipelineFile::parse(&path, text) {
            // What the build asks of an accepted pipeline before any stage.
            let _ = file.output_dir();
        }
    });
}

/// The bands build the stage-file targets start from, and its graph.
fn bands() -> (&'static Path, PatchGraph) {
    let dir = scene("bands");
    (dir, PatchGraph::load(&dir.join("graph.ron")).unwrap())
}

fn read(dir: &Path, name: &str) -> Vec<u8> {
    std::fs::read(dir.join(name)).unwrap()
}

/// A copy of the build in `dir` with `name` replaced by `bytes`, given to `load`.
fn beside(dir: &Path, name: &str, bytes: &[u8], load: &dyn Fn(&Path)) {
    let tmp = tempfile::tempdir().unwrap();
    crate::util::copy_files(dir, tmp.path());
    let path = tmp.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    load(&path);
}

// Each stage file (RON) mutated beside its build's other files, or its side file mutated and
// handed to its decoder (past the hash check that would refuse it first).

#[test]
fn any_merge_file_is_read_or_refused_without_a_panic() {
    let (dir, graph) = bands();
    let mpp = graph.world.meters_per_pixel;
    let bases = [read(dir, "merge.ron"), read(dir, "merge.bin")];
    fuzz("merge", &bases, |k, b| {
        if k == 0 {
            beside(dir, "merge.ron", b, &|p| {
                let _ = crowd_core::maps::MergeFile::load(p);
            })
        } else {
            let _ = MergedMaps::from_bytes(Path::new("merge.bin"), mpp, b);
        }
    });
}

#[test]
fn any_graph_file_is_read_or_refused_without_a_panic() {
    let (dir, _) = bands();
    fuzz("graph", &[read(dir, "graph.ron")], |_, b| {
        as_file("graph.ron", b, |p| {
            let _ = PatchGraph::load(p);
        })
    });
}

#[test]
fn any_patterns_file_is_read_or_refused_without_a_panic() {
    let (dir, graph) = bands();
    let bases = [read(dir, "patterns.ron"), read(dir, "patterns.bin")];
    fuzz("patterns", &bases, |k, b| {
        if k == 0 {
            beside(dir, "patterns.ron", b, &|p| {
                let _ = Patterns::load_for(p, &graph);
            })
        } else {
            let _ = crowd_core::patterns::decode_crossings(Path::new("patterns.bin"), b);
        }
    });
}

#[test]
fn any_trajectories_file_of_stages_4_to_6_is_read_or_refused_without_a_panic() {
    let (dir, graph) = bands();
    let motion = [
        ("trajectories", "match"),
        ("collided", "collide"),
        ("smoothed", "smooth"),
    ];
    let bases: Vec<Vec<u8>> = motion
        .iter()
        .flat_map(|(f, _)| {
            [
                read(dir, &format!("{f}.ron")),
                read(dir, &format!("{f}.bin")),
            ]
        })
        .collect();
    fuzz("trajectories", &bases, |k, b| {
        let (file, stage) = motion[k / 2];
        if k % 2 == 0 {
            beside(dir, &format!("{file}.ron"), b, &|p| {
                if let Ok((_, m)) = TrajectoriesFile::load_stage(p, stage, version(stage)) {
                    let _ = check_motion(p, graph.patches.len(), &m);
                }
            })
        } else {
            let path = Path::new("motion.bin");
            if let Ok(m) = decode_motion(path, b) {
                let _ = check_motion(path, graph.patches.len(), &m);
            }
        }
    });
}

#[test]
fn any_export_manifest_is_read_or_refused_without_a_panic() {
    let (dir, _) = bands();
    fuzz("export.ron", &[read(dir, "export.ron")], |_, b| {
        beside(dir, "export.ron", b, &|p| {
            if let Ok(file) = crowd_core::files::read_ron::<crowd_export::ExportFile>(p) {
                let _ = (file.library_differs(p), file.gltf_differs(p));
            }
        })
    });
}

/// Stage `stage`'s format version, as the build reads it.
fn version(stage: &str) -> u32 {
    crowd::stages::STAGES
        .iter()
        .find(|s| s.kind == stage)
        .unwrap()
        .version
}

/// The runtime's loaders and sampler. The sections' checksums are made right again, so that
/// the mutations reach the checks behind them. Read from a file a piece at a time, a library
/// is the one of its bytes, or refused with the same error.
#[test]
fn any_library_is_loaded_or_refused_without_a_panic() {
    let (dir, _) = bands();
    fuzz("library.crowd", &[read(dir, "library.crowd")], |_, b| {
        let b = crate::export::with_fresh_checksums(b.to_vec());
        let loaded = crowd_runtime::Library::from_bytes(&b);
        let read = crowd_runtime::Library::read_from(std::io::Cursor::new(&b));
        assert_eq!(read, loaded, "read from a file, as from its bytes");
        crate::export::assert_opened_alike(&b, &loaded);
        if let Ok(lib) = loaded {
            let mut sampler = crowd_runtime::Sampler::new(&lib);
            let mut out = Vec::new();
            sampler.sample(3.0, [-1e9, -1e9, 1e9, 1e9], &mut out);
        }
    });
}

/// What `crowd check` gives its glTF reader for `graph`'s world.
fn glb_inputs<'a>(
    graph: &PatchGraph,
    walls: &'a [crowd_check::Wall],
) -> crowd_check::glb::Inputs<'a> {
    crowd_check::glb::Inputs {
        radius_m: graph.radius_m,
        walls,
        speed_limit_m_s: 1.9,
        world_m: graph.world.covered_m(),
    }
}

/// `crowd check`'s glTF reader and its figures.
#[test]
fn any_gltf_world_is_read_or_refused_without_a_panic() {
    let (dir, graph) = bands();
    let walls = crowd_check::walls(&graph);
    let inputs = glb_inputs(&graph, &walls);
    fuzz("world.glb", &[read(dir, "world.glb")], |_, b| {
        let _ = crowd_check::glb::figures(b, &inputs);
    });
}

/// What the long fuzz runs found, kept: a glTF whose JSON holds a value the `gltf` crate
/// parses as invalid but lets through its validation (an animation path, an interpolation)
/// is an error of `crowd check`, not a panic inside the crate.
#[test]
fn a_gltf_with_an_unknown_path_or_interpolation_is_an_error() {
    let (dir, graph) = bands();
    let walls = crowd_check::walls(&graph);
    let inputs = glb_inputs(&graph, &walls);
    let glb = read(dir, "world.glb");
    for (from, to, said) in [
        (
            &b"\"translation\""[..],
            &b"\"translatioX\""[..],
            "target path",
        ),
        (b"\"LINEAR\"", b"\"LINEAX\"", "interpolation"),
    ] {
        let at = glb.windows(from.len()).position(|w| w == from).unwrap();
        let mut bytes = glb.clone();
        bytes[at..at + from.len()].copy_from_slice(to);
        let e = crowd_check::glb::figures(&bytes, &inputs).unwrap_err();
        assert!(e.0.contains(said), "{e}");
    }
}
