// How fast does `meshpde serve` stream a poke? A bare WebSocket client (no browser,
// so page rendering does not limit it) pokes a mesh and counts the update frames it
// receives, their sizes, the probe's active domain and the server's time per frame.
//
//   node web/test/throughput.mjs MESHPDE_BINARY MESH [--influence L] [--seconds S] [--warmup W]
//   node web/test/throughput.mjs MESHPDE_BINARY MESH --slices [VOLUME] [--space ras|lps]
//   node web/test/throughput.mjs MESHPDE_BINARY MESH --browser-drag [--seconds S] [--radius R]
//
// --browser-drag measures a correct drag in the page itself (Debian's chromium through
// playwright-core, headless, drawing in software): the mouse presses on the mesh
// and circles for S seconds while the preview streams; it reports the position updates
// the page applied and the frames it drew per second, and where an update's time goes:
// the server's time to build it (stats frame_ms), the page's work on it (decode, normals,
// colours) and the drawing of a frame.
//
// --slices times the image view's slices: 30 slider positions along each of the three
// planes, one request at a time, from the request to the whole SLC frame received
// (the server's sampling and window/level, and the transfer). Without VOLUME it
// generates a 512 x 512 x 300 CT (synthetic-ct.mjs) and removes it afterwards.
// --warmup W pokes for W seconds before counting, so the probe's active domain has
// grown to its full size when the measurement starts.
//
// Prints one JSON object. The server sends at most one update every 16 ms (62.5/s).
import { spawn } from 'node:child_process';
import { randomBytes } from 'node:crypto';
import net from 'node:net';
import os from 'node:os';
import { rmSync } from 'node:fs';
import { join } from 'node:path';
import { writeSyntheticCT } from './synthetic-ct.mjs';

const [binary, meshPath, ...rest] = process.argv.slice(2);
const opt = (name, fallback) => {
  const i = rest.indexOf(name);
  return i >= 0 ? +rest[i + 1] : fallback;
};
const influence = opt('--influence', 0), seconds = opt('--seconds', 4), warmup = opt('--warmup', 0);
const simulation = rest.includes('--wave') ? 'wave' : rest.includes('--heat') ? 'heat' : '';
const slices = rest.includes('--slices'), browserDrag = rest.includes('--browser-drag');
if (!binary || !meshPath) {
  console.error('usage: node web/test/throughput.mjs MESHPDE_BINARY MESH [--influence L] [--seconds S] [--slices [VOLUME]]');
  process.exit(2);
}
let volume = null, generatedVolume = null;
if (slices) {
  const next = rest[rest.indexOf('--slices') + 1];
  volume = next && !next.startsWith('--') ? next : null;
  if (!volume) {
    generatedVolume = volume = join(os.tmpdir(), `meshpde-ct-${process.pid}.mha`);
    writeSyntheticCT(volume);
  }
}
const spaceAt = rest.indexOf('--space');
const serveArgs = ['serve', meshPath, '--port', '0', ...(volume ? ['--image', volume] : []),
                   ...(spaceAt >= 0 ? ['--space', rest[spaceAt + 1]] : [])];
const loadStart = performance.now();
const server = spawn(binary, serveArgs, { stdio: ['ignore', 'pipe', 'inherit'] });
const port = await new Promise((resolve, reject) => {
  let out = '';
  server.stdout.on('data', (d) => {
    out += d;
    const m = /:(\d+)\//.exec(out);
    if (m) resolve(+m[1]);
  });
  server.on('exit', (c) => reject(new Error(`server exited ${c}`)));
});

if (browserDrag) {
  // The page as it draws in a software-rendered browser, and with ?quality=full (as a
  // GPU would draw it: multisampled, physically based shading, full resolution) as the
  // baseline of the same run.
  const out = { software_mode: await dragInTheBrowser(port, ''), full_quality: await dragInTheBrowser(port, '?quality=full') };
  server.kill('SIGINT');
  console.log(JSON.stringify(out, null, 2));
  process.exit(0);
}

