// The web app's shared helpers (docs/web.md): DOM shorthands, number and error formatting,
// the JSON-RPC error codes the page tells apart, and window.simgate, what the page knows.
export const $ = (id) => document.getElementById(id);
export const el = (tag, props = {}, ...children) => {
  const e = Object.assign(document.createElement(tag), props);
  for (const c of children) e.append(c);
  return e;
};
export const fmt = (v, digits = 3) => (typeof v === 'number' ? v.toFixed(digits) : String(v ?? '–'));
export const errorText = (e) => e?.data?.message ?? e?.message ?? String(e);
// A service the server does not have, or does not let this transport call.
export const isUnknownMethod = (e) => e?.code === -32601;
// The transport wants rpc.login first (its `auth` option), or the token was wrong.
export const isUnauthorized = (e) => e?.code === -32005;

// What the browser test (and a curious developer) can read.
export const exposed = window.simgate = {
  connected: false,
  ready: false,          // connected, and logged in when the transport wants a token
  login: 'none',         // 'none' (no token needed), 'asking', 'wrong' (asking again) or 'done'
  services: [],          // method names of rpc.discover
  bodies: {},            // body name -> [x, y, z]
  meshes: 0,             // three.js meshes in the scene
  hfields: 0,            // of which heightfields
  frames: 0,             // frames rendered
  poseSource: 'none',    // 'stream', 'poll' or 'none'
  view: 'none',          // 'geometry', 'markers', 'none' or 'no-webgl'
  cameras: {},           // camera component -> {images, width, height, live, error}
  inputs: {},            // input stream -> {published, refused, last, error}
};
