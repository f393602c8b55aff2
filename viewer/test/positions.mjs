// Prints, as JSON, where the viewer's own reader and sampler put every character of a library
// at the given times: `node positions.mjs LIBRARY T1 T2 ...`. tests/view.rs holds these to
// crowd-runtime's positions (1 mm). Times are sampled in the order given (forward steps and a
// jump back, as a player scrubs).
import { readFileSync } from 'node:fs';
import { readLibrary } from '../src/library.js';
import { Sampler } from '../src/sampler.js';

const [file, ...times] = process.argv.slice(2);
const bytes = readFileSync(file);
let lib;
try {
  lib = readLibrary(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength));
} catch (e) {
  console.log(JSON.stringify({ error: e.message }));
  process.exit(0);
}
const sampler = new Sampler(lib);
const xy = new Float32Array(2 * lib.characters);
const frames = times.map(Number).map((t) => {
  sampler.sample(t, xy);
  return { t, xy: Array.from(xy) };
});
console.log(JSON.stringify({ characters: lib.characters, walkers: lib.walkerCount, frames }));
