//! Tidy tests (as rust-analyzer has): the house rules that keep the code map true, checked on
//! every `cargo test --workspace`. Each failure says what to change.
//!
//! - every crate under `crates/` is named in ARCHITECTURE.md, and every source file too (by
//!   file name; `lib.rs`, `main.rs`, `mod.rs` and `tests.rs` are implied by their crate);
//! - every source file opens with a `//!` comment that says why it exists;
//! - no crate depends on a stage crate, except where ARCHITECTURE.md justifies it by a paper
//!   (`JUSTIFIED`).

use std::fs;
use std::path::{Path, PathBuf};

/// Crates a stage may take besides the shared ones, and why (ARCHITECTURE.md says the same).
const JUSTIFIED: &[(&str, &str, &str)] = &[
    (
        "crowd-optimize",
        "crowd-match",
        "Crowd Art measures a patch's density by matching its crossings (stage 4)",
    ),
    (
        "crowd-export",
        "crowd-runtime",
        "the library is written in the runtime's own format (FORMAT.md)",
    ),
    (
        "crowd-check",
        "crowd-runtime",
        "the check reads what ships as an engine does, through the runtime",
    ),
    (
        "crowd-moments",
        "crowd-edit",
        "stage 7 is Allain's optimal crowd editing, whose model, adjoint and descents crowd-edit is",
    ),
];

/// Crates every stage may use: the vocabulary and the space-time geometry.
const SHARED: &[&str] = &["crowd-core", "crowd-geometry"];

/// The crates the command line glues together; only it may depend on all of them.
const GLUE: &str = "crowd";

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("xtask lives in the workspace")
        .to_path_buf()
}

fn architecture() -> String {
    fs::read_to_string(root().join("ARCHITECTURE.md")).expect("ARCHITECTURE.md is readable")
}

/// Every `.rs` file under `dir`, sorted.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    let mut entries: Vec<PathBuf> = entries.map(|e| e.unwrap().path()).collect();
    entries.sort();
    for path in entries {
        let name = path.file_name().unwrap().to_string_lossy();
        if path.is_dir() && name != "target" && !name.starts_with('.') {
            rust_files(&path, out);
        } else if name.ends_with(".rs") {
            out.push(path);
        }
    }
}

fn sources() -> Vec<PathBuf> {
    let mut files = Vec::new();
    for dir in ["crates", "xtask", "tests", "fuzz"] {
        rust_files(&root().join(dir), &mut files);
    }
    assert!(files.len() > 50, "found only {} source files", files.len());
    files
}

/// The crate folders under `crates/`.
fn crate_dirs() -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> = fs::read_dir(root().join("crates"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("Cargo.toml").exists() || p.join("src").is_dir())
        .collect();
    dirs.sort();
    dirs
}

/// The `crowd-*` packages named in a manifest's `[dependencies]` (not dev- or build-).
fn stage_dependencies(manifest: &str) -> Vec<String> {
    let mut in_deps = false;
    let mut deps = Vec::new();
    for line in manifest.lines().map(str::trim) {
        if line.starts_with('[') {
            in_deps = line == "[dependencies]";
        } else if in_deps && line.starts_with("crowd-") {
            let name = line.split(['.', '=', ' ']).next().unwrap();
            deps.push(name.to_string());
        }
    }
    deps
}

fn package_name(manifest: &str) -> String {
    manifest
        .lines()
        .find_map(|l| l.trim().strip_prefix("name = "))
        .map(|n| n.trim_matches('"').to_string())
        .expect("every crate has a package name")
}

#[test]
fn every_crate_is_in_the_code_map() {
    let map = architecture();
    for dir in crate_dirs() {
        let name = dir.file_name().unwrap().to_string_lossy();
        assert!(
            map.contains(&format!("`crates/{name}`")),
            "ARCHITECTURE.md's code map has no entry `crates/{name}`: say what the crate does, \
             what goes in and out, and the type to read first"
        );
    }
}

#[test]
fn every_source_file_is_named_in_the_code_map() {
    let map = architecture();
    let implied = ["lib.rs", "main.rs", "mod.rs", "tests.rs"];
    let missing: Vec<String> = sources()
        .iter()
        .filter(|p| !p.starts_with(root().join("fuzz")))
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .filter(|name| !implied.contains(&name.as_str()) && !map.contains(name.as_str()))
        .collect();
    assert!(
        missing.is_empty(),
        "ARCHITECTURE.md does not name these source files; add each to its crate's entry: \
         {missing:?}"
    );
}

#[test]
fn every_source_file_opens_with_a_doc_comment() {
    let missing: Vec<String> = sources()
        .iter()
        .filter(|p| {
            let text = fs::read_to_string(p).unwrap();
            let first = text.lines().find(|l| !l.trim().is_empty());
            !first.is_some_and(|l| l.starts_with("//!"))
        })
        .map(|p| p.strip_prefix(root()).unwrap().display().to_string())
        .collect();
    assert!(
        missing.is_empty(),
        "these files do not open with a `//!` comment saying why they exist: {missing:?}"
    );
}

#[test]
fn no_crate_depends_on_a_stage_unless_a_paper_says_so() {
    let mut wrong = Vec::new();
    for dir in crate_dirs() {
        let Ok(manifest) = fs::read_to_string(dir.join("Cargo.toml")) else {
            continue;
        };
        let package = package_name(&manifest);
        if package == GLUE {
            continue;
        }
        for dep in stage_dependencies(&manifest) {
            let justified = JUSTIFIED.iter().any(|(p, d, _)| *p == package && *d == dep);
            if !SHARED.contains(&dep.as_str()) && !justified {
                wrong.push(format!("{package} -> {dep}"));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "stages reach into each other: {wrong:?}; move what they share into crowd-core or \
         crowd-geometry, or justify the dependency by a paper in ARCHITECTURE.md and JUSTIFIED"
    );
    let map = architecture();
    for (package, dep, _) in JUSTIFIED {
        assert!(
            map.contains(&format!("{package} -> {dep}")),
            "ARCHITECTURE.md's dependency picture should show (and justify) {package} -> {dep}"
        );
    }
}
