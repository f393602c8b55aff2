//! Golden hashes: every output file of bands' build and check, byte for byte, against
//! `tests/golden/`.
//! A change to what a stage writes must be on purpose: it bumps that stage's `VERSION` (so old
//! files rebuild) and refreshes the list with `UPDATE_GOLDEN=1 cargo test --test tests golden`.

use crate::util::*;
use std::fmt::Write;

/// The stage (and its crate's `VERSION`) that writes a file of a build folder.
fn writer(file: &str) -> &'static str {
    let stem = file.split('.').next().unwrap_or(file);
    match stem {
        "merge" => "merge (crowd_core::maps::MergeFile::VERSION)",
        "graph" => "graph (crowd_core::PatchGraph::VERSION)",
        "patterns" | "optimize" => "optimize (crowd_core::patterns::Patterns::VERSION)",
        "trajectories" => "match (crowd_core::trajectories::TrajectoriesFile::VERSION)",
        "collided" => "collide (crowd_collide::VERSION)",
        "smoothed" => "smooth (crowd_smooth::VERSION)",
        "export" | "library" | "world" => "export (crowd_export::VERSION)",
        "check" => "`crowd check` (crates/check)",
        _ => "the report's pictures (crates/cli/src/report_md.rs)",
    }
}

/// `name  hash` lines, one per output file but `timings.ron` and `report.md`, sorted by name;
/// the hash is BLAKE3 (crowd_core::Hash, the one of the stage headers) of the file's bytes.
fn listing(dir: &std::path::Path) -> String {
    let mut text = String::new();
    for (name, bytes) in snapshot(dir) {
        let _ = writeln!(text, "{name}  {}", crowd_core::Hash::of(&bytes));
    }
    text
}

/// Bands, built whole by the run ([`scene`]) and checked (`check.ron`): each file's hash against
/// `tests/golden/bands.txt`. Transcendental functions come from the platform's libm, so the list
/// holds for the platform it was made on (x86-64 Linux, as CI).
#[test]
fn bands_writes_the_golden_bytes() {
    let path = root().join("tests/golden/bands.txt");
    let dir = copy_of("bands");
    crowd_ok(&["check", "-q", s(dir.path())]);
    let now = listing(dir.path());
    if std::env::var_os("UPDATE_GOLDEN").is_some() {
        std::fs::write(&path, &now).unwrap();
        eprintln!("wrote {}", path.display());
        return;
    }
    let golden = std::fs::read_to_string(&path).unwrap_or_else(|e| {
        panic!(
            "{}: {e}; make it with `UPDATE_GOLDEN=1 cargo test --test tests golden`",
            path.display()
        )
    });
    let parse = |text: &str| -> Vec<(String, String)> {
        text.lines()
            .filter_map(|l| l.split_once("  "))
            .map(|(n, h)| (n.to_string(), h.to_string()))
            .collect()
    };
    let (was, is) = (parse(&golden), parse(&now));
    let hash_in = |list: &[(String, String)], name: &str| {
        list.iter().find(|(n, _)| n == name).map(|(_, h)| h.clone())
    };
    let mut changes = Vec::new();
    for (name, hash) in &was {
        match hash_in(&is, name) {
            None => changes.push(format!("{name}: no longer written")),
            Some(h) if &h != hash => {
                changes.push(format!("{name}: changed (written by {})", writer(name)))
            }
            Some(_) => {}
        }
    }
    for (name, _) in &is {
        if hash_in(&was, name).is_none() {
            changes.push(format!("{name}: new"));
        }
    }
    assert!(
        changes.is_empty(),
        "bands' outputs differ from {}:\n  {}\nIf the change is meant, bump that stage's VERSION \
         (so older files rebuild) and refresh the list on purpose with \
         `UPDATE_GOLDEN=1 cargo test --test tests golden`.",
        path.display(),
        changes.join("\n  ")
    );
}
