// Kestrel ground station page: talks MQTT over the broker's WebSocket listener (MQTT.js), decodes
// the telemetry schema v1 (comm/SCHEMA.md: agents send CBOR; commands go out as JSON, which every
// decoder accepts), draws the agents on a 2D map and sends goals, teleop and pings.
'use strict';

const kSchema = 1;
const kColors = ['#4fc3f7', '#ffb74d', '#aed581', '#f06292', '#ba68c8', '#fff176'];
const kTrajectoryMax = 20000;  // points kept per agent
const kPingPeriodMs = 1000;
const kRetryMs = 1000;         // a goal is re-sent (same id) until acknowledged
const kRetries = 10;

// ---- CBOR (RFC 8949), the subset nlohmann::json::to_cbor writes ------------------------------
function decodeCbor(bytes) {
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  let pos = 0;
  const need = (n) => { if (pos + n > bytes.length) throw new Error('truncated CBOR'); };
  const argument = (info) => {
    if (info < 24) return info;
    if (info === 24) { need(1); return view.getUint8(pos++); }
    if (info === 25) { need(2); const v = view.getUint16(pos); pos += 2; return v; }
    if (info === 26) { need(4); const v = view.getUint32(pos); pos += 4; return v; }
    if (info === 27) {
      need(8);
      const v = view.getBigUint64(pos); pos += 8;
      // Stamps in ns exceed 2^53: keep them exact as BigInt; small values stay numbers.
      return v <= BigInt(Number.MAX_SAFE_INTEGER) ? Number(v) : v;
    }
    throw new Error('unsupported CBOR length ' + info);
  };
  const half = (h) => {
    const e = (h >> 10) & 0x1f, f = h & 0x3ff, s = h & 0x8000 ? -1 : 1;
    if (e === 0) return s * f * 2 ** -24;
    if (e === 31) return f ? NaN : s * Infinity;
    return s * (1 + f / 1024) * 2 ** (e - 15);
  };
  const item = (depth) => {
    if (depth > 32) throw new Error('CBOR nested too deep');
    need(1);
    const head = view.getUint8(pos++);
    const major = head >> 5, info = head & 31;
    switch (major) {
      case 0: return argument(info);
      case 1: { const a = argument(info); return typeof a === 'bigint' ? -1n - a : -1 - a; }
      case 2: { const n = Number(argument(info)); need(n); const b = bytes.slice(pos, pos + n); pos += n; return b; }
      case 3: {
        const n = Number(argument(info)); need(n);
        const s = new TextDecoder().decode(bytes.subarray(pos, pos + n)); pos += n; return s;
      }
      case 4: { const n = Number(argument(info)); const a = []; for (let i = 0; i < n; ++i) a.push(item(depth + 1)); return a; }
      case 5: {
        const n = Number(argument(info)); const m = {};
        for (let i = 0; i < n; ++i) { const k = item(depth + 1); m[k] = item(depth + 1); }
        return m;
      }
      case 7:
        if (info === 20) return false;
        if (info === 21) return true;
        if (info === 22 || info === 23) return null;
        if (info === 25) { need(2); const v = half(view.getUint16(pos)); pos += 2; return v; }
        if (info === 26) { need(4); const v = view.getFloat32(pos); pos += 4; return v; }
        if (info === 27) { need(8); const v = view.getFloat64(pos); pos += 8; return v; }
        throw new Error('unsupported CBOR simple value ' + info);
      default: throw new Error('unsupported CBOR major type ' + major);
    }
  };
  const value = item(0);
  if (pos !== bytes.length) throw new Error('trailing bytes after CBOR item');
  return value;
}

// A payload is a CBOR map (0xa0..0xbf) or JSON text (comm/codec.cpp decides the same way).
function decodePayload(bytes) {
  let i = 0;
  while (i < bytes.length && (bytes[i] === 0x20 || bytes[i] === 0x0a || bytes[i] === 0x0d || bytes[i] === 0x09)) ++i;
  if (i < bytes.length && bytes[i] === 0x7b) return JSON.parse(new TextDecoder().decode(bytes));
  return decodeCbor(bytes);
}

