// The service console: a form per method of rpc.discover, a log of the calls with their
// progress, status and reply, and a Cancel button (rpc.cancel) while one runs (docs/web.md).
import { $, el, errorText, exposed } from './util.js';

// A form field's text as a JSON value: a string parameter takes it as it is; anything else
// is parsed as JSON, and taken as a string when it is not JSON.
function parseValue(text, schema) {
  if (schema?.type === 'string') return text;
  try { return JSON.parse(text); } catch { return text; }
}

export function setupConsole(rpc) {
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
