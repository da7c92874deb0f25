// simgate's web app (docs/web.md): one WebSocket to the server that served this page,
// JSON-RPC 2.0 over it (docs/transports/jsonrpc.md). Seven parts:
//   - Rpc: calls matched to their replies by id, progress reports, notifications;
//   - the login: when the transport wants a token (its `auth` option), the page asks for it
//     and calls rpc.login before anything else;
//   - the state header: simulation get_simulation_state (else time statistics) at 2 Hz,
//     pause / play / step;
//   - the service console: a form per method of rpc.discover, a log of the calls with their
//     progress, status and reply, and a Cancel button (rpc.cancel) while one runs;
//   - the scene: simulation get_scene_geometry drawn with three.js, bodies moved by the
//     `simulation` stream (rpc.subscribe), or by polling when the server has no such stream;
//     without get_scene_geometry, each root body of simulation get_scene_objects as a marker;
//     a new model generation (a spawn, a delete) reloads it, and the console's services, the
//     cameras and the input streams with it (a robot spawned with components, or deleted);
//   - the cameras: every component with a get_image service, its image on asking, and live
//     from its data stream (rpc.subscribe) when this transport carries one;
//   - the input streams (rpc.streams, direction IN): a command box for each (rpc.publish),
//     and a drive pad for a velocity stream {v, w} (arrow keys or buttons, held to drive).
// What the browser test reads is on window.simgate (tests/web/webapp_test.js).
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const STATE_PERIOD_MS = 500;        // the state header's refresh
const POSE_POLL_PERIOD_MS = 250;    // body poses when there is no stream
const RECONNECT_MS = 2000;          // after the connection is lost

const $ = (id) => document.getElementById(id);
const el = (tag, props = {}, ...children) => {
  const e = Object.assign(document.createElement(tag), props);
  for (const c of children) e.append(c);
  return e;
};
const fmt = (v, digits = 3) => (typeof v === 'number' ? v.toFixed(digits) : String(v ?? '–'));
const errorText = (e) => e?.data?.message ?? e?.message ?? String(e);
// A service the server does not have, or does not let this transport call.
const isUnknownMethod = (e) => e?.code === -32601;
// The transport wants rpc.login first (its `auth` option), or the token was wrong.
const isUnauthorized = (e) => e?.code === -32005;
// A measured real-time factor, or '–' when none is known (0: paused, or playing for less
// than the server's measuring window since play).
const fmtFactor = (f) => (typeof f === 'number' && f > 0 ? f.toFixed(2) : '–');

// What the browser test (and a curious developer) can read.
const exposed = window.simgate = {
  connected: false,
  ready: false,          // connected, and logged in when the transport wants a token
  login: 'none',         // 'none' (no token needed), 'asking', 'wrong' (asking again) or 'done'
  services: [],          // method names of rpc.discover
  bodies: {},            // body name -> [x, y, z]
  meshes: 0,             // three.js meshes in the scene
  hfields: 0,            // of which heightfields
  frames: 0,             // frames rendered
  poseSource: 'none',    // 'stream', 'poll' or 'none'
  view: 'none',          // 'geometry', 'markers', 'none' or 'no-webgl'
  cameras: {},           // camera component -> {images, width, height, live, error}
  inputs: {},            // input stream -> {published, refused, last, error}
};

// ---------------------------------------------------------------- JSON-RPC over WebSocket

class Rpc {
  constructor(url) {
    this.url = url;
    this.nextId = 1;
    this.pending = new Map();      // id -> {resolve, reject, onProgress}
    this.listeners = new Map();    // notification method -> [fn]
    this.onopen = () => {};
    this.onclose = () => {};
  }

  connect() {
    this.ws = new WebSocket(this.url);
    this.ws.onopen = () => this.onopen();
    this.ws.onclose = () => {
      for (const p of this.pending.values()) p.reject({ code: 0, message: 'connection lost' });
      this.pending.clear();
      this.onclose();
    };
    this.ws.onmessage = (event) => {
      let message;
      try { message = JSON.parse(event.data); } catch { return; }
      for (const m of Array.isArray(message) ? message : [message]) this.dispatch(m);
    };
  }

  dispatch(m) {
    if (m.method) {  // a notification
      if (m.method === 'rpc.progress') this.pending.get(m.params?.id)?.onProgress?.(m.params);
      for (const fn of this.listeners.get(m.method) ?? []) fn(m.params);
      return;
    }
    const p = this.pending.get(m.id);
    if (!p) return;
    this.pending.delete(m.id);
    if ('error' in m) p.reject(m.error); else p.resolve(m.result);
  }

  on(method, fn) {
    if (!this.listeners.has(method)) this.listeners.set(method, []);
    this.listeners.get(method).push(fn);
  }

