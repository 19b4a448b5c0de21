// Kestrel ground station page: talks MQTT over the broker's WebSocket listener (MQTT.js), decodes
// the telemetry schema v1 (comm/SCHEMA.md: agents send CBOR; commands go out as JSON, which every
// decoder accepts), draws the agents on a 2D map and sends goals, teleop and pings. Each agent's
// camera arrives as WebRTC video (H.264, peer to peer, signaling over the same broker:
// comm/webrtc_signaling.hpp), with its glass-to-glass latency read from a stamp in the picture.
'use strict';

const kSchema = 1;
const kColors = ['#4fc3f7', '#ffb74d', '#aed581', '#f06292', '#ba68c8', '#fff176'];
const kTrajectoryMax = 20000;  // points kept per agent
const kPingPeriodMs = 1000;
const kRetryMs = 1000;         // a goal is re-sent (same id) until acknowledged
const kRetries = 10;
const params = new URLSearchParams(location.search);
// ?video=0 starts without video (kestrelStation.setVideo turns it on); ?overlay=1 asks agents to
// draw boxes and features; ?ping_ms=N pings faster (latency benchmarks).
let videoEnabled = params.get('video') !== '0';
let videoOverlay = params.get('overlay') === '1';
const pingPeriodMs = Math.max(20, Number(params.get('ping_ms')) || kPingPeriodMs);
// ?jitter_ms=N asks Chromium's video jitter buffer to hold about N ms (RTCRtpReceiver
// jitterBufferTarget; unset: Chromium's own estimate), for glass-to-glass experiments.
const jitterTargetMs = params.has('jitter_ms') ? Math.max(0, Number(params.get('jitter_ms')) || 0) : null;
// ?video_retry_ms=N and ?video_stall_ms=N lengthen the two waits below for a slow agent or link
// (a sanitizer build's agent encodes about one frame a second; restarting its peer sooner only
// gives it another one to set up).
const msParam = (name, dflt) => Math.max(dflt, Number(params.get(name)) || dflt);
const kVideoRetryMs = msParam('video_retry_ms', 4000);  // no picture this long after a hello: start over
const kVideoStallMs = msParam('video_stall_ms', 3000);  // no new frame this long while playing: start over
const kVideoAliveMs = 2000;   // the agent drops viewers it has not heard from in 8 s
const kLatencyKept = 3000;

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
// mapd's merged map (kestrel/v1/team/objects): always a full snapshot, in the team frame.
const team = { objects: new Map(), updates: 0 };
const pings = new Map();    // ping id -> {agent, t0}
const pending = new Map();  // command id -> {agent, topic, json, tries, kind}
const stats = { messages: 0, rejected: 0, staleObjects: 0, stalePaths: 0, goalsSent: 0, acks: [] };
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
      lastHeard: 0, missed: 0, lastSeq: null, offsets: [], rttLog: [], video: null, restartVideo: false,
    };
    agents.set(id, a);
    if (selected === null) selected = id;
  }
  return a;
}

// A QoS 1 objects message can arrive twice and late (re-sent after a broker crash, behind what
// followed it): applied after a newer snapshot it would bring back what that snapshot removed.
// `n` numbers a sender's objects messages (comm/SCHEMA.md); one without `n` is always applied.
function objectsMessageIsNew(holder, m) {
  if (typeof m.n !== 'number' || m.n <= 0) return true;
  if (m.n <= (holder.objectsSeq || 0)) {
    ++stats.staleObjects;
    return false;
  }
  holder.objectsSeq = m.n;
  return true;
}

