// The cameras: every component with a get_image service, its image on asking, and live from
// its data stream (rpc.subscribe) when this transport carries one; a depth image decoded and
// stretched so that it can be seen (docs/web.md, docs/components/cameras.md).
import { $, el, errorText, exposed, fmt } from './util.js';

// The image kinds of the data streams (docs/components/cameras.md, Streams).
const IMAGE_KINDS = new Set(['image', 'depth_image']);

// A depth image (a 16-bit grey PNG of millimetres: docs/components/cameras.md) as an 8-bit
// PNG a person can read: the record's min_depth..max_depth stretched from white (near) to
// dark grey (far), black where nothing is within reach. Shown as is, millimetres in 16 bits
// come out nearly black (a browser keeps the high byte: 4 m is 15 of 255).
async function depthPreview(record) {
  const png = Uint8Array.from(atob(record.image), (c) => c.charCodeAt(0));
  const view = new DataView(png.buffer);
  const idat = [];
  let width = 0, height = 0, depth = 0, colour = -1, interlace = 0;
  for (let at = 8; at + 8 <= png.length;) {
    const length = view.getUint32(at);
    const type = String.fromCharCode(...png.subarray(at + 4, at + 8));
    const data = png.subarray(at + 8, at + 8 + length);
    if (type === 'IHDR') {
      width = view.getUint32(at + 8);
      height = view.getUint32(at + 12);
      [depth, colour, , , interlace] = data.subarray(8, 13);
    } else if (type === 'IDAT') {
      idat.push(data);
    } else if (type === 'IEND') {
      break;
    }
    at += 12 + length;
  }
  if (depth !== 16 || colour !== 0 || interlace !== 0 || !width || !height) throw new Error('not a 16-bit grey PNG');
  // the image data: zlib (DecompressionStream's 'deflate'), then the filters of each row
  const inflated = new Uint8Array(await new Response(
    new Blob(idat).stream().pipeThrough(new DecompressionStream('deflate'))).arrayBuffer());
  const stride = width * 2;
  if (inflated.length < height * (stride + 1)) throw new Error('truncated image data');
  const rows = new Uint8Array(height * stride);
  for (let y = 0; y < height; ++y) {
    const filter = inflated[y * (stride + 1)];
    const line = inflated.subarray(y * (stride + 1) + 1, (y + 1) * (stride + 1));
    const out = rows.subarray(y * stride, (y + 1) * stride);
    const up = y > 0 ? rows.subarray((y - 1) * stride, y * stride) : new Uint8Array(stride);
    for (let i = 0; i < stride; ++i) {
      const a = i >= 2 ? out[i - 2] : 0, b = up[i], c = i >= 2 ? up[i - 2] : 0;
      let predicted = 0;
      if (filter === 1) predicted = a;
      else if (filter === 2) predicted = b;
      else if (filter === 3) predicted = (a + b) >> 1;
      else if (filter === 4) {
        const p = a + b - c, pa = Math.abs(p - a), pb = Math.abs(p - b), pc = Math.abs(p - c);
        predicted = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
      }
      out[i] = (line[i] + predicted) & 0xff;
    }
  }
  const near = (record.min_depth ?? 0) * 1000, far = Math.max((record.max_depth ?? 0) * 1000, near + 1);
  const canvas = document.createElement('canvas');
  canvas.width = width;
  canvas.height = height;
  const ctx = canvas.getContext('2d');
  const pixels = ctx.createImageData(width, height);
  for (let i = 0; i < width * height; ++i) {
    const mm = (rows[2 * i] << 8) | rows[2 * i + 1];
    const grey = mm === 0 ? 0 : Math.round(255 - 200 * Math.min(1, Math.max(0, (mm - near) / (far - near))));
    pixels.data.set([grey, grey, grey, 255], 4 * i);
  }
  ctx.putImageData(pixels, 0, 0);
  return canvas.toDataURL('image/png');
}

