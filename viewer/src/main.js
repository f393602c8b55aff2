// The page of `crowd view`: reads the build folder's `library.crowd` with its own reader,
// draws every character over the painted ground, plays it, and exposes `window.crowdViewer`
// for tests (ours and anyone's): stats(), setTime(s), play(), pause(), toggle(name, on).

import * as THREE from 'three';
import { readLibrary, TICK_S } from './library.js';
import { Sampler } from './sampler.js';
import { Stage } from './stage.js';
import { overlays, lightEdits } from './overlays.js';
import { patchAt, showPatch } from './panel.js';

const $ = (id) => document.getElementById(id);

/// Shows what went wrong on the page, in words, instead of a blank screen.
function fail(message) {
  const box = $('error');
  box.textContent = message;
  box.hidden = false;
  window.crowdViewer.error = message;
}

async function fetchOk(url, what) {
  const response = await fetch(url);
  if (!response.ok) throw new Error(`${what}: ${response.status} ${await response.text()}`);
  return response;
}

async function start() {
  const bytes = await (await fetchOk('/files/library.crowd', 'library.crowd')).arrayBuffer();
  let lib;
  try {
    lib = readLibrary(bytes);
  } catch (e) {
    throw new Error(`library.crowd cannot be played: ${e.message}`);
  }
  let scene = {};
  try {
    scene = await (await fetchOk('/scene.json', 'scene.json')).json();
  } catch (e) {
    console.warn(e);
  }
  const world = scene.world ?? {
    size: [lib.world.cols * lib.world.side, lib.world.rows * lib.world.side],
    side: lib.world.side,
  };
  world.radius = lib.world.radius;
  const sampler = new Sampler(lib);
  const count = lib.characters;
  const xy = new Float32Array(2 * count);
  const stage = new Stage($('view'), world, count, lib.walkerCount);
  // The ground first, so that every frame from `ready` on has it (a folder without merge.ron
  // has none: the page goes on without).
  await new Promise((done) => {
    const ground = (t) => {
      stage.setGround(t);
      done();
    };
    new THREE.TextureLoader().load('/ground.png', ground, undefined, () => done());
  });
  const layers = overlays(scene);
  for (const [name, { object, on }] of layers) {
    stage.addLayer(name, object, on);
    const box = $('toggles').appendChild(document.createElement('label'));
    box.innerHTML = `<input type="checkbox" data-layer="${name}"${on ? ' checked' : ''}> ${name}`;
    box.querySelector('input').addEventListener('change', (e) => toggle(name, e.target.checked));
  }
  stage.onChange = () => draw();
  stage.controls(([x, y]) => {
    const p = patchAt(lib, Math.floor(x / lib.world.side), Math.floor(y / lib.world.side));
    if (p >= 0) showPatch($('panel'), lib, p);
    else $('panel').hidden = true;
  });
  const period = lib.world.periodTicks * TICK_S;
  const state = { time: 0, playing: true, speed: 1, fps: 0, sampleMs: 0, last: null, frames: [] };
  const scrub = $('time');
  scrub.max = String(period);
  scrub.addEventListener('input', () => setTime(Number(scrub.value)));
  $('play').addEventListener('click', () => (state.playing ? pause() : play()));
  $('speed').addEventListener('change', (e) => (state.speed = Number(e.target.value)));

  function draw() {
    const t0 = performance.now();
    sampler.sample(state.time, xy);
    state.sampleMs = performance.now() - t0;
    stage.place(xy, sampler.facing, lib.walkerCount);
    lightEdits(stage.layers.get('edits'), state.time % period, period);
    stage.render();
    scrub.value = String(state.time % period);
    $('clock').textContent = `${(state.time % period).toFixed(2)} / ${period.toFixed(0)} s`;
    $('stats').textContent = `${count} characters (${stage.people.count} in view), sampling ${state.sampleMs.toFixed(2)} ms, ${state.fps.toFixed(0)} fps`;
  }
  function frame(now) {
    // Paused, a frame is drawn only when something changes (setTime, toggle, pan, zoom).
    if (state.playing) {
      if (state.last !== null) {
        state.time = (state.time + ((now - state.last) / 1000) * state.speed) % period;
      }
      // Over the last ten frames, however long they took (software GL draws 94k people at a
      // few frames a second).
      state.frames.push(now);
      if (state.frames.length > 10) state.frames.shift();
      const n = state.frames.length;
      state.fps = n > 1 ? ((n - 1) * 1000) / (now - state.frames[0]) : 0;
      draw();
    }
    state.last = now;
    requestAnimationFrame(frame);
  }
  function setTime(seconds) {
    state.time = ((seconds % period) + period) % period;
    draw();
  }
  function play() {
    state.playing = true;
    $('play').textContent = 'pause';
  }
  function pause() {
    state.playing = false;
    $('play').textContent = 'play';
  }
  function toggle(name, on) {
    const layer = stage.layers.get(name);
    if (!layer) throw new Error(`no layer ${name}; the layers are ${[...stage.layers.keys()].join(', ')}`);
    layer.visible = on;
    const box = document.querySelector(`input[data-layer="${name}"]`);
    if (box) box.checked = on;
    draw();
  }
  window.addEventListener('resize', () => {
    stage.resize();
    draw();
  });
  stage.resize();
  Object.assign(window.crowdViewer, {
    stats: () => ({
      characters: count,
      drawn: stage.people.count,
      time: state.time,
      fps: state.fps,
      sampleMs: state.sampleMs,
    }),
    setTime,
    play,
    pause,
    toggle,
    layers: () => [...stage.layers.keys()],
    frame: (x0, y0, x1, y1) => {
      stage.frame(x0, y0, x1, y1);
      draw();
    },
  });
  draw();
  requestAnimationFrame(frame);
}

window.crowdViewer = { error: null };
window.crowdViewer.ready = start().then(
  () => true,
  (e) => {
    fail(e.message);
    return false;
  },
);