// ---- occupancy-grid deltas: zlib(runs of LEB128 skip,count + count cell bytes) ----------------
async function inflate(bytes) {
  const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream('deflate'));
  return new Uint8Array(await new Response(stream).arrayBuffer());
}

function applyRuns(cells, raw) {
  let pos = 0, cell = 0;
  const varint = () => {
    let v = 0, shift = 0;
    for (;;) {
      if (pos >= raw.length || shift > 49) throw new Error('bad varint in grid runs');
      const b = raw[pos++];
      v += (b & 0x7f) * 2 ** shift;
      if (!(b & 0x80)) return v;
      shift += 7;
    }
  };
  while (pos < raw.length) {
    const skip = varint(), count = varint();
    if (cell + skip + count > cells.length || pos + count > raw.length) throw new Error('grid run out of range');
    cell += skip;
    cells.set(raw.subarray(pos, pos + count), cell);
    pos += count; cell += count;
  }
}

// ---- state ------------------------------------------------------------------------------------
const agents = new Map();   // id -> agent state
const pings = new Map();    // ping id -> {agent, t0}
const pending = new Map();  // command id -> {agent, topic, json, tries, kind}
const stats = { messages: 0, rejected: 0, goalsSent: 0, acks: [] };
let selected = null;
let client = null;
let nextPing = 1000000000;  // far from the terminal station's ids
let nextCommand = 1;
const sessionTag = Math.random().toString(36).slice(2, 8);
let view = null;            // world->canvas transform of the last frame (for clicks)

function agentState(id) {
  let a = agents.get(id);
  if (!a) {
    a = {
      id, color: kColors[agents.size % kColors.length], role: '?', state: '?', online: false,
      status: null, pose: null, poses: 0, poseTimes: [], traj: [], objects: new Map(),
      path: null, grid: null, gridChain: Promise.resolve(), gridImage: null, rtt: [],
      lastHeard: 0, missed: 0, lastSeq: null,
    };
    agents.set(id, a);
    if (selected === null) selected = id;
  }
  return a;
}

function log(text, cls) {
  const li = document.createElement('li');
  li.textContent = new Date().toISOString().slice(11, 19) + ' ' + text;
  if (cls) li.className = cls;
  const ol = document.getElementById('log');
  ol.prepend(li);
  while (ol.children.length > 200) ol.lastChild.remove();
}

function handle(topic, payload) {
  const parts = topic.split('/');
  if (parts.length !== 4 || parts[0] !== 'kestrel' || parts[1] !== 'v1' || parts[2] === 'team') return;
  const [, , id, stream] = parts;
  if (stream === 'cmd' || stream === 'ping') return;  // our own traffic and the terminal station's
  let m;
  try {
    m = decodePayload(payload);
    if (typeof m !== 'object' || m === null || Array.isArray(m)) throw new Error('not a map');
    if (m.v !== kSchema) throw new Error('unknown schema version ' + m.v);
    if (m.k !== stream) throw new Error(`kind '${m.k}' on stream '${stream}'`);
  } catch (e) {
    ++stats.rejected;
    console.warn(`rejected ${topic}: ${e.message}`);
    return;
  }
  ++stats.messages;
  const a = agentState(id);
  const now = performance.now();
  a.lastHeard = now;
  switch (stream) {
    case 'pose': {
      a.pose = { p: m.p, q: m.q, s: m.s, n: m.n };
      ++a.poses;
      if (a.lastSeq !== null && m.n > a.lastSeq + 1) a.missed += m.n - a.lastSeq - 1;
      a.lastSeq = m.n;
      a.poseTimes.push(now);
      const last = a.traj[a.traj.length - 1];
      if (!last || Math.hypot(last[0] - m.p[0], last[1] - m.p[1]) > 0.005) a.traj.push([m.p[0], m.p[1]]);
      if (a.traj.length > kTrajectoryMax) a.traj.splice(0, a.traj.length - kTrajectoryMax);
      break;
    }
    case 'status':
      a.status = m; a.role = m.role; a.state = m.st; a.online = m.on;
      break;
    case 'objects':
      if (m.full) a.objects.clear();
      for (const o of m.o) a.objects.set(o.id, o);
      for (const id of m.rm) a.objects.delete(id);
      break;
    case 'path':
      a.path = { goal: m.g, xy: m.xy, done: m.done, at: now };
      log(`${id}: path for ${m.g} (${m.xy.length / 2} points${m.done ? ', reached' : ''})`);
      break;
    case 'grid':
      // Deltas apply in order on top of their base version; inflation is async, so chain them.
      a.gridChain = a.gridChain.then(() => applyGrid(a, m)).catch((e) => {
        ++stats.rejected;
        console.warn(`grid from ${id}: ${e.message}`);
      });
      break;
    case 'ack': {
      stats.acks.push({ agent: id, id: m.id, r: m.r, d: m.d || '' });
      const p = pending.get(m.id);
      if (p) pending.delete(m.id);
      if (p || String(m.id).startsWith('web-')) {
        log(`${id}: ${p ? p.kind + ' ' : ''}${m.id} → ${m.r}${m.d ? ' (' + m.d + ')' : ''}`,
            m.r === 'rejected' ? 'bad' : 'good');
      }
      break;
    }
    case 'pong': {
      const p = pings.get(m.id);
      if (!p) break;  // the terminal station's ping
      pings.delete(m.id);
      const t3 = performance.now();
      const agentNs = Number(BigInt(m.t2) - BigInt(m.t1));
      a.rtt.push(Math.max(0, (t3 - p.t0ms) - agentNs * 1e-6));
      if (a.rtt.length > 20) a.rtt.shift();
      break;
    }
    default: break;  // detections: not drawn
  }
}

