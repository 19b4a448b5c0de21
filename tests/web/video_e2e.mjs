// End-to-end test of live video (issue 8): a real mosquitto (scripts/mosquitto/start_broker.sh,
// passwords + ACL), a real `kestrel agent --video 640x480` replaying sim:office-static, `kestrel
// station --http`, and Debian's Chromium (playwright-core) on loopback only. Checks: the page's
// <video> plays at 640x480 with decoded frames increasing over 5 s and a scene in the picture
// (screenshot in ARTIFACT_DIR/video.png); a second viewer joins and both play; telemetry keeps
// arriving throughout; malformed signaling does not disturb the stream; a page reload resumes
// the video; an agent restart is picked up by the page by itself. Prints a latency table:
// glass-to-glass (capture stamp in the picture -> Chromium's display time, clock offset from
// the page's pings) and telemetry round trips with and without video.
//
//   node tests/web/video_e2e.mjs BUILD_DIR [ARTIFACT_DIR] [--bench SECONDS] [--size WxH] [--repeats N] [--query Q]
// --bench: measuring phases of SECONDS, alternating video off / on N times (default 3) on one
// page and one agent, so both sides see the same SLAM load and slow drift of the machine's load
// biases neither; per-phase p50/p99 of the telemetry ping round trip and the
// on/off ratio of each pair, medians over the pairs. Results to
// bench/results/video_latency_WxH.json. --query adds page parameters (e.g. jitter_ms=0).
// Exit 0: pass, 1: fail, 77: cannot run here (no Chromium / web/node_modules) — CTest "skipped".
import fs from 'node:fs';
import path from 'node:path';
import { repo, harness, freePort, sleep, waitFor, timeScale } from './e2e_harness.mjs';

const args = process.argv.slice(2);
const flag = (name, dflt) => { const i = args.indexOf(name); if (i < 0) return dflt; const v = args[i + 1]; args.splice(i, 2); return v; };
const benchSeconds = Number(flag('--bench', 0));
const size = flag('--size', '640x480');
const repeats = Math.max(1, Number(flag('--repeats', 3)));
const pageQuery = flag('--query', '');  // extra page parameters, e.g. jitter_ms=0
const [width, height] = size.split('x').map(Number);
const build = path.resolve(args[0] || path.join(repo, 'build'));
const artifacts = path.resolve(args[1] || path.join(build, 'test-artifacts'));
const phaseMs = benchSeconds > 0 ? benchSeconds * 1000 : 5000;

const h = harness(build, 'video');
const { chromium, chromiumPath, children, start, tail, check } = h;
const tmp = h.tmp;

function pct(xs, q) {
  if (!xs.length) return NaN;
  const s = [...xs].sort((a, b) => a - b);
  return s[Math.min(s.length - 1, Math.round(q * (s.length - 1)))];
}

const t0 = Date.now();
const elapsed = () => `${((Date.now() - t0) / 1000).toFixed(1)} s`;
let browser = null;
const sequence = path.join(tmp, 'office-static');
const agentArgs = (duration) => ['agent', '--id', 'ugv1', '--role', 'ugv', '--broker', null, '--password', 'pw-ugv',
  '--source', `kestrel:${sequence}`, '--duration', String(duration), '--video', size,
  // Online, streaming its last frame, after the replay ends: with both cores loaded the phases
  // below can outlast the sequence (the second viewer once joined 8 s before the replay's end).
  '--linger', '600'];
