// simgate's web app (docs/web.md): one WebSocket to the server that served this page,
// JSON-RPC 2.0 over it (docs/transports/jsonrpc.md). This module starts the page and wires
// its parts, one ES module each (index.html loads this one; the browser fetches the others):
//   - rpc.js, Rpc: calls matched to their replies by id, progress reports, notifications;
//   - login.js: when the transport wants a token (its `auth` option), the page asks for it
//     and calls rpc.login before anything else;
//   - state.js, the state header: simulation get_simulation_state (else time statistics) at
//     2 Hz, pause / play / step;
//   - console.js, the service console: a form per method of rpc.discover, a log of the calls
//     with their progress, status and reply, and a Cancel button (rpc.cancel) while one runs;
//   - scene.js, the scene: simulation get_scene_geometry drawn with three.js, bodies moved by
//     the `simulation` stream (rpc.subscribe), or by polling when the server has no such
//     stream; without get_scene_geometry, each root body of simulation get_scene_objects as a
//     marker; a new model generation (a spawn, a delete) reloads it, and the console's
//     services, the cameras and the input streams with it (a robot spawned with components,
//     or deleted); and the bodies table;
//   - cameras.js: every component with a get_image service, its image on asking, and live
//     from its data stream (rpc.subscribe) when this transport carries one;
//   - inputs.js, the input streams (rpc.streams, direction IN): a command box for each
//     (rpc.publish), and a drive pad for a velocity stream {v, w} (arrow keys or buttons,
//     held to drive);
//   - util.js: the helpers they share, and window.simgate.
// What the browser test reads is on window.simgate (tests/web/webapp_test.js).
import { setupCameras } from './cameras.js';
import { setupConsole } from './console.js';
import { setupInputs } from './inputs.js';
import { login } from './login.js';
import { Rpc } from './rpc.js';
import { setupScene } from './scene.js';
import { setupState } from './state.js';
import { $, exposed } from './util.js';

const RECONNECT_MS = 2000;          // after the connection is lost

const rpc = new Rpc(`${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/`);
const refreshState = setupState(rpc);
const loadServices = setupConsole(rpc);
// a model changed by a spawn or a delete may bring or take a robot: its services, cameras
// and streams
const startScene = setupScene(rpc, () => {
  const methods = loadServices();
  const streams = rpc.call('rpc.streams').catch(() => []);
  startCameras(methods, streams, true);
  startInputs(streams);
});
const startCameras = setupCameras(rpc);
const startInputs = setupInputs(rpc);

rpc.onopen = async () => {
  exposed.connected = true;
  $('connection').textContent = `connected to ${location.host}`;
  $('connection').dataset.state = 'connected';
  if (!(await login(rpc))) return;  // a wrong token: the server closes, the next connection asks again
  if (!exposed.connected) return;   // lost while asking
  if (exposed.login === 'done') $('connection').textContent = `connected to ${location.host} (logged in)`;
  exposed.ready = true;
  refreshState();
  const methods = loadServices();
  startScene();
  // one rpc.streams for the cameras and the commands (a transport without streams: none)
  const streams = rpc.call('rpc.streams').catch(() => []);
  startCameras(methods, streams);
  startInputs(streams);
};
rpc.onclose = () => {
  const was = exposed.connected;
  exposed.connected = false;
  exposed.ready = false;
  $('login').hidden = true;
  $('connection').textContent = was ? 'connection lost; reconnecting…' : 'cannot connect; retrying…';
  $('connection').dataset.state = 'disconnected';
  setTimeout(() => rpc.connect(), RECONNECT_MS);
};
rpc.connect();
