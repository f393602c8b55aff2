//! Stage 8's library, played by crowd-runtime: what an engine gets is what stage 6 made,
//! within the error `export.ron` states, and every character walks on without a jump.

use crate::util::*;
use crowd_core::trajectories::TrajectoriesFile;
use crowd_runtime::{Library, LibraryFile, Sample, Sampler, TICK_S};
use proptest::prelude::*;
use std::path::Path;
use std::sync::OnceLock;

/// What the runtime's f32 world coordinates, and times rounded to 0.05 ms at up to 2 m/s, may
/// add to the library's stated position error, metres.
const F32_ALLOWANCE_M: f64 = 1.5e-4;

/// `export.ron`'s stated worst-case position error of the library against stage 6, metres.
fn stated_position_error(out: &Path) -> f64 {
    let text = std::fs::read_to_string(out.join("export.ron")).unwrap();
    let file: crowd_export::ExportFile = ron::from_str(&text).unwrap();
    file.position_error_m
}

fn library(out: &Path) -> Library {
    Library::from_bytes(&std::fs::read(out.join("library.crowd")).unwrap()).unwrap()
}

fn smoothed(out: &Path) -> Vec<crowd_core::trajectories::PatchMotion> {
    let (stage, version) = (crowd_smooth::STAGE, crowd_smooth::VERSION);
    TrajectoriesFile::load_stage(&out.join("smoothed.ron"), stage, version)
        .unwrap()
        .1
}

const EVERYWHERE: [f32; 4] = [-1e9, -1e9, 1e9, 1e9];

#[test]
fn every_scene_but_painting_exports_a_library_that_loads_with_every_walker_and_stander() {
    for name in ["bands", "center-flow", "city", "lanes", "ring"] {
        let out = scene(name);
        let lib = library(out);
        let motion = smoothed(out);
        let standers: usize = motion.iter().map(|m| m.standers.len()).sum();
        let walker_time: f64 = motion
            .iter()
            .flat_map(|m| &m.trajectories)
            .map(|t| t.duration())
            .sum();
        // Each walker spends one period in the world per period: walker-time / period walkers.
        let walkers = (walker_time / lib.period_s()).round() as u64;
        assert_eq!(lib.walkers(), walkers, "{name}");
        assert_eq!(lib.standers.len(), standers, "{name}");
        let mut sampler = Sampler::new(&lib);
        let mut seen = Vec::new();
        sampler.sample(3.25, EVERYWHERE, &mut seen);
        assert_eq!(seen.len() as u64, walkers + standers as u64, "{name}");
    }
}

/// Stage 6's keyframes, and where the runtime puts somebody at their times: within the stated
/// error of all of them, and within the quantisation alone of those export kept.
#[test]
fn sampling_at_the_keyframes_gives_stage_6_positions_within_the_stated_error() {
    let out = scene("city");
    let stated = stated_position_error(out);
    // The default drops keyframes within 0.75 mm, and quantises city's 8 m patches to 0.061 mm.
    assert!(stated > 7.5e-4 && stated < 1e-3, "{stated}");
    let graph = crowd_core::PatchGraph::load(&out.join("graph.ron")).unwrap();
    let lib = library(out);
    let motion = smoothed(out);
    let (checked, worst) = worst_at_keyframes(&graph, &lib, &motion, stated + F32_ALLOWANCE_M);
    assert!(checked > 1000, "{checked}");
    eprintln!("{checked} keyframes, worst {worst:.2e} m (stated {stated:.2e} m)");

    let kept = crowd_export::simplify::motion(motion.clone(), 0.75e-3);
    let quantisation = graph.world.patch_side_m * crowd_export::library::POSITION_ERROR_SHARE;
    // A kept keyframe is off by quantisation, and by a tick's walk where export eased its time.
    let eased = stated - 0.75e-3 - quantisation;
    let (checked, worst) =
        worst_at_keyframes(&graph, &lib, &kept, quantisation + eased + F32_ALLOWANCE_M);
    assert!(checked > 500, "{checked}");
    eprintln!("{checked} kept keyframes, worst {worst:.2e} m (quantisation {quantisation:.2e} m)");
}

