//! Reading a library: from bytes in memory ([`Library::from_bytes`]) or from a file a piece at
//! a time ([`Library::read_from`]), the same checks in the same order either way. Nothing read
//! is trusted: every slice is bounded by the bytes there, every checksum checked, as many whole
//! records read as a section holds, then the library handed to the rules.

use super::container::{
    CHARACTERS, CROSSINGS, ENTRY_LEN, HEADER_LEN, PATCHES, POINTS, STANDERS, TRAJECTORIES, TURN,
    TURN_RATES_DEG_S, WORLD,
};
use super::records::{Character, Crossing, Library, Patch, Point, Trajectory, World};
use super::rules::invalid;
use super::{MAGIC, VERSION};
use crate::crc::Crc32;
use crate::error::LoadError;
use std::io::{Read, Seek, SeekFrom};

impl Library {
    /// Reads and checks a library. Nothing in `bytes` is trusted: every count is bounded by
    /// the bytes that hold it, every index is checked, every character's loop is walked.
    pub fn from_bytes(bytes: &[u8]) -> Result<Library, LoadError> {
        let len = bytes.len() as u64;
        let header = at(bytes, bounded(0, HEADER_LEN as u64, len, "the header")?);
        let table = at(bytes, table_bounds(header, len)?);
        let lib = decode(&mut InMemory { bytes, table }, |src| {
            src.records((POINTS, "PNTS"), Point::BYTES, Point::from_le_bytes)
        })?;
        lib.validate()?;
        Ok(lib)
    }

    /// [`Library::from_bytes`] of a file, read a section at a time and the large ones a piece
    /// at a time, so that loading holds the library and not its bytes as well (the million's:
    /// 0.9 GB of each). The same library, or the same error, as `from_bytes` of its bytes; a
    /// file that cannot be read is [`LoadError::Read`].
    pub fn read_from(file: impl Read + Seek) -> Result<Library, LoadError> {
        let lib = decode(&mut FromFile::open(file)?, |src| {
            src.records((POINTS, "PNTS"), Point::BYTES, Point::from_le_bytes)
        })?;
        lib.validate()?;
        Ok(lib)
    }
}

/// Where a library's sections come from.
pub(super) trait Sections {
    /// The section table's bytes.
    fn table(&self) -> &[u8];

    /// Section `tag`'s records of `size` bytes each, made by `read`, once the section is
    /// found, inside the file and its checksum holds ([`LoadError`] otherwise, in that order).
    fn records<T>(
        &mut self,
        section: ([u8; 4], &'static str),
        size: usize,
        read: impl Fn(&[u8]) -> T,
    ) -> Result<Vec<T>, LoadError>;
}

/// A library's bytes in memory.
struct InMemory<'a> {
    bytes: &'a [u8],
    table: &'a [u8],
}

impl Sections for InMemory<'_> {
    fn table(&self) -> &[u8] {
        self.table
    }

    fn records<T>(
        &mut self,
        (tag, name): ([u8; 4], &'static str),
        size: usize,
        read: impl Fn(&[u8]) -> T,
    ) -> Result<Vec<T>, LoadError> {
        let (range, crc) = entry(self.table, tag, name, self.bytes.len() as u64)?;
        let body = at(self.bytes, range);
        let mut check = Crc32::new();
        check.update(body);
        checked(check, crc, name)?;
        whole_records(body.len(), size, name)?;
        Ok(body.chunks_exact(size).map(read).collect())
    }
}

/// A library's file, read as it is decoded.
pub(super) struct FromFile<F> {
    pub file: F,
    pub len: u64,
    pub table: Vec<u8>,
}

impl<F: Read + Seek> FromFile<F> {
    /// `file`'s header and section table read, ready to decode.
    pub fn open(mut file: F) -> Result<FromFile<F>, LoadError> {
        let len = file.seek(SeekFrom::End(0)).map_err(LoadError::read)?;
        let header = read_at(&mut file, bounded(0, HEADER_LEN as u64, len, "the header")?)?;
        let table = read_at(&mut file, table_bounds(&header, len)?)?;
        Ok(FromFile { file, len, table })
    }

