// jayson_peer.js — the npm JSON-RPC peer: jayson@5's TCP server serving `test_component.add`.
//
// Newline-delimited JSON-RPC 2.0 over TCP, bound to 127.0.0.1 (--port, 0 = ephemeral),
// printing {"port": N} once listening. It is what the JSON-RPC transport is compared with,
// measured by the same client (simgate_bench_loadgen). Stops on SIGTERM/SIGINT or after
// --max-seconds.
//
// Usage: node bench/peers/jayson_peer.js [--port 0] [--max-seconds 600]
'use strict';

const path = require('path');
const jayson = require(path.join(__dirname, '..', 'node_modules', 'jayson'));

function option(name, fallback) {
  const i = process.argv.indexOf('--' + name);
  return i >= 0 && i + 1 < process.argv.length ? Number(process.argv[i + 1]) : fallback;
}

const server = new jayson.Server({
  'test_component.add': function (args, callback) {
    const [a, b] = Array.isArray(args) ? args : [args.a, args.b];
    callback(null, a + b);
  },
});

const tcp = server.tcp();
tcp.on('connection', (socket) => socket.setNoDelay(true));
tcp.listen(option('port', 0), '127.0.0.1', () => {
  process.stdout.write(JSON.stringify({ port: tcp.address().port }) + '\n');
});

function stop() {
  tcp.close();
  process.exit(0);
}
process.on('SIGTERM', stop);
process.on('SIGINT', stop);
setTimeout(stop, option('max-seconds', 600) * 1000).unref();