export function setupCameras(rpc) {
  const figures = new Map();      // component -> {img, caption, live checkbox, status}
  const subscriptions = new Map(); // component -> subscription number, while live

  // An image record (get_image's reply, a stream sample): PNG in base64 (MORSE's way); a
  // depth image stretched so that it can be seen (depthPreview).
  async function show(component, record) {
    const figure = figures.get(component);
    const state = exposed.cameras[component];
    if (!figure || !record?.image || record.format !== 'png') return;
    const depth = record.encoding === 'mono16';
    try {
      figure.img.src = depth ? await depthPreview(record) : `data:image/png;base64,${record.image}`;
    } catch (e) {
      fail(component, 'depth image', e);
      return;
    }
    state.images += 1;
    state.width = record.width;
    state.height = record.height;
    state.depth = depth;
    const range = depth ? ` ${fmt(record.min_depth, 2)}–${fmt(record.max_depth, 2)} m (near is light)` : '';
    figure.status.textContent = `${record.width}×${record.height} ${record.encoding ?? ''}${range}, t = ${fmt(record.timestamp, 2)} s`;
  }

  function fail(component, what, e) {
    exposed.cameras[component].error = `${what}: ${errorText(e)}`;
    figures.get(component).status.textContent = exposed.cameras[component].error;
  }

  async function snapshot(component) {
    try {
      await show(component, await rpc.call(`${component}.get_image`));
    } catch (e) {
      fail(component, 'get_image', e);
    }
  }

  async function setLive(component, on) {
    const state = exposed.cameras[component];
    try {
      if (on) {
        const answer = await rpc.call('rpc.subscribe', { component });
        subscriptions.set(component, answer.subscription);
      } else if (subscriptions.has(component)) {
        await rpc.call('rpc.unsubscribe', { subscription: subscriptions.get(component) });
        subscriptions.delete(component);
      }
      state.live = on;
    } catch (e) {
      figures.get(component).live.checked = state.live;
      fail(component, on ? 'rpc.subscribe' : 'rpc.unsubscribe', e);
    }
  }

  rpc.on('rpc.sample', (p) => { if (subscriptions.has(p.component)) show(p.component, p.data); });

  function figureFor(component, stream) {
    const img = el('img', { alt: `what ${component} sees` });
    const status = el('span', { className: 'note', textContent: 'no image yet' });
    const live = el('input', { type: 'checkbox', disabled: !stream,
      title: stream ? `rpc.subscribe ${component}: every image of its stream (${stream.frequency} Hz)`
        : 'this transport carries no stream of this camera (the deployment\'s "streams")' });
    live.onchange = () => setLive(component, live.checked);
    const button = el('button', { type: 'button', textContent: 'Image', title: `${component}.get_image` });
    button.onclick = () => snapshot(component);
    const figure = el('figure', { className: 'camera' }, img,
      el('figcaption', {}, el('strong', { textContent: component }), ' ', button, ' ',
        el('label', {}, live, ' live'), ' ', status));
    figure.dataset.component = component;
    figures.set(component, { img, status, live });
    return figure;
  }

  // `methods`: a promise of rpc.discover's methods (the console's load()); `streamList` one
  // of rpc.streams' answer ([] where there is none). `connected`: the connection is the one
  // the panel was built on (a model change: a robot spawned or deleted), whose live
  // subscriptions end first; else a new one, whose server forgot them.
  return async function start(methods, streamList, connected = false) {
    if (connected)
      for (const subscription of subscriptions.values())
        rpc.call('rpc.unsubscribe', { subscription }).catch(() => {});  // its camera may be gone
    const names = (await methods).map((m) => m.name);
    const streams = await streamList;
    const streamOf = new Map(streams.filter((s) => s.direction === 'OUT' && IMAGE_KINDS.has(s.kind))
      .map((s) => [s.component, s]));
    const cameras = [...new Set([...names.filter((n) => n.endsWith('.get_image')).map((n) => n.slice(0, -'.get_image'.length)),
      ...streamOf.keys()])].sort();
    subscriptions.clear();
    figures.clear();
    exposed.cameras = Object.fromEntries(cameras.map((c) => [c, { images: 0, width: 0, height: 0, live: false, error: '' }]));
    const box = $('cameras');
    box.replaceChildren(...cameras.map((c) => figureFor(c, streamOf.get(c))));
    if (cameras.length === 0) box.replaceChildren(el('p', { className: 'note', textContent: 'no camera is served here' }));
    // one image each to begin with (a camera renders only when asked or subscribed)
    await Promise.all(cameras.filter((c) => names.includes(`${c}.get_image`)).map(snapshot));
  };
}
