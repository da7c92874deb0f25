// simgate/kit/websocket_connection.h — the WebSocket framing on the kit's connection: an
// HTTP request, upgraded to a WebSocket (RFC 6455), that carries text messages both ways.
// The websocket transport (JSON-RPC) and docs/examples/ws_transport.cc are built on it.
//
// A WebSocketConnection is the kit's connection (simgate/kit/connection.h: reads, direct reads,
// coalesced writes, the budgets of unsent bytes and of all connections' memory, the idle,
// silent and unfinished-message timers, auth, close) with what is WebSocket's own:
//   - Handshake: Boost.Beast reads one HTTP request (header and body within
//     k_max_request_bytes, within k_handshake_timeout); an upgrade the host accepts
//     (WebSocketHost::refuse_upgrade: the Origin, origin_policy.h) is answered 101 by Beast;
//     anything else is answered by the host (WebSocketHost::on_http_request: a file, or 404) and
//     closed. The response's own bytes count against max_buffered_bytes while written. The
//     host may pick a subprotocol among those the request offers (WebSocketHost::subprotocol:
//     Sec-WebSocket-Protocol in the 101).
//   - Frames: each read's bytes go to a FrameParser (ws_frames.h: the frames, without a
//     socket; fuzzed), whose events the session handles. Client frames must be masked
//     (else close 1002); text and binary messages, fragmented or not, with pings, pongs
//     and close frames between fragments. A message longer than max_message_bytes (binary
//     or not) is skipped to its end as it arrives (never buffered; the host answers it) and
//     the connection keeps working; other binary messages are refused unread, or for a
//     host whose binary_messages() is true read and handed over as text ones are. Reserved
//     bits, opcodes, a continuation out of place, a control frame fragmented or over 125
//     bytes (the parser's protocol errors), a close frame of one byte (the session's):
//     close 1002. Text is not checked for UTF-8 here:
//     the JSON parser refuses what is not (-32700). What the parser keeps of a message
//     counts against max_buffered_bytes (past it: close 1013), and a message begun (a frame
//     head too) must end within line_timeout_s, as a line must on the line transports.
//   - Messages out: queue_text() and queue_binary() frame a message (the kit's budgets
//     apply; append_frame_head() frames one written in parts, inside the kit's queue_with());
//     a ping is answered by a pong with its payload (no budget, no activity).
//   - Keep-alive (on the server's sweep): a client silent for `keepalive` (the
//     `keepalive_s` option, 150 s by default) is sent a ping; silent for twice that (it
//     answered no ping either), it is dropped. 0: neither.
//   - Close handshake: the client's close frame is answered with its code, then the socket
//     closes; end()/close_with() send one (after the messages queued), read on (ignoring
//     messages) until the client's close frame or end of input, within k_close_timeout.
//
// A transport derives its session from WebSocketConnection (adding its per-connection state)
// and its manager from WebSocketServer (implementing WebSocketHost and ConnectionServer's
// on_messages_done and on_closed: its protocol).
//
// Life cycle: created on accept, ConnectionServer::add()ed (start(): the HTTP
// request), kept alive by its pending handlers and by the server's set; close() (the socket
// closed) or close_with() (a close frame first) ends it. Threads: the transport's I/O
// thread only.
#ifndef SIMGATE_KIT_WEBSOCKET_CONNECTION_H_
#define SIMGATE_KIT_WEBSOCKET_CONNECTION_H_

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

#include "simgate/kit/connection.h"
#include "simgate/kit/http.h"
#include "simgate/kit/origin_policy.h"
#include "simgate/kit/ws_frames.h"

