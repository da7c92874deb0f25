#!/usr/bin/env node
// The web app in a real browser (docs/web.md): Debian's headless Chromium (/usr/bin/chromium)
// driven by npm's playwright-core, against `simgate run` on the demo deployment (its websocket
// transport on an ephemeral port of 127.0.0.1, serving the build tree's web app).
// Checks: the page loads without errors and lists the services; `robot.waypoint goto`
// called from its form moves the robot (the position the page shows changes) and
// succeeds; a second goto cancelled from the page ends PREEMPTED; pause, step and play
// drive the simulation, and the real-time factor shown is never "0.00" (a number once
// measured, else "–"); the 3D view has drawn the scene, and draws a height field spawned
// from the page's console; a robot another client spawns shows its services in the console
// and its camera in the camera panel; a camera on the robot shows its image, then live from its stream;
// the arrow keys on the drive pad move the robot (rpc.publish to robot.motion). Then, against a second `simgate run`
// whose websocket transport wants a token (`auth`), the page asks for it before anything,
// asks again after a wrong one, and works once given the right one. Keeps a screenshot:
//   node webapp_test.js SIMGATE SOURCE_DIR ARTIFACTS_DIR
// Exit 77 (skipped) without Chromium or without node_modules (scripts/test installs them).
'use strict';

const fs = require('fs');
const os = require('os');
const path = require('path');
const { spawn } = require('child_process');

const CHROMIUM = process.env.SIMGATE_CHROMIUM || '/usr/bin/chromium';
const WAIT_MS = 60000;          // the longest single wait
const TEST_DEADLINE_MS = 170000; // the whole test (ctest's TIMEOUT is 180 s)

const [simgate, sourceDir, artifactsDir] = process.argv.slice(2);
if (!simgate || !sourceDir || !artifactsDir) {
  console.error('usage: webapp_test.js SIMGATE SOURCE_DIR ARTIFACTS_DIR');
  process.exit(2);
}
if (!fs.existsSync(CHROMIUM)) {
  console.log(`SKIP: no Chromium at ${CHROMIUM} (Debian: apt-get install chromium)`);
  process.exit(77);
}
let chromium;
try {
  ({ chromium } = require('playwright-core'));
} catch (e) {
  console.log('SKIP: playwright-core is not installed in tests/web (scripts/test installs it: npm install)');
  process.exit(77);
}

const deadline = setTimeout(() => {
  console.error(`FAIL: the test did not finish within ${TEST_DEADLINE_MS / 1000} s`);
  cleanup().finally(() => process.exit(1));
}, TEST_DEADLINE_MS);

let gateway = null;
let browser = null;
const workdir = fs.mkdtempSync(path.join(os.tmpdir(), 'simgate-web-'));

async function cleanup() {
  if (browser) await browser.close().catch(() => {});
  browser = null;
  let code = null;
  if (gateway && gateway.exitCode === null) {
    const exited = new Promise((resolve) => gateway.once('exit', (c) => resolve(c)));
    gateway.kill('SIGTERM');
    const timer = new Promise((resolve) => setTimeout(() => resolve('timeout'), 20000));
    code = await Promise.race([exited, timer]);
    if (code === 'timeout') gateway.kill('SIGKILL');
  } else if (gateway) {
    code = gateway.exitCode;
  }
  gateway = null;
  return code;
}

function check(condition, message) {
  if (!condition) throw new Error(message);
  console.log(`ok: ${message}`);
}

const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));

