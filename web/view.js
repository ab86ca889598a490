/* SPDX-License-Identifier: MIT */
// view.js - the before/after viewers: two WebGL canvases sharing one orbit
// camera (so they always show the same side), each mesh one indexed
// BufferGeometry made from the fields document's typed arrays (one draw
// call per mesh, no per-vertex objects), coloured per vertex through a
// colour map whose scale can be shared by both views, with legends.
import * as THREE from './three.module.js';
import { OrbitControls } from './OrbitControls.js';

const BACKGROUND = 0xf2f4f7;
const PLAIN = [0.72, 0.74, 0.78];

// Cool-warm (diverging, for curvature: white is zero) and a sequential map
// (for displacement: white is none), as colour stops over t in [0, 1].
const DIVERGING = [[0.23, 0.30, 0.75], [0.55, 0.69, 0.99], [0.87, 0.87, 0.87],
                   [0.96, 0.60, 0.48], [0.71, 0.02, 0.15]];
const SEQUENTIAL = [[0.93, 0.93, 0.93], [0.99, 0.80, 0.45], [0.94, 0.45, 0.18],
                    [0.70, 0.09, 0.16], [0.35, 0.0, 0.25]];

// The renderer takes vertex colours as linear RGB and writes sRGB; the
// maps (and the legends' 2D canvas) are sRGB: the mesh gets each channel
// through the sRGB transfer function so that it shows the legend's colours
// (without it the mesh was a paler map than its legend).
function toLinear(c) {
  return c <= 0.04045 ? c / 12.92 : Math.pow((c + 0.055) / 1.055, 2.4);
}

function mapColour(stops, t, out, o) {
  t = Math.min(1, Math.max(0, t)) * (stops.length - 1);
  const i = Math.min(stops.length - 2, Math.floor(t)), f = t - i;
  const a = stops[i], b = stops[i + 1];
  out[o] = a[0] + (b[0] - a[0]) * f;
  out[o + 1] = a[1] + (b[1] - a[1]) * f;
  out[o + 2] = a[2] + (b[2] - a[2]) * f;
}

// The default scale of a field from the daemon's robust stats of one mesh
// (the smoothed one when there is one: a noisy input then saturates where
// it is noisy instead of flattening the result to grey): [0, p98] for
// displacement; for curvature [min(p02, 0), max(p98, 0)], which the
// diverging map shows with zero in its middle (position), or +-a when the
// field has one sign. Measured on the noisy knot (tests/test_ui.mjs): the
// former default, symmetric over both meshes' extremes, coloured the
// smoothed knot nearly uniformly.
export function defaultScale(field, stats) {
  if (!stats) return [0, 1];
  if (field === 'displacement') return [0, stats.p98 || 1];
  let lo = Math.min(stats.p02 ?? 0, 0), hi = Math.max(stats.p98 ?? 0, 0);
  if (lo === 0) lo = -hi;
  if (hi === 0) hi = -lo;
  return lo < hi ? [lo, hi] : [-1, 1];
}

// Where x falls on the scale [lo, hi], 0..1. A diverging scale that spans
// zero puts zero at the middle (white) and stretches each side to its own
// end; any other scale is linear.
export function position(x, lo, hi, diverging) {
  if (diverging && lo < 0 && hi > 0) return x < 0 ? 0.5 - 0.5 * x / lo : 0.5 + 0.5 * x / hi;
  return (x - lo) / (hi > lo ? hi - lo : 1);
}

export class Compare {
  constructor(canvases, legends) {
    this.camera = new THREE.PerspectiveCamera(35, 4 / 3, 1e-3, 1e3);
    this.views = canvases.map((c, i) => this.#view(c, legends[i]));
    this.pending = false;
    this.waiting = []; // frame()'s resolvers
    const ro = new ResizeObserver(() => this.#resize());
    canvases.forEach(c => ro.observe(c));
  }

  #view(canvas, legend) {
    const renderer = new THREE.WebGLRenderer({ canvas, antialias: true,
                                               preserveDrawingBuffer: true });
    renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    const scene = new THREE.Scene();
    scene.background = new THREE.Color(BACKGROUND);
    scene.add(new THREE.HemisphereLight(0xffffff, 0x50505a, 1.6));
    const light = new THREE.DirectionalLight(0xffffff, 1.4);
    scene.add(light);
    const controls = new OrbitControls(this.camera, canvas);
    controls.addEventListener('change', () => this.render());
    canvas.addEventListener('keydown', e => this.#key(e, controls));
    return { canvas, legend, renderer, scene, light, controls, mesh: null };
  }

  // Arrow keys orbit, +/- zoom (the canvases are focusable).
  #key(e, controls) {
    const off = this.camera.position.clone().sub(controls.target);
    const sph = new THREE.Spherical().setFromVector3(off);
    const step = 0.12;
    switch (e.key) {
    case 'ArrowLeft': sph.theta -= step; break;
    case 'ArrowRight': sph.theta += step; break;
    case 'ArrowUp': sph.phi = Math.max(0.05, sph.phi - step); break;
    case 'ArrowDown': sph.phi = Math.min(Math.PI - 0.05, sph.phi + step); break;
    case '+': case '=': sph.radius /= 1.15; break;
    case '-': sph.radius *= 1.15; break;
    default: return;
    }
    e.preventDefault();
    this.camera.position.copy(controls.target).add(off.setFromSpherical(sph));
    controls.update();
  }

  #resize() {
    for (const v of this.views) {
      const w = v.canvas.clientWidth, h = v.canvas.clientHeight;
      if (w && h) v.renderer.setSize(w, h, false);
    }
    const c = this.views[0].canvas;
    if (c.clientWidth && c.clientHeight) {
      this.camera.aspect = c.clientWidth / c.clientHeight;
      this.camera.updateProjectionMatrix();
    }
    this.render();
  }