async function applyGrid(a, m) {
  const n = m.w * m.h;
  if (!(n > 0) || n > 16e6) throw new Error(`grid ${m.w}x${m.h}`);
  let cells;
  if (m.b === 0) {
    cells = new Uint8Array(n).fill(255);
  } else {
    // A delta on a version we do not have: wait for the next keyframe.
    if (!a.grid || a.grid.n !== m.b || a.grid.w !== m.w || a.grid.h !== m.h) return;
    cells = a.grid.cells.slice();
  }
  applyRuns(cells, await inflate(m.z instanceof Uint8Array ? m.z : new Uint8Array(m.z)));
  a.grid = { n: m.n, w: m.w, h: m.h, r: m.r, o: m.o, cells };
  // Row 0 is the lowest row in the world; the image's row 0 is its top.
  const img = new ImageData(m.w, m.h);
  for (let y = 0; y < m.h; ++y) {
    for (let x = 0; x < m.w; ++x) {
      const v = cells[y * m.w + x], k = 4 * ((m.h - 1 - y) * m.w + x);
      if (v === 255) continue;
      const g = 235 - Math.min(100, v) * 2.1;
      img.data[k] = img.data[k + 1] = img.data[k + 2] = g;
      img.data[k + 3] = 200;
    }
  }
  a.gridImage = await createImageBitmap(img);
}

// ---- commands ---------------------------------------------------------------------------------
function publishCommand(agent, body, retry) {
  const id = `web-${sessionTag}-${nextCommand++}`;
  const msg = Object.assign({ v: kSchema, k: 'cmd', id, t: Date.now() * 1e6 }, body);
  const topic = `kestrel/v1/${agent}/cmd`;
  const json = JSON.stringify(msg);
  client.publish(topic, json, { qos: 1 });
  if (retry) pending.set(id, { agent, topic, json, tries: 1, kind: body.c, last: performance.now() });
  return id;
}

function sendGoal(x, y) {
  if (!selected || !client || !client.connected) return;
  const id = publishCommand(selected, { c: 'goal', g: [x, y, 0] }, true);
  ++stats.goalsSent;
  stats.lastGoal = { agent: selected, id, x, y };
  log(`goal (${x.toFixed(2)}, ${y.toFixed(2)}) → ${selected} [${id}]`);
}

