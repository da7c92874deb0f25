#!/usr/bin/env node
// End-to-end test of the foxglove transport's sensor channels with Foxglove's own client and
// schemas (@foxglove/ws-protocol, @foxglove/schemas: nobody on the team wrote them), against
// the real gateway (`simgate run gateway_foxglove_rover.json`: the rover room, its cameras
// rendered headless): each camera, the depth camera, the laser, the odometry and the log in
// Foxglove's schemas, with what their panels need (a PNG, metres, the scan's arc, a
// quaternion); the IMU, which no Foxglove schema fits, as plottable JSON; a client that reads
// nothing costs the server bounded memory and delays no other.
//
//   node foxglove_sensors_test.js <simgate> run <config> [--plugin-path DIR]
// Exit code: 0 passed, 1 failed, 77 the npm packages are not installed.
'use strict';

const fs = require('fs');
const { Ajv, WebSocket, foxgloveSchemas, check, Session, sleep, runTest } = require('./session');

const TOTAL_TIMEOUT_MS = 100000;

// The first message of `topic`, checked against Foxglove's own schema `name`.
async function first(s, ajv, topic, name) {
  const channel = s.channel(topic);
  check(channel, `${topic} is advertised (have: ${[...s.channels.values()].map((c) => c.topic).join(', ')})`);
  check(channel.schemaName === 'foxglove.' + name, `${topic} is a foxglove.${name} channel (got ${channel.schemaName})`);
  ajv.compile(JSON.parse(channel.schema));  // ours compiles too
  const official = ajv.compile(foxgloveSchemas[name]);
  const id = s.client.subscribe(channel.id);
  await s.until(() => (s.messages.get(id) || []).length >= 1, `a ${topic} message`, 30000);
  const message = JSON.parse(s.messages.get(id)[0].data);
  check(official(message), `${topic} fits foxglove.${name}: ` + ajv.errorsText(official.errors));
  s.client.unsubscribe(id);
  return message;
}

async function sensors(s, ajv) {
  // a camera: its PNG as the record has it, and its intrinsics, of the same size
  const image = await first(s, ajv, '/rover/camera', 'CompressedImage');
  const png = Buffer.from(image.data, 'base64');
  check(image.format === 'png' && png.subarray(1, 4).toString() === 'PNG', 'the image is a PNG');
  check(png.readUInt32BE(16) === 160 && png.readUInt32BE(20) === 120, 'the PNG is 160x120');
  check(image.frame_id === 'rover.camera', 'the image\'s frame is its camera: ' + image.frame_id);
  const calibration = await first(s, ajv, '/rover/camera/calibration', 'CameraCalibration');
  check(calibration.width === 160 && calibration.height === 120, 'the calibration\'s size');
  check(calibration.K[0] > 0 && Math.abs(calibration.K[2] - 80) < 1 && calibration.K[8] === 1,
        'the intrinsics: fx > 0, cx at the centre: ' + JSON.stringify(calibration.K));

  // the depth camera: raw floats, metres
  const depth = await first(s, ajv, '/rover/depth', 'RawImage');
  check(depth.encoding === '32FC1' && depth.step === 80 * 4, 'depth: 32FC1, 4 bytes a pixel');
  const bytes = Buffer.from(depth.data, 'base64');
  check(bytes.length === depth.step * depth.height, `depth: step x height bytes (${bytes.length})`);
  const metres = [];
  for (let i = 0; i < bytes.length; i += 4) metres.push(bytes.readFloatLE(i));
  check(metres.every((m) => m >= 0 && m < 100) && metres.some((m) => m > 0.05),
        'depth: metres within the room: ' + metres.slice(0, 5).join(' '));
  await first(s, ajv, '/rover/depth/calibration', 'CameraCalibration');

  // the laser: 270° every 1°, from -135°, ranges within laser_range
  const scan = await first(s, ajv, '/rover/laser', 'LaserScan');
  check(scan.ranges.length === 271, `271 rays (got ${scan.ranges.length})`);
  const degrees = (r) => (r * 180) / Math.PI;
  check(Math.abs(degrees(scan.start_angle) + 135) < 1e-6 && Math.abs(degrees(scan.end_angle) - 135) < 1e-6,
        `the arc: -135° to 135° (got ${degrees(scan.start_angle)} to ${degrees(scan.end_angle)})`);
  check(scan.ranges.every((r) => r > 0 && r <= 10) && scan.ranges.some((r) => r < 10), 'ranges within laser_range, some walls seen');

  // the sensors' frames hang from their bodies in /tf: the 3D panel places the scan
  const tf = await first(s, ajv, '/tf', 'FrameTransforms');
  for (const name of ['rover.laser', 'rover.camera', 'rover.depth', 'rover.imu']) {
    const t = tf.transforms.find((x) => x.child_frame_id === name);
    check(t && t.parent_frame_id === 'rover', `/tf: rover -> ${name}: ` + JSON.stringify(tf.transforms.map((x) => x.child_frame_id)));
  }

  // the odometry: driving forward moves its pose along x
  const odometry = await first(s, ajv, '/rover/odometry', 'Odometry');
  check(odometry.frame_id === 'rover.odometry/origin' && odometry.body_frame_id === 'rover.odometry', 'odometry frames');
  const q = odometry.pose.orientation;
  check(Math.abs(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w - 1) < 1e-9, 'a unit quaternion');
  const motion = s.client.advertise({ topic: '/rover/motion', encoding: 'json', schemaName: 'simgate.velocity' });
  const odometryChannel = s.client.subscribe(s.channel('/rover/odometry').id);
  s.client.sendMessage(motion, new TextEncoder().encode(JSON.stringify({ v: 0.5, w: 0 })));
  await s.until(() => (s.messages.get(odometryChannel) || []).some((m) => JSON.parse(m.data).pose.position.x > 0.05),
                'the odometry moving forward', 20000);
  s.client.sendMessage(motion, new TextEncoder().encode(JSON.stringify({ v: 0, w: 0 })));
  s.client.unsubscribe(odometryChannel);

  // the IMU: no Foxglove schema fits it, so its JSON (plottable), with a schema of its own
  const imu = s.channel('/rover/imu');
  check(imu && imu.schemaName === 'simgate.imu', '/rover/imu is its JSON: ' + (imu && imu.schemaName));

  // the log: lines as they are logged (spawning a body logs one at info)
  const log = s.channel('/log');
  check(log && log.schemaName === 'foxglove.Log', '/log is a foxglove.Log channel');
  const official = ajv.compile(foxgloveSchemas.Log);
  const logId = s.client.subscribe(log.id);
  const spawned = await s.call('/simulation/spawn_entity', {
    name: 'crate2', mjcf: "<mujoco><worldbody><body><freejoint/><geom type='box' size='.1 .1 .1'/></body></worldbody></mujoco>",
    pose: [0.5, 1, 0.3] });
  check(spawned.ok, 'spawn_entity: ' + JSON.stringify(spawned));
  await s.until(() => (s.messages.get(logId) || []).some((m) => /crate2/.test(JSON.parse(m.data).message)), 'the spawn logged on /log');
  for (const m of s.messages.get(logId)) {
    const line = JSON.parse(m.data);
    check(official(line), 'a log line fits foxglove.Log: ' + ajv.errorsText(official.errors));
  }
  const line = s.messages.get(logId).map((m) => JSON.parse(m.data)).find((l) => /crate2/.test(l.message));
  check(line.level === 2 && line.name === 'simgate', 'an info line: ' + JSON.stringify(line));
  check(!s.error, 'the client saw no protocol error: ' + (s.error && s.error.message));
}