  // {id, done}: done resolves with the result or rejects with the JSON-RPC error object.
  start(method, params, onProgress) {
    const id = this.nextId++;
    const done = new Promise((resolve, reject) => {
      if (this.ws?.readyState !== WebSocket.OPEN) {
        reject({ code: 0, message: 'not connected' });
        return;
      }
      this.pending.set(id, { resolve, reject, onProgress });
      const request = { jsonrpc: '2.0', method, id };
      if (params !== undefined) request.params = params;
      this.ws.send(JSON.stringify(request));
    });
    return { id, done };
  }

  call(method, params) { return this.start(method, params).done; }
  cancel(id) { return this.call('rpc.cancel', { id }); }
}


// ---------------------------------------------------------------- the login

const TOKEN_KEY = 'simgate-token';  // sessionStorage: the token of this tab, not kept after it

// Resolves with the token the user types in the login form.
function askToken(message) {
  const form = $('login');
  form.hidden = false;
  $('login-message').textContent = message;
  $('login-token').focus();
  return new Promise((resolve) => {
    form.onsubmit = (event) => {
      event.preventDefault();
      const token = $('login-token').value.trim();
      if (!token) return;
      form.hidden = true;
      resolve(token);
    };
  });
}

// Before anything else on a new connection: true once the connection may call services
// (no token needed, or rpc.login accepted), false when the token was wrong (the server then
// closes the connection; the next one asks again).
async function login(rpc) {
  let token = sessionStorage.getItem(TOKEN_KEY);
  if (!token) {
    // rpc.cancel of no call: false when no token is needed, -32005 when one is
    try {
      await rpc.call('rpc.cancel', { id: null });
      return true;
    } catch (e) {
      if (!isUnauthorized(e)) return true;
    }
    token = await askToken(exposed.login === 'wrong'
      ? 'Wrong token. Token of this server (its "auth" option):'
      : 'This server wants a token (its "auth" option):');
    exposed.login = 'asking';
  }
  try {
    await rpc.call('rpc.login', { token });
    sessionStorage.setItem(TOKEN_KEY, token);
    exposed.login = 'done';
    return true;
  } catch (e) {
    sessionStorage.removeItem(TOKEN_KEY);
    exposed.login = 'wrong';
    $('connection').textContent = `rpc.login: ${errorText(e)}`;
    return false;
  }
}

// ---------------------------------------------------------------- the state header

function setupState(rpc) {
  let source = 'simulation.get_simulation_state';
  async function refresh() {
    if (!exposed.connected || !exposed.ready) return;
    try {
      const s = await rpc.call(source);
      $('state-run').textContent = s.state ?? '–';
      $('state-time').textContent = `${fmt(s.sim_time)} s`;
      const target = s.target_realtime_factor === 0 ? 'max' : fmt(s.target_realtime_factor, 2);
      $('state-rtf').textContent = `${fmtFactor(s.realtime_factor ?? s.recent_realtime_factor)} (target ${target})`;
      $('state-clients').textContent = s.clients ?? '–';
      if ($('state-error').textContent.startsWith('state:')) $('state-error').textContent = '';
    } catch (e) {
      // get_simulation_state not served here: time statistics says much the same
      if (isUnknownMethod(e) && source !== 'time.statistics') source = 'time.statistics';
      else $('state-error').textContent = `state: ${errorText(e)}`;
    }
  }
  setInterval(refresh, STATE_PERIOD_MS);

  const control = (method, params) => async () => {
    try {
      await rpc.call(method, params);
      $('state-error').textContent = '';
    } catch (e) {
      $('state-error').textContent = `${method}: ${errorText(e)}`;
    }
    refresh();
  };
  $('btn-pause').onclick = control('simulation.pause');
  $('btn-play').onclick = control('simulation.play');
  $('btn-step').onclick = () => control('simulation.step', { n: Number($('step-n').value) || 1 })();
  return refresh;
}

// ---------------------------------------------------------------- the service console

// A form field's text as a JSON value: a string parameter takes it as it is; anything else
// is parsed as JSON, and taken as a string when it is not JSON.
function parseValue(text, schema) {
  if (schema?.type === 'string') return text;
  try { return JSON.parse(text); } catch { return text; }
}

