// The state header: simulation get_simulation_state (else time statistics) at 2 Hz, pause /
// play / step (docs/web.md).
import { $, errorText, exposed, fmt, isUnknownMethod } from './util.js';

const STATE_PERIOD_MS = 500;        // the state header's refresh

// A measured real-time factor, or '–' when none is known (0: paused, or playing for less
// than the server's measuring window since play).
const fmtFactor = (f) => (typeof f === 'number' && f > 0 ? f.toFixed(2) : '–');

export function setupState(rpc) {
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
