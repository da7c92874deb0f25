// websocket_session.h — one client connection of the websocket transport: an HTTP request,
// upgraded to a WebSocket (Boost.Beast), that carries one JSON-RPC message per text message.
//
// What it does, so that the JSON-RPC engine (plugins/jsonrpc/jsonrpc_engine.h) sees the same
// session as over TCP:
//   - Handshake: reads one HTTP request (header and body within k_max_request_bytes, within
//     k_handshake_timeout); a WebSocket upgrade is accepted, anything else answered by the
//     host (WsHost::on_http_request: the web app's files, or 404) and closed; an upgrade the
//     host refuses (WsHost::refuse_upgrade: an Origin not allowed) is answered and closed.
//   - Reading: one async read at a time, a message assembled from its pieces; a message
//     longer than max_message_bytes is skipped to its end (the host answers it) and the
//     connection keeps working; binary messages are handed to the host as such. Reading
//     pauses while more than pause_at_unsent_bytes of replies wait unsent.
//   - Writing: queue_message() appends a text message to the outbox; flush_writes() (the
//     host calls it once per burst) writes them, one write in flight, the rest behind it.
//   - A client that does not read: a reply that finds more than max_unsent_bytes waiting
//     closes the connection; droppable messages (progress, samples) are dropped once more
//     than kit::LineConnection::k_droppable_unsent_bytes wait (the TCP transports' limits).
//   - Ping/pong and the close handshake: Beast (stream_base::timeout::suggested(server):
//     a silent peer that answers no ping for 300 s is dropped).
//
// Life cycle: created on accept, start()ed, kept alive by its pending handlers
// (shared_from_this) and by the host's set; close() (a close frame with a reason) or
// abort() (the socket closed) ends it, on_closed() tells the host once.
// Threads: every member function runs on the transport's single I/O thread.
#ifndef SIMGATE_PLUGINS_WEBSOCKET_WEBSOCKET_SESSION_H_
#define SIMGATE_PLUGINS_WEBSOCKET_WEBSOCKET_SESSION_H_

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>  // before Asio: Boost 1.74 needs std::exchange in C++20 mode

#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/http/message.hpp>
#include <boost/beast/http/parser.hpp>
#include <boost/beast/http/string_body.hpp>
#include <boost/beast/websocket/rfc6455.hpp>
#include <boost/beast/websocket/stream.hpp>

#include "jsonrpc_engine.h"
#include "simgate/kit/line_connection.h"

namespace simgate::websocket {

class WsSession;

// What a session needs from the transport that owns it (I/O thread).
class WsHost {
 public:
  virtual ~WsHost() = default;
  // One complete text message.
  virtual void on_message(WsSession& session, std::string_view text) = 0;
  // A message exceeded max_message_bytes (`bytes` arrived before it was skipped), or was
  // binary: the protocol answers it.
  virtual void on_refused_message(WsSession& session, std::size_t bytes, bool binary) = 0;
  // The end of one read: hand the calls over, write the replies.
  virtual void on_read_done(WsSession& session) = 0;
  // A plain HTTP request (not an upgrade): the response to send before closing.
  virtual std::string on_http_request(const boost::beast::http::request<boost::beast::http::string_body>& request) = 0;
  // An upgrade request: "" to accept it, else the HTTP response refusing it (403: a page of
  // another origin, origin_policy.h), sent before closing.
  virtual std::string refuse_upgrade(const boost::beast::http::request<boost::beast::http::string_body>& request) = 0;
  // The connection closed (error, peer gone, limit, server stopping): forget it.
  virtual void on_closed(WsSession& session) = 0;
  // The session has messages queued: call its flush_writes() at the end of the burst.
  virtual void touch(WsSession& session) = 0;
  // Sweeps of the connections so far (kit/connection_rules.h): the sessions' clock.
  virtual std::uint32_t tick() const = 0;
};

struct WsLimits {
  std::size_t max_message_bytes = 8 << 20;   // longest text message accepted
  std::size_t max_unsent_bytes = 16 << 20;   // unsent messages a reply may find before disconnecting
  std::size_t pause_at_unsent_bytes = 8 << 20;  // unsent bytes that pause reading
};

class WsSession : public std::enable_shared_from_this<WsSession>, public jsonrpc::SessionCalls {
 public:
  // `who` names the transport in logs; `number` the connection ("client #3 (127.0.0.1:5123)").
  WsSession(boost::asio::ip::tcp::socket socket, WsHost& host, WsLimits limits, std::string_view who,
            std::uint64_t number);
  WsSession(const WsSession&) = delete;
  WsSession& operator=(const WsSession&) = delete;

  std::shared_ptr<WsSession> shared() { return shared_from_this(); }

  // Reads the HTTP request, then messages.
  void start();

