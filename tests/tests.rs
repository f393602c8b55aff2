//! End-to-end tests: the real `crowd` binary on the shared scenes and on real broken files.
//! Each test works in its own temporary folder.

mod util;

mod bad_input;
mod build;
mod export;
mod patterns;
mod scenes;
mod settings;
