// The overlays a toggle shows over the crowd, from `scene.json` (the build folder's stage
// files, as `crowd view` serves them): the patch grid, requested and measured density as
// colour, requested directions as arrows, obstacles, `crowd check`'s findings, and the edits'
// rectangles (bright while their window is on).

import * as THREE from 'three';

const Z = { density: 0.5, obstacles: 0.8, grid: 1, arrows: 1.5, check: 3, edits: 3.5 };

function lines(points, colour, z) {
  const geometry = new THREE.BufferGeometry();
  const flat = new Float32Array(points.length * 3);
  points.forEach(([x, y], i) => flat.set([x, y, z], 3 * i));
  geometry.setAttribute('position', new THREE.BufferAttribute(flat, 3));
  return new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({ color: colour }));
}

/// Outline segments of the rectangle (x0, y0, x1, y1).
function outline([x0, y0, x1, y1]) {
  return [[x0, y0], [x1, y0], [x1, y0], [x1, y1], [x1, y1], [x0, y1], [x0, y1], [x0, y0]];
}

/// One coloured square per patch: `value(patch)` in people per m2, 0 to `top`.
function densityLayer(scene, value, top) {
  const side = scene.world.side;
  const group = new THREE.Group();
  const geometry = new THREE.PlaneGeometry(side, side);
  for (const p of scene.patches) {
    const v = value(p);
    if (v == null) continue;
    const u = Math.min(v / top, 1);
    const colour = new THREE.Color().setHSL(0.66 - 0.66 * u, 0.8, 0.5);
    const tile = new THREE.Mesh(
      geometry,
      new THREE.MeshBasicMaterial({ color: colour, transparent: true, opacity: 0.45 }),
    );
    tile.position.set((p.col + 0.5) * side, (p.row + 0.5) * side, Z.density);
    group.add(tile);
  }
  return group;
}

/// Every overlay, by toggle name, and whether it starts shown.
export function overlays(scene) {
  const out = new Map();
  if (!scene.world || !scene.patches) return out;
  const side = scene.world.side;
  const grid = [];
  for (const p of scene.patches) grid.push(...outline([p.col * side, p.row * side, (p.col + 1) * side, (p.row + 1) * side]));
  out.set('grid', { object: lines(grid, 0x7a7a8a, Z.grid), on: false });
  const top = Math.max(0.05, ...scene.patches.map((p) => Math.max(p.requested ?? 0, p.measured ?? 0)));
  out.set('requested', { object: densityLayer(scene, (p) => p.requested, top), on: false });
  out.set('measured', { object: densityLayer(scene, (p) => p.measured, top), on: false });
  const arrows = [];
  for (const p of scene.patches) {
    if (!p.direction) continue;
    const [dx, dy] = p.direction;
    const cx = (p.col + 0.5) * side;
    const cy = (p.row + 0.5) * side;
    const l = side * 0.35;
    const tip = [cx + dx * l, cy + dy * l];
    arrows.push([cx - dx * l, cy - dy * l], tip);
    const back = [-dx * l * 0.35, -dy * l * 0.35];
    const ortho = [-dy * l * 0.2, dx * l * 0.2];
    arrows.push(tip, [tip[0] + back[0] + ortho[0], tip[1] + back[1] + ortho[1]]);
    arrows.push(tip, [tip[0] + back[0] - ortho[0], tip[1] + back[1] - ortho[1]]);
  }
  out.set('directions', { object: lines(arrows, 0x1d4ed8, Z.arrows), on: false });
  const boxes = new THREE.Group();
  const dark = new THREE.MeshBasicMaterial({ color: 0x303038 });
  for (const p of scene.patches) {
    for (const [x0, y0, x1, y1] of p.obstacles) {
      const box = new THREE.Mesh(new THREE.PlaneGeometry(x1 - x0, y1 - y0), dark);
      box.position.set(p.col * side + (x0 + x1) / 2, p.row * side + (y0 + y1) / 2, Z.obstacles);
      boxes.add(box);
    }
  }
  out.set('obstacles', { object: boxes, on: true });
  out.set('check', { object: findings(scene), on: true });
  out.set('edits', { object: edits(scene), on: true });
  return out;
}

/// `crowd check`'s findings: a ring where each checked file's worst pair was (red when they
/// collide, grey when it is only the closest), and where its fastest walker was.
function findings(scene) {
  const group = new THREE.Group();
  const check = scene.check;
  if (!check) return group;
  const ring = (x, y, colour, r) => {
    const mesh = new THREE.Mesh(
      new THREE.RingGeometry(r * 0.8, r, 32),
      new THREE.MeshBasicMaterial({ color: colour }),
    );
    mesh.position.set(x, y, Z.check);
    group.add(mesh);
  };
  const parts = [check, check.library, check.gltf].filter(Boolean);
  for (const part of parts) {
    const at = part.worst_at;
    if (Array.isArray(at)) ring(at[0], at[1], part.collisions > 0 ? 0xe11d48 : 0x9ca3af, 1.2);
  }
  return group;
}

/// The edits' rectangles (a meeting's point as a small square), with their windows kept to
/// light them while they are on.
function edits(scene) {
  const group = new THREE.Group();
  group.userData.windows = [];
  for (const e of scene.edits ?? []) {
    let [x0, y0, x1, y1] = e.rect;
    if (x0 === x1 && y0 === y1) {
      x0 -= 0.5; y0 -= 0.5; x1 += 0.5; y1 += 0.5;
    }
    const line = lines(outline([x0, y0, x1, y1]), 0x111111, Z.edits);
    line.userData.window = e.window_s;
    group.add(line);
  }
  return group;
}

/// Lights the edits whose window holds time `t` (seconds of the period `period`).
export function lightEdits(layer, t, period) {
  if (!layer) return;
  for (const line of layer.children) {
    const [a, b] = line.userData.window;
    const on = (t >= a && t <= b) || (b > period && t + period <= b) || Math.abs(t - a) < 0.25;
    line.material.color.set(on ? 0xf59e0b : 0x111111);
  }
}