    /// Section `tag` read through for its checksum and checked to hold whole records of
    /// `size` bytes, as [`Sections::records`] checks it, but nothing kept: where it is.
    pub fn check_through(
        &mut self,
        (tag, name): ([u8; 4], &'static str),
        size: usize,
    ) -> Result<std::ops::Range<usize>, LoadError> {
        let (range, crc) = entry(&self.table, tag, name, self.len)?;
        self.file
            .seek(SeekFrom::Start(range.start as u64))
            .map_err(LoadError::read)?;
        let mut check = Crc32::new();
        let mut piece = vec![0; size * PIECE_RECORDS.min(range.len() / size + 1)];
        let mut left = range.len();
        while left > 0 {
            let piece = &mut piece[..left.min(size * PIECE_RECORDS)];
            self.file.read_exact(piece).map_err(LoadError::read)?;
            check.update(piece);
            left -= piece.len();
        }
        checked(check, crc, name)?;
        whole_records(range.len(), size, name)?;
        Ok(range)
    }
}

/// Records read from a file at a time (each piece a whole number of records).
pub(super) const PIECE_RECORDS: usize = 1 << 16;

impl<F: Read + Seek> Sections for FromFile<F> {
    fn table(&self) -> &[u8] {
        &self.table
    }

    fn records<T>(
        &mut self,
        (tag, name): ([u8; 4], &'static str),
        size: usize,
        read: impl Fn(&[u8]) -> T,
    ) -> Result<Vec<T>, LoadError> {
        let (range, crc) = entry(&self.table, tag, name, self.len)?;
        let body_len = range.end - range.start;
        self.file
            .seek(SeekFrom::Start(range.start as u64))
            .map_err(LoadError::read)?;
        let mut out = Vec::with_capacity(body_len / size);
        let mut check = Crc32::new();
        let mut piece = vec![0; size * PIECE_RECORDS.min(body_len / size + 1)];
        let mut left = body_len;
        while left > 0 {
            let n = left.min(piece.len());
            let piece = &mut piece[..n];
            self.file.read_exact(piece).map_err(LoadError::read)?;
            check.update(piece);
            out.extend(piece.chunks_exact(size).map(&read));
            left -= n;
        }
        checked(check, crc, name)?;
        whole_records(body_len, size, name)?;
        Ok(out)
    }
}

/// The library in `src`'s sections, each checked as it is read (the rules are not: see
/// [`Library::validate`]), its points as `points` reads them.
pub(super) fn decode<S: Sections>(
    src: &mut S,
    points: impl FnOnce(&mut S) -> Result<Vec<Point>, LoadError>,
) -> Result<Library, LoadError> {
    let w: Vec<u8> = src.records((WORLD, "WRLD"), 1, |b| b[0])?;
    if w.len() != 36 {
        return Err(invalid("WRLD", 0, "36 bytes"));
    }
    let world = World {
        patch_side_m: le_f32(&w[0..4]),
        period_ticks: le_u32(&w[4..8]),
        radius_m: le_f32(&w[8..12]),
        cols: le_u32(&w[12..16]),
        rows: le_u32(&w[16..20]),
        seed: le_u64(&w[20..28]),
        input_hash: w[28..36].try_into().expect("8 bytes"),
        turn_rate_deg_s: turn_rate(src)?,
    };
    let finite_positive = |v: f32| v.is_finite() && v > 0.0;
    if !finite_positive(world.patch_side_m) || !finite_positive(world.radius_m) {
        return Err(invalid(
            "WRLD",
            0,
            "a finite, positive patch side and radius",
        ));
    }
    if world.period_ticks == 0 {
        return Err(invalid("WRLD", 0, "a period of at least one tick"));
    }
    let patches = src.records((PATCHES, "PTCH"), 24, |r| Patch {
        col: le_u32(&r[0..4]),
        row: le_u32(&r[4..8]),
        first_trajectory: le_u32(&r[8..12]),
        trajectories: le_u32(&r[12..16]),
        first_stander: le_u32(&r[16..20]),
        standers: le_u32(&r[20..24]),
    })?;
    let standers = src.records((STANDERS, "STND"), 4, |r| Point {
        x: le_u16(&r[0..2]),
        y: le_u16(&r[2..4]),
        t: 0,
    })?;
    let crossings = src.records((CROSSINGS, "CROS"), 28, |r| Crossing {
        from_patch: le_u32(&r[0..4]),
        to_patch: le_u32(&r[4..8]),
        x: le_f32(&r[8..12]),
        y: le_f32(&r[12..16]),
        t: le_u32(&r[16..20]),
        vx: le_f32(&r[20..24]),
        vy: le_f32(&r[24..28]),
    })?;
    let trajectories = src.records((TRAJECTORIES, "TRAJ"), 28, |r| Trajectory {
        patch: le_u32(&r[0..4]),
        entry: le_u32(&r[4..8]),
        exit: le_u32(&r[8..12]),
        next: le_u32(&r[12..16]),
        first_point: le_u32(&r[16..20]),
        points: le_u32(&r[20..24]),
        start: le_u32(&r[24..28]),
    })?;
    let points = points(src)?;
    let characters = src.records((CHARACTERS, "CHAR"), 12, |r| Character {
        first_trajectory: le_u32(&r[0..4]),
        trajectories: le_u32(&r[4..8]),
        laps: le_u32(&r[8..12]),
    })?;
    let lib = Library {
        world,
        patches,
        standers,
        crossings,
        trajectories,
        points,
        characters,
    };
    Ok(lib)
}

/// The section table's place, from the header: magic and version checked first.
fn table_bounds(header: &[u8], len: u64) -> Result<std::ops::Range<usize>, LoadError> {
    if header[..8] != MAGIC {
        return Err(LoadError::BadMagic);
    }
    let version = le_u32(&header[8..12]);
    if version != VERSION {
        return Err(LoadError::UnsupportedVersion(version));
    }
    let count = u64::from(le_u32(&header[12..16]));
    let table_len = count * ENTRY_LEN as u64;
    bounded(HEADER_LEN as u64, table_len, len, "the section table")
}

/// Section `tag`'s place and checksum, from the first entry of the table that names it.
fn entry(
    table: &[u8],
    tag: [u8; 4],
    name: &'static str,
    len: u64,
) -> Result<(std::ops::Range<usize>, u32), LoadError> {
    let entry = table
        .chunks_exact(ENTRY_LEN)
        .find(|e| e[..4] == tag)
        .ok_or(LoadError::MissingSection(name))?;
    let crc = le_u32(&entry[4..8]);
    let range = bounded(le_u64(&entry[8..16]), le_u64(&entry[16..24]), len, name)?;
    Ok((range, crc))
}

/// `len` bytes at `offset` of a file of `file_len`, or where they would run past its end.
fn bounded(
    offset: u64,
    len: u64,
    file_len: u64,
    what: &'static str,
) -> Result<std::ops::Range<usize>, LoadError> {
    match offset.checked_add(len) {
        Some(end) if end <= file_len => Ok(offset as usize..end as usize),
        _ => Err(LoadError::Truncated {
            what,
            offset,
            needed: len,
        }),
    }
}

fn at(bytes: &[u8], range: std::ops::Range<usize>) -> &[u8] {
    &bytes[range]
}

fn read_at(
    file: &mut (impl Read + Seek),
    range: std::ops::Range<usize>,
) -> Result<Vec<u8>, LoadError> {
    file.seek(SeekFrom::Start(range.start as u64))
        .map_err(LoadError::read)?;
    let mut out = vec![0; range.end - range.start];
    file.read_exact(&mut out).map_err(LoadError::read)?;
    Ok(out)
}

/// Whether a section's bytes, read into `check`, match the checksum in the table. Fuzzing
/// builds skip it, so that mutated bytes reach the checks behind it (a corrupted file must be
/// refused by those too; the property test in tests/export.rs recomputes checksums for the
/// same reason).
fn checked(check: Crc32, crc: u32, section: &'static str) -> Result<(), LoadError> {
    if cfg!(not(fuzzing)) && check.finish() != crc {
        return Err(LoadError::Checksum { section });
    }
    Ok(())
}

/// Fixed-size records: as many as the bytes hold, never more.
fn whole_records(len: usize, size: usize, section: &'static str) -> Result<(), LoadError> {
    if !len.is_multiple_of(size) {
        return Err(invalid(section, (len / size) as u64, "whole records"));
    }
    Ok(())
}

/// The `TURN` section's rate, or the default when the library has none (it is optional:
/// libraries written before it play with the default).
fn turn_rate(src: &mut impl Sections) -> Result<f32, LoadError> {
    if !src.table().chunks_exact(ENTRY_LEN).any(|e| e[..4] == TURN) {
        return Ok(crate::turn::DEFAULT_TURN_RATE_DEG_S as f32);
    }
    let body: Vec<u8> = src.records((TURN, "TURN"), 1, |b| b[0])?;
    let rate = (body.len() == 4).then(|| le_f32(&body));
    match rate {
        Some(r) if TURN_RATES_DEG_S.contains(&r) => Ok(r),
        _ => Err(invalid(
            "TURN",
            0,
            "4 bytes: a turn rate in degrees a second from 30 to 3600",
        )),
    }
}

fn le_u16(b: &[u8]) -> u16 {
    u16::from_le_bytes([b[0], b[1]])
}

fn le_u32(b: &[u8]) -> u32 {
    u32::from_le_bytes([b[0], b[1], b[2], b[3]])
}

fn le_u64(b: &[u8]) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[..8]);
    u64::from_le_bytes(a)
}

fn le_f32(b: &[u8]) -> f32 {
    f32::from_bits(le_u32(b))
}