/// Samples every fifth keyframe of every third trajectory of every thirteenth patch of
/// `motion`, asserting each within `tolerance` metres of the nearest character: how many, and
/// the worst distance.
fn worst_at_keyframes(
    graph: &crowd_core::PatchGraph,
    lib: &Library,
    motion: &[crowd_core::trajectories::PatchMotion],
    tolerance: f64,
) -> (usize, f64) {
    let mut sampler = Sampler::new(lib);
    let mut seen = Vec::new();
    let mut checked = 0;
    let mut worst: f64 = 0.0;
    for (p, m) in motion.iter().enumerate().step_by(13) {
        let origin = graph.world_from_patch(graph.patches[p].cell);
        for tr in m.trajectories.iter().step_by(3) {
            for cp in tr.points.iter().step_by(5) {
                let at = origin + cp.pos;
                let e = 1e-3;
                let view = [
                    (at.x - e) as f32,
                    (at.y - e) as f32,
                    (at.x + e) as f32,
                    (at.y + e) as f32,
                ];
                sampler.sample(cp.t, view, &mut seen);
                let nearest = seen
                    .iter()
                    .map(|s| (f64::from(s.x) - at.x).hypot(f64::from(s.y) - at.y))
                    .fold(f64::INFINITY, f64::min);
                assert!(nearest <= tolerance, "patch {p} at {}: {nearest}", cp.t);
                worst = worst.max(nearest);
                checked += 1;
            }
        }
    }
    (checked, worst)
}

/// Every character, frame after frame over three periods: never a step longer than the
/// fastest walk allows, across patch borders and period ends alike.
#[test]
fn every_character_walks_on_continuously_across_patches_and_periods() {
    let lib = library(scene("ring"));
    let mut fastest: f64 = 0.0;
    for t in &lib.trajectories {
        let patch = &lib.patches[t.patch as usize];
        for w in lib.points_of(t).windows(2) {
            let (a, b) = (
                lib.world_position(patch, w[0]),
                lib.world_position(patch, w[1]),
            );
            if w[1].t > w[0].t {
                let d = (b[0] - a[0]).hypot(b[1] - a[1]);
                fastest = fastest.max(d / (f64::from(w[1].t - w[0].t) * TICK_S));
            }
        }
    }
    let dt = 1.0 / 30.0;
    let frames = (3.0 * lib.period_s() / dt) as usize;
    let mut sampler = Sampler::new(&lib);
    let (mut before, mut now): (Vec<Sample>, Vec<Sample>) = (Vec::new(), Vec::new());
    sampler.sample(0.0, EVERYWHERE, &mut before);
    for f in 1..=frames {
        sampler.sample(f as f64 * dt, EVERYWHERE, &mut now);
        assert_eq!(now.len(), before.len());
        for (a, b) in before.iter().zip(&now) {
            assert_eq!(a.id, b.id);
            let step = f64::from(b.x - a.x).hypot(f64::from(b.y - a.y));
            assert!(
                step <= fastest * dt + 1e-3,
                "character {} jumps {step} m at frame {f}",
                a.id
            );
        }
        std::mem::swap(&mut before, &mut now);
    }
}

#[test]
fn a_frame_is_the_same_whether_time_ran_forward_to_it_or_jumped_there() {
    let lib = library(scene("bands"));
    let mut walked = Sampler::new(&lib);
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for f in 0..=900 {
        walked.sample(f as f64 / 30.0, EVERYWHERE, &mut a);
    }
    for t in [30.0, 1e4 + 30.0 - 500.0 * lib.period_s()] {
        Sampler::new(&lib).sample(t, EVERYWHERE, &mut b);
        assert_eq!(a.len(), b.len());
        for (x, y) in a.iter().zip(&b) {
            assert_eq!(x.id, y.id);
            assert!(
                (x.x - y.x).abs() < 1e-3 && (x.y - y.y).abs() < 1e-3,
                "{x:?} {y:?}"
            );
        }
    }
    // And back in time: the sampler searches instead of walking.
    walked.sample(1.0, EVERYWHERE, &mut a);
    Sampler::new(&lib).sample(1.0, EVERYWHERE, &mut b);
    assert_eq!(a.len(), b.len());
    assert!(a.iter().zip(&b).all(|(x, y)| x == y), "the same samples");
}

/// A library opened on its file plays a run of its loops, read alone ([`LibraryFile::loops`]),
/// to the bit as the whole library plays those walkers; and that run is a library the runtime
/// loads as it is.
#[test]
fn a_run_of_loops_read_from_the_file_plays_as_the_whole_library_plays_them() {
    let lib = library(scene("city"));
    let bytes = std::fs::read(scene("city").join("library.crowd")).unwrap();
    let file = LibraryFile::open(std::io::Cursor::new(&bytes)).expect("city's library opens");
    let n = lib.characters.len();
    let firsts: Vec<u32> = (lib.characters.iter())
        .scan(0, |next, ch| {
            let first = *next;
            *next += ch.laps;
            Some(first)
        })
        .collect();
    let mut all = Sampler::new(&lib);
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for run in [0..n / 3, n / 3..n / 3 + 1, n / 3 + 1..n] {
        let part = file.loops(run.clone()).expect("city's loops read");
        assert_eq!(
            part,
            lib.loops(run.clone()),
            "read from the file as from memory"
        );
        assert_eq!(Library::from_bytes(&part.to_bytes()).as_ref(), Ok(&part));
        assert_eq!(
            part.walkers(),
            lib.characters[run.clone()]
                .iter()
                .map(|c| u64::from(c.laps))
                .sum::<u64>()
        );
        let first = firsts[run.start];
        let mut played = Sampler::new(&part);
        for t in (0..300).map(|f| f as f64 / 10.0).chain([1e3]) {
            all.sample(t, EVERYWHERE, &mut a);
            played.sample(t, EVERYWHERE, &mut b);
            assert_eq!(b.len() as u64, part.walkers(), "no standers: t = {t}");
            for s in &b {
                let whole = a[(first + s.id) as usize];
                assert_eq!(
                    (s.x, s.y, s.heading),
                    (whole.x, whole.y, whole.heading),
                    "t = {t}"
                );
            }
        }
    }
}

