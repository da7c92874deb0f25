#!/usr/bin/env node
// A served replay in Foxglove's playback bar (issue #39): the bar spans the recording, and a
// seek goes to the recorded run's state at the time sought, forward or back, bit for bit.
//
//   node foxglove_replay_test.js <simgate> <config> <workdir> [--plugin-path DIR]
// Records <config> (the robot driven over Foxglove's own client, @foxglove/ws-protocol) to
// <workdir>/playback.mcap, then serves it with `simgate replay --serve` and drives the
// playback bar on a raw connection (PlaybackConnection). Exit code: 0 passed, 1 failed, 77
// the npm packages are not installed.
'use strict';

const fs = require('fs');
const path = require('path');
const { check, startGateway, withTimeout, Session, PlaybackConnection, runTest } = require('./session');

const TOTAL_TIMEOUT_MS = 120000;
const RECORDED_S = 6;  // simulated seconds recorded (at 5x real time)

const [simgate, config, workdir, ...rest] = process.argv.slice(2);
const file = path.join(workdir, 'playback.mcap');
const ns = (seconds) => BigInt(Math.round(seconds * 1e9));
const seconds = (t) => t.sec + t.nsec / 1e9;

// `simgate run <config> --record <file>`: the robot turns in a circle for RECORDED_S
// simulated seconds; the file is whole once simgate has stopped.
async function record() {
  fs.mkdirSync(workdir, { recursive: true });
  fs.rmSync(file, { force: true });
  const { child, url } = startGateway([simgate, 'run', config, '--record', file, '--realtime-factor', '5', ...rest]);
  const exited = new Promise((resolve) => child.on('exit', (code) => resolve(code)));
  try {
    const s = new Session(await url, 'foxglove.websocket.v1');
    await s.until(() => s.service('/robot/motion/set_speed'), 'the services of the recorded run');
    const set = await s.call('/robot/motion/set_speed', { v: 0.6, w: 0.5 });
    check(set.ok, 'set_speed in the recorded run: ' + JSON.stringify(set));
    await s.until(() => s.times.some((t) => t >= ns(RECORDED_S)), `${RECORDED_S} s simulated`, 30000);
    s.close();
  } finally {
    child.kill('SIGINT');
  }
  const code = await withTimeout(exited, 'simgate run stopping');
  check(code === 0, `simgate run --record exits 0 (got ${code})`);
}

(async () => {
  await record();
  runTest([simgate, 'replay', file, '--serve', ...rest], TOTAL_TIMEOUT_MS,
          'a served replay seeks in its recording from Foxglove\'s playback bar', async (url) => {
    const s = new Session(url, 'foxglove.websocket.v1');
    await s.until(() => s.service('/simulation/get_replay_status'), 'the served replay\'s services');
    const call = async (name, request = {}) => {
      const r = await s.call(name, request);
      check(r.ok, `${name}: ${JSON.stringify(r)}`);
      return JSON.parse(r.data);
    };
    const replay = await call('/simulation/get_replay_status');
    check(replay.end_time >= RECORDED_S && replay.start_time === 0 && replay.departed_at === null,
          'the replay\'s status: ' + JSON.stringify(replay));

    const p = new PlaybackConnection(url);
    await p.until(() => p.info, 'serverInfo');
    check(p.info.capabilities.includes('playbackControl'), 'capability playbackControl');
    check(seconds(p.info.dataStartTime) === replay.start_time &&
          Math.abs(seconds(p.info.dataEndTime) - replay.end_time) < 1e-6,
          'the bar spans the recording: ' + JSON.stringify([p.info.dataStartTime, p.info.dataEndTime, replay]));

    // paused, a seek forward (the replay takes the steps as fast as it can)
    const pose = async () => JSON.stringify(await call('/robot/pose/get_local_data'));
    const at = async (id, play, time) => {
      p.request(play, 1, ns(time), id);
      const state = await p.answer(id, 30000);
      check(state.didSeek && state.status === (play ? 0 : 1),
            `${id}: answered as a seek, ${play ? 'playing' : 'paused'}: status ${state.status}`);
      check(Math.abs(Number(state.ns) / 1e9 - time) < 0.0011, `${id}: at ${time} s (told ${state.ns} ns)`);
      return state;
    };
    await at('forward', false, 4.5);
    let status = await call('/simulation/get_replay_status');
    check(status.step === 2250 && Math.abs(status.sim_time - 4.5) < 1e-9, 'at step 2250: ' + JSON.stringify(status));
    const there = await pose();

    // back: the recording's start put back, then replayed to the time sought
    await at('back', false, 1.0);
    status = await call('/simulation/get_replay_status');
    check(status.step === 500, 'back at step 500: ' + JSON.stringify(status));
    check((await pose()) !== there, 'the robot is elsewhere at 1 s');
    await at('again', false, 4.5);
    check((await pose()) === there, 'at 4.5 s again, the robot is where it was, bit for bit');
    status = await call('/simulation/get_replay_status');
    check(status.departed_at === null, 'the seeks never departed from the recording: ' + JSON.stringify(status));
    // the recorded run's automatic snapshots were replayed (the replay's own transport takes
    // none); those of the pass before the seek back were dropped with it
    const states = (await call('/simulation/list_states')).map((x) => x.sim_time);
    check(states.length > 0 && new Set(states).size === states.length && Math.max(...states) <= 4.5,
          'the snapshots of this pass, each once: ' + JSON.stringify(states));

    // past the end: the last state, the playback ended
    p.request(false, 1, ns(replay.end_time + 100), 'past');
    const past = await p.answer('past', 30000);
    check(past.status === 3 && Math.abs(Number(past.ns) / 1e9 - replay.end_time) < 1e-6,
          `past the end: ended at the recording's end (status ${past.status}, ${past.ns} ns)`);
    // playing from 5.5 s, it goes on at the recording's pace
    await at('play', true, 5.5);
    await s.until(() => s.times.length > 0 && s.times[s.times.length - 1] > ns(5.6), 'time going on after play');
    p.close();
    s.close();
  });
})().catch((e) => {
  console.error('FAIL: ' + (e && e.stack ? e.stack : e));
  process.exit(1);
});