function setupConsole(rpc) {
  const calls = $('calls');

  function logCall(method, params) {
    const status = el('span', { className: 'status', textContent: 'RUNNING' });
    const progress = el('code', { className: 'progress' });
    const reply = el('pre', { className: 'reply' });
    const cancel = el('button', { type: 'button', className: 'cancel', textContent: 'Cancel' });
    const entry = el('li', { className: 'call' },
      el('div', {}, status, ' ', el('code', { className: 'method', textContent: method }), ' ',
        el('code', { className: 'params', textContent: JSON.stringify(params) }), ' ', cancel),
      progress, reply);
    entry.dataset.method = method;
    entry.dataset.status = 'RUNNING';
    calls.prepend(entry);
    const set = (text) => { status.textContent = text; entry.dataset.status = text; };
    return { entry, set, progress, reply, cancel };
  }

  async function callService(method, params, isAsync) {
    const sent = { ...params };
    if (isAsync) sent._meta = { progress: true };  // rpc.progress reports while it runs
    const log = logCall(method, params);
    const { id, done } = rpc.start(method, sent, (p) => {
      log.progress.textContent = `progress: ${JSON.stringify(p.data)}`;
    });
    log.entry.dataset.callId = id;
    log.cancel.onclick = async () => {
      log.cancel.disabled = true;
      try {
        const found = await rpc.cancel(id);
        if (!found) log.progress.textContent = 'cancel: the call was no longer running';
      } catch (e) {
        log.progress.textContent = `cancel: ${errorText(e)}`;
      }
    };
    try {
      const result = await done;
      log.set('SUCCESS');
      log.reply.textContent = JSON.stringify(result, null, 2);
    } catch (e) {
      // the service's status (FAILED, PREEMPTED) when it ran, else the protocol's error
      log.set(e?.data?.status ?? 'ERROR');
      log.reply.textContent = `${e.code ?? ''} ${errorText(e)}` + (e.data ? `\n${JSON.stringify(e.data, null, 2)}` : '');
    }
    log.cancel.remove();
  }

  function methodForm(m) {
    const isAsync = Boolean(m['x-async']);
    const inputs = [];
    const fields = (m.params ?? []).map((p) => {
      const def = p.schema?.default;
      const input = el('input', {
        name: p.name,
        placeholder: def !== undefined ? JSON.stringify(def) : (p.schema?.type ?? 'value'),
        title: `${p.name}${p.required ? ' (required)' : ''}: ${p.schema?.type ?? 'any'}`,
      });
      input.dataset.param = p.name;
      inputs.push({ input, param: p });
      return el('label', {}, `${p.name}${p.required ? '*' : ''} `, input);
    });
    const button = el('button', { type: 'submit', className: 'call-button', textContent: 'Call' });
    const form = el('form', { className: 'method' },
      el('div', { className: 'method-head' },
        el('code', { textContent: m.name }), isAsync ? el('span', { className: 'tag', textContent: 'async' }) : '',
        el('span', { className: 'doc', textContent: m.summary ?? m.description ?? '' })),
      el('div', { className: 'fields' }, ...fields, button));
    form.dataset.method = m.name;
    form.onsubmit = (event) => {
      event.preventDefault();
      const params = {};
      for (const { input, param } of inputs)
        if (input.value !== '') params[param.name] = parseValue(input.value, param.schema);
      callService(m.name, params, isAsync);
    };
    return form;
  }

  async function load() {
    const box = $('services');
    try {
      const doc = await rpc.call('rpc.discover');
      const methods = (doc.methods ?? []).slice().sort((a, b) => a.name.localeCompare(b.name));
      exposed.services = methods.map((m) => m.name);
      // one group per component, its methods' forms inside
      const groups = new Map();
      for (const m of methods) {
        const component = m['x-component'] ?? m.name.slice(0, m.name.lastIndexOf('.'));
        if (!groups.has(component)) groups.set(component, []);
        groups.get(component).push(m);
      }
      box.replaceChildren(...[...groups].map(([component, ms]) => {
        const group = el('details', { className: 'component', open: component.startsWith('robot') },
          el('summary', { textContent: `${component} (${ms.length})` }), ...ms.map(methodForm));
        group.dataset.component = component;
        return group;
      }));
      if (methods.length === 0) box.replaceChildren(el('p', { className: 'note', textContent: 'no service is served here' }));
      return methods;
    } catch (e) {
      box.replaceChildren(el('p', { className: 'error', textContent: `rpc.discover: ${errorText(e)}` }));
      return [];
    }
  }

  $('service-filter').oninput = () => {
    const words = $('service-filter').value.toLowerCase().split(/\s+/).filter(Boolean);
    for (const form of document.querySelectorAll('form.method')) {
      const name = form.dataset.method.toLowerCase();
      form.hidden = !words.every((w) => name.includes(w));
    }
    for (const group of document.querySelectorAll('details.component')) {
      group.hidden = [...group.querySelectorAll('form.method')].every((f) => f.hidden);
      if (words.length) group.open = true;
    }
  };
  return load;
}

// ---------------------------------------------------------------- the bodies table

function showBodies(positions) {
  exposed.bodies = positions;
  const tbody = $('bodies').tBodies[0];
  for (const [name, [x, y, z]] of Object.entries(positions)) {
    let row = tbody.querySelector(`tr[data-body="${CSS.escape(name)}"]`);
    if (!row) {
      row = el('tr', {}, el('th', { textContent: name }), el('td', { className: 'x' }),
        el('td', { className: 'y' }), el('td', { className: 'z' }));
      row.dataset.body = name;
      tbody.append(row);
    }
    row.cells[1].textContent = fmt(x);
    row.cells[2].textContent = fmt(y);
    row.cells[3].textContent = fmt(z);
  }
}

// ---------------------------------------------------------------- the 3D view

