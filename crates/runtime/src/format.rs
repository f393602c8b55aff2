//! The library's bytes (`FORMAT.md`): a header, a section table, packed little-endian records.
//! [`Library::to_bytes`] writes them (stage 8 calls it); [`Library::from_bytes`] reads and
//! checks them without trusting anything.

use crate::crc::crc32;
use crate::error::LoadError;

/// The first 8 bytes of every library.
pub const MAGIC: [u8; 8] = *b"CRWDLIB\0";
/// The format version this crate reads and writes.
pub const VERSION: u32 = 1;
/// Times are whole ticks of this many seconds (0.1 ms): quantised to within 0.05 ms.
pub const TICK_S: f64 = 1e-4;
/// Positions are patch-local, in steps of side / QUANT_STEPS: within side / 131,070 (0.06 mm
/// for an 8 m patch).
pub const QUANT_STEPS: f64 = 65535.0;

/// The longest a trajectory may last, in periods. It bounds the walkers a library can claim
/// (at most this many per trajectory record), so that loading allocates in proportion to the
/// file's size, whatever it says.
pub const MAX_PERIODS_PER_TRAJECTORY: u32 = 64;

/// The most patches a world has across and up (so a patch's place fits two u16s, as the
/// sampler keeps it): 524 km at 8 m a patch.
pub const MAX_GRID: u32 = 1 << 16;

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

/// What holds for the whole world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct World {
    pub patch_side_m: f32,
    /// The loop: every character's motion repeats after `period_ticks` x [`TICK_S`] seconds
    /// (or a whole number of them, for a character whose loop crosses several periods).
    pub period_ticks: u32,
    pub radius_m: f32,
    /// Patch grid size.
    pub cols: u32,
    pub rows: u32,
    pub seed: u64,
    /// The first 8 bytes of the build's input hash, to tell builds apart.
    pub input_hash: [u8; 8],
}

/// A patch: its place in the grid (south-west corner at (col, row) x side) and its records.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Patch {
    pub col: u32,
    pub row: u32,
    pub first_trajectory: u32,
    pub trajectories: u32,
    pub first_stander: u32,
    pub standers: u32,
}

/// A patch-local position in steps of side / 65535, and for a trajectory point the ticks since
/// its trajectory's start (standers: `t` is 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Point {
    pub x: u16,
    pub y: u16,
    pub t: u32,
}

/// An entry or exit point of the patterns: where (world metres), when (ticks in the period),
/// at what velocity (m/s), from which patch to which.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crossing {
    pub from_patch: u32,
    pub to_patch: u32,
    pub x: f32,
    pub y: f32,
    pub t: u32,
    pub vx: f32,
    pub vy: f32,
}

/// One walker's way through one patch, and the link to the way it continues on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Trajectory {
    pub patch: u32,
    /// Crossings it enters and leaves by.
    pub entry: u32,
    pub exit: u32,
    /// The trajectory (in the patch across `exit`) that enters by `exit`: the same character.
    pub next: u32,
    pub first_point: u32,
    pub points: u32,
    /// Ticks in [0, period) when it starts at its entry.
    pub start: u32,
}

/// A loop of linked trajectories. It lasts `laps` periods, so `laps` characters walk it at
/// once, a period apart: character ids `first_id .. first_id + laps`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Character {
    pub first_trajectory: u32,
    pub trajectories: u32,
    pub laps: u32,
}

/// A whole library, decoded and checked.
#[derive(Debug, Clone, PartialEq)]
pub struct Library {
    pub world: World,
    pub patches: Vec<Patch>,
    pub standers: Vec<Point>,
    pub crossings: Vec<Crossing>,
    pub trajectories: Vec<Trajectory>,
    pub points: Vec<Point>,
    pub characters: Vec<Character>,
}

impl Library {
    /// Seconds of one period.
    pub fn period_s(&self) -> f64 {
        f64::from(self.world.period_ticks) * TICK_S
    }

    /// How many characters walk (each loop's laps) and stand.
    pub fn walkers(&self) -> u64 {
        self.characters.iter().map(|c| u64::from(c.laps)).sum()
    }

