// A reader of `library.crowd` (FORMAT.md), written from the format's page alone: a second,
// independent reader beside crowd-runtime's. It checks what the Rust loader checks (magic,
// version, the section table, every checksum, every index and range, every loop) and says
// what is wrong with a bad file, naming the section, the record and what was expected.

/// One tick, in seconds (FORMAT.md, "Time and identity").
export const TICK_S = 1e-4;
export const MAGIC = 'CRWDLIB\0';
export const VERSION = 1;
/// Positions are patch-local, in steps of side / 65535.
export const QUANT_STEPS = 65535;
/// A trajectory lasts at most this many periods.
export const MAX_PERIODS_PER_TRAJECTORY = 64;
const MAX_GRID = 65536;

/// What is wrong with a library's bytes, in words.
export class LibraryError extends Error {
  constructor(message) {
    super(message);
    this.name = 'LibraryError';
  }
}

const RECORD = { WRLD: 36, PTCH: 24, STND: 4, CROS: 28, TRAJ: 28, PNTS: 8, CHAR: 12, TURN: 4 };
const REQUIRED = ['WRLD', 'PTCH', 'STND', 'CROS', 'TRAJ', 'PNTS', 'CHAR'];

let crcTable = null;

/// CRC-32 (IEEE 802.3, as zlib and PNG) of `bytes`.
export function crc32(bytes) {
  if (!crcTable) {
    crcTable = new Uint32Array(256);
    for (let n = 0; n < 256; n++) {
      let c = n;
      for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
      crcTable[n] = c >>> 0;
    }
  }
  let c = 0xffffffff;
  for (let i = 0; i < bytes.length; i++) c = crcTable[(c ^ bytes[i]) & 0xff] ^ (c >>> 8);
  return (c ^ 0xffffffff) >>> 0;
}

function invalid(section, index, expected) {
  return new LibraryError(`${section} record ${index}: expected ${expected}`);
}

/// The sections of `buffer` by tag, each checked against the file and its checksum.
function sections(buffer) {
  const size = buffer.byteLength;
  if (size < 16) {
    throw new LibraryError(`the file is ${size} bytes; a library starts with a 16-byte header`);
  }
  const view = new DataView(buffer);
  const bytes = new Uint8Array(buffer);
  const magic = String.fromCharCode(...bytes.subarray(0, 8));
  if (magic !== MAGIC) {
    const hex = [...bytes.subarray(0, 8)].map((b) => b.toString(16).padStart(2, '0')).join(' ');
    throw new LibraryError(
      `not a crowd library: expected the magic CRWDLIB\\0 (43 52 57 44 4c 49 42 00) at byte 0, found ${hex}`,
    );
  }
  const version = view.getUint32(8, true);
  if (version !== VERSION) {
    throw new LibraryError(`format version ${version}; this reader reads version ${VERSION}`);
  }
  const count = view.getUint32(12, true);
  if (16 + count * 24 > size) {
    throw new LibraryError(
      `the header lists ${count} sections, whose table (${count * 24} bytes) runs past the file's ${size} bytes`,
    );
  }
  const out = new Map();
  for (let i = 0; i < count; i++) {
    const at = 16 + i * 24;
    const tag = String.fromCharCode(...bytes.subarray(at, at + 4));
    const crc = view.getUint32(at + 4, true);
    const offset = Number(view.getBigUint64(at + 8, true));
    const length = Number(view.getBigUint64(at + 16, true));
    if (offset + length > size) {
      throw new LibraryError(
        `section ${tag} (bytes ${offset}..${offset + length}) runs past the end of the file (${size} bytes): cut short?`,
      );
    }
    const data = bytes.subarray(offset, offset + length);
    const actual = crc32(data);
    if (actual !== crc) {
      throw new LibraryError(
        `section ${tag}: checksum ${actual.toString(16).padStart(8, '0')}, the table says ${crc.toString(16).padStart(8, '0')}: the file is damaged`,
      );
    }
    const record = RECORD[tag];
    if (record && length % record !== 0) {
      throw new LibraryError(
        `section ${tag} is ${length} bytes, not a whole number of ${record}-byte records`,
      );
    }
    if (!out.has(tag)) out.set(tag, { offset, length, view: new DataView(buffer, offset, length) });
  }
  for (const tag of REQUIRED) {
    if (!out.has(tag)) throw new LibraryError(`the section ${tag} is missing`);
  }
  if (out.get('WRLD').length !== RECORD.WRLD) {
    throw new LibraryError(`section WRLD is ${out.get('WRLD').length} bytes; expected one record of 36`);
  }
  return out;
}

