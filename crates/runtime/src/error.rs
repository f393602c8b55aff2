//! Why a library was refused: always with the place in the bytes.

use std::fmt;

/// A library that cannot be played, and where it went wrong.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LoadError {
    /// The bytes end before something that should be there.
    Truncated {
        what: &'static str,
        offset: u64,
        needed: u64,
    },
    BadMagic,
    UnsupportedVersion(u32),
    MissingSection(&'static str),
    /// A section's bytes do not match the checksum in the section table.
    Checksum {
        section: &'static str,
    },
    /// The file could not be read ([`crate::Library::read_from`]), for this reason.
    Read(std::io::ErrorKind),
    /// A value that breaks the format's rules: which section, which record, what is wrong.
    Invalid {
        section: &'static str,
        index: u64,
        expected: &'static str,
    },
}

impl LoadError {
    pub(crate) fn read(e: std::io::Error) -> LoadError {
        LoadError::Read(e.kind())
    }
}

impl fmt::Display for LoadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LoadError::Truncated {
                what,
                offset,
                needed,
            } => write!(
                f,
                "truncated: {what} needs {needed} bytes at offset {offset}, past the end"
            ),
            LoadError::BadMagic => write!(
                f,
                "not a crowd library: the first 8 bytes are not the magic"
            ),
            LoadError::UnsupportedVersion(v) => {
                write!(
                    f,
                    "format version {v} is not supported (expected {})",
                    crate::VERSION
                )
            }
            LoadError::Read(kind) => write!(f, "cannot be read: {kind}"),
            LoadError::MissingSection(s) => write!(f, "the section table has no '{s}' section"),
            LoadError::Checksum { section } => {
                write!(f, "section '{section}' does not match its checksum")
            }
            LoadError::Invalid {
                section,
                index,
                expected,
            } => write!(
                f,
                "section '{section}', record {index}: expected {expected}"
            ),
        }
    }
}

impl std::error::Error for LoadError {}
