// plugins/websocket/websocket_request_manager.h — JSON-RPC 2.0 over WebSocket.
//
// What: the JSON-RPC engine (simgate/jsonrpc/engine.h: the very protocol of the jsonrpc
// transport, compiled once, not copied) framed as one message (request or batch) per
// WebSocket text message, in both directions, on the kit's WebSocket connections
// (simgate/kit/websocket_connection.h; a session: websocket_session.h). Only
// the framing differs from the TCP transport: discover, named params, async out of order,
// cancel, batches, login, deadlines, progress and stream subscriptions are the same code.
// A binary message, or a text message over max_message_bytes, is answered -32600 and the
// connection keeps working. A plain HTTP request on the port (no upgrade) gets a file of the
// web app (static_files.h, docs/web.md), or 404 with a short text when `web` is false.
// Wire: docs/transports/websocket.md.
//
// Life cycle: the constructor reads the options (ConfigError on bad ones) and binds the
// listening socket (std::runtime_error if the port is taken); start() launches the I/O
// thread; stop() closes every connection, joins the thread and finishes what is still
// pending with Failure::shutdown. stop() is idempotent and the destructor calls it.
//
// Its connections are the kit's (simgate/kit/connection.h), as the TCP transports' are: the
// same options with the same meaning (idle_timeout_s, idle_evict_s, line_timeout_s for an
// unfinished message, max_connections_per_peer, max_unsent_bytes, max_buffered_bytes for
// what all connections hold); kit/websocket_connection.h adds the WebSocket handshake,
// frames, keep-alive and close handshake.
//
// Threads: one I/O thread runs the io_context (accept, handshake, read, parse, hand over,
// write), polling a little before it sleeps while events come close together (io_spin_us,
// simgate/kit/idle_spin.h); while it polls, it reads the socket of a client sending alone
// itself (DirectReads), as the TCP transport does. The calls of one read go to the core
// together, run on this thread when the simulation lock is free; sessions and pending
// calls are touched by the I/O thread only.
#ifndef SIMGATE_PLUGINS_WEBSOCKET_WEBSOCKET_REQUEST_MANAGER_H_
#define SIMGATE_PLUGINS_WEBSOCKET_WEBSOCKET_REQUEST_MANAGER_H_

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <boost/asio/ip/tcp.hpp>

#include "simgate/jsonrpc/engine.h"
#include "simgate/kit/origin_policy.h"
#include "simgate/kit/tcp_server.h"
#include "static_files.h"
#include "websocket_session.h"

namespace simgate::websocket {

// The default port (jsonrpc has 4001, the socket transport 4000).
inline constexpr std::uint16_t k_default_port = 8090;

class WebSocketRequestManager : public jsonrpc::JsonRpcEngine, private kit::WebSocketServer {
 public:
  // Parses the options and binds; throws ConfigError or std::runtime_error.
  explicit WebSocketRequestManager(const json& options);
  ~WebSocketRequestManager() override;
  // What the constructor checks of `options`, without binding (the plugin's validate).
  static std::vector<std::string> validate_options(const json& options) {
    return Settings::parse(options).rpc.tcp.warnings;
  }
  std::size_t client_count() const override { return connection_count(); }

  void start() override;
  void stop() override;
  // {"ws://127.0.0.1:<port>/"} with the bound port.
  std::vector<std::string> endpoints() const override;

  std::uint16_t port() const { return listener_.port(); }

 private:
  // The options: JSON-RPC's (jsonrpc::Options), the web app's (WebOptions), and every
  // WebSocket transport's (kit::WebSocketOptions: the pages allowed to connect, keepalive_s).
  struct Settings {
    jsonrpc::Options rpc;
    WebOptions web;
    kit::WebSocketOptions websocket;
    static Settings parse(const json& options);
  };
  // The Server header of its HTTP answers.
  static constexpr std::string_view k_server = "simgate websocket transport";
  explicit WebSocketRequestManager(Settings settings);
  // The 404 body that says what this port is.
  std::string port_text() const;

  // JsonRpcEngine: the end of a burst
  void flush_replies() override { flush_touched(); }

  // kit::WebSocketServer: the framing (I/O thread)
  void on_message(kit::WebSocketConnection& session, std::string_view text) override;
  void on_refused_message(kit::WebSocketConnection& session, std::size_t bytes,
                          bool binary) override;
  void on_messages_done(kit::Connection& session, bool read_finished) override;
  kit::HttpResponse on_http_request(
      const boost::beast::http::request<boost::beast::http::string_body>& request) override;
  std::string refuse_upgrade(
      const boost::beast::http::request<boost::beast::http::string_body>& request) override;
  void on_closed(kit::Connection& session) override;

  // A new connection (refusal_reason keeps the count under max_connections and
  // max_connections_per_peer).
  void accept(boost::asio::ip::tcp::socket socket);
  void shutdown_io();

  kit::TcpListener listener_;        // the listening socket, bound in the constructor
  kit::IoThread io_thread_;          // runs io_
  std::uint64_t next_session_ = 1;   // numbers connections in logs (I/O thread)
  std::optional<StaticFiles> web_;   // the web app's files (none: `web` false)
  kit::WebSocketOptions websocket_;  // allowed_origins (bound to the port), keepalive_s
};

}  // namespace simgate::websocket

#endif  // SIMGATE_PLUGINS_WEBSOCKET_WEBSOCKET_REQUEST_MANAGER_H_
