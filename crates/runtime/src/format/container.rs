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

impl Library {
    /// The library's bytes: the header, a table left blank, each section written in place
    /// after it, then the table filled in (each section's checksum of its bytes there). One
    /// list the file's size: the million's library was 0.9 GB, held twice over as sections
    /// and then copied into a list grown as it went.
    pub fn to_bytes(&self) -> Vec<u8> {
        let sections: [([u8; 4], SectionWriter); 8] = [
            (WORLD, write_world),
            (PATCHES, write_patches),
            (STANDERS, write_standers),
            (CROSSINGS, write_crossings),
            (TRAJECTORIES, write_trajectories),
            (POINTS, write_points),
            (CHARACTERS, write_characters),
            (TURN, write_turn),
        ];
        let table_end = HEADER_LEN + ENTRY_LEN * sections.len();
        let records = 36
            + self.patches.len() * 24
            + self.standers.len() * 4
            + self.crossings.len() * 28
            + self.trajectories.len() * 28
            + self.points.len() * 8
            + self.characters.len() * 12
            + 4;
        let mut out = Vec::with_capacity(table_end + records);
        out.extend_from_slice(&MAGIC);
        put_u32(&mut out, VERSION);
        put_u32(&mut out, sections.len() as u32);
        out.resize(table_end, 0);
        for (i, (tag, write)) in sections.iter().enumerate() {
            let start = out.len();
            write(self, &mut out);
            let mut entry = Vec::with_capacity(ENTRY_LEN);
            entry.extend_from_slice(tag);
            put_u32(&mut entry, crc32(&out[start..]));
            entry.extend_from_slice(&(start as u64).to_le_bytes());
            entry.extend_from_slice(&((out.len() - start) as u64).to_le_bytes());
            let at = HEADER_LEN + ENTRY_LEN * i;
            out[at..at + ENTRY_LEN].copy_from_slice(&entry);
        }
        out
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

/// Appends one section's records to a library's bytes.
type SectionWriter = fn(&Library, &mut Vec<u8>);

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

fn write_patches(lib: &Library, w: &mut Vec<u8>) {
    for p in &lib.patches {
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

fn write_standers(lib: &Library, w: &mut Vec<u8>) {
    for s in &lib.standers {
        w.extend_from_slice(&s.x.to_le_bytes());
        w.extend_from_slice(&s.y.to_le_bytes());
    }
}

fn write_crossings(lib: &Library, w: &mut Vec<u8>) {
    for c in &lib.crossings {
        put_u32(w, c.from_patch);
        put_u32(w, c.to_patch);
        put_f32(w, c.x);
        put_f32(w, c.y);
        put_u32(w, c.t);
        put_f32(w, c.vx);
        put_f32(w, c.vy);
    }
}

fn write_trajectories(lib: &Library, w: &mut Vec<u8>) {
    for t in &lib.trajectories {
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

fn write_points(lib: &Library, w: &mut Vec<u8>) {
    for p in &lib.points {
        w.extend_from_slice(&p.x.to_le_bytes());
        w.extend_from_slice(&p.y.to_le_bytes());
        put_u32(w, p.t);
    }
}

fn write_characters(lib: &Library, w: &mut Vec<u8>) {
    for c in &lib.characters {
        put_u32(w, c.first_trajectory);
        put_u32(w, c.trajectories);
        put_u32(w, c.laps);
    }
}

fn write_turn(lib: &Library, w: &mut Vec<u8>) {
    put_f32(w, lib.world.turn_rate_deg_s);
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
