// The mcp transport against the Model Context Protocol's own client (@modelcontextprotocol/sdk,
// nobody on the team wrote it) over streamable HTTP: the gateway (argv: simgate run
// gateway_mcp.json ...) serves the rover room; the client lists the tools (a denied service
// absent), calls simulation_list_robots, a long goto with progress then cancels it, takes a
// camera's image and a snapshot (PNG), makes a world and deletes it (its tools come and go),
// and is refused with a wrong token and with none.
// Exit 77 (skipped) without the SDK (scripts/test installs it).
'use strict';
const path = require('path');
const { spawn } = require('child_process');

let Client, StreamableHTTPClientTransport, ResourceUpdatedNotificationSchema, ToolListChangedNotificationSchema;
try {
  ({ Client } = require(path.join(__dirname, 'node_modules/@modelcontextprotocol/sdk/dist/cjs/client/index.js')));
  ({ StreamableHTTPClientTransport } = require(path.join(__dirname, 'node_modules/@modelcontextprotocol/sdk/dist/cjs/client/streamableHttp.js')));
  ({ ResourceUpdatedNotificationSchema, ToolListChangedNotificationSchema } =
    require(path.join(__dirname, 'node_modules/@modelcontextprotocol/sdk/dist/cjs/types.js')));
} catch (e) {
  console.log('SKIP: @modelcontextprotocol/sdk is not installed (scripts/test installs it): ' + e.message);
  process.exit(77);
}

const TOKEN = 'mcp-test-token-' + process.pid + '-0123456789abcdef';
const TOTAL_TIMEOUT_MS = 120000;

function check(condition, what) {
  if (!condition) throw new Error('check failed: ' + what);
}
const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));

// The gateway, its endpoint read from its log line.
function startGateway(argv) {
  const child = spawn(argv[0], argv.slice(1), {
    stdio: ['ignore', 'pipe', 'inherit'],
    env: { ...process.env, SIMGATE_MCP_TEST_TOKEN: TOKEN },
  });
  const url = new Promise((resolve, reject) => {
    let out = '';
    child.stdout.on('data', (chunk) => {
      out += chunk.toString();
      const m = out.match(/^mcp: (http:\/\/127\.0\.0\.1:\d+\/mcp)$/m);
      if (m) resolve(m[1]);
    });
    child.on('exit', (code) => reject(new Error(`simgate exited early with code ${code}`)));
  });
  return { child, url };
}

async function connect(url, token) {
  const headers = token === undefined ? {} : { Authorization: 'Bearer ' + token };
  const client = new Client({ name: 'simgate-mcp-test', version: '1.0.0' });
  await client.connect(new StreamableHTTPClientTransport(new URL(url), { requestInit: { headers } }));
  return client;
}

// The PNG's signature, and its IHDR's width and height.
function pngSize(base64) {
  const png = Buffer.from(base64, 'base64');
  check(png.subarray(0, 8).equals(Buffer.from([0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a])),
        'the image content is a PNG');
  return { width: png.readUInt32BE(16), height: png.readUInt32BE(20) };
}

async function tools(client) {
  const { tools } = await client.listTools();
  const names = tools.map((t) => t.name);
  console.log(`tools/list: ${tools.length} tools`);
  check(names.includes('simulation_list_robots'), 'simulation_list_robots is a tool');
  check(names.includes('rover_waypoint_goto'), 'rover_waypoint_goto is a tool');
  check(!names.some((n) => n.startsWith('rover_teleport_')), 'the denied rover.teleport services are no tools: ' + names.filter((n) => n.includes('teleport')));
  const goto = tools.find((t) => t.name === 'rover_waypoint_goto');
  check(goto.title === 'rover.waypoint.goto', 'the title is the service: ' + goto.title);
  check(goto.inputSchema.type === 'object' && goto.inputSchema.properties.x && goto.inputSchema.properties.deadline_ms,
        'goto takes x, y, z and deadline_ms: ' + JSON.stringify(goto.inputSchema));
  check(goto.inputSchema.required.includes('x'), 'x is required');
}