// A heightfield's top surface: ncol x nrow points over [-size[0], size[0]] x [-size[1],
// size[1]], each at its elevation (0..1) times size[2]; data row by row along y (MuJoCo's).
function hfieldGeometry(h) {
  const { nrow, ncol, data } = h;
  const [sx, sy, sz] = h.size;
  if (!(nrow >= 2 && ncol >= 2) || data?.length !== nrow * ncol) return null;
  const positions = new Float32Array(3 * nrow * ncol);
  for (let r = 0; r < nrow; ++r)
    for (let c = 0; c < ncol; ++c) {
      const i = r * ncol + c;
      positions[3 * i] = -sx + (2 * sx * c) / (ncol - 1);
      positions[3 * i + 1] = -sy + (2 * sy * r) / (nrow - 1);
      positions[3 * i + 2] = data[i] * sz;
    }
  const index = [];
  for (let r = 0; r + 1 < nrow; ++r)
    for (let c = 0; c + 1 < ncol; ++c) {
      const a = r * ncol + c, b = a + 1, d = a + ncol, e = d + 1;
      index.push(a, b, e, a, e, d);  // counter-clockwise seen from above (+z)
    }
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(positions, 3));
  geometry.setIndex(index);
  geometry.computeVertexNormals();
  return geometry;
}

// A three.js geometry for a MuJoCo geom (size: MuJoCo's geom_size), or null.
function geomGeometry(g, meshes, hfields) {
  const [a, b, c] = g.size ?? [0, 0, 0];
  switch (g.type) {
    case 'plane': {
      // a half-size of 0 is an infinite plane: drawn large
      const plane = new THREE.PlaneGeometry(2 * (a || 50), 2 * (b || 50));
      return plane;
    }
    case 'sphere': return new THREE.SphereGeometry(a, 24, 16);
    case 'ellipsoid': return new THREE.SphereGeometry(1, 24, 16).scale(a, b, c);
    // three.js's capsule and cylinder stand along y, MuJoCo's along z
    case 'capsule': return new THREE.CapsuleGeometry(a, 2 * b, 8, 16).rotateX(Math.PI / 2);
    case 'cylinder': return new THREE.CylinderGeometry(a, a, 2 * b, 24).rotateX(Math.PI / 2);
    case 'box': return new THREE.BoxGeometry(2 * a, 2 * b, 2 * c);
    case 'mesh': {
      const mesh = meshes?.[g.mesh];
      if (!mesh) return null;
      const geometry = new THREE.BufferGeometry();
      geometry.setAttribute('position', new THREE.Float32BufferAttribute(mesh.vertices, 3));
      geometry.setIndex(mesh.faces);
      geometry.computeVertexNormals();
      return geometry;
    }
    case 'hfield': {
      const hfield = hfields?.[g.hfield];
      return hfield ? hfieldGeometry(hfield) : null;
    }
    default: return null;
  }
}

const setPose = (object, pos, quat) => {
  if (pos) object.position.set(pos[0], pos[1], pos[2]);
  if (quat) object.quaternion.set(quat[1], quat[2], quat[3], quat[0]);  // MuJoCo: w, x, y, z
};

