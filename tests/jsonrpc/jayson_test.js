#!/usr/bin/env node
// End-to-end test of the jsonrpc transport with a JSON-RPC client library nobody on the
// team wrote: jayson's TCP client (npm, tests/jsonrpc/package.json). jayson opens one TCP
// connection per call and ends it right after a notification.
//
//   node jayson_test.js [--suite host|gateway] <server program> [its arguments...]
// Suite `host` (default): the server is jsonrpc_test_host, serving the test services of
// tests/jsonrpc/test_services.h; it prints "listening on tcp://127.0.0.1:<port>" and stops
// when its stdin closes. Suite `gateway`: the server is `simgate run gateway_jsonrpc.json`,
// the demo scene's real components; it prints "jsonrpc: tcp://127.0.0.1:<port>" and stops
// on SIGTERM. Exit code: 0 passed, 1 failed, 77 jayson not installed.
'use strict';

const path = require('path');
const { spawn } = require('child_process');

let jayson;
try {
  jayson = require(path.join(__dirname, 'node_modules', 'jayson'));
} catch (e) {
  console.log('SKIP: jayson is not installed (run npm install in tests/jsonrpc): ' + e.message);
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

// Starts the server and resolves with its port.
function startServer(argv) {
  const child = spawn(argv[0], argv.slice(1), { stdio: ['pipe', 'pipe', 'inherit'] });
  const port = new Promise((resolve, reject) => {
    let out = '';
    child.stdout.on('data', (chunk) => {
      out += chunk.toString();
      const m = out.match(/(?:listening on |jsonrpc: )tcp:\/\/127\.0\.0\.1:(\d+)/);
      if (m) resolve(Number(m[1]));
    });
    child.on('exit', (code) => reject(new Error(`server exited early with code ${code}`)));
    child.on('error', reject);
  });
  return { child, port: withTimeout(port, 'server start') };
}

// One call as jayson reports it: {error, result} (error is the JSON-RPC error object).
function call(client, method, params, what) {
  return withTimeout(
    new Promise((resolve, reject) => {
      client.request(method, params, (err, error, result) => {
        if (err) reject(err); // transport-level failure
        else resolve({ error, result });
      });
    }),
    what || method,
  );
}

function notify(client, method, params) {
  return withTimeout(
    new Promise((resolve, reject) => {
      client.request(method, params, null, (err) => (err ? reject(err) : resolve()));
    }),
    `notification ${method}`,
  );
}

async function eventually(client, method, params, expected) {
  for (let i = 0; i < 500; i++) {
    const { result } = await call(client, method, params);
    if (JSON.stringify(result) === JSON.stringify(expected)) return;
  }
  throw new Error(`${method}(${JSON.stringify(params)}) never returned ${JSON.stringify(expected)}`);
}

let failures = 0;
let passed = 0;
function check(name, condition, detail) {
  if (condition) {
    passed++;
    console.log(`ok - ${name}`);
  } else {
    failures++;
    console.log(`not ok - ${name}: ${detail === undefined ? '' : JSON.stringify(detail)}`);
  }
}

async function run(client) {
  // sync, positional and named
  let r = await call(client, 'robot.arm.add', [2, 3]);
  check('sync positional result', r.result === 5 && !r.error, r);
  r = await call(client, 'robot.arm.greet', { name: 'jayson' });
  check('sync named params with default', r.result === 'hello, jayson', r);

  // errors, as jayson reports them
  r = await call(client, 'robot.arm.fail', ['gripper jammed']);
  check('service failure is -32000 with the message in data',
        r.error && r.error.code === -32000 && r.error.data && r.error.data.message === 'gripper jammed', r);
  r = await call(client, 'robot.nothing.go', []);
  check('unknown method is -32601', r.error && r.error.code === -32601, r);
  r = await call(client, 'spec.subtract', [1]);
  check('wrong arity is -32602', r.error && r.error.code === -32602, r);
  r = await call(client, 'spec.subtract', { minuend: 1, bogus: 2 });
  check('unknown named parameter is -32602', r.error && r.error.code === -32602 && r.error.data.parameter === 'bogus', r);

  // async: the reply arrives when the service completes, while other calls go on
  const held = call(client, 'robot.arm.hold', ['js1'], 'async hold');
  await eventually(client, 'ctl.pending', ['js1'], true);
  r = await call(client, 'robot.arm.add', [1, 1]);
  check('sync call while an async one is pending', r.result === 2, r);
  r = await call(client, 'ctl.release', ['js1', { reached: true }]);
  check('release found the async call', r.result === true, r);
  r = await held;
  check('async result arrives on completion', r.result && r.result.reached === true, r);

  // async preemption
  const first = call(client, 'robot.arm.hold', ['js2'], 'first hold');
  await eventually(client, 'ctl.pending', ['js2'], true);
  const second = call(client, 'robot.arm.hold', ['js3'], 'second hold');
  r = await first;
  check('interruptible async call is preempted (-32001)', r.error && r.error.code === -32001, r);
  await eventually(client, 'ctl.pending', ['js3'], true);
  await call(client, 'ctl.release', ['js3', 'done']);
  r = await second;
  check('the preempting call completes', r.result === 'done', r);

  // busy: non-interruptible
  const base = call(client, 'robot.base.hold', ['js4'], 'base hold');
  await eventually(client, 'ctl.pending', ['js4'], true);
  r = await call(client, 'robot.base.hold', ['js5']);
  check('non-interruptible async service answers busy (-32004)', r.error && r.error.code === -32004, r);
  await call(client, 'ctl.release', ['js4', 4]);
  r = await base;
  check('the running call completes', r.result === 4, r);

  // notification: jayson writes it and ends the connection at once
  await notify(client, 'ctl.mark', ['jayson-note']);
  await eventually(client, 'ctl.marked', ['jayson-note'], true);
  check('notification ran although the client closed right after sending it', true);

  // batch
  const batch = await withTimeout(
    new Promise((resolve, reject) => {
      client.request(
        [client.request('robot.arm.add', [1, 2], undefined, false),
         client.request('spec.subtract', [42, 23], undefined, false),
         client.request('robot.nothing.go', [], undefined, false)],
        (err, responses) => (err ? reject(err) : resolve(responses)));
    }),
    'batch');
  const results = batch.filter((x) => 'result' in x).map((x) => x.result).sort();
  const errors = batch.filter((x) => 'error' in x).map((x) => x.error.code);
  check('batch answers every call', batch.length === 3 && JSON.stringify(results) === '[19,3]' &&
        JSON.stringify(errors) === '[-32601]', batch);

  // discovery
  r = await call(client, 'rpc.discover', []);
  check('rpc.discover returns an OpenRPC document', r.result && r.result.openrpc === '1.2.6' &&
        r.result.methods.some((m) => m.name === 'robot.arm.hold' && m['x-async'] === true), r.error);
}

// The demo scene through the gateway: real components, real simulation time.
async function runGateway(client) {
  let r = await call(client, 'time.now', []);
  check('sync service of the gateway (time.now)', typeof r.result === 'number' && !r.error, r);
  r = await call(client, 'simulation.list_robots', []);
  check('simulation.list_robots lists the robot', Array.isArray(r.result) && r.result.includes('robot'), r);

  // async: time.sleep completes after simulated time passed; other calls go on meanwhile
  const before = (await call(client, 'time.now', [])).result;
  const sleeping = call(client, 'time.sleep', [0.2], 'time.sleep');
  r = await call(client, 'simulation.list_robots', []);
  check('sync call while time.sleep is pending', Array.isArray(r.result), r);
  r = await sleeping;
  const after = (await call(client, 'time.now', [])).result;
  check('async time.sleep completes without error', !r.error, r);
  check('simulated time advanced by the sleep', after - before >= 0.2 - 1e-6, { before, after });

  // errors as jayson reports them
  r = await call(client, 'robot.motion.set_speed', ['fast', 0]);
  check('wrong parameter type is -32602 naming the parameter',
        r.error && r.error.code === -32602 && r.error.data && r.error.data.parameter === 'v', r);
  r = await call(client, 'robot.nothing.go', []);
  check('unknown component is -32601', r.error && r.error.code === -32601, r);
  r = await call(client, 'robot.motion.set_speed', { v: 0.0, w: 0.0 });
  check('named params on a real component', !r.error, r);

  // discovery of the real services
  r = await call(client, 'rpc.discover', []);
  const methods = r.result ? r.result.methods : [];
  const goto = methods.find((m) => m.name === 'robot.waypoint.goto');
  check('rpc.discover describes robot.waypoint.goto as async with defaults',
        goto && goto['x-async'] === true && goto.params.some((p) => p.name === 'tolerance' && p.required === false),
        goto);
}

async function main() {
  let argv = process.argv.slice(2);
  let suite = 'host';
  if (argv[0] === '--suite') {
    suite = argv[1];
    argv = argv.slice(2);
  }
  if (argv.length === 0) {
    console.error('usage: jayson_test.js <server program> [args...]');
    process.exit(2);
  }
  const server = startServer(argv);
  const overall = setTimeout(() => {
    console.error(`FAIL: test did not finish within ${TOTAL_TIMEOUT_MS} ms`);
    server.child.kill('SIGKILL');
    process.exit(1);
  }, TOTAL_TIMEOUT_MS);
  let code = 0;
  try {
    const port = await server.port;
    const client = jayson.client.tcp({ host: '127.0.0.1', port });
    await (suite === 'gateway' ? runGateway(client) : run(client));
  } catch (e) {
    console.log(`not ok - ${e.stack || e}`);
    failures++;
  }
  // stop the server: it exits when its stdin closes
  server.child.removeAllListeners('exit');
  const exited = new Promise((resolve) => server.child.on('exit', (c, sig) => resolve(sig ? sig : c)));
  if (suite === 'gateway') server.child.kill('SIGTERM');
  else server.child.stdin.end();
  const status = await withTimeout(exited, 'server exit').catch((e) => {
    server.child.kill('SIGKILL');
    return e.message;
  });
  check('server exited cleanly', status === 0, status);
  clearTimeout(overall);
  console.log(`${passed} passed, ${failures} failed`);
  code = failures === 0 ? 0 : 1;
  process.exit(code);
}

main();