// Teleop is not re-sent: a late velocity is worse than a lost one.
const teleopKeys = { ArrowUp: [0.5, 0], ArrowDown: [-0.3, 0], ArrowLeft: [0, 0.8], ArrowRight: [0, -0.8], ' ': [0, 0] };
let lastTeleop = 0;
function teleop(key, release) {
  const a = selected && agents.get(selected);
  if (!a || !client || !client.connected) return false;
  if (a.role !== 'ugv') { log(`teleop: ${a.id} is a ${a.role}, not a UGV`, 'bad'); return true; }
  const [vel, w] = release ? [0, 0] : teleopKeys[key];
  const now = performance.now();
  if (!release && now - lastTeleop < 200) return true;  // at most 5 Hz while a key is held
  lastTeleop = now;
  const id = publishCommand(a.id, { c: 'teleop', vel, w }, false);
  log(`teleop v=${vel} w=${w} → ${a.id} [${id}]`);
  return true;
}

function tick() {
  const now = performance.now();
  for (const [id, p] of pending) {
    if (now - p.last < kRetryMs) continue;
    if (p.tries >= kRetries) { pending.delete(id); log(`${p.kind} ${id}: no acknowledgement, gave up`, 'bad'); continue; }
    client.publish(p.topic, p.json, { qos: 1 });
    ++p.tries; p.last = now;
  }
  for (const [id, p] of pings) if (now - p.t0ms > 10000) pings.delete(id);
  if (!client || !client.connected) return;
  for (const a of agents.values()) {
    if (!a.online) continue;
    const id = nextPing++;
    pings.set(id, { agent: a.id, t0ms: performance.now() });
    // t0 is echoed back unchanged; the page's own clock suffices (RTT only).
    client.publish(`kestrel/v1/${a.id}/ping`, JSON.stringify({ v: kSchema, k: 'ping', id, t0: Math.round(performance.now() * 1e6) }), { qos: 0 });
  }
}

// ---- view -------------------------------------------------------------------------------------
function linkHealth(a, now) {
  if (!a.online && a.status) return 'offline';
  const age = now - a.lastHeard;
  return age < 1500 ? 'good' : age < 5000 ? 'stale' : 'lost';
}

function poseHz(a, now) {
  while (a.poseTimes.length && now - a.poseTimes[0] > 2000) a.poseTimes.shift();
  return a.poseTimes.length / 2;
}

function median(xs) {
  if (!xs.length) return null;
  const s = [...xs].sort((p, q) => p - q);
  return s[Math.floor(s.length / 2)];
}

function renderTable(now) {
  const body = document.querySelector('#agents tbody');
  for (const a of agents.values()) {
    let tr = body.querySelector(`tr[data-agent="${CSS.escape(a.id)}"]`);
    if (!tr) {
      tr = document.createElement('tr');
      tr.dataset.agent = a.id;
      tr.innerHTML = '<td class="id"></td><td class="role"></td><td class="state"></td><td class="num hz"></td><td class="num rtt"></td><td class="link"></td><td class="num objects"></td>';
      tr.addEventListener('click', () => { selected = a.id; });
      body.appendChild(tr);
    }
    const rtt = median(a.rtt), health = linkHealth(a, now);
    tr.classList.toggle('selected', a.id === selected);
    tr.querySelector('.id').innerHTML = `<span class="swatch" style="background:${a.color}"></span>`;
    tr.querySelector('.id').append(a.id);
    tr.querySelector('.role').textContent = a.role;
    tr.querySelector('.state').textContent = a.state;
    tr.querySelector('.hz').textContent = poseHz(a, now).toFixed(1);
    tr.querySelector('.rtt').textContent = rtt === null ? '–' : rtt.toFixed(1);
    const link = tr.querySelector('.link');
    link.textContent = health + (a.missed ? ` (${a.missed} missed)` : '');
    link.className = 'link ' + health;
    tr.querySelector('.objects').textContent = a.objects.size;
  }
}

function worldBounds() {
  let x0 = Infinity, y0 = Infinity, x1 = -Infinity, y1 = -Infinity;
  const add = (x, y) => { x0 = Math.min(x0, x); y0 = Math.min(y0, y); x1 = Math.max(x1, x); y1 = Math.max(y1, y); };
  for (const a of agents.values()) {
    for (const p of a.traj) add(p[0], p[1]);
    if (a.grid) { add(a.grid.o[0], a.grid.o[1]); add(a.grid.o[0] + a.grid.w * a.grid.r, a.grid.o[1] + a.grid.h * a.grid.r); }
    if (a.path) for (let i = 0; i < a.path.xy.length; i += 2) add(a.path.xy[i], a.path.xy[i + 1]);
    for (const o of a.objects.values()) add(o.c[0], o.c[1]);
  }
  if (!isFinite(x0)) return [-5, -5, 5, 5];
  const pad = 1.0;
  return [x0 - pad, y0 - pad, x1 + pad, y1 + pad];
}

