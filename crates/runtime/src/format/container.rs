//! The container: a 16-byte header (magic, version, section count), a table of 24-byte
//! entries (tag, CRC-32, offset, length), then each section's packed little-endian records.
//! Writing lays them out; reading bounds every slice by the bytes there, checks each
//! checksum and reads as many whole records as a section holds, then hands the library to the
//! rules.

use super::records::{Character, Crossing, Library, Patch, Point, Trajectory, World};
use super::rules::invalid;
use super::{MAGIC, VERSION};
use crate::crc::crc32;
use crate::error::LoadError;
use std::ops::Range;

const HEADER_LEN: usize = 16;
const ENTRY_LEN: usize = 24;
/// Sections, in the order they are written. A reader ignores tags it does not know.
const WORLD: [u8; 4] = *b"WRLD";
const PATCHES: [u8; 4] = *b"PTCH";
const STANDERS: [u8; 4] = *b"STND";
const CROSSINGS: [u8; 4] = *b"CROS";
const TRAJECTORIES: [u8; 4] = *b"TRAJ";
const POINTS: [u8; 4] = *b"PNTS";
const CHARACTERS: [u8; 4] = *b"CHAR";
/// Optional: how fast characters turn (one `f32`, degrees a second).
const TURN: [u8; 4] = *b"TURN";
/// The turn rates a library may ask for, degrees a second (`export.turn_rate_deg_s`'s range).
pub const TURN_RATES_DEG_S: std::ops::RangeInclusive<f32> = 30.0..=3600.0;

/// A section: its tag, the size and number of its records, and a run of them appended to a
/// list.
struct Section {
    tag: [u8; 4],
    size: usize,
    records: fn(&Library) -> usize,
    write: fn(&Library, Range<usize>, &mut Vec<u8>),
}

/// The sections, in the order they are written.
const SECTIONS: [Section; 8] = [
    Section {
        tag: WORLD,
        size: 36,
        records: |_| 1,
        write: |lib, _, w| write_world(lib, w),
    },
    Section {
        tag: PATCHES,
        size: 24,
        records: |lib| lib.patches.len(),
        write: write_patches,
    },
    Section {
        tag: STANDERS,
        size: 4,
        records: |lib| lib.standers.len(),
        write: write_standers,
    },
    Section {
        tag: CROSSINGS,
        size: 28,
        records: |lib| lib.crossings.len(),
        write: write_crossings,
    },
    Section {
        tag: TRAJECTORIES,
        size: 28,
        records: |lib| lib.trajectories.len(),
        write: write_trajectories,
    },
    Section {
        tag: POINTS,
        size: 8,
        records: |lib| lib.points.len(),
        write: write_points,
    },
    Section {
        tag: CHARACTERS,
        size: 12,
        records: |lib| lib.characters.len(),
        write: write_characters,
    },
    Section {
        tag: TURN,
        size: 4,
        records: |_| 1,
        write: |lib, _, w| put_f32(w, lib.world.turn_rate_deg_s),
    },
];

/// Records a piece of [`Library::write_to`] holds (2 MB of points: a piece that long is hashed
/// on every core).
const PIECE_RECORDS: usize = 1 << 18;

impl Library {
    /// The library's bytes: the header, a table left blank, each section written in place
    /// after it, then the table filled in (each section's checksum of its bytes there). One
    /// list the file's size: the million's library was 0.9 GB, held twice over as sections
    /// and then copied into a list grown as it went.
    pub fn to_bytes(&self) -> Vec<u8> {
        let table_end = HEADER_LEN + ENTRY_LEN * SECTIONS.len();
        let mut out = Vec::with_capacity(self.byte_len());
        out.extend_from_slice(&self.head(&[0; SECTIONS.len()]));
        for (i, section) in SECTIONS.iter().enumerate() {
            let start = out.len();
            (section.write)(self, 0..(section.records)(self), &mut out);
            let at = HEADER_LEN + ENTRY_LEN * i + 4;
            let crc = crc32(&out[start..]);
            out[at..at + 4].copy_from_slice(&crc.to_le_bytes());
        }
        debug_assert!(out.len() == self.byte_len() && table_end <= out.len());
        out
    }

    /// The bytes of [`Library::to_bytes`], handed to `sink` a piece at a time and never held
    /// whole (a gathering build writes the million's 0.9 GB so): each section is made twice,
    /// once for its checksum in the table before it, once to hand over.
    pub fn write_to<E>(&self, mut sink: impl FnMut(&[u8]) -> Result<(), E>) -> Result<(), E> {
        let mut crcs = [0; SECTIONS.len()];
        for (crc, section) in crcs.iter_mut().zip(&SECTIONS) {
            let mut c = crate::crc::Crc32::new();
            self.pieces(section, |piece| {
                c.update(piece);
                Ok::<(), E>(())
            })?;
            *crc = c.finish();
        }
        sink(&self.head(&crcs))?;
        for section in &SECTIONS {
            self.pieces(section, &mut sink)?;
        }
        Ok(())
    }

