// The meshpde browser editor. Draws what the server sends (see editor/editor_server.cpp for
// the wire format) and turns mouse gestures into requests; all numerics run on the
// server. window.meshpde exposes the state for tests and for the curious.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/OrbitControls.js';
import { createImageView } from './image-view.js';
import { createStillDraw } from './still-draw.js';

const $ = (id) => document.getElementById(id);
const state = {
  ready: false, client: 0, name: '', vertexCount: 0, faceCount: 0, meanEdge: 1,
  positions: null, rest: null, field: null, fieldName: '', fieldRange: [0, 1],
  force: [0, 0, 0], forceVisible: false, contact: -1, intersections: 0,
  canUndo: false, canRedo: false, lastError: '', lastOk: '', oks: 0, errors: 0, frames: 0, updates: 0, arrowCount: 0,
};
window.meshpde = state;

// ---------------------------------------------------------------- scene
const viewport = $('viewport');
// A browser without a GPU draws with a software rasterizer (SwiftShader, llvmpipe),
// where multisampling and physically based shading cost most of a frame: there the
// page draws without multisampling, with Lambert shading, and at half resolution while
// a drag or poke is on (web/test/throughput.mjs --browser-drag measures it).
function softwareRenderer() {
  try {
    const gl = document.createElement('canvas').getContext('webgl2');
    if (!gl) return false;
    const info = gl.getExtension('WEBGL_debug_renderer_info');
    const name = `${gl.getParameter(gl.RENDERER)} ${info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : ''}`;
    gl.getExtension('WEBGL_lose_context')?.loseContext();
    return /swiftshader|llvmpipe|softpipe|software/i.test(name);
  } catch {
    return false;
  }
}
// (?quality=full in the address keeps multisampling and full shading regardless.)
state.software = !new URLSearchParams(location.search).has('quality') && softwareRenderer();
const renderer = new THREE.WebGLRenderer({ antialias: !state.software, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
viewport.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0xfafafa);
const camera = new THREE.PerspectiveCamera(40, 1, 0.01, 1e5);
scene.add(new THREE.HemisphereLight(0xffffff, 0x667788, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
camera.add(sun);
sun.position.set(0.5, 1, 1);
scene.add(camera);
// Orbit controls turn about the camera's up axis as it is when they are made: a
// standard view with another up (superior, for the patient's views) makes new ones.
let controls = null;
function makeControls() {
  const target = controls ? controls.target.clone() : new THREE.Vector3();
  if (controls) controls.dispose();
  controls = new OrbitControls(camera, renderer.domElement);
  controls.enableDamping = false;
  controls.target.copy(target);
  controls.addEventListener('change', () => { still.thaw(); invalidate(); });
}
// The scene is drawn when something changed, not every animation frame: an idle page
// then costs nothing, and a software-rendered page (no GPU) answers the server's
// frames instead of queueing them behind its own drawing.
let dirty = true;
const invalidate = () => { dirty = true; };
// A drag on a software rasterizer draws the still part of the surface once (see
// still-draw.js); any other change to what is drawn ends that.
const still = createStillDraw({ renderer, scene, camera });
const redraw = () => { still.thaw(); invalidate(); };
document.addEventListener('input', redraw);
document.addEventListener('change', redraw);
makeControls();

// The surface is pushed back a little in depth so that the lines drawn on it (the rim
// of what a drag would touch) are not lost in it.
const material = state.software
  ? new THREE.MeshLambertMaterial({ vertexColors: true, side: THREE.DoubleSide, polygonOffset: true,
    polygonOffsetFactor: 1, polygonOffsetUnits: 1 })
  : new THREE.MeshStandardMaterial({ vertexColors: true, side: THREE.DoubleSide, roughness: 0.65, metalness: 0.0,
    flatShading: false, polygonOffset: true, polygonOffsetFactor: 1, polygonOffsetUnits: 1 });
// Half resolution while a drag or poke is on (software rasterizers only), the full one
// again once it ends.
function interactive(on) {
  if (!state.software) return;
  const ratio = on ? 0.5 * window.devicePixelRatio : window.devicePixelRatio;
  if (renderer.getPixelRatio() === ratio) return;
  renderer.setPixelRatio(ratio);
  resize();
  invalidate();
}
const wireMaterial = new THREE.MeshBasicMaterial({ color: 0x222222, wireframe: true, transparent: true, opacity: 0.25 });
let mesh = null, wire = null, geometry = null;
const arrow = new THREE.ArrowHelper(new THREE.Vector3(0, 1, 0), new THREE.Vector3(), 1, 0xd62728);
arrow.visible = false;
scene.add(arrow);
const arrows = new THREE.LineSegments(new THREE.BufferGeometry(), new THREE.LineBasicMaterial({ color: 0xd62728 }));
arrows.visible = false;
scene.add(arrows);
// The correct tool's marks: before a press, the rim of the region a drag at the point
// under the cursor would move (orange) and of its handle (blue); while dragging, the
// handle (a blue dot) and the drag vector (a blue arrow), drawn over the surface.
const RIM_COLOR = 0xff7f0e, HANDLE_COLOR = 0x1f77b4;
const rimLines = new THREE.LineSegments(new THREE.BufferGeometry(), new THREE.LineBasicMaterial({ color: RIM_COLOR }));
const handleLines = new THREE.LineSegments(new THREE.BufferGeometry(),
  new THREE.LineBasicMaterial({ color: HANDLE_COLOR }));
const handleDot = new THREE.Mesh(new THREE.SphereGeometry(1, 16, 12),
  new THREE.MeshBasicMaterial({ color: HANDLE_COLOR, depthTest: false }));
const dragArrow = new THREE.ArrowHelper(new THREE.Vector3(0, 1, 0), new THREE.Vector3(), 1, HANDLE_COLOR);
for (const o of [rimLines, handleLines, handleDot, dragArrow]) { o.visible = false; o.renderOrder = 2; scene.add(o); }
dragArrow.line.material.depthTest = false;
dragArrow.cone.material.depthTest = false;

// The 3D view fills the view, or its right half while the 2D view is docked beside it.
function resize() {
  still.thaw();
  const docked = viewport.classList.contains('docked');
  const w = docked ? Math.floor(viewport.clientWidth / 2) : viewport.clientWidth, h = viewport.clientHeight;
  renderer.setSize(w, h);
  camera.aspect = w / Math.max(h, 1);
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', () => { resize(); invalidate(); });

// Viridis, as the server's renderer draws it.
const VIRIDIS = [[68, 1, 84], [59, 82, 139], [33, 144, 141], [93, 201, 99], [253, 231, 37]];
function viridis(t) {
  t = Math.min(1, Math.max(0, t)) * (VIRIDIS.length - 1);
  const i = Math.min(Math.floor(t), VIRIDIS.length - 2), f = t - i;
  return VIRIDIS[i].map((c, k) => (c + f * (VIRIDIS[i + 1][k] - c)) / 255);
}
const BASE = [0.72, 0.78, 0.88], MOVING = [1.0, 0.55, 0.15];

let baseColours = false;  // every vertex has the base colour (nothing to repaint while that holds)
function paintColors() {
  if (!geometry) return;
  still.thaw();
  const col = geometry.getAttribute('color');
  const n = state.vertexCount, P = state.positions, R = state.rest;
  const [lo, hi] = state.fieldRange;
  // Highlight what the probe moves noticeably: 2 % of the largest motion.
  let largest = 0;
  if (R && !state.field)
    for (let i = 0; i < 3 * n; ++i) largest = Math.max(largest, Math.abs(P[i] - R[i]));
  const tol = Math.max(1e-3 * state.meanEdge, 0.02 * largest);
  let allBase = true;
  for (let i = 0; i < n; ++i) {
    let c = BASE;
    if (state.field) c = viridis(hi > lo ? (state.field[i] - lo) / (hi - lo) : 0.5);
    else if (R) {
      const dx = P[3 * i] - R[3 * i], dy = P[3 * i + 1] - R[3 * i + 1], dz = P[3 * i + 2] - R[3 * i + 2];
      if (dx * dx + dy * dy + dz * dz > tol * tol) c = MOVING;  // the part the probe moves: its active domain
    }
    if (c !== BASE) allBase = false;
    col.setXYZ(i, c[0], c[1], c[2]);
  }
  baseColours = allBase;
  col.needsUpdate = true;
}

// The triangles around each vertex (compressed rows), for normals updated where
// vertices moved rather than over the whole mesh.
let vertexFaces = null;
function buildVertexFaces(nv, T) {
  const offsets = new Uint32Array(nv + 1), faces = new Uint32Array(T.length);
  for (let k = 0; k < T.length; ++k) offsets[T[k] + 1] += 1;
  for (let v = 0; v < nv; ++v) offsets[v + 1] += offsets[v];
  const fill = offsets.slice(0, nv);
  for (let k = 0; k < T.length; ++k) faces[fill[T[k]]++] = Math.floor(k / 3);
  return { offsets, faces, mark: new Uint32Array(nv), epoch: 0 };
}
// Vertex normals of the moved vertices and their neighbours: the sum of their
// triangles' area-weighted normals, normalized (what computeVertexNormals does for all).
function updateNormals(ids) {
  const P = state.positions, T = state.triangles, N = geometry.getAttribute('normal').array;
  const { offsets, faces, mark } = vertexFaces;
  const epoch = ++vertexFaces.epoch, touched = [];
  for (const v of ids)
    for (let k = offsets[v]; k < offsets[v + 1]; ++k)
      for (let c = 0; c < 3; ++c) {
        const w = T[3 * faces[k] + c];
        if (mark[w] !== epoch) { mark[w] = epoch; touched.push(w); }
      }
  for (const v of touched) {
    let nx = 0, ny = 0, nz = 0;
    for (let k = offsets[v]; k < offsets[v + 1]; ++k) {
      const f = 3 * faces[k], a = 3 * T[f], b = 3 * T[f + 1], c = 3 * T[f + 2];
      const ux = P[c] - P[b], uy = P[c + 1] - P[b + 1], uz = P[c + 2] - P[b + 2];
      const wx = P[a] - P[b], wy = P[a + 1] - P[b + 1], wz = P[a + 2] - P[b + 2];
      nx += uy * wz - uz * wy; ny += uz * wx - ux * wz; nz += ux * wy - uy * wx;
    }
    const len = Math.hypot(nx, ny, nz) || 1;
    N[3 * v] = nx / len; N[3 * v + 1] = ny / len; N[3 * v + 2] = nz / len;
  }
  geometry.getAttribute('normal').needsUpdate = true;
}

function buildMesh(buf) {
  const dv = new DataView(buf);
  const nv = dv.getUint32(4, true), nf = dv.getUint32(8, true);
  const pos = new Float32Array(buf.slice(12, 12 + 12 * nv));
  const idx = new Uint32Array(buf.slice(12 + 12 * nv, 12 + 12 * nv + 12 * nf));
  still.thaw();
  if (mesh) { scene.remove(mesh); scene.remove(wire); geometry.dispose(); }
  geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(pos, 3).setUsage(THREE.DynamicDrawUsage));
  geometry.setAttribute('color', new THREE.BufferAttribute(new Float32Array(3 * nv), 3));
  geometry.setIndex(new THREE.BufferAttribute(idx, 1));
  geometry.computeVertexNormals();
  geometry.computeBoundingSphere();
  mesh = new THREE.Mesh(geometry, material);
  wire = new THREE.Mesh(geometry, wireMaterial);
  wire.visible = $('wireframe').checked;
  mesh.visible = $('surface').checked;
  scene.add(mesh, wire);
  state.vertexCount = nv; state.faceCount = nf;
  state.positions = pos; state.rest = pos.slice(); state.field = null; state.fieldName = '';
  state.triangles = idx;
  vertexFaces = buildVertexFaces(nv, idx);
  $('legend').hidden = true;
  paintColors();
  fitView(HOME_DIRECTION, HOME_UP);
  imageView.onMeshLoaded();
  imageView.onPositions();
  // A reopened session: its settings, camera and image view as they were saved.
  if (pendingPage) { applyPageSettings(pendingPage); pendingPage = null; }
  state.ready = true;
}

// ---------------------------------------------------------------- a session's settings
// What a saved session keeps of the page (EditorPage::save_session stores it as given):
// the tools' options, the view and the image's.
const SETTING_INPUTS = ['reach', 'radius', 'method', 'drag-mode', 'image', 'dynamic', 'brush-property', 'brush-value',
  'brush-radius', 'paint-value', 'g1', 'g2', 'wireframe', 'surface', 'save-format', 'save-displacement'];
function pageSettings() {
  const inputs = {};
  for (const id of SETTING_INPUTS) inputs[id] = $(id).type === 'checkbox' ? $(id).checked : $(id).value;
  return { tool: tool(), inputs, camera: { position: camera.position.toArray(), target: controls.target.toArray(),
    up: camera.up.toArray() }, image: state.imageView.image ? imageView.settings() : null };
}
let pendingPage = null;
function applyPageSettings(s) {
  for (const id of SETTING_INPUTS) {
    const v = s.inputs?.[id];
    if (v === undefined) continue;
    if ($(id).type === 'checkbox') $(id).checked = !!v;
    else $(id).value = v;
    $(id).dispatchEvent(new Event('input'));
    $(id).dispatchEvent(new Event('change'));
  }
  const radio = [...document.querySelectorAll('input[name=tool]')].find((r) => r.value === s.tool);
  if (radio) { radio.checked = true; radio.dispatchEvent(new Event('change')); }
  const c = s.camera;
  if (c && [c.position, c.target, c.up].every((x) => Array.isArray(x) && x.length === 3 && x.every(Number.isFinite))) {
    camera.up.fromArray(c.up);
    camera.position.fromArray(c.position);
    makeControls();
    controls.target.fromArray(c.target);
    camera.lookAt(controls.target);
    controls.update();
  }
  imageView.applySettings(s.image);
  invalidate();
}

// The view a mesh opens with, and reset view: from the front right above, y up.
const HOME_DIRECTION = new THREE.Vector3(0.3, 0.4, 1), HOME_UP = new THREE.Vector3(0, 1, 0);
// The camera on the side `direction` of the mesh (its bounding sphere whole in view),
// looking at its centre with `up` up.
function fitView(direction, up) {
  if (!geometry) return;
  const s = geometry.boundingSphere;
  // Far enough for the whole bounding sphere to fit the (vertical) field of view.
  const distance = 1.15 * s.radius / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2));
  camera.up.copy(up);
  camera.position.copy(s.center).add(direction.clone().normalize().multiplyScalar(distance));
  camera.near = s.radius / 100; camera.far = s.radius * 100;
  camera.updateProjectionMatrix();
  camera.lookAt(s.center);
  makeControls();
  controls.target.copy(s.center);
  controls.update();
  invalidate();
}
// Standard views in the patient's frame: the mesh's coordinates are LPS (x to the
// patient's left, y posterior) or RAS (x right, y anterior); z is superior in both.
// From above and below, anterior is up on the screen.
function standardView(name) {
  const ras = state.space === 'RAS';
  const anterior = new THREE.Vector3(0, ras ? 1 : -1, 0), left = new THREE.Vector3(ras ? -1 : 1, 0, 0);
  const superior = new THREE.Vector3(0, 0, 1);
  const views = {
    anterior: [anterior, superior], posterior: [anterior.clone().negate(), superior],
    left: [left, superior], right: [left.clone().negate(), superior],
    superior: [superior, anterior], inferior: [superior.clone().negate(), anterior],
  };
  fitView(...views[name]);
  state.view = name;
}
state.view = 'home';
window.meshpde.cameraDirection = () => camera.position.clone().sub(controls.target).normalize().toArray();
window.meshpde.cameraUp = () => camera.up.toArray();

// Where a page's time goes (web/test/throughput.mjs --browser-drag reads it): ms of
// page work per position update, and of drawing per frame, the last 1,000 of each.
state.timing = { page: [], draw: [] };
const timed = (list, ms) => { list.push(ms); if (list.length > 1000) list.shift(); };

function applyPositions(buf) {
  const t0 = performance.now();
  const dv = new DataView(buf);
  const n = dv.getUint32(4, true);
  const ids = new Uint32Array(buf.slice(8, 8 + 4 * n));
  const xyz = new Float32Array(buf.slice(8 + 4 * n, 8 + 16 * n));
  const P = state.positions;
  for (let k = 0; k < n; ++k) {
    const i = ids[k];
    P[3 * i] = xyz[3 * k]; P[3 * i + 1] = xyz[3 * k + 1]; P[3 * i + 2] = xyz[3 * k + 2];
  }
  geometry.getAttribute('position').needsUpdate = true;
  // A few moved vertices: their normals and their neighbours'; many: all of them.
  if (n < state.vertexCount / 8) updateNormals(ids);
  else geometry.computeVertexNormals();
  if (!state.poking) state.rest = P.slice();  // a correction, undo or redo: the new rest shape
  // The colours change with a field or a poke; a drag's preview leaves them at the base.
  if (state.field || state.poking || !baseColours) paintColors();
  // A correct drag's preview without a GPU: the still part of the surface drawn once.
  else if (drag && state.software && tool() === 'correct') {
    if (still.holds(ids)) still.update();
    else still.freeze({ geometry, surfaces: [mesh, wire], triangles: state.triangles, vertexFaces,
      ids: state.dragVertices ? [...state.dragVertices, ...ids] : ids });
  }
  imageView.onPositions();
  timed(state.timing.page, performance.now() - t0);
}

// Arrows for a vector field: a shaft and two barbs each, longest = 8 % of the mesh size.
function applyVectors(buf) {
  const n = new DataView(buf).getUint32(4, true);
  state.arrowCount = n;
  if (n === 0) { arrows.visible = false; return; }
  const ids = new Uint32Array(buf.slice(8, 8 + 4 * n));
  const v = new Float32Array(buf.slice(8 + 4 * n, 8 + 16 * n));
  let longest = 0;
  for (let k = 0; k < n; ++k) longest = Math.max(longest, Math.hypot(v[3 * k], v[3 * k + 1], v[3 * k + 2]));
  const scale = longest > 0 ? 0.08 * geometry.boundingSphere.radius / longest : 0;
  const P = state.positions, seg = new Float32Array(18 * n);
  const up = new THREE.Vector3(), side = new THREE.Vector3(), d = new THREE.Vector3(), p = new THREE.Vector3();
  for (let k = 0; k < n; ++k) {
    const i = ids[k];
    p.set(P[3 * i], P[3 * i + 1], P[3 * i + 2]);
    d.set(v[3 * k], v[3 * k + 1], v[3 * k + 2]).multiplyScalar(scale);
    const tip = p.clone().add(d);
    side.copy(d).cross(up.set(0.3, 0.7, 0.5)).normalize().multiplyScalar(0.25 * d.length());
    const back = tip.clone().addScaledVector(d, -0.3);
    const b1 = back.clone().add(side), b2 = back.clone().sub(side);
    seg.set([p.x, p.y, p.z, tip.x, tip.y, tip.z, tip.x, tip.y, tip.z, b1.x, b1.y, b1.z,
             tip.x, tip.y, tip.z, b2.x, b2.y, b2.z], 18 * k);
  }
  arrows.geometry.setAttribute('position', new THREE.BufferAttribute(seg, 3));
  arrows.geometry.computeBoundingSphere();
  arrows.visible = true;
}

function applyField(buf) {
  const n = new DataView(buf).getUint32(4, true);
  state.field = new Float32Array(buf.slice(8, 8 + 4 * n));
  paintColors();
}

// ---------------------------------------------------------------- connection
// The status line after an action that has no figures of its own to report.
const ENDS_CORRECTION_PANEL = new Set(['undo', 'redo', 'paint', 'paint_vector', 'clear_paint', 'brush', 'source',
  'clear_sources', 'play', 'poke_begin', 'generate']);
const DONE = {
  undo: 'undone: the surface is as it was before the last correction',
  redo: 'redone: the correction is applied again',
  paint: 'painted: the values spread smoothly from every painted vertex',
  paint_vector: 'painted: the vectors spread smoothly from every painted vertex',
  clear_paint: 'paint cleared',
  source: 'source added: play to let it spread',
  clear_sources: 'sources cleared',
  play: 'playing',
  pause: 'paused',
  poke_begin: 'poking: the surface pushes back; release to let it settle',
  poke_end: 'released: the surface settles back',
};
const status = (text, error = false) => { $('status').textContent = text; $('status').className = error ? 'error' : ''; };
const ws = new WebSocket(`ws://${location.host}/`);
ws.binaryType = 'arraybuffer';
const send = (obj) => { if (ws.readyState === 1) ws.send(JSON.stringify(obj)); };
window.meshpde.send = send;
window.meshpde.socket = ws;
ws.onclose = () => status('disconnected from the server', true);
ws.onmessage = (ev) => {
  if (typeof ev.data !== 'string') {
    invalidate();
    const tag = new TextDecoder().decode(new Uint8Array(ev.data, 0, 4));
    if (tag === 'MESH') buildMesh(ev.data);
    else if (tag === 'POS ') applyPositions(ev.data);
    else if (tag === 'FLD ') applyField(ev.data);
    else if (tag === 'VEC ') applyVectors(ev.data);
    else if (tag === 'SLC ') imageView.onSlice(ev.data);
    else if (tag === 'RIM ') { applyRim(ev.data); return; }  // not a surface update
    else if (tag === 'REG ') { state.dragVertices = new Uint32Array(ev.data, 8); return; }
    state.updates += 1;
    return;
  }
  const m = JSON.parse(ev.data);
  if (m.type !== 'stats') invalidate();
  if (m.type === 'hello') state.client = m.client;
  else if (m.type === 'mesh') {
    state.ready = false; state.name = m.name; state.meanEdge = m.mean_edge; state.space = m.space || 'LPS';
    state.segmentation = m.segmentation;
    pendingPage = m.page || null;
    state.historyStep = m.history_step;
    $('mesh-name').textContent = `${m.name}: ${m.vertices.toLocaleString()} vertices`;
    $('last-correction').hidden = true;  // a mesh opened: no correction yet
    $('save').title = m.segmentation
      ? `Download the edited surface, and write ${m.segmentation.output} beside ${m.segmentation.input}`
      : 'Download the edited mesh in its own format';
    const notes = [];
    if (m.page) notes.push(`reopened a saved session of ${m.name}: ${m.history_step} correction` +
                           `${m.history_step === 1 ? '' : 's'} applied, with their undo and redo`);
    if (m.segmentation) notes.push(`editing segment '${m.segmentation.segment}' of ${m.segmentation.input}`);
    if (m.held_vertices) notes.push(`${m.held_vertices} vertices of flat caps are held`);
    if (m.units && m.units !== 'mm') notes.push(`${m.name} is in ${m.units}: shown and edited in mm, saved in ${m.units}`);
    if (m.units_warning) notes.push(m.units_warning);
    status(notes.length ? notes.join('\n') : `opened ${m.name}`);
    $('image').disabled = !m.has_image;
    if (!m.has_image) $('image').checked = false;
    imageView.onMeshMessage(m);
  } else if (m.type === 'image') {  // a volume uploaded beside the mesh
    $('image').disabled = false;
    $('image').checked = true;
    imageView.onMeshMessage(m);
  } else if (m.type === 'field') {
    state.fieldName = m.name;
    if (m.name !== 'moved (mm)' && m.name !== 'image pull (mm)') $('colour-by-label').hidden = true;  // the next action
    if (!m.name) { state.field = null; $('legend').hidden = true; paintColors(); return; }
    state.fieldRange = [m.min, m.max];
    $('legend').hidden = false;
    $('legend-name').textContent = m.name;
    $('legend-min').textContent = (+m.min).toPrecision(3);
    $('legend-max').textContent = (+m.max).toPrecision(3);
  } else if (m.type === 'stats') updateStats(m);
  else if (m.type === 'ok') {
    state.lastOk = m.request; state.oks += 1;
    // One message per action, replaced by the next: what this one did.
    if (m.request in DONE) status(DONE[m.request]);
    // The panel of figures describes the correction just made: another edit (undo and
    // redo included) ends it, so that it never shows one action's figures after another.
    if (ENDS_CORRECTION_PANEL.has(m.request)) $('last-correction').hidden = true;
    if (m.request === 'drag_begin' && drag)  // (a click's, already released: nothing to say)
      status(`dragging: region of ${m.region_vertices} vertices ready in ${m.setup_ms.toFixed(1)} ms`);
    if (m.request === 'correct') {
      state.lastCorrect = m;
      $('last-correction').hidden = false;
      $('stat-moved').textContent = m.moved_vertices.toLocaleString();
      $('stat-largest').textContent = m.max_displacement.toFixed(2);
      $('stat-region').textContent = m.region_vertices.toLocaleString();
      $('stat-time').textContent = m.time_ms.toFixed(0);
      // An image-guided correction can also be shown by what the image did.
      $('colour-by-label').hidden = m.image_pull_max === undefined;
      $('colour-by').value = 'moved (mm)';
    }
    if (m.request === 'correct')
      status(`corrected: ${m.moved_vertices} vertices moved in ${m.time_ms.toFixed(1)} ms, ` +
             `${m.new_self_intersections} new self-intersections (${m.intersection_action})` +
             (m.applied_fraction < 1
               ? `\nonly ${m.applied_fraction.toFixed(2)} of the drag was applied: all of it would make the wall ` +
                 'intersect itself' : '') +
             (m.region_warning ? `\n${m.region_warning}` : '') +
             (m.image_pull_max !== undefined
               ? `\nthe image moved the wall up to ${m.image_pull_max.toFixed(2)} mm beyond the drag (colour by: image pull)`
               : ''));
    if (m.request === 'save_segmentation') {
      state.lastSegmentationSave = m;
      status(`wrote ${m.file}: ${m.added} voxels added, ${m.removed} removed` +
             (m.conflicts ? `, ${m.conflicts} left to other segments` : ''));
    }
  } else if (m.type === 'error') {
    state.lastError = m.message; state.errors += 1;
    if (m.request === 'slice') imageView.onSliceError();
    if (m.request === 'rim') { rimInFlight = false; hideRim(); }
    status(m.message, true);
  }
};

let fpsCount = 0, lastUpdates = 0;
setInterval(() => {
  $('stat-fps').textContent = fpsCount;
  $('stat-updates').textContent = state.updates - lastUpdates;
  fpsCount = 0;
  lastUpdates = state.updates;
}, 1000);

function updateStats(s) {
  state.force = s.force; state.contact = s.contact; state.intersections = s.intersections;
  state.canUndo = s.can_undo; state.canRedo = s.can_redo;
  $('stat-solve').textContent = s.solve_ms.toFixed(1);
  $('stat-frame').textContent = s.frame_ms.toFixed(2);
  $('stat-domain').textContent = s.active;
  $('stat-p99').textContent = s.p99_us ? s.p99_us.toFixed(0) : '-';
  $('stat-misses').textContent = s.misses;
  $('stat-intersections').textContent = s.intersections;
  $('undo').disabled = !s.can_undo;
  $('redo').disabled = !s.can_redo;
  const f = new THREE.Vector3(...s.force);
  $('stat-force').textContent = f.length().toPrecision(3);
  const show = s.poking && s.contact >= 0 && f.length() > 0 && state.positions;
  if (show || arrow.visible) invalidate();
  arrow.visible = !!show;
  state.forceVisible = !!show;
  if (show) {
    const P = state.positions, i = s.contact;
    arrow.position.set(P[3 * i], P[3 * i + 1], P[3 * i + 2]);
    arrow.setDirection(f.clone().normalize());
    const r = geometry.boundingSphere.radius;
    arrow.setLength(0.05 * r + 0.25 * r * Math.min(1, f.length() / (forceScale = Math.max(forceScale, f.length()))));
  }
}
let forceScale = 1e-30;

// The correct tool's options, shared by the 3D drag and the 2D slice view's drag.
const correctOptions = () => ({ radius: +$('radius').value, method: $('method').value, image: $('image').checked,
  dynamic: $('dynamic').checked });
const imageView = createImageView({ scene, state, send, $, correctOptions, invalidate,
  relayout: () => { resize(); invalidate(); } });

// ---------------------------------------------------------------- gestures
const raycaster = new THREE.Raycaster();
const tool = () => document.querySelector('input[name=tool]:checked').value;
function pick(ev) {
  if (!mesh) return null;
  const r = renderer.domElement.getBoundingClientRect();
  const ndc = new THREE.Vector2(((ev.clientX - r.left) / r.width) * 2 - 1, -((ev.clientY - r.top) / r.height) * 2 + 1);
  raycaster.setFromCamera(ndc, camera);
  const hit = raycaster.intersectObject(mesh, false)[0];
  if (!hit) return null;
  // The corner of the hit triangle nearest the hit point.
  let best = -1, bestD = Infinity;
  for (const i of [hit.face.a, hit.face.b, hit.face.c]) {
    const P = state.positions;
    const d = hit.point.distanceToSquared(new THREE.Vector3(P[3 * i], P[3 * i + 1], P[3 * i + 2]));
    if (d < bestD) { bestD = d; best = i; }
  }
  // The triangle's normal in the scene (the mesh is drawn untransformed).
  return { vertex: best, triangle: hit.faceIndex, point: hit.point.clone(),
    normal: hit.face ? hit.face.normal.clone() : null };
}

// ---------------------------------------------------------------- what a drag will touch
// Hovering with the correct tool (fem) asks the server for the rim of the region and of
// the handle a drag at the point under the cursor would have (`rim` request, `RIM `
// frame): one request on its way at a time, the newest hover waiting for its answer.
let rimSeq = 0, rimInFlight = false, rimPending = null;
const correctHover = () => tool() === 'correct' && $('method').value === 'fem';
function requestRim(hit) {
  const m = { type: 'rim', point: hit.point.toArray(), triangle: hit.triangle, radius: +$('radius').value,
    seq: ++rimSeq };
  if (rimInFlight) { rimPending = m; return; }
  rimInFlight = true;
  send(m);
}
function hideRim() {
  rimPending = null;
  if (rimLines.visible || handleLines.visible || handleDot.visible) invalidate();
  rimLines.visible = handleLines.visible = handleDot.visible = false;
  state.rim = null;
}
function segments(lines, xyz) {
  lines.geometry.dispose();
  lines.geometry = new THREE.BufferGeometry();
  lines.geometry.setAttribute('position', new THREE.BufferAttribute(xyz, 3));
  lines.geometry.computeBoundingSphere();
  lines.visible = xyz.length > 0;
}
// The handle's dot: a fixed size on screen (its radius 0.6 % of its distance from the camera).
function placeDot(p) {
  handleDot.position.copy(p);
  handleDot.scale.setScalar(0.006 * camera.position.distanceTo(p));
  handleDot.visible = true;
}
function applyRim(buf) {
  rimInFlight = false;
  const dv = new DataView(buf);
  const seq = dv.getUint32(4, true), regionVertices = dv.getUint32(8, true);
  const radius = dv.getFloat32(12, true), handleRadius = dv.getFloat32(16, true);
  const n = dv.getUint32(20, true), m = dv.getUint32(24, true);
  if (rimPending) { const next = rimPending; rimPending = null; rimInFlight = true; send(next); }
  // A hover that ended (or a drag that began) while this was on its way: not shown.
  if (seq !== rimSeq || drag || !correctHover() || !hovered) return;
  const xyz = new Float32Array(buf.slice(28, 28 + 24 * (n + m)));
  segments(rimLines, xyz.subarray(0, 6 * n));
  segments(handleLines, xyz.subarray(6 * n));
  placeDot(hovered.point);
  state.rim = { seq, regionVertices, radius, handleRadius, point: hovered.point.toArray(),
    rim: xyz.slice(0, 6 * n), handle: xyz.slice(6 * n) };
  $('stat-rim').textContent = `${regionVertices.toLocaleString()} vertices within ${radius} mm`;
}
let hovered = null;
let drag = null;  // {vertex, start, plane, mode, normal, up, keep}
// The correct tool's drag direction (the "drag along" choice): the screen's plane; the
// surface normal at the picked point, turned towards the camera (the mouse's vertical
// motion pulls the wall towards the viewer or pushes it away); or the plane of the 2D
// slice view (the motion's component across that plane dropped).
const SLICE_NORMAL_AXIS = { axial: 2, coronal: 1, sagittal: 0 };
// The wheel, while the button is held, pushes or pulls along the picked point's normal
// in every mode: each notch a sixteenth of the region's radius (0.5 mm at 8 mm), up
// towards the viewer.
function dragOffset(p) {
  let o = p.clone().sub(drag.start);
  if (drag.mode === 'normal') o = drag.normal.clone().multiplyScalar(o.dot(drag.up));
  else if (drag.mode === 'slice') o.setComponent(drag.keep, 0);
  if (drag.wheel && drag.facing) o.addScaledVector(drag.facing, drag.wheel);
  return o;
}
function planePoint(ev) {
  const r = renderer.domElement.getBoundingClientRect();
  const ndc = new THREE.Vector2(((ev.clientX - r.left) / r.width) * 2 - 1, -((ev.clientY - r.top) / r.height) * 2 + 1);
  raycaster.setFromCamera(ndc, camera);
  const p = new THREE.Vector3();
  return raycaster.ray.intersectPlane(drag.plane, p) ? p : null;
}
let lastMove = 0;
renderer.domElement.addEventListener('pointerdown', (ev) => {
  if (ev.button !== 0) return;
  const hit = pick(ev);
  if (!hit) return;
  const t = tool();
  const vectorPaint = t === 'paint' && document.querySelector('input[name=paint-kind]:checked').value === 'vector';
  if (t === 'paint' && !vectorPaint) {
    send({ type: 'paint', vertex: hit.vertex, value: +$('paint-value').value, g1: +$('g1').value, g2: +$('g2').value });
    return;
  }
  if (t === 'brush') {
    send({ type: 'brush', property: $('brush-property').value, vertex: hit.vertex, radius: +$('brush-radius').value,
      value: +$('brush-value').value });
    return;
  }
  if (t === 'heat' || t === 'wave') { send({ type: 'source', vertex: hit.vertex }); return; }
  controls.enabled = false;
  const normal = camera.getWorldDirection(new THREE.Vector3());
  drag = { vertex: hit.vertex, triangle: hit.triangle, start: hit.point,
    plane: new THREE.Plane().setFromNormalAndCoplanarPoint(normal, hit.point), mode: 'screen', wheel: 0,
    last: hit.point.clone() };
  hideRim();
  if (t === 'correct') {
    const mode = $('drag-mode').value, slice = $('img-2d') ? $('img-2d').value : 'none';
    // The picked triangle's normal, on the side the camera sees (the wheel's direction).
    if (hit.normal) {
      drag.facing = hit.normal.clone();
      if (drag.facing.dot(normal) > 0) drag.facing.negate();
    }
    placeDot(hit.point);
    if (mode === 'normal' && hit.normal) {
      // Along that normal, the screen's up pulling.
      drag.mode = 'normal';
      drag.normal = drag.facing;
      drag.up = camera.up.clone().projectOnPlane(normal).normalize();
      status('correct: drag up to pull the wall towards you, down to push it away (along its normal)');
    } else if (mode === 'slice' && slice in SLICE_NORMAL_AXIS) {
      drag.mode = 'slice';
      drag.keep = SLICE_NORMAL_AXIS[slice];
      status(`correct: the drag stays in the ${slice} slice's plane`);
    } else if (mode === 'slice') {
      status('correct: no 2D slice is shown (choose one under image), so the drag follows the screen', true);
    }
  }
  renderer.domElement.setPointerCapture(ev.pointerId);
  interactive(true);
  if (t === 'poke') { state.poking = true; send({ type: 'poke_begin', vertex: hit.vertex, influence: +$('reach').value }); }
  // The correct tool previews live: the server factors the region once, then each
  // move is a product with its basis; releasing sends the real correction.
  if (t === 'correct' && $('method').value === 'fem') {
    state.dragVertices = null;  // the vertices it can move: the server sends them before its reply
    send({ type: 'drag_begin', vertex: hit.vertex, point: hit.point.toArray(), triangle: hit.triangle,
      radius: +$('radius').value });
  }
});
// The drag vector as an arrow from the picked point, the handle's dot at its head.
function showDragVector(offset) {
  const length = offset.length();
  dragArrow.visible = length > 0;
  if (length > 0) {
    dragArrow.position.copy(drag.start);
    dragArrow.setDirection(offset.clone().normalize());
    dragArrow.setLength(length, Math.min(0.3 * length, 0.02 * camera.position.distanceTo(drag.start)),
      Math.min(0.15 * length, 0.01 * camera.position.distanceTo(drag.start)));
  }
  if (tool() === 'correct') placeDot(drag.start.clone().add(offset));
}
function moveDrag(offset, force = false) {
  if (tool() === 'poke') {
    const now = performance.now();
    if (!force && now - lastMove < 8) return;  // at most about 120 probe updates a second
    lastMove = now;
    send({ type: 'poke_move', offset: offset.toArray() });
    return;
  }
  showDragVector(offset);
  if (tool() === 'correct' && $('method').value === 'fem') {
    const now = performance.now();
    if (force || now - lastMove >= 8) {
      lastMove = now;
      send({ type: 'drag_move', offset: offset.toArray() });
      // A running preview answers with the moved surface, drawn with the arrow in one
      // frame (a frame of the arrow alone costs a software rasterizer as much).
      if (state.dragVertices) return;
    }
  }
  invalidate();
}
// A hover picks at most every 40 ms (a pick tests every triangle: milliseconds on a large
// mesh), the last position always.
let hoverEvent = null, hoverTimer = 0, lastHoverPick = 0;
function hoverPick() {
  hoverTimer = 0;
  lastHoverPick = performance.now();
  if (drag || !hoverEvent || !correctHover()) return;
  hovered = pick(hoverEvent);
  if (hovered) requestRim(hovered);
  else hideRim();
}
renderer.domElement.addEventListener('pointermove', (ev) => {
  if (!drag) {
    if (ev.buttons || !correctHover()) { if (hovered) { hovered = null; hideRim(); } return; }
    hoverEvent = { clientX: ev.clientX, clientY: ev.clientY };
    if (!hoverTimer) hoverTimer = setTimeout(hoverPick, Math.max(0, 40 - (performance.now() - lastHoverPick)));
    return;
  }
  const p = planePoint(ev);
  if (!p) return;
  drag.last = p;
  moveDrag(dragOffset(p));
});
renderer.domElement.addEventListener('pointerleave', () => { if (!drag) { hovered = null; hoverEvent = null; hideRim(); } });
// Another tool or method hides the rim; another radius redraws it where the cursor is.
document.querySelectorAll('input[name=tool]').forEach((r) => r.addEventListener('change', () => { hovered = null; hideRim(); }));
$('method').addEventListener('change', () => { hovered = null; hideRim(); });
$('radius').addEventListener('input', () => { if (hovered && +$('radius').value > 0) requestRim(hovered); });
renderer.domElement.addEventListener('wheel', (ev) => {
  if (!drag || tool() !== 'correct' || !drag.facing) return;
  ev.preventDefault();
  drag.wheel += (ev.deltaY < 0 ? 1 : -1) * (+$('radius').value / 16);
  moveDrag(dragOffset(drag.last), true);
}, { passive: false });
function endDrag(ev) {
  if (!drag) return;
  const p = planePoint(ev) || drag.last;
  const offset = dragOffset(p);
  if (tool() === 'poke') send({ type: 'poke_end' });
  else if (tool() === 'paint' && offset.length() > 0)
    send({ type: 'paint_vector', vertex: drag.vertex, vector: offset.toArray(), g1: +$('g1').value, g2: +$('g2').value });
  else if (tool() === 'correct' && offset.length() > 0)
    // The picked surface point moves (not its nearest vertex); replaces the preview.
    send({ type: 'correct', vertex: drag.vertex, point: drag.start.toArray(), triangle: drag.triangle,
      move: offset.toArray(), ...correctOptions() });
  else if (tool() === 'correct') send({ type: 'drag_end' });
  state.poking = false;
  state.lastDrag = { start: drag.start.toArray(), offset: offset.toArray() };
  drag = null;
  still.thaw();
  dragArrow.visible = false;
  handleDot.visible = false;
  interactive(false);
  invalidate();
  controls.enabled = true;
}
renderer.domElement.addEventListener('pointerup', endDrag);
renderer.domElement.addEventListener('pointercancel', endDrag);
// A double click on the surface moves the image's three planes through that point.
renderer.domElement.addEventListener('dblclick', (ev) => {
  const hit = state.imageView.image ? pick(ev) : null;
  if (!hit) return;
  imageView.moveTo(hit.point.toArray());
  status(`the image's planes moved through (${hit.point.toArray().map((x) => x.toFixed(1)).join(', ')}) mm`);
});

// ---------------------------------------------------------------- buttons, files
$('load-generated').onclick = () => send({ type: 'generate', kind: $('generate').value });
$('colour-by').onchange = () => send({ type: 'colour', field: $('colour-by').value });
$('undo').onclick = () => send({ type: 'undo' });
$('redo').onclick = () => send({ type: 'redo' });
$('view-reset').onclick = () => { fitView(HOME_DIRECTION, HOME_UP); state.view = 'home'; };
const STANDARD_VIEWS = ['anterior', 'posterior', 'left', 'right', 'superior', 'inferior'];
for (const name of STANDARD_VIEWS) $(`view-${name}`).onclick = () => standardView(name);
// Keys: Ctrl+Z undo, Ctrl+Shift+Z or Ctrl+Y redo (Cmd on a Mac), Home or 0 resets the
// view, 1 to 6 the standard views. Not while typing in a field.
document.addEventListener('keydown', (e) => {
  const typing = e.target instanceof HTMLElement && (e.target.tagName === 'INPUT' || e.target.tagName === 'SELECT' ||
    e.target.tagName === 'TEXTAREA') && e.target.type !== 'checkbox' && e.target.type !== 'radio' && e.target.type !== 'range';
  if (typing) return;
  const key = e.key.toLowerCase();
  if ((e.ctrlKey || e.metaKey) && (key === 'z' || key === 'y')) {
    const redo = key === 'y' || e.shiftKey;
    if (!$(redo ? 'redo' : 'undo').disabled) send({ type: redo ? 'redo' : 'undo' });
    e.preventDefault();
  } else if (!e.ctrlKey && !e.metaKey && !e.altKey) {
    if (e.key === 'Home' || e.key === '0') $('view-reset').click();
    else if (e.key >= '1' && e.key <= '6') standardView(STANDARD_VIEWS[+e.key - 1]);
  }
});
$('clear-paint').onclick = () => send({ type: 'clear_paint' });
$('play').onclick = () => send({ type: 'play', kind: tool() === 'wave' ? 'wave' : 'heat' });
$('pause').onclick = () => send({ type: 'pause' });
$('clear-sources').onclick = () => send({ type: 'clear_sources' });
$('wireframe').onchange = () => { if (wire) wire.visible = $('wireframe').checked; };
// Hiding the surface shows the image planes whole (the wireframe, if on, stays).
$('surface').onchange = () => { if (mesh) mesh.visible = $('surface').checked; };
for (const id of ['g1', 'g2']) $(id).oninput = () => { $(`${id}-value`).textContent = $(id).value; };
// Stiffness multiplies (any value > 0); mass, elasticity and viscosity are in [0, 1].
const brushDefaults = { stiffness: 5, mass: 0.8, elasticity: 0.3, viscosity: 1 };
$('brush-property').onchange = () => {
  const p = $('brush-property').value;
  $('brush-value').value = brushDefaults[p];
  $('brush-value').max = p === 'stiffness' ? '' : '1';
};

async function upload(file) {
  status(`uploading ${file.name} (${(file.size / 1e6).toFixed(1)} MB)…`);
  const r = await fetch(`/api/upload?client=${state.client}&name=${encodeURIComponent(file.name)}`,
    { method: 'POST', body: file });
  if (!r.ok) {
    let msg = `${r.status} ${r.statusText}`;
    try { msg = (await r.json()).error || msg; } catch { /* not JSON: keep the status */ }
    status(`upload refused: ${msg}`, true);
    state.lastError = msg; state.errors += 1;
  } else if (!/\.meshpde$/i.test(file.name)) status(`opened ${file.name}`);  // a session says what it reopened
}
$('file').onchange = () => { if ($('file').files[0]) upload($('file').files[0]); };
viewport.addEventListener('dragover', (ev) => { ev.preventDefault(); viewport.classList.add('drop'); });
viewport.addEventListener('dragleave', () => viewport.classList.remove('drop'));
viewport.addEventListener('drop', (ev) => {
  ev.preventDefault();
  viewport.classList.remove('drop');
  if (ev.dataTransfer.files[0]) upload(ev.dataTransfer.files[0]);
});
// A file the server answers a save with, downloaded under the name it gives (else
// `fallback`); null, with the reason on the status line, when the server refused.
async function download(response, what, fallback) {
  const r = await response;
  if (!r.ok) {
    const why = (await r.json().catch(() => ({}))).error;
    status(`${what} failed: ${why || r.status}`, true);
    return null;
  }
  const name = /filename="([^"]+)"/.exec(r.headers.get('Content-Disposition') || '')?.[1] || fallback;
  const a = document.createElement('a');
  a.href = URL.createObjectURL(await r.blob());
  a.download = name;
  document.body.appendChild(a);
  a.click();
  a.remove();
  return name;
}
// The whole session as one file: the server writes the mesh, the corrections with
// their history, the tissue and the image; the page adds its settings.
$('save-session').onclick = async () => {
  const name = await download(fetch(`/api/session?client=${state.client}`,
    { method: 'POST', body: JSON.stringify(pageSettings()) }), 'saving the session', 'session.meshpde');
  if (name) status(`saved the session as ${name}: open it again with file… (or meshpde serve ${name})`);
};
$('save').onclick = async () => {
  const format = $('save-format').value, displacement = $('save-displacement').checked ? 1 : 0;
  const name = await download(fetch(`/api/save?client=${state.client}&format=${format}&displacement=${displacement}`),
    'save', 'mesh');
  if (!name) return;
  status(`saved ${name}`);
  // The segmentation the server opened: the corrected one is written beside it.
  if (state.segmentation) send({ type: 'save_segmentation' });
};

