//! The library's points kept in a scratch file as stage 8 makes them ([`Spill`]), so that a
//! gathering build never holds the world's (the million's 0.77 GB): `world.glb` reads a loop's
//! back at a time ([`Spilled::loop_library`]), and `library.crowd` copies them in their place
//! ([`Spilled::copy_to`]).

use crate::ExportError;
use crate::library::PointSink;
use crowd_runtime::crc::Crc32;
use crowd_runtime::{Library, Point, Trajectory};
use std::io::{Read, Seek, SeekFrom, Write};
use std::sync::Mutex;

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
            file: Mutex::new(file.map_err(ExportError::Scratch)?),
            count: self.count,
            crc: self.crc.finish(),
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

/// The points of a [`Spill`], in a file of their PNTS bytes.
#[derive(Debug)]
pub struct Spilled {
    file: Mutex<std::fs::File>,
    count: usize,
    crc: u32,
}

/// Points read back from the scratch file at a time for a loop's library.
const BLOCK_POINTS: usize = 1 << 17;

/// Bytes copied from the scratch file at a time.
const COPY_BYTES: usize = 4 << 20;

impl Spilled {
    /// How many points, and their bytes' checksum (the PNTS section's).
    pub fn section(&self) -> (usize, u32) {
        (self.count, self.crc)
    }

    /// `n` points from point `first`.
    pub fn read(&self, first: usize, n: usize) -> std::io::Result<Vec<Point>> {
        let mut bytes = vec![0u8; n * Point::BYTES];
        let mut file = self.file.lock().unwrap_or_else(|e| e.into_inner());
        file.seek(SeekFrom::Start((first * Point::BYTES) as u64))?;
        file.read_exact(&mut bytes)?;
        Ok(bytes
            .chunks_exact(Point::BYTES)
            .map(Point::from_le_bytes)
            .collect())
    }

    /// The library of loop `lp` of `index` (whose points these are) alone
    /// ([`Library::loops`]).
    pub fn loop_library(&self, index: &Library, lp: usize) -> std::io::Result<Library> {
        // Its trajectories are asked for in the file's order: read a block at a time (one
        // read a trajectory was a quarter of the million's export).
        let mut block: (usize, Vec<Point>) = (0, Vec::new());
        let read = |_, t: &Trajectory| {
            let (first, n) = (t.first_point as usize, t.points as usize);
            if first < block.0 || first + n > block.0 + block.1.len() {
                let len = n.max(BLOCK_POINTS).min(self.count.saturating_sub(first));
                block = (first, self.read(first, len.max(n))?);
            }
            let at = first - block.0;
            Ok(block.1[at..at + n].to_vec())
        };
        index.loops_with(lp..lp + 1, read)
    }

    /// Every point's bytes, handed to `sink` a piece at a time.
    pub fn copy_to<E: From<std::io::Error>>(
        &self,
        sink: &mut dyn FnMut(&[u8]) -> Result<(), E>,
    ) -> Result<(), E> {
        let mut file = self.file.lock().unwrap_or_else(|e| e.into_inner());
        file.seek(SeekFrom::Start(0))?;
        let mut left = self.count * Point::BYTES;
        let mut piece = vec![0u8; COPY_BYTES.min(left)];
        while left > 0 {
            let piece = &mut piece[..COPY_BYTES.min(left)];
            file.read_exact(piece)?;
            sink(piece)?;
            left -= piece.len();
        }
        Ok(())
    }
}
