//! The `crowd` command line as a library, so tests and benchmarks drive exactly what users run.

pub mod artifacts;
pub mod budget;
pub mod check;
pub mod check_shard;
pub mod cli;
pub mod driver;
pub mod edit;
pub mod edit_pictures;
pub mod edit_render;
pub mod flow_maps;
pub mod inspect;
pub mod memory;
pub mod report;
pub mod report_md;
pub mod reuse;
pub mod stage;
pub mod stages;
pub mod ui;
pub mod warnings;
