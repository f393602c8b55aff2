// Drives `crowd view`'s page in headless Chromium (Debian's, through playwright-core) and
// prints what it saw as JSON, for tests/view.rs to judge:
//   node e2e.mjs play URL SCREENSHOT.png [X0,Y0,X1,Y1]
//                                          the page of a good build: its stats, how many
//                                          pixels two times and a toggle change, a screenshot
//                                          (of the world, or of that rectangle, metres)
//   node e2e.mjs broken URL                the page of a corrupt library: the error it shows
//   node e2e.mjs bench URL FRAMES          sampling time and frame rate over FRAMES frames
import { chromium } from 'playwright-core';

const [mode, url, arg, region] = process.argv.slice(2);
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium',
  args: [
    '--no-sandbox',
    '--disable-gpu',
    '--disable-quic',
    '--no-first-run',
    '--disable-background-networking',
    '--disable-component-update',
    '--disable-sync',
    '--use-angle=swiftshader',
    '--enable-unsafe-swiftshader',
  ],
});
const out = {};
try {
  const page = await browser.newPage({ viewport: { width: 1200, height: 800 } });
  const logs = [];
  page.on('console', (m) => logs.push(`${m.type()}: ${m.text()}`));
  page.on('pageerror', (e) => logs.push(`pageerror: ${e.message}`));
  await page.goto(url);
  out.ready = await page.evaluate(() => window.crowdViewer.ready);
  out.error = await page.evaluate(() => window.crowdViewer.error);
  out.shown = await page.evaluate(() => {
    const box = document.getElementById('error');
    return box.hidden ? null : box.textContent;
  });
  out.logs = logs;
  if (mode === 'play' && out.ready) {
    await page.evaluate(() => window.crowdViewer.pause());
    // The canvas's pixels at a time, kept in the page under `name` (moving them out would
    // cost more than the rest of the test).
    const snap = (name, t) =>
      page.evaluate(([name, t]) => {
        window.crowdViewer.setTime(t);
        const gl = document.getElementById('view');
        const c = document.createElement('canvas');
        c.width = gl.width;
        c.height = gl.height;
        const g = c.getContext('2d');
        g.drawImage(gl, 0, 0);
        window.snaps ??= {};
        window.snaps[name] = g.getImageData(0, 0, c.width, c.height).data;
        return window.snaps[name].length / 4;
      }, [name, t]);
    // How many pixels differ between two snapshots.
    const differ = (a, b) =>
      page.evaluate(([a, b]) => {
        const x = window.snaps[a];
        const y = window.snaps[b];
        let n = 0;
        for (let i = 0; i < x.length; i += 4) {
          if (x[i] !== y[i] || x[i + 1] !== y[i + 1] || x[i + 2] !== y[i + 2]) n++;
        }
        return n;
      }, [a, b]);
    out.pixels = await snap('at2', 2);
    await snap('at9', 9);
    await snap('again', 2);
    out.stats = await page.evaluate(() => window.crowdViewer.stats());
    out.layers = await page.evaluate(() => window.crowdViewer.layers());
    out.timesDiffer = await differ('at2', 'at9');
    out.sameTimeDiffers = await differ('at2', 'again');
    await page.evaluate(() => window.crowdViewer.toggle('grid', true));
    await snap('grid', 2);
    out.gridDiffers = await differ('at2', 'grid');
    await page.evaluate(() => window.crowdViewer.toggle('grid', false));
    await snap('gridOff', 2);
    out.gridOffDiffers = await differ('at2', 'gridOff');
    // A click on the middle of the first patch shows its crossings and space-time plot.
    const box = await page.evaluate(async () => {
      const scene = await (await fetch('/scene.json')).json();
      const p = scene.patches[0];
      const side = scene.world.side;
      window.crowdViewer.frame(p.col * side, p.row * side, (p.col + 1) * side, (p.row + 1) * side);
      const r = document.getElementById('view').getBoundingClientRect();
      return { x: r.left + r.width / 2, y: r.top + r.height / 2 };
    });
    await page.mouse.click(box.x, box.y);
    // Zoomed in on one patch, only the characters in view are drawn.
    out.zoomed = await page.evaluate(() => window.crowdViewer.stats());
    out.panel = await page.evaluate(() => {
      const panel = document.getElementById('panel');
      return {
        shown: !panel.hidden,
        title: panel.querySelector('h2')?.textContent ?? null,
        crossings: panel.querySelectorAll('tr').length - 1,
        plot: !!panel.querySelector('canvas#spacetime'),
      };
    });
    if (arg) {
      const rect = region ? region.split(',').map(Number) : null;
      await page.evaluate((rect) => {
        const v = window.crowdViewer;
        if (rect) v.frame(...rect);
        v.toggle('grid', true);
        v.setTime(8.5);
      }, rect);
      await page.screenshot({ path: arg });
    }
  }
  if (mode === 'bench' && out.ready) {
    // Sampling at 60 frames a second of crowd time (each frame 1/60 s on, as a player at
    // 60 fps samples), whatever the software renderer's own rate; then that rate, playing.
    const frames = Number(arg ?? 120);
    out.bench = await page.evaluate(async (frames) => {
      const v = window.crowdViewer;
      v.pause();
      // Each frame 1/60 s of crowd time on from 3 s: the median and 95th percentile.
      const stepping = () => {
        const samples = [];
        for (let i = 0; i < frames; i++) {
          v.setTime(3 + i / 60);
          samples.push(v.stats().sampleMs);
        }
        samples.sort((a, b) => a - b);
        return [samples[Math.floor(frames / 2)], samples[Math.floor(frames * 0.95)]];
      };
      const [sampleMsMedian, sampleMsP95] = stepping();
      // Playing, over the whole world, then zoomed in on 40 m: the frame rate, and the
      // sampling of each frame drawn (while software GL draws the frame before).
      const playing = async () => {
        const ms = [];
        for (let i = 0; i < 12; i++) {
          await new Promise((r) => requestAnimationFrame(r));
          if (i > 1) ms.push(v.stats().sampleMs);
        }
        ms.sort((a, b) => a - b);
        return { ...v.stats(), sampleMsMedian: ms[ms.length >> 1], sampleMsMax: ms[ms.length - 1] };
      };
      v.play();
      const whole = await playing();
      const scene = await (await fetch('/scene.json')).json();
      const [w, h] = scene.world.size;
      v.frame(w / 2 - 20, h / 2 - 20, w / 2 + 20, h / 2 + 20);
      const zoomed = await playing();
      // Stepping again, zoomed in: software GL then draws a few hundred characters a frame,
      // not 95k (on 2 cores its threads otherwise take turns with the page's).
      v.pause();
      const [zoomedMedian, zoomedP95] = stepping();
      return {
        characters: whole.characters,
        frames,
        sampleMsMedian,
        sampleMsP95,
        zoomedSampleMsMedian: zoomedMedian,
        zoomedSampleMsP95: zoomedP95,
        playing: whole,
        zoomed,
      };
    }, frames);
  }
} finally {
  await browser.close();
}
console.log(JSON.stringify(out));