class SceneView {
  constructor(container) {
    this.renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(window.devicePixelRatio);
    container.append(this.renderer.domElement);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0xdde3ea);
    this.camera = new THREE.PerspectiveCamera(50, 1, 0.05, 500);
    this.camera.up.set(0, 0, 1);  // MuJoCo is z-up
    this.camera.position.set(5, -6, 4);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.target.set(0, 0, 0.3);
    this.controls.update();
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x445544, 1.2));
    const sun = new THREE.DirectionalLight(0xffffff, 1.5);
    sun.position.set(3, -4, 8);
    this.scene.add(sun);
    // a 1 m grid on the ground (three.js's lies in x-z, MuJoCo's ground in x-y)
    const grid = new THREE.GridHelper(20, 20, 0x3c463c, 0x5f6b5f);
    grid.rotateX(Math.PI / 2);
    grid.position.z = 0.002;
    this.scene.add(grid);
    this.root = new THREE.Group();  // what the server's scene is drawn in
    this.scene.add(this.root);
    this.bodies = [];               // body index -> Group, placed in the world
    new ResizeObserver(() => this.resize(container)).observe(container);
    this.resize(container);
    this.renderer.setAnimationLoop(() => {
      this.controls.update();
      this.renderer.render(this.scene, this.camera);
      exposed.frames++;
    });
  }

  resize(container) {
    const w = container.clientWidth || 640, h = container.clientHeight || 400;
    this.renderer.setSize(w, h);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
  }

  clear() {
    this.root.traverse((o) => { o.geometry?.dispose(); o.material?.dispose(); });
    this.root.clear();
    this.bodies = [];
    exposed.meshes = 0;
    exposed.hfields = 0;
  }

  // get_scene_geometry's answer: a group per body, its geoms inside.
  build(geometry) {
    this.clear();
    for (const b of geometry.bodies) {
      const group = new THREE.Group();
      group.name = b.name;
      setPose(group, b.pos, b.quat);
      this.root.add(group);
      this.bodies.push(group);
    }
    const byId = new Map(geometry.bodies.map((b, i) => [b.id ?? i, this.bodies[i]]));
    for (const g of geometry.geoms) {
      if ((g.group ?? 0) >= 3) continue;      // MuJoCo hides groups 3-5 by default
      const rgba = g.rgba ?? [0.7, 0.7, 0.7, 1];
      if (rgba[3] === 0) continue;            // invisible
      const shape = geomGeometry(g, geometry.meshes, geometry.hfields);
      if (!shape) continue;
      const material = new THREE.MeshStandardMaterial({
        color: new THREE.Color(rgba[0], rgba[1], rgba[2]),
        transparent: rgba[3] < 1, opacity: rgba[3], roughness: 0.8,
        side: g.type === 'plane' || g.type === 'hfield' ? THREE.DoubleSide : THREE.FrontSide,
      });
      const mesh = new THREE.Mesh(shape, material);
      mesh.name = g.name ?? '';
      setPose(mesh, g.pos, g.quat);
      (byId.get(g.body) ?? this.root).add(mesh);
      exposed.meshes++;
      if (g.type === 'hfield') exposed.hfields++;
    }
  }

  // poses: [[x, y, z, qw, qx, qy, qz], ...] one per body, in body order.
  move(poses) {
    poses.forEach((p, i) => { if (this.bodies[i]) setPose(this.bodies[i], p, p.slice(3)); });
  }

  // Without get_scene_geometry: a marker per root body of get_scene_objects.
  markers(objects) {
    for (const [name, [, pos, q]] of Object.entries(objects)) {
      let marker = this.root.getObjectByName(name);
      if (!marker) {
        marker = new THREE.Mesh(new THREE.BoxGeometry(0.3, 0.3, 0.3),
          new THREE.MeshStandardMaterial({ color: name.startsWith('robot') ? 0x3355cc : 0x998866 }));
        marker.name = name;
        this.root.add(marker);
        exposed.meshes++;
      }
      marker.position.set(pos[0], pos[1], pos[2]);
      marker.quaternion.set(q[0], q[1], q[2], q[3]);  // get_scene_objects: x, y, z, w
    }
  }
}

function setupScene(rpc, onModelChanged) {
  let view = null;
  try {
    view = new SceneView($('view'));
  } catch (e) {
    exposed.view = 'no-webgl';
    $('view-info').textContent = `no 3D view: ${e.message} (the rest of the page works)`;
  }
  let geometry = null;       // the last get_scene_geometry answer
  let pollTimer = null;

  const positionsOf = (bodies, poses) => {
    const out = {};
    bodies.forEach((b, i) => { if (b.name && b.id !== 0 && poses[i]) out[b.name] = poses[i].slice(0, 3); });
    return out;
  };

  async function fetchGeometry(includeMeshes) {
    return rpc.call('simulation.get_scene_geometry', { include_meshes: includeMeshes });
  }

  async function onPoses(sample) {
    if (!geometry) return;
    if (sample.generation !== undefined && sample.generation !== geometry.generation) {
      await loadGeometry();  // the model changed (an entity spawned or deleted)
      onModelChanged();      // and with it, maybe, the services (a robot spawned or deleted)
      return;
    }
    // poses one per body in id order: by index when the lists match, else by id
    const poses = sample.poses.length === geometry.bodies.length
      ? sample.poses : geometry.bodies.map((b) => sample.poses[b.id]);
    view?.move(poses);
    showBodies(positionsOf(geometry.bodies, poses));
  }

  async function loadGeometry() {
    geometry = await fetchGeometry(true);
    view?.build(geometry);
    exposed.view = view ? 'geometry' : exposed.view;
    showBodies(positionsOf(geometry.bodies, geometry.bodies.map((b) => [...b.pos, ...b.quat])));
  }

  function poll(fn) {
    clearInterval(pollTimer);
    exposed.poseSource = 'poll';
    pollTimer = setInterval(async () => {
      if (!exposed.connected || !exposed.ready) return;
      try { await fn(); } catch (e) { $('view-info').textContent = `poses: ${errorText(e)}`; }
    }, POSE_POLL_PERIOD_MS);
  }

  rpc.on('rpc.sample', (p) => { if (p.component === 'simulation') onPoses(p.data); });

  return async function start() {
    clearInterval(pollTimer);
    try {
      await loadGeometry();
      try {
        await rpc.call('rpc.subscribe', { component: 'simulation' });
        exposed.poseSource = 'stream';
        $('view-info').textContent = `${exposed.meshes} geoms; poses streamed`;
      } catch (e) {
        // no `simulation` stream on this transport: poll the poses
        $('view-info').textContent = `${exposed.meshes} geoms; poses polled (the transport carries no simulation stream)`;
        console.info(`rpc.subscribe simulation: ${errorText(e)}`);
        poll(async () => {
          const g = await fetchGeometry(false);
          await onPoses({ generation: g.generation, poses: g.bodies.map((b) => [...b.pos, ...b.quat]) });
        });
      }
    } catch (e) {
      // no get_scene_geometry: the root bodies of get_scene_objects, as markers
      $('view-info').textContent = isUnknownMethod(e)
        ? 'simulation.get_scene_geometry is not served here: each root body is drawn as a box'
        : `simulation.get_scene_geometry: ${errorText(e)}; each root body is drawn as a box`;
      exposed.view = view ? 'markers' : exposed.view;
      const refresh = async () => {
        const objects = await rpc.call('simulation.get_scene_objects');
        view?.markers(objects);
        showBodies(Object.fromEntries(Object.entries(objects).map(([name, [, pos]]) => [name, pos])));
      };
      try { await refresh(); poll(refresh); } catch (e2) {
        $('view-info').textContent += ` (simulation.get_scene_objects: ${errorText(e2)})`;
      }
    }
  };
}

