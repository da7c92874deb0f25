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
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "simgate/core/request_manager.h"
#include "simgate/kit/id_table.h"
#include "simgate/kit/line_connection.h"

namespace simgate::jsonrpc {

class Session : public kit::LineConnection {
 public:
  using LineConnection::LineConnection;

  std::shared_ptr<Session> shared() { return std::static_pointer_cast<Session>(shared_from_this()); }

  // Queues one message (the newline is added); written at the end of the burst.
  void queue_line(std::string_view line) {
    queue_with([line](std::string& out) {
      out.append(line);
      out.push_back('\n');
    });
  }

  // ---- calls in flight (ids scoped to this connection)
  std::size_t in_flight() const { return unanswered(); }
  // A call, notification or cancel is in flight until done().
  void add_in_flight() { expect_reply(); }
  bool has_id(const std::string& key) const { return calls_.find(key) != nullptr; }
  // Remembers the call `id` under the client's id (its dumped JSON).
  void track(const std::string& key, RequestId id) {
    if (kit::IdTable::Entry* entry = calls_.insert(key)) entry->id = id;
  }
  std::optional<RequestId> find(const std::string& key) const {
    const kit::IdTable::Entry* entry = calls_.find(key);
    if (!entry) return std::nullopt;
    return entry->id;
  }
  // A call (or cancel) in flight produced its reply; `key` is its id's ("" when untracked).
  void done(const std::string& key) {
    if (!key.empty()) calls_.erase(key);
    replied();
  }
  // The calls to cancel when the client leaves.
  std::vector<RequestId> pending_calls() const {
    std::vector<RequestId> ids;
    ids.reserve(calls_.size());
    calls_.for_each([&](const kit::IdTable::Entry& e) { ids.push_back(e.id); });
    return ids;
  }

 private:
  kit::IdTable calls_;  // dumped JSON-RPC id -> the core's request id
};

}  // namespace simgate::jsonrpc

#endif  // SIMGATE_PLUGINS_JSONRPC_SESSION_H_