/// `count` records of `fields` u32s each from a section (little-endian, any alignment).
function u32s(section, fields) {
  const n = section.length / 4;
  const out = new Uint32Array(n);
  const v = section.view;
  for (let i = 0; i < n; i++) out[i] = v.getUint32(4 * i, true);
  return { data: out, count: n / fields };
}

/// A library read from `buffer` (an ArrayBuffer) and checked.
export class Library {
  constructor(buffer) {
    const s = sections(buffer);
    const w = s.get('WRLD').view;
    this.world = {
      side: w.getFloat32(0, true),
      periodTicks: w.getUint32(4, true),
      radius: w.getFloat32(8, true),
      cols: w.getUint32(12, true),
      rows: w.getUint32(16, true),
      seed: w.getBigUint64(20, true),
      inputHash: [...new Uint8Array(buffer, s.get('WRLD').offset + 28, 8)]
        .map((b) => b.toString(16).padStart(2, '0'))
        .join(''),
      turnRateDegS: 360,
    };
    const turn = s.get('TURN');
    if (turn && turn.length === 4) this.world.turnRateDegS = turn.view.getFloat32(0, true);
    const patches = u32s(s.get('PTCH'), 6);
    this.patches = patches.data;
    this.patchCount = patches.count;
    const stnd = s.get('STND');
    this.standers = new Uint16Array(stnd.length / 2);
    for (let i = 0; i < this.standers.length; i++) this.standers[i] = stnd.view.getUint16(2 * i, true);
    this.standerCount = stnd.length / 4;
    const cros = s.get('CROS');
    this.crossingCount = cros.length / 28;
    this.crossings = {
      from: new Uint32Array(this.crossingCount),
      to: new Uint32Array(this.crossingCount),
      x: new Float32Array(this.crossingCount),
      y: new Float32Array(this.crossingCount),
      t: new Uint32Array(this.crossingCount),
      vx: new Float32Array(this.crossingCount),
      vy: new Float32Array(this.crossingCount),
    };
    for (let i = 0; i < this.crossingCount; i++) {
      const o = 28 * i;
      const v = cros.view;
      const c = this.crossings;
      c.from[i] = v.getUint32(o, true);
      c.to[i] = v.getUint32(o + 4, true);
      c.x[i] = v.getFloat32(o + 8, true);
      c.y[i] = v.getFloat32(o + 12, true);
      c.t[i] = v.getUint32(o + 16, true);
      c.vx[i] = v.getFloat32(o + 20, true);
      c.vy[i] = v.getFloat32(o + 24, true);
    }
    const traj = u32s(s.get('TRAJ'), 7);
    this.traj = traj.data;
    this.trajCount = traj.count;
    // Points as the file has them, two u32s each: x | y << 16, then t (little-endian, as
    // every browser is). A point and the next share a cache line, which a player stepping
    // 5,000 walkers a frame onto their next piece needs.
    const pnts = s.get('PNTS');
    this.pointCount = pnts.length / 8;
    this.pts = new Uint32Array(2 * this.pointCount);
    for (let i = 0; i < 2 * this.pointCount; i++) this.pts[i] = pnts.view.getUint32(4 * i, true);
    const chars = u32s(s.get('CHAR'), 3);
    this.chars = chars.data;
    this.charCount = chars.count;
    this.validate();
    this.walkerCount = 0;
    for (let c = 0; c < this.charCount; c++) this.walkerCount += this.chars[3 * c + 2];
  }

  /// Trajectory `i`'s fields.
  trajectory(i) {
    const t = this.traj;
    const o = 7 * i;
    return {
      patch: t[o], entry: t[o + 1], exit: t[o + 2], next: t[o + 3],
      firstPoint: t[o + 4], points: t[o + 5], start: t[o + 6],
    };
  }

  /// Patch `i`'s fields.
  patch(i) {
    const p = this.patches;
    const o = 6 * i;
    return {
      col: p[o], row: p[o + 1], firstTrajectory: p[o + 2], trajectories: p[o + 3],
      firstStander: p[o + 4], standers: p[o + 5],
    };
  }

  /// Point `k`'s patch-local position (steps of side / 65535) and time (ticks).
  x(k) {
    return this.pts[2 * k] & 0xffff;
  }

  y(k) {
    return this.pts[2 * k] >>> 16;
  }

  t(k) {
    return this.pts[2 * k + 1];
  }

  /// How long trajectory `i` lasts, ticks.
  duration(i) {
    const o = 7 * i;
    return this.t(this.traj[o + 4] + this.traj[o + 5] - 1);
  }

