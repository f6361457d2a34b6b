// The image beside the mesh (meshpde serve --image VOLUME): three orthogonal slice
// planes in the 3D view (axial, coronal, sagittal in the patient frame), each movable,
// with window/level and the mesh's cut line on each; and a 2D view of one slice where
// the cut line can be dragged to correct the wall in that plane.
//
// The server sends slices on demand (the "SLC " frame, editor/editor_page.h) as 8-bit
// pixels after window/level; the page never holds the volume. One request per plane
// is in flight at a time, and the newest slider position wins.
import * as THREE from 'three';

const AXES = ['axial', 'coronal', 'sagittal'];
const NORMAL = [2, 1, 0];               // the coordinate each plane holds fixed
// The letter of the patient direction each axis points to, in each frame.
const LETTERS = { RAS: ['R', 'A', 'S'], LPS: ['L', 'P', 'S'] };

// Window and level presets: [window, level] in the image's values (Hounsfield units for
// CT); auto and MR are computed from the volume's value range and percentiles.
const PRESETS = { cta: [600, 150], 'ct-soft': [400, 40], 'ct-bone': [1500, 450] };

// invalidate() asks the page to draw its 3D view again (it draws only on change);
// relayout() to size it again (the 2D view docked beside it, or not).
export function createImageView({ scene, state, send, $, correctOptions, invalidate, relayout }) {
  const view = {
    image: null,                        // the mesh message's "image"
    slices: [null, null, null],         // the last SLC frame of each plane, decoded
    latencies: [],                      // ms from a slider move to its slice on screen
    shown: 0,                           // slices applied
  };
  state.imageView = view;
  const planes = [], lines = [];
  // A slice's texture: RGBA bytes, grey in each colour, in sRGB like every other colour
  // on the page. (WebGL 2 has no luminance format with storage, and three.js no longer
  // offers one; a red-only texture would draw red.)
  const sliceTexture = (width, height) => {
    const tex = new THREE.DataTexture(new Uint8Array(4 * width * height), width, height, THREE.RGBAFormat);
    tex.colorSpace = THREE.SRGBColorSpace;
    tex.magFilter = tex.minFilter = THREE.LinearFilter;
    return tex;
  };
  for (let k = 0; k < 3; ++k) {
    const tex = sliceTexture(1, 1);
    const plane = new THREE.Mesh(new THREE.BufferGeometry(),
      new THREE.MeshBasicMaterial({ map: tex, side: THREE.DoubleSide, transparent: true, opacity: 0.92 }));
    plane.visible = false;
    plane.renderOrder = -1;
    const line = new THREE.LineSegments(new THREE.BufferGeometry(),
      new THREE.LineBasicMaterial({ color: 0xffd700, depthTest: false }));
    line.renderOrder = 2;
    line.visible = false;
    scene.add(plane, line);
    planes.push(plane);
    lines.push(line);
  }
  const want = [null, null, null], inflight = [false, false, false], sentAt = new Map();
  let seq = 0;

  // The typed numbers are the window and level (a preset may lie beyond the sliders'
  // range, the volume's values); the sliders follow them.
  const windowLevel = () => ({ window: +$('img-window-value').value, level: +$('img-level-value').value });
  function setWindowLevel(w, l) {
    $('img-window-value').value = +w.toPrecision(6);
    $('img-level-value').value = +l.toPrecision(6);
    $('img-window').value = w;
    $('img-level').value = l;
  }
  function applyPreset() {
    const im = view.image, name = $('img-preset').value;
    if (!im || name === 'custom') return;
    const p1 = im.level - im.window / 2, p99 = im.level + im.window / 2, [vmin, vmax] = im.range;
    const [w, l] = name === 'full' ? [vmax - vmin, (vmax + vmin) / 2]
      : name === 'mr' ? [p99 - vmin, (p99 + vmin) / 2]
        : PRESETS[name] || [im.window, im.level];
    setWindowLevel(Math.max(w, +$('img-window').min || 1e-6), l);
  }
  function request(k) {
    if (!view.image || inflight[k] || !want[k]) return;
    const w = want[k];
    want[k] = null;
    inflight[k] = true;
    seq += 1;
    sentAt.set(seq, w.movedAt);
    send({ type: 'slice', axis: AXES[k], position: w.position, ...windowLevel(), seq });
  }
  function ask(k, movedAt = performance.now()) {
    want[k] = { position: +$(`img-${AXES[k]}`).value, movedAt };
    $(`img-${AXES[k]}-value`).textContent = (+$(`img-${AXES[k]}`).value).toFixed(1);
    request(k);
  }
  const askAll = () => { for (let k = 0; k < 3; ++k) ask(k); };

  // A slice request the server refused (say, a window of 0): nothing is in flight any
  // more, so the sliders ask again on their next move instead of waiting for ever.
  view.onSliceError = () => { inflight.fill(false); };

  // ------------------------------------------------------------ the mesh message
  view.onMeshMessage = (m) => {
    view.image = m.image || null;
    $('image-options').hidden = !view.image;
    $('slice-box').hidden = true;
    layout();
    for (let k = 0; k < 3; ++k) { planes[k].visible = false; lines[k].visible = false; view.slices[k] = null; }
    for (let k = 0; k < 3; ++k) views[k] = { zoom: 1, ca: null, cb: null };
    if (!view.image) return;
    const im = view.image, [lo, hi] = im.bounds;
    const step = Math.min(...im.spacing);
    for (let k = 0; k < 3; ++k) {
      const s = $(`img-${AXES[k]}`), n = NORMAL[k];
      s.min = lo[n]; s.max = hi[n]; s.step = step;
      s.value = (lo[n] + hi[n]) / 2;
    }
    const [vmin, vmax] = im.range;
    const valueStep = (vmax - vmin) / 500 || 1;  // a window is never 0: the server refuses it
    for (const id of ['img-window', 'img-level']) { $(id).min = id === 'img-window' ? valueStep : vmin; $(id).max = vmax; }
    $('img-window').step = $('img-level').step = valueStep;
    $('img-window-value').step = $('img-level-value').step = +valueStep.toPrecision(3);
    $('img-window-value').min = +valueStep.toPrecision(3);
    $('img-preset').value = 'auto';
    setWindowLevel(im.window, im.level);
    $('img-name').textContent = `${im.name}: ${im.dims.join(' × ')} voxels, mesh in ${im.space}`;
    $('slice-box').hidden = $('img-2d').value === 'none';
    // The planes start through the mesh, so that each one cuts the wall: now for a
    // volume uploaded beside a mesh, once its positions are here for a new mesh.
    if (m.type === 'mesh') { centrePending = true; return; }
    centreOnMesh();
    askAll();
  };
  let centrePending = false;
  // Each plane through the centre of the mesh's bounding box (within the volume).
  function centreOnMesh() {
    const P = state.positions, im = view.image;
    if (!P || !im) return;
    const [lo, hi] = im.bounds;
    for (let k = 0; k < 3; ++k) {
      const n = NORMAL[k];
      let a = Infinity, b = -Infinity;
      for (let i = n; i < P.length; i += 3) { a = Math.min(a, P[i]); b = Math.max(b, P[i]); }
      $(`img-${AXES[k]}`).value = Math.min(Math.max((a + b) / 2, lo[n]), hi[n]);
    }
  }
  view.onMeshLoaded = () => {
    if (!centrePending) return;
    centrePending = false;
    centreOnMesh();
    askAll();
  };

  // ------------------------------------------------------------ slices
  view.onSlice = (buf) => {
    const dv = new DataView(buf);
    const k = dv.getUint32(4, true), width = dv.getUint32(8, true), height = dv.getUint32(12, true);
    const id = dv.getUint32(16, true), position = dv.getFloat32(20, true);
    const f = (o) => [dv.getFloat32(o, true), dv.getFloat32(o + 4, true), dv.getFloat32(o + 8, true)];
    const origin = f(24), u = f(36), v = f(48);
    const pixels = new Uint8Array(buf, 60, width * height);
    const arrived = performance.now();
    const s = { axis: k, width, height, position, origin, u, v, pixels };
    view.slices[k] = s;
    // The texture: the grey byte of each pixel, as sent, in R, G and B; row b of the
    // slice is row b of the texture (v up). Same size as the last one: its storage is
    // reused.
    const plane = planes[k];
    let tex = plane.material.map;
    if (tex.image.width !== width || tex.image.height !== height) {
      tex.dispose();
      tex = sliceTexture(width, height);
      plane.material.map = tex;
      plane.material.needsUpdate = true;
    }
    const rgba = tex.image.data;
    for (let i = 0, j = 0; i < pixels.length; ++i, j += 4) {
      rgba[j] = rgba[j + 1] = rgba[j + 2] = pixels[i];
      rgba[j + 3] = 255;
    }
    tex.needsUpdate = true;
    // The quad covers the pixels' squares: half a pixel beyond the outer centres.
    const corner = (a, b) => [0, 1, 2].map((c) => origin[c] + a * u[c] + b * v[c]);
    const a0 = -0.5, a1 = width - 0.5, b0 = -0.5, b1 = height - 0.5;
    const P = [corner(a0, b0), corner(a1, b0), corner(a1, b1), corner(a0, b1)].flat();
    plane.geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(P), 3));
    plane.geometry.setAttribute('uv', new THREE.BufferAttribute(new Float32Array([0, 0, 1, 0, 1, 1, 0, 1]), 2));
    plane.geometry.setIndex([0, 1, 2, 0, 2, 3]);
    plane.geometry.computeBoundingSphere();
    plane.visible = $(`img-${AXES[k]}-show`).checked;
    updateCut(k);
    if (k === twoD()) draw2d();
    const moved = sentAt.get(id);
    sentAt.delete(id);
    // On screen once the next frame has drawn it (texture upload included).
    if (moved !== undefined) {
      const handled = performance.now();
      requestAnimationFrame(() => {
        view.latencies.push({ axis: AXES[k], ms: performance.now() - moved, arrived_ms: arrived - moved,
          page_ms: handled - arrived });
      });
    }
    view.shown += 1;
    inflight[k] = false;
    request(k);  // the newest position, if the slider moved meanwhile
  };

  // ------------------------------------------------------------ cut lines
  // Segments where the mesh's triangles cross plane k: [x0, y0, z0, x1, y1, z1, ...]
  // and, for each segment, the triangle it crosses.
  function cut(k) {
    const s = view.slices[k];
    if (!s || !state.positions || !state.triangles) return { xyz: new Float32Array(0), tri: [] };
    const P = state.positions, T = state.triangles, n = NORMAL[k], c = s.position;
    const out = [], tri = [];
    for (let t = 0; t < T.length; t += 3) {
      const d = [P[3 * T[t] + n] - c, P[3 * T[t + 1] + n] - c, P[3 * T[t + 2] + n] - c];
      if ((d[0] > 0 && d[1] > 0 && d[2] > 0) || (d[0] <= 0 && d[1] <= 0 && d[2] <= 0)) continue;
      const pts = [];
      for (let e = 0; e < 3; ++e) {
        const i = T[t + e], j = T[t + (e + 1) % 3], di = d[e], dj = d[(e + 1) % 3];
        if ((di > 0) === (dj > 0)) continue;
        const w = di / (di - dj);
        for (let q = 0; q < 3; ++q) pts.push(P[3 * i + q] + w * (P[3 * j + q] - P[3 * i + q]));
      }
      if (pts.length === 6) { out.push(...pts); tri.push(t / 3); }
    }
    return { xyz: new Float32Array(out), tri };
  }
  const cuts = [null, null, null];
  function updateCut(k) {
    cuts[k] = cut(k);
    lines[k].geometry.setAttribute('position', new THREE.BufferAttribute(cuts[k].xyz, 3));
    lines[k].geometry.computeBoundingSphere();
    lines[k].visible = planes[k].visible;
    invalidate();
  }
  let cutPending = false;
  view.onPositions = () => {
    if (!view.image || cutPending) return;
    cutPending = true;
    requestAnimationFrame(() => {
      cutPending = false;
      for (let k = 0; k < 3; ++k) if (view.slices[k]) updateCut(k);
      draw2d();
    });
  };

  // ------------------------------------------------------------ the 2D view
  const canvas = $('slice-view'), overlay = $('slice-overlay');
  const twoD = () => AXES.indexOf($('img-2d').value);  // -1: none
  // Zoom and pan of each plane's 2D view: `zoom` times the fit, with slice pixel
  // (ca, cb) at the canvas centre (null: the slice's centre). The wheel zooms about the
  // cursor, a right-button (or shift) drag pans, a double click fits again.
  const views = [0, 1, 2].map(() => ({ zoom: 1, ca: null, cb: null }));
  // Canvas placement of slice k: pixel (a, b) centre at (x0 + (a + 0.5) scale,
  // y0 + (height - b - 0.5) scale), v upwards.
  function fit(s) {
    const z = views[s.axis];
    const scale = z.zoom * Math.min(canvas.width / s.width, canvas.height / s.height);
    const ca = z.ca ?? (s.width / 2 - 0.5), cb = z.cb ?? (s.height / 2 - 0.5);
    return { scale, x0: canvas.width / 2 - (ca + 0.5) * scale, y0: canvas.height / 2 - (s.height - cb - 0.5) * scale };
  }
  function toCanvas(s, p) {
    const { scale, x0, y0 } = fit(s);
    const r = [0, 1, 2].map((c) => p[c] - s.origin[c]);
    const uu = s.u[0] ** 2 + s.u[1] ** 2 + s.u[2] ** 2, vv = s.v[0] ** 2 + s.v[1] ** 2 + s.v[2] ** 2;
    const a = (r[0] * s.u[0] + r[1] * s.u[1] + r[2] * s.u[2]) / uu, b = (r[0] * s.v[0] + r[1] * s.v[1] + r[2] * s.v[2]) / vv;
    return [x0 + (a + 0.5) * scale, y0 + (s.height - b - 0.5) * scale];
  }
  function fromCanvas(s, x, y) {
    const { scale, x0, y0 } = fit(s);
    const a = (x - x0) / scale - 0.5, b = s.height - (y - y0) / scale - 0.5;
    return [0, 1, 2].map((c) => s.origin[c] + a * s.u[c] + b * s.v[c]);
  }
  // The 2D view's canvases take the size of their box (resized by its grip, or docked
  // beside the 3D view); the 3D view is sized again when docking changes.
  let docked = false;
  function layout() {
    const box = $('slice-box');
    const dock = $('img-dock').checked && !box.hidden;
    if (dock !== docked) {
      docked = dock;
      $('viewport').classList.toggle('docked', dock);
      relayout();
    }
    if (box.hidden) return false;
    const w = Math.max(1, box.clientWidth), h = Math.max(1, box.clientHeight);
    if (canvas.width === w && canvas.height === h) return false;
    canvas.width = overlay.width = w;
    canvas.height = overlay.height = h;
    return true;
  }
  view.docked = () => docked;
  const scratch = document.createElement('canvas');
  function draw2d() {
    const k = twoD();
    $('slice-box').hidden = !view.image || k < 0;
    layout();
    if (k < 0 || !view.slices[k]) return;
    const s = view.slices[k];
    scratch.width = s.width; scratch.height = s.height;
    const img = scratch.getContext('2d').createImageData(s.width, s.height);
    for (let b = 0; b < s.height; ++b)        // row b of the slice is canvas row height-1-b
      for (let a = 0; a < s.width; ++a) {
        const g = s.pixels[b * s.width + a], o = 4 * ((s.height - 1 - b) * s.width + a);
        img.data[o] = img.data[o + 1] = img.data[o + 2] = g;
        img.data[o + 3] = 255;
      }
    scratch.getContext('2d').putImageData(img, 0, 0);
    const ctx = canvas.getContext('2d'), { scale, x0, y0 } = fit(s);
    ctx.fillStyle = '#000';
    ctx.fillRect(0, 0, canvas.width, canvas.height);
    ctx.imageSmoothingEnabled = true;
    ctx.drawImage(scratch, x0, y0, scale * s.width, scale * s.height);
    drawOverlay();
  }
  function drawOverlay(dragTo = null) {
    const k = twoD(), ctx = overlay.getContext('2d');
    ctx.clearRect(0, 0, overlay.width, overlay.height);
    if (k < 0 || !view.slices[k] || !cuts[k]) return;
    const s = view.slices[k], xyz = cuts[k].xyz;
    ctx.strokeStyle = '#ffd700';
    ctx.lineWidth = 1.5;
    ctx.beginPath();
    for (let i = 0; i < xyz.length; i += 6) {
      const p = toCanvas(s, xyz.subarray(i, i + 3)), q = toCanvas(s, xyz.subarray(i + 3, i + 6));
      ctx.moveTo(p[0], p[1]);
      ctx.lineTo(q[0], q[1]);
    }
    ctx.stroke();
    // The patient directions of the view's right and top edges, and the plane's place.
    const letters = LETTERS[view.image.space] || ['x', 'y', 'z'];
    const ua = NORMAL[k] === 0 ? 1 : 0, va = NORMAL[k] === 2 ? 1 : 2;
    ctx.font = 'bold 12px system-ui';
    ctx.fillStyle = '#fff';
    ctx.strokeStyle = '#000';
    ctx.lineWidth = 3;
    const label = (text, x, y) => { ctx.strokeText(text, x, y); ctx.fillText(text, x, y); };
    label(letters[ua], overlay.width - 14, overlay.height / 2);
    label(letters[va], overlay.width / 2, 14);
    label(`${AXES[k]} ${'xyz'[NORMAL[k]]} = ${s.position.toFixed(1)} mm`, 6, overlay.height - 6);
    if (drag2d && dragTo) {
      ctx.strokeStyle = '#1f77b4';
      ctx.beginPath();
      ctx.moveTo(drag2d.x, drag2d.y);
      ctx.lineTo(dragTo[0], dragTo[1]);
      ctx.stroke();
    }
  }
  // The 2D view's slice at a canvas point: its pixels interpolated bilinearly (grey
  // 0..255, null outside), and the millimetres one canvas pixel spans. For tests.
  view.sliceGreyAt2d = (x, y) => {
    const k = twoD(), s = k >= 0 ? view.slices[k] : null;
    if (!s) return null;
    const { scale, x0, y0 } = fit(s);
    const a = (x - x0) / scale - 0.5, b = s.height - (y - y0) / scale - 0.5;
    if (a < 0 || b < 0 || a > s.width - 1 || b > s.height - 1) return null;
    const a0 = Math.min(Math.floor(a), s.width - 2), b0 = Math.min(Math.floor(b), s.height - 2), fa = a - a0, fb = b - b0;
    const g = (da, db) => s.pixels[(b0 + db) * s.width + a0 + da];
    return (1 - fb) * ((1 - fa) * g(0, 0) + fa * g(1, 0)) + fb * ((1 - fa) * g(0, 1) + fa * g(1, 1));
  };
  view.zoom2d = () => { const k = twoD(); return k >= 0 ? views[k].zoom : 0; };
  // The slice pixel (a, b) under a canvas point of the 2D view (null without one).
  view.slicePixelAt2d = (x, y) => {
    const k = twoD(), s = k >= 0 ? view.slices[k] : null;
    if (!s) return null;
    const { scale, x0, y0 } = fit(s);
    return [(x - x0) / scale - 0.5, s.height - (y - y0) / scale - 0.5];
  };
  view.mmPerCanvasPixel = () => {
    const k = twoD(), s = k >= 0 ? view.slices[k] : null;
    return s ? Math.hypot(...s.u) / fit(s).scale : 0;
  };
  // An n x n grid of pixel centres of plane k's slice, inside its outer tenth, each as
  // a point of the 3D view and the grey the server sent for it. For tests, which read
  // the rendered 3D view there.
  view.planeSamples3d = (k, n) => {
    const s = view.slices[k], out = [];
    if (!s) return out;
    for (let i = 0; i < n; ++i)
      for (let j = 0; j < n; ++j) {
        const a = Math.round((0.1 + 0.8 * i / (n - 1)) * (s.width - 1));
        const b = Math.round((0.1 + 0.8 * j / (n - 1)) * (s.height - 1));
        out.push({ p: [0, 1, 2].map((c) => s.origin[c] + a * s.u[c] + b * s.v[c]), grey: s.pixels[b * s.width + a] });
      }
    return out;
  };
  // Points of the cut line on the 2D view, for tests: canvas pixels, two a segment.
  view.cutLine2d = () => {
    const k = twoD();
    if (k < 0 || !view.slices[k] || !cuts[k]) return [];
    const s = view.slices[k], xyz = cuts[k].xyz, out = [];
    for (let i = 0; i < xyz.length; i += 3) out.push(toCanvas(s, xyz.subarray(i, i + 3)));
    return out;
  };

  // Dragging the cut line: press near it, release where the wall belongs. The mesh
  // vertex nearest the pressed point (among the crossed triangle's corners) moves by
  // the drag, in the plane, with the correct tool's options.
  let drag2d = null;
  const canvasXY = (ev) => {
    const r = overlay.getBoundingClientRect();
    return [(ev.clientX - r.left) * overlay.width / r.width, (ev.clientY - r.top) * overlay.height / r.height];
  };
  let pan = null;  // {x, y}: the last pointer position of a pan
  overlay.addEventListener('contextmenu', (ev) => ev.preventDefault());
  overlay.addEventListener('wheel', (ev) => {
    const k = twoD(), s = k >= 0 ? view.slices[k] : null;
    if (!s) return;
    ev.preventDefault();
    const [x, y] = canvasXY(ev), before = fit(s);
    const a = (x - before.x0) / before.scale - 0.5, b = s.height - (y - before.y0) / before.scale - 0.5;
    const z = views[k];
    z.zoom = Math.min(64, Math.max(1, z.zoom * Math.pow(1.2, -ev.deltaY / 100)));
    // The slice pixel under the cursor stays under it.
    const scale = z.zoom * Math.min(canvas.width / s.width, canvas.height / s.height);
    z.ca = (canvas.width / 2 - (x - (a + 0.5) * scale)) / scale - 0.5;
    z.cb = s.height - 0.5 - (canvas.height / 2 - (y - (s.height - b - 0.5) * scale)) / scale;
    draw2d();
  }, { passive: false });
  overlay.addEventListener('dblclick', () => {
    const k = twoD();
    if (k < 0) return;
    views[k] = { zoom: 1, ca: null, cb: null };
    draw2d();
  });
  overlay.addEventListener('pointerdown', (ev) => {
    const k = twoD();
    if (k >= 0 && view.slices[k] && (ev.button === 2 || (ev.button === 0 && ev.shiftKey))) {
      const s = view.slices[k], f = fit(s), z = views[k];
      z.ca = (canvas.width / 2 - f.x0) / f.scale - 0.5;
      z.cb = s.height - 0.5 - (canvas.height / 2 - f.y0) / f.scale;
      pan = canvasXY(ev);
      overlay.setPointerCapture(ev.pointerId);
      return;
    }
    if (k < 0 || !view.slices[k] || !cuts[k] || ev.button !== 0) return;
    const s = view.slices[k], [x, y] = canvasXY(ev), xyz = cuts[k].xyz;
    let best = -1, bestD = 10 * 10;  // within 10 canvas pixels of the line
    for (let i = 0; i < xyz.length; i += 3) {
      const p = toCanvas(s, xyz.subarray(i, i + 3)), d = (p[0] - x) ** 2 + (p[1] - y) ** 2;
      if (d < bestD) { bestD = d; best = i; }
    }
    if (best < 0) return;
    const t = cuts[k].tri[Math.floor(best / 6)], P = state.positions, T = state.triangles;
    const at = fromCanvas(s, x, y);
    let vertex = -1, vd = Infinity;
    for (let c = 0; c < 3; ++c) {
      const i = T[3 * t + c], d = (P[3 * i] - at[0]) ** 2 + (P[3 * i + 1] - at[1]) ** 2 + (P[3 * i + 2] - at[2]) ** 2;
      if (d < vd) { vd = d; vertex = i; }
    }
    drag2d = { k, x, y, at, vertex };
    overlay.setPointerCapture(ev.pointerId);
  });
  overlay.addEventListener('pointermove', (ev) => {
    if (pan) {
      const k = twoD(), s = k >= 0 ? view.slices[k] : null;
      if (!s) return;
      const [x, y] = canvasXY(ev), scale = fit(s).scale, z = views[k];
      z.ca -= (x - pan[0]) / scale;
      z.cb += (y - pan[1]) / scale;
      pan = [x, y];
      draw2d();
      return;
    }
    if (drag2d) drawOverlay(canvasXY(ev));
  });
  const end2d = (ev) => {
    if (pan) { pan = null; return; }
    if (!drag2d) return;
    const s = view.slices[drag2d.k], [x, y] = canvasXY(ev), to = fromCanvas(s, x, y);
    const move = [0, 1, 2].map((c) => to[c] - drag2d.at[c]);
    // The surface point under the cut line moves (the server takes the one nearest `at`).
    if (Math.hypot(...move) > 0) send({ type: 'correct', vertex: drag2d.vertex, point: drag2d.at, move, ...correctOptions() });
    view.lastDrag = { vertex: drag2d.vertex, point: drag2d.at, move };
    drag2d = null;
    drawOverlay();
  };
  overlay.addEventListener('pointerup', end2d);
  overlay.addEventListener('pointercancel', end2d);

  // ------------------------------------------------------------ controls
  for (let k = 0; k < 3; ++k) {
    $(`img-${AXES[k]}`).oninput = () => ask(k);
    $(`img-${AXES[k]}-show`).onchange = () => {
      planes[k].visible = lines[k].visible = $(`img-${AXES[k]}-show`).checked && !!view.slices[k];
    };
  }
  for (const id of ['img-window', 'img-level'])
    $(id).oninput = () => {
      $(`${id}-value`).value = +(+$(id).value).toPrecision(6);
      $('img-preset').value = 'custom';
      askAll();
    };
  for (const id of ['img-window', 'img-level'])
    $(`${id}-value`).onchange = () => {
      const w = +$('img-window-value').value, l = +$('img-level-value').value;
      if (!(w > 0) || !Number.isFinite(l)) { applyPreset(); return; }  // back to a valid pair
      setWindowLevel(w, l);
      $('img-preset').value = 'custom';
      askAll();
    };
  $('img-preset').onchange = () => { applyPreset(); askAll(); };
  $('img-2d').onchange = draw2d;
  $('img-dock').onchange = () => { layout(); draw2d(); };
  // The grip at the 2D view's top right corner: the box grows up and to the right.
  $('slice-grip').addEventListener('pointerdown', (ev) => {
    ev.preventDefault();
    ev.stopPropagation();
    const box = $('slice-box'), main = $('viewport');
    const start = { x: ev.clientX, y: ev.clientY, w: box.clientWidth, h: box.clientHeight };
    const move = (e) => {
      box.style.width = `${Math.min(main.clientWidth - 16, Math.max(160, start.w + e.clientX - start.x))}px`;
      box.style.height = `${Math.min(main.clientHeight - 16, Math.max(160, start.h - (e.clientY - start.y)))}px`;
      if (layout()) draw2d();
    };
    const up = () => { window.removeEventListener('pointermove', move); window.removeEventListener('pointerup', up); };
    window.addEventListener('pointermove', move);
    window.addEventListener('pointerup', up);
  });
  window.addEventListener('resize', () => { if (layout()) draw2d(); });

  // The view's settings, kept in a saved session and given back when it is reopened.
  view.settings = () => ({ planes: AXES.map((a) => +$(`img-${a}`).value), show: AXES.map((a) => $(`img-${a}-show`).checked),
    window: +$('img-window-value').value, level: +$('img-level-value').value, preset: $('img-preset').value,
    twoD: $('img-2d').value, dock: $('img-dock').checked });
  view.applySettings = (s) => {
    if (!s || !view.image) return;
    AXES.forEach((a, k) => {
      if (Number.isFinite(s.planes?.[k])) $(`img-${a}`).value = s.planes[k];
      if (typeof s.show?.[k] === 'boolean') $(`img-${a}-show`).checked = s.show[k];
    });
    if (s.window > 0 && Number.isFinite(s.level)) setWindowLevel(s.window, s.level);
    if (typeof s.preset === 'string' && [...$('img-preset').options].some((o) => o.value === s.preset)) $('img-preset').value = s.preset;
    if (['axial', 'coronal', 'sagittal', 'none'].includes(s.twoD)) $('img-2d').value = s.twoD;
    $('img-dock').checked = !!s.dock;
    askAll();
    draw2d();
  };

  // The three planes through a point of the scene (a double click on the surface, as
  // 3D Slicer's crosshair does), each within the volume.
  view.moveTo = (p) => {
    const im = view.image;
    if (!im) return;
    const [lo, hi] = im.bounds;
    for (let k = 0; k < 3; ++k) {
      const n = NORMAL[k];
      $(`img-${AXES[k]}`).value = Math.min(Math.max(p[n], lo[n]), hi[n]);
    }
    view.movedTo = p;
    askAll();
  };
  return view;
}
