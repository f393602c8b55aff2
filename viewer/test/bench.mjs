// Times the viewer's sampler in Node (V8, as Chromium): `node bench.mjs LIBRARY [FRAMES]`
// samples every character at 60 frames a second from t = 3 s and prints the median and 95th
// percentile milliseconds a frame, as JSON. (The page reports the same figure as
// `stats().sampleMs`; `e2e.mjs bench` measures it there.)
import { readFileSync } from 'node:fs';
import { readLibrary } from '../src/library.js';
import { Sampler } from '../src/sampler.js';

const [file, frames = '600'] = process.argv.slice(2);
const bytes = readFileSync(file);
let clock = performance.now();
const lib = readLibrary(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength));
const readMs = performance.now() - clock;
clock = performance.now();
const sampler = new Sampler(lib);
const setupMs = performance.now() - clock;
const xy = new Float32Array(2 * lib.characters);
const times = [];
for (let k = 0; k < Number(frames); k++) {
  const t0 = performance.now();
  sampler.sample(3 + k / 60, xy);
  times.push(performance.now() - t0);
}
const first = times[0];
times.sort((a, b) => a - b);
console.log(JSON.stringify({
  characters: lib.characters,
  readMs,
  setupMs,
  firstFrameMs: first,
  medianMs: times[Math.floor(times.length / 2)],
  p95Ms: times[Math.floor(times.length * 0.95)],
}));
