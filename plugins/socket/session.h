// session.h — one client connection of the socket transport.
//
// A Session is the kit's line connection (simgate/kit/line_connection.h: framing, the
// oversized-line rule, reads, coalesced writes, backpressure, end of input) with what the
// socket protocol keeps per connection:
//   - Pending requests: the client's ids of requests not yet answered, mapped to the core's
//     RequestId, so ids and cancel are scoped to the connection. Reading pauses while
//     max_in_flight replies are owed (ConnectionLimits::pause_at_unanswered).
//   - Deferred replies: an error reply the manager made itself, travelling through the
//     core behind the connection's earlier requests so the replies keep their order.
//   - Progress: whether the client opted in (`<id> simgate progress [true]`) to progress
//     lines `<id> PROGRESS <json>` for its async requests sent from then on.
//
// Threads: the transport's I/O thread only.
#ifndef SIMGATE_PLUGINS_SOCKET_SESSION_H_
#define SIMGATE_PLUGINS_SOCKET_SESSION_H_

#include <cstddef>
#include <memory>
#include <string_view>

#include "simgate/core/status.h"
#include "simgate/kit/id_table.h"
#include "simgate/kit/line_connection.h"

namespace simgate::socket {

class Session : public kit::LineConnection {
 public:
  using LineConnection::LineConnection;

  std::shared_ptr<Session> shared() {
    return std::static_pointer_cast<Session>(shared_from_this());
  }

  // Pending requests of this connection, by the client's id.
  const kit::IdTable::Entry* find_pending(std::string_view client_id) const {
    return pending_.find(client_id);
  }
  // Registers a request under the client's id: returns its entry, whose `id` the caller
  // sets at once (the pointer is valid until the table next changes), or null when that id
  // is already pending here.
  kit::IdTable::Entry* add_pending(std::string_view client_id) {
    kit::IdTable::Entry* entry = pending_.insert(client_id);
    if (entry) expect_reply();
    return entry;
  }
  // Forgets a request that will get no answer of its own (its line was refused).
  void drop_pending(std::string_view client_id) {
    if (pending_.erase(client_id)) replied();
  }
  // Queues the reply "<client id> <status>[ <value>]" to the pending request `id`, whose
  // client id hashes to `client_id_hash` (its entry's hash), and forgets the request.
  void answer(std::size_t client_id_hash, RequestId id, std::string_view status, const json* value);
  const kit::IdTable& pending() const { return pending_; }
  // Queues the progress line "<client id> PROGRESS <json>" of the pending request `id`
  // (hash as for answer()), unless more than kit::Connection::k_droppable_unsent_bytes wait
  // unsent: a client that does not read loses reports, never a reply. True if queued.
  bool report_progress(std::size_t client_id_hash, RequestId id, const json& value);
  // The connection opted in to progress lines (`<id> simgate progress [true|false]`):
  // requests read from now on are submitted with Call::progress.
  bool wants_progress() const { return wants_progress_; }
  void set_wants_progress(bool on) { wants_progress_ = on; }
  // Forgets every pending request (the connection closed).
  void clear_pending() { pending_.clear(); }
  // A reply the manager made itself (an error) but that must follow the replies of earlier
  // requests travels through the core in order: defer_reply() when it leaves,
  // queue_deferred_reply() when it comes back.
  void defer_reply() { expect_reply(); }
  void queue_deferred_reply(std::string_view bytes) {
    queue(bytes);
    replied();
  }
  // Requests or deferred replies not answered yet: a new error reply must wait for them.
  bool has_unanswered() const { return unanswered() > 0; }

 private:
  kit::IdTable pending_;         // client id -> core request id
  bool wants_progress_ = false;  // opted in to progress lines
};

}  // namespace simgate::socket

#endif  // SIMGATE_PLUGINS_SOCKET_SESSION_H_
