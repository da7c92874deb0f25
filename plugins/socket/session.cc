#include "session.h"

#include "simgate/core/log.h"
#include "simgate/morse/wire.h"

namespace simgate::socket {

void Session::answer(std::size_t client_id_hash, RequestId id, std::string_view status,
                     const json* value) {
  if (closed()) return;
  const kit::IdTable::Entry* entry = pending_.find(client_id_hash, id);
  if (!entry) {
    log::error("Socket service manager: ", label(), ": no pending request ", id,
               " to answer (reply dropped)");
    return;
  }
  // formatted straight into the outbox, then forgotten; the limit may close the connection
  // instead, which forgets every pending request (entry with them)
  queue_with([&](std::string& out) { append_reply(out, entry->key, status, value); });
  if (closed()) return;
  pending_.erase(entry);
  replied();
}

bool Session::report_progress(std::size_t client_id_hash, RequestId id, const json& value) {
  const kit::IdTable::Entry* entry = pending_.find(client_id_hash, id);
  if (!entry) return false;
  return queue_droppable_with(
      [&](std::string& out) { append_reply(out, entry->key, k_progress_status, &value); });
}

}  // namespace simgate::socket