/// A library opened on its file ([`LibraryFile::open`]) holds the records of the library of
/// its bytes but the points, and reads each trajectory's points as they are there; or it is
/// refused with the same error.
pub(crate) fn assert_opened_alike(
    bytes: &[u8],
    loaded: &Result<Library, crowd_runtime::LoadError>,
) {
    match (LibraryFile::open(std::io::Cursor::new(bytes)), loaded) {
        (Err(e), Err(l)) => assert_eq!(&e, l),
        (Ok(file), Ok(lib)) => {
            let index = Library {
                points: Vec::new(),
                ..lib.clone()
            };
            assert_eq!(file.index(), &index);
            let n = lib.trajectories.len();
            let window = file.window(0..n).expect("its points read");
            for (i, t) in lib.trajectories.iter().enumerate() {
                assert_eq!(window.points_of(i, t), Some(lib.points_of(t)));
            }
            let half = file.window(n / 2..n).expect("half its points read");
            assert_eq!(
                half.points_of(0, &lib.trajectories[0]),
                None.filter(|_| n > 1)
            );
            let part = file.loops(0..lib.characters.len()).expect("its loops read");
            assert_eq!(part.walkers(), lib.walkers());
            assert_eq!(Library::from_bytes(&part.to_bytes()).as_ref(), Ok(&part));
        }
        (opened, loaded) => panic!(
            "opened {:?}, loaded {:?}",
            opened.map(|_| ()),
            loaded.as_ref().map(|_| ())
        ),
    }
}

/// `Sampler::playing` (what `crowd check` plays again after a brush stroke) places each of its
/// walkers to the bit where `Sampler::new` places it, frame after frame and after a jump.
#[test]
fn a_sampler_of_some_walkers_places_them_as_the_sampler_of_all() {
    let lib = library(scene("city"));
    let some: Vec<u32> = (0..lib.walkers() as u32).filter(|w| w % 7 == 3).collect();
    assert!(some.len() > 10);
    let headings = crowd_runtime::turn::library_headings(&lib);
    let mut part = Sampler::playing(&lib, headings, &some).expect("walkers of the library");
    let mut all = Sampler::new(&lib);
    let (mut a, mut b) = (Vec::new(), Vec::new());
    let times = (0..600).map(|f| f as f64 / 30.0).chain([7.5, 1e3]);
    for t in times {
        all.sample(t, EVERYWHERE, &mut a);
        part.sample(t, EVERYWHERE, &mut b);
        assert_eq!(b.len(), some.len(), "t = {t}");
        for (i, s) in b.iter().enumerate() {
            let whole = a[some[i] as usize];
            assert_eq!(whole.id, some[i]);
            assert_eq!(
                (s.id, s.x, s.y, s.heading),
                (i as u32, whole.x, whole.y, whole.heading),
                "t = {t}"
            );
        }
    }
    assert!(
        Sampler::playing(
            &lib,
            crowd_runtime::turn::library_headings(&lib),
            &[lib.walkers() as u32]
        )
        .is_none()
    );
}

const BY_SIZE: crowd_export::Handing = crowd_export::Handing::BySize;
const RECORDS: crowd_export::Handing = crowd_export::Handing::Records;

/// A library's bytes as stage 8 handed it over.
fn bytes_of(library: crowd_export::LibraryBytes) -> Vec<u8> {
    match library {
        crowd_export::LibraryBytes::Held(bytes) => bytes,
        crowd_export::LibraryBytes::Records(lib) => lib.to_bytes(),
        crowd_export::LibraryBytes::Handed(..) => panic!("its bytes were handed over"),
        crowd_export::LibraryBytes::Spilled(lib, spilled) => {
            let mut bytes = Vec::new();
            let points = |sink: &mut dyn FnMut(&[u8]) -> std::io::Result<()>| spilled.copy_to(sink);
            lib.write_with_points(spilled.section(), points, |piece| {
                bytes.extend_from_slice(piece);
                Ok(())
            })
            .expect("the scratch file reads back");
            bytes
        }
    }
}