async function listRobots(client) {
  const r = await client.callTool({ name: 'simulation_list_robots', arguments: {} });
  check(!r.isError, 'list_robots succeeds: ' + JSON.stringify(r));
  check(JSON.stringify(r.structuredContent) === JSON.stringify({ result: ['rover'] }), 'the robots: ' + JSON.stringify(r.structuredContent));
  check(r.content[0].type === 'text' && JSON.parse(r.content[0].text)[0] === 'rover', 'the text content is the result');
}

async function badCalls(client) {
  let error;
  try {
    await client.callTool({ name: 'rover_teleport_translate', arguments: { x: 1, y: 0, z: 0 } });
  } catch (e) { error = e; }
  check(error && /Unknown tool/.test(error.message), 'a denied service is an unknown tool: ' + (error && error.message));
  const wrong = await client.callTool({ name: 'rover_waypoint_goto', arguments: { x: 'far', y: 0, z: 0 } });
  check(wrong.isError && /x/.test(wrong.content[0].text), 'a wrong argument is a tool error naming it: ' + JSON.stringify(wrong));
  const missing = await client.callTool({ name: 'rover_waypoint_goto', arguments: {} });
  check(missing.isError, 'missing arguments are a tool error: ' + JSON.stringify(missing));
}

// A goto far away: progress reports, then cancelled; the rover stops.
async function longCallCancelled(client) {
  const controller = new AbortController();
  const reports = [];
  const call = client.callTool({ name: 'rover_waypoint_goto', arguments: { x: 3, y: 0, z: 0 } }, undefined,
                               { signal: controller.signal, onprogress: (p) => reports.push(p), timeout: 60000 });
  const until = Date.now() + 20000;
  while (reports.length < 3 && Date.now() < until) await sleep(20);
  check(reports.length >= 3, `the goto reports progress (${reports.length} reports)`);
  check(JSON.parse(reports[0].message).distance_left > 0, 'a report says the distance left: ' + reports[0].message);
  const status = await client.callTool({ name: 'rover_waypoint_get_status', arguments: {} });
  check(status.structuredContent.result === 'Transit', 'the rover is in transit: ' + JSON.stringify(status.structuredContent));
  controller.abort('enough');
  let error;
  try { await call; } catch (e) { error = e; }
  check(error, 'the cancelled call rejects');
  let after;
  for (let i = 0; i < 100; ++i) {
    after = (await client.callTool({ name: 'rover_waypoint_get_status', arguments: {} })).structuredContent.result;
    if (after !== 'Transit') break;
    await sleep(20);
  }
  check(after !== 'Transit', 'the cancel reached the goto: its status is ' + after);
  console.log(`goto: ${reports.length} progress reports, then cancelled (status ${after})`);
}

async function deadline(client) {
  const started = Date.now();
  const r = await client.callTool({ name: 'rover_waypoint_goto', arguments: { x: -3, y: 0, z: 0, deadline_ms: 300 } });
  check(r.isError && /timeout|deadline|within/i.test(r.content[0].text), 'a goto past its deadline_ms is a tool error: ' + JSON.stringify(r));
  check(Date.now() - started < 10000, 'it ended near its deadline');
}

async function images(client) {
  const image = await client.callTool({ name: 'rover_camera_get_image', arguments: {} });
  check(!image.isError, 'get_image succeeds: ' + JSON.stringify(image).slice(0, 300));
  const content = image.content.find((c) => c.type === 'image');
  check(content && content.mimeType === 'image/png', 'get_image answers image content');
  const size = pngSize(content.data);
  check(size.width === 160 && size.height === 120, 'the camera image is 160x120: ' + JSON.stringify(size));
  check(!JSON.stringify(image.structuredContent).includes(content.data.slice(0, 40)), 'the structured content leaves the image bytes out');
  const snapshot = await client.callTool({ name: 'simulation_get_snapshot', arguments: { width: 64, height: 48 } });
  if (snapshot.isError && /cannot render/.test(snapshot.content[0].text)) {
    console.log('snapshot: no GL here (' + snapshot.content[0].text + ')');
    return;
  }
  const picture = snapshot.content.find((c) => c.type === 'image');
  check(picture, 'get_snapshot answers image content: ' + JSON.stringify(snapshot).slice(0, 300));
  const s = pngSize(picture.data);
  check(s.width === 64 && s.height === 48, 'the snapshot is 64x48: ' + JSON.stringify(s));
}

