#!/usr/bin/env node
// End-to-end test of the websocket transport with a WebSocket client nobody on the team
// wrote: npm's `ws` (installed with jayson into tests/jsonrpc/node_modules).
//
//   node ws_client_test.js <server program> [its arguments...]
// The server is websocket_test_host, serving the test services of
// tests/jsonrpc/test_services.h; it prints "listening on ws://127.0.0.1:<port>/" and stops
// when its stdin closes. Exit code: 0 passed, 1 failed, 77 ws not installed.
'use strict';

const path = require('path');
const { spawn } = require('child_process');

let WebSocket;
try {
  WebSocket = require(path.join(__dirname, '..', 'jsonrpc', 'node_modules', 'ws'));
} catch (e) {
  console.log('SKIP: ws is not installed (run npm install in tests/jsonrpc): ' + e.message);
  process.exit(77);
}

const STEP_TIMEOUT_MS = 10000;
const TOTAL_TIMEOUT_MS = 90000;

function withTimeout(promise, what) {
  let timer;
  const timeout = new Promise((_, reject) => {
    timer = setTimeout(() => reject(new Error(`${what}: no answer within ${STEP_TIMEOUT_MS} ms`)), STEP_TIMEOUT_MS);
  });
  return Promise.race([promise, timeout]).finally(() => clearTimeout(timer));
}

// Starts the server and resolves with its ws:// address.
function startServer(argv) {
  const child = spawn(argv[0], argv.slice(1), { stdio: ['pipe', 'pipe', 'inherit'] });
  const url = new Promise((resolve, reject) => {
    let out = '';
    child.stdout.on('data', (chunk) => {
      out += chunk.toString();
      const m = out.match(/listening on (ws:\/\/127\.0\.0\.1:\d+\/)/);
      if (m) resolve(m[1]);
    });
    child.on('exit', (code) => reject(new Error(`server exited early with code ${code}`)));
    child.on('error', reject);
  });
  return { child, url: withTimeout(url, 'server start') };
}

// A connection whose messages are matched to calls by id; notifications are kept.
class Peer {
  constructor(ws) {
    this.ws = ws;
    this.waiting = new Map();  // id -> resolve
    this.unmatched = [];       // messages nobody waits for (errors with a null id, notifications)
    this.waiters = [];         // resolves waiting for an unmatched message
    ws.on('message', (data, isBinary) => {
      if (isBinary) throw new Error('the server sent a binary message');
      const message = JSON.parse(data.toString());
      const resolve = !Array.isArray(message) && message.id !== null && this.waiting.get(message.id);
      if (resolve) {
        this.waiting.delete(message.id);
        resolve(message);
      } else if (this.waiters.length) {
        this.waiters.shift()(message);
      } else {
        this.unmatched.push(message);
      }
    });
  }
  static open(url) {
    return withTimeout(
      new Promise((resolve, reject) => {
        const ws = new WebSocket(url);
        ws.once('open', () => resolve(new Peer(ws)));
        ws.once('error', reject);
      }),
      'connect');
  }
  // Sends one request and resolves with its response.
  call(id, method, params) {
    const answer = new Promise((resolve) => this.waiting.set(id, resolve));
    this.ws.send(JSON.stringify({ jsonrpc: '2.0', id, method, params }));
    return withTimeout(answer, `${method} (id ${id})`);
  }
  // Sends raw text (or a Buffer as a binary message) and resolves with the next unmatched message.
  sendRaw(data, options) {
    const answer = this.unmatched.length ? Promise.resolve(this.unmatched.shift())
                                         : new Promise((resolve) => this.waiters.push(resolve));
    this.ws.send(data, options);
    return withTimeout(answer, 'raw message');
  }
  close() { this.ws.close(); }
}

function check(condition, what, got) {
  if (!condition) throw new Error(`${what}: got ${JSON.stringify(got)}`);
  console.log(`ok - ${what}`);
}

async function main() {
  const argv = process.argv.slice(2);
  if (!argv.length) throw new Error('usage: node ws_client_test.js <server program> [args...]');
  const server = startServer(argv);
  try {
    const url = await server.url;
    const peer = await Peer.open(url);

    let r = await peer.call(1, 'spec.subtract', [42, 23]);
    check(r.result === 19, 'sync call, positional params', r);
    r = await peer.call(2, 'spec.subtract', { subtrahend: 23, minuend: 42 });
    check(r.result === 19, 'named params', r);

    // async, out of order: the second call finishes first
    const first = peer.call(3, 'robot.arm.hold', ['w1']);
    const second = peer.call(4, 'robot.cam.hold', ['w2']);
    await peer.call(5, 'ctl.iteration', []);
    await peer.call(6, 'ctl.release', ['w2', 'two']);
    r = await second;
    check(r.result === 'two', 'async call answered first', r);
    await peer.call(7, 'ctl.release', ['w1', 'one']);
    r = await first;
    check(r.result === 'one', 'async call answered second', r);

    // cancel
    const held = peer.call(8, 'robot.arm.hold', ['w3']);
    await peer.call(9, 'ctl.iteration', []);
    r = await peer.call(10, 'rpc.cancel', { id: 8 });
    check(r.result === true, 'rpc.cancel found the call', r);
    r = await held;
    check(r.error && r.error.code === -32002, 'the cancelled call answers -32002', r);

    // batch
    r = await peer.sendRaw(JSON.stringify([
      { jsonrpc: '2.0', id: 11, method: 'spec.sum', params: [1, 2, 4] },
      { jsonrpc: '2.0', method: 'spec.notify_hello', params: [7] },
      { jsonrpc: '2.0', id: 12, method: 'nothing.here' },
    ]));
    check(Array.isArray(r) && r.length === 2 && r[0].result === 7 && r[1].error.code === -32601, 'batch', r);

    r = await peer.call(13, 'rpc.discover');
    check(r.result && r.result.methods.some((m) => m.name === 'robot.arm.hold'), 'rpc.discover', r.result && r.result.info);

    r = await peer.call(14, 'robot.arm.nothing', []);
    check(r.error && r.error.code === -32601, 'unknown method', r);
    r = await peer.sendRaw('{"jsonrpc": "2.0", "method": "foobar, "params": "bar", "baz]');
    check(r.error && r.error.code === -32700, 'malformed JSON', r);
    r = await peer.sendRaw(Buffer.from('{"jsonrpc":"2.0","id":15,"method":"spec.get_data"}'), { binary: true });
    check(r.error && r.error.code === -32600, 'binary message', r);
    r = await peer.call(16, 'spec.get_data');
    check(JSON.stringify(r.result) === '["hello",5]', 'the connection lives on', r);

    peer.close();
  } finally {
    server.child.stdin.end();
  }
}

const total = setTimeout(() => {
  console.error(`FAIL: the test took more than ${TOTAL_TIMEOUT_MS} ms`);
  process.exit(1);
}, TOTAL_TIMEOUT_MS);
main().then(
  () => {
    clearTimeout(total);
    console.log('PASS');
  },
  (e) => {
    console.error('FAIL: ' + e.message);
    process.exit(1);
  });