// The team layer is no agent: it has no pose, status or commands, only mapd's objects.
function handleTeam(stream, payload) {
  if (stream !== 'objects' || payload.length === 0) return;
  let m;
  try {
    m = decodePayload(payload);
    if (typeof m !== 'object' || m === null || m.v !== kSchema || m.k !== 'objects' || !Array.isArray(m.o)) {
      throw new Error('not a team objects message');
    }
  } catch (e) {
    ++stats.rejected;
    console.warn(`rejected team objects: ${e.message}`);
    return;
  }
  ++stats.messages;
  if (!objectsMessageIsNew(team, m)) return;
  if (m.full) team.objects.clear();
  for (const o of m.o) team.objects.set(o.id, o);
  for (const id of m.rm || []) team.objects.delete(id);
  ++team.updates;
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
  if (parts.length === 6 && parts[0] === 'kestrel' && parts[1] === 'v1' && parts[3] === 'webrtc') {
    if (parts[5] === 'to_viewer') videoSignal(parts[2], parts[4], payload);
    return;  // to_agent: ours and other stations'
  }
  if (parts.length !== 4 || parts[0] !== 'kestrel' || parts[1] !== 'v1') return;
  const [, , id, stream] = parts;
  if (id === 'team') { handleTeam(stream, payload); return; }
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
      // An agent that went offline lost its peers: the next one it starts needs a new hello.
      if (!m.on && a.online) a.restartVideo = true;
      a.status = m; a.role = m.role; a.state = m.st; a.online = m.on;
      break;
    case 'objects':
      if (!objectsMessageIsNew(a, m)) break;
      if (m.full) a.objects.clear();
      for (const o of m.o) a.objects.set(o.id, o);
      for (const id of m.rm) a.objects.delete(id);
      break;
    case 'path': {
      // Stamped by the agent's clock when planned: one re-sent late (after a broker crash) must
      // not replace the path of a newer goal.
      const t = BigInt(m.t);
      if (a.pathT !== undefined && t < a.pathT) {
        ++stats.stalePaths;
        break;
      }
      a.pathT = t;
      a.path = { goal: m.g, xy: m.xy, done: m.done, at: now };
      log(`${id}: path for ${m.g} (${m.xy.length / 2} points${m.done ? ', reached' : ''})`);
      break;
    }
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
      a.rttLog.push(a.rtt[a.rtt.length - 1]);  // for latency benchmarks (kestrelStation.rtts)
      if (a.rttLog.length > kLatencyKept) a.rttLog.shift();
      // Agent clock minus ours, ((t1 - t0) + (t2 - t3)) / 2, on wall clocks (comm/SCHEMA.md).
      const wall3 = performance.timeOrigin + t3;
      const t1 = Number(BigInt(m.t1)) / 1e6, t2 = Number(BigInt(m.t2)) / 1e6;
      a.offsets.push(((t1 - p.wall0) + (t2 - wall3)) / 2);
      if (a.offsets.length > 20) a.offsets.shift();
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
    const t0ms = performance.now(), wall0 = performance.timeOrigin + t0ms;
    pings.set(id, { agent: a.id, t0ms, wall0 });
    client.publish(`kestrel/v1/${a.id}/ping`, JSON.stringify({ v: kSchema, k: 'ping', id, t0: Math.round(wall0 * 1e6) }), { qos: 0 });
  }
}

// ---- video over WebRTC ------------------------------------------------------------------------
// The agent offers (send-only H.264); the page answers. Chromium needs no candidates of its own
// on loopback: it sends checks to the agent's 127.0.0.1 candidate. A hello that brings no
// picture, a picture that stops, or an agent that restarts: the page starts over by itself.
let nextViewer = 1;
const kStampBits = 64, kStampCols = 16, kStampCell = 8;

function videoPanel(a) {
  let fig = document.querySelector(`#videos figure[data-agent="${CSS.escape(a.id)}"]`);
  if (fig) return fig;
  fig = document.createElement('figure');
  fig.className = 'video';
  fig.dataset.agent = a.id;
  fig.innerHTML = '<video autoplay muted playsinline></video><figcaption><span class="vid"></span> <span class="vstats">waiting…</span></figcaption>';
  fig.querySelector('.vid').textContent = a.id;
  document.getElementById('videos').appendChild(fig);
  return fig;
}

function publishSignal(a, body) {
  if (!client || !client.connected || !a.video) return;
  client.publish(`kestrel/v1/${a.id}/webrtc/${a.video.viewer}/to_agent`,
    JSON.stringify(Object.assign({ v: 1 }, body)), { qos: 1 });
}