/// A library written a piece at a time (as a build writes a large one) is the bytes of it
/// written whole, and of the file stage 8 wrote; and its stated size is theirs.
#[test]
fn a_library_written_a_piece_at_a_time_is_the_library_written_whole() {
    for name in ["bands", "city", "ring"] {
        let file = std::fs::read(scene(name).join("library.crowd")).unwrap();
        let lib = Library::from_bytes(&file).unwrap();
        let mut pieces = Vec::new();
        let mut count = 0;
        lib.write_to(|piece| {
            pieces.extend_from_slice(piece);
            count += 1;
            Ok::<(), ()>(())
        })
        .unwrap();
        assert!(
            pieces == file,
            "{name}: the pieces differ from library.crowd"
        );
        assert!(
            lib.to_bytes() == file,
            "{name}: to_bytes differs from library.crowd"
        );
        assert_eq!(lib.byte_len(), file.len(), "{name}");
        // The header, then each section's pieces: city's and ring's points take more than one.
        let pieces = |n: usize| n.div_ceil(1 << 18);
        let points_pieces = pieces(lib.points.len());
        let others = [
            lib.patches.len(),
            lib.standers.len(),
            lib.crossings.len(),
            lib.trajectories.len(),
            lib.characters.len(),
        ];
        let expected = 1 + 2 + others.map(pieces).iter().sum::<usize>() + points_pieces;
        assert_eq!(count, expected, "{name}");
        assert!(name == "bands" || points_pieces > 1, "{name}");
        // A sink that fails stops the writing there.
        let mut handed = 0;
        let failed = lib.write_to(|_| {
            handed += 1;
            if handed == 3 {
                Err("disk full")
            } else {
                Ok(())
            }
        });
        assert_eq!((failed, handed), (Err("disk full"), 3), "{name}");
    }
}

fn bands_library() -> &'static Vec<u8> {
    static BYTES: OnceLock<Vec<u8>> = OnceLock::new();
    BYTES.get_or_init(|| std::fs::read(scene("bands").join("library.crowd")).unwrap())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// A corrupt or cut library is refused with an error, or (where the change is one the
    /// format cannot see, such as a position) plays: never a panic. Read from a file a piece
    /// at a time, it is the same library or the same error.
    #[test]
    fn flipped_or_truncated_bytes_never_panic(
        flips in proptest::collection::vec((any::<prop::sample::Index>(), 1u8..=255), 0..8),
        cut in proptest::option::of(any::<prop::sample::Index>()),
        fix_checksums in any::<bool>(),
    ) {
        let mut bytes = bands_library().clone();
        for (at, x) in &flips {
            let i = at.index(bytes.len());
            bytes[i] ^= x;
        }
        if let Some(cut) = cut {
            bytes.truncate(cut.index(bytes.len()));
        }
        if fix_checksums {
            // Corruption that checksums cannot catch: the checks behind them must.
            bytes = with_fresh_checksums(bytes);
        }
        let loaded = Library::from_bytes(&bytes);
        // Read from a file a piece at a time: the same library, or the same error.
        let read = Library::read_from(std::io::Cursor::new(&bytes));
        prop_assert_eq!(&read, &loaded);
        assert_opened_alike(&bytes, &loaded);
        if let Ok(lib) = loaded {
            let mut s = Sampler::new(&lib);
            let mut out = Vec::new();
            for t in [0.0, 7.5, -3.0, 1e6] {
                s.sample(t, EVERYWHERE, &mut out);
            }
        }
    }
}

/// Where a library's PNTS section is named in its table, and its offset and length.
fn points_section(bytes: &[u8]) -> (usize, u64, u64) {
    let count = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let entry = (0..count)
        .map(|e| 16 + 24 * e)
        .find(|&at| &bytes[at..at + 4] == b"PNTS")
        .expect("a PNTS entry");
    let word = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
    (entry, word(entry + 8), word(entry + 16))
}

/// `bytes` with every section's checksum recomputed, where the table is readable.
pub(crate) fn with_fresh_checksums(mut bytes: Vec<u8>) -> Vec<u8> {
    if bytes.len() < 16 {
        return bytes;
    }
    let count = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    for e in 0..count.min(64) {
        let at = 16 + 24 * e;
        if at + 24 > bytes.len() {
            break;
        }
        let offset = u64::from_le_bytes(bytes[at + 8..at + 16].try_into().unwrap());
        let len = u64::from_le_bytes(bytes[at + 16..at + 24].try_into().unwrap());
        let Some(end) = offset.checked_add(len) else {
            continue;
        };
        if end as usize > bytes.len() {
            continue;
        }
        let crc = crowd_runtime::crc32(&bytes[offset as usize..end as usize]);
        bytes[at + 4..at + 8].copy_from_slice(&crc.to_le_bytes());
    }
    bytes
}

