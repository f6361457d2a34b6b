// The editor's server under load and abuse (issue 21 part 2), on loopback only, every
// loop bounded in count and time. Bare WebSocket clients (no browser), as in
// throughput.mjs.
//
//   node web/test/load.mjs MESHPDE_BINARY DATA_DIR [--seconds S] [--cycles N] [--sanitized] [--load-only]
//
// 1. Baseline: one page plays heat alone; the gaps between its field updates.
// 2. Load: seven pages play heat while an eighth uploads aorta-103k.vtp and corrects it
//    over and over (each correction several hundred ms); the seven pages' gaps. With
//    --sanitized the eighth corrects aorta-closed-6k.vtp instead: the same messages and
//    code, where one correction of the 100k mesh takes ten times as long.
// 3. Abuse, each against one page while a heat page watches: a message over the size
//    limit (closed with 1009), malformed messages (errors), a flood (the rate limit), a
//    half-sent HTTP request (dropped after the request timeout), an upload over
//    --max-upload-mb (413), a path outside the web root (404), and --host 0.0.0.0 (the
//    warning).
// 4. Cycles: N connect-edit-disconnect cycles, every third one closing in the middle
//    of a correction, every sixth painting, brushing, dragging (every twelfth closing
//    in the middle of the drag, the others releasing it), colouring by the correction,
//    undoing, redoing and asking for a region's rim: the server's resident memory,
//    threads and open files before and after.
//
// Prints one JSON object of figures (gaps in ms: p50, p99, max). Exits 1 when a
// functional check fails (a page starved of updates, an abuse not answered as
// documented, threads or files leaked, memory grown as if a tenth of the cycles' pages leaked); the timings
// are reported, never asserted (machines are shared and noisy).
import { spawn } from 'node:child_process';
import { randomBytes } from 'node:crypto';
import fs from 'node:fs';
import net from 'node:net';

const [binary, dataDir, ...rest] = process.argv.slice(2);
const opt = (name, fallback) => {
  const i = rest.indexOf(name);
  return i >= 0 ? +rest[i + 1] : fallback;
};
const seconds = opt('--seconds', 8), cycles = opt('--cycles', 1000);
// --sanitized: the server is the ASan+UBSan build. Its quarantine keeps freed memory
// (so resident memory is not compared) and it runs several times slower (so the heat
// pages' update-rate floor is not checked, and the correcting page's mesh is the
// 6k aorta); threads, files, errors and a clean sanitizer report still are.
const sanitized = rest.includes('--sanitized');
// --load-only: phases 1 and 2 only (to compare two builds of the server).
const loadOnly = rest.includes('--load-only');
if (!binary || !dataDir) {
  console.error('usage: node web/test/load.mjs MESHPDE_BINARY DATA_DIR [--seconds S] [--cycles N] [--sanitized] [--load-only]');
  process.exit(2);
}
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
const failures = [];
const check = (what, ok, detail = '') => { if (!ok) failures.push(`${what}${detail ? `: ${detail}` : ''}`); };

async function startServer(args) {
  const server = spawn(binary, ['serve', ...args, '--port', '0'], { stdio: ['ignore', 'pipe', 'pipe'] });
  let stderr = '';
  server.stderr.on('data', (d) => { stderr += d; });
  const port = await new Promise((resolve, reject) => {
    let out = '';
    const timer = setTimeout(() => reject(new Error('server did not start in 60 s')), 60000);
    server.stdout.on('data', (d) => {
      out += d;
      const m = /:(\d+)\//.exec(out);
      if (m) { clearTimeout(timer); resolve(+m[1]); }
    });
    server.on('exit', (c) => reject(new Error(`server exited ${c}: ${stderr}`)));
  });
  return { server, port, stderr: () => stderr };
}