function stopVideo(a, why) {
  const v = a.video;
  if (!v) return;
  if (v.pc) { publishSignal(a, { k: 'bye' }); v.pc.close(); }
  v.pc = null; v.state = 'idle'; v.why = why;
}

function startVideo(a) {
  const fig = videoPanel(a);
  const el = fig.querySelector('video');
  if (!a.video) {
    a.video = { el, state: 'idle', restarts: 0, frames: 0, stampsOk: 0, stampsBad: 0, latencies: [],
      canvas: null, ctx: null, stats: { fps: 0, kbps: 0, w: 0, h: 0, decoded: 0 }, prevBytes: null };
    el.requestVideoFrameCallback((now, meta) => onVideoFrame(a, now, meta));
  } else {
    stopVideo(a, 'restart');
    ++a.video.restarts;
  }
  const v = a.video;
  v.viewer = `${sessionTag}v${nextViewer++}`;
  v.state = 'asked'; v.since = performance.now(); v.lastAlive = v.since; v.lastFrameAt = null; v.offer = null;
  const pc = new RTCPeerConnection({ iceServers: [] });
  v.pc = pc;
  pc.ontrack = (ev) => {
    if (jitterTargetMs !== null && 'jitterBufferTarget' in ev.receiver) ev.receiver.jitterBufferTarget = jitterTargetMs;
    el.srcObject = ev.streams[0] || new MediaStream([ev.track]);
  };
  pc.onicecandidate = (ev) => {
    if (ev.candidate && ev.candidate.candidate) publishSignal(a, { k: 'candidate', m: ev.candidate.sdpMLineIndex || 0, c: ev.candidate.candidate });
  };
  pc.onconnectionstatechange = () => { if (pc === v.pc && pc.connectionState === 'failed') a.restartVideo = true; };
  publishSignal(a, { k: 'hello', overlay: videoOverlay });
}

async function videoSignal(agentId, viewer, payload) {
  const a = agents.get(agentId);
  if (!a || !a.video || a.video.viewer !== viewer) return;  // another viewer's, or stale
  const v = a.video, pc = v.pc;
  let m;
  try {
    m = JSON.parse(new TextDecoder().decode(payload));
    if (typeof m !== 'object' || m === null || m.v !== 1) throw new Error('not a v1 signaling map');
  } catch (e) {
    ++stats.rejected;
    console.warn(`rejected video signal from ${agentId}: ${e.message}`);
    return;
  }
  try {
    if (m.k === 'offer' && pc && typeof m.sdp === 'string') {
      v.offer = { w: m.w, h: m.h, fps: m.fps, kbps: m.kbps, overlay: m.overlay };
      await pc.setRemoteDescription({ type: 'offer', sdp: m.sdp });
      const answer = await pc.createAnswer();
      await pc.setLocalDescription(answer);
      if (pc !== v.pc) return;
      publishSignal(a, { k: 'answer', sdp: pc.localDescription.sdp });
      v.state = 'answered';
    } else if (m.k === 'candidate' && pc) {
      await pc.addIceCandidate({ candidate: m.c, sdpMLineIndex: m.m });
    } else if (m.k === 'error') {
      log(`${agentId} video: ${m.d}`, 'bad');
      a.restartVideo = true;
    }
  } catch (e) {
    console.warn(`video ${agentId}: ${e.message}`);
    a.restartVideo = true;
  }
}

// The capture stamp (comm/webrtc_stamp.hpp): 64 cells of 8x8 in the top-left corner, µs mod 2^40,
// frame number, CRC-8.
function crc8(bytes) {
  let crc = 0;
  for (const b of bytes) {
    crc ^= b;
    for (let i = 0; i < 8; ++i) crc = crc & 0x80 ? ((crc << 1) ^ 0x07) & 0xff : (crc << 1) & 0xff;
  }
  return crc;
}

