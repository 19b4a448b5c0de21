// What the browser end-to-end tests share: finding Chromium, playwright-core and the CLI
// (exit 77 = CTest "skipped" when the machine has no browser), starting `kestrel` children with
// logs in a private temporary folder, a real mosquitto from scripts/mosquitto/start_broker.sh,
// polling with a time limit, counting checks, and killing everything on the way out.
import { spawn, execFileSync } from 'node:child_process';
import { createRequire } from 'node:module';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import net from 'node:net';
import { fileURLToPath } from 'node:url';

export const repo = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..', '..');
export const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

export function freePort() {
  return new Promise((resolve, reject) => {
    const s = net.createServer();
    s.listen(0, '127.0.0.1', () => { const { port } = s.address(); s.close(() => resolve(port)); });
    s.on('error', reject);
  });
}

// Sanitizer builds run several times slower: CTest passes the factor on every time limit.
export const timeScale = Math.max(1, Number(process.env.KESTREL_TEST_TIME_SCALE) || 1);

export async function waitFor(what, fn, baseTimeoutMs) {
  const timeoutMs = baseTimeoutMs * timeScale;
  const t0 = Date.now();
  let last;
  while (Date.now() - t0 < timeoutMs) {
    last = await fn();
    if (last) return last;
    await sleep(200);
  }
  throw new Error(`timed out after ${timeoutMs} ms waiting for ${what}`);
}

// build: the CMake build folder holding `kestrel`; name: a word for the temporary folder.
export function harness(build, name) {
  const chromiumPath = process.env.KESTREL_CHROMIUM || '/usr/bin/chromium';
  const kestrel = path.join(build, 'kestrel');
  const skip = (why) => { console.log(`SKIPPED: ${why}`); process.exit(77); };
  if (!fs.existsSync(chromiumPath)) skip(`no Chromium at ${chromiumPath}`);
  if (!fs.existsSync(path.join(repo, 'web/node_modules/playwright-core'))) skip('web/node_modules missing (scripts/setup)');
  if (!fs.existsSync(kestrel)) { console.error(`FAIL: ${kestrel} not built`); process.exit(1); }
  const { chromium } = createRequire(path.join(repo, 'web', 'package.json'))('playwright-core');

  const h = {
    chromium, chromiumPath, kestrel, children: [], failures: 0, brokerPid: null,
    tmp: fs.mkdtempSync(path.join(os.tmpdir(), `kestrel-${name}-e2e-`)),
  };
  // A sanitizer build's children print their reports into their logs and may be killed before
  // their exit status could say so: each log is read for one before it is deleted.
  const sanitizerReport = /WARNING: ThreadSanitizer|ERROR: AddressSanitizer|ERROR: LeakSanitizer|runtime error:/;
  h.cleanup = () => {
    if (h.cleaned) return;  // once: from the test's finally, again from process exit
    h.cleaned = true;
    for (const c of h.children) if (c.exitCode === null && c.signalCode === null) { try { c.kill('SIGKILL'); } catch {} }
    if (h.brokerPid) { try { process.kill(h.brokerPid, 'SIGKILL'); } catch {} h.brokerPid = null; }
    for (const c of h.children) {
      let log = '';
      try { log = fs.readFileSync(c.logFile, 'utf8'); } catch { continue; }
      const at = log.search(sanitizerReport);
      if (at >= 0) h.check(false, `${c.name}: sanitizer report in its log:\n${log.slice(at, at + 3000)}`);
    }
    // KESTREL_KEEP_E2E=1 keeps the children's logs and folders for a look after a failure.
    if (process.env.KESTREL_KEEP_E2E) console.log(`kept: ${h.tmp}`);
    else fs.rmSync(h.tmp, { recursive: true, force: true });
  };
  process.on('exit', h.cleanup);
  for (const sig of ['SIGINT', 'SIGTERM']) process.on(sig, () => { h.cleanup(); process.exit(1); });

  h.start = (childName, args) => {
    const logFile = path.join(h.tmp, `${childName}.log`);
    const out = fs.openSync(logFile, 'w');
    // Agents render their scene under $TMPDIR; a private one goes away with the test even when
    // the agent is killed before it can remove its folder.
    const childTmp = path.join(h.tmp, 'tmp');
    fs.mkdirSync(childTmp, { recursive: true });
    const child = spawn(kestrel, args, {
      stdio: ['ignore', out, out], env: { ...process.env, KESTREL_MQTT_PASSWORD: '', TMPDIR: childTmp },
    });
    child.logFile = logFile;
    child.name = childName;
    h.children.push(child);
    return child;
  };
  h.tail = (child, n = 15) => {
    try { return fs.readFileSync(child.logFile, 'utf8').split('\n').slice(-n).join('\n'); } catch { return ''; }
  };
  h.check = (ok, what) => {
    console.log(`${ok ? 'ok  ' : 'FAIL'} ${what}`);
    if (!ok) ++h.failures;
  };
  // users: { name: password }. Returns the broker's TCP and WebSocket ports.
  h.startBroker = (users) => {
    // The backgrounded mosquitto inherits the script's stdout: capture it in a file, not a pipe
    // (a pipe would stay open as long as the broker runs).
    const brokerLog = path.join(h.tmp, 'start_broker.out');
    const fd = fs.openSync(brokerLog, 'w');
    execFileSync(path.join(repo, 'scripts/mosquitto/start_broker.sh'),
      ['--dir', path.join(h.tmp, 'broker'), ...Object.entries(users).flatMap(([u, p]) => ['--user', `${u}:${p}`])],
      { stdio: ['ignore', fd, fd] });
    fs.closeSync(fd);
    const brokerOut = fs.readFileSync(brokerLog, 'utf8');
    const m = /port=(\d+) ws_port=(\d+) pid=(\d+)/.exec(brokerOut);
    if (!m) throw new Error(`start_broker.sh said: ${brokerOut}`);
    h.brokerPid = Number(m[3]);
    return { port: Number(m[1]), wsPort: Number(m[2]) };
  };
  // On an exception: every child's log tail, and one failure.
  h.fail = (e) => {
    console.error(`FAIL: ${e.message}`);
    for (const c of h.children) console.error(`--- ${c.name} log tail ---\n${h.tail(c)}`);
    ++h.failures;
  };
  return h;
}
