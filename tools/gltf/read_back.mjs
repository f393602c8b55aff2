// Reads world.glb back with glTF Transform (an independent reader) and checks it against what
// the Rust test expects: node count, one looping clip of exactly one period, and positions of
// named nodes at given times within 1 mm. Usage: node read_back.mjs world.glb expected.json
import { readFile } from 'node:fs/promises';
import { NodeIO } from '@gltf-transform/core';

const [glbPath, expectedPath] = process.argv.slice(2);
const expected = JSON.parse(await readFile(expectedPath, 'utf8'));
const doc = await new NodeIO().read(glbPath);
const root = doc.getRoot();
const fail = (msg) => { console.log(`read_back: ${msg}`); process.exit(1); };

const nodes = root.listNodes();
if (nodes.length !== expected.nodes) fail(`${nodes.length} nodes, expected ${expected.nodes}`);
const animations = root.listAnimations();
if (animations.length !== 1) fail(`${animations.length} animations, expected 1`);
const clip = animations[0];
if (!clip.getName().endsWith('_loop')) fail(`clip name ${clip.getName()} does not end in _loop`);
const extras = clip.getExtras();
if (extras.loop !== true || Math.abs(extras.period - expected.period) > 1e-9) fail(`clip extras ${JSON.stringify(extras)}`);
let start = Infinity, end = -Infinity;
const translation = new Map();
for (const ch of clip.listChannels()) {
  const input = ch.getSampler().getInput().getArray();
  start = Math.min(start, input[0]);
  end = Math.max(end, input[input.length - 1]);
  if (ch.getTargetPath() === 'translation') translation.set(ch.getTargetNode().getName(), ch.getSampler());
}
if (Math.abs(start) > 1e-6 || Math.abs(end - expected.period) > 1e-4) fail(`clip spans ${start}..${end}, expected 0..${expected.period}`);

let worst = 0;
for (const s of expected.samples) {
  const sampler = translation.get(s.node);
  if (!sampler) fail(`no translation channel for ${s.node}`);
  const t = sampler.getInput().getArray();
  const v = sampler.getOutput().getArray();
  let k = 0;
  while (k + 1 < t.length && t[k + 1] <= s.t) k++;
  const k1 = Math.min(k + 1, t.length - 1);
  const f = k1 > k ? (s.t - t[k]) / (t[k1] - t[k]) : 0;
  const p = [0, 1, 2].map((i) => v[3 * k + i] + f * (v[3 * k1 + i] - v[3 * k + i]));
  const d = Math.hypot(p[0] - s.pos[0], p[1] - s.pos[1], p[2] - s.pos[2]);
  worst = Math.max(worst, d);
  if (d > 1e-3) fail(`${s.node} at ${s.t} s: at ${p}, expected ${s.pos} (${d} m off)`);
}
console.log(`read_back: ${nodes.length} nodes, clip 0..${end} s, ${expected.samples.length} samples within ${worst.toExponential(2)} m`);