// A correct drag in chromium: the page's own rates and timings (see the header).
async function dragInTheBrowser(port, query) {
  const { chromium } = await import('playwright-core');
  const browser = await chromium.launch({
    executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
    args: ['--no-sandbox', '--disable-gpu', '--enable-unsafe-swiftshader', '--disable-dev-shm-usage'],
  });
  try {
    const page = await (await browser.newContext({ viewport: { width: 1280, height: 800 } })).newPage();
    await page.goto(`http://127.0.0.1:${port}/${query}`);
    await page.waitForFunction(() => window.meshpde?.ready, null, { timeout: 120000 });
    await page.check('input[name=tool][value=correct]');
    await page.fill('#radius', String(opt('--radius', 8)));
    const box = await page.locator('#viewport > canvas').boundingBox();
    // The vertex drawn nearest the view's centre: where the drag starts.
    const from = await page.evaluate(() => {
      const c = document.querySelector('#viewport > canvas').getBoundingClientRect();
      const mid = { x: c.left + c.width / 2, y: c.top + c.height / 2 };
      let best = null, bestD = Infinity;
      for (let i = 0; i < meshpde.vertexCount; i += 7) {
        const q = meshpde.screenOf(i), d = Math.hypot(q.x - mid.x, q.y - mid.y);
        if (d < bestD) { bestD = d; best = q; }
      }
      return best;
    });
    await page.mouse.move(from.x, from.y);
    await page.mouse.down();
    await page.waitForFunction(() => meshpde.lastOk === 'drag_begin', null, { timeout: 60000 }).catch(() => {});
    const region = await page.evaluate(() => document.getElementById('status').textContent);
    const before = await page.evaluate(() => ({ updates: meshpde.updates, frames: meshpde.frames,
      page: meshpde.timing.page.length, draw: meshpde.timing.draw.length }));
    // The mouse circles at 60 moves a second, as a real one would (pointer events sent
    // in the page on a timer: the browser's own pace, not this script's round trips).
    const t0 = Date.now();
    const r = Math.min(40, box.width / 10);
    const moved = await page.evaluate(([x, y, radius, ms]) => new Promise((done) => {
      const canvas = document.querySelector('#viewport > canvas'), frame = [];
      let k = 0;
      const timer = setInterval(() => {
        k += 1;
        canvas.dispatchEvent(new PointerEvent('pointermove', { bubbles: true, pointerId: 1, buttons: 1,
          clientX: x + radius * Math.sin(k / 10), clientY: y - radius * (1 - Math.cos(k / 10)) }));
        if (k % 30 === 0) frame.push(+document.getElementById('stat-frame').textContent);
      }, 1000 / 60);
      setTimeout(() => { clearInterval(timer); done({ moves: k, frame }); }, ms);
    }), [from.x, from.y, r, seconds * 1000]);
    const stats = moved.frame;
    const elapsed = (Date.now() - t0) / 1000;
    const after = await page.evaluate(() => ({ updates: meshpde.updates, frames: meshpde.frames,
      page: meshpde.timing.page, draw: meshpde.timing.draw, vertices: meshpde.vertexCount,
      triangles: meshpde.faceCount, split: meshpde.stillDraw() }));
    await page.mouse.up();
    const tail = (list, n) => list.slice(Math.max(0, list.length - n));
    const pct = (a, q) => { const x = [...a].sort((u, v) => u - v); return x.length ? +x[Math.min(x.length - 1, Math.floor(q * x.length))].toFixed(1) : 0; };
    const pageMs = tail(after.page, after.page.length - before.page), drawMs = tail(after.draw, after.draw.length - before.draw);
    return {
      vertices: after.vertices, seconds: +elapsed.toFixed(2), drag_set_up: region,
      // Drawn each frame while the still part is kept (0: the whole mesh is drawn).
      moving_triangles: after.split.movingTriangles, moving_vertices: after.split.movingVertices,
      triangles: after.triangles,
      software_renderer_detected: await page.evaluate(() => meshpde.software),
      mouse_moves_per_second: +(moved.moves / elapsed).toFixed(1),
      updates_per_second: +((after.updates - before.updates) / elapsed).toFixed(1),
      frames_per_second: +((after.frames - before.frames) / elapsed).toFixed(1),
      server_frame_ms_p50: pct(stats.filter(Number.isFinite), 0.5),
      page_ms_per_update_p50: pct(pageMs, 0.5), page_ms_per_update_p90: pct(pageMs, 0.9),
      draw_ms_per_frame_p50: pct(drawMs, 0.5), draw_ms_per_frame_p90: pct(drawMs, 0.9),
    };
  } finally {
    await browser.close();
  }
}

