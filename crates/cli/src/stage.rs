//! What a stage is to the command line: one value that `crowd build`, the stage subcommands,
//! `--until`, `crowd check --stage`, the report and `timings.ron` all read. The stages
//! themselves, in build order, are the table in `stages.rs`; adding a stage is adding an entry
//! there.

use crate::artifacts::Artifacts;
use crate::ui::Ui;
use anyhow::Result;
use crowd_core::Hash;
use crowd_core::files::Writes;
use std::path::{Path, PathBuf};

/// One stage of the pipeline.
pub struct Stage {
    /// Its name in messages, `timings.ron`, `--until` and its subcommand (`crowd merge`).
    pub name: &'static str,
    /// Its number in DESIGN.md (1 merge ... 8 export).
    pub number: u8,
    /// The subcommand's one-line help.
    pub about: &'static str,
    /// The stage files it reads, in the build folder (the layers of the pipeline are read by
    /// merge). The last is the one a subcommand's `--input` replaces; the others are read
    /// beside it.
    pub reads: &'static [&'static str],
    /// Its file with the header (RON), in the build folder; side files are written beside it.
    pub output: &'static str,
    /// Every file it writes, `output` last.
    pub writes: &'static [&'static str],
    /// The stage name its file's header carries.
    pub kind: &'static str,
    /// Its format version: part of every hash, bumped when its algorithm or layout changes.
    pub version: u32,
    /// The hash of everything it reads: the input files' bytes and the settings.
    pub hash: fn(&mut Artifacts) -> Result<Hash>,
    /// Whether its file at the path is up to date for the hash; when it is, what the next
    /// stages need of it is kept in the artifacts. A file that cannot be read is stale; one that
    /// reads but does not fit its inputs is an error.
    pub fresh: fn(&mut Artifacts, &Path, Hash) -> Result<bool>,
    /// Runs it, writing into the path (and beside it): the files to write, and its result
    /// left in the artifacts for the next stage.
    pub run: fn(&mut Artifacts, &Path, Hash, &Ui) -> Result<Ran>,
    /// Whether a build of this pipeline runs it (stage 7 only when there are edits).
    pub applies: fn(&crowd_core::config::PipelineFile) -> bool,
}

/// What a stage run gives back.
pub struct Ran {
    /// Files written already to their temporary names, too large to hold (a gathering build's
    /// side file), put in place before `writes`.
    pub streamed: Vec<crowd_core::files::StreamedFile>,
    /// Files to write, as pieces one after another, that the stages after it read meanwhile
    /// (stage 6's side file, which export thins), put in place after `streamed` and before
    /// `writes`.
    pub shared: Vec<(PathBuf, std::sync::Arc<Vec<Vec<u8>>>)>,
    /// The files to write, side files before the file that names them.
    pub writes: Writes,
    /// A figure worth printing after the stage (stage 3's E).
    pub note: Option<String>,
    /// The seconds its parts took, by name (stage 7: each edit), for `timings.ron` as
    /// `"stage: part"`.
    pub parts: Vec<(String, f64)>,
    /// Hashes of files among `writes` that the stage made anyway (a side file's, the
    /// library's), told to `Hash::of_file` once the files are in place: the check after the
    /// build then does not read them again (painting: 530 MB).
    pub hashes: Vec<(PathBuf, Hash)>,
}

impl Ran {
    pub fn files(writes: Writes) -> Ran {
        Ran {
            streamed: Vec::new(),
            shared: Vec::new(),
            writes,
            note: None,
            parts: Vec::new(),
            hashes: Vec::new(),
        }
    }

    /// This run, knowing that the file it writes at `path` hashes to `hash`.
    pub fn knowing(mut self, path: PathBuf, hash: Hash) -> Ran {
        self.hashes.push((path, hash));
        self
    }

    /// The bytes written to `path`.
    pub fn bytes_of(&self, path: &Path) -> Option<&[u8]> {
        self.writes
            .iter()
            .find(|(p, _)| p == path)
            .map(|(_, b)| b.as_slice())
    }
}

impl Stage {
    /// The file a subcommand's `--input` replaces: the previous stage's.
    pub fn main_input(&self) -> Option<&'static str> {
        self.reads.last().copied()
    }
}

impl std::fmt::Debug for Stage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "stage {} ({})", self.number, self.name)
    }
}

impl PartialEq for Stage {
    fn eq(&self, other: &Stage) -> bool {
        self.name == other.name
    }
}

/// The stage called `name`.
pub fn named(name: &str) -> Option<&'static Stage> {
    crate::stages::STAGES
        .iter()
        .copied()
        .find(|s| s.name == name)
}

/// The stages in build order, up to and including `until` (all when `None`).
pub fn up_to(until: Option<&'static Stage>) -> impl Iterator<Item = &'static Stage> {
    let last = until.map_or(usize::MAX, |u| {
        crate::stages::STAGES
            .iter()
            .position(|s| *s == u)
            .unwrap_or(usize::MAX)
    });
    crate::stages::STAGES
        .iter()
        .copied()
        .take(last.saturating_add(1))
}

/// A clap value parser for stage names (`--until`), listing them in `--help`.
pub fn parser() -> impl clap::builder::TypedValueParser<Value = &'static Stage> {
    parser_among(&crate::stages::STAGES)
}

/// A clap value parser for the names of some stages only (`crowd check --stage` takes the
/// stages that write trajectories).
pub fn parser_among(
    stages: &'static [&'static Stage],
) -> impl clap::builder::TypedValueParser<Value = &'static Stage> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(stages.iter().map(|s| s.name))
        .map(|name: String| named(&name).expect("the parser only takes stage names"))
}