function readStamp(v) {
  if (!v.canvas) {
    v.canvas = document.createElement('canvas');
    v.canvas.width = kStampCols * kStampCell; v.canvas.height = (kStampBits / kStampCols) * kStampCell;
    v.ctx = v.canvas.getContext('2d', { willReadFrequently: true });
  }
  const { width: W, height: H } = v.canvas;
  v.ctx.drawImage(v.el, 0, 0, W, H, 0, 0, W, H);
  const px = v.ctx.getImageData(0, 0, W, H).data;
  const bytes = new Uint8Array(8);
  for (let bit = 0; bit < kStampBits; ++bit) {
    const cx = (bit % kStampCols) * kStampCell + 2, cy = Math.floor(bit / kStampCols) * kStampCell + 2;
    let sum = 0;
    for (let dy = 0; dy < 4; ++dy) for (let dx = 0; dx < 4; ++dx) sum += px[4 * ((cy + dy) * W + cx + dx) + 1];
    if (sum / 16 > 128) bytes[bit >> 3] |= 0x80 >> (bit & 7);
  }
  if (crc8(bytes.subarray(0, 7)) !== bytes[7]) return null;
  let us = 0;
  for (let i = 0; i < 5; ++i) us = us * 256 + bytes[i];
  return { us, frame: bytes[5] * 256 + bytes[6] };
}

function onVideoFrame(a, now, meta) {
  const v = a.video;
  v.el.requestVideoFrameCallback((n, m) => onVideoFrame(a, n, m));
  ++v.frames;
  v.lastFrameAt = performance.now();
  if (v.state === 'answered') { v.state = 'playing'; log(`${a.id}: video playing (${v.el.videoWidth}x${v.el.videoHeight})`, 'good'); }
  const stamp = readStamp(v);
  if (!stamp) { ++v.stampsBad; return; }
  ++v.stampsOk;
  const offset = median(a.offsets);
  if (offset === null) return;
  // Shown at expectedDisplayTime (our clock); the agent's clock then read offset ms more. The
  // stamp holds the agent's capture time in µs modulo 2^40: take the candidate nearest to it.
  const shownAgentUs = (performance.timeOrigin + meta.expectedDisplayTime + offset) * 1000;
  const wrap = 2 ** 40;
  let back = (shownAgentUs - stamp.us) % wrap;
  if (back < 0) back += wrap;
  if (back > wrap / 2) back -= wrap;
  v.latencies.push(back / 1000);
  if (v.latencies.length > kLatencyKept) v.latencies.shift();
}

async function videoStats(a) {
  const v = a.video;
  if (!v || !v.pc) return;
  const report = await v.pc.getStats();
  const t = performance.now();
  report.forEach((r) => {
    if (r.type !== 'inbound-rtp' || r.kind !== 'video') return;
    if (v.prevBytes !== null && t > v.prevAt) v.stats.kbps = ((r.bytesReceived - v.prevBytes) * 8) / (t - v.prevAt);
    v.prevBytes = r.bytesReceived; v.prevAt = t;
    v.stats.fps = r.framesPerSecond || 0;
    v.stats.w = r.frameWidth || 0; v.stats.h = r.frameHeight || 0;
    v.stats.decoded = r.framesDecoded || 0;
    v.stats.keyframes = r.keyFramesDecoded || 0;
    v.stats.pli = r.pliCount || 0;
  });
}

function videoTick(a) {
  const now = performance.now();
  if (!videoEnabled || !a.online) {
    if (a.video && a.video.pc) stopVideo(a, videoEnabled ? 'agent offline' : 'video off');
    if (!a.online) a.restartVideo = false;
    return;
  }
  const v = a.video;
  if (!v || v.state === 'idle' || a.restartVideo) {
    a.restartVideo = false;
    startVideo(a);
    return;
  }
  const stalled = v.lastFrameAt === null ? now - v.since > kVideoRetryMs : now - v.lastFrameAt > kVideoStallMs;
  if (stalled) { startVideo(a); return; }
  if (now - v.lastAlive > kVideoAliveMs) { v.lastAlive = now; publishSignal(a, { k: 'alive' }); }
  videoStats(a).catch(() => {});
}

function percentile(xs, q) {
  if (!xs.length) return null;
  const s = [...xs].sort((p, r) => p - r);
  return s[Math.min(s.length - 1, Math.round(q * (s.length - 1)))];
}

