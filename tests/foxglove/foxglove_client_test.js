#!/usr/bin/env node
// End-to-end test of the foxglove transport with Foxglove's own client, which nobody on the
// team wrote: @foxglove/ws-protocol's FoxgloveClient over npm's ws (tests/foxglove/package.json),
// against the real gateway (`simgate run gateway_foxglove.json`: the demo scene).
//
//   node foxglove_client_test.js <simgate> run <config> [--plugin-path DIR]
// The gateway prints "foxglove: ws://127.0.0.1:<port>/" and stops on SIGTERM.
// Exit code: 0 passed, 1 failed, 77 the npm packages are not installed.
'use strict';

const { WebSocket, Ajv, foxgloveSchemas, withTimeout, check, Session, PlaybackConnection, sleep, runTest } = require('./session');

const TOTAL_TIMEOUT_MS = 100000;
const SUBPROTOCOLS = ['foxglove.websocket.v1', 'foxglove.sdk.v1'];

async function refusedWithout(url) {
  // a client that offers no Foxglove subprotocol is refused before the upgrade, as
  // Foxglove's own servers do
  const ws = new WebSocket(url);
  const status = await withTimeout(new Promise((resolve) => {
    ws.on('unexpected-response', (req, res) => { resolve(res.statusCode); ws.terminate(); });
    ws.on('open', () => { resolve('open'); ws.terminate(); });
    ws.on('error', () => {});
  }), 'a refusal without a subprotocol');
  check(status === 400, `no subprotocol: HTTP 400 (got ${status})`);
}

