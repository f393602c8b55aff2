//! The container: a 16-byte header (magic, version, section count), a table of 24-byte
//! entries (tag, CRC-32, offset, length), then each section's packed little-endian records.
//! Writing lays them out; `read.rs` reads them back.

use super::records::Library;
use super::{MAGIC, VERSION};
use crate::crc::crc32;
use std::ops::Range;

pub(super) const HEADER_LEN: usize = 16;
pub(super) const ENTRY_LEN: usize = 24;
/// Sections, in the order they are written. A reader ignores tags it does not know.
pub(super) const WORLD: [u8; 4] = *b"WRLD";
pub(super) const PATCHES: [u8; 4] = *b"PTCH";
pub(super) const STANDERS: [u8; 4] = *b"STND";
pub(super) const CROSSINGS: [u8; 4] = *b"CROS";
pub(super) const TRAJECTORIES: [u8; 4] = *b"TRAJ";
pub(super) const POINTS: [u8; 4] = *b"PNTS";
pub(super) const CHARACTERS: [u8; 4] = *b"CHAR";
/// Optional: how fast characters turn (one `f32`, degrees a second).
pub(super) const TURN: [u8; 4] = *b"TURN";
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

/// PNTS's place in [`SECTIONS`].
const POINTS_AT: usize = 5;

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
    pub fn write_to<E>(&self, sink: impl FnMut(&[u8]) -> Result<(), E>) -> Result<(), E> {
        let mut crc = crate::crc::Crc32::new();
        self.pieces(&SECTIONS[POINTS_AT], |piece| {
            crc.update(piece);
            Ok::<(), E>(())
        })?;
        let points = (self.points.len(), crc.finish());
        self.write_with_points(points, |sink| self.pieces(&SECTIONS[POINTS_AT], sink), sink)
    }

    /// [`Library::write_to`] of a library whose points are elsewhere (`self.points` is not
    /// read): `count` of them whose bytes' checksum is `crc`, handed over in their place by
    /// `points` (stage 8 of a large world keeps them in a scratch file as it makes them).
    pub fn write_with_points<E>(
        &self,
        (count, crc): (usize, u32),
        points: impl FnOnce(&mut dyn FnMut(&[u8]) -> Result<(), E>) -> Result<(), E>,
        mut sink: impl FnMut(&[u8]) -> Result<(), E>,
    ) -> Result<(), E> {
        debug_assert_eq!(SECTIONS[POINTS_AT].tag, POINTS);
        let mut crcs = [0; SECTIONS.len()];
        for (i, (c, section)) in crcs.iter_mut().zip(&SECTIONS).enumerate() {
            if i == POINTS_AT {
                *c = crc;
                continue;
            }
            let mut check = crate::crc::Crc32::new();
            self.pieces(section, |piece| {
                check.update(piece);
                Ok::<(), E>(())
            })?;
            *c = check.finish();
        }
        let records = |i: usize| match i {
            POINTS_AT => count,
            _ => (SECTIONS[i].records)(self),
        };
        sink(&self.head_of(&crcs, records))?;
        let mut points = Some(points);
        for (i, section) in SECTIONS.iter().enumerate() {
            if i == POINTS_AT {
                (points.take().expect("one PNTS section"))(&mut sink)?;
            } else {
                self.pieces(section, &mut sink)?;
            }
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
        self.head_of(crcs, |i| (SECTIONS[i].records)(self))
    }

    /// [`Library::head`] of sections of `records(i)` records each.
    fn head_of(&self, crcs: &[u32; SECTIONS.len()], records: impl Fn(usize) -> usize) -> Vec<u8> {
        let mut out = Vec::with_capacity(HEADER_LEN + ENTRY_LEN * SECTIONS.len());
        out.extend_from_slice(&MAGIC);
        put_u32(&mut out, VERSION);
        put_u32(&mut out, SECTIONS.len() as u32);
        let mut start = (HEADER_LEN + ENTRY_LEN * SECTIONS.len()) as u64;
        for (i, (section, crc)) in SECTIONS.iter().zip(crcs).enumerate() {
            let len = (section.size * records(i)) as u64;
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
        w.extend_from_slice(&p.to_le_bytes());
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