// A minimal RFC 6455 client: masked frames out, text and binary frames in.
class Page {
  constructor(port) {
    this.port = port;
    this.buf = Buffer.alloc(0);
    this.messages = [];     // JSON messages received
    this.fieldTimes = [];   // arrival times of "FLD " frames
    this.closed = null;     // close status once closed
    this.waiters = [];
  }
  async open() {
    this.sock = net.connect(this.port, '127.0.0.1');
    await new Promise((r, j) => { this.sock.once('connect', r); this.sock.once('error', j); });
    this.sock.on('error', () => {});
    this.sock.on('close', () => { if (this.closed === null) this.closed = 1006; this.wake(); });
    this.sock.write(`GET / HTTP/1.1\r\nHost: 127.0.0.1:${this.port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n` +
                    `Sec-WebSocket-Key: ${randomBytes(16).toString('base64')}\r\nSec-WebSocket-Version: 13\r\n\r\n`);
    let handshaken = false;
    this.sock.on('data', (d) => {
      this.buf = Buffer.concat([this.buf, d]);
      if (!handshaken) {
        const end = this.buf.indexOf('\r\n\r\n');
        if (end < 0) return;
        this.buf = this.buf.subarray(end + 4);
        handshaken = true;
      }
      this.parse();
    });
    this.hello = await this.wait((m) => m.type === 'hello', 30000);
    await this.wait((m) => m.type === 'mesh', 60000);
    return this;
  }
  parse() {
    for (;;) {
      if (this.buf.length < 2) return;
      const op = this.buf[0] & 15;
      let len = this.buf[1] & 127, at = 2;
      if (len === 126) { if (this.buf.length < 4) return; len = this.buf.readUInt16BE(2); at = 4; }
      else if (len === 127) { if (this.buf.length < 10) return; len = Number(this.buf.readBigUInt64BE(2)); at = 10; }
      if (this.buf.length < at + len) return;
      const payload = this.buf.subarray(at, at + len);
      this.buf = this.buf.subarray(at + len);
      if (op === 1) this.messages.push(JSON.parse(payload.toString()));
      else if (op === 2 && payload.subarray(0, 4).toString() === 'FLD ') this.fieldTimes.push(performance.now());
      else if (op === 8) this.closed = payload.length >= 2 ? payload.readUInt16BE(0) : 1005;
      this.wake();
    }
  }
  wake() { for (const w of this.waiters.splice(0)) w(); }
  async wait(pred, ms) {
    const deadline = performance.now() + ms;
    let seen = 0;
    for (;;) {
      for (; seen < this.messages.length; ++seen) if (pred(this.messages[seen])) return this.messages[seen];
      if (this.closed !== null) throw new Error(`connection closed (${this.closed}) while waiting`);
      const left = deadline - performance.now();
      if (left <= 0) throw new Error('timed out waiting for a message');
      await new Promise((r) => { this.waiters.push(r); setTimeout(r, Math.min(left, 200)); });
    }
  }
  sendRaw(payload, opcode = 1) {
    const mask = randomBytes(4);
    let head;
    if (payload.length < 126) head = Buffer.from([0x80 | opcode, 0x80 | payload.length]);
    else if (payload.length < 65536) head = Buffer.from([0x80 | opcode, 0x80 | 126, payload.length >> 8, payload.length & 255]);
    else {
      head = Buffer.alloc(10);
      head[0] = 0x80 | opcode; head[1] = 0x80 | 127;
      head.writeBigUInt64BE(BigInt(payload.length), 2);
    }
    const body = Buffer.alloc(payload.length);
    for (let i = 0; i < payload.length; ++i) body[i] = payload[i] ^ mask[i & 3];
    this.sock.write(Buffer.concat([head, mask, body]));
  }
  send(obj) { this.sendRaw(Buffer.from(JSON.stringify(obj))); }
  async request(obj, ms = 60000) {
    const from = this.messages.length;
    this.send(obj);
    return this.wait((m) => this.messages.indexOf(m) >= from && (m.type === 'ok' || m.type === 'error') &&
                            m.request === obj.type, ms);
  }
  close() { this.sock.destroy(); }
}