function renderMap() {
  const canvas = document.getElementById('map');
  const ctx = canvas.getContext('2d');
  const W = canvas.width, H = canvas.height;
  ctx.setTransform(1, 0, 0, 1, 0, 0);
  ctx.clearRect(0, 0, W, H);
  const [x0, y0, x1, y1] = worldBounds();
  // Fit the content, equal scale on both axes, y up; clicks use the transform of the last frame.
  const s = Math.min(W / (x1 - x0), H / (y1 - y0));
  const cx = (x0 + x1) / 2, cy = (y0 + y1) / 2;
  view = { s, cx, cy, W, H };
  const px = (x) => W / 2 + (x - cx) * s, py = (y) => H / 2 - (y - cy) * s;

  // 1 m grid lines.
  ctx.strokeStyle = '#353b44'; ctx.lineWidth = 1;
  for (let x = Math.ceil(x0); x <= x1; ++x) { ctx.beginPath(); ctx.moveTo(px(x), 0); ctx.lineTo(px(x), H); ctx.stroke(); }
  for (let y = Math.ceil(y0); y <= y1; ++y) { ctx.beginPath(); ctx.moveTo(0, py(y)); ctx.lineTo(W, py(y)); ctx.stroke(); }

  for (const a of agents.values()) {
    if (!a.gridImage) continue;
    const g = a.grid;
    ctx.imageSmoothingEnabled = false;
    ctx.drawImage(a.gridImage, px(g.o[0]), py(g.o[1] + g.h * g.r), g.w * g.r * s, g.h * g.r * s);
  }
  for (const a of agents.values()) {
    for (const o of a.objects.values()) {
      ctx.save();
      ctx.translate(px(o.c[0]), py(o.c[1]));
      ctx.rotate(-(o.y || 0));
      ctx.strokeStyle = a.color; ctx.lineWidth = 1.5;
      ctx.strokeRect(-o.s[0] * s / 2, -o.s[1] * s / 2, o.s[0] * s, o.s[1] * s);
      ctx.restore();
      ctx.fillStyle = '#eee'; ctx.font = '11px sans-serif';
      ctx.fillText(`${o.l} #${o.id}`, px(o.c[0]) + 4, py(o.c[1]) - 4);
    }
  }
  for (const a of agents.values()) {
    if (a.traj.length > 1) {
      ctx.strokeStyle = a.color; ctx.lineWidth = 2; ctx.beginPath();
      a.traj.forEach((p, i) => (i ? ctx.lineTo(px(p[0]), py(p[1])) : ctx.moveTo(px(p[0]), py(p[1]))));
      ctx.stroke();
    }
    if (a.path && a.path.xy.length >= 2) {
      const xy = a.path.xy;
      ctx.setLineDash([6, 4]); ctx.strokeStyle = '#fff'; ctx.lineWidth = 2; ctx.beginPath();
      for (let i = 0; i < xy.length; i += 2) (i ? ctx.lineTo(px(xy[i]), py(xy[i + 1])) : ctx.moveTo(px(xy[i]), py(xy[i + 1])));
      ctx.stroke(); ctx.setLineDash([]);
      const gx = px(xy[xy.length - 2]), gy = py(xy[xy.length - 1]);
      ctx.strokeStyle = a.color; ctx.beginPath(); ctx.arc(gx, gy, 7, 0, 2 * Math.PI); ctx.stroke();
    }
    if (a.pose) {
      const [qx, qy, qz, qw] = a.pose.q;
      const yaw = Math.atan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy * qy + qz * qz));
      const x = px(a.pose.p[0]), y = py(a.pose.p[1]);
      ctx.save(); ctx.translate(x, y); ctx.rotate(-yaw);
      ctx.fillStyle = a.color; ctx.strokeStyle = a.id === selected ? '#fff' : '#000'; ctx.lineWidth = 1.5;
      ctx.beginPath(); ctx.moveTo(11, 0); ctx.lineTo(-7, 6); ctx.lineTo(-7, -6); ctx.closePath(); ctx.fill(); ctx.stroke();
      ctx.restore();
      ctx.fillStyle = a.color; ctx.font = 'bold 12px sans-serif'; ctx.fillText(a.id, x + 10, y + 16);
    }
  }
  ctx.fillStyle = '#99a'; ctx.font = '11px sans-serif';
  ctx.fillText(`1 m grid · ${stats.messages} messages · ${stats.rejected} rejected`, 8, H - 8);
}

