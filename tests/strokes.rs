//! A brush stroke rebuilt: with the painting read as people per m2 and stage 3 by region, a
//! stroke inside one region re-optimises that region alone, stages 4-6 compute again only the
//! patches whose inputs changed (at least 90 % are reused), and the rebuild writes the bytes
//! of a build from scratch of the new painting.

use crate::util::*;
use crowd_core::{Cell, PatchGraph};
use std::path::Path;

const SIDE: u32 = 16;

/// `city`'s layers, read as densities, in regions of 16 patches.
fn city_pipeline(dir: &Path) -> std::path::PathBuf {
    let layers = shared_scenes().join("city");
    for name in ["density", "static", "direction", "obstacles"] {
        let file = format!("{name}.png");
        std::fs::copy(layers.join(&file), dir.join(&file)).unwrap();
    }
    let text = format!(
        "(\n    scene: (\n        meters_per_pixel: 1.0,\n        layers: [\n            \
         (kind: Density, path: \"density.png\"),\n            (kind: Static, path: \
         \"static.png\"),\n            (kind: Direction, path: \"direction.png\"),\n            \
         (kind: Obstacles, path: \"obstacles.png\"),\n        ],\n    ),\n    people: \
         PerSquareMetre(walkers: 0.1, standers: 0.02),\n    patch_side_m: 8.0,\n    period_s: \
         20.0,\n    radius_m: 0.3,\n    seed: 1,\n    optimize: (region_patches: \
         Some({SIDE})),\n    output: \"out\",\n)\n"
    );
    let path = dir.join("pipeline.ron");
    std::fs::write(&path, text).unwrap();
    path
}

/// A patch whose four neighbours are patches of its own region, none on a seam: a disc over it
/// and them is a stroke inside one region.
fn inner_patch(graph: &PatchGraph) -> Cell {
    let inside = |c: Cell| {
        (1..SIDE - 1).contains(&(c.col % SIDE)) && (1..SIDE - 1).contains(&(c.row % SIDE))
    };
    graph
        .patches
        .iter()
        .map(|p| p.cell)
        .find(|&c| {
            inside(c)
                && [(1, 0), (-1, 0), (0, 1), (0, -1)].iter().all(|(dx, dy)| {
                    let n = Cell {
                        col: (c.col as i64 + dx) as u32,
                        row: (c.row as i64 + dy) as u32,
                    };
                    inside(n) && graph.patch_at(n).is_some()
                })
        })
        .expect("city has a patch inside a region")
}

/// Paints a disc of full density, 5 m in radius, at the middle of `cell` (8 m patches, 1 m
/// pixels, rows from the north): the patch and its four neighbours.
fn paint_disc(density: &Path, cell: Cell) {
    let mut image = image::open(density).unwrap().to_luma8();
    let h = image.height() as f64;
    let (cx, cy) = (
        cell.col as f64 * 8.0 + 4.0,
        h - (cell.row as f64 * 8.0 + 4.0),
    );
    for (x, y, p) in image.enumerate_pixels_mut() {
        let (dx, dy) = (x as f64 + 0.5 - cx, y as f64 + 0.5 - cy);
        if dx * dx + dy * dy <= 25.0 {
            p.0 = [255];
        }
    }
    image.save(density).unwrap();
}

/// What a build printed (its progress lines go to stderr).
fn said(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr)
}

/// The numbers in stage `stage`'s "N of M patches reused".
fn patches_reused(said: &str, stage: &str) -> (u32, u32) {
    let line = said
        .lines()
        .find(|l| l.trim_start().starts_with(&format!("{stage}:")) && l.contains("patches reused"))
        .unwrap_or_else(|| panic!("{stage} says what it reused:\n{said}"));
    let words: Vec<&str> = line.split_whitespace().collect();
    let at = words.iter().rposition(|w| *w == "of").unwrap();
    let number = |w: &str| {
        w.trim_matches(|c: char| !c.is_ascii_digit())
            .parse()
            .unwrap()
    };
    (number(words[at - 1]), number(words[at + 1]))
}

/// The number in "N of M regions optimised" of a build's output, and M.
fn regions_optimised(stdout: &str) -> (u32, u32) {
    let line = stdout
        .lines()
        .find(|l| l.contains("regions optimised"))
        .unwrap_or_else(|| panic!("stage 3 says how much it redid:\n{stdout}"));
    let words: Vec<&str> = line.split_whitespace().collect();
    let at = words.iter().position(|w| *w == "of").unwrap();
    let number = |w: &str| {
        w.trim_matches(|c: char| !c.is_ascii_digit())
            .parse()
            .unwrap()
    };
    (number(words[at - 1]), number(words[at + 1]))
}