  // Shows the two meshes: positions (Float32Array, 3 per vertex; null:
  // that view is emptied) and the shared faces (Uint32Array), replacing
  // what was shown; the camera frames the first.
  setMeshes(positionsList, faces) {
    const index = new THREE.BufferAttribute(faces, 1);
    this.views.forEach((v, i) => {
      if (v.mesh) {
        v.scene.remove(v.mesh);
        v.mesh.geometry.dispose();
        v.mesh.material.dispose();
        v.mesh = null;
      }
      if (!positionsList[i]) return this.#legend(v.legend, null);
      const g = new THREE.BufferGeometry();
      g.setIndex(index);
      g.setAttribute('position', new THREE.BufferAttribute(positionsList[i], 3));
      g.computeVertexNormals();
      const n = positionsList[i].length / 3;
      g.setAttribute('color', new THREE.BufferAttribute(new Float32Array(3 * n), 3));
      g.computeBoundingSphere();
      const m = new THREE.MeshLambertMaterial({ vertexColors: true, side: THREE.DoubleSide });
      v.mesh = new THREE.Mesh(g, m);
      v.scene.add(v.mesh);
    });
    this.resetView();
    this.render();
  }

  // Whether view i shows a mesh.
  has(i) {
    return this.views[i].mesh !== null;
  }

  resetView() {
    const v = this.views[0];
    if (!v.mesh) return;
    const s = v.mesh.geometry.boundingSphere;
    const d = s.radius / Math.sin((this.camera.fov * Math.PI) / 360) * 1.05;
    this.camera.near = d / 100;
    this.camera.far = d * 100;
    this.camera.position.set(s.center.x, s.center.y + 0.15 * d, s.center.z + d);
    this.camera.updateProjectionMatrix();
    for (const w of this.views) {
      w.controls.target.copy(s.center);
      w.controls.update();
    }
    this.render();
  }

  // Colours view i by values (Float32Array, one per vertex; null: plain)
  // over scale [lo, hi] (position); map 'diverging' or 'sequential'.
  colour(i, values, lo, hi, map) {
    const v = this.views[i];
    if (!v.mesh) return;
    const attr = v.mesh.geometry.getAttribute('color');
    const c = attr.array, div = map !== 'sequential', stops = div ? DIVERGING : SEQUENTIAL;
    for (let k = 0, o = 0; o < c.length; k++, o += 3) {
      const x = values ? values[k] : NaN;
      if (Number.isFinite(x)) {
        mapColour(stops, position(x, lo, hi, div), c, o);
        c[o] = toLinear(c[o]);
        c[o + 1] = toLinear(c[o + 1]);
        c[o + 2] = toLinear(c[o + 2]);
      }
      else { c[o] = PLAIN[0]; c[o + 1] = PLAIN[1]; c[o + 2] = PLAIN[2]; }
    }
    attr.needsUpdate = true;
    this.#legend(v.legend, values ? stops : null);
    this.render();
  }

  #legend(canvas, stops) {
    const g = canvas.getContext('2d');
    const w = canvas.width, h = canvas.height, rgb = [0, 0, 0];
    for (let x = 0; x < w; x++) {
      if (stops) mapColour(stops, x / (w - 1), rgb, 0);
      else rgb.splice(0, 3, ...PLAIN);
      g.fillStyle = `rgb(${rgb.map(q => Math.round(q * 255)).join(',')})`;
      g.fillRect(x, 0, 1, h);
    }
  }

  // One frame of both views, at the next animation frame.
  render() {
    if (this.pending) return;
    this.pending = true;
    requestAnimationFrame(() => {
      this.pending = false;
      this.drawNow();
      for (const resolve of this.waiting.splice(0)) resolve();
    });
  }

  // Resolves once the next frame (render()'s) is drawn.
  frame() {
    return new Promise(resolve => {
      this.waiting.push(resolve);
      this.render();
    });
  }

  drawNow() {
    for (const v of this.views) {
      v.light.position.copy(this.camera.position);
      v.renderer.render(v.scene, this.camera);
    }
  }

  // Mean milliseconds of n frames of both views while the camera orbits,
  // each waited for (a one-pixel readback ends the GPU's work).
  benchFrames(n) {
    const px = new Uint8Array(4), t0 = performance.now();
    const c = this.views[0].controls;
    for (let k = 0; k < n; k++) {
      const off = this.camera.position.clone().sub(c.target);
      off.applyAxisAngle(new THREE.Vector3(0, 1, 0), (2 * Math.PI) / n);
      this.camera.position.copy(c.target).add(off);
      this.camera.lookAt(c.target);
      this.drawNow();
      for (const v of this.views) {
        const gl = v.renderer.getContext();
        gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
      }
    }
    return (performance.now() - t0) / n;
  }
}