/// The tools in `tools/gltf` (installed by `.ci/run`: `npm ci --prefix tools/gltf`).
fn node_tool(script: &str, args: &[&str]) -> std::process::Output {
    let dir = root().join("tools/gltf");
    assert!(
        dir.join("node_modules").is_dir(),
        "{}: run `npm ci --prefix tools/gltf` first (.ci/run does)",
        dir.display()
    );
    std::process::Command::new("node")
        .arg(dir.join(script))
        .args(args)
        .output()
        .expect("node runs")
}

/// world.glb, checked by the Khronos validator and read back by glTF Transform: one node per
/// walker and stander, a clip of one period, and positions at a few times where crowd-runtime
/// puts the same characters (within 1 mm; both are made from the same keyframes, and the library
/// adds its 0.06 mm quantisation).
#[test]
fn world_glb_validates_and_an_independent_reader_finds_our_characters_where_we_do() {
    let out = scene("city");
    let glb = out.join("world.glb");
    let validated = node_tool("validate.mjs", &[s(&glb)]);
    let text = String::from_utf8_lossy(&validated.stdout);
    assert!(validated.status.success(), "{text}");
    assert!(text.contains("0 errors, 0 warnings"), "{text}");

    let lib = library(out);
    let mut sampler = Sampler::new(&lib);
    let (mut seen, mut samples) = (Vec::new(), Vec::new());
    for t in [0.0, 3.3, 9.95, 17.0, lib.period_s()] {
        sampler.sample(t, EVERYWHERE, &mut seen);
        let walkers = lib.walkers() as u32;
        for c in seen.iter().filter(|c| c.id < walkers).step_by(97) {
            samples.push(serde_json::json!({
                "node": format!("walker_{}", c.id),
                "t": t,
                "pos": [c.x, 0.0, -c.y],
            }));
        }
    }
    let expected = serde_json::json!({
        "nodes": lib.walkers() + lib.standers.len() as u64,
        "period": lib.period_s(),
        "samples": samples,
    });
    let dir = tempfile::tempdir().unwrap();
    let expected_path = dir.path().join("expected.json");
    std::fs::write(&expected_path, expected.to_string()).unwrap();
    let read = node_tool("read_back.mjs", &[s(&glb), s(&expected_path)]);
    let text = String::from_utf8_lossy(&read.stdout);
    assert!(
        read.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&read.stderr)
    );
    eprintln!("{text}");
}

/// `crowd inspect export.ron` loads the library as an engine would, and names the file and
/// the section when it is corrupt.
#[test]
fn inspect_checks_the_library_and_names_a_corrupt_section() {
    let dir = copy_of("bands");
    let out = dir.path();
    let manifest = out.join("export.ron");
    let text = String::from_utf8(crowd_ok(&["inspect", s(&manifest)]).stdout).unwrap();
    assert!(text.contains("loads and checks: 1105 walkers"), "{text}");
    assert!(text.contains("world.glb"), "{text}");
    let path = out.join("library.crowd");
    let mut bytes = std::fs::read(&path).unwrap();
    let at = bytes.len() / 2;
    bytes[at] ^= 0x40;
    std::fs::write(&path, bytes).unwrap();
    let failed = crowd(&["inspect", s(&manifest)]);
    assert!(!failed.status.success());
    let err = String::from_utf8_lossy(&failed.stderr);
    assert!(
        err.contains("library.crowd") && err.contains("does not match its checksum"),
        "{err}"
    );
}

/// `crowd export --region` puts part of the world in the glTF (still valid), keeps the whole
/// world in the library, and refuses a region that is not one.
#[test]
fn export_region_puts_part_of_the_world_in_the_gltf() {
    let dir = copy_of("bands");
    let out = dir.path();
    let pipeline = scene_pipeline("bands");
    let (p, i, o) = (
        s(&pipeline),
        out.join("smoothed.ron"),
        out.join("export.ron"),
    );
    let export = |region: &str| {
        crowd(&[
            "export",
            "-q",
            "--pipeline",
            p,
            "-i",
            s(&i),
            "-o",
            s(&o),
            "--region",
            region,
        ])
    };
    assert!(export("0,0,40,40").status.success());
    let text = String::from_utf8(crowd_ok(&["inspect", s(&o)]).stdout).unwrap();
    assert!(text.contains("loads and checks: 1105 walkers"), "{text}");
    assert!(
        text.contains("the characters in x 0-40 m, y 0-40 m"),
        "{text}"
    );
    let validated = node_tool("validate.mjs", &[s(&out.join("world.glb"))]);
    let report = String::from_utf8_lossy(&validated.stdout);
    assert!(report.contains("0 errors, 0 warnings"), "{report}");
    for bad in ["40,0,0,40", "0,0,40", "0,0,40,4O"] {
        let failed = export(bad);
        assert!(!failed.status.success(), "{bad}");
        let err = String::from_utf8_lossy(&failed.stderr);
        assert!(
            err.contains("--region") && err.contains("expected"),
            "{bad}: {err}"
        );
    }
}