    /// The size of [`Library::to_bytes`].
    pub fn byte_len(&self) -> usize {
        let records: usize = SECTIONS.iter().map(|s| s.size * (s.records)(self)).sum();
        HEADER_LEN + ENTRY_LEN * SECTIONS.len() + records
    }

    /// The header and the section table, with the sections' checksums `crcs`.
    fn head(&self, crcs: &[u32; SECTIONS.len()]) -> Vec<u8> {
        let mut out = Vec::with_capacity(HEADER_LEN + ENTRY_LEN * SECTIONS.len());
        out.extend_from_slice(&MAGIC);
        put_u32(&mut out, VERSION);
        put_u32(&mut out, SECTIONS.len() as u32);
        let mut start = (HEADER_LEN + ENTRY_LEN * SECTIONS.len()) as u64;
        for (section, crc) in SECTIONS.iter().zip(crcs) {
            let len = (section.size * (section.records)(self)) as u64;
            out.extend_from_slice(&section.tag);
            put_u32(&mut out, *crc);
            out.extend_from_slice(&start.to_le_bytes());
            out.extend_from_slice(&len.to_le_bytes());
            start += len;
        }
        out
    }

    /// `section`'s bytes, a run of [`PIECE_RECORDS`] records at a time.
    fn pieces<E>(
        &self,
        section: &Section,
        mut f: impl FnMut(&[u8]) -> Result<(), E>,
    ) -> Result<(), E> {
        let n = (section.records)(self);
        let mut piece = Vec::with_capacity(section.size * n.min(PIECE_RECORDS));
        for from in (0..n).step_by(PIECE_RECORDS) {
            piece.clear();
            (section.write)(self, from..(from + PIECE_RECORDS).min(n), &mut piece);
            f(&piece)?;
        }
        Ok(())
    }

    /// Reads and checks a library. Nothing in `bytes` is trusted: every count is bounded by
    /// the bytes that hold it, every index is checked, every character's loop is walked.
    pub fn from_bytes(bytes: &[u8]) -> Result<Library, LoadError> {
        let header = slice(bytes, 0, HEADER_LEN as u64, "the header")?;
        if header[..8] != MAGIC {
            return Err(LoadError::BadMagic);
        }
        let version = le_u32(&header[8..12]);
        if version != VERSION {
            return Err(LoadError::UnsupportedVersion(version));
        }
        let count = u64::from(le_u32(&header[12..16]));
        let table = slice(
            bytes,
            HEADER_LEN as u64,
            count * ENTRY_LEN as u64,
            "the section table",
        )?;
        let section = |tag: [u8; 4], name: &'static str| -> Result<&[u8], LoadError> {
            let entry = table
                .chunks_exact(ENTRY_LEN)
                .find(|e| e[..4] == tag)
                .ok_or(LoadError::MissingSection(name))?;
            let crc = le_u32(&entry[4..8]);
            let offset = le_u64(&entry[8..16]);
            let len = le_u64(&entry[16..24]);
            let body = slice(bytes, offset, len, name)?;
            // Fuzzing builds skip the checksum, so that mutated bytes reach the checks behind
            // it (a corrupted file must be refused by those too; the property test in
            // tests/export.rs recomputes checksums for the same reason).
            if cfg!(not(fuzzing)) && crc32(body) != crc {
                return Err(LoadError::Checksum { section: name });
            }
            Ok(body)
        };
        let w = section(WORLD, "WRLD")?;
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
            turn_rate_deg_s: turn_rate(table, &section)?,
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
        let patches: Vec<Patch> = records(section(PATCHES, "PTCH")?, 24, "PTCH", |r| Patch {
            col: le_u32(&r[0..4]),
            row: le_u32(&r[4..8]),
            first_trajectory: le_u32(&r[8..12]),
            trajectories: le_u32(&r[12..16]),
            first_stander: le_u32(&r[16..20]),
            standers: le_u32(&r[20..24]),
        })?;
        let standers: Vec<Point> = records(section(STANDERS, "STND")?, 4, "STND", |r| Point {
            x: le_u16(&r[0..2]),
            y: le_u16(&r[2..4]),
            t: 0,
        })?;
        let crossings: Vec<Crossing> =
            records(section(CROSSINGS, "CROS")?, 28, "CROS", |r| Crossing {
                from_patch: le_u32(&r[0..4]),
                to_patch: le_u32(&r[4..8]),
                x: le_f32(&r[8..12]),
                y: le_f32(&r[12..16]),
                t: le_u32(&r[16..20]),
                vx: le_f32(&r[20..24]),
                vy: le_f32(&r[24..28]),
            })?;
        let trajectories: Vec<Trajectory> =
            records(section(TRAJECTORIES, "TRAJ")?, 28, "TRAJ", |r| Trajectory {
                patch: le_u32(&r[0..4]),
                entry: le_u32(&r[4..8]),
                exit: le_u32(&r[8..12]),
                next: le_u32(&r[12..16]),
                first_point: le_u32(&r[16..20]),
                points: le_u32(&r[20..24]),
                start: le_u32(&r[24..28]),
            })?;
        let points: Vec<Point> = records(section(POINTS, "PNTS")?, 8, "PNTS", |r| Point {
            x: le_u16(&r[0..2]),
            y: le_u16(&r[2..4]),
            t: le_u32(&r[4..8]),
        })?;
        let characters: Vec<Character> =
            records(section(CHARACTERS, "CHAR")?, 12, "CHAR", |r| Character {
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
        lib.validate()?;
        Ok(lib)
    }
}

fn slice<'a>(
    bytes: &'a [u8],
    offset: u64,
    len: u64,
    what: &'static str,
) -> Result<&'a [u8], LoadError> {
    let end = offset.checked_add(len);
    match end {
        Some(end) if end <= bytes.len() as u64 => Ok(&bytes[offset as usize..end as usize]),
        _ => Err(LoadError::Truncated {
            what,
            offset,
            needed: len,
        }),
    }
}