    /// World position of a patch-local quantised point of `patch`.
    pub fn world_position(&self, patch: &Patch, p: Point) -> [f64; 2] {
        let side = f64::from(self.world.patch_side_m);
        let q = side / QUANT_STEPS;
        [
            f64::from(patch.col) * side + f64::from(p.x) * q,
            f64::from(patch.row) * side + f64::from(p.y) * q,
        ]
    }

    /// The points of a trajectory of this library.
    pub fn points_of(&self, t: &Trajectory) -> &[Point] {
        let first = t.first_point as usize;
        &self.points[first..first + t.points as usize]
    }

    /// Ticks from a trajectory's start to its end.
    pub fn duration_ticks(&self, t: &Trajectory) -> u32 {
        self.points_of(t).last().map_or(0, |p| p.t)
    }

    /// The library's bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut sections: Vec<([u8; 4], Vec<u8>)> = Vec::new();
        let mut w = Vec::new();
        let world = &self.world;
        put_f32(&mut w, world.patch_side_m);
        put_u32(&mut w, world.period_ticks);
        put_f32(&mut w, world.radius_m);
        put_u32(&mut w, world.cols);
        put_u32(&mut w, world.rows);
        w.extend_from_slice(&world.seed.to_le_bytes());
        w.extend_from_slice(&world.input_hash);
        sections.push((WORLD, w));
        let mut w = Vec::with_capacity(self.patches.len() * 24);
        for p in &self.patches {
            for v in [
                p.col,
                p.row,
                p.first_trajectory,
                p.trajectories,
                p.first_stander,
                p.standers,
            ] {
                put_u32(&mut w, v);
            }
        }
        sections.push((PATCHES, w));
        let mut w = Vec::with_capacity(self.standers.len() * 4);
        for s in &self.standers {
            w.extend_from_slice(&s.x.to_le_bytes());
            w.extend_from_slice(&s.y.to_le_bytes());
        }
        sections.push((STANDERS, w));
        let mut w = Vec::with_capacity(self.crossings.len() * 28);
        for c in &self.crossings {
            put_u32(&mut w, c.from_patch);
            put_u32(&mut w, c.to_patch);
            put_f32(&mut w, c.x);
            put_f32(&mut w, c.y);
            put_u32(&mut w, c.t);
            put_f32(&mut w, c.vx);
            put_f32(&mut w, c.vy);
        }
        sections.push((CROSSINGS, w));
        let mut w = Vec::with_capacity(self.trajectories.len() * 28);
        for t in &self.trajectories {
            for v in [
                t.patch,
                t.entry,
                t.exit,
                t.next,
                t.first_point,
                t.points,
                t.start,
            ] {
                put_u32(&mut w, v);
            }
        }
        sections.push((TRAJECTORIES, w));
        let mut w = Vec::with_capacity(self.points.len() * 8);
        for p in &self.points {
            w.extend_from_slice(&p.x.to_le_bytes());
            w.extend_from_slice(&p.y.to_le_bytes());
            put_u32(&mut w, p.t);
        }
        sections.push((POINTS, w));
        let mut w = Vec::with_capacity(self.characters.len() * 12);
        for c in &self.characters {
            put_u32(&mut w, c.first_trajectory);
            put_u32(&mut w, c.trajectories);
            put_u32(&mut w, c.laps);
        }
        sections.push((CHARACTERS, w));