// The largest difference between the normals as drawn (updated around moved vertices)
// and the whole mesh's recomputed, which then replace them (tests).
window.meshpde.normalsError = () => {
  if (!geometry) return NaN;
  const drawn = geometry.getAttribute('normal').array.slice();
  geometry.computeVertexNormals();
  const all = geometry.getAttribute('normal').array;
  let worst = 0;
  for (let i = 0; i < all.length; ++i) worst = Math.max(worst, Math.abs(all[i] - drawn[i]));
  return worst;
};

// Which of the correct tool's marks are on show, and where the handle's dot is (tests).
window.meshpde.marks = () => ({ rim: rimLines.visible, handleRim: handleLines.visible, dot: handleDot.visible,
  arrow: dragArrow.visible, dotAt: handleDot.position.toArray() });

// Whether a drag draws only its moving triangles over a kept image of the rest, and how
// many (tests); and the view's pixels as drawn now and as a whole redraw draws them,
// which ends that (tests: the two must be the same picture).
window.meshpde.stillDraw = () => ({ active: still.active, movingTriangles: still.movingTriangles,
  movingVertices: still.movingVertices });
window.meshpde.drawnAndWhole = () => {
  const drawn = window.meshpde.canvasPixels().data;
  still.thaw();
  renderer.render(scene, camera);
  return { drawn, whole: window.meshpde.canvasPixels().data };
};
// The 3D view's pixels as drawn (device pixels, origin top left; tests read them): data
// is RGBA row by row, rgb(x, y) one pixel's colour (black outside the view).
window.meshpde.canvasPixels = () => {
  const gl = renderer.domElement, c = document.createElement('canvas');
  c.width = gl.width; c.height = gl.height;
  const ctx = c.getContext('2d');
  ctx.drawImage(gl, 0, 0);
  const { width, height } = c, data = ctx.getImageData(0, 0, width, height).data;
  const rgb = (x, y) => (x < 0 || y < 0 || x >= width || y >= height ? [0, 0, 0]
    : Array.from(data.subarray(4 * (y * width + x), 4 * (y * width + x) + 3)));
  return { data, width, height, rgb };
};

