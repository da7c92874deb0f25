// session.h — one client connection of the JSON-RPC transport.
//
// A Session is the kit's line connection (simgate/kit/line_connection.h: framing, the
// oversized-line rule, reads, coalesced writes, backpressure, end of input) with what
// JSON-RPC keeps per connection: the ids of its pending calls, so that ids and rpc.cancel
// are scoped to the connection, and the count of calls in flight (pending calls,
// notifications and cancels not finished), which max_in_flight bounds: a call over it is
// answered -32006 rather than left unread.
//
// Threads: the transport's I/O thread only.
#ifndef SIMGATE_PLUGINS_JSONRPC_SESSION_H_
#define SIMGATE_PLUGINS_JSONRPC_SESSION_H_

#include <memory>
#include <string>
#include <string_view>

#include "jsonrpc_engine.h"
#include "simgate/kit/line_connection.h"

namespace simgate::jsonrpc {

class Session : public kit::LineConnection, public SessionCalls {
 public:
  using LineConnection::LineConnection;

  std::shared_ptr<Session> shared() { return std::static_pointer_cast<Session>(shared_from_this()); }

  // Queues one message (the newline is added); written at the end of the burst.
  void queue_message(std::string_view line) {
    queue_with([line](std::string& out) {
      out.append(line);
      out.push_back('\n');
    });
  }
  // Queues the message `format(out)` appends, unless the client lets replies pile up
  // unread (LineConnection::queue_droppable_with); true if queued.
  template <class Format>
  bool queue_droppable_message(Format&& format) {
    return queue_droppable_with([&format](std::string& out) {
      format(out);
      out.push_back('\n');
    });
  }

  // ---- calls in flight (ids scoped to this connection: SessionCalls)
  std::size_t in_flight() const { return unanswered(); }
  // A call, notification or cancel is in flight until done().
  void add_in_flight() { expect_reply(); }
  // A call (or cancel) in flight produced its reply; `key` is its id's ("" when untracked).
  void done(const std::string& key) {
    forget_id(key);
    replied();
  }
};

}  // namespace simgate::jsonrpc

#endif  // SIMGATE_PLUGINS_JSONRPC_SESSION_H_
