//! `crowd view`: the page's own reader of `library.crowd` against crowd-runtime, and the page
//! itself in headless Chromium (Debian's `chromium`, driven by playwright-core; `.ci/run`
//! installs both).

use crate::util::*;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

/// `node viewer/test/SCRIPT ARGS`, its stdout as JSON.
fn viewer_node(script: &str, args: &[&str]) -> serde_json::Value {
    let dir = root().join("viewer");
    assert!(
        dir.join("node_modules").is_dir(),
        "{}: run `npm ci --prefix viewer` first (.ci/run does)",
        dir.display()
    );
    let output = Command::new("node")
        .arg(dir.join("test").join(script))
        .args(args)
        .output()
        .expect("node runs");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "{script} failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_str(stdout.trim())
        .unwrap_or_else(|e| panic!("{script}: not JSON ({e}):\n{stdout}"))
}

/// Every character at `times`, by id, as crowd-runtime samples them.
fn runtime_positions(library: &Path, times: &[f64]) -> Vec<Vec<(f32, f32)>> {
    let bytes = std::fs::read(library).unwrap();
    let lib = crowd_runtime::Library::from_bytes(&bytes).unwrap();
    let mut sampler = crowd_runtime::Sampler::new(&lib);
    let mut out = Vec::new();
    let everywhere = [f32::MIN, f32::MIN, f32::MAX, f32::MAX];
    times
        .iter()
        .map(|&t| {
            sampler.sample(t, everywhere, &mut out);
            let mut frame = vec![(f32::NAN, f32::NAN); sampler.characters()];
            for s in &out {
                frame[s.id as usize] = (s.x, s.y);
            }
            frame
        })
        .collect()
}

/// The page's reader and sampler (viewer/src, run by Node) put every character of `city` and
/// `ring` where crowd-runtime does, to 1 mm, at times forward, past the period, and back.
#[test]
fn the_viewers_reader_finds_every_character_where_crowd_runtime_does() {
    let times = [0.0, 0.016, 7.3, 13.917, 19.9999, 45.25, 3.0, 131.7];
    let args: Vec<String> = times.iter().map(|t| t.to_string()).collect();
    for name in ["city", "ring"] {
        let library = scene(name).join("library.crowd");
        let mut argv = vec![s(&library)];
        argv.extend(args.iter().map(String::as_str));
        let js = viewer_node("positions.mjs", &argv);
        let rust = runtime_positions(&library, &times);
        assert_eq!(js["characters"].as_u64().unwrap() as usize, rust[0].len());
        let mut worst = 0.0f64;
        for (k, frame) in js["frames"].as_array().unwrap().iter().enumerate() {
            let xy = frame["xy"].as_array().unwrap();
            for (id, &(x, y)) in rust[k].iter().enumerate() {
                let (jx, jy) = (
                    xy[2 * id].as_f64().unwrap(),
                    xy[2 * id + 1].as_f64().unwrap(),
                );
                let d = (jx - f64::from(x)).hypot(jy - f64::from(y));
                assert!(
                    d <= 1e-3,
                    "{name}: character {id} at t = {} s: viewer ({jx}, {jy}), runtime ({x}, {y})",
                    times[k]
                );
                worst = worst.max(d);
            }
        }
        eprintln!("{name}: largest distance {worst:.2e} m");
    }
}

