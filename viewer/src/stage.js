// The three.js side of the viewer: a top view of the world (x east, y north, metres), the
// painted ground, every character as one instance of one mesh, and pan and zoom from the whole
// world down to one patch.

import * as THREE from 'three';

/// A character from above: a disc of its radius with a nose the way it faces.
function body(radius) {
  // Eight corners (a software renderer draws 94k of these a frame), the first one a nose.
  const shape = new THREE.Shape();
  const n = 8;
  for (let k = 0; k <= n; k++) {
    const a = (k / n) * Math.PI * 2;
    const r = k % n === 0 ? radius * 1.4 : radius;
    const x = Math.cos(a) * r;
    const y = Math.sin(a) * r;
    if (k === 0) shape.moveTo(x, y);
    else shape.lineTo(x, y);
  }
  return new THREE.ShapeGeometry(shape);
}

export class Stage {
  constructor(canvas, world, count, walkers) {
    this.world = world;
    this.renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(1);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0xf4f4f0);
    const [w, h] = world.size;
    this.camera = new THREE.OrthographicCamera(-w / 2, w / 2, h / 2, -h / 2, 0.1, 100);
    this.camera.position.set(w / 2, h / 2, 50);
    this.camera.lookAt(w / 2, h / 2, 0);
    this.view = { x: w / 2, y: h / 2, span: Math.max(w, h) * 1.05 };
    const geometry = body(world.radius);
    const material = new THREE.MeshBasicMaterial({ color: 0xffffff });
    this.people = new THREE.InstancedMesh(geometry, material, Math.max(count, 1));
    this.people.count = count;
    this.people.frustumCulled = false;
    this.people.position.z = 2;
    // Each character's colour; an instance slot takes its character's when the culling in
    // `place` gives it another one.
    this.colours = new Float32Array(3 * count);
    const colour = new THREE.Color();
    for (let i = 0; i < count; i++) {
      if (i < walkers) colour.setHSL(((i * 0.618034) % 1 + 1) % 1, 0.65, 0.45);
      else colour.set(0xc0508a);
      colour.toArray(this.colours, 3 * i);
      this.people.setColorAt(i, colour);
    }
    this.slotOf = Int32Array.from({ length: count }, (_, i) => i);
    this.people.instanceMatrix.setUsage(THREE.DynamicDrawUsage);
    this.scene.add(this.people);
    this.layers = new Map();
  }

  /// The painted ground, a picture over the whole world.
  setGround(texture) {
    const [w, h] = this.world.size;
    texture.magFilter = THREE.NearestFilter;
    texture.colorSpace = THREE.SRGBColorSpace;
    const plane = new THREE.Mesh(
      new THREE.PlaneGeometry(w, h),
      new THREE.MeshBasicMaterial({ map: texture }),
    );
    plane.position.set(w / 2, h / 2, 0);
    this.scene.add(plane);
  }

  /// An overlay that a toggle shows and hides.
  addLayer(name, object, visible) {
    object.visible = visible;
    this.layers.set(name, object);
    this.scene.add(object);
  }

  /// Places the characters in view (a character's radius beyond the edges), one instance
  /// each, and hides the rest: `xy` world positions, `facing` the walkers' (cos, sin) of
  /// their heading (standers face east). Zoomed in on a patch, a frame uploads and draws the
  /// few dozen characters there, not the world's 100k.
  place(xy, facing, walkers) {
    const people = this.people;
    const m = people.instanceMatrix.array;
    const colours = people.instanceColor.array;
    const n = this.colours.length / 3;
    const cam = this.camera;
    const r = this.world.radius + 0.1;
    const x0 = this.view.x + cam.left - r;
    const x1 = this.view.x + cam.right + r;
    const y0 = this.view.y + cam.bottom - r;
    const y1 = this.view.y + cam.top + r;
    let drawn = 0;
    let recoloured = false;
    for (let i = 0; i < n; i++) {
      const x = xy[2 * i];
      const y = xy[2 * i + 1];
      if (x < x0 || x > x1 || y < y0 || y > y1) continue;
      const c = i < walkers ? facing[2 * i] : 1;
      const s = i < walkers ? facing[2 * i + 1] : 0;
      const o = 16 * drawn;
      m[o] = c; m[o + 1] = s; m[o + 2] = 0; m[o + 3] = 0;
      m[o + 4] = -s; m[o + 5] = c; m[o + 6] = 0; m[o + 7] = 0;
      m[o + 8] = 0; m[o + 9] = 0; m[o + 10] = 1; m[o + 11] = 0;
      m[o + 12] = x; m[o + 13] = y; m[o + 14] = 0; m[o + 15] = 1;
      if (this.slotOf[drawn] !== i) {
        this.slotOf[drawn] = i;
        colours[3 * drawn] = this.colours[3 * i];
        colours[3 * drawn + 1] = this.colours[3 * i + 1];
        colours[3 * drawn + 2] = this.colours[3 * i + 2];
        recoloured = true;
      }
      drawn++;
    }
    people.count = drawn;
    people.instanceMatrix.clearUpdateRanges();
    people.instanceMatrix.addUpdateRange(0, 16 * drawn);
    people.instanceMatrix.needsUpdate = true;
    if (recoloured) {
      people.instanceColor.clearUpdateRanges();
      people.instanceColor.addUpdateRange(0, 3 * drawn);
      people.instanceColor.needsUpdate = true;
    }
  }

  /// Fits the camera to the canvas and the view (centre and the span it shows).
  resize() {
    const canvas = this.renderer.domElement;
    const w = canvas.clientWidth;
    const h = canvas.clientHeight;
    this.renderer.setSize(w, h, false);
    const aspect = w / Math.max(h, 1);
    const half = this.view.span / 2;
    const cam = this.camera;
    cam.left = -half * Math.max(aspect, 1);
    cam.right = half * Math.max(aspect, 1);
    cam.top = half / Math.min(aspect, 1);
    cam.bottom = -half / Math.min(aspect, 1);
    cam.position.set(this.view.x, this.view.y, 50);
    cam.updateProjectionMatrix();
    this.onChange?.();
  }

  /// The world point under canvas pixel (px, py).
  worldAt(px, py) {
    const canvas = this.renderer.domElement;
    const cam = this.camera;
    const u = px / canvas.clientWidth;
    const v = py / canvas.clientHeight;
    return [
      this.view.x + cam.left + u * (cam.right - cam.left),
      this.view.y + cam.top - v * (cam.top - cam.bottom),
    ];
  }

  /// Drag to pan, wheel to zoom (round the point under the pointer), from the whole world
  /// down to a few metres.
  controls(onClick) {
    const canvas = this.renderer.domElement;
    let drag = null;
    canvas.addEventListener('pointerdown', (e) => {
      drag = { x: e.clientX, y: e.clientY, moved: false };
      canvas.setPointerCapture(e.pointerId);
    });
    canvas.addEventListener('pointermove', (e) => {
      if (!drag) return;
      const dx = e.clientX - drag.x;
      const dy = e.clientY - drag.y;
      if (Math.abs(dx) + Math.abs(dy) > 2) drag.moved = true;
      const cam = this.camera;
      this.view.x -= (dx / canvas.clientWidth) * (cam.right - cam.left);
      this.view.y += (dy / canvas.clientHeight) * (cam.top - cam.bottom);
      drag.x = e.clientX;
      drag.y = e.clientY;
      this.resize();
    });
    canvas.addEventListener('pointerup', (e) => {
      if (drag && !drag.moved) {
        const r = canvas.getBoundingClientRect();
        onClick(this.worldAt(e.clientX - r.left, e.clientY - r.top));
      }
      drag = null;
    });
    canvas.addEventListener('wheel', (e) => {
      e.preventDefault();
      const r = canvas.getBoundingClientRect();
      const [wx, wy] = this.worldAt(e.clientX - r.left, e.clientY - r.top);
      const f = Math.exp(e.deltaY * 0.0015);
      const [w, h] = this.world.size;
      const span = Math.min(Math.max(this.view.span * f, 4), Math.max(w, h) * 2);
      const k = span / this.view.span;
      this.view.x = wx + (this.view.x - wx) * k;
      this.view.y = wy + (this.view.y - wy) * k;
      this.view.span = span;
      this.resize();
    }, { passive: false });
  }

  /// Shows the world between (x0, y0) and (x1, y1).
  frame(x0, y0, x1, y1) {
    this.view = { x: (x0 + x1) / 2, y: (y0 + y1) / 2, span: Math.max(x1 - x0, y1 - y0) };
    this.resize();
  }

  render() {
    this.renderer.render(this.scene, this.camera);
  }
}