async function session(url, subprotocol, ajv) {
  const s = new Session(url, subprotocol);
  await s.until(() => s.info && s.channel('/robot/pose') && s.service('/simulation/list_robots'), `${subprotocol}: serverInfo, channels and services`);
  check(s.ws.protocol === subprotocol, `the server agreed ${subprotocol} (got '${s.ws.protocol}')`);
  check(s.info.capabilities.includes('services') && s.info.capabilities.includes('time'), 'capabilities services and time');
  check(JSON.stringify(s.info.supportedEncodings) === '["json"]', 'supportedEncodings json');

  // a channel: JSON, with a JSON Schema every sample satisfies, log times in simulated ns
  const pose = s.channel('/robot/pose');
  check(pose.encoding === 'json' && pose.schemaEncoding === 'jsonschema', 'pose: json with a jsonschema');
  const validate = ajv.compile(JSON.parse(pose.schema));
  const events = s.channel('/simulation');
  check(events, 'the simulation\'s events are a channel');
  const sub = s.client.subscribe(pose.id);
  await s.until(() => (s.messages.get(sub) || []).length >= 3, 'three pose samples');
  for (const m of s.messages.get(sub)) {
    const sample = JSON.parse(m.data);
    check(validate(sample), 'a pose sample fits its schema: ' + ajv.errorsText(validate.errors));
    for (const key of ['x', 'y', 'z', 'yaw', 'timestamp']) check(typeof sample[key] === 'number', `pose.${key} is a number`);
    const ns = BigInt(Math.round(sample.timestamp * 1e9));
    const diff = m.timestamp > ns ? m.timestamp - ns : ns - m.timestamp;
    check(diff <= 1000n, `the log time is the sample's simulated time (${m.timestamp} vs ${ns})`);
  }
  await s.until(() => s.times.length >= 2, 'time messages');

  // the 3D panel's messages: every body's pose and every geom, in Foxglove's own schemas
  // (@foxglove/schemas, which nobody on the team wrote)
  for (const [topic, name] of [['/tf', 'FrameTransforms'], ['/scene', 'SceneUpdate']]) {
    const channel = s.channel(topic);
    check(channel && channel.schemaName === 'foxglove.' + name, `${topic} is a foxglove.${name} channel`);
    ajv.compile(JSON.parse(channel.schema));  // ours compiles too
    const official = ajv.compile(foxgloveSchemas[name]);
    const id = s.client.subscribe(channel.id);
    await s.until(() => (s.messages.get(id) || []).length >= 1, `a ${topic} message`);
    const message = JSON.parse(s.messages.get(id)[0].data);
    check(official(message), `${topic} fits foxglove.${name}: ` + ajv.errorsText(official.errors));
    if (topic === '/tf') {
      const robot = message.transforms.find((t) => t.child_frame_id === 'robot');
      check(robot && robot.parent_frame_id === 'world', '/tf: world -> robot: ' + JSON.stringify(message.transforms.map((t) => t.child_frame_id)));
      check(Math.abs(robot.translation.z - 0.0998) < 0.01, '/tf: the robot stands on its wheels: ' + JSON.stringify(robot.translation));
    } else {
      const robot = message.entities.find((e) => e.frame_id === 'robot');
      check(robot && robot.frame_locked && robot.cubes.length + robot.cylinders.length + robot.spheres.length > 0,
            '/scene: the robot\'s geoms are drawn on its frame: ' + JSON.stringify(message.entities.map((e) => e.id)));
      check(message.deletions.length === 1 && message.deletions[0].type === 1, '/scene: what an earlier model drew is deleted first');
      // the scene is sent once per model, not with every sample
      await new Promise((r) => setTimeout(r, 300));
      check(s.messages.get(id).length === 1, `/scene: one message per model (got ${s.messages.get(id).length})`);
    }
    s.client.unsubscribe(id);
  }
  check(s.times[s.times.length - 1] >= s.times[0], 'the time moves forward');

  // services: JSON in, JSON out; failures name the status and the reason
  const robots = await s.call('/simulation/list_robots', {});
  check(robots.ok && robots.encoding === 'json', 'list_robots answers: ' + JSON.stringify(robots));
  check(JSON.parse(robots.data).includes('robot'), 'list_robots names the robot: ' + robots.data);
  const set = s.service('/time/set_time_scale');
  const request = JSON.parse(set.request.schema);
  check(request.required && request.required.includes('value'), 'the request schema requires value');
  const bad = await s.call('/time/set_time_scale', { value: 'fast' });
  check(!bad.ok && /FAILED/.test(bad.message), 'a wrong argument fails with the reason: ' + JSON.stringify(bad));
  const unknown = await s.callId(999999, {});
  check(!unknown.ok && /no service 999999/.test(unknown.message), 'an unknown service id fails: ' + JSON.stringify(unknown));
  const notJson = await s.call('/simulation/list_robots', '{"a":');
  check(!notJson.ok && /not JSON/.test(notJson.message), 'a request that is not JSON fails: ' + JSON.stringify(notJson));
  const cbor = await s.call('/simulation/list_robots', '{}', 'cbor');
  check(!cbor.ok && /encoding/.test(cbor.message), 'another encoding fails: ' + JSON.stringify(cbor));
  // a long call is answered when it ends
  const started = Date.now();
  const slept = await s.call('/time/sleep', { time: 0.3 });
  check(slept.ok && Date.now() - started >= 250, 'time.sleep answers after its simulated time: ' + JSON.stringify(slept));

  // bad input: a status each, and the connection goes on
  let st = await s.statusAfter(() => s.ws.send('{"op": "subscribe", "subscriptions": [{"id": 1'), 'text that is not JSON');
  check(st.level === 2 && /not JSON/.test(st.message), 'not JSON: ' + st.message);
  st = await s.statusAfter(() => s.ws.send('{"op": "fetchAsset", "uri": "package://x", "requestId": 1}'), 'an op not served');
  check(st.level === 2 && /fetchAsset/.test(st.message), 'an op not served: ' + st.message);
  st = await s.statusAfter(() => s.client.subscribe(987654), 'a subscription to no channel');
  check(st.level === 2 && /no channel 987654/.test(st.message) && /\/robot\/pose/.test(st.message), 'no such channel: ' + st.message);
  st = await s.statusAfter(() => s.ws.send(`{"op": "subscribe", "subscriptions": [{"id": ${sub}, "channelId": ${pose.id}}]}`), 'a reused subscription id');
  check(st.level === 2 && /in use/.test(st.message), 'a reused subscription id: ' + st.message);
  st = await s.statusAfter(() => s.ws.send(Buffer.from([9, 1, 2, 3])), 'a bad binary opcode');
  check(st.level === 2 && /opcode 9/.test(st.message), 'a bad binary opcode: ' + st.message);
  st = await s.statusAfter(() => s.ws.send(Buffer.from([2, 1, 0])), 'a short service call');
  check(st.level === 2 && /service call request of 3 bytes/.test(st.message), 'a short service call: ' + st.message);
  const again = await s.call('/simulation/list_robots', {});
  check(again.ok, 'the connection still serves after bad input');

  // unsubscribe: no more samples on it
  s.client.unsubscribe(sub);
  await new Promise((r) => setTimeout(r, 300));
  const count = s.messages.get(sub).length;
  await new Promise((r) => setTimeout(r, 400));
  check(s.messages.get(sub).length === count, 'no samples after unsubscribe');
  check(!s.error, 'the client saw no protocol error: ' + (s.error && s.error.message));
  return s;
}

