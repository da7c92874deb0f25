// The login: when the transport wants a token (its `auth` option), the page asks for it and
// calls rpc.login before anything else (docs/web.md).
import { $, errorText, exposed, isUnauthorized } from './util.js';

const TOKEN_KEY = 'simgate-token';  // sessionStorage: the token of this tab, not kept after it

// Resolves with the token the user types in the login form.
function askToken(message) {
  const form = $('login');
  form.hidden = false;
  $('login-message').textContent = message;
  $('login-token').focus();
  return new Promise((resolve) => {
    form.onsubmit = (event) => {
      event.preventDefault();
      const token = $('login-token').value.trim();
      if (!token) return;
      form.hidden = true;
      resolve(token);
    };
  });
}

// Before anything else on a new connection: true once the connection may call services
// (no token needed, or rpc.login accepted), false when the token was wrong (the server then
// closes the connection; the next one asks again).
export async function login(rpc) {
  let token = sessionStorage.getItem(TOKEN_KEY);
  if (!token) {
    // rpc.cancel of no call: false when no token is needed, -32005 when one is
    try {
      await rpc.call('rpc.cancel', { id: null });
      return true;
    } catch (e) {
      if (!isUnauthorized(e)) return true;
    }
    token = await askToken(exposed.login === 'wrong'
      ? 'Wrong token. Token of this server (its "auth" option):'
      : 'This server wants a token (its "auth" option):');
    exposed.login = 'asking';
  }
  try {
    await rpc.call('rpc.login', { token });
    sessionStorage.setItem(TOKEN_KEY, token);
    exposed.login = 'done';
    return true;
  } catch (e) {
    sessionStorage.removeItem(TOKEN_KEY);
    exposed.login = 'wrong';
    $('connection').textContent = `rpc.login: ${errorText(e)}`;
    return false;
  }
}