// Gap statistics (ms) of update arrival times within [from, to]: over one page's
// series, or pooled over several pages' (each page's gaps are its own).
function gaps(series, from, to) {
  const g = [];
  let updates = 0;
  for (const times of series) {
    const t = times.filter((x) => x >= from && x <= to);
    updates += t.length;
    for (let i = 1; i < t.length; ++i) g.push(t[i] - t[i - 1]);
  }
  g.sort((a, b) => a - b);
  const q = (p) => (g.length ? g[Math.min(g.length - 1, Math.floor(p * g.length))] : Infinity);
  return { updates, p50: +q(0.5).toFixed(1), p99: +q(0.99).toFixed(1), max: +(g.length ? g[g.length - 1] : Infinity).toFixed(1) };
}

async function heatPage(port) {
  const p = await new Page(port).open();
  await p.request({ type: 'source', vertex: 100 });
  await p.request({ type: 'play', kind: 'heat' });
  return p;
}

// Waits until the closed pages' workers have finished and been joined (the server
// trims the heap when it joins them; on a loaded machine the last correction may take
// a while) and returns the server's figures then.
async function quiet(pid, threads) {
  let now = null;
  for (let t = 0; t < 30; ++t) {
    await sleep(500);
    now = procStats(pid);
    if (t >= 3 && now.threads === threads) break;
  }
  return now;
}

function procStats(pid) {
  const status = fs.readFileSync(`/proc/${pid}/status`, 'utf8');
  return {
    rss_mb: +(+/VmRSS:\s+(\d+)/.exec(status)[1] / 1024).toFixed(1),
    threads: +/Threads:\s+(\d+)/.exec(status)[1],
    files: fs.readdirSync(`/proc/${pid}/fd`).length,
  };
}

async function httpRaw(port, text, waitMs) {
  // Sends `text` and reports whether (and when) the server closed the connection.
  const sock = net.connect(port, '127.0.0.1');
  await new Promise((r) => sock.once('connect', r));
  const t0 = performance.now();
  let reply = '';
  sock.on('data', (d) => { reply += d; });
  sock.on('error', () => {});
  sock.write(text);
  const closedAt = await new Promise((r) => {
    sock.once('close', () => r(performance.now() - t0));
    setTimeout(() => r(null), waitMs);
  });
  sock.destroy();
  return { closedAfterMs: closedAt, reply };
}

// Stops a server with SIGTERM: it must exit 0 with no sanitizer report (in the
// sanitizer build, leaks at exit are reported by LeakSanitizer and fail it).
async function stopServer(srv, stderr, what) {
  srv.kill('SIGTERM');
  const code = await new Promise((r) => (srv.exitCode !== null ? r(srv.exitCode) : srv.once('exit', (c) => r(c))));
  check(`${what}: stops with status 0 on SIGTERM`, code === 0, `${code}`);
  check(`${what}: no sanitizer report`, !/Sanitizer/.test(stderr()), stderr().slice(0, 2000));
}