        let mut out = Vec::new();
        out.extend_from_slice(&MAGIC);
        put_u32(&mut out, VERSION);
        put_u32(&mut out, sections.len() as u32);
        let mut offset = (HEADER_LEN + ENTRY_LEN * sections.len()) as u64;
        for (tag, bytes) in &sections {
            out.extend_from_slice(tag);
            put_u32(&mut out, crc32(bytes));
            out.extend_from_slice(&offset.to_le_bytes());
            out.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
            offset += bytes.len() as u64;
        }
        for (_, bytes) in sections {
            out.extend_from_slice(&bytes);
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

    /// Every rule a sampler relies on.
    fn validate(&self) -> Result<(), LoadError> {
        let w = &self.world;
        if w.cols > MAX_GRID || w.rows > MAX_GRID {
            return Err(invalid("WRLD", 0, "at most 65536 patches across and up"));
        }
        let in_range =
            |first: u32, count: u32, len: usize| u64::from(first) + u64::from(count) <= len as u64;
        for (i, p) in self.patches.iter().enumerate() {
            let i = i as u64;
            if p.col >= w.cols || p.row >= w.rows {
                return Err(invalid("PTCH", i, "a cell inside the world's grid"));
            }
            if !in_range(p.first_trajectory, p.trajectories, self.trajectories.len()) {
                return Err(invalid("PTCH", i, "trajectories inside TRAJ"));
            }
            if !in_range(p.first_stander, p.standers, self.standers.len()) {
                return Err(invalid("PTCH", i, "standers inside STND"));
            }
        }
        for (i, c) in self.crossings.iter().enumerate() {
            let i = i as u64;
            let n = self.patches.len() as u32;
            if c.from_patch >= n || c.to_patch >= n || c.t >= w.period_ticks {
                return Err(invalid(
                    "CROS",
                    i,
                    "patches inside PTCH and a time in the period",
                ));
            }
            if ![c.x, c.y, c.vx, c.vy].iter().all(|v| v.is_finite()) {
                return Err(invalid("CROS", i, "finite position and velocity"));
            }
        }
        let n = self.trajectories.len();
        for (i, t) in self.trajectories.iter().enumerate() {
            let e = |expected| Err(invalid("TRAJ", i as u64, expected));
            if t.patch as usize >= self.patches.len()
                || t.entry as usize >= self.crossings.len()
                || t.exit as usize >= self.crossings.len()
                || t.next as usize >= n
            {
                return e("patch, crossings and next inside their sections");
            }
            let p = &self.patches[t.patch as usize];
            let first = u64::from(p.first_trajectory);
            if !(first..first + u64::from(p.trajectories)).contains(&(i as u64)) {
                return e("to lie in its patch's range of trajectories");
            }
            if t.points < 2 || !in_range(t.first_point, t.points, self.points.len()) {
                return e("at least two points inside PNTS");
            }
            if t.start >= w.period_ticks {
                return e("a start in [0, period)");
            }
            let pts = self.points_of(t);
            if pts[0].t != 0 || pts.windows(2).any(|w| w[1].t < w[0].t) {
                return e("point times from 0, never decreasing");
            }
            let periods = u64::from(MAX_PERIODS_PER_TRAJECTORY) * u64::from(w.period_ticks);
            if u64::from(pts[pts.len() - 1].t) > periods {
                return e("to last at most MAX_PERIODS_PER_TRAJECTORY (64) periods");
            }
            let next = &self.trajectories[t.next as usize];
            if next.entry != t.exit {
                return e("its next trajectory to enter by its exit");
            }
            let end = u64::from(t.start) + u64::from(pts[pts.len() - 1].t);
            if end % u64::from(w.period_ticks) != u64::from(next.start) {
                return e("its end, modulo the period, to be its next trajectory's start");
            }
        }
        // Every trajectory lies on exactly one listed loop, walked by its `next` links.
        let mut seen = vec![false; n];
        for (i, c) in self.characters.iter().enumerate() {
            let e = |expected| Err(invalid("CHAR", i as u64, expected));
            if c.first_trajectory as usize >= n || c.trajectories == 0 || c.laps == 0 {
                return e("a first trajectory inside TRAJ, and at least one trajectory and lap");
            }
            let mut at = c.first_trajectory as usize;
            let mut ticks = 0u64;
            for _ in 0..c.trajectories {
                if seen[at] {
                    return e("a loop through trajectories of no other loop");
                }
                seen[at] = true;
                let t = &self.trajectories[at];
                ticks += u64::from(self.duration_ticks(t));
                at = t.next as usize;
            }
            if at != c.first_trajectory as usize {
                return e("its trajectories' next links to come back to its first");
            }
            if ticks != u64::from(c.laps) * u64::from(w.period_ticks) {
                return e("its trajectories to last its laps x the period");
            }
        }
        if let Some(i) = seen.iter().position(|s| !s) {
            return Err(invalid("TRAJ", i as u64, "to lie on one of CHAR's loops"));
        }
        Ok(())
    }
}

fn invalid(section: &'static str, index: u64, expected: &'static str) -> LoadError {
    LoadError::Invalid {
        section,
        index,
        expected,
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
