// JSON-RPC 2.0 over one WebSocket (docs/transports/jsonrpc.md): calls matched to their
// replies by id, progress reports (rpc.progress), notifications (rpc.sample, ...).

export class Rpc {
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