/// The reader refuses a damaged library with what is wrong, as the Rust loader does.
#[test]
fn the_viewers_reader_names_what_is_wrong_with_a_damaged_library() {
    let good = std::fs::read(scene("bands").join("library.crowd")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut flipped = good.clone();
    let last = flipped.len() - 3;
    flipped[last] ^= 0x55;
    let mut magic = good.clone();
    magic[0] = b'X';
    let cases: [(&str, Vec<u8>, &str); 3] = [
        (
            "cut",
            good[..good.len() / 2].to_vec(),
            "past the end of the file",
        ),
        ("flipped", flipped, "checksum"),
        ("magic", magic, "not a crowd library"),
    ];
    for (name, bytes, expected) in cases {
        let path = dir.path().join(format!("{name}.crowd"));
        std::fs::write(&path, bytes).unwrap();
        let js = viewer_node("positions.mjs", &[s(&path), "0"]);
        let error = js["error"].as_str().unwrap_or_default();
        assert!(error.contains(expected), "{name}: {js}");
        assert!(crowd_runtime::Library::from_bytes(&std::fs::read(&path).unwrap()).is_err());
    }
}

/// `crowd view DIR --no-open` running, and its address.
struct Viewing {
    child: Child,
    address: String,
}

impl Viewing {
    fn start(dir: &Path) -> Viewing {
        let mut child = Command::new(env!("CARGO_BIN_EXE_crowd"))
            .args(["view", s(dir), "--no-open"])
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("crowd view starts");
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        let address = line
            .split_whitespace()
            .find(|w| w.starts_with("http://127.0.0.1:"))
            .unwrap_or_else(|| panic!("no address in {line:?}"))
            .to_string();
        Viewing { child, address }
    }
}

impl Drop for Viewing {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn chromium() {
    assert!(
        Path::new("/usr/bin/chromium").exists(),
        "/usr/bin/chromium: install Debian's chromium first (.ci/run does)"
    );
}

/// Where the viewer's screenshots go: `docs/pictures/viewer/` with `UPDATE_SCREENSHOTS=1`
/// (the README shows those), the test's own folder otherwise.
fn screenshot_path(name: &str, tmp: &Path) -> PathBuf {
    match std::env::var_os("UPDATE_SCREENSHOTS") {
        Some(_) => {
            let dir = root().join("docs/pictures/viewer");
            std::fs::create_dir_all(&dir).unwrap();
            dir.join(format!("{name}.png"))
        }
        None => tmp.join(format!("{name}.png")),
    }
}

/// The page loads a built scene, shows every character of the library, moves them with time,
/// its patch-grid toggle changes the picture, and a click on a patch shows its crossings and
/// space-time plot (zoomed in there, the characters out of view are not drawn); a screenshot
/// of each scene.
#[test]
fn the_viewer_plays_city_and_ring_in_headless_chromium() {
    chromium();
    let tmp = tempfile::tempdir().unwrap();
    // A part of each, near enough to see the people: a city street corner, a side of the ring.
    for (name, region) in [("city", "64,0,136,48"), ("ring", "20,40,92,88")] {
        let dir = scene(name);
        let viewing = Viewing::start(dir);
        let shot = screenshot_path(name, tmp.path());
        let seen = viewer_node("e2e.mjs", &["play", &viewing.address, s(&shot), region]);
        assert_eq!(seen["ready"], true, "{name}: {seen}");
        let bytes = std::fs::read(dir.join("library.crowd")).unwrap();
        let lib = crowd_runtime::Library::from_bytes(&bytes).unwrap();
        let count = crowd_runtime::Sampler::new(&lib).characters();
        assert_eq!(seen["stats"]["characters"], count, "{name}: {seen}");
        assert_eq!(seen["stats"]["drawn"], count, "{name}: {seen}");
        let changed = |key: &str| seen[key].as_u64().unwrap();
        assert!(
            changed("timesDiffer") > 100,
            "{name}: t = 2 s and 9 s look alike: {seen}"
        );
        assert_eq!(
            changed("sameTimeDiffers"),
            0,
            "{name}: one time, two pictures: {seen}"
        );
        assert!(
            changed("gridDiffers") > 100,
            "{name}: the grid toggle shows nothing: {seen}"
        );
        assert_eq!(
            changed("gridOffDiffers"),
            0,
            "{name}: the grid stays: {seen}"
        );
        // A click on a patch: its crossings and its space-time plot.
        let panel = &seen["panel"];
        assert_eq!(panel["shown"], true, "{name}: {seen}");
        assert!(
            panel["title"]
                .as_str()
                .unwrap_or_default()
                .starts_with("Patch 0"),
            "{name}: {panel}"
        );
        assert!(panel["crossings"].as_u64().unwrap() > 0, "{name}: {panel}");
        // Zoomed in on that patch, only the characters in view are drawn.
        let drawn = seen["zoomed"]["drawn"].as_u64().unwrap();
        assert!(
            drawn > 0 && drawn < count as u64 / 4,
            "{name}: {drawn} of {count} drawn"
        );
        assert_eq!(panel["plot"], true, "{name}: {panel}");
        let picture = image::open(&shot).unwrap();
        assert!(picture.width() >= 1000, "{name}: no screenshot");
    }
}

/// A corrupt library is a readable error on the page, not a blank screen.
#[test]
fn the_viewer_shows_what_is_wrong_with_a_corrupt_library() {
    chromium();
    let dir = copy_of("bands");
    let path = dir.path().join("library.crowd");
    let mut bytes = std::fs::read(&path).unwrap();
    let last = bytes.len() - 3;
    bytes[last] ^= 0x55;
    std::fs::write(&path, bytes).unwrap();
    let viewing = Viewing::start(dir.path());
    let seen = viewer_node("e2e.mjs", &["broken", &viewing.address]);
    assert_eq!(seen["ready"], false, "{seen}");
    let shown = seen["shown"].as_str().unwrap_or_default();
    assert!(
        shown.contains("library.crowd cannot be played") && shown.contains("checksum"),
        "{seen}"
    );
}

/// The bundle `crowd view` serves is what `viewer/src` and the pinned three.js give.
#[test]
fn the_served_bundle_is_built_from_the_viewers_sources() {
    let dir = root().join("viewer");
    assert!(
        dir.join("node_modules").is_dir(),
        "run `npm ci --prefix viewer` first"
    );
    let output = Command::new("node")
        .arg(dir.join("bundle.mjs"))
        .arg("--check")
        .output()
        .expect("node runs");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
}
