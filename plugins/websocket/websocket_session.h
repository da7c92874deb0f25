// websocket_session.h — one client connection of the websocket transport: an HTTP request,
// upgraded to a WebSocket, that carries one JSON-RPC message per text message.
//
// Boost.Beast reads the HTTP request and answers the upgrade (or the host answers a plain
// request); from then on the session frames RFC 6455 itself on the plain socket, so that
// the transport's I/O thread can read a lone client's socket directly while it polls, as
// the TCP transport does (simgate/kit/idle_spin.h), and write straight to it:
//   - Handshake: reads one HTTP request (header and body within k_max_request_bytes, within
//     k_handshake_timeout); an upgrade the host accepts (WsHost::refuse_upgrade: the Origin)
//     is answered 101 by Beast; anything else is answered by the host
//     (WsHost::on_http_request: the web app's files, or 404) and closed.
//   - Reading: each read's bytes go to a FrameParser (ws_frames.h: the frames, without a
//     socket; fuzzed), whose events the session handles. Client frames must be masked
//     (else close 1002); text and binary messages, fragmented or not, with pings, pongs
//     and close frames between fragments. A message longer than max_message_bytes (binary
//     or not) is skipped to its end as it arrives (never buffered; the host answers it) and
//     the connection keeps working; other binary messages are handed to the host as such
//     (never buffered either). Reserved bits, opcodes, a continuation out of place, a
//     control frame fragmented or over 125 bytes (the parser's protocol errors), a close
//     frame of one byte (the session's): close 1002. Reading pauses while more than
//     pause_at_unsent_bytes of replies wait unsent. Text is not checked for UTF-8 here: the
//     JSON parser refuses what is not (-32700).
//   - Direct reads (idle_spin.h): when the host watches the session (a lone client while
//     the I/O thread polls) no async read is started; the polling thread calls read_now()
//     until it parks the session (read_async()).
//   - Writing: queue_message() frames a text message into the outbox; flush_writes() (the
//     host calls it once per burst) writes the outbox straight to the non-blocking socket
//     while it takes it, through one async write otherwise; messages queued meanwhile go in
//     the next write (coalesced). A ping is answered by a pong with its payload.
//   - A client that does not read: a reply that finds more than max_unsent_bytes waiting
//     closes the connection; droppable messages (progress, samples) are dropped once more
//     than kit::LineConnection::k_droppable_unsent_bytes wait (the TCP transports' limits).
//   - Memory of all sessions together (WsHost::held, kit/held_bytes.h: max_buffered_bytes):
//     each session counts its unsent frames, the message it is receiving and its HTTP
//     response's own bytes there; past the cap, the session whose message is still arriving
//     is closed (1013), a reply that finds its session with frames unsent closes it, and
//     one its socket does not take at once too (the TCP transports' rules).
//   - Keep-alive (keep_alive(), from the host's sweep): a client silent for
//     WsLimits::keepalive (the `keepalive_s` option, 150 s by default) is sent a ping; silent
//     for twice that (it answered no ping either), it is dropped. 0: neither.
//   - Close handshake: the client's close frame is answered with its code, then the socket
//     closes; close() sends one (after the messages queued), reads on (ignoring messages)
//     until the client's close frame or end of input, within k_close_timeout.
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
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>  // before Asio: Boost 1.74 needs std::exchange in C++20 mode
#include <vector>

#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/http/message.hpp>
#include <boost/beast/http/parser.hpp>
#include <boost/beast/http/string_body.hpp>
#include <boost/beast/websocket/rfc6455.hpp>
#include <boost/beast/websocket/stream.hpp>

#include "jsonrpc_engine.h"
#include "simgate/kit/held_bytes.h"
#include "simgate/kit/line_connection.h"
#include "static_files.h"
#include "ws_frames.h"

namespace simgate::websocket {

// Whether a close frame may carry `code` (RFC 6455 section 7.4): a client's other codes
// are answered with 1002, not echoed.
bool is_valid_close_code(std::uint16_t code);

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
  virtual HttpResponse on_http_request(const boost::beast::http::request<boost::beast::http::string_body>& request) = 0;
  // An upgrade request: "" to accept it, else the HTTP response refusing it (403: a page of
  // another origin, origin_policy.h), sent before closing.
  virtual std::string refuse_upgrade(const boost::beast::http::request<boost::beast::http::string_body>& request) = 0;
  // The connection closed (error, peer gone, limit, server stopping): forget it.
  virtual void on_closed(WsSession& session) = 0;
  // The session has messages queued: call its flush_writes() at the end of the burst.
  virtual void touch(WsSession& session) = 0;
  // The session is about to wait for its next bytes: true when the host's polling thread
  // will read its socket itself (read_now) until it parks it (read_async).
  virtual bool watch(WsSession& session) = 0;
  // Sweeps of the connections so far (kit/connection_rules.h): the sessions' clock.
  virtual std::uint32_t tick() const = 0;
  // What all sessions hold in memory together (max_buffered_bytes).
  virtual kit::HeldBytes& held() = 0;
};