// `simgate run` on the demo deployment, every transport on port 0, `edit` applied to the
// config and `env` added to the environment; its websocket's port.
async function startGateway(edit = () => {}, env = {}) {
  const config = JSON.parse(fs.readFileSync(path.join(sourceDir, 'config', 'demo.json'), 'utf8'));
  config.scene.mjcf = path.join(sourceDir, 'config', 'scenes', 'demo.xml');
  config.log_level = 'warning';
  for (const t of Object.values(config.transports)) {
    t.options = t.options || {};
    t.options.port = 0;
    if ('stream_port' in t.options) t.options.stream_port = 0;
  }
  if (!config.transports.websocket) throw new Error('config/demo.json has no websocket transport');
  edit(config);
  const configPath = path.join(workdir, 'web-test.json');
  fs.writeFileSync(configPath, JSON.stringify(config, null, 2));
  const endpointsPath = path.join(workdir, 'endpoints.json');
  const log = fs.openSync(path.join(workdir, 'gateway.log'), 'w');
  fs.rmSync(endpointsPath, { force: true });
  gateway = spawn(simgate, ['run', configPath, '--endpoints-file', endpointsPath],
                  { stdio: ['ignore', log, log], env: { ...process.env, ...env } });
  const start = Date.now();
  while (!fs.existsSync(endpointsPath)) {
    if (gateway.exitCode !== null || Date.now() - start > WAIT_MS)
      throw new Error('simgate did not start:\n' + fs.readFileSync(path.join(workdir, 'gateway.log'), 'utf8'));
    await sleep(20);  // polling for a file the child writes; bounded by WAIT_MS
  }
  // written whole, then renamed into place: {"websocket": ["ws://127.0.0.1:PORT/"], ...}
  const endpoints = JSON.parse(fs.readFileSync(endpointsPath, 'utf8'));
  const url = endpoints.websocket && endpoints.websocket[0];
  if (!url) throw new Error(`no websocket endpoint in ${JSON.stringify(endpoints)}`);
  return Number(url.split(':')[2].replace('/', ''));
}

// A new page of the browser, every problem it reports collected in `problems`, talking to
// the server on `port` only.
async function openPage(port, problems) {
  const page = await browser.newPage({ viewport: { width: 1400, height: 900 } });
  page.on('pageerror', (e) => problems.push(`page error: ${e.message}`));
  page.on('console', (m) => { if (m.type() === 'error') problems.push(`console error: ${m.text()}`); });
  page.on('requestfailed', (r) => problems.push(`request failed: ${r.url()} ${r.failure()?.errorText}`));
  // the page talks to its own server only
  await page.route('**/*', (route) => {
    const u = new URL(route.request().url());
    if (u.hostname === '127.0.0.1' && Number(u.port) === port) return route.continue();
    problems.push(`request off the server: ${u.href}`);
    return route.abort();
  });
  return page;
}

// What the page shows of `component`'s camera: its image's size, how many colours it has and
// its brightest red level (read back through a canvas).
function imageShown(page, component) {
  return page.evaluate((name) => {
    const img = document.querySelector(`figure.camera[data-component="${name}"] img`);
    const copy = document.createElement('canvas');
    copy.width = img.naturalWidth;
    copy.height = img.naturalHeight;
    const ctx = copy.getContext('2d');
    ctx.drawImage(img, 0, 0);
    const data = ctx.getImageData(0, 0, copy.width, copy.height).data;
    const colours = new Set();
    let brightest = 0;
    for (let i = 0; i < data.length; i += 4) {
      colours.add((data[i] << 16) | (data[i + 1] << 8) | data[i + 2]);
      brightest = Math.max(brightest, data[i]);
    }
    return { width: img.naturalWidth, height: img.naturalHeight, colours: colours.size, brightest };
  }, component);
}

// One JSON-RPC call on a connection of its own (another client than the page's app), opened
// from the page's browser: its answer.
function rpcCall(page, port, method, params) {
  return page.evaluate(([url, method, params]) => new Promise((resolve, reject) => {
    const ws = new WebSocket(url);
    ws.onopen = () => ws.send(JSON.stringify({ jsonrpc: '2.0', id: 1, method, params }));
    ws.onmessage = (e) => {
      const m = JSON.parse(e.data);
      if (m.id === 1) { ws.close(); resolve(m); }
    };
    ws.onerror = () => reject(new Error(`websocket ${url}: error`));
  }), [`ws://127.0.0.1:${port}/`, method, params]);
}

// The demo robot with a camera on its body (looking forward), streamed to the page's transport;
// the page's transport serves a robot spawned as "rover".
function withCamera(config) {
  config.robots.find((r) => r.name === 'robot').components.push(
    { name: 'camera', type: 'video_camera', frequency: 5, options: { cam_width: 160, cam_height: 120 } },
    { name: 'depth', type: 'depth_camera', options: { cam_width: 80, cam_height: 60 } });
  config.streams['robot.camera'] = { transports: ['websocket'] };
  // a robot spawned at run time as "rover" is served to the page too (the mapping of its names)
  config.services['rover.*'] = ['socket', 'websocket'];
}