// The gateway's resident memory (kB), from /proc.
function rssKib(pid) {
  const m = fs.readFileSync(`/proc/${pid}/status`, 'utf8').match(/VmRSS:\s+(\d+)/);
  return m ? Number(m[1]) : 0;
}

// A client that subscribes to the images and /tf, then reads nothing: the server's memory
// stays bounded (it keeps the newest image, drops what cannot be sent) and another client
// stays on schedule (its /tf no further behind the simulated time than a reading client's).
async function aClientThatReadsNothing(s, url, pid) {
  const slow = new WebSocket(url, ['foxglove.websocket.v1']);
  const channels = new Map();
  await new Promise((resolve, reject) => {
    slow.on('message', (data, binary) => {
      if (binary) return;
      const m = JSON.parse(data.toString());
      if (m.op === 'advertise') for (const c of m.channels) channels.set(c.topic, c.id);
      if (channels.has('/tf') && channels.has('/rover/camera') && channels.has('/rover/depth')) resolve();
    });
    slow.on('error', reject);
  });
  slow.send(JSON.stringify({ op: 'subscribe', subscriptions: ['/tf', '/rover/camera', '/rover/depth', '/rover/laser']
    .map((topic, i) => ({ id: i + 1, channelId: channels.get(topic) })) }));
  await sleep(500);
  slow._socket.pause();  // from now on it reads nothing
  const before = rssKib(pid);
  const tf = s.client.subscribe(s.channel('/tf').id);
  await sleep(4000);
  const grown = rssKib(pid) - before;
  // ThreadSanitizer maps shadow memory, four times the size of what the server touches, and its
  // allocator keeps what one thread frees for that thread's later allocations (images made on
  // the render thread, freed on the I/O thread): the same bound, scaled (64 MB of the server's
  // own; under TSan the resident size grew 69 MB with the plain build's growing 0)
  const limitKib = (process.env.SIMGATE_SANITIZE === 'thread' ? 4 : 1) * 64 * 1024;
  console.log(`a client that reads nothing: the server grew ${grown} kB (bound ${limitKib} kB)`);
  check(grown < limitKib, `the server's memory stays bounded with a client that reads nothing (grew ${grown} kB in 4 s)`);
  const received = s.messages.get(tf) || [];
  check(received.length > 0, 'the reading client got /tf messages');
  const lag = Number(s.times[s.times.length - 1] - received[received.length - 1].timestamp) / 1e9;
  console.log(`the reading client's /tf: ${lag.toFixed(3)} s behind the simulated time`);
  check(lag < 1.0, `the reading client's /tf keeps up with the simulated time (${lag.toFixed(3)} s behind)`);
  s.client.unsubscribe(tf);
  slow.terminate();
}

runTest(process.argv.slice(2), TOTAL_TIMEOUT_MS, 'the foxglove transport\'s sensor channels fit @foxglove/schemas',
        async (url, child) => {
          const s = new Session(url, 'foxglove.websocket.v1');
          await s.until(() => s.info && s.channel('/rover/laser') && s.service('/simulation/spawn_entity'), 'serverInfo, channels and services');
          await sensors(s, new Ajv({ strict: false }));
          await aClientThatReadsNothing(s, url, child.pid);
          s.close();
        });