// A minimal RFC 6455 client: text frames out (masked), any frames in.
const sock = net.connect(port, '127.0.0.1');
await new Promise((r) => sock.once('connect', r));
sock.write(`GET / HTTP/1.1\r\nHost: 127.0.0.1:${port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n` +
           `Sec-WebSocket-Key: ${randomBytes(16).toString('base64')}\r\nSec-WebSocket-Version: 13\r\n\r\n`);
function sendText(obj) {
  const payload = Buffer.from(JSON.stringify(obj));
  const mask = randomBytes(4);
  const head = payload.length < 126 ? Buffer.from([0x81, 0x80 | payload.length])
                                    : Buffer.from([0x81, 0x80 | 126, payload.length >> 8, payload.length & 255]);
  const body = Buffer.from(payload.map((b, i) => b ^ mask[i % 4]));
  sock.write(Buffer.concat([head, mask, body]));
}
let buf = Buffer.alloc(0), handshaken = false;
const frames = [];
let onFrame = () => {};
sock.on('data', (d) => {
  buf = Buffer.concat([buf, d]);
  if (!handshaken) {
    const end = buf.indexOf('\r\n\r\n');
    if (end < 0) return;
    buf = buf.subarray(end + 4);
    handshaken = true;
  }
  for (;;) {
    if (buf.length < 2) return;
    const op = buf[0] & 15;
    let len = buf[1] & 127, off = 2;
    if (len === 126) { if (buf.length < 4) return; len = buf.readUInt16BE(2); off = 4; }
    else if (len === 127) { if (buf.length < 10) return; len = Number(buf.readBigUInt64BE(2)); off = 10; }
    if (buf.length < off + len) return;
    const payload = buf.subarray(off, off + len);
    buf = buf.subarray(off + len);
    onFrame(op, payload);
  }
});

let mesh = null, stats = [], updates = [], started = 0, slice = null;
onFrame = (op, p) => {
  if (op === 2 && p.subarray(0, 4).toString() === 'SLC ') {
    slice = { t: performance.now(), seq: p.readUInt32LE(16), width: p.readUInt32LE(8), height: p.readUInt32LE(12), bytes: p.length };
    return;
  }
  if (op === 1) {
    const m = JSON.parse(p.toString());
    if (m.type === 'mesh') mesh = m;
    if (m.type === 'stats' && started) stats.push(m);
    if (m.type === 'error') console.error('server error:', m.message);
  } else if (op === 2 && started && ['POS ', 'FLD '].includes(p.subarray(0, 4).toString())) {
    updates.push({ t: performance.now(), n: p.readUInt32LE(4), bytes: p.length });
  }
};
while (!mesh) await new Promise((r) => setTimeout(r, 20));
await new Promise((r) => setTimeout(r, 300));

