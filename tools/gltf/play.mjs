// Plays world.glb in three.js as a game would: GLTFLoader, one AnimationMixer, the clip
// `crowd_loop` looping, frames at 60 fps for two periods. Measures what a viewer sees, node
// by node: the fastest turn of a node between frames (deg/s), velocity jumps between frames
// (m/s per frame; a node's own wrap at the clip's end is left out: there a character goes on
// as the node its extras name, `crowd_next`), and, following `crowd_next` at every wrap, the
// characters as one continuous walk through the seams. Prints one JSON line of figures; with
// --follow NODE, also that character's position and heading a frame apart around three seams.
//
// Usage: node play.mjs world.glb [--follow walker_12]
import { readFile } from 'node:fs/promises';
import * as THREE from 'three';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';

const [glbPath, ...rest] = process.argv.slice(2);
const followIndex = rest.indexOf('--follow');
const follow = followIndex >= 0 ? rest[followIndex + 1] : null;

const bytes = await readFile(glbPath);
const buffer = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
const gltf = await new Promise((resolve, reject) =>
  new GLTFLoader().parse(buffer, '', resolve, reject));
const clip = gltf.animations.find((a) => a.name === 'crowd_loop') ?? gltf.animations[0];
const period = clip.duration;
const mixer = new THREE.AnimationMixer(gltf.scene);
mixer.clipAction(clip).setLoop(THREE.LoopRepeat, Infinity).play();

const walkers = [];
gltf.scene.traverse((o) => {
  if (o.name.startsWith('walker_')) walkers.push(o);
});
const byName = new Map(walkers.map((o) => [o.name, o]));
const next = new Map(walkers.map((o) => [o.name, o.userData.crowd_next ?? null]));

// World (x, y) and heading (radians from +x towards +y) of a node: glTF (x, 0, -y), facing +Z
// turned by yaw = heading + pi/2 about +Y.
const euler = new THREE.Euler();
const state = (o) => {
  euler.setFromQuaternion(o.quaternion, 'YXZ');
  return { x: o.position.x, y: -o.position.z, h: euler.y - Math.PI / 2 };
};
const turn = (a, b) => {
  let d = (b - a) % (2 * Math.PI);
  if (d > Math.PI) d -= 2 * Math.PI;
  if (d < -Math.PI) d += 2 * Math.PI;
  return d;
};

const fps = 60;
const dt = 1 / fps;
const frames = Math.round(((follow ? 3.2 : 2) * period) / dt);
let prev = null;
let prevV = null;
let fastestTurn = 0;
let fastestTurnAt = null;
let largestJump = 0;
let largestJumpAt = null;
let seamJump = 0;
let seamJumpAt = null;
let seamTurn = 0;
let seamGap = 0;
const followed = [];
let current = follow;
const mixerStart = performance.now();
for (let f = 0; f <= frames; f++) {
  mixer.setTime(f * dt);
  const now = walkers.map(state);
  if (prev) {
    // Which nodes wrapped between these frames: the clip time went back.
    const wrapped = (f * dt) % period < ((f - 1) * dt) % period;
    const v = now.map((s, i) => ({ x: (s.x - prev[i].x) / dt, y: (s.y - prev[i].y) / dt }));
    for (let i = 0; i < walkers.length; i++) {
      if (wrapped) {
        // The character goes on as crowd_next: compare that node now with this one before.
        const succ = byName.get(next.get(walkers[i].name));
        if (!succ) continue;
        const s = state(succ);
        const gap = Math.hypot(s.x - prev[i].x, s.y - prev[i].y);
        seamGap = Math.max(seamGap, gap - 1.89 * dt);
        seamTurn = Math.max(seamTurn, Math.abs(turn(prev[i].h, s.h)) / dt);
        if (prevV) {
          const vs = { x: (s.x - prev[i].x) / dt, y: (s.y - prev[i].y) / dt };
          const jump = Math.hypot(vs.x - prevV[i].x, vs.y - prevV[i].y);
          if (jump > seamJump) {
            seamJump = jump;
            seamJumpAt = { node: walkers[i].name, t: f * dt };
          }
        }
        continue;
      }
      const rate = Math.abs(turn(prev[i].h, now[i].h)) / dt;
      if (rate > fastestTurn) {
        fastestTurn = rate;
        fastestTurnAt = { node: walkers[i].name, t: f * dt };
      }
      if (prevV) {
        const jump = Math.hypot(v[i].x - prevV[i].x, v[i].y - prevV[i].y);
        if (jump > largestJump) {
          largestJump = jump;
          largestJumpAt = { node: walkers[i].name, t: f * dt };
        }
      }
    }
    prevV = wrapped ? null : v;
  }
  if (current) {
    const node = byName.get(current);
    const t = f * dt;
    const s = state(node);
    followed.push({ t: +t.toFixed(4), node: current, x: +s.x.toFixed(4), y: +s.y.toFixed(4), heading_deg: +((s.h * 180) / Math.PI).toFixed(2) });
    const tn = (f + 1) * dt;
    if (tn % period < t % period) current = next.get(current);
  }
  prev = now;
}
const mixerMs = (performance.now() - mixerStart) / (frames + 1);
const figures = {
  file: glbPath,
  nodes: walkers.length,
  named: walkers.filter((o) => byName.has(o.userData.crowd_next)).length,
  period_s: period,
  frames: frames + 1,
  fastest_turn_deg_s: (fastestTurn * 180) / Math.PI,
  fastest_turn_at: fastestTurnAt,
  largest_velocity_change_per_frame_m_s: largestJump,
  largest_velocity_change_at: largestJumpAt,
  seam_fastest_turn_deg_s: (seamTurn * 180) / Math.PI,
  seam_largest_velocity_change_m_s: seamJump,
  seam_largest_velocity_change_at: seamJumpAt,
  seam_gap_beyond_a_walk_m: Math.max(0, seamGap),
  mixer_ms_per_frame: mixerMs,
};
console.log(JSON.stringify(figures));
if (follow) {
  // A frame either side of each of the first three seams the character passes.
  const seams = [];
  for (let i = 1; i < followed.length && seams.length < 3; i++) {
    if (followed[i].node !== followed[i - 1].node || followed[i].t % period < followed[i - 1].t % period) {
      seams.push(i);
    }
  }
  for (const i of seams) {
    for (const row of followed.slice(Math.max(0, i - 2), i + 2)) console.log(JSON.stringify(row));
    console.log('--');
  }
}