struct WsLimits {
  std::size_t max_message_bytes = 8 << 20;   // longest text message accepted
  std::size_t max_unsent_bytes = 16 << 20;   // unsent messages a reply may find before disconnecting
  std::size_t pause_at_unsent_bytes = 8 << 20;  // unsent bytes that pause reading
  // silence (no message, ping or pong) after which the client is pinged, and after twice
  // which it is dropped; 0: never (Beast's suggested server timeouts: 150 s and 300 s)
  std::chrono::milliseconds keepalive{150'000};
};

class WsSession : public std::enable_shared_from_this<WsSession>,
                  public jsonrpc::SessionCalls,
                  private FrameSink {
 public:
  // `who` names the transport in logs; `number` the connection ("client #3 (127.0.0.1:5123)").
  WsSession(boost::asio::ip::tcp::socket socket, WsHost& host, WsLimits limits, std::string_view who,
            std::uint64_t number);
  WsSession(const WsSession&) = delete;
  WsSession& operator=(const WsSession&) = delete;

  std::shared_ptr<WsSession> shared() { return shared_from_this(); }

  // Reads the HTTP request, then messages.
  void start();
  // Watched by the host: reads what is waiting, without waiting, and handles it as an async
  // read's completion would; false when nothing was waiting.
  bool read_now();
  // No longer watched: waits for its next bytes through the event loop (an async read).
  void read_async();
  // The host's sweep, every k_connection_sweep (`tick` its clock): pings a silent client,
  // drops one silent too long.
  void keep_alive(std::uint32_t tick);

  // ---- the engine's session (jsonrpc_engine.h)
  // Queues one text message; a message that finds more than max_unsent_bytes waiting
  // closes the connection instead (and the memory rules of the file's comment).
  void queue_message(std::string_view text);
  // Queues the message `format(std::string&)` builds, unless more than
  // k_droppable_unsent_bytes wait unsent (false: dropped).
  template <class Format>
  bool queue_droppable_message(Format&& format) {
    if (closed_ || unsent() > kit::LineConnection::k_droppable_unsent_bytes) return false;
    std::string text;
    format(text);
    queue_message(text);
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
  // Its number within the transport: what its calls carry as Call::client.
  std::uint64_t number() const { return number_; }
  const boost::asio::ip::address& peer() const { return peer_; }
  bool closed() const { return closed_; }
  // Ends the connection with a close frame (policy violation) carrying `reason`, after the
  // messages already queued; idempotent.
  void close(std::string_view reason) { close_with(boost::beast::websocket::close_code::policy_error, reason); }
  // The same with `code` (1009 too big, 1001 going away...).
  void close_with(boost::beast::websocket::close_code code, std::string_view reason);
  // Closes the socket at once (the peer left, the server stops); idempotent.
  void abort(std::string_view reason);
  bool aborted() const { return aborted_; }

  // For the host's touch list.
  bool touched = false;

  // ---- resources held without use (kit/connection_rules.h, the host's sweep)
  // Sweeps since it last read a message (not a ping or a pong: those keep nothing alive),
  // wrote one or was owed a reply; 0 while it owes one or has messages unsent (it is not
  // idle then).
  std::uint32_t idle_ticks() const {
    if (in_flight_ > 0 || unsent() > 0) return 0;
    return host_.tick() - active_tick_;
  }
  // The same even while it owes replies (a client waiting for calls that never end).
  std::uint32_t silent_ticks() const {
    if (unsent() > 0) return 0;
    return host_.tick() - active_tick_;
  }
  std::size_t unanswered() const { return in_flight_; }

  // How long the HTTP request may take to arrive.
  static constexpr std::chrono::seconds k_handshake_timeout{30};
  // The largest HTTP request (header and body) accepted before the upgrade.
  static constexpr std::uint32_t k_max_request_bytes = 16 * 1024;
  // The most one read takes.
  static constexpr std::size_t k_read_bytes = 64 * 1024;
  // Messages queued in one burst past which they are written without waiting for its end.
  static constexpr std::size_t k_coalesce_bytes = 256 * 1024;
  // How long the client has to answer a close frame with its own.
  static constexpr std::chrono::seconds k_close_timeout{5};

 private:
  void on_request(const boost::system::error_code& ec);
  void on_upgraded(const boost::system::error_code& ec);
  void read_more();
  void on_read(const boost::system::error_code& ec, std::size_t n);
  // on_read() without starting the next read: the frames, end of input or error.
  void handle_read(const boost::system::error_code& ec, std::size_t n);
  // Parses the in_end_ bytes in in_ (frames_); false when the connection was aborted or
  // closed for a protocol error.
  bool consume();
  // ---- the parser's events (FrameSink)
  void on_text(std::string_view text) override;
  void on_refused(std::size_t bytes, bool binary) override;
  void on_control(std::uint8_t opcode, std::string_view payload) override;
  void on_protocol_error(std::string_view reason) override { protocol_error(reason); }
  // Closes the connection with 1002 (protocol error) naming `reason` (at once when our
  // close frame is already queued); false, for consume().
  bool protocol_error(std::string_view reason);
  // closed_ is set: the client's messages are no longer read (its control frames are).
  void closing() {
    closed_ = true;
    frames_.discard_messages();
  }
  // Appends one unfragmented frame (unmasked: the server's) to the outbox.
  void append_frame(std::uint8_t opcode, std::string_view payload);
  void start_write();
  void after_write();
  // Brings what the host counts for this session (WsHost::held) to what it holds now.
  void recount();
  // The host is past max_buffered_bytes after a message was queued: written now, and the
  // session closed when its socket leaves some of it unsent.
  void write_or_close();
  // Closes a session whose replies wait unread while the host is past max_buffered_bytes.
  void close_past_the_cap();
  // The close frame is out: waits for the client's, or closes at once when it sent it first.
  void after_close_sent();
  bool paused() const { return unsent() > limits_.pause_at_unsent_bytes && !close_sent_; }
  std::size_t unsent() const { return outbox_.size() + sending_.size() - sent_; }
  void active() { active_tick_ = host_.tick(); }

  boost::asio::ip::tcp::socket socket_;         // the connection (non-blocking once upgraded)
  std::optional<boost::beast::websocket::stream<boost::asio::ip::tcp::socket>> upgrade_;  // Beast, for the upgrade only
  WsHost& host_;                                // the transport (outlives every session)
  WsLimits limits_;                             // from the transport options
  std::string who_;                             // the transport, for logs
  std::string label_;                           // the client, for logs
  std::uint64_t number_;                        // the connection's number within its transport
  boost::asio::ip::address peer_;               // the client's address
  bool authenticated_ = true;                   // may call services (the host decides at accept)
  boost::beast::flat_buffer http_buffer_;       // the HTTP request
  std::optional<boost::beast::http::request_parser<boost::beast::http::string_body>> parser_;  // until the upgrade
  bool upgraded_ = false;                       // the WebSocket handshake is done

  // reading
  std::vector<char> in_;                        // bytes read (k_read_bytes)...
  std::size_t in_end_ = 0;                      // ...not parsed yet (the ones that came with the upgrade)
  FrameParser frames_;                          // the frames (ws_frames.h): the message being read
  bool reading_ = false;                        // an async read is in flight
  bool handling_ = false;                       // a read's frames are being handled (no new read)
  bool delivered_ = false;                      // a message was handed over during this read
  std::uint32_t heard_tick_ = 0;                // the sweep of the client's last frame
  bool pinged_ = false;                         // a keep-alive ping is unanswered

  // writing
  std::string outbox_;                          // frames waiting for the next write
  std::string sending_;                         // frames being written...
  std::size_t sent_ = 0;                        // ...of which this many are written
  bool writing_ = false;                        // an async write is in flight
  bool message_queued_ = false;                 // a message (not only control frames) queued since the last write ended

  std::size_t in_flight_ = 0;                   // calls, notifications and cancels not finished
  bool closed_ = false;                         // close() or abort() was called (the host was told)
  bool close_queued_ = false;                   // our close frame is in the outbox
  bool close_sent_ = false;                     // ...and written
  bool client_closed_ = false;                  // the client's close frame arrived
  bool aborted_ = false;                        // the socket is closed
  HttpResponse http_response_;                  // a plain HTTP request's answer, being written
  std::size_t counted_ = 0;                     // what the host's held() counts for this session
  boost::asio::steady_timer timer_;             // the handshake's deadline, then the close's
  std::uint32_t active_tick_ = 0;               // the sweep of its last read, write or reply owed
};

}  // namespace simgate::websocket

#endif  // SIMGATE_PLUGINS_WEBSOCKET_WEBSOCKET_SESSION_H_
