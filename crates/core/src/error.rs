//! Errors that name the file, the place in it and what was expected.
//!
//! Bad input never panics: every stage returns one of these, and the command line prints it and
//! exits non-zero before anything already built is touched.

use std::fmt;
use std::io;
use std::path::{Path, PathBuf};

pub type Result<T, E = Error> = std::result::Result<T, E>;

/// A place in a text file, 1-based.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LineCol {
    pub line: usize,
    pub col: usize,
}

impl fmt::Display for LineCol {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.line, self.col)
    }
}

fn at(place: &Option<LineCol>) -> String {
    place.map(|p| format!(":{p}")).unwrap_or_default()
}

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The file system refused: a missing file, a folder that cannot be written.
    #[error("{}: cannot {action}: {cause}", path.display())]
    Io {
        path: PathBuf,
        action: &'static str,
        cause: io::Error,
    },
    /// A RON file that does not parse, or does not fit its type.
    #[error("{}:{place}: {message}", path.display())]
    Syntax {
        path: PathBuf,
        place: LineCol,
        message: String,
    },
    /// A setting that parses but is not allowed.
    #[error("{}{}: `{field}` {message}", path.display(), at(place))]
    Field {
        path: PathBuf,
        place: Option<LineCol>,
        field: String,
        message: String,
    },
    /// A layer image that cannot be used.
    #[error("{}: {message}", path.display())]
    Image { path: PathBuf, message: String },
    /// Settings and painted data that contradict each other (named through the settings file).
    #[error("{}{}: {message}", path.display(), at(place))]
    Scene {
        path: PathBuf,
        place: Option<LineCol>,
        message: String,
    },
    /// A stage file that is damaged, of another version, or of another stage.
    #[error("{}: {message}", path.display())]
    StageFile { path: PathBuf, message: String },
}

impl Error {
    pub fn io(path: &Path, action: &'static str, cause: io::Error) -> Error {
        Error::Io {
            path: path.to_path_buf(),
            action,
            cause,
        }
    }

    pub fn stage_file(path: &Path, message: impl Into<String>) -> Error {
        Error::StageFile {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }
}