// ---------------------------------------------------------------- the cameras

// The image kinds of the data streams (docs/components/cameras.md, Streams).
const IMAGE_KINDS = new Set(['image', 'depth_image']);

// A depth image (a 16-bit grey PNG of millimetres: docs/components/cameras.md) as an 8-bit
// PNG a person can read: the record's min_depth..max_depth stretched from white (near) to
// dark grey (far), black where nothing is within reach. Shown as is, millimetres in 16 bits
// come out nearly black (a browser keeps the high byte: 4 m is 15 of 255).
async function depthPreview(record) {
  const png = Uint8Array.from(atob(record.image), (c) => c.charCodeAt(0));
  const view = new DataView(png.buffer);
  const idat = [];
  let width = 0, height = 0, depth = 0, colour = -1, interlace = 0;
  for (let at = 8; at + 8 <= png.length;) {
    const length = view.getUint32(at);
    const type = String.fromCharCode(...png.subarray(at + 4, at + 8));
    const data = png.subarray(at + 8, at + 8 + length);
    if (type === 'IHDR') {
      width = view.getUint32(at + 8);
      height = view.getUint32(at + 12);
      [depth, colour, , , interlace] = data.subarray(8, 13);
    } else if (type === 'IDAT') {
      idat.push(data);
    } else if (type === 'IEND') {
      break;
    }
    at += 12 + length;
  }
  if (depth !== 16 || colour !== 0 || interlace !== 0 || !width || !height) throw new Error('not a 16-bit grey PNG');
  // the image data: zlib (DecompressionStream's 'deflate'), then the filters of each row
  const inflated = new Uint8Array(await new Response(
    new Blob(idat).stream().pipeThrough(new DecompressionStream('deflate'))).arrayBuffer());
  const stride = width * 2;
  if (inflated.length < height * (stride + 1)) throw new Error('truncated image data');
  const rows = new Uint8Array(height * stride);
  for (let y = 0; y < height; ++y) {
    const filter = inflated[y * (stride + 1)];
    const line = inflated.subarray(y * (stride + 1) + 1, (y + 1) * (stride + 1));
    const out = rows.subarray(y * stride, (y + 1) * stride);
    const up = y > 0 ? rows.subarray((y - 1) * stride, y * stride) : new Uint8Array(stride);
    for (let i = 0; i < stride; ++i) {
      const a = i >= 2 ? out[i - 2] : 0, b = up[i], c = i >= 2 ? up[i - 2] : 0;
      let predicted = 0;
      if (filter === 1) predicted = a;
      else if (filter === 2) predicted = b;
      else if (filter === 3) predicted = (a + b) >> 1;
      else if (filter === 4) {
        const p = a + b - c, pa = Math.abs(p - a), pb = Math.abs(p - b), pc = Math.abs(p - c);
        predicted = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
      }
      out[i] = (line[i] + predicted) & 0xff;
    }
  }
  const near = (record.min_depth ?? 0) * 1000, far = Math.max((record.max_depth ?? 0) * 1000, near + 1);
  const canvas = document.createElement('canvas');
  canvas.width = width;
  canvas.height = height;
  const ctx = canvas.getContext('2d');
  const pixels = ctx.createImageData(width, height);
  for (let i = 0; i < width * height; ++i) {
    const mm = (rows[2 * i] << 8) | rows[2 * i + 1];
    const grey = mm === 0 ? 0 : Math.round(255 - 200 * Math.min(1, Math.max(0, (mm - near) / (far - near))));
    pixels.data.set([grey, grey, grey, 255], 4 * i);
  }
  ctx.putImageData(pixels, 0, 0);
  return canvas.toDataURL('image/png');
}