/// Fixed-size records: as many as the bytes hold, never more.
fn records<T>(
    body: &[u8],
    size: usize,
    section: &'static str,
    read: impl Fn(&[u8]) -> T,
) -> Result<Vec<T>, LoadError> {
    if !body.len().is_multiple_of(size) {
        return Err(invalid(
            section,
            (body.len() / size) as u64,
            "whole records",
        ));
    }
    Ok(body.chunks_exact(size).map(read).collect())
}

fn put_u32(out: &mut Vec<u8>, v: u32) {
    out.extend_from_slice(&v.to_le_bytes());
}

fn write_world(lib: &Library, w: &mut Vec<u8>) {
    let world = &lib.world;
    put_f32(w, world.patch_side_m);
    put_u32(w, world.period_ticks);
    put_f32(w, world.radius_m);
    put_u32(w, world.cols);
    put_u32(w, world.rows);
    w.extend_from_slice(&world.seed.to_le_bytes());
    w.extend_from_slice(&world.input_hash);
}

fn write_patches(lib: &Library, run: Range<usize>, w: &mut Vec<u8>) {
    for p in &lib.patches[run] {
        for v in [
            p.col,
            p.row,
            p.first_trajectory,
            p.trajectories,
            p.first_stander,
            p.standers,
        ] {
            put_u32(w, v);
        }
    }
}

fn write_standers(lib: &Library, run: Range<usize>, w: &mut Vec<u8>) {
    for s in &lib.standers[run] {
        w.extend_from_slice(&s.x.to_le_bytes());
        w.extend_from_slice(&s.y.to_le_bytes());
    }
}

fn write_crossings(lib: &Library, run: Range<usize>, w: &mut Vec<u8>) {
    for c in &lib.crossings[run] {
        put_u32(w, c.from_patch);
        put_u32(w, c.to_patch);
        put_f32(w, c.x);
        put_f32(w, c.y);
        put_u32(w, c.t);
        put_f32(w, c.vx);
        put_f32(w, c.vy);
    }
}

fn write_trajectories(lib: &Library, run: Range<usize>, w: &mut Vec<u8>) {
    for t in &lib.trajectories[run] {
        for v in [
            t.patch,
            t.entry,
            t.exit,
            t.next,
            t.first_point,
            t.points,
            t.start,
        ] {
            put_u32(w, v);
        }
    }
}

fn write_points(lib: &Library, run: Range<usize>, w: &mut Vec<u8>) {
    for p in &lib.points[run] {
        w.extend_from_slice(&p.x.to_le_bytes());
        w.extend_from_slice(&p.y.to_le_bytes());
        put_u32(w, p.t);
    }
}

fn write_characters(lib: &Library, run: Range<usize>, w: &mut Vec<u8>) {
    for c in &lib.characters[run] {
        put_u32(w, c.first_trajectory);
        put_u32(w, c.trajectories);
        put_u32(w, c.laps);
    }
}

fn put_f32(out: &mut Vec<u8>, v: f32) {
    out.extend_from_slice(&v.to_le_bytes());
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

/// The `TURN` section's rate, or the default when the library has none (it is optional:
/// libraries written before it play with the default).
fn turn_rate<'a>(
    table: &[u8],
    section: &impl Fn([u8; 4], &'static str) -> Result<&'a [u8], LoadError>,
) -> Result<f32, LoadError> {
    if !table.chunks_exact(ENTRY_LEN).any(|e| e[..4] == TURN) {
        return Ok(crate::turn::DEFAULT_TURN_RATE_DEG_S as f32);
    }
    let body = section(TURN, "TURN")?;
    let rate = (body.len() == 4).then(|| le_f32(body));
    match rate {
        Some(r) if TURN_RATES_DEG_S.contains(&r) => Ok(r),
        _ => Err(invalid(
            "TURN",
            0,
            "4 bytes: a turn rate in degrees a second from 30 to 3600",
        )),
    }
}