const vertex = Math.floor(mesh.vertices / 2);
if (slices) {
  if (!mesh.image) { console.error('the server has no image'); process.exit(1); }
  const im = mesh.image, out = { volume: im.dims.join('x'), server_start_s: +((performance.now() - loadStart) / 1000).toFixed(1) };
  let seq = 0;
  for (const [k, axis] of ['axial', 'coronal', 'sagittal'].entries()) {
    const n = [2, 1, 0][k], [lo, hi] = [im.bounds[0][n], im.bounds[1][n]], ms = [];
    let last = null;
    for (let i = 0; i < 30; ++i) {
      seq += 1;
      slice = null;
      const t = performance.now();
      sendText({ type: 'slice', axis, position: lo + ((i + 0.5) / 30) * (hi - lo), window: im.window, level: im.level, seq });
      while (!slice || slice.seq !== seq) await new Promise((r) => setImmediate(r));
      ms.push(slice.t - t);
      last = slice;
    }
    ms.sort((a, b) => a - b);
    out[axis] = { pixels: `${last.width}x${last.height}`, bytes: last.bytes, p50_ms: +ms[15].toFixed(2),
                  p90_ms: +ms[27].toFixed(2), max_ms: +ms[29].toFixed(2) };
  }
  sock.end();
  server.kill('SIGINT');
  if (generatedVolume) rmSync(generatedVolume, { force: true });
  console.log(JSON.stringify(out, null, 2));
  process.exit(0);
}
if (simulation) {
  // --heat / --wave: a source at the middle vertex, played; the updates are whole fields.
  sendText({ type: 'source', vertex });
  sendText({ type: 'play', kind: simulation });
  await new Promise((r) => setTimeout(r, warmup * 1000));
  started = performance.now();
  await new Promise((r) => setTimeout(r, seconds * 1000));
  const elapsedSim = (performance.now() - started) / 1000;
  sock.end();
  server.kill('SIGINT');
  const g = updates.slice(1).map((u, i) => u.t - updates[i].t).sort((a, b) => a - b);
  console.log(JSON.stringify({
    vertices: mesh.vertices, simulation, seconds: +elapsedSim.toFixed(2),
    updates_per_second: +(updates.length / elapsedSim).toFixed(1),
    update_gap_ms_p50: g.length ? +g[Math.floor(0.5 * g.length)].toFixed(1) : 0,
    values_per_update: updates.length ? updates[0].n : 0,
    megabytes_per_second: +(updates.reduce((s, u) => s + u.bytes, 0) / elapsedSim / 1e6).toFixed(2),
    server_frame_ms_p50: stats.length ? +stats.map((x) => x.frame_ms).sort((a, b) => a - b)[Math.floor(stats.length / 2)].toFixed(2) : 0,
    active_domain_p50: stats.length ? stats.map((x) => x.active).sort((a, b) => a - b)[Math.floor(stats.length / 2)] : 0,
    active_domain_max: Math.max(0, ...stats.map((x) => x.active)),
  }, null, 2));
  process.exit(0);
}
// Poke the middle vertex and move the probe in and out for the whole run.
sendText({ type: 'poke_begin', vertex, influence });
const amplitude = 3 * mesh.mean_edge;
const t0 = performance.now();
let counting = false;
while (performance.now() - t0 < (warmup + seconds) * 1000) {
  const t = (performance.now() - t0) / 1000;
  if (!counting && t >= warmup) {
    counting = true;
    started = performance.now();
  }
  sendText({ type: 'poke_move', offset: [0, 0, -amplitude * (0.5 + 0.5 * Math.abs(Math.sin(2 * t)))] });
  await new Promise((r) => setTimeout(r, 8));
}
const elapsed = (performance.now() - started) / 1000;  // the counted window only
sendText({ type: 'poke_end' });
sock.end();
server.kill('SIGINT');

const sorted = (a) => [...a].sort((x, y) => x - y);
const pct = (a, q) => (a.length ? sorted(a)[Math.min(a.length - 1, Math.floor(q * a.length))] : 0);
const gaps = updates.slice(1).map((u, i) => u.t - updates[i].t);
console.log(JSON.stringify({
  vertices: mesh.vertices,
  seconds: +elapsed.toFixed(2),
  updates_per_second: +(updates.length / elapsed).toFixed(1),
  update_gap_ms_p50: +pct(gaps, 0.5).toFixed(1),
  update_gap_ms_p99: +pct(gaps, 0.99).toFixed(1),
  moved_vertices_per_update_p50: pct(updates.map((u) => u.n), 0.5),
  moved_vertices_per_update_max: Math.max(0, ...updates.map((u) => u.n)),
  megabytes_per_second: +(updates.reduce((s, u) => s + u.bytes, 0) / elapsed / 1e6).toFixed(2),
  active_domain_p50: pct(stats.map((s) => s.active), 0.5),
  active_domain_max: Math.max(0, ...stats.map((s) => s.active)),
  server_frame_ms_p50: +pct(stats.map((s) => s.frame_ms), 0.5).toFixed(2),
  server_frame_ms_max: +Math.max(0, ...stats.map((s) => s.frame_ms)).toFixed(2),
  probe_step_p99_us: stats.length ? stats[stats.length - 1].p99_us : 0,
  probe_misses: stats.length ? stats[stats.length - 1].misses : 0,
}, null, 2));
process.exit(0);
