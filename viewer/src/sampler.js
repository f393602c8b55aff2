// Where every character of a library is at a time (FORMAT.md, "Time and identity"): walker
// (loop, lap) at world time t is at loop time (t - start of the loop's first trajectory -
// lap x period) mod (laps x period), measured along the loop's trajectories in order; a
// character moves in a straight line at constant speed from one point to the next.
//
// A frame must cost little for 100k characters, so each walker keeps a cursor: its piece, the
// loop times the piece starts and ends at, where it starts in the world, its velocity and its
// facing. A frame then reads each walker's own few numbers one after another (not the points,
// which are scattered over the file: fetching them each frame made a frame of `painting` take
// 22 ms); while time moves forward a walker steps on piece by piece, and only a jump (a scrub,
// a seek) searches, by bisection. Stepping on costs most of a frame (7k of `painting`'s 95k
// walkers a frame at 60 fps), in reading the next point (72 MB of points, a cache miss each);
// the cursor's other fields are kept in small arrays that stay in cache (packed into one
// line per walker with the rest, 6 MB, they made a frame 20 % slower; listing the walkers
// that step on and reading their points ahead, so that the misses overlap, made it 40 %
// slower).

import { QUANT_STEPS, TICK_S } from './library.js';

export class Sampler {
  /// A sampler of `lib` (a checked Library).
  constructor(lib) {
    this.lib = lib;
    const w = lib.world;
    this.period = w.periodTicks;
    this.step = w.side / QUANT_STEPS;
    // Per loop: its trajectories in walking order, the loop time each starts at, its length.
    const nLoops = lib.charCount;
    this.loopFirst = new Uint32Array(nLoops + 1);
    this.loopTraj = new Uint32Array(lib.trajCount);
    this.loopStart = new Float64Array(lib.trajCount);
    this.loopLength = new Float64Array(nLoops);
    this.loopEpoch = new Float64Array(nLoops);
    let k = 0;
    for (let c = 0; c < nLoops; c++) {
      this.loopFirst[c] = k;
      let at = lib.chars[3 * c];
      const count = lib.chars[3 * c + 1];
      this.loopEpoch[c] = lib.traj[7 * at + 6];
      let tick = 0;
      for (let i = 0; i < count; i++) {
        this.loopTraj[k] = at;
        this.loopStart[k] = tick;
        tick += lib.duration(at);
        k++;
        at = lib.traj[7 * at + 3];
      }
      this.loopLength[c] = tick;
    }
    this.loopFirst[nLoops] = k;
    // Per entry of `loopTraj`, its trajectory's last point: a walker steps on without reading
    // the trajectory's record.
    this.lastPoint = new Uint32Array(lib.trajCount);
    for (let j = 0; j < lib.trajCount; j++) {
      const t = this.loopTraj[j];
      this.lastPoint[j] = lib.traj[7 * t + 4] + lib.traj[7 * t + 5] - 1;
    }
    // Per walker: its loop and lap, and its cursor (-1: none yet).
    const n = lib.walkerCount;
    this.walkerLoop = new Uint32Array(n);
    this.walkerLap = new Uint32Array(n);
    let id = 0;
    for (let c = 0; c < nLoops; c++) {
      for (let lap = 0; lap < lib.chars[3 * c + 2]; lap++) {
        this.walkerLoop[id] = c;
        this.walkerLap[id] = lap;
        id++;
      }
    }
    // Per walker, the tick its loop time counts from, and its loop's length.
    // Per walker, eight numbers side by side (a frame reads them in one sweep): the tick its
    // loop time counts from, its loop's length, the loop times its piece starts and ends at
    // (none yet: +inf), its world position at the piece's start, its velocity (m per tick).
    this.hot = new Float64Array(8 * n);
    for (let i = 0; i < n; i++) {
      const c = this.walkerLoop[i];
      this.hot[8 * i] = this.loopEpoch[c] + this.walkerLap[i] * this.period;
      this.hot[8 * i + 1] = this.loopLength[c];
      this.hot[8 * i + 2] = Infinity;
    }
    this.curK = new Int32Array(n).fill(-1); // index into loopTraj
    this.curP = new Uint32Array(n); // the point that starts the piece

    // The way it faces on the piece, a unit vector (a frame then needs no trigonometry).
    this.facing = new Float32Array(2 * n);
    // Per trajectory: its patch's origin.
    this.originX = new Float32Array(lib.trajCount);
    this.originY = new Float32Array(lib.trajCount);
    for (let t = 0; t < lib.trajCount; t++) {
      const p = lib.traj[7 * t];
      this.originX[t] = lib.patches[6 * p] * w.side;
      this.originY[t] = lib.patches[6 * p + 1] * w.side;
    }
    // Standers never move: placed once.
    this.standers = new Float32Array(2 * lib.standerCount);
    for (let p = 0; p < lib.patchCount; p++) {
      const first = lib.patches[6 * p + 4];
      const count = lib.patches[6 * p + 5];
      for (let s = first; s < first + count; s++) {
        this.standers[2 * s] = lib.patches[6 * p] * w.side + lib.standers[2 * s] * this.step;
        this.standers[2 * s + 1] = lib.patches[6 * p + 1] * w.side + lib.standers[2 * s + 1] * this.step;
      }
    }
  }

