//! The library's points kept in a scratch file as stage 8 makes them ([`Spill`]), so that a
//! gathering build never holds the world's (the million's 0.77 GB): `world.glb`'s headings
//! read a loop's back a trajectory at a time ([`LoopPoints`]), and `library.crowd` copies them
//! in their place ([`Spilled::copy_to`]).

use crate::ExportError;
use crate::library::PointSink;
use crowd_core::files::read_at;
use crowd_runtime::Point;
use crowd_runtime::crc::Crc32;
use crowd_runtime::turn::{FirstFailure, LoopPoints};
use std::io::Write;

/// Points written to a scratch file as they are made, with their bytes' checksum.
pub struct Spill {
    file: std::io::BufWriter<std::fs::File>,
    count: usize,
    crc: Crc32,
    bytes: Vec<u8>,
}

impl Spill {
    /// A scratch file in `dir` (removed when it is dropped, whatever happens).
    pub fn create_in(dir: &std::path::Path) -> Result<Spill, ExportError> {
        let file = tempfile::tempfile_in(dir).map_err(ExportError::Scratch)?;
        Ok(Spill {
            file: std::io::BufWriter::with_capacity(1 << 20, file),
            count: 0,
            crc: Crc32::new(),
            bytes: Vec::new(),
        })
    }

    /// The points written, to be read back.
    pub fn finish(self) -> Result<Spilled, ExportError> {
        let file = self.file.into_inner().map_err(|e| e.into_error());
        Ok(Spilled {
            file: file.map_err(ExportError::Scratch)?,
            count: self.count,
            crc: self.crc.finish(),
            failed: FirstFailure::default(),
        })
    }
}

impl PointSink for Spill {
    fn held(&self) -> usize {
        self.count
    }

    fn take(&mut self, points: &[Point]) -> Result<(), ExportError> {
        self.bytes.clear();
        for p in points {
            self.bytes.extend_from_slice(&p.to_le_bytes());
        }
        self.crc.update(&self.bytes);
        self.count += points.len();
        self.file
            .write_all(&self.bytes)
            .map_err(ExportError::Scratch)
    }
}

/// The points of a [`Spill`], in a file of their PNTS bytes, read from any thread.
#[derive(Debug)]
pub struct Spilled {
    file: std::fs::File,
    count: usize,
    crc: u32,
    /// The first read of the file that failed, for [`Spilled::failure`]: the heading model
    /// reads a loop's points through [`LoopPoints`], which cannot fail.
    failed: FirstFailure<std::io::Error>,
}

/// Bytes copied from the scratch file at a time.
const COPY_BYTES: usize = 4 << 20;

/// Loops of this many keys or more have their headings made a window of runs at a time from
/// the scratch file ([`LoopPoints::stream_keys`]), their keys never all at once: the held
/// library's threshold, 8 million keys, would hold 0.2 GB of them.
const STREAM_KEYS: usize = 1 << 20;

impl Spilled {
    /// How many points, and their bytes' checksum (the PNTS section's).
    pub fn section(&self) -> (usize, u32) {
        (self.count, self.crc)
    }

    /// `n` points from point `first`.
    pub fn read(&self, first: usize, n: usize) -> std::io::Result<Vec<Point>> {
        if first + n > self.count {
            return Err(std::io::Error::new(
                std::io::ErrorKind::UnexpectedEof,
                format!("points {first}..{} of {}", first + n, self.count),
            ));
        }
        let mut bytes = vec![0u8; n * Point::BYTES];
        read_at(&self.file, &mut bytes, (first * Point::BYTES) as u64)?;
        Ok(bytes
            .chunks_exact(Point::BYTES)
            .map(Point::from_le_bytes)
            .collect())
    }

    /// The first read that failed since the file was written, if one did: what was read
    /// through [`LoopPoints`] is then not the points.
    pub fn failure(&self) -> std::io::Result<()> {
        self.failed.take()
    }

    /// Every point's bytes, handed to `sink` a piece at a time.
    pub fn copy_to<E: From<std::io::Error>>(
        &self,
        sink: &mut dyn FnMut(&[u8]) -> Result<(), E>,
    ) -> Result<(), E> {
        let total = self.count * Point::BYTES;
        let mut piece = vec![0u8; COPY_BYTES.min(total)];
        let mut at = 0;
        while at < total {
            let piece = &mut piece[..COPY_BYTES.min(total - at)];
            read_at(&self.file, piece, at as u64)?;
            sink(piece)?;
            at += piece.len();
        }
        Ok(())
    }
}

/// A loop's points read back a trajectory at a time, as `world.glb`'s headings walk the loop:
/// the million's longest loop holds 0.34 GB of them.
impl LoopPoints for Spilled {
    fn with<R>(&self, first: u32, n: u32, read: impl FnOnce(&[Point]) -> R) -> R {
        (self.failed).hand(self.read(first as usize, n as usize), n, read)
    }

    fn stream_keys(&self) -> usize {
        STREAM_KEYS
    }
}