async function main() {
  const port = await startGateway(withCamera);
  const pageUrl = `http://127.0.0.1:${port}/`;
  console.log(`simgate serves ${pageUrl}`);

  browser = await chromium.launch({
    executablePath: CHROMIUM,
    headless: true,
    args: [
      '--no-sandbox',                        // as root in a container
      '--use-angle=swiftshader',             // WebGL without a GPU (software rendering)
      '--enable-unsafe-swiftshader',
      '--disable-background-networking',     // no traffic but the page's, to 127.0.0.1
      '--disable-component-update',
      '--no-first-run',
      '--disable-sync',
      '--disable-default-apps',
    ],
  });
  const problems = [];
  const page = await openPage(port, problems);

  const response = await page.goto(pageUrl, { timeout: WAIT_MS });
  check(response.status() === 200 && (await page.title()) === 'simgate', `the page loads from ${pageUrl}`);
  check(await page.locator('#login').isHidden(), 'no token asked for (the transport has no auth)');

  // the services, from rpc.discover
  await page.waitForFunction(() => window.simgate?.connected && window.simgate.services.length > 0, null,
    { timeout: WAIT_MS });
  const services = await page.evaluate(() => window.simgate.services);
  check(services.includes('robot.waypoint.goto'), `the page lists the services (${services.length}, robot.waypoint.goto among them)`);
  check(!services.includes('simulation.quit'), 'simulation.quit is denied, so not listed');
  const goto = page.locator('form[data-method="robot.waypoint.goto"]');
  check(await goto.isVisible(), 'robot.waypoint.goto has a form');

  // the state header
  await page.waitForFunction(() => /\d/.test(document.getElementById('state-time').textContent), null, { timeout: WAIT_MS });
  check(true, `the header shows the sim time: ${await page.textContent('#state-time')}`);
  // the page's own WebSocket is one of the clients get_simulation_state counts
  await page.waitForFunction(() => Number(document.getElementById('state-clients').textContent) >= 1, null,
                             { timeout: WAIT_MS });
  check(true, `the header counts the clients: ${await page.textContent('#state-clients')}`);

  // the robot's position as the page shows it
  const robotX = async () => Number(await page.textContent('#bodies tr[data-body="robot"] td.x'));
  await page.waitForSelector('#bodies tr[data-body="robot"]', { timeout: WAIT_MS });
  const x0 = await robotX();
  console.log(`robot at x = ${x0}`);

  // goto (2, 0, 0): the robot moves, the call succeeds
  await goto.locator('input[data-param="x"]').fill('2');
  await goto.locator('input[data-param="y"]').fill('0');
  await goto.locator('input[data-param="z"]').fill('0');
  await goto.locator('button.call-button').click();
  const first = page.locator('#calls li.call').first();
  await page.waitForFunction((x) => {
    const cell = document.querySelector('#bodies tr[data-body="robot"] td.x');
    return cell && Math.abs(Number(cell.textContent) - x) > 0.1;
  }, x0, { timeout: WAIT_MS });
  check(true, `the robot's position shown changes (x ${x0} -> ${await robotX()})`);
  await page.waitForFunction(() => document.querySelector('#calls li.call')?.dataset.status !== 'RUNNING', null,
    { timeout: WAIT_MS });
  const firstStatus = await first.getAttribute('data-status');
  check(firstStatus === 'SUCCESS', `goto (2, 0, 0) ends ${firstStatus}: ${await first.locator('.reply').textContent()}`);
  check((await first.locator('.progress').textContent()).includes('distance_left'), 'progress reports were shown');

  // a second goto, cancelled from the page: PREEMPTED
  await goto.locator('input[data-param="x"]').fill('-4');
  await goto.locator('input[data-param="y"]').fill('3');
  await goto.locator('button.call-button').click();
  const second = page.locator('#calls li.call').first();
  await second.locator('button.cancel').click({ timeout: WAIT_MS });
  await page.waitForFunction(() => document.querySelector('#calls li.call')?.dataset.status !== 'RUNNING', null,
    { timeout: WAIT_MS });
  const secondStatus = await second.getAttribute('data-status');
  check(secondStatus === 'PREEMPTED', `the cancelled goto ends ${secondStatus}: ${await second.locator('.reply').textContent()}`);

  // pause, step, play; every text the real-time factor shows from now on is recorded
  await page.evaluate(() => {
    const rtf = document.getElementById('state-rtf');
    window.rtfTexts = [rtf.textContent];
    new MutationObserver(() => window.rtfTexts.push(rtf.textContent))
      .observe(rtf, { childList: true, characterData: true, subtree: true });
  });
  const state = () => page.textContent('#state-run');
  await page.click('#btn-pause');
  await page.waitForFunction(() => document.getElementById('state-run').textContent === 'paused', null, { timeout: WAIT_MS });
  const pausedAt = await page.textContent('#state-time');
  await page.fill('#step-n', '100');
  await page.click('#btn-step');
  await page.waitForFunction((t) => document.getElementById('state-time').textContent !== t, pausedAt, { timeout: WAIT_MS });
  check(true, `pause then step 100: sim time ${pausedAt} -> ${await page.textContent('#state-time')}`);
  await page.click('#btn-play');
  await page.waitForFunction(() => document.getElementById('state-run').textContent === 'playing', null, { timeout: WAIT_MS });
  check((await state()) === 'playing', 'play resumes');
  // the factor measured after play (the server's window: about a second of playing)
  await page.waitForFunction(() => /^\d/.test(document.getElementById('state-rtf').textContent), null,
                             { timeout: WAIT_MS });
  const rtfTexts = await page.evaluate(() => window.rtfTexts);
  check(rtfTexts.some((t) => t.startsWith('–')), `the real-time factor shows "–" while none is known: ${rtfTexts.join(' | ')}`);
  check(!rtfTexts.some((t) => /^0\.00\b/.test(t)), 'the real-time factor never shows 0.00');

  // the 3D view: meshes in the scene, frames rendered, and pixels that are not the background
  await page.waitForFunction(() => window.simgate.meshes > 0 && window.simgate.frames > 2, null, { timeout: WAIT_MS });
  const drawn = await page.evaluate(() => {
    const canvas = document.querySelector('#view canvas');
    const copy = document.createElement('canvas');
    copy.width = canvas.width;
    copy.height = canvas.height;
    const ctx = copy.getContext('2d');
    ctx.drawImage(canvas, 0, 0);
    const data = ctx.getImageData(0, 0, copy.width, copy.height).data;
    let other = 0;
    for (let i = 0; i < data.length; i += 4)
      if (Math.abs(data[i] - 0xdd) + Math.abs(data[i + 1] - 0xe3) + Math.abs(data[i + 2] - 0xea) > 30) ++other;
    return { other, total: data.length / 4, meshes: window.simgate.meshes, view: window.simgate.view,
             poses: window.simgate.poseSource };
  });
  if (services.includes('simulation.get_scene_geometry'))
    check(drawn.view === 'geometry', `the 3D view draws the model's geoms (get_scene_geometry), not markers`);
  check(drawn.other > drawn.total / 100,
    `the 3D view has drawn the scene (${drawn.meshes} meshes, view '${drawn.view}', poses '${drawn.poses}', ` +
    `${drawn.other} of ${drawn.total} pixels not background)`);

  // the camera: an image on loading (get_image), then live from its stream, then stopped
  const camera = () => page.evaluate(() => window.simgate.cameras['robot.camera']);
  await page.waitForFunction(() => window.simgate.cameras['robot.camera']?.images >= 1, null, { timeout: WAIT_MS });
  const shown = await imageShown(page, 'robot.camera');
  check(shown.width === 160 && shown.height === 120 && shown.colours > 1,
    `the page shows robot.camera's image (${shown.width}x${shown.height}, ${shown.colours} colours)`);
  // a depth image is stretched so that it can be seen: near is light (issue #35 item 11; shown
  // as sent, millimetres in 16 bits were nearly black: the browser keeps their high byte)
  await page.waitForFunction(() => window.simgate.cameras['robot.depth']?.images >= 1, null, { timeout: WAIT_MS });
  const depth = await imageShown(page, 'robot.depth');
  check(depth.width === 80 && depth.brightest > 200 && depth.colours > 16,
    `the page shows robot.depth's image stretched (${depth.colours} greys, brightest ${depth.brightest})`);
  const live = page.locator('figure.camera[data-component="robot.camera"] input[type="checkbox"]');
  check(await live.isEnabled(), 'robot.camera can go live (its stream is on this transport)');
  const before = (await camera()).images;
  await live.check();
  await page.waitForFunction((n) => window.simgate.cameras['robot.camera'].images >= n + 3, before, { timeout: WAIT_MS });
  check((await camera()).live, `live: the stream's images replace each other (${(await camera()).images - before} came)`);
  await live.uncheck();
  await page.waitForFunction(() => !window.simgate.cameras['robot.camera'].live, null, { timeout: WAIT_MS });
  check((await camera()).error === '', 'unsubscribed without an error');

  // the drive pad of robot.motion (the demo carries it on the websocket): ArrowUp held on
  // the pad drives the robot forward through rpc.publish, released it sends a stop
  const pad = page.locator('div.input[data-component="robot.motion"] .drive');
  check(await pad.count() === 1, 'robot.motion (velocity {v, w}) has a drive pad');
  const xBefore = await robotX();
  await pad.focus();
  await page.keyboard.down('ArrowUp');
  await page.waitForFunction((x) => {
    const cell = document.querySelector('#bodies tr[data-body="robot"] td.x');
    return cell && Math.abs(Number(cell.textContent) - x) > 0.1;
  }, xBefore, { timeout: WAIT_MS });
  await page.keyboard.up('ArrowUp');
  await page.waitForFunction(() => window.simgate.inputs['robot.motion'].last?.v === 0, null, { timeout: WAIT_MS });
  const motion = await page.evaluate(() => window.simgate.inputs['robot.motion']);
  check(motion.refused === 0 && motion.published >= 2 && motion.last.w === 0,
    `ArrowUp held on the pad drove the robot (x ${xBefore} -> ${await robotX()}) with ${motion.published} ` +
    `commands, then a stop ${JSON.stringify(motion.last)}`);

  fs.mkdirSync(artifactsDir, { recursive: true });
  const shot = path.join(artifactsDir, 'webapp.png');
  await page.screenshot({ path: shot });
  console.log(`screenshot: ${shot}`);

  // a height field spawned from the page's console: the page reloads the geometry (a new
  // generation) and draws it (its elevations are MuJoCo's zeros without a file)
  const spawn = page.locator('form[data-method="simulation.spawn_entity"]');
  if (await spawn.count()) {
    await page.fill('#service-filter', 'spawn_entity');
    await spawn.locator('input[data-param="name"]').fill('terrain');
    await spawn.locator('input[data-param="mjcf"]').fill(
      '<mujoco><asset><hfield name="bumps" nrow="5" ncol="6" size="1.5 1 0.3 0.05"/></asset>' +
      '<worldbody><body><geom type="hfield" hfield="bumps" rgba="0.4 0.6 0.3 1"/></body></worldbody></mujoco>');
    await spawn.locator('input[data-param="pose"]').fill('[3, 3, 0]');
    await spawn.locator('button.call-button').click();
    await page.waitForFunction(() => document.querySelector('#calls li.call')?.dataset.status !== 'RUNNING', null,
      { timeout: WAIT_MS });
    const spawned = page.locator('#calls li.call').first();
    check((await spawned.getAttribute('data-status')) === 'SUCCESS',
      `spawn_entity of a height field from the page: ${await spawned.locator('.reply').textContent()}`);
    await page.waitForFunction(() => window.simgate.hfields === 1, null, { timeout: WAIT_MS });
    check(true, `the page draws the spawned height field (${await page.evaluate(() => window.simgate.meshes)} meshes)`);

    // a robot spawned with a component (by another client: the page is told by the new
    // model generation): its services appear in the console without a reload
    const other = await rpcCall(page, port, 'simulation.spawn_entity', {
      name: 'rover', mjcf: '<body><freejoint/><geom type="box" size="0.2 0.15 0.1" mass="3"/></body>',
      pose: [-3, 2, 0.2],
      robot: { type: 'robot', components: [{ name: 'pose', type: 'pose' },
        { name: 'camera', type: 'video_camera', options: { cam_width: 32, cam_height: 24 } }] },
    });
    check(other.result?.name === 'rover', `another client spawns a robot with a component: ${JSON.stringify(other)}`);
    await page.waitForFunction(() => window.simgate.services.includes('rover.pose.get_local_data'), null,
      { timeout: WAIT_MS });
    check(await page.locator('details.component[data-component="rover.pose"]').count() === 1,
      'the console lists the spawned robot\'s component');
    await page.waitForFunction(() => window.simgate.cameras['rover.camera']?.images >= 1, null, { timeout: WAIT_MS });
    check(true, 'the camera panel shows the spawned robot\'s camera');
  }

  check(problems.length === 0, `no page error, console error or failed request${problems.length ? ':\n  ' + problems.join('\n  ') : ''}`);
  await page.close();

  // a transport that wants a token: the page asks for it before anything else
  const stopped = await stopGateway();
  check(stopped === 0, `the first simgate exits 0 (${stopped})`);
  await loginTest();
}