try {
  const users = { station: 'st-secret', ugv1: 'pw-ugv' };
  const { port, wsPort } = h.startBroker(users);
  const broker = `mqtt://127.0.0.1:${port}`;
  const withBroker = (a) => a.map((x) => (x === null ? broker : x));

  // Rendered once (the bulk of the test's time on 2 cores), replayed by both agent runs. Long
  // enough for every phase below; the restarted agent only needs the last one.
  const seconds = Math.ceil(35 + (benchSeconds > 0 ? 2 * benchSeconds + repeats * (2 * benchSeconds + 8) : 0));
  const render = start('render', ['sim', '--scenario', 'office-static', '--out', sequence, '--duration', String(seconds)]);
  await new Promise((r) => (render.exitCode !== null ? r() : render.once('exit', r)));
  if (render.exitCode !== 0) throw new Error(`kestrel sim failed:\n${tail(render)}`);
  console.log(`[${elapsed()}] rendered ${seconds} s of office-static`);
  let agent = start('agent', withBroker(agentArgs(seconds)));
  const httpPort = await freePort();
  const station = start('station', ['station', '--broker', broker, '--password', users.station,
    '--http', String(httpPort), '--ws-port', String(wsPort), '--duration', '600']);
  await waitFor('the station page to be served', async () => {
    if (station.exitCode !== null) throw new Error(`station exited:\n${tail(station)}`);
    try { return (await fetch(`http://127.0.0.1:${httpPort}/config.json`, { signal: AbortSignal.timeout(2000) })).ok; } catch { return false; }
  }, 15000);

  browser = await chromium.launch({
    executablePath: chromiumPath,
    // Loopback only (notes/webrtc-on-loopback.md): Chromium needs both WebRTC flags or ICE never starts.
    args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
      '--disable-component-update', '--disable-sync', '--allow-loopback-in-peer-connection',
      '--disable-features=WebRtcHideLocalIpsWithMdns', '--autoplay-policy=no-user-gesture-required'],
  });
  const consoleErrors = [];
  // A sanitizer build's agent encodes about a frame a second: the page waits timeScale times
  // longer for a picture before it starts a viewer over.
  const slow = timeScale > 1 ? `video_retry_ms=${4000 * timeScale}&video_stall_ms=${3000 * timeScale}` : '';
  const withSlow = (query) => (slow ? `${query}${query ? '&' : '?'}${slow}` : query);
  const openPage = async (query) => {
    const ctx = await browser.newContext({ viewport: { width: 1400, height: 900 } });
    const page = await ctx.newPage();
    page.on('console', (msg) => { if (msg.type() === 'error') consoleErrors.push(msg.text()); });
    page.on('pageerror', (e) => consoleErrors.push(e.message));
    await page.goto(`http://127.0.0.1:${httpPort}/${withSlow(query)}`);
    return page;
  };
  // Pings every 50 ms: enough round trips for a p99 in a few seconds.
  const page = await openPage('?video=0&ping_ms=50');
  const snap = (p = page) => p.evaluate(() => window.kestrelStation.snapshot());
  const video = (p = page) => p.evaluate(() => window.kestrelStation.video('ugv1'));
  const ugv = (s) => s.agents.find((a) => a.id === 'ugv1');

  const first = await waitFor('ugv1 telemetry on the page', async () => {
    if (agent.exitCode !== null) throw new Error(`agent exited:\n${tail(agent)}`);
    const s = await snap();
    return ugv(s)?.poses > 5 && ugv(s)?.rtt !== null ? s : null;
  }, 90000);
  console.log(`[${elapsed()}] telemetry flowing (${ugv(first).poses} poses)`);

  // Phase 1: telemetry without video.
  await page.evaluate(() => window.kestrelStation.clearLatencies('ugv1'));
  await sleep(phaseMs);
  const rttOff = await page.evaluate(() => window.kestrelStation.rtts('ugv1'));

  // Phase 2: video on (a fresh load without ?video=0, so that the reload below keeps it on).
  await page.goto(`http://127.0.0.1:${httpPort}/${withSlow(`?ping_ms=50${pageQuery ? '&' + pageQuery : ''}`)}`);
  const playing = await waitFor('the video to play', async () => {
    const v = await video();
    return v && v.state === 'playing' && v.videoWidth > 0 && v.frames > 5 ? v : null;
  }, 20000);
  console.log(`[${elapsed()}] video playing: ${playing.videoWidth}x${playing.videoHeight}, offer ${JSON.stringify(playing.offer)}`);
  check(playing.videoWidth === width && playing.videoHeight === height, `<video> is ${playing.videoWidth}x${playing.videoHeight} (want ${size})`);
  await page.evaluate(() => window.kestrelStation.clearLatencies('ugv1'));
  const before = await video();
  const posesBefore = ugv(await snap()).poses;
  await sleep(phaseMs);
  const after = await video();
  const posesAfter = ugv(await snap()).poses;
  const fps = (after.decoded - before.decoded) / (phaseMs / 1000);
  // At least 3 fps (a sanitizer build encodes timeScale times slower).
  const minFps = 3 / timeScale;
  check(after.decoded > before.decoded + minFps * phaseMs / 1000, `decoded frames ${before.decoded} → ${after.decoded} over ${phaseMs / 1000} s (${fps.toFixed(1)} fps, want > ${minFps.toFixed(2)})`);
  // Poses at 2 per second at least, latency under half a second, both timeScale times looser in
  // a sanitizer build (its agent tracks and encodes about a frame a second).
  const minPoses = (2 * phaseMs / 1000) / timeScale;
  check(posesAfter > posesBefore + minPoses, `telemetry keeps arriving with video on (${posesBefore} → ${posesAfter} poses, want > ${minPoses.toFixed(1)} more)`);
  check(after.stampsOk > 0 && after.stampsBad <= after.stampsOk / 20, `capture stamps read: ${after.stampsOk} ok, ${after.stampsBad} unreadable`);
  const g2g = await page.evaluate(() => window.kestrelStation.latencies('ugv1'));
  const rttOn = await page.evaluate(() => window.kestrelStation.rtts('ugv1'));
  check(g2g.length > 10 / timeScale && pct(g2g, 0.5) > 0 && pct(g2g, 0.5) < 500 * timeScale,
    `glass-to-glass latency from ${g2g.length} frames: p50 ${pct(g2g, 0.5).toFixed(1)} ms, p95 ${pct(g2g, 0.95).toFixed(1)} ms`);
  const pixels = await page.evaluate(() => window.kestrelStation.videoPixels('ugv1'));
  check(pixels && pixels.std > 10, `the picture shows a scene (grey mean ${pixels?.mean.toFixed(0)}, std ${pixels?.std.toFixed(1)})`);
  fs.mkdirSync(artifacts, { recursive: true });
  const shot = path.join(artifacts, 'video.png');
  await page.screenshot({ path: shot });
  await page.locator('#videos video').first().screenshot({ path: path.join(artifacts, 'video-frame.png') });
  console.log(`screenshot: ${shot}`);
  const caption = await page.locator('#videos figcaption .vstats').first().textContent();
  check(/\d+×\d+ · \d+ fps · \d+ kbit\/s · latency \d+ ms/.test(caption), `panel shows resolution, fps, bitrate, latency: "${caption}"`);

  // Benchmark: alternate video off / on on this page and agent (same SLAM load, same Chromium).
  // Telemetry latency is the ping round trip (page -> broker -> agent -> broker -> page, less
  // the agent's own handling), the one telemetry latency with both ends stamped on wall clocks.
  // A pose carries its sensor stamp, not a wall-clock one, and a replaying agent that tracking
  // holds back feeds frames ever later than their stamps (seconds within a run here), so pose
  // age (receive time minus stamp) measures that drift, not the link; it is not used.
  const phases = [];
  if (benchSeconds > 0) {
    for (let r = 0; r < repeats; ++r) {
      for (const on of [false, true]) {
        await page.evaluate((x) => window.kestrelStation.setVideo(x), on);
        if (on) {
          const f0 = (await video()).frames;
          await waitFor('the video to play again', async () => {
            const v = await video();
            return v.state === 'playing' && v.frames > f0 + 10 ? v : null;
          }, 20000);
        } else {
          await waitFor('the video to stop', async () => (await video()).state === 'idle', 5000);
        }
        await sleep(1000);  // let the pipeline start / tear down settle
        await page.evaluate(() => window.kestrelStation.clearLatencies('ugv1'));
        const d0 = (await video()).decoded;
        await sleep(phaseMs);
        const d1 = (await video()).decoded;
        phases.push({
          on, rtt: await page.evaluate(() => window.kestrelStation.rtts('ugv1')),
          g2g: on ? await page.evaluate(() => window.kestrelStation.latencies('ugv1')) : [],
          fps: on ? (d1 - d0) / (phaseMs / 1000) : 0,
        });
        console.log(`[${elapsed()}] phase ${r + 1}/${repeats} video ${on ? 'on ' : 'off'}: ${phases.at(-1).rtt.length} pings`);
      }
    }
  }

  // Bad signaling from the station's side must not disturb the agent.
  await page.evaluate(() => {
    const k = window.kestrelStation;
    k.publishRaw('kestrel/v1/ugv1/webrtc/evil/to_agent', '{not json');
    k.publishRaw('kestrel/v1/ugv1/webrtc/evil/to_agent', JSON.stringify({ v: 1, k: 'answer', sdp: 'v=0' }));
    k.publishRaw('kestrel/v1/ugv1/webrtc/evil/to_agent', JSON.stringify({ v: 1, k: 'launch' }));
    k.publishRaw('kestrel/v1/ugv1/webrtc/evil/to_agent', 'x'.repeat(200000));
  });

  // A second viewer joins.
  const page2 = await openPage('');
  const v2 = await waitFor('the second viewer to play', async () => {
    const v = await video(page2);
    return v && v.state === 'playing' && v.frames > 10 ? v : null;
  }, 20000);
  // The first viewer keeps decoding: its count grows between two looks. Not against the count
  // from before the second viewer joined: with both cores loaded (the team test beside it) a
  // stalled first viewer restarts its peer, as the page does, and counts afresh (77 -> 27 seen).
  let seen = await video();
  let advancing = null;
  try {
    advancing = await waitFor('the first viewer to keep decoding', async () => {
      const v = await video();
      const ok = v && seen && v.decoded > seen.decoded ? v : null;
      seen = v || seen;
      return ok;
    }, 10000);
  } catch {
    advancing = null;
  }
  check(v2.videoWidth === width, `second viewer plays ${v2.videoWidth}x${v2.videoHeight}`);
  check(advancing !== null,
        `first viewer still decoding with two viewers (${after.decoded} before the second joined, ${seen?.decoded} after)`);
  await page2.close();

  // Reload mid-stream: the video resumes.
  await page.reload();
  const resumed = await waitFor('the video to resume after reload', async () => {
    const v = await video();
    return v && v.state === 'playing' && v.frames > 10 ? v : null;
  }, 20000);
  check(resumed.videoWidth === width, `after reload the video plays again (${resumed.frames} frames)`);

  // Agent restart: the page finds the new agent and its video by itself.
  const restartsBefore = resumed.restarts;
  const framesBefore = resumed.frames;
  agent.kill('SIGKILL');
  await new Promise((r) => (agent.exitCode !== null || agent.signalCode !== null ? r() : agent.once('exit', r)));
  console.log(`[${elapsed()}] agent killed; starting it again`);
  agent = start('agent2', withBroker(agentArgs(seconds)));
  const back = await waitFor('the video to come back after the agent restart', async () => {
    if (agent.exitCode !== null) throw new Error(`restarted agent exited:\n${tail(agent)}`);
    const v = await video();
    return v && v.state === 'playing' && v.restarts > restartsBefore && v.frames > framesBefore + 10 ? v : null;
  }, 60000);
  check(back.videoWidth === width, `video back after the agent restart (${back.restarts - restartsBefore} restart(s) of the peer)`);
  const telemetryBack = ugv(await snap()).poses;
  await sleep(1000);
  check(ugv(await snap()).poses > telemetryBack, 'telemetry from the restarted agent');

  const final = await snap();
  check(final.rejected === 0, `page decoded ${final.messages} messages, rejected ${final.rejected}`);
  check(consoleErrors.length === 0, `no page errors${consoleErrors.length ? ': ' + consoleErrors.join(' | ') : ''}`);

  // The table.
  const row = (name, xs) => `| ${name.padEnd(38)} | ${String(xs.length).padStart(5)} | ${pct(xs, 0.5).toFixed(1).padStart(6)} | ${pct(xs, 0.95).toFixed(1).padStart(6)} | ${pct(xs, 0.99).toFixed(1).padStart(6)} |`;
  console.log(`\nLatency on loopback, ${size}, ms (${phaseMs / 1000} s per phase)`);
  console.log('| measure                                |     n |    p50 |    p95 |    p99 |');
  console.log('|----------------------------------------|-------|--------|--------|--------|');
  console.log(row('glass to glass (capture -> display)', g2g));
  console.log(row('telemetry round trip, video off', rttOff));
  console.log(row('telemetry round trip, video on', rttOn));
  console.log(`video: ${fps.toFixed(1)} fps decoded, ${Math.round(after.stats.kbps)} kbit/s received, offer target ${after.offer?.kbps} kbit/s`);
  const p99Off = pct(rttOff, 0.99), p99On = pct(rttOn, 0.99);
  console.log(`telemetry p99 with video / without: ${(p99On / p99Off).toFixed(2)}`);
  let alternating = null;
  if (phases.length) {
    const median = (xs) => pct(xs, 0.5);
    const pairs = [];
    for (let i = 0; i + 1 < phases.length; i += 2) pairs.push([phases[i], phases[i + 1]]);
    const stat = (sel, q) => pairs.map(([off, on]) => ({ off: pct(sel(off), q), on: pct(sel(on), q) }));
    const line = (name, sel, q) => {
      const xs = stat(sel, q);
      const off = median(xs.map((x) => x.off)), on = median(xs.map((x) => x.on));
      const ratio = median(xs.map((x) => x.on / x.off));
      const each = xs.map((x) => (x.on / x.off).toFixed(2)).join(' ');
      console.log(`| ${name.padEnd(32)} | ${off.toFixed(1).padStart(7)} | ${on.toFixed(1).padStart(7)} | ${ratio.toFixed(2).padStart(5)} | ${each} |`);
      return { off_ms: off, on_ms: on, ratio, ratios: xs.map((x) => x.on / x.off) };
    };
    console.log(`\nTelemetry with video off / on, ${size}, ${repeats} alternating pairs of ${phaseMs / 1000} s (medians over pairs; ratio = on/off per pair)`);
    console.log('| measure                          | off ms  | on ms   | ratio | per pair |');
    console.log('|----------------------------------|---------|---------|-------|----------|');
    alternating = {
      pairs: pairs.length, seconds_per_phase: phaseMs / 1000,
      ping_rtt_p50: line('ping round trip p50', (p) => p.rtt, 0.5),
      ping_rtt_p99: line('ping round trip p99', (p) => p.rtt, 0.99),
    };
    const g = phases.filter((p) => p.on).flatMap((p) => p.g2g);
    const fpsOn = median(phases.filter((p) => p.on).map((p) => p.fps));
    console.log(`glass to glass over the on phases: n ${g.length}, p50 ${pct(g, 0.5).toFixed(1)} ms, p95 ${pct(g, 0.95).toFixed(1)} ms; decoded ${fpsOn.toFixed(1)} fps`);
    alternating.glass_to_glass_ms = { n: g.length, p50: pct(g, 0.5), p95: pct(g, 0.95), p99: pct(g, 0.99) };
    alternating.decoded_fps = fpsOn;
    alternating.video_nice = process.env.KESTREL_VIDEO_NICE ?? 'default';
  }
  if (benchSeconds > 0) {
    const out = path.join(repo, 'bench', 'results');
    fs.mkdirSync(out, { recursive: true });
    const q = (xs) => ({ n: xs.length, p50: pct(xs, 0.5), p95: pct(xs, 0.95), p99: pct(xs, 0.99) });
    fs.writeFileSync(path.join(out, `video_latency_${size}.json`), JSON.stringify({
      size, seconds: benchSeconds, glass_to_glass_ms: q(g2g), telemetry_rtt_video_off_ms: q(rttOff),
      telemetry_rtt_video_on_ms: q(rttOn), fps, kbps: after.stats.kbps, offer_kbps: after.offer?.kbps,
      alternating,
    }, null, 2));
  }
} catch (e) {
  h.fail(e);
} finally {
  if (browser) await browser.close().catch(() => {});
  h.cleanup();
}
console.log(`[${elapsed()}] ${h.failures ? `${h.failures} check(s) failed` : 'all checks passed'}`);
process.exit(h.failures ? 1 : 0);