// Screen position of a vertex (for tests and scripted demos).
window.meshpde.screenOf = (i) => {
  const P = state.positions;
  const v = new THREE.Vector3(P[3 * i], P[3 * i + 1], P[3 * i + 2]).project(camera);
  const r = renderer.domElement.getBoundingClientRect();
  return { x: r.left + (v.x + 1) / 2 * r.width, y: r.top + (1 - v.y) / 2 * r.height };
};

// A point of the scene as a pixel of the 3D view's canvas (device pixels, origin top
// left): where a test reads the rendered colour of that point.
window.meshpde.canvasPixelOf = (p) => {
  const v = new THREE.Vector3(p[0], p[1], p[2]).project(camera), c = renderer.domElement;
  return { x: (v.x + 1) / 2 * c.width, y: (1 - v.y) / 2 * c.height, inside: Math.abs(v.x) < 1 && Math.abs(v.y) < 1 && Math.abs(v.z) < 1 };
};

function loop() {
  requestAnimationFrame(loop);
  if (!dirty) return;
  dirty = false;
  controls.update();
  const t0 = performance.now();
  if (still.active) still.draw();
  else renderer.render(scene, camera);
  timed(state.timing.draw, performance.now() - t0);
  fpsCount += 1;
  state.frames += 1;
}
resize();
loop();