  // ---- the engine's session (jsonrpc_engine.h)
  // Queues one text message; a message that finds more than max_unsent_bytes waiting
  // closes the connection instead.
  void queue_message(std::string_view text) { queue_owned(std::string(text)); }
  // Queues the message `format(std::string&)` builds, unless more than
  // k_droppable_unsent_bytes wait unsent (false: dropped).
  template <class Format>
  bool queue_droppable_message(Format&& format) {
    if (closed_ || unsent_ > kit::LineConnection::k_droppable_unsent_bytes) return false;
    std::string text;
    format(text);
    queue_owned(std::move(text));
    return true;
  }
  // Writes what was queued, unless a write is in flight (it takes them next).
  void flush_writes();
  std::size_t in_flight() const { return in_flight_; }
  void add_in_flight() {
    ++in_flight_;
    active();
  }
  void done(const std::string& key) {
    forget_id(key);
    if (in_flight_ > 0) --in_flight_;
    active();
  }
  bool authenticated() const { return authenticated_; }
  void set_authenticated() { authenticated_ = true; }
  // The client must call rpc.login before anything else (the host decides at accept).
  void require_login() { authenticated_ = false; }
  const std::string& label() const { return label_; }
  const boost::asio::ip::address& peer() const { return peer_; }
  bool closed() const { return closed_; }
  // Ends the connection with a close frame (policy violation) carrying `reason`, after the
  // messages already queued; idempotent.
  void close(std::string_view reason) { close_with(boost::beast::websocket::close_code::policy_error, reason); }
  // The same with `code` (1009 too big, 1001 going away...).
  void close_with(boost::beast::websocket::close_code code, std::string_view reason);
  // Closes the socket at once (the peer left, the server stops); idempotent.
  void abort(std::string_view reason);

  // For the host's touch list.
  bool touched = false;

  // ---- resources held without use (kit/connection_rules.h, the host's sweep)
  // Sweeps since it last read (a message, a ping, a pong), wrote or was owed a reply; 0
  // while it owes one or has messages unsent (it is not idle then).
  std::uint32_t idle_ticks() const {
    if (in_flight_ > 0 || writing_ || !outbox_.empty()) return 0;
    return host_.tick() - active_tick_;
  }
  // The same even while it owes replies (a client waiting for calls that never end).
  std::uint32_t silent_ticks() const {
    if (writing_ || !outbox_.empty()) return 0;
    return host_.tick() - active_tick_;
  }
  std::size_t unanswered() const { return in_flight_; }

  // How long the HTTP request may take to arrive.
  static constexpr std::chrono::seconds k_handshake_timeout{30};
  // The largest HTTP request (header and body) accepted before the upgrade.
  static constexpr std::uint32_t k_max_request_bytes = 16 * 1024;
  // The most one read takes.
  static constexpr std::size_t k_read_bytes = 64 * 1024;

 private:
  void queue_owned(std::string text);
  void on_request(const boost::system::error_code& ec);
  void read_more();
  void on_read(const boost::system::error_code& ec, std::size_t n);
  void start_write();
  void on_write(const boost::system::error_code& ec);
  void active() { active_tick_ = host_.tick(); }

  // on the plain socket: no per-operation timer bookkeeping on the hot path (the HTTP
  // request's deadline is handshake_timer_, the WebSocket's Beast's own timeouts)
  using Stream = boost::beast::websocket::stream<boost::asio::ip::tcp::socket>;
  Stream ws_;                                   // the connection
  WsHost& host_;                                // the transport (outlives every session)
  WsLimits limits_;                             // from the transport options
  std::string who_;                             // the transport, for logs
  std::string label_;                           // the client, for logs
  boost::asio::ip::address peer_;               // the client's address
  bool authenticated_ = true;                   // may call services (the host decides at accept)
  boost::beast::flat_buffer buffer_;            // the HTTP request, then the message being read
  std::optional<boost::beast::http::request_parser<boost::beast::http::string_body>> parser_;  // until the upgrade
  bool upgraded_ = false;                       // the WebSocket handshake is done
  bool reading_ = false;                        // a read is in flight
  std::size_t skipped_ = 0;                     // bytes of an oversized message skipped so far (0: none)
  std::deque<std::string> outbox_;              // messages queued, the front one being written while writing_
  std::size_t unsent_ = 0;                      // bytes of outbox_
  bool writing_ = false;                        // a write is in flight
  std::size_t in_flight_ = 0;                   // calls, notifications and cancels not finished
  bool closed_ = false;                         // close() or abort() was called
  std::optional<std::pair<boost::beast::websocket::close_code, std::string>> close_after_writes_;  // close() waiting
  std::string http_response_;                   // a plain HTTP request's answer, being written
  boost::asio::steady_timer handshake_timer_;   // closes a connection whose HTTP request does not come
  std::uint32_t active_tick_ = 0;               // the sweep of its last read, write or reply owed
};

}  // namespace simgate::websocket

#endif  // SIMGATE_PLUGINS_WEBSOCKET_WEBSOCKET_SESSION_H_