// A body spawned at run time: the scene is sent again (the earlier one deleted first), the
// transforms name the new body.
async function sceneFollowsTheModel(s) {
  const scene = s.client.subscribe(s.channel('/scene').id);
  const tf = s.client.subscribe(s.channel('/tf').id);
  await s.until(() => (s.messages.get(scene) || []).length >= 1, 'the scene');
  const spawned = await s.call('/simulation/spawn_entity', {
    name: 'crate', mjcf: "<mujoco><worldbody><body><freejoint/><geom type='box' size='.2 .2 .2'/></body></worldbody></mujoco>",
    pose: [1.5, -1, 0.5] });
  check(spawned.ok, 'spawn_entity: ' + JSON.stringify(spawned));
  await s.until(() => s.messages.get(scene).length >= 2, 'the scene of the new model');
  const update = JSON.parse(s.messages.get(scene)[1].data);
  check(update.deletions[0].type === 1 && update.entities.some((e) => e.id === 'body/crate'),
        'the new scene draws the crate: ' + JSON.stringify(update.entities.map((e) => e.id)));
  await s.until(() => s.messages.get(tf).some((m) => JSON.parse(m.data).transforms.some((t) => t.child_frame_id === 'crate')),
                'a transform of the crate');
  s.client.unsubscribe(scene);
  s.client.unsubscribe(tf);
}

