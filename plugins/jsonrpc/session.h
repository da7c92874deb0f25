// session.h — one client connection of the jsonrpc transport.
//
// A LineSession is the kit's line connection (simgate/kit/line_connection.h: framing, the
// oversized-line rule, reads, coalesced writes, backpressure, end of input) and the JSON-RPC
// engine's session (simgate/jsonrpc/engine.h: the ids of its pending calls, calls in
// flight, which max_in_flight bounds: a call over it is answered -32006 rather than left
// unread). A message is one line.
//
// Threads: the transport's I/O thread only.
#ifndef SIMGATE_PLUGINS_JSONRPC_SESSION_H_
#define SIMGATE_PLUGINS_JSONRPC_SESSION_H_

#include <string>
#include <string_view>

#include "simgate/jsonrpc/engine.h"
#include "simgate/kit/line_connection.h"

namespace simgate::jsonrpc {

class LineSession : public kit::LineConnection, public Session {
 public:
  template <class... Args>
  explicit LineSession(Args&&... args)
      : LineConnection(std::forward<Args>(args)...), Session(connection()) {}

  // One message: the line, its newline added; written at the end of the burst.
  void queue_message(std::string_view line) override {
    queue_with([line](std::string& out) {
      out.append(line);
      out.push_back('\n');
    });
  }
};

}  // namespace simgate::jsonrpc

#endif  // SIMGATE_PLUGINS_JSONRPC_SESSION_H_