/// `world.glb` of every shared scene played by three.js (`tools/gltf/play.mjs`: GLTFLoader, an
/// AnimationMixer looping `crowd_loop`, two periods at 60 fps), as a game shows it: every node
/// names its successor (painting's region: every node its character is still shown in at the
/// seam), no node turns faster than 360 degrees a second between frames, and following
/// `crowd_next` at each wrap, a character goes on through the seam with no gap beyond a
/// frame's walk, no faster turn, and no larger change of velocity from frame to frame than
/// inside the nodes (the walks' own corners, which stage 6 takes over a tenth of a second: at
/// most 2.6 m/s a frame inside nodes, where a hurried walk cannot ease into its band or stage 6
/// keeps a corner whose smoothed walk would come too close: ring's walker_2295 turns 120
/// degrees at 1.5 m/s at t = 18.68 s on its way to a pause, 2.52 m/s).
#[test]
fn world_glb_played_by_three_js_turns_like_people_and_goes_on_through_the_seam() {
    for name in ["bands", "center-flow", "lanes", "ring", "city", "painting"] {
        let glb = scene(name).join("world.glb");
        let out = node_tool("play.mjs", &[s(&glb)]);
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{name}: {text} {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let f: serde_json::Value = serde_json::from_str(text.lines().next().unwrap()).unwrap();
        let num = |k: &str| {
            f[k].as_f64()
                .unwrap_or_else(|| panic!("{name}: {k} in {f}"))
        };
        if name != "painting" {
            assert_eq!(num("named"), num("nodes"), "{name}: {f}");
        }
        assert!(
            num("largest_velocity_change_per_frame_m_s") <= 2.6,
            "{name}: {f}"
        );
        assert!(num("fastest_turn_deg_s") <= 360.0 * 1.005, "{name}: {f}");
        assert!(
            num("seam_fastest_turn_deg_s") <= 360.0 * 1.005,
            "{name}: {f}"
        );
        assert!(num("seam_gap_beyond_a_walk_m") < 1e-3, "{name}: {f}");
        assert!(
            num("seam_largest_velocity_change_m_s")
                <= num("largest_velocity_change_per_frame_m_s") + 1e-6,
            "{name}: {f}"
        );
        eprintln!("{name}: {f}");
    }
}

/// The library says how fast its characters turn (`TURN`, optional: a library without it plays
/// at 360 degrees a second), and a rate outside 30-3600 is refused with the section named.
#[test]
fn the_turn_rate_section_is_read_defaulted_and_checked() {
    let bytes = std::fs::read(scene("bands").join("library.crowd")).unwrap();
    let lib = Library::from_bytes(&bytes).unwrap();
    assert_eq!(lib.world.turn_rate_deg_s, 360.0);
    // The section's entry, and its body.
    let count = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let entry = (0..count)
        .map(|e| 16 + 24 * e)
        .find(|&at| &bytes[at..at + 4] == b"TURN")
        .expect("a TURN section");
    let offset = u64::from_le_bytes(bytes[entry + 8..entry + 16].try_into().unwrap()) as usize;
    // Renamed to a tag no reader knows: the default.
    let mut unnamed = bytes.clone();
    unnamed[entry..entry + 4].copy_from_slice(b"XXXX");
    let lib = Library::from_bytes(&unnamed).unwrap();
    assert_eq!(lib.world.turn_rate_deg_s, 360.0);
    // Out of range, checksum fixed: refused, naming the section.
    let mut fast = bytes.clone();
    fast[offset..offset + 4].copy_from_slice(&5000f32.to_le_bytes());
    let err = Library::from_bytes(&with_fresh_checksums(fast)).unwrap_err();
    assert!(err.to_string().contains("TURN"), "{err}");
}

/// A gathering build's export reads each patch of the final motion when it asks for it (from
/// the file, thinned again each time) and holds only the patches whose loops its glTF region
/// may show: it must write the bytes of the export that holds the whole world thinned.
#[test]
fn export_made_patch_by_patch_writes_what_export_of_the_held_motion_writes() {
    use crowd_export::motion::{Made, Summaries};
    for name in ["city", "ring"] {
        let out = scene(name);
        let graph = crowd_core::PatchGraph::load(&out.join("graph.ron")).unwrap();
        let (_, crossings) =
            crowd_core::patterns::Patterns::load(&out.join("patterns.ron")).unwrap();
        let (stage, version) = (crowd_smooth::STAGE, crowd_smooth::VERSION);
        let patches = graph.patches.len();
        let (_, lazy) =
            TrajectoriesFile::open_for(&out.join("smoothed.ron"), stage, version, patches).unwrap();
        let size = graph.world.size_m;
        // The whole world, and a quarter of it.
        for region in [None, Some((0.0, 0.0, size.x / 2.0, size.y / 2.0))] {
            let inputs = crowd_export::Inputs {
                period_s: 20.0,
                seed: 7,
                settings: crowd_core::config::ExportSettings {
                    gltf_region: region,
                    simplify_mm: 0.75,
                    turn_rate_deg_s: 360.0,
                },
            };
            let tolerance = crowd_export::tolerance_m(&inputs);
            let hash = crowd_core::Hash::of(name.as_bytes());
            let held = crowd_export::simplify::motion(smoothed(out), tolerance);
            let whole =
                crowd_export::export(&graph, crossings.clone(), &held, &inputs, hash, BY_SIZE)
                    .unwrap();
            let made = Made::new(lazy.patches(), |p| {
                Ok(crowd_export::simplify::patch(lazy.patch(p)?, tolerance))
            });
            let part =
                crowd_export::export(&graph, crossings.clone(), &made, &inputs, hash, RECORDS)
                    .unwrap();
            // A gathering build's: the points kept in a scratch file as they are made, and the
            // glTF's loops read back from it one at a time.
            let scratch = tempfile::tempdir().unwrap();
            let spilled = crowd_export::Handing::Spilled(scratch.path());
            let spilled =
                crowd_export::export(&graph, crossings.clone(), &made, &inputs, hash, spilled)
                    .unwrap();
            // Handed over as soon as made: the same bytes, and the size and hash they have.
            let handed_bytes = std::sync::Mutex::new(Vec::new());
            let hand = |bytes: Vec<u8>, hash: crowd_core::Hash| {
                assert_eq!(hash, crowd_core::Hash::of(&bytes), "handed with their hash");
                *handed_bytes.lock().unwrap() = bytes;
            };
            let handed = crowd_export::Handing::Handed(&hand);
            let handed =
                crowd_export::export(&graph, crossings.clone(), &held, &inputs, hash, handed)
                    .unwrap();
            let handed_bytes = handed_bytes.into_inner().unwrap();
            let crowd_export::LibraryBytes::Handed(size, bytes_hash) = handed.library else {
                panic!("{name} {region:?}: a small library's bytes are handed over");
            };
            assert_eq!(
                (size, bytes_hash),
                (
                    handed_bytes.len() as u64,
                    crowd_core::Hash::of(&handed_bytes)
                )
            );
            assert_eq!(whole.manifest, handed.manifest, "{name} {region:?}");
            assert!(
                whole.glb == handed.glb,
                "{name} {region:?}: world.glb differs"
            );
            let (writes, _) = crowd_export::writes(Path::new("out/export.ron"), handed).unwrap();
            let names: Vec<_> = writes.iter().map(|w| w.0.clone()).collect();
            assert_eq!(
                names,
                [Path::new("out/world.glb"), Path::new("out/export.ron")]
            );
            assert_eq!(whole.manifest, part.manifest, "{name} {region:?}");
            assert_eq!(whole.manifest, spilled.manifest, "{name} {region:?}");
            let whole_bytes = bytes_of(whole.library);
            assert!(
                whole_bytes == handed_bytes,
                "{name} {region:?}: library.crowd differs, handed over"
            );
            assert!(
                whole_bytes == bytes_of(part.library),
                "{name} {region:?}: library.crowd differs"
            );
            assert!(
                whole_bytes == bytes_of(spilled.library),
                "{name} {region:?}: library.crowd differs, its points spilled"
            );
            assert!(
                whole.glb == part.glb && whole.glb == spilled.glb,
                "{name} {region:?}: world.glb differs"
            );
            // With a region, city's patches far from it are never read for the glTF (ring's
            // loops go round the ring, each near the region once a lap).
            let summaries = Summaries::of(&graph, &made).unwrap();
            let links = crowd_export::characters::link(&held, crossings.len()).unwrap();
            let (library, _) = crowd_export::library::build(
                &graph, &crossings, &held, &summaries, &links, 20.0, 7, [0; 8],
            )
            .unwrap();
            let world = crowd_export::glb::World {
                graph: &graph,
                summaries: &summaries,
                motion: &made,
                links: &links,
                period_s: 20.0,
                seed: 7,
                input_hash: String::new(),
                region,
                library: crowd_export::glb::LibraryRef::Held(&library),
            };
            let read = crowd_export::glb::patches_read(&world)
                .iter()
                .filter(|&&r| r)
                .count();
            let walked = held.iter().filter(|m| !m.trajectories.is_empty()).count();
            match region {
                None => assert_eq!(read, walked, "{name}"),
                Some(_) => assert!(read < walked, "{name}: {read} of {walked} patches read"),
            }
        }
    }
}

/// A library read from a file a piece at a time is the library of its bytes, and a file that
/// fails as it is read says so instead of loading part of it.
#[test]
fn a_library_read_from_a_file_is_the_library_of_its_bytes() {
    let bytes = bands_library();
    let whole = Library::from_bytes(bytes).expect("bands' library loads");
    let path = scene("bands").join("library.crowd");
    let file = std::fs::File::open(&path).expect("bands' library");
    assert_eq!(Library::read_from(file), Ok(whole));
    /// A file whose reads fail after `good` bytes.
    struct Failing<'a>(std::io::Cursor<&'a [u8]>, u64);
    impl std::io::Read for Failing<'_> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            if self.0.position() >= self.1 {
                return Err(std::io::Error::other("the disk went away"));
            }
            self.0.read(buf)
        }
    }
    impl std::io::Seek for Failing<'_> {
        fn seek(&mut self, to: std::io::SeekFrom) -> std::io::Result<u64> {
            self.0.seek(to)
        }
    }
    let failing = Failing(std::io::Cursor::new(bytes), bytes.len() as u64 / 2);
    let opened = LibraryFile::open(Failing(std::io::Cursor::new(bytes), bytes.len() as u64 / 2));
    assert_eq!(
        opened.map(|_| ()),
        Err(crowd_runtime::LoadError::Read(std::io::ErrorKind::Other))
    );
    let err = Library::read_from(failing).expect_err("half a file is no library");
    assert_eq!(
        err,
        crowd_runtime::LoadError::Read(std::io::ErrorKind::Other)
    );
    assert!(err.to_string().contains("cannot be read"), "{err}");
}