async function stopGateway() {
  if (!gateway) return null;
  const exited = gateway.exitCode !== null ? Promise.resolve(gateway.exitCode)
    : new Promise((resolve) => gateway.once('exit', (c) => resolve(c)));
  if (gateway.exitCode === null) gateway.kill('SIGTERM');
  const code = await Promise.race([exited, sleep(20000).then(() => 'timeout')]);
  if (code === 'timeout') gateway.kill('SIGKILL');
  gateway = null;
  return code;
}

async function loginTest() {
  const token = require('crypto').randomBytes(16).toString('hex');
  const port = await startGateway((config) => {
    config.transports.websocket.options.auth = { token_env: 'SIMGATE_WEB_TEST_TOKEN', loopback: true };
  }, { SIMGATE_WEB_TEST_TOKEN: token });
  const problems = [];
  const page = await openPage(port, problems);
  await page.goto(`http://127.0.0.1:${port}/`, { timeout: WAIT_MS });
  await page.waitForSelector('#login', { state: 'visible', timeout: WAIT_MS });
  const before = await page.evaluate(() => ({ ...window.simgate }));
  check(before.services.length === 0 && !before.ready && (await page.textContent('#state-time')) === '–',
    `with auth, the page asks for the token before anything else: "${await page.textContent('#login-message')}"`);
  // a wrong token: the server closes the connection, the next one asks again
  await page.fill('#login-token', 'not-the-token-0123456789');
  await page.click('#login-submit');
  await page.waitForFunction(() => window.simgate.login === 'wrong' &&
                             !document.getElementById('login').hidden, null, { timeout: WAIT_MS });
  check((await page.textContent('#login-message')).includes('Wrong token'), 'a wrong token: asked again, saying so');
  await page.fill('#login-token', token);
  await page.click('#login-submit');
  await page.waitForFunction(() => window.simgate.ready && window.simgate.services.length > 0, null, { timeout: WAIT_MS });
  check(await page.evaluate(() => window.simgate.login === 'done'), 'the right token: logged in, the services listed');
  await page.waitForFunction(() => /\d/.test(document.getElementById('state-time').textContent), null, { timeout: WAIT_MS });
  check(await page.locator('#login').isHidden(), `the header works (${await page.textContent('#state-time')}), the login form is gone`);
  check(problems.length === 0, `no page error, console error or failed request${problems.length ? ':\n  ' + problems.join('\n  ') : ''}`);
}

main().then(async () => {
  const code = await cleanup();
  clearTimeout(deadline);
  if (code !== 0) {
    console.error(`FAIL: simgate exited ${code}:\n` + fs.readFileSync(path.join(workdir, 'gateway.log'), 'utf8'));
    process.exit(1);
  }
  fs.rmSync(workdir, { recursive: true, force: true });
  console.log('PASS');
  process.exit(0);
}, async (e) => {
  console.error(`FAIL: ${e.stack || e}`);
  await cleanup();
  clearTimeout(deadline);
  console.error('simgate log:\n' + fs.readFileSync(path.join(workdir, 'gateway.log'), 'utf8'));
  process.exit(1);
});
