// What a click on a patch shows: its entry and exit points (the crossings of its borders,
// where and when) and its space-time plot (each trajectory's x and y against time over one
// period, entries as dots, exits as rings), read from the library itself.

import { QUANT_STEPS, TICK_S } from './library.js';

/// The index of the patch at cell (col, row), or -1.
export function patchAt(lib, col, row) {
  for (let i = 0; i < lib.patchCount; i++) {
    if (lib.patches[6 * i] === col && lib.patches[6 * i + 1] === row) return i;
  }
  return -1;
}

function crossingRow(lib, c, kind) {
  const t = (lib.crossings.t[c] * TICK_S).toFixed(2);
  const x = lib.crossings.x[c].toFixed(2);
  const y = lib.crossings.y[c].toFixed(2);
  return `<tr><td>${kind}</td><td>${c}</td><td>(${x}, ${y})</td><td>${t} s</td></tr>`;
}

/// Fills `panel` (an element) with patch `p` of `lib`.
export function showPatch(panel, lib, p) {
  const patch = lib.patch(p);
  const side = lib.world.side;
  const period = lib.world.periodTicks;
  const entries = [];
  const exits = [];
  for (let c = 0; c < lib.crossingCount; c++) {
    if (lib.crossings.to[c] === p) entries.push(c);
    if (lib.crossings.from[c] === p) exits.push(c);
  }
  const rows = [
    ...entries.map((c) => crossingRow(lib, c, 'entry')),
    ...exits.map((c) => crossingRow(lib, c, 'exit')),
  ].join('');
  panel.innerHTML = `
    <h2>Patch ${p} <small>(col ${patch.col}, row ${patch.row}: x ${patch.col * side}-${(patch.col + 1) * side} m, y ${patch.row * side}-${(patch.row + 1) * side} m)</small></h2>
    <p>${patch.trajectories} trajectories, ${patch.standers} standers, ${entries.length} entry and ${exits.length} exit points.</p>
    <canvas id="spacetime" width="420" height="300"></canvas>
    <p class="legend">Space-time: x (top) and y (bottom), patch metres, against time over one period; dots = entries, rings = exits.</p>
    <table><tr><th></th><th>crossing</th><th>place (m)</th><th>time</th></tr>${rows}</table>`;
  const canvas = panel.querySelector('#spacetime');
  const g = canvas.getContext('2d');
  const W = canvas.width;
  const H = canvas.height / 2;
  g.fillStyle = '#fff';
  g.fillRect(0, 0, W, 2 * H);
  g.strokeStyle = '#ccc';
  g.strokeRect(0.5, 0.5, W - 1, H - 1);
  g.strokeRect(0.5, H + 0.5, W - 1, H - 1);
  const step = side / QUANT_STEPS;
  const px = (tick) => ((tick % period) / period) * W;
  const py = (v, axis) => axis * H + H - (v * step / side) * (H - 8) - 4;
  for (let tr = patch.firstTrajectory; tr < patch.firstTrajectory + patch.trajectories; tr++) {
    const t = lib.trajectory(tr);
    const hue = (tr * 137.5) % 360;
    g.strokeStyle = `hsl(${hue} 60% 45%)`;
    g.fillStyle = g.strokeStyle;
    for (const [axis, value] of [[0, (k) => lib.x(k)], [1, (k) => lib.y(k)]]) {
      g.beginPath();
      let prev = null;
      for (let k = t.firstPoint; k < t.firstPoint + t.points; k++) {
        const tick = t.start + lib.t(k);
        const x = px(tick);
        const y = py(value(k), axis);
        // A wrap past the period starts the line again at the left.
        if (prev === null || x < prev) g.moveTo(x, y);
        else g.lineTo(x, y);
        prev = x;
      }
      g.stroke();
      const first = t.firstPoint;
      const last = t.firstPoint + t.points - 1;
      g.beginPath();
      g.arc(px(t.start), py(value(first), axis), 3, 0, Math.PI * 2);
      g.fill();
      g.beginPath();
      g.arc(px(t.start + lib.t(last)), py(value(last), axis), 3.5, 0, Math.PI * 2);
      g.stroke();
    }
  }
  panel.hidden = false;
}