// Client publishing: a channel on an input stream's topic takes its commands (the robot drives
// off), Foxglove Teleop's geometry_msgs/Twist too; a topic with no input stream, another
// encoding, a message that is not an object: a status each.
async function publishingDrives(s) {
  check(s.info.capabilities.includes('clientPublish'), 'capability clientPublish');
  const pose = s.client.subscribe(s.channel('/robot/pose').id);
  await s.until(() => (s.messages.get(pose) || []).length >= 1, 'a pose before driving');
  const x0 = JSON.parse(s.messages.get(pose).at(-1).data).x;
  const motion = s.client.advertise({ topic: '/robot/motion', encoding: 'json', schemaName: 'simgate.velocity' });
  const twist = s.client.advertise({ topic: '/robot/motion', encoding: 'json', schemaName: 'geometry_msgs/Twist' });
  const send = (channel, object) => s.client.sendMessage(channel, new TextEncoder().encode(JSON.stringify(object)));
  for (let i = 0; i < 5; i++) { send(motion, { v: 1.0, w: 0 }); await new Promise((r) => setTimeout(r, 100)); }
  await s.until(() => JSON.parse(s.messages.get(pose).at(-1).data).x > x0 + 0.1, 'the robot driving forward', 15000);
  const x1 = JSON.parse(s.messages.get(pose).at(-1).data).x;
  for (let i = 0; i < 5; i++) { send(twist, { linear: { x: -1.0, y: 0, z: 0 }, angular: { x: 0, y: 0, z: 0 } }); await new Promise((r) => setTimeout(r, 100)); }
  await s.until(() => JSON.parse(s.messages.get(pose).at(-1).data).x < x1 - 0.05, 'the robot backing up on a Twist', 15000);
  send(motion, { v: 0, w: 0 });

  let st = await s.statusAfter(() => s.client.advertise({ topic: '/robot/nothing', encoding: 'json', schemaName: 'x' }), 'a topic with no input stream');
  check(st.level === 2 && /no input stream at '\/robot\/nothing'/.test(st.message) && /\/robot\/motion \{v, w\}/.test(st.message), 'no input stream: ' + st.message);
  st = await s.statusAfter(() => s.client.advertise({ topic: '/robot/motion', encoding: 'cbor', schemaName: 'x' }), 'another encoding');
  check(st.level === 2 && /takes json/.test(st.message), 'another encoding: ' + st.message);
  st = await s.statusAfter(() => s.client.sendMessage(motion, new TextEncoder().encode('[1, 2]')), 'a command that is not an object');
  check(st.level === 2 && /not a JSON object/.test(st.message), 'not an object: ' + st.message);
  st = await s.statusAfter(() => s.client.sendMessage(4242, new TextEncoder().encode('{}')), 'a channel not advertised');
  check(st.level === 2 && /not advertised/.test(st.message), 'a channel not advertised: ' + st.message);
  s.client.unadvertise(motion);
  s.client.unadvertise(twist);
  s.client.unsubscribe(pose);
}

// Parameters: the components' properties, read, set (the setter's answer carries its id),
// and a subscriber told of the change; a parameter that does not exist: a status.
async function parameters(setter, watcher) {
  for (const cap of ['parameters', 'parametersSubscribe'])
    check(setter.info.capabilities.includes(cap), 'capability ' + cap);
  const name = '/robot/waypoint/max_angular_speed';
  setter.client.getParameters([], 'all');
  await setter.until(() => setter.parameterValues.some((m) => m.id === 'all'), 'getParameters');
  const all = setter.parameterValues.find((m) => m.id === 'all').parameters;
  const speed = all.find((p) => p.name === name);
  check(speed && speed.value === 1.5, `${name} is 1.5: ` + JSON.stringify(all.map((p) => p.name)));
  check(all.some((p) => p.name === '/robot/wheel_radius'), 'the robot\'s own properties too');

  watcher.client.subscribeParameterUpdates([name]);
  await watcher.until(() => watcher.parameterValues.some((m) => m.parameters.some((p) => p.name === name && p.value === 1.5)),
                      'the subscriber gets the value');
  setter.client.setParameters([{ name, value: 0.75 }], 'set1');
  await setter.until(() => setter.parameterValues.some((m) => m.id === 'set1'), 'setParameters answered');
  const answer = setter.parameterValues.find((m) => m.id === 'set1').parameters;
  check(answer.length === 1 && answer[0].name === name && answer[0].value === 0.75, 'the set value: ' + JSON.stringify(answer));
  await watcher.until(() => watcher.parameterValues.some((m) => m.parameters.some((p) => p.name === name && p.value === 0.75)),
                      'the subscriber told of the change', 15000);
  let st = await setter.statusAfter(() => setter.client.setParameters([{ name: '/robot/waypoint/nope', value: 1 }]), 'an unknown property');
  check(st.level === 2 && /nope/.test(st.message), 'an unknown property: ' + st.message);
  st = await setter.statusAfter(() => setter.client.setParameters([{ name: '/nowhere/x', value: 1 }]), 'an unknown component');
  check(st.level === 2 && /no parameter '\/nowhere\/x'/.test(st.message), 'an unknown component: ' + st.message);
  setter.client.setParameters([{ name, value: 1.5 }]);
  watcher.client.unsubscribeParameterUpdates([]);
}