const report = {};
const aortaName = sanitized ? 'aorta-closed-6k.vtp' : 'aorta-103k.vtp';
const aortaVertices = sanitized ? 5000 : 100000;  // at least
const aorta = `${dataDir}/${aortaName}`;
if (!fs.existsSync(aorta)) {
  console.log(`missing test data ${aorta}`);
  process.exit(process.env.CI === 'true' ? 1 : 77);  // 77: skipped (a failure under CI=true)
}
const { server, port, stderr: serverStderr } = await startServer(['--max-upload-mb', '16']);
try {
  // 1. Baseline: one heat page alone.
  {
    const p = await heatPage(port);
    const t0 = performance.now();
    await sleep(seconds * 1000);
    report.baseline_one_page = gaps([p.fieldTimes], t0 + 500, performance.now());
    check('the lone heat page gets updates', report.baseline_one_page.updates > seconds * 5);
    p.close();
  }
  // 2. Seven heat pages and one correcting a real aorta (100k vertices; 6k --sanitized).
  phase2: {
    const heat = [];
    for (let i = 0; i < 7; ++i) heat.push(await heatPage(port));
    const worker = await new Page(port).open();
    const bytes = fs.readFileSync(aorta);
    const up = await fetch(`http://127.0.0.1:${port}/api/upload?client=${worker.hello.client}&name=${aortaName}`,
                           { method: 'POST', body: bytes });
    const upJson = await up.json();
    check(`${aortaName} uploads`, up.ok && upJson.vertices > aortaVertices, JSON.stringify(upJson));
    const t0 = performance.now();
    const times = [];
    let k = 0;
    // At least the given seconds, and until two corrections are done (at most a
    // minute): on two loaded cores one correction can take 4 s while the seven pages
    // step (0.7 s alone), so the count is not asked of a fixed window.
    const wanted = sanitized ? 1 : 2;
    while (performance.now() - t0 < seconds * 1000 || (times.length < wanted && performance.now() - t0 < 60000)) {
      const i = k++ % 50;
      const vertex = sanitized ? 200 + 97 * i : 20000 + 997 * i;
      const r = await worker.request({ type: 'correct', vertex, move: [0, 0, 0.5], radius: 14 });
      if (r.type === 'ok') times.push(r.time_ms);
    }
    const t1 = performance.now();
    const per = heat.map((p) => gaps([p.fieldTimes], t0 + 500, t1));
    const all = gaps(heat.map((p) => p.fieldTimes), t0 + 500, t1);
    report.load = {
      pages: 8,
      corrections: times.length,
      correction_ms: { min: +Math.min(...times).toFixed(1), max: +Math.max(...times).toFixed(1),
                       mean: +(times.reduce((a, b) => a + b, 0) / Math.max(1, times.length)).toFixed(1) },
      heat_gap_ms_p99_over_seven_pages: all.p99,
      heat_gap_ms_max: all.max,
      per_page: per,
    };
    check('corrections ran', times.length >= wanted, `${times.length}`);
    // Starved pages would get nothing while a correction runs; each must keep a
    // quarter of the lone page's rate at least (not a timing target: a sanity floor).
    const rate = report.baseline_one_page.updates / (seconds - 0.5);
    for (const [i, g] of per.entries())
      if (!sanitized) check(`heat page ${i} keeps getting updates while another corrects`,
            g.updates >= 0.25 * rate * ((t1 - t0) / 1000 - 0.5), JSON.stringify(g));
    if (loadOnly) {
      heat.forEach((p) => p.close());
      worker.close();
      break phase2;
    }
    // 3. Abuse against one more page while the heat pages watch.
    const victim = await new Page(port).open();
    const before = heat.map((p) => p.fieldTimes.length);
    const bad = await victim.request({ type: 'correct', vertex: 'x' });
    check('a request of the wrong shape gets an error', bad.type === 'error' && /vertex/.test(bad.message), JSON.stringify(bad));
    victim.sendRaw(Buffer.from('not json'));
    await victim.wait((m) => m.type === 'error' && /JSON/.test(m.message), 10000);
    victim.sendRaw(Buffer.from([1, 2, 3]), 2);
    await victim.wait((m) => m.type === 'error' && /text message/.test(m.message), 10000);
    const from = victim.messages.length;
    for (let i = 0; i < 5000; ++i) victim.send({ type: 'ping' });
    const limited = await victim.wait((m) => victim.messages.indexOf(m) >= from && m.type === 'error' && /rate limit/.test(m.message), 20000);
    report.flood = { sent: 5000, answer: limited.message };
    await sleep(1500);
    const pong = await victim.request({ type: 'ping' });
    check('after a flood the page is served again', pong.type === 'ok');
    victim.sendRaw(Buffer.alloc((1 << 20) + 16, 32));
    for (let i = 0; i < 50 && victim.closed === null; ++i) await sleep(100);
    check('a message over 1 MiB closes that connection with 1009', victim.closed === 1009, `${victim.closed}`);
    await sleep(500);
    // More than ten updates each in the abuse's 2-3 seconds; the sanitizer build's
    // server steps heat several times slower (8-10 updates a page there on the
    // development machine), so there the pages need only keep getting some.
    const needed = sanitized ? 3 : 10;
    heat.forEach((p, i) => check(`heat page ${i} unaffected by the abuse`, p.fieldTimes.length > before[i] + needed && p.closed === null,
                                 `${p.fieldTimes.length - before[i]} updates during it, closed: ${p.closed}`));
    // Uploads over the limit, paths outside the web root, half-sent requests.
    const big = await fetch(`http://127.0.0.1:${port}/api/upload?client=${heat[0].hello.client}&name=big.ply`,
                            { method: 'POST', body: Buffer.alloc(17 * 1024 * 1024, 32) }).then((r) => r.status, () => -1);
    check('an upload over --max-upload-mb is refused', big === 413 || big === -1, `${big}`);
    for (const path of ['/../../etc/passwd', '/%2e%2e/%2e%2e/etc/passwd', '/..%2f..%2fetc%2fpasswd']) {
      const r = await httpRaw(port, `GET ${path} HTTP/1.1\r\nHost: x\r\n\r\n`, 3000);
      check(`no file outside the web root: ${path}`, /^HTTP\/1\.1 (404|400)/.test(r.reply), r.reply.slice(0, 40));
    }
    const half = await httpRaw(port, 'GET /index.html HTTP/1.1\r\nHost: 127', 20000);
    report.half_sent_request_dropped_after_ms = half.closedAfterMs === null ? null : Math.round(half.closedAfterMs);
    check('a half-sent HTTP request is dropped within 15 s', half.closedAfterMs !== null && half.closedAfterMs < 15000,
          `${half.closedAfterMs}`);
    heat.forEach((p) => p.close());
    worker.close();
  }
} finally {
  await stopServer(server, serverStderr, 'the load server');
}

