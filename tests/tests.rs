//! End-to-end tests: the real `crowd` binary on the shared scenes and on real broken files.
//! Each shipped scene is built once per run and shared read-only (`util::scene`); a test that
//! changes files works in its own temporary folder.

mod util;

mod bad_input;
mod build;
mod check;
mod edit;
mod export;
mod export_clip;
mod fuzz;
mod golden;
mod hostile;
mod kill;
mod moments;
mod paintings;
mod patterns;
mod scenes;
mod settings;
mod shards;
mod strokes;
mod view;
mod warnings;