// Playback control (capability playbackControl) on a raw connection: pause, a seek back to
// an automatic snapshot (the simulated time restored), a faster speed, play; a seek forward
// refused with a status. `s` (a FoxgloveClient session) checks the simulation's own state.
async function playback(url, s) {
  const p = new PlaybackConnection(url);
  await p.until(() => p.info, 'serverInfo on a raw connection');
  const { info, statuses } = p;
  check(info.capabilities.includes('playbackControl'), 'capability playbackControl: ' + info.capabilities);
  check(typeof info.dataStartTime.sec === 'number' && typeof info.dataEndTime.nsec === 'number',
        'serverInfo gives the playback range: ' + JSON.stringify([info.dataStartTime, info.dataEndTime]));
  const simulation = async () => JSON.parse((await s.call('/simulation/get_simulation_state', {})).data);
  await sleep(1200);  // a few automatic snapshots (rewind_interval_s 0.2)

  p.request(false, 1, undefined, 'pause');
  const paused = await p.answer('pause');
  check(paused.status === 1 && !paused.didSeek && paused.speed === 1, 'paused: ' + JSON.stringify(paused, (k, v) => typeof v === 'bigint' ? String(v) : v));
  let state = await simulation();
  check(state.state === 'paused', 'the simulation is paused: ' + state.state);

  const sought = paused.ns - 500000000n;  // half a second back
  p.request(false, 1, sought, 'seek');
  const seek = await p.answer('seek');
  check(seek.didSeek && seek.status === 1, 'the seek is answered as one');
  check(seek.ns <= sought && seek.ns >= sought - 400000000n,
        `restored at the snapshot at or before the time sought (${seek.ns} for ${sought})`);
  state = await simulation();
  check(Math.abs(state.sim_time - Number(seek.ns) / 1e9) < 1e-6, `the simulated time is the one restored (${state.sim_time})`);
  check(state.state === 'paused', 'still paused after the seek');

  p.request(true, 2, undefined, 'fast');
  const fast = await p.answer('fast');
  check(fast.status === 0 && fast.speed === 2, 'playing at 2x');
  state = await simulation();
  check(state.state !== 'paused' && state.target_realtime_factor === 2, 'the time scale is 2: ' + JSON.stringify([state.state, state.target_realtime_factor]));

  const before = statuses.length;
  p.request(true, 1, seek.ns + 3600000000000n, 'forward');
  await p.answer('forward');
  check(statuses.slice(before).some((x) => /not reached/.test(x.message)), 'a seek forward is refused: ' + JSON.stringify(statuses.slice(before)));
  state = await simulation();
  check(state.target_realtime_factor === 1 && state.state !== 'paused', 'back to real time, playing');
  p.close();
}

