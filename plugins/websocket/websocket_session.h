// websocket_session.h — one client connection of the websocket transport: an HTTP request,
// upgraded to a WebSocket, that carries one JSON-RPC message per text message.
//
// A WsSession is the kit's connection (simgate/kit/connection.h: reads, direct reads,
// coalesced writes, the budgets of unsent bytes and of all connections' memory, the idle,
// silent and unfinished-message timers, auth, close) with what is WebSocket's own:
//   - Handshake: Boost.Beast reads one HTTP request (header and body within
//     k_max_request_bytes, within k_handshake_timeout); an upgrade the host accepts
//     (WsHost::refuse_upgrade: the Origin) is answered 101 by Beast; anything else is
//     answered by the host (WsHost::on_http_request: the web app's files, or 404) and
//     closed. The response's own bytes count against max_buffered_bytes while written.
//   - Frames: each read's bytes go to a FrameParser (ws_frames.h: the frames, without a
//     socket; fuzzed), whose events the session handles. Client frames must be masked
//     (else close 1002); text and binary messages, fragmented or not, with pings, pongs
//     and close frames between fragments. A message longer than max_message_bytes (binary
//     or not) is skipped to its end as it arrives (never buffered; the host answers it) and
//     the connection keeps working; other binary messages are handed to the host as such
//     (never buffered either). Reserved bits, opcodes, a continuation out of place, a
//     control frame fragmented or over 125 bytes (the parser's protocol errors), a close
//     frame of one byte (the session's): close 1002. Text is not checked for UTF-8 here:
//     the JSON parser refuses what is not (-32700). What the parser keeps of a message
//     counts against max_buffered_bytes (past it: close 1013), and a message begun (a frame
//     head too) must end within line_timeout_s, as a line must on the line transports.
//   - Messages out: queue_message() frames a text message (the kit's budgets apply); a ping
//     is answered by a pong with its payload (no budget, no activity).
//   - Keep-alive (on the server's sweep): a client silent for `keepalive` (the
//     `keepalive_s` option, 150 s by default) is sent a ping; silent for twice that (it
//     answered no ping either), it is dropped. 0: neither.
//   - Close handshake: the client's close frame is answered with its code, then the socket
//     closes; end()/close_with() send one (after the messages queued), read on (ignoring
//     messages) until the client's close frame or end of input, within k_close_timeout.
//
// Life cycle: created on accept, kit::ConnectionServer::add()ed (start(): the HTTP
// request), kept alive by its pending handlers and by the server's set; close() (the socket
// closed) or close_with() (a close frame first) ends it. Threads: the transport's I/O
// thread only.
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

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/http/message.hpp>
#include <boost/beast/http/parser.hpp>
#include <boost/beast/http/string_body.hpp>
#include <boost/beast/websocket/rfc6455.hpp>
#include <boost/beast/websocket/stream.hpp>

#include "jsonrpc_engine.h"
#include "simgate/kit/connection.h"
#include "static_files.h"
#include "ws_frames.h"

namespace simgate::websocket {

// Whether a close frame may carry `code` (RFC 6455 section 7.4): a client's other codes
// are answered with 1002, not echoed.
bool is_valid_close_code(std::uint16_t code);

class WsSession;

// What a session hands to its transport besides the kit's calls (I/O thread).
class WsHost {
 public:
  virtual ~WsHost() = default;
  // One complete text message.
  virtual void on_message(WsSession& session, std::string_view text) = 0;
  // A message exceeded max_message_bytes (`bytes` arrived before it was skipped), or was
  // binary: the protocol answers it.
  virtual void on_refused_message(WsSession& session, std::size_t bytes, bool binary) = 0;
  // A plain HTTP request (not an upgrade): the response to send before closing.
  virtual HttpResponse on_http_request(const boost::beast::http::request<boost::beast::http::string_body>& request) = 0;
  // An upgrade request: "" to accept it, else the HTTP response refusing it (403: a page of
  // another origin, origin_policy.h), sent before closing.
  virtual std::string refuse_upgrade(const boost::beast::http::request<boost::beast::http::string_body>& request) = 0;
};

// The server of the websocket transport: the kit's connection server with the sessions' host.
class WsServer : public kit::ConnectionServer, public WsHost {
 public:
  using ConnectionServer::ConnectionServer;
};

class WsSession : public kit::Connection, public jsonrpc::SessionCalls, private FrameSink {
 public:
  // `who` names the transport in logs; `number` the connection ("client #3 (127.0.0.1:5123)");
  // `keepalive`: the silence after which the client is pinged (0: never).
  WsSession(boost::asio::ip::tcp::socket socket, WsServer& server, kit::ConnectionLimits limits,
            std::chrono::milliseconds keepalive, std::string_view who, std::uint64_t number);