#[test]
fn a_stroke_reuses_nine_patches_in_ten_and_rebuilds_the_bytes_of_a_fresh_build() {
    let dir = tempfile::tempdir().unwrap();
    let pipeline = city_pipeline(dir.path());
    let out = dir.path().join("out");
    let first = crowd_ok(&["build", "--pipeline", s(&pipeline)]);
    let (optimised, regions) = regions_optimised(&said(&first));
    assert_eq!((optimised, regions), (16, 16), "city is 50 x 50 patches");

    let graph = PatchGraph::load(&out.join("graph.ron")).unwrap();
    let cell = inner_patch(&graph);
    paint_disc(&dir.path().join("density.png"), cell);
    let again = crowd_ok(&["build", "--pipeline", s(&pipeline)]);
    let stdout = said(&again);
    assert_eq!(
        regions_optimised(&stdout),
        (1, 16),
        "a stroke at {cell:?} re-optimises its region alone:\n{stdout}"
    );
    // Stages 4-6 compute again only the patches whose inputs changed.
    let mut reused = Vec::new();
    for stage in ["match", "collide", "smooth"] {
        let (kept, total) = patches_reused(&stdout, stage);
        assert_eq!(total as usize, graph.patches.len());
        assert!(
            10 * kept >= 9 * total,
            "{stage} reused {kept} of {total} patches:\n{stdout}"
        );
        reused.push((stage, kept, total));
    }
    eprintln!("reused after the stroke: {reused:?}");
    // The check judges again only what the stroke reached, the rest from its memo (and writes
    // the bytes of a check from nothing, below).
    let judged = stdout
        .lines()
        .find(|l| l.trim_start().starts_with("check:"))
        .and_then(|l| l.split("judged again: ").nth(1))
        .unwrap_or_else(|| panic!("the check says what it judged again:\n{stdout}"));
    for part in judged.trim_end_matches(')').split(", ") {
        let words: Vec<&str> = part.split_whitespace().collect();
        let at = words.iter().position(|w| *w == "of").unwrap();
        let (done, of): (u32, u32) = (
            words[at - 1].parse().unwrap(),
            words[at + 1].parse().unwrap(),
        );
        assert!(10 * done <= of, "the check judged again {part}:\n{stdout}");
    }
    let changed = PatchGraph::load(&out.join("graph.ron")).unwrap();
    let moved: Vec<Cell> = graph
        .patches
        .iter()
        .zip(&changed.patches)
        .filter(|(a, b)| a.walker_density != b.walker_density)
        .map(|(a, _)| a.cell)
        .collect();
    assert!(
        (1..=5).contains(&moved.len()) && moved.contains(&cell),
        "the stroke changed the patches under it: {moved:?}"
    );

    // The same painting built from nothing, in another folder.
    let scratch = dir.path().join("scratch");
    crowd_ok(&[
        "build",
        "-q",
        "--pipeline",
        s(&pipeline),
        "--output",
        s(&scratch),
    ]);
    let files = snapshot(&scratch);
    assert!(files.len() > 10, "{} files", files.len());
    for (file, bytes) in files {
        let rebuilt = std::fs::read(out.join(&file)).unwrap();
        assert!(rebuilt == bytes, "{file} differs from a build from scratch");
    }

    // Every stage forced to run again with nothing changed reuses every region and patch.
    let forced = said(&crowd_ok(&["build", "--pipeline", s(&pipeline), "--force"]));
    assert_eq!(regions_optimised(&forced), (0, 16), "{forced}");
    for stage in ["match", "collide", "smooth"] {
        let (kept, total) = patches_reused(&forced, stage);
        assert_eq!(kept, total, "{stage}: {forced}");
    }
    for (file, bytes) in snapshot(&scratch) {
        assert!(
            std::fs::read(out.join(&file)).unwrap() == bytes,
            "{file} after --force"
        );
    }
}

/// The caches are only caches: cut, emptied or swapped between stages, a rebuild computes
/// everything again and writes the same bytes (the check's memo too).
#[test]
fn damaged_caches_are_missed_reuse_never_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let pipeline = city_pipeline(dir.path());
    let out = dir.path().join("out");
    crowd_ok(&["build", "-q", "--pipeline", s(&pipeline)]);
    let before = snapshot(&out);
    let cut = |name: &str| {
        let path = out.join(name);
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
    };
    cut("regions.bin");
    cut("trajectories.keys");
    cut("check.memo");
    std::fs::write(out.join("collided.keys"), b"").unwrap();
    std::fs::copy(out.join("trajectories.keys"), out.join("smoothed.keys")).unwrap();
    let again = said(&crowd_ok(&["build", "--pipeline", s(&pipeline), "--force"]));
    assert_eq!(regions_optimised(&again), (16, 16), "{again}");
    for stage in ["match", "collide", "smooth"] {
        assert_eq!(patches_reused(&again, stage).0, 0, "{stage}: {again}");
    }
    assert!(!again.contains("panicked"), "{again}");
    assert_eq!(snapshot(&out), before);
}