// A world made at run time (simulation create_world, docs/worlds.md): its services are
// advertised under /w<k>/, called there, and unadvertised when it is deleted; its channels
// too, its /w<k>/tf and /w<k>/scene made of its own scene (not world 0's, where a crate was
// spawned), their frames "w<k>/..."; a robot teleported in it moves there only.
async function worlds(s) {
  const made = await s.call('/simulation/create_world', {});
  check(made.ok, 'create_world answers: ' + JSON.stringify(made));
  const world = JSON.parse(made.data);
  const prefix = `/${world.name}`;
  await s.until(() => s.service(`${prefix}/robot/motion/set_speed`) && s.service(`${prefix}/simulation/list_robots`),
                `the services of ${world.name} advertised`);
  const robots = await s.call(`${prefix}/simulation/list_robots`, {});
  check(robots.ok && JSON.parse(robots.data).includes('robot'), `${prefix}/simulation/list_robots: ` + JSON.stringify(robots));

  const topics = ['/robot/pose', '/tf', '/scene'];
  await s.until(() => topics.every((t) => s.channel(prefix + t)), `the channels of ${world.name} advertised`);
  const moved = await s.call(`${prefix}/robot/teleport/translate`, { x: 0, y: 3 });
  check(moved.ok, `${prefix}/robot/teleport/translate: ` + JSON.stringify(moved));
  const sub = {};  // world 1's channels and world 0's
  for (const t of [...topics.map((t) => prefix + t), '/robot/pose', '/tf'])
    sub[t] = s.client.subscribe(s.channel(t).id);
  const last = (topic) => JSON.parse(s.messages.get(sub[topic]).at(-1).data);
  const has = (topic) => (s.messages.get(sub[topic]) || []).length > 0;
  const robotIn = (tf, frame) => tf.transforms.find((t) => t.child_frame_id === frame);
  await s.until(() => has(`${prefix}/robot/pose`) && last(`${prefix}/robot/pose`).y > 2.5,
                `${prefix}/robot/pose where the robot was teleported`);
  await s.until(() => has(`${prefix}/tf`) && robotIn(last(`${prefix}/tf`), `${world.name}/robot`) &&
                      robotIn(last(`${prefix}/tf`), `${world.name}/robot`).translation.y > 2.5,
                `${prefix}/tf: ${world.name}/world -> ${world.name}/robot where it was teleported`);
  const tf = last(`${prefix}/tf`);
  check(tf.transforms.every((t) => t.parent_frame_id.startsWith(world.name + '/') && t.child_frame_id.startsWith(world.name + '/')),
        `${prefix}/tf: every frame is ${world.name}'s: ` + JSON.stringify(tf.transforms.map((t) => [t.parent_frame_id, t.child_frame_id])));
  check(robotIn(tf, `${world.name}/robot`).parent_frame_id === `${world.name}/world`, `${prefix}/tf: the robot hangs from ${world.name}/world`);
  // world 0 did not move
  await s.until(() => has('/robot/pose') && has('/tf'), 'world 0\'s pose and /tf');
  check(Math.abs(last('/robot/pose').y) < 1, 'world 0\'s robot stayed: ' + JSON.stringify(last('/robot/pose')));
  check(Math.abs(robotIn(last('/tf'), 'robot').translation.y) < 1, '/tf: world 0\'s robot stayed');
  // its scene: its bodies on its frames, not the crate spawned in world 0
  await s.until(() => has(`${prefix}/scene`), `${prefix}/scene`);
  const scene = last(`${prefix}/scene`);
  check(scene.entities.some((e) => e.frame_id === `${world.name}/robot`) &&
        scene.entities.every((e) => e.frame_id.startsWith(world.name + '/') && e.frame_id !== `${world.name}/crate`),
        `${prefix}/scene: ${world.name}'s bodies: ` + JSON.stringify(scene.entities.map((e) => [e.id, e.frame_id])));
  for (const id of Object.values(sub)) s.client.unsubscribe(id);

  const gone = await s.call('/simulation/delete_world', { world: world.world });
  check(gone.ok, 'delete_world answers: ' + JSON.stringify(gone));
  await s.until(() => ![...s.services.values()].some((x) => x.name.startsWith(prefix + '/')) &&
                      ![...s.channels.values()].some((c) => c.topic.startsWith(prefix + '/')),
                `the services and channels of ${world.name} unadvertised`);
  check(s.service('/simulation/list_robots') && s.channel('/tf'), 'world 0\'s services and channels stay');
}

runTest(process.argv.slice(2), TOTAL_TIMEOUT_MS, `foxglove transport with @foxglove/ws-protocol (${SUBPROTOCOLS.join(', ')})`,
        async (url) => {
          await refusedWithout(url);
          const ajv = new Ajv({ strict: false });
          // both subprotocols, two clients at once: one client's mistakes never reach the other
          const sessions = await Promise.all(SUBPROTOCOLS.map((p) => session(url, p, ajv)));
          await sceneFollowsTheModel(sessions[0]);
          await publishingDrives(sessions[1]);
          await parameters(sessions[0], sessions[1]);
          await worlds(sessions[1]);
          await playback(url, sessions[0]);
          for (const s of sessions) s.close();
        });
