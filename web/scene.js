// The scene: simulation get_scene_geometry drawn with three.js, bodies moved by the
// `simulation` stream (rpc.subscribe), or by polling when the server has no such stream;
// without get_scene_geometry, each root body of simulation get_scene_objects as a marker; a
// new model generation (a spawn, a delete) reloads it and tells the page (onModelChanged).
// The bodies table shows where each body is (docs/web.md).
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { $, el, errorText, exposed, fmt, isUnknownMethod } from './util.js';

const POSE_POLL_PERIOD_MS = 250;    // body poses when there is no stream

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

export function setupScene(rpc, onModelChanged) {
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