  std::shared_ptr<WsSession> shared() { return std::static_pointer_cast<WsSession>(shared_from_this()); }

  // Reads the HTTP request, then messages.
  void start() override;

  // ---- the engine's session (jsonrpc_engine.h)
  // Queues one text message (the kit's budgets: the connection may be closed instead).
  void queue_message(std::string_view text) {
    queue_with([text](std::string& out) { append_frame(out, FrameParser::k_text, text); });
  }
  // Queues the message `format(std::string&)` builds, unless more than
  // k_droppable_unsent_bytes wait unsent (false: dropped).
  template <class Format>
  bool queue_droppable_message(Format&& format) {
    return queue_droppable_with([&format](std::string& out) {
      std::string text;
      format(text);
      append_frame(out, FrameParser::k_text, text);
    });
  }
  std::size_t in_flight() const { return unanswered(); }
  void add_in_flight() { expect_reply(); }
  void done(const std::string& key) {
    forget_id(key);
    replied();
  }

  // A close frame with `code` and (at most 123 bytes of) `reason`, after the messages
  // already queued; the socket closes once the client answers it; idempotent.
  void close_with(boost::beast::websocket::close_code code, std::string_view reason);
  // The server's goodbye: 1001 for a timeout, 1008 for a refusal.
  void end(std::string_view reason, kit::Ending how) override;

  // How long the HTTP request may take to arrive.
  static constexpr std::chrono::seconds k_handshake_timeout{30};
  // The largest HTTP request (header and body) accepted before the upgrade.
  static constexpr std::uint32_t k_max_request_bytes = 16 * 1024;
  // The most one read takes.
  static constexpr std::size_t k_read_bytes = 64 * 1024;
  // How long the client has to answer a close frame with its own.
  static constexpr std::chrono::seconds k_close_timeout{5};

  // Appends one unfragmented frame (unmasked: the server's) to `out`.
  static void append_frame(std::string& out, std::uint8_t opcode, std::string_view payload);

 protected:
  // ---- kit::Connection: the framing
  void consume(std::string_view data) override;
  void input_ended() override { close("client left"); }
  bool message_unfinished() const override { return upgraded_ && !frames_.idle(); }
  void on_close() override;
  void on_written() override;
  void on_sweep(std::uint32_t tick) override;

 private:
  void on_request(const boost::system::error_code& ec);
  void on_upgraded(const boost::system::error_code& ec);
  // ---- the parser's events (FrameSink)
  void on_text(std::string_view text) override;
  void on_refused(std::size_t bytes, bool binary) override;
  void on_control(std::uint8_t opcode, std::string_view payload) override;
  void on_protocol_error(std::string_view reason) override { protocol_error(reason); }
  // Closes the connection with 1002 (protocol error) naming `reason` (at once when our
  // close frame is already queued).
  void protocol_error(std::string_view reason);
  // The connection is over for the protocol: the client's messages are no longer read (its
  // control frames are).
  void closing(std::string_view reason) {
    finish(reason);
    frames_.discard_messages();
  }
  // Queues a control frame (a pong, a ping, the close frame).
  void queue_frame(std::uint8_t opcode, std::string_view payload) {
    queue_control([&](std::string& out) { append_frame(out, opcode, payload); });
  }

  WsHost& host_;                                // the transport (outlives every session)
  std::chrono::milliseconds keepalive_;         // keepalive_s (0: no pings)
  boost::beast::flat_buffer http_buffer_;       // the HTTP request
  std::optional<boost::beast::http::request_parser<boost::beast::http::string_body>> parser_;  // until the upgrade
  std::optional<boost::beast::websocket::stream<boost::asio::ip::tcp::socket&>> upgrade_;  // Beast, for the upgrade only
  HttpResponse http_response_;                  // a plain HTTP request's answer, being written
  bool upgraded_ = false;                       // the WebSocket handshake is done

  FrameParser frames_;                          // the frames (ws_frames.h): the message being read
  bool delivered_ = false;                      // a message ended during this read
  std::uint32_t heard_tick_ = 0;                // the sweep of the client's last frame
  bool pinged_ = false;                         // a keep-alive ping is unanswered
  bool close_queued_ = false;                   // our close frame is in the outbox
  bool close_sent_ = false;                     // ...and written
  bool client_closed_ = false;                  // the client's close frame arrived
  boost::asio::steady_timer timer_;             // the handshake's deadline, then the close's
};

}  // namespace simgate::websocket

#endif  // SIMGATE_PLUGINS_WEBSOCKET_WEBSOCKET_SESSION_H_