  /// Characters in all: walkers, then standers.
  get characters() {
    return this.walkerCount + this.standerCount;
  }

  /// FORMAT.md's "Rules a reader checks".
  validate() {
    const w = this.world;
    if (!(w.periodTicks > 0) || !(w.side > 0) || !(w.radius > 0)) {
      throw invalid('WRLD', 0, 'a positive period, side and radius');
    }
    if (w.cols > MAX_GRID || w.rows > MAX_GRID) {
      throw invalid('WRLD', 0, 'at most 65536 patches across and up');
    }
    const inRange = (first, count, len) => first + count <= len;
    for (let i = 0; i < this.patchCount; i++) {
      const p = this.patch(i);
      if (p.col >= w.cols || p.row >= w.rows) throw invalid('PTCH', i, "a cell inside the world's grid");
      if (!inRange(p.firstTrajectory, p.trajectories, this.trajCount)) {
        throw invalid('PTCH', i, 'trajectories inside TRAJ');
      }
      if (!inRange(p.firstStander, p.standers, this.standerCount)) {
        throw invalid('PTCH', i, 'standers inside STND');
      }
    }
    const c = this.crossings;
    for (let i = 0; i < this.crossingCount; i++) {
      if (c.from[i] >= this.patchCount || c.to[i] >= this.patchCount || c.t[i] >= w.periodTicks) {
        throw invalid('CROS', i, 'patches inside PTCH and a time in the period');
      }
      if (![c.x[i], c.y[i], c.vx[i], c.vy[i]].every(Number.isFinite)) {
        throw invalid('CROS', i, 'finite position and velocity');
      }
    }
    const n = this.trajCount;
    const longest = MAX_PERIODS_PER_TRAJECTORY * w.periodTicks;
    for (let i = 0; i < n; i++) {
      const t = this.trajectory(i);
      if (t.patch >= this.patchCount || t.entry >= this.crossingCount || t.exit >= this.crossingCount || t.next >= n) {
        throw invalid('TRAJ', i, 'patch, crossings and next inside their sections');
      }
      const p = this.patch(t.patch);
      if (i < p.firstTrajectory || i >= p.firstTrajectory + p.trajectories) {
        throw invalid('TRAJ', i, "to lie in its patch's range of trajectories");
      }
      if (t.points < 2 || !inRange(t.firstPoint, t.points, this.pointCount)) {
        throw invalid('TRAJ', i, 'at least two points inside PNTS');
      }
      if (t.start >= w.periodTicks) throw invalid('TRAJ', i, 'a start in [0, period)');
      if (this.t(t.firstPoint) !== 0) throw invalid('TRAJ', i, 'point times from 0, never decreasing');
      for (let k = t.firstPoint + 1; k < t.firstPoint + t.points; k++) {
        if (this.t(k) < this.t(k - 1)) throw invalid('TRAJ', i, 'point times from 0, never decreasing');
      }
      const last = this.t(t.firstPoint + t.points - 1);
      if (last > longest) throw invalid('TRAJ', i, 'to last at most MAX_PERIODS_PER_TRAJECTORY (64) periods');
      const next = this.trajectory(t.next);
      if (next.entry !== t.exit) throw invalid('TRAJ', i, 'its next trajectory to enter by its exit');
      if ((t.start + last) % w.periodTicks !== next.start) {
        throw invalid('TRAJ', i, "its end, modulo the period, to be its next trajectory's start");
      }
    }
    const seen = new Uint8Array(n);
    for (let i = 0; i < this.charCount; i++) {
      const first = this.chars[3 * i];
      const count = this.chars[3 * i + 1];
      const laps = this.chars[3 * i + 2];
      if (first >= n || count === 0 || laps === 0) {
        throw invalid('CHAR', i, 'a first trajectory inside TRAJ, and at least one trajectory and lap');
      }
      let at = first;
      let ticks = 0;
      for (let k = 0; k < count; k++) {
        if (seen[at]) throw invalid('CHAR', i, 'a loop through trajectories of no other loop');
        seen[at] = 1;
        ticks += this.duration(at);
        at = this.traj[7 * at + 3];
      }
      if (at !== first) throw invalid('CHAR', i, "its trajectories' next links to come back to its first");
      if (ticks !== laps * w.periodTicks) throw invalid('CHAR', i, 'its trajectories to last its laps x the period');
    }
    const stray = seen.indexOf(0);
    if (stray >= 0) throw invalid('TRAJ', stray, "to lie on one of CHAR's loops");
  }
}

/// Reads and checks a library; throws a LibraryError saying what is wrong.
export function readLibrary(buffer) {
  return new Library(buffer);
}