// The scene and the streams as resources: listed, read (the camera's as a PNG blob), and a
// subscription's notifications/resources/updated on the session's GET stream.
async function resources(client) {
  const { resources } = await client.listResources();
  const uris = resources.map((r) => r.uri);
  console.log('resources/list: ' + uris.join(', '));
  check(uris.includes('simgate://scene') && uris.includes('simgate://streams/rover.pose') &&
        uris.includes('simgate://streams/rover.camera'), 'the scene and the two streams are resources');
  const scene = await client.readResource({ uri: 'simgate://scene' });
  check(scene.contents[0].mimeType === 'application/json' && JSON.parse(scene.contents[0].text),
        'the scene reads as JSON: ' + JSON.stringify(scene).slice(0, 200));
  const pose = await client.readResource({ uri: 'simgate://streams/rover.pose' });
  const sample = JSON.parse(pose.contents[0].text);
  check(typeof sample.time === 'number' && typeof sample.data.x === 'number', 'a pose sample: ' + pose.contents[0].text);
  const camera = await client.readResource({ uri: 'simgate://streams/rover.camera' });
  const blob = camera.contents.find((c) => c.mimeType === 'image/png');
  check(blob, 'the camera\'s sample has its PNG as a blob: ' + JSON.stringify(camera).slice(0, 300));
  const size = pngSize(blob.blob);
  check(size.width === 160 && size.height === 120, 'the camera resource is 160x120: ' + JSON.stringify(size));
  const updates = [];
  client.setNotificationHandler(ResourceUpdatedNotificationSchema, (n) => updates.push(n.params.uri));
  await client.subscribeResource({ uri: 'simgate://streams/rover.pose' });
  const until = Date.now() + 15000;
  while (updates.length < 2 && Date.now() < until) await sleep(20);
  check(updates.length >= 2 && updates.every((u) => u === 'simgate://streams/rover.pose'),
        `notifications/resources/updated for the subscribed pose (${updates.length})`);
  await client.unsubscribeResource({ uri: 'simgate://streams/rover.pose' });
  let missing;
  try { await client.readResource({ uri: 'simgate://streams/nothing' }); } catch (e) { missing = e; }
  check(missing && /Resource not found/.test(missing.message), 'an unknown resource: ' + (missing && missing.message));
  console.log(`resources: read the scene, a pose, a 160x120 camera image; ${updates.length} updates`);
}

// A robot spawned at run time: the session's GET stream says the tools changed, and its
// services are tools; deleted, they are gone.
async function toolsChange(client) {
  let changes = 0;
  client.setNotificationHandler(ToolListChangedNotificationSchema, () => { ++changes; });
  const spawned = await client.callTool({
    name: 'simulation_spawn_entity',
    arguments: {
      name: 'bot', pose: [0, 1.5, 0.3],
      mjcf: "<mujoco><worldbody><body><freejoint/><geom type='box' size='.1 .1 .1' mass='1'/></body></worldbody></mujoco>",
      robot: { type: 'robot', components: [{ name: 'pose', type: 'pose' }] },
    },
  });
  check(!spawned.isError, 'spawn_entity: ' + JSON.stringify(spawned).slice(0, 300));
  const until = Date.now() + 15000;
  while (changes < 1 && Date.now() < until) await sleep(20);
  check(changes >= 1, 'notifications/tools/list_changed after a robot was spawned');
  const names = (await client.listTools()).tools.map((t) => t.name);
  check(names.includes('bot_pose_get_local_data'), 'the spawned robot\'s services are tools');
  const deleted = await client.callTool({ name: 'simulation_delete_entity', arguments: { name: 'bot' } });
  check(!deleted.isError, 'delete_entity: ' + JSON.stringify(deleted).slice(0, 300));
  const after = (await client.listTools()).tools.map((t) => t.name);
  check(!after.includes('bot_pose_get_local_data'), 'deleted, its tools are gone');
  console.log(`tools/list_changed: ${changes} notification(s) for a robot spawned and deleted`);
}