function setupCameras(rpc) {
  const figures = new Map();      // component -> {img, caption, live checkbox, status}
  const subscriptions = new Map(); // component -> subscription number, while live

  // An image record (get_image's reply, a stream sample): PNG in base64 (MORSE's way); a
  // depth image stretched so that it can be seen (depthPreview).
  async function show(component, record) {
    const figure = figures.get(component);
    const state = exposed.cameras[component];
    if (!figure || !record?.image || record.format !== 'png') return;
    const depth = record.encoding === 'mono16';
    try {
      figure.img.src = depth ? await depthPreview(record) : `data:image/png;base64,${record.image}`;
    } catch (e) {
      fail(component, 'depth image', e);
      return;
    }
    state.images += 1;
    state.width = record.width;
    state.height = record.height;
    state.depth = depth;
    const range = depth ? ` ${fmt(record.min_depth, 2)}–${fmt(record.max_depth, 2)} m (near is light)` : '';
    figure.status.textContent = `${record.width}×${record.height} ${record.encoding ?? ''}${range}, t = ${fmt(record.timestamp, 2)} s`;
  }

  function fail(component, what, e) {
    exposed.cameras[component].error = `${what}: ${errorText(e)}`;
    figures.get(component).status.textContent = exposed.cameras[component].error;
  }

  async function snapshot(component) {
    try {
      await show(component, await rpc.call(`${component}.get_image`));
    } catch (e) {
      fail(component, 'get_image', e);
    }
  }

  async function setLive(component, on) {
    const state = exposed.cameras[component];
    try {
      if (on) {
        const answer = await rpc.call('rpc.subscribe', { component });
        subscriptions.set(component, answer.subscription);
      } else if (subscriptions.has(component)) {
        await rpc.call('rpc.unsubscribe', { subscription: subscriptions.get(component) });
        subscriptions.delete(component);
      }
      state.live = on;
    } catch (e) {
      figures.get(component).live.checked = state.live;
      fail(component, on ? 'rpc.subscribe' : 'rpc.unsubscribe', e);
    }
  }

  rpc.on('rpc.sample', (p) => { if (subscriptions.has(p.component)) show(p.component, p.data); });

  function figureFor(component, stream) {
    const img = el('img', { alt: `what ${component} sees` });
    const status = el('span', { className: 'note', textContent: 'no image yet' });
    const live = el('input', { type: 'checkbox', disabled: !stream,
      title: stream ? `rpc.subscribe ${component}: every image of its stream (${stream.frequency} Hz)`
        : 'this transport carries no stream of this camera (the deployment\'s "streams")' });
    live.onchange = () => setLive(component, live.checked);
    const button = el('button', { type: 'button', textContent: 'Image', title: `${component}.get_image` });
    button.onclick = () => snapshot(component);
    const figure = el('figure', { className: 'camera' }, img,
      el('figcaption', {}, el('strong', { textContent: component }), ' ', button, ' ',
        el('label', {}, live, ' live'), ' ', status));
    figure.dataset.component = component;
    figures.set(component, { img, status, live });
    return figure;
  }

  // `methods`: a promise of rpc.discover's methods (the console's load()); `streamList` one
  // of rpc.streams' answer ([] where there is none). `connected`: the connection is the one
  // the panel was built on (a model change: a robot spawned or deleted), whose live
  // subscriptions end first; else a new one, whose server forgot them.
  return async function start(methods, streamList, connected = false) {
    if (connected)
      for (const subscription of subscriptions.values())
        rpc.call('rpc.unsubscribe', { subscription }).catch(() => {});  // its camera may be gone
    const names = (await methods).map((m) => m.name);
    const streams = await streamList;
    const streamOf = new Map(streams.filter((s) => s.direction === 'OUT' && IMAGE_KINDS.has(s.kind))
      .map((s) => [s.component, s]));
    const cameras = [...new Set([...names.filter((n) => n.endsWith('.get_image')).map((n) => n.slice(0, -'.get_image'.length)),
      ...streamOf.keys()])].sort();
    subscriptions.clear();
    figures.clear();
    exposed.cameras = Object.fromEntries(cameras.map((c) => [c, { images: 0, width: 0, height: 0, live: false, error: '' }]));
    const box = $('cameras');
    box.replaceChildren(...cameras.map((c) => figureFor(c, streamOf.get(c))));
    if (cameras.length === 0) box.replaceChildren(el('p', { className: 'note', textContent: 'no camera is served here' }));
    // one image each to begin with (a camera renders only when asked or subscribed)
    await Promise.all(cameras.filter((c) => names.includes(`${c}.get_image`)).map(snapshot));
  };
}

// ---------------------------------------------------------------- the input streams

const DRIVE_PERIOD_MS = 100;  // a held drive key publishes this often (the command holds meanwhile)
// arrow key -> [forward, turn left] factors of the pad's speeds
const DRIVE_KEYS = { ArrowUp: [1, 0], ArrowDown: [-1, 0], ArrowLeft: [0, 1], ArrowRight: [0, -1] };