function frame() {
  const now = performance.now();
  renderTable(now);
  renderMap();
  requestAnimationFrame(frame);
}

// ---- start ------------------------------------------------------------------------------------
async function main() {
  const config = await (await fetch('config.json', { cache: 'no-store' })).json();
  const link = document.getElementById('link');
  client = mqtt.connect(config.broker_ws, {
    username: config.username, password: config.password,
    clientId: `${config.client_id}-${sessionTag}`, protocolVersion: 5,
    reconnectPeriod: 1000, connectTimeout: 5000,
  });
  client.on('connect', () => {
    link.textContent = `connected to ${config.broker_ws} as ${config.username}`;
    link.className = 'good';
    client.subscribe('kestrel/v1/+/#', { qos: 1 });
  });
  client.on('close', () => { link.textContent = 'disconnected, retrying…'; link.className = 'bad'; });
  client.on('error', (e) => { link.textContent = 'broker error: ' + e.message; link.className = 'bad'; });
  client.on('message', (topic, payload) => handle(topic, new Uint8Array(payload)));

  const canvas = document.getElementById('map');
  canvas.addEventListener('click', (ev) => {
    if (!view) return;
    const r = canvas.getBoundingClientRect();
    const cx = (ev.clientX - r.left) * canvas.width / r.width, cy = (ev.clientY - r.top) * canvas.height / r.height;
    sendGoal(view.cx + (cx - view.W / 2) / view.s, view.cy - (cy - view.H / 2) / view.s);
  });
  window.addEventListener('keydown', (ev) => { if (ev.key in teleopKeys && teleop(ev.key, false)) ev.preventDefault(); });
  window.addEventListener('keyup', (ev) => { if (ev.key in teleopKeys && ev.key !== ' ') teleop(ev.key, true); });
  setInterval(tick, kPingPeriodMs / 2);
  requestAnimationFrame(frame);
}

// What the end-to-end test reads (tests/web/station_e2e.mjs): the page's own state, as drawn.
window.kestrelStation = {
  snapshot() {
    const now = performance.now();
    return {
      connected: !!(client && client.connected), messages: stats.messages, rejected: stats.rejected,
      goalsSent: stats.goalsSent, lastGoal: stats.lastGoal || null, acks: stats.acks.slice(),
      selected,
      agents: [...agents.values()].map((a) => ({
        id: a.id, role: a.role, state: a.state, online: a.online, poses: a.poses,
        pose: a.pose && a.pose.p, trajectory: a.traj.length,
        // Points the agent has been at: free space, good goals for a test to click.
        visited: [0, 0.25, 0.5].map((f) => a.traj[Math.floor(f * (a.traj.length - 1))]).filter(Boolean), hz: poseHz(a, now), rtt: median(a.rtt),
        link: linkHealth(a, now), objects: a.objects.size, grid: a.grid ? a.grid.n : null,
        path: a.path ? { goal: a.path.goal, points: a.path.xy.length / 2 } : null,
      })),
    };
  },
  // Canvas pixel of a world point under the current view (so a test can click a known spot).
  toCanvas(x, y) { return view ? [view.W / 2 + (x - view.cx) * view.s, view.H / 2 - (y - view.cy) * view.s] : null; },
  select(id) { selected = id; },
  grid(id) {
    const g = agents.get(id)?.grid;
    return g ? { w: g.w, h: g.h, r: g.r, o: g.o, cells: Array.from(g.cells) } : null;
  },
};

main().catch((e) => {
  const link = document.getElementById('link');
  link.textContent = 'station page failed: ' + e.message;
  link.className = 'bad';
});