/// A library written with its points handed over from elsewhere (stage 8's scratch file, a
/// piece at a time) is the bytes of the library written whole.
#[test]
fn a_library_written_with_its_points_from_elsewhere_is_the_same_bytes() {
    let bytes = bands_library();
    let lib = Library::from_bytes(bytes).expect("bands' library loads");
    let (_, at, len) = points_section(bytes);
    let points = &bytes[at as usize..(at + len) as usize];
    let index = Library {
        points: Vec::new(),
        ..lib.clone()
    };
    let mut out = Vec::new();
    let handed = |sink: &mut dyn FnMut(&[u8]) -> Result<(), ()>| {
        points.chunks(1000).try_for_each(&mut *sink)
    };
    let crc = crowd_runtime::crc32(points);
    let written = index.write_with_points((lib.points.len(), crc), handed, |piece| {
        out.extend_from_slice(piece);
        Ok(())
    });
    assert_eq!(written, Ok(()));
    assert_eq!(&out, bytes);
}

/// A library opened on its file reads its points when asked: if the file changed meanwhile
/// under a trajectory, that trajectory's points are refused by name, never played.
#[test]
fn points_changed_in_the_file_after_it_was_opened_are_refused() {
    use std::io::{Seek, SeekFrom, Write};
    let bytes = bands_library();
    let lib = Library::from_bytes(bytes).expect("bands' library loads");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("library.crowd");
    std::fs::write(&path, bytes).unwrap();
    let file = LibraryFile::open(std::fs::File::open(&path).unwrap()).expect("it opens");
    let n = lib.trajectories.len();
    assert!(file.window(0..n).is_ok());
    // Trajectory 1's last point made earlier than the one before it.
    let (_, at, _) = points_section(bytes);
    let t = &lib.trajectories[1];
    let last = u64::from(t.first_point + t.points - 1);
    let mut f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    f.seek(SeekFrom::Start(at + last * 8 + 4)).unwrap();
    f.write_all(&0u32.to_le_bytes()).unwrap();
    drop(f);
    let refused = crowd_runtime::LoadError::Invalid {
        section: "PNTS",
        index: 1,
        expected: "the points its trajectory had when the library was opened",
    };
    assert_eq!(file.window(0..n), Err(refused.clone()));
    assert_eq!(
        file.loops(0..lib.characters.len()).map(|_| ()),
        Err(refused)
    );
    assert!(
        file.window(2..n).is_ok(),
        "the other trajectories read as before"
    );
}

/// A section one byte short of whole records is refused for its checksum first, then (with the
/// checksum made right) for its records, whichever way the library is read.
#[test]
fn a_section_of_part_of_a_record_is_refused_the_same_way_from_a_file() {
    let mut bytes = bands_library().clone();
    let (entry, _, len) = points_section(&bytes);
    bytes[entry + 16..entry + 24].copy_from_slice(&(len - 1).to_le_bytes());
    let both = |bytes: &[u8]| {
        let loaded = Library::from_bytes(bytes);
        assert_eq!(Library::read_from(std::io::Cursor::new(bytes)), loaded);
        assert_opened_alike(bytes, &loaded);
        loaded.expect_err("part of a record is no library")
    };
    use crowd_runtime::LoadError;
    assert_eq!(both(&bytes), LoadError::Checksum { section: "PNTS" });
    let whole = len / 8 - 1;
    let invalid = LoadError::Invalid {
        section: "PNTS",
        index: whole,
        expected: "whole records",
    };
    assert_eq!(both(&with_fresh_checksums(bytes)), invalid);
}
