// What the foxglove transport's end-to-end tests share (foxglove_client_test.js,
// foxglove_sensors_test.js, foxglove_replay_test.js): npm's packages (or exit 77 without
// them), the gateway started as a child, a Session: @foxglove/ws-protocol's FoxgloveClient
// recording what the server tells it, and a PlaybackConnection (playback control).
'use strict';

const path = require('path');
const { spawn } = require('child_process');

let FoxgloveClient, WebSocket, Ajv, foxgloveSchemas;
try {
  ({ FoxgloveClient } = require(path.join(__dirname, 'node_modules', '@foxglove', 'ws-protocol')));
  foxgloveSchemas = require(path.join(__dirname, 'node_modules', '@foxglove', 'schemas', 'jsonschema'));
  WebSocket = require(path.join(__dirname, 'node_modules', 'ws'));
  Ajv = require(path.join(__dirname, 'node_modules', 'ajv'));
} catch (e) {
  console.log('SKIP: the npm packages are not installed (npm install in tests/foxglove): ' + e.message);
  process.exit(77);
}

const STEP_TIMEOUT_MS = 10000;

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

function withTimeout(promise, what, ms = STEP_TIMEOUT_MS) {
  let timer;
  const timeout = new Promise((_, reject) => {
    timer = setTimeout(() => reject(new Error(`${what}: nothing within ${ms} ms`)), ms);
  });
  return Promise.race([promise, timeout]).finally(() => clearTimeout(timer));
}

function check(condition, what) {
  if (!condition) throw new Error('check failed: ' + what);
}

// The gateway's environment. Under AddressSanitizer freed memory waits in a quarantine of up to
// 256 MB before reuse, so the gateway's resident memory grows with every image it frees and a
// test of bounded memory would measure the quarantine: 16 MB keeps it from dominating (and still
// catches a use after free of anything freed recently).
function gatewayEnvironment() {
  const asan = process.env.ASAN_OPTIONS;
  return { ...process.env, ASAN_OPTIONS: (asan ? asan + ':' : '') + 'quarantine_size_mb=16' };
}

function startGateway(argv) {
  const child = spawn(argv[0], argv.slice(1), { stdio: ['ignore', 'pipe', 'inherit'], env: gatewayEnvironment() });
  const url = new Promise((resolve, reject) => {
    let out = '';
    child.stdout.on('data', (chunk) => {
      out += chunk.toString();
      const m = out.match(/foxglove: (ws:\/\/127\.0\.0\.1:\d+\/)/);
      if (m) resolve(m[1]);
    });
    child.on('exit', (code) => reject(new Error(`simgate exited early with code ${code}`)));
    child.on('error', reject);
  });
  return { child, url: withTimeout(url, 'simgate start', 60000) };
}

// A connected FoxgloveClient that records what the server tells it.
class Session {
  constructor(url, subprotocol) {
    this.ws = new WebSocket(url, [subprotocol]);
    this.client = new FoxgloveClient({ ws: this.ws });
    this.channels = new Map(); // id -> channel
    this.services = new Map(); // id -> service
    this.statuses = [];
    this.times = [];
    this.messages = new Map(); // subscription id -> [{timestamp, data}]
    this.responses = new Map(); // call id -> {ok, data|message}
    this.waiters = [];
    const c = this.client;
    c.on('serverInfo', (info) => { this.info = info; this.poke(); });
    c.on('advertise', (list) => { for (const ch of list) this.channels.set(ch.id, ch); this.poke(); });
    c.on('unadvertise', (ids) => { for (const id of ids) this.channels.delete(id); this.poke(); });
    c.on('advertiseServices', (list) => { for (const s of list) this.services.set(s.id, s); this.poke(); });
    c.on('unadvertiseServices', (ids) => { for (const id of ids) this.services.delete(id); this.poke(); });
    c.on('status', (s) => { this.statuses.push(s); this.poke(); });
    this.parameterValues = [];
    c.on('parameterValues', (m) => { this.parameterValues.push(m); this.poke(); });
    c.on('time', (t) => { this.times.push(t.timestamp); this.poke(); });
    c.on('message', (m) => {
      if (!this.messages.has(m.subscriptionId)) this.messages.set(m.subscriptionId, []);
      this.messages.get(m.subscriptionId).push({ timestamp: m.timestamp, data: Buffer.from(m.data.buffer, m.data.byteOffset, m.data.byteLength).toString() });
      this.poke();
    });
    c.on('serviceCallResponse', (r) => {
      this.responses.set(r.callId, { ok: true, encoding: r.encoding, data: Buffer.from(r.data.buffer, r.data.byteOffset, r.data.byteLength).toString() });
      this.poke();
    });
    c.on('serviceCallFailure', (f) => { this.responses.set(f.callId, { ok: false, message: f.message }); this.poke(); });
    c.on('error', (e) => { this.error = e; this.poke(); });
    c.on('close', () => { this.closed = true; this.poke(); });
    this.nextCall = 1;
  }
  poke() {
    const waiting = this.waiters;
    this.waiters = [];
    for (const w of waiting) if (!w()) this.waiters.push(w);
  }
  until(predicate, what, ms) {
    return withTimeout(new Promise((resolve) => {
      const w = () => { if (predicate()) { resolve(); return true; } return false; };
      if (!w()) this.waiters.push(w);
    }), what, ms);
  }
  channel(topic) { return [...this.channels.values()].find((c) => c.topic === topic); }
  service(name) { return [...this.services.values()].find((s) => s.name === name); }
  async call(name, request, encoding = 'json') {
    const service = this.service(name);
    check(service, `service ${name} is advertised (have: ${[...this.services.values()].map((s) => s.name).join(', ')})`);
    return this.callId(service.id, request, encoding, name);
  }
  async callId(serviceId, request, encoding = 'json', what = `service ${serviceId}`) {
    const callId = this.nextCall++;
    const data = typeof request === 'string' ? request : JSON.stringify(request);
    this.client.sendServiceCallRequest({ serviceId, callId, encoding, data: new TextEncoder().encode(data) });
    await this.until(() => this.responses.has(callId), `the answer of ${what}`);
    return this.responses.get(callId);
  }
  async statusAfter(send, what) {
    const before = this.statuses.length;
    send();
    await this.until(() => this.statuses.length > before, `a status message for ${what}`);
    return this.statuses[before];
  }
  close() { this.client.close(); }
}