namespace simgate::kit {

// Whether a close frame may carry `code` (RFC 6455 section 7.4): a client's other codes
// are answered with 1002, not echoed.
bool is_valid_close_code(std::uint16_t code);

class WebSocketConnection;

// The token an upgrade request presents (auth.h): its `Authorization: Bearer <token>`
// header, else the `token` parameter of its target's query ("/?token=...", percent-decoded:
// what a browser's WebSocket or Foxglove's connection dialog can send); nullopt: none.
std::optional<std::string> upgrade_token(const HttpRequest& request);

// The options every WebSocket transport reads besides the kit's TcpOptions.
struct WebSocketOptions {
  OriginPolicy origins;  // "allowed_origins" (origin_policy.h)
  // "keepalive_s": the silence after which a client is pinged, and after twice which it is
  // dropped (0: never; up to a day; 150 s, Beast's suggested server timeout)
  std::chrono::milliseconds keepalive{150'000};
  // Takes both keys out of `options` (ConfigError on bad values), so that the transport's
  // own parser (TcpOptions, JSON-RPC's) sees only the rest.
  static WebSocketOptions take(json& options);
  // An upgrade from a page of an origin `origins` refuses (cross-site WebSocket hijacking):
  // its 403 response, logged as `who`'s; "" when it is allowed.
  std::string refuse_upgrade(const HttpRequest& request, std::string_view who,
                             std::string_view server) const;
};

// What a WebSocket connection hands to its transport besides the kit's calls (I/O thread).
class WebSocketHost {
 public:
  virtual ~WebSocketHost() = default;
  // One complete text message.
  virtual void on_message(WebSocketConnection& connection, std::string_view text) = 0;
  // A message exceeded max_message_bytes (`bytes` arrived before it was skipped), or was
  // binary: the protocol answers it.
  virtual void on_refused_message(WebSocketConnection& connection, std::size_t bytes,
                                  bool binary) = 0;
  // The upgrade is done: the connection is a WebSocket (a protocol whose server speaks
  // first sends its greeting here).
  virtual void on_open(WebSocketConnection& /*connection*/) {}
  // Whether binary messages are read (within max_message_bytes, as text ones) and handed to
  // on_binary_message, rather than refused unread. Asked once per connection.
  virtual bool binary_messages() const { return false; }
  // One complete binary message (a host whose binary_messages() is true).
  virtual void on_binary_message(WebSocketConnection& connection, std::string_view data) {
    on_refused_message(connection, data.size(), true);
  }
  // An upgrade the host accepts (refuse_upgrade said ""): the subprotocol to answer with
  // (one the request's Sec-WebSocket-Protocol offers), or "" for none. Refusing a request
  // that offers none the host speaks is refuse_upgrade's.
  virtual std::string subprotocol(
      const boost::beast::http::request<boost::beast::http::string_body>& /*request*/) const {
    return {};
  }
  // A plain HTTP request (not an upgrade): the response to send before closing.
  virtual HttpResponse on_http_request(
      const boost::beast::http::request<boost::beast::http::string_body>& request) = 0;
  // Whether a client that must present the transport's token (auth.h) may do so after the
  // upgrade, in the protocol (JSON-RPC's rpc.login). Either way a token in the upgrade
  // request (upgrade_token) is checked first, a wrong one refused with 401; false: the
  // protocol has no login (Foxglove's), so an upgrade without the token is refused too.
  virtual bool login_after_upgrade() const { return true; }
  // An upgrade request: "" to accept it, else the HTTP response refusing it (403: a page of
  // another origin, origin_policy.h), sent before closing.
  virtual std::string refuse_upgrade(
      const boost::beast::http::request<boost::beast::http::string_body>& request) = 0;
};

// The server of a WebSocket transport: the kit's connection server with the host.
class WebSocketServer : public ConnectionServer, public WebSocketHost {
 public:
  using ConnectionServer::ConnectionServer;
};

class WebSocketConnection : public Connection, private FrameSink {
 public:
  // `who` names the transport in logs; `number` the connection ("client #3 (127.0.0.1:5123)");
  // `keepalive`: the silence after which the client is pinged (0: never).
  WebSocketConnection(boost::asio::ip::tcp::socket socket, WebSocketServer& server,
                      ConnectionLimits limits, std::chrono::milliseconds keepalive,
                      std::string_view who, std::uint64_t number);

  // Reads the HTTP request, then messages.
  void start() override;

  // Queues one text message (the kit's budgets: the connection may be closed instead).
  void queue_text(std::string_view text) {
    queue_with([text](std::string& out) { append_frame(out, FrameParser::k_text, text); });
  }
  // Queues one binary message (the same budgets).
  void queue_binary(std::string_view data) {
    queue_with([data](std::string& out) { append_frame(out, FrameParser::k_binary, data); });
  }
  // Upgraded, and not closed: messages may be queued.
  bool open() const { return upgraded_ && !closed(); }
  // The subprotocol the upgrade agreed (WebSocketHost::subprotocol), "" for none.
  const std::string& subprotocol() const { return subprotocol_; }

  // A close frame with `code` and (at most 123 bytes of) `reason`, after the messages
  // already queued; the socket closes once the client answers it; idempotent.
  void close_with(boost::beast::websocket::close_code code, std::string_view reason);
  // The server's goodbye: 1001 for a timeout, 1008 for a refusal.
  void end(std::string_view reason, Ending how) override;

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
  // Appends the head of one unfragmented frame of `length` payload bytes, which the caller
  // appends next (a message written in parts, without a copy of them).
  static void append_frame_head(std::string& out, std::uint8_t opcode, std::uint64_t length);

 protected:
  // ---- Connection: the framing
  void consume(std::string_view data) override;
  void input_ended() override { close("client left"); }
  bool message_unfinished() const override { return upgraded_ && !frames_.idle(); }
  void on_close() override;
  void on_written() override;
  void on_sweep(std::uint32_t tick) override;

 private:
  std::shared_ptr<WebSocketConnection> shared_self() {
    return std::static_pointer_cast<WebSocketConnection>(shared_from_this());
  }
  void on_request(const boost::system::error_code& ec);
  // The upgrade's token checked (WebSocketHost::login_after_upgrade): "" when it may go on,
  // else the 401 response refusing it.
  std::string authenticate_upgrade(const HttpRequest& request);
  void on_upgraded(const boost::system::error_code& ec);
  // ---- the parser's events (FrameSink)
  void on_text(std::string_view text) override;
  void on_binary(std::string_view data) override;
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

  WebSocketHost& host_;                    // the transport (outlives every connection)
  std::chrono::milliseconds keepalive_;    // keepalive_s (0: no pings)
  boost::beast::flat_buffer http_buffer_;  // the HTTP request
  // until the upgrade
  std::optional<boost::beast::http::request_parser<boost::beast::http::string_body>> parser_;
  std::optional<boost::beast::websocket::stream<boost::asio::ip::tcp::socket&>>
      upgrade_;                 // Beast, for the upgrade only
  HttpResponse http_response_;  // a plain HTTP request's answer, being written
  bool upgraded_ = false;       // the WebSocket handshake is done
  std::string subprotocol_;     // the subprotocol the upgrade agreed ("" none)

  FrameParser frames_;               // the frames (ws_frames.h): the message being read
  bool delivered_ = false;           // a message ended during this read
  std::uint32_t heard_tick_ = 0;     // the sweep of the client's last frame
  bool pinged_ = false;              // a keep-alive ping is unanswered
  bool close_queued_ = false;        // our close frame is in the outbox
  bool close_sent_ = false;          // ...and written
  bool client_closed_ = false;       // the client's close frame arrived
  boost::asio::steady_timer timer_;  // the handshake's deadline, then the close's
};

}  // namespace simgate::kit

#endif  // SIMGATE_KIT_WEBSOCKET_CONNECTION_H_