function setupInputs(rpc) {
  const timers = new Set();  // the drive pads' repeat timers (cleared when the pads are rebuilt)

  async function publish(component, data, status) {
    const state = exposed.inputs[component];
    try {
      await rpc.call('rpc.publish', { component, data });
      state.published += 1;
      state.last = data;
      state.error = '';
      status.textContent = `sent ${JSON.stringify(data)}`;
    } catch (e) {
      if (e?.code === -32602) state.refused += 1;  // the component's refusal, not a lost connection
      state.error = errorText(e);
      status.className = 'error';
      status.textContent = state.error;
      return;
    }
    status.className = 'note';
  }

  // A velocity stream {v, w}: the command of the keys held, sent while any is held, then a stop.
  function drivePad(component, status) {
    const speed = el('input', { type: 'number', value: '0.5', min: '0', step: '0.1', title: 'v, m/s' });
    const turn = el('input', { type: 'number', value: '1', min: '0', step: '0.1', title: 'w, rad/s' });
    const held = new Set();
    let timer = null;
    const command = () => {
      let forward = 0, left = 0;
      for (const key of held) { forward += DRIVE_KEYS[key][0]; left += DRIVE_KEYS[key][1]; }
      return { v: forward * Number(speed.value), w: left * Number(turn.value) };
    };
    const update = () => {
      publish(component, command(), status);
      clearInterval(timer);
      timers.delete(timer);
      timer = held.size ? setInterval(() => publish(component, command(), status), DRIVE_PERIOD_MS) : null;
      if (timer) timers.add(timer);
    };
    const press = (key) => { if (!held.has(key)) { held.add(key); update(); } };
    const release = (key) => { if (held.delete(key)) update(); };
    const button = (key, label) => {
      const b = el('button', { type: 'button', textContent: label, title: `${key} (held)` });
      b.onpointerdown = () => press(key);
      b.onpointerup = b.onpointerleave = () => release(key);
      return b;
    };
    const pad = el('div', { className: 'drive', tabIndex: 0,
      title: 'click here, then hold the arrow keys to drive' },
    el('div', { className: 'keys' }, el('span'), button('ArrowUp', '▲'), el('span'),
      button('ArrowLeft', '◀'), button('ArrowDown', '▼'), button('ArrowRight', '▶')),
    el('label', {}, 'v ', speed, ' m/s'), el('label', {}, 'w ', turn, ' rad/s'));
    pad.onkeydown = (e) => { if (e.key in DRIVE_KEYS && e.target === pad) { e.preventDefault(); press(e.key); } };
    pad.onkeyup = (e) => { if (e.key in DRIVE_KEYS) release(e.key); };
    // focus gone, keys released unseen: stop rather than drive on
    pad.onblur = () => { if (held.size) { held.clear(); update(); } };
    return pad;
  }

  // Any input stream: a JSON object typed and sent.
  function commandBox(stream, status) {
    const example = Object.fromEntries((stream.fields ?? []).map((f) => [f, 0]));
    const text = el('input', { type: 'text', className: 'command', value: JSON.stringify(example),
      title: `a JSON object with ${(stream.fields ?? []).join(', ') || 'the stream\'s fields'}` });
    const send = el('button', { type: 'button', textContent: 'Publish', title: `rpc.publish ${stream.component}` });
    send.onclick = () => {
      let data;
      try { data = JSON.parse(text.value); } catch (e) { data = undefined; }
      if (data === null || typeof data !== 'object' || Array.isArray(data)) {
        status.className = 'error';
        status.textContent = 'a command is a JSON object, e.g. ' + JSON.stringify(example);
        return;
      }
      publish(stream.component, data, status);
    };
    return el('div', { className: 'fields' }, text, send);
  }

  // `streamList`: a promise of rpc.streams' answer ([] where there is none).
  return async function start(streamList) {
    // a reconnection: the old pads' keys are forgotten, nothing repeats an old command
    for (const t of timers) clearInterval(t);
    timers.clear();
    const streams = await streamList;
    const inputs = streams.filter((s) => s.direction === 'IN').sort((a, b) => a.component.localeCompare(b.component));
    exposed.inputs = Object.fromEntries(inputs.map((s) => [s.component, { published: 0, refused: 0, last: null, error: '' }]));
    const box = $('inputs');
    box.replaceChildren(...inputs.map((s) => {
      const status = el('span', { className: 'note' });
      const velocity = s.kind === 'velocity' && ['v', 'w'].every((f) => s.fields?.includes(f));
      const section = el('div', { className: 'input' },
        el('strong', { textContent: s.component }), el('span', { className: 'note', textContent: ` ${s.kind} {${(s.fields ?? []).join(', ')}}` }),
        velocity ? drivePad(s.component, status) : commandBox(s, status), status);
      section.dataset.component = s.component;
      return section;
    }));
    if (inputs.length === 0)
      box.replaceChildren(el('p', { className: 'note', textContent: 'no input stream is carried here (the deployment\'s "streams")' }));
  };
}

// ---------------------------------------------------------------- start

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