// A raw connection speaking playback control with the Foxglove SDK's binary layout
// (@foxglove/ws-protocol 0.8 has no playback messages): serverInfo, status messages and the
// Playback States it is sent.
class PlaybackConnection {
  constructor(url) {
    this.ws = new WebSocket(url, ['foxglove.websocket.v1']);
    this.states = [];
    this.statuses = [];
    this.poke = () => {};
    this.ws.on('message', (data, binary) => {
      if (binary) {
        if (data[0] === 0x05) {
          const length = data.readUInt32LE(15);
          this.states.push({ status: data[1], ns: data.readBigUInt64LE(2), speed: data.readFloatLE(10),
                             didSeek: data[14] === 1, requestId: data.subarray(19, 19 + length).toString() });
        }
      } else {
        const m = JSON.parse(data.toString());
        if (m.op === 'serverInfo') this.info = m;
        if (m.op === 'status') this.statuses.push(m);
      }
      this.poke();
    });
  }
  until(predicate, what, ms = STEP_TIMEOUT_MS) {
    return withTimeout(new Promise((resolve) => {
      this.poke = () => { if (predicate()) resolve(); };
      this.poke();
    }), what, ms);
  }
  // A Playback Control Request: play or pause, at `speed`, seeking to `seekNs` (a BigInt) if given.
  request(play, speed, seekNs, id) {
    const head = Buffer.alloc(19);
    head[0] = 0x03;
    head[1] = play ? 0 : 1;
    head.writeFloatLE(speed, 2);
    head[6] = seekNs === undefined ? 0 : 1;
    head.writeBigUInt64LE(seekNs === undefined ? 0n : seekNs, 7);
    head.writeUInt32LE(Buffer.byteLength(id), 15);
    this.ws.send(Buffer.concat([head, Buffer.from(id)]));
  }
  // The Playback State answering request `id`.
  async answer(id, ms) {
    await this.until(() => this.states.some((x) => x.requestId === id), `the playback state answering ${id}`, ms);
    return this.states.find((x) => x.requestId === id);
  }
  close() { this.ws.close(); }
}

// The test's frame: starts the gateway (`argv`), runs `body(url, child)` within `ms`, says
// PASS with `passed` or FAIL with the reason (exit code 1), and stops the gateway either way.
function runTest(argv, ms, passed, body) {
  const { child, url } = startGateway(argv);
  const overall = setTimeout(() => {
    console.error('FAIL: the test took longer than ' + ms + ' ms');
    child.kill('SIGKILL');
    process.exit(1);
  }, ms);
  (async () => {
    try {
      await body(await url, child);
      console.log('PASS: ' + passed);
    } finally {
      clearTimeout(overall);
      child.kill('SIGTERM');
    }
  })().catch((e) => {
    console.error('FAIL: ' + (e && e.stack ? e.stack : e));
    process.exit(1);
  });
}

module.exports = { FoxgloveClient, WebSocket, Ajv, foxgloveSchemas, withTimeout, check, startGateway, Session, PlaybackConnection, sleep, runTest };
