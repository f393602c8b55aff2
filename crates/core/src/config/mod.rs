//! `pipeline.ron`: what to build and how.
//!
//! Unknown fields are errors (with the nearest valid name suggested), and every value is checked
//! before any stage runs, with the line and column of the offending field: each settings struct
//! has its own `validate`, which `Pipeline::validate` calls.
//!
//! - `pipeline.rs`: `Pipeline` (the schema's top level) and `PipelineFile` (load, parse, check,
//!   paths);
//! - `settings.rs`: each stage's settings struct, its defaults and its `validate`;
//! - `edits.rs`: the moments stage 7 edits in (`Edit`, `EditKind`) and their checks;
//! - `checks.rs`: the field checks they are made of (`Invalid` names the field path);
//! - `ron_text.rs`: RON errors in words, and where a field is written.

mod checks;
mod edits;
mod pipeline;
mod ron_text;
mod settings;

pub use checks::{Check, Invalid, Num};
pub use edits::{
    DEFAULT_Q, Edit, EditKind, EditLimits, MAX_MEET_PEOPLE, MAX_VORTICITY, check_edits_on_map,
    validate_edits,
};
pub use pipeline::{LayerKind, LayerSpec, People, Pipeline, PipelineFile, Scene};
pub use settings::{
    CollideSettings, ExportSettings, GraphSettings, MatchSettings, MergeSettings, OptimizeSettings,
    SmoothSettings,
};

#[cfg(test)]
mod tests;