// 4. Connect-edit-disconnect cycles on a small mesh.
if (!loadOnly) {
  const small = `${process.env.TMPDIR || '/tmp'}/meshpde-load-${process.pid}.ply`;
  await new Promise((r, j) => spawn(binary, ['generate', 'icosphere', '--level', '3', '-o', small]).on('exit', (c) => (c ? j(new Error('generate')) : r())));
  const { server: s2, port: p2, stderr: s2err } = await startServer([small]);
  try {
    const cycle = async (k) => {
      const p = await new Page(p2).open();
      if (k % 3 === 0) {
        p.send({ type: 'correct', vertex: k % 600, move: [0, 0, 0.05], radius: 0.4 });
        await sleep(1);
        p.close();  // in the middle of the correction
        return;
      }
      if (k % 6 === 1) {
        // The other editing requests, each answered 'ok': paint, vectors, the tissue
        // brush, a drag (every other time left open at the close), undo and redo.
        const v = k % 600;
        const answeredOk = async (requests) => {
          for (const m of requests) {
            const r = await p.request(m);
            check(`cycle ${k}: ${m.type} answered ok`, r.type === 'ok', JSON.stringify(r).slice(0, 300));
          }
        };
        await answeredOk([{ type: 'paint', vertex: v, value: 1 }, { type: 'paint', vertex: (v + 300) % 600, value: 0 },
                          { type: 'paint_vector', vertex: (v + 100) % 600, vector: [0, 0, 0.1] }, { type: 'clear_paint' },
                          { type: 'brush', property: 'stiffness', vertex: v, radius: 0.3, value: 3 },
                          { type: 'drag_begin', vertex: v, radius: 0.4 }]);
        p.send({ type: 'drag_move', offset: [0, 0, 0.03] });
        if (k % 12 === 1) { p.close(); return; }  // closed in the middle of the drag
        // Released as the page releases a drag: the preview ends and the correction is sent.
        await answeredOk([{ type: 'drag_end' }, { type: 'correct', vertex: v, move: [0, 0, 0.03], radius: 0.4 },
                          { type: 'colour', field: 'moved (mm)' }, { type: 'undo' }, { type: 'redo' }]);
        // The region's rim as the page asks for it on hover (answered by a binary frame,
        // an error only in words): no error by the time a ping is answered.
        const from = p.messages.length;
        p.send({ type: 'rim', point: [0, 0, 1], radius: 0.4, seq: k });
        await p.request({ type: 'ping' });
        const bad = p.messages.slice(from).find((m) => m.type === 'error');
        check(`cycle ${k}: rim answered without an error`, !bad, JSON.stringify(bad || {}).slice(0, 300));
        p.close();
        return;
      }
      await p.request({ type: k % 2 ? 'correct' : 'poke_begin', vertex: k % 600, move: [0, 0, 0.05], radius: 0.4 });
      if (k % 2 === 0) await p.request({ type: 'poke_end' });
      p.close();
    };
    for (let k = 0; k < 50; ++k) await cycle(k);  // warm up the allocator
    // A page whose message is over the limit reads the close frame (1009) every time,
    // not a reset that loses it (which happened about one time in four).
    const tooBig = [];
    for (let k = 0; k < 30; ++k) {
      const p = await new Page(p2).open();
      p.sendRaw(Buffer.alloc((1 << 20) + 16, 32));
      for (let i = 0; i < 50 && p.closed === null; ++i) await sleep(20);
      tooBig.push(p.closed);
      p.close();
    }
    check('30 pages out of 30 with a message over 1 MiB read the close status 1009', tooBig.every((c) => c === 1009),
          JSON.stringify(tooBig));
    await sleep(1500);  // the server keeps such a socket a second before closing it
    // What one page costs while open (its session, operators, buffers): the yardstick
    // for a leak. The figure is measured, not assumed, so the check follows the mesh
    // and the build.
    const before = procStats(s2.pid);
    const open = [];
    for (let k = 0; k < 40; ++k) {
      const p = await new Page(p2).open();
      await p.request({ type: 'correct', vertex: k * 7, move: [0, 0, 0.05], radius: 0.4 });
      open.push(p);
    }
    const perPageKb = Math.max(0, ((procStats(s2.pid).rss_mb - before.rss_mb) * 1024) / open.length);
    for (const p of open) p.close();
    await quiet(s2.pid, before.threads);
    const start = procStats(s2.pid);
    const trace = [start.rss_mb];
    for (let k = 50; k < 50 + cycles; ++k) {
      await cycle(k);
      if ((k - 49) % 250 === 0) trace.push(procStats(s2.pid).rss_mb);
    }
    const end = await quiet(s2.pid, start.threads);
    // A leak grows with the cycles; glibc's arenas do not: they keep what the busiest
    // moment needed (up to 5 MB over a 22 MB server, seen on a loaded CI machine, and
    // from 23 to 28 MB and back within 4,000 cycles), however many cycles follow. So
    // the bound is what leaking a tenth of the cycles' pages would add, and never
    // less than 8 MB.
    const allowedMb = Math.max(8, (0.1 * cycles * perPageKb) / 1024);
    report.cycles = { count: cycles, page_kb: +perPageKb.toFixed(0), start, end, allowed_growth_mb: +allowedMb.toFixed(1), rss_mb_every_250: trace };
    check('threads return to where they started', end.threads === start.threads, `${start.threads} -> ${end.threads}`);
    check('open files return to where they started', end.files === start.files, `${start.files} -> ${end.files}`);
    if (!sanitized)
      check('resident memory grows less than leaking a tenth of the pages would make it', end.rss_mb - start.rss_mb <= allowedMb,
            `${start.rss_mb} -> ${end.rss_mb} MB, allowed +${allowedMb.toFixed(1)} MB (one page ${perPageKb.toFixed(0)} kB)`);
  } finally {
    await stopServer(s2, s2err, 'the cycling server');
    fs.rmSync(small, { force: true });
  }
}

// The warning for a server reachable beyond this machine (bound, never connected to).
if (!loadOnly) {
  const { server: s3, stderr } = await startServer(['--host', '0.0.0.0']);
  await sleep(300);
  check('--host 0.0.0.0 warns that the editor has no authentication', /no authentication/.test(stderr()), stderr());
  await stopServer(s3, stderr, 'the 0.0.0.0 server');
}

report.failures = failures;
console.log(JSON.stringify(report, null, 1));
process.exit(failures.length ? 1 : 0);
