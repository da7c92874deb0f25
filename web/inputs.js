// The input streams (rpc.streams, direction IN): a command box for each (rpc.publish), and a
// drive pad for a velocity stream {v, w} (arrow keys or buttons, held to drive) (docs/web.md).
import { $, el, errorText, exposed } from './util.js';

const DRIVE_PERIOD_MS = 100;  // a held drive key publishes this often (the command holds meanwhile)
// arrow key -> [forward, turn left] factors of the pad's speeds
const DRIVE_KEYS = { ArrowUp: [1, 0], ArrowDown: [-1, 0], ArrowLeft: [0, 1], ArrowRight: [0, -1] };

export function setupInputs(rpc) {
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