function renderVideos() {
  for (const a of agents.values()) {
    const v = a.video;
    if (!v) continue;
    const fig = videoPanel(a);
    const recent = v.latencies.slice(-90);
    const p50 = percentile(recent, 0.5), p95 = percentile(recent, 0.95);
    const st = v.state === 'playing'
      ? `${v.stats.w}×${v.stats.h} · ${v.stats.fps.toFixed(0)} fps · ${Math.round(v.stats.kbps)} kbit/s · latency ${p50 === null ? '–' : p50.toFixed(0)} ms (p95 ${p95 === null ? '–' : p95.toFixed(0)})`
      : v.state === 'idle' ? (v.why || 'off') : 'connecting…';
    const span = fig.querySelector('.vstats');
    if (span.textContent !== st) span.textContent = st;
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
  for (const o of team.objects.values()) add(o.c[0], o.c[1]);
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
  // Team layer: dashed gold boxes, labelled with the agents that saw each object.
  for (const o of team.objects.values()) {
    ctx.save();
    ctx.translate(px(o.c[0]), py(o.c[1]));
    ctx.rotate(-(o.y || 0));
    ctx.setLineDash([4, 3]); ctx.strokeStyle = '#ffd54f'; ctx.lineWidth = 2;
    ctx.strokeRect(-o.s[0] * s / 2, -o.s[1] * s / 2, o.s[0] * s, o.s[1] * s);
    ctx.restore();
    ctx.fillStyle = '#ffd54f'; ctx.font = '11px sans-serif';
    ctx.fillText(`${o.l} (${(o.a || []).join(',')})`, px(o.c[0]) + 4, py(o.c[1]) + 12);
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
  renderVideos();
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
  setInterval(tick, pingPeriodMs / 2);
  setInterval(() => { for (const a of agents.values()) videoTick(a); }, 500);
  window.addEventListener('pagehide', () => { for (const a of agents.values()) stopVideo(a, 'page closed'); });
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
      team: { updates: team.updates, objects: [...team.objects.values()].map((o) => ({ id: o.id, label: o.l, agents: o.a || [] })) },
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
  video(id) {
    const a = agents.get(id), v = a && a.video;
    if (!v) return null;
    const q = v.el.getVideoPlaybackQuality ? v.el.getVideoPlaybackQuality() : null;
    return {
      state: v.state, viewer: v.viewer, restarts: v.restarts, videoWidth: v.el.videoWidth, videoHeight: v.el.videoHeight,
      frames: v.frames, decoded: q ? q.totalVideoFrames : 0, stampsOk: v.stampsOk, stampsBad: v.stampsBad,
      latency: { n: v.latencies.length, p50: percentile(v.latencies, 0.5), p95: percentile(v.latencies, 0.95) },
      offer: v.offer, stats: Object.assign({}, v.stats), offsetMs: median(a.offsets),
    };
  },
  latencies(id) { const v = agents.get(id)?.video; return v ? v.latencies.slice() : []; },
  clearLatencies(id) { const v = agents.get(id)?.video; if (v) v.latencies.length = 0; const a = agents.get(id); if (a) a.rttLog.length = 0; },
  rtts(id) { return agents.get(id)?.rttLog.slice() || []; },
  setVideo(on) { videoEnabled = !!on; },
  // Publishes raw text as the station (tests inject malformed signaling with it).
  publishRaw(topic, text) { client.publish(topic, text, { qos: 1 }); },
  // Pixel statistics of the current video frame (is there a scene, or a blank?).
  videoPixels(id) {
    const v = agents.get(id)?.video;
    if (!v || !v.el.videoWidth) return null;
    const c = document.createElement('canvas');
    c.width = v.el.videoWidth; c.height = v.el.videoHeight;
    const ctx = c.getContext('2d');
    ctx.drawImage(v.el, 0, 0);
    const d = ctx.getImageData(0, 32, c.width, c.height - 32).data;
    let sum = 0, sq = 0;
    const n = d.length / 4;
    for (let i = 0; i < d.length; i += 4) { const g = (d[i] + d[i + 1] + d[i + 2]) / 3; sum += g; sq += g * g; }
    const mean = sum / n;
    return { mean, std: Math.sqrt(Math.max(0, sq / n - mean * mean)) };
  },
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
