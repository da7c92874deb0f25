// websocket_session.h — one client connection of the websocket transport.
//
// A WsSession is the kit's WebSocket connection (simgate/kit/websocket_connection.h: the
// HTTP upgrade, frames, ping/pong, keep-alive, close handshake, and the kit's reads, writes,
// budgets and timers) and the JSON-RPC engine's session (simgate/jsonrpc/engine.h). A
// message is one WebSocket text message.
//
// Threads: the transport's I/O thread only.
#ifndef SIMGATE_PLUGINS_WEBSOCKET_WEBSOCKET_SESSION_H_
#define SIMGATE_PLUGINS_WEBSOCKET_WEBSOCKET_SESSION_H_

#include <string_view>
#include <utility>

#include "simgate/jsonrpc/engine.h"
#include "simgate/kit/websocket_connection.h"

namespace simgate::websocket {

class WsSession : public kit::WebSocketConnection, public jsonrpc::Session {
 public:
  template <class... Args>
  explicit WsSession(Args&&... args)
      : WebSocketConnection(std::forward<Args>(args)...), Session(connection()) {}

  // One message: a text message.
  void queue_message(std::string_view text) override { queue_text(text); }
};

}  // namespace simgate::websocket

#endif  // SIMGATE_PLUGINS_WEBSOCKET_WEBSOCKET_SESSION_H_