// A world made at run time (simulation create_world, docs/worlds.md): its tools come under the
// w<k>_ prefix, the transport's deny list applying in it too, and go when it is deleted.
async function worldsChange(client) {
  let changes = 0;
  client.setNotificationHandler(ToolListChangedNotificationSchema, () => { ++changes; });
  const made = await client.callTool({ name: 'simulation_create_world', arguments: {} });
  check(!made.isError && made.structuredContent.name === 'w1', 'create_world: ' + JSON.stringify(made).slice(0, 300));
  const until = Date.now() + 15000;
  while (changes < 1 && Date.now() < until) await sleep(20);
  check(changes >= 1, 'notifications/tools/list_changed after a world was made');
  const names = (await client.listTools()).tools.map((t) => t.name);
  check(names.includes('w1_rover_waypoint_goto'), 'the new world\'s services are tools');
  check(!names.some((n) => n.startsWith('w1_rover_teleport_')), 'the deny list applies in the new world');
  const robots = await client.callTool({ name: 'w1_simulation_list_robots', arguments: {} });
  check(JSON.stringify(robots.structuredContent) === JSON.stringify({ result: ['rover'] }),
        'w1_simulation_list_robots: ' + JSON.stringify(robots.structuredContent));
  // its streams are resources under its prefix: its own samples
  const uris = (await client.listResources()).resources.map((r) => r.uri);
  check(uris.includes('simgate://streams/w1/rover.pose'), 'the new world\'s pose stream is a resource: ' + uris);
  const pose = JSON.parse((await client.readResource({ uri: 'simgate://streams/w1/rover.pose' })).contents[0].text);
  const poseOf0 = JSON.parse((await client.readResource({ uri: 'simgate://streams/rover.pose' })).contents[0].text);
  check(typeof pose.data.x === 'number' && pose.time <= poseOf0.time,
        'w1\'s pose is its own (made now, its time not past world 0\'s): ' + JSON.stringify(pose));
  const gone = await client.callTool({ name: 'simulation_delete_world', arguments: { world: 1 } });
  check(!gone.isError, 'delete_world: ' + JSON.stringify(gone).slice(0, 300));
  const after = (await client.listTools()).tools.map((t) => t.name);
  check(!after.some((n) => n.startsWith('w1_')), 'deleted, its tools are gone');
  const urisAfter = (await client.listResources()).resources.map((r) => r.uri);
  check(!urisAfter.some((u) => u.startsWith('simgate://streams/w1/')), 'deleted, its resources are gone');
  console.log('worlds: w1 made, listed as w1_ tools and resources, called, read, deleted');
}

async function refused(url) {
  for (const [token, what] of [['wrong-token-0123456789', 'a wrong token'], [undefined, 'no token']]) {
    let error;
    try { await connect(url, token); } catch (e) { error = e; }
    check(error && /40[13]|wrong token|requires a token/.test(String(error.message)), `${what} is refused: ${error && error.message}`);
  }
}

async function main(argv) {
  const { child, url: urlPromise } = startGateway(argv);
  const overall = setTimeout(() => {
    console.error('FAIL: the test took longer than ' + TOTAL_TIMEOUT_MS + ' ms');
    child.kill('SIGKILL');
    process.exit(1);
  }, TOTAL_TIMEOUT_MS);
  try {
    const url = await urlPromise;
    const client = await connect(url, TOKEN);
    await tools(client);
    await listRobots(client);
    await badCalls(client);
    await longCallCancelled(client);
    await deadline(client);
    await images(client);
    await resources(client);
    await toolsChange(client);
    await worldsChange(client);
    await refused(url);
    await client.close();
    console.log('PASS: an MCP client lists and calls simgate\'s tools');
  } finally {
    clearTimeout(overall);
    child.kill('SIGTERM');
  }
}

main(process.argv.slice(2)).catch((e) => {
  console.error('FAIL: ' + (e && e.stack ? e.stack : e));
  process.exit(1);
});
