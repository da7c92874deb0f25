// The mcp transport's streams of calls (mcp_server.h, CallStream): a long call's events, kept
// so that a client whose connection dropped resumes the stream (streamable HTTP's
// resumability: GET with Last-Event-ID), and cancelled when it does not come back.
//
// Threads: the I/O thread only.
#include <charconv>

#include "mcp_server.h"
#include "simgate/core/log.h"
#include "simgate/jsonrpc/protocol.h"

namespace simgate::mcp {

namespace code = jsonrpc::code;

namespace {

std::string event_id(std::uint64_t stream, std::uint64_t event) {
  return std::to_string(stream) + "-" + std::to_string(event);
}

// "<stream>-<event>" read; false for anything else.
bool parse_event_id(std::string_view id, std::uint64_t& stream, std::uint64_t& event) {
  const std::size_t dash = id.find('-');
  if (dash == std::string_view::npos) return false;
  const auto a = std::from_chars(id.data(), id.data() + dash, stream);
  const auto b = std::from_chars(id.data() + dash + 1, id.data() + id.size(), event);
  return a.ec == std::errc() && a.ptr == id.data() + dash && b.ec == std::errc() &&
         b.ptr == id.data() + id.size();
}

}  // namespace

void McpServer::begin_call_stream(RequestId request, Pending& pending,
                                  kit::HttpConnection& connection) {
  auto s = sessions_.find(pending.session);
  if (s == sessions_.end()) return;
  Session& session = s->second;
  pending.stream = session.next_stream++;
  CallStream& stream = session.streams[pending.stream];
  stream.request = request;
  stream.connection = std::static_pointer_cast<kit::HttpConnection>(connection.shared_from_this());
  connection.begin_events();
}

void McpServer::stream_event(const Pending& pending, std::string message, bool droppable) {
  auto s = sessions_.find(pending.session);
  if (s == sessions_.end()) return;
  auto it = s->second.streams.find(pending.stream);
  if (it == s->second.streams.end()) return;
  CallStream& stream = it->second;
  const std::uint64_t number = stream.next_event++;
  auto connection = stream.connection.lock();
  if (connection && connection->streaming()) {
    // a client that does not read loses progress reports (a resume replays them), never the
    // result
    if (!droppable || connection->room_for_droppable())
      connection->queue_event(message, event_id(pending.stream, number));
  }
  stream.events.emplace_back(number, std::move(message));
  if (stream.events.size() > k_kept_events) stream.events.pop_front();
}

void McpServer::end_call_stream(const Pending& pending) {
  auto s = sessions_.find(pending.session);
  if (s == sessions_.end()) return;
  auto it = s->second.streams.find(pending.stream);
  if (it == s->second.streams.end()) return;
  CallStream& stream = it->second;
  stream.done = true;
  auto connection = stream.connection.lock();
  if (connection && connection->streaming()) {
    connection->end_events();
    s->second.streams.erase(it);
  }
  // else detached: kept until its client resumes it or resume_window passes
}

void McpServer::detach_streams(const kit::Connection& connection) {
  const auto now = std::chrono::steady_clock::now();
  for (auto& [id, session] : sessions_)
    for (auto& [number, stream] : session.streams) {
      auto owner = stream.connection.lock();
      if (owner && owner.get() != &connection) continue;
      stream.connection.reset();
      if (stream.detached == std::chrono::steady_clock::time_point{}) stream.detached = now;
    }
}

void McpServer::resume_stream(kit::HttpConnection& connection, Session& session,
                              std::string_view last) {
  std::uint64_t number = 0, seen = 0;
  auto it =
      parse_event_id(last, number, seen) ? session.streams.find(number) : session.streams.end();
  if (it == session.streams.end())
    return respond_error(connection, 404, nullptr, code::invalid_request,
                         "no stream to resume after event " + quoted_prefix(last, 40) +
                             " (ended, never made, or not resumed within resume_window_s)");
  CallStream& stream = it->second;
  // the old connection may not know yet that its client gave up on it
  if (auto old = stream.connection.lock(); old && old->streaming()) old->end_events();
  stream.connection = std::static_pointer_cast<kit::HttpConnection>(connection.shared_from_this());
  stream.detached = {};
  connection.begin_events();
  for (const auto& [event, message] : stream.events)
    if (event > seen) connection.queue_event(message, event_id(number, event));
  log::debug(name(), ": ", connection.label(), ": stream ", number, " resumed after event ", seen);
  if (stream.done) {
    connection.end_events();
    session.streams.erase(it);
  }
}

void McpServer::expire_streams(std::chrono::steady_clock::time_point now) {
  for (auto& [id, session] : sessions_)
    for (auto it = session.streams.begin(); it != session.streams.end();) {
      const CallStream& stream = it->second;
      if (stream.detached == std::chrono::steady_clock::time_point{} ||
          now - stream.detached < settings_.resume_window) {
        ++it;
        continue;
      }
      // nobody came back for it: the call ends (on_disconnect "let_run": it runs on, unread)
      if (!stream.done && settings_.tcp.cancel_on_disconnect) {
        if (auto p = pending_.find(stream.request); p != pending_.end()) p->second.cancelled = true;
        cancel(stream.request);
      }
      it = session.streams.erase(it);
    }
}

}  // namespace simgate::mcp