  /// Puts walker `i`'s cursor on the piece holding loop time `tau`, searching.
  seek(i, tau) {
    const lib = this.lib;
    const c = this.walkerLoop[i];
    let lo = this.loopFirst[c];
    let hi = this.loopFirst[c + 1] - 1;
    while (lo < hi) {
      const mid = (lo + hi + 1) >> 1;
      if (this.loopStart[mid] <= tau) lo = mid;
      else hi = mid - 1;
    }
    const t = this.loopTraj[lo];
    const first = lib.traj[7 * t + 4];
    const last = first + lib.traj[7 * t + 5] - 1;
    const local = tau - this.loopStart[lo];
    let a = first;
    let b = last - 1;
    while (a < b) {
      const mid = (a + b + 1) >> 1;
      if (lib.pts[2 * mid + 1] <= local) a = mid;
      else b = mid - 1;
    }
    this.enter(i, lo, a);
  }

  /// Puts walker `i` on the piece from point `p` of the loop's `k`-th trajectory.
  enter(i, k, p) {
    const pts = this.lib.pts;
    const t = this.loopTraj[k];
    const step = this.step;
    const xy0 = pts[2 * p];
    const xy1 = pts[2 * p + 2];
    const a = this.loopStart[k] + pts[2 * p + 1];
    const b = this.loopStart[k] + pts[2 * p + 3];
    const dx = (xy1 & 0xffff) - (xy0 & 0xffff);
    const dy = (xy1 >>> 16) - (xy0 >>> 16);
    const span = b - a;
    this.curK[i] = k;
    this.curP[i] = p;
    const h = this.hot;
    const o = 8 * i;
    h[o + 2] = a;
    h[o + 3] = b;
    h[o + 4] = this.originX[t] + (xy0 & 0xffff) * step;
    h[o + 5] = this.originY[t] + (xy0 >>> 16) * step;
    h[o + 6] = span > 0 ? (dx * step) / span : 0;
    h[o + 7] = span > 0 ? (dy * step) / span : 0;
    if (dx !== 0 || dy !== 0) {
      const inv = 1 / Math.sqrt(dx * dx + dy * dy);
      this.facing[2 * i] = dx * inv;
      this.facing[2 * i + 1] = dy * inv;
    } else {
      this.stand(i, p, t);
    }
  }

  /// Moves walker `i`'s cursor forward to the piece holding `tau` (a little later than its
  /// piece), or searches when that is far.
  advance(i, tau) {
    const lib = this.lib;
    for (let steps = 0; steps < 8; steps++) {
      let k = this.curK[i];
      let p = this.curP[i] + 1;
      if (p >= this.lastPoint[k]) {
        // On to the loop's next trajectory (round to its first at the loop's end).
        const c = this.walkerLoop[i];
        k = k + 1 < this.loopFirst[c + 1] ? k + 1 : this.loopFirst[c];
        if (k === this.loopFirst[c]) return this.seek(i, tau);
        p = lib.traj[7 * this.loopTraj[k] + 4];
      }
      this.enter(i, k, p);
      if (tau < this.hot[8 * i + 3]) return;
    }
    this.seek(i, tau);
  }

  /// Faces walker `i`, standing on the piece from point `p` of trajectory `t`, the way its
  /// last walking piece in the trajectory went (the next one's, at its start; east if it
  /// never walks): a frame depends only on its time.
  stand(i, p, t) {
    const lib = this.lib;
    const first = lib.traj[7 * t + 4];
    const last = first + lib.traj[7 * t + 5] - 1;
    let dx = 0;
    let dy = 0;
    for (let k = p; k > first && dx === 0 && dy === 0; k--) {
      dx = lib.x(k) - lib.x(k - 1);
      dy = lib.y(k) - lib.y(k - 1);
    }
    for (let k = p + 1; k < last && dx === 0 && dy === 0; k++) {
      dx = lib.x(k + 1) - lib.x(k);
      dy = lib.y(k + 1) - lib.y(k);
    }
    const len = Math.sqrt(dx * dx + dy * dy);
    this.facing[2 * i] = len > 0 ? dx / len : 1;
    this.facing[2 * i + 1] = len > 0 ? dy / len : 0;
  }

  /// Every character's world position at `seconds` into `out` (x, y per character: walkers
  /// by id, then standers). The way each walker faces is then in `facing` (cos, sin of its
  /// heading per walker: the way its piece goes; standing, see `stand`).
  sample(seconds, out) {
    const ticks = seconds / TICK_S;
    const n = this.lib.walkerCount;
    const hot = this.hot;
    for (let i = 0; i < n; i++) {
      const o = 8 * i;
      const len = hot[o + 1];
      let tau = ticks - hot[o];
      if (tau < 0 || tau >= len) tau -= len * Math.floor(tau / len);
      if (tau < hot[o + 2]) this.seek(i, tau);
      else if (tau >= hot[o + 3]) this.advance(i, tau);
      const u = tau - hot[o + 2];
      out[2 * i] = hot[o + 4] + hot[o + 6] * u;
      out[2 * i + 1] = hot[o + 5] + hot[o + 7] * u;
    }
    out.set(this.standers, 2 * n);
  }
}
