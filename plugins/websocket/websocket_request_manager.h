// plugins/websocket/websocket_request_manager.h — JSON-RPC 2.0 over WebSocket.
//
// What: the JSON-RPC engine (plugins/jsonrpc/jsonrpc_engine.h: the very protocol of the
// jsonrpc transport, shared, not copied) framed as one message (request or batch) per
// WebSocket text message, in both directions, over Boost.Beast (websocket_session.h). Only
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
// Connections held without use are treated as by the TCP transports
// (kit/connection_rules.h): idle_timeout_s closes one idle that long, idle_evict_s lets a
// newcomer take the place of the one idle longest at max_connections, and
// max_connections_per_peer bounds the connections of one non-loopback address.
//
// Threads: one I/O thread runs the io_context (accept, handshake, read, parse, hand over,
// write), polling a little before it sleeps while events come close together (io_spin_us,
// simgate/kit/idle_spin.h); while it polls, it reads the socket of a client sending alone
// itself (DirectReads), as the TCP transport does. The calls of one message go to the core together, run on this
// thread when the simulation lock is free; sessions and pending calls are touched by the
// I/O thread only.
#ifndef SIMGATE_PLUGINS_WEBSOCKET_WEBSOCKET_REQUEST_MANAGER_H_
#define SIMGATE_PLUGINS_WEBSOCKET_WEBSOCKET_REQUEST_MANAGER_H_

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <unordered_set>
#include <vector>

#include <boost/asio/ip/tcp.hpp>

#include "jsonrpc_engine.h"
#include "origin_policy.h"
#include "simgate/kit/connection_rules.h"
#include "simgate/kit/idle_spin.h"
#include "simgate/kit/read_split.h"
#include "simgate/kit/tcp_server.h"
#include "static_files.h"
#include "websocket_session.h"

namespace simgate::websocket {

// The default port (jsonrpc has 4001, the socket transport 4000).
inline constexpr std::uint16_t k_default_port = 8090;

class WebSocketRequestManager : public jsonrpc::JsonRpcEngine<WsSession>, private WsHost {
 public:
  // Parses the options and binds; throws ConfigError or std::runtime_error.
  explicit WebSocketRequestManager(const json& options);
  ~WebSocketRequestManager() override;
  // What the constructor checks of `options`, without binding (the plugin's validate).
  static std::vector<std::string> validate_options(const json& options) {
    return Settings::parse(options).rpc.tcp.warnings;
  }
  std::size_t client_count() const override { return count_.load(std::memory_order_relaxed); }

  void start() override;
  void stop() override;
  // {"ws://127.0.0.1:<port>/"} with the bound port.
  std::vector<std::string> endpoints() const override;

  std::uint16_t port() const { return listener_.port(); }

 private:
  // The options: JSON-RPC's (jsonrpc::Options), the web app's (WebOptions), the pages
  // allowed to connect (OriginPolicy) and the keep-alive (`keepalive_s`, WsLimits).
  struct Settings {
    jsonrpc::Options rpc;
    WebOptions web;
    OriginPolicy origins;
    std::chrono::milliseconds keepalive = WsLimits{}.keepalive;
    static Settings parse(const json& options);
  };
  explicit WebSocketRequestManager(Settings settings);
  // The 404 body that says what this port is.
  std::string port_text() const;
  // A plain-text HTTP response (the 404 without a web app, a refused upgrade's 403, 503).
  std::string plain_response(const boost::beast::http::request<boost::beast::http::string_body>& request,
                             boost::beast::http::status status, const std::string& body) const;

  // JsonRpcEngine: the end of a burst
  void flush_replies() override;

  // WsHost: the framing (I/O thread)
  void on_message(WsSession& session, std::string_view text) override;
  void on_refused_message(WsSession& session, std::size_t bytes, bool binary) override;
  void on_read_done(WsSession& session) override;
  HttpResponse on_http_request(const boost::beast::http::request<boost::beast::http::string_body>& request) override;
  std::string refuse_upgrade(const boost::beast::http::request<boost::beast::http::string_body>& request) override;
  void on_closed(WsSession& session) override;
  void touch(WsSession& session) override;
  std::uint32_t tick() const override { return tick_; }
  kit::HeldBytes& held() override { return held_; }
  bool watch(WsSession& session) override;

  // A new connection (refusal_reason keeps the count under max_connections and
  // max_connections_per_peer).
  void accept(boost::asio::ip::tcp::socket socket);
  // Why a connection from `peer` is refused, or "": at max_connections, after the session
  // idle (or silent) longest was closed to make room when idle_evict_s allows it
  // (kit/connection_rules.h, as the TCP transports); or its address at its per-peer limit.
  std::string refusal_reason(const boost::asio::ip::tcp::endpoint& peer);
  // Every k_connection_sweep while sessions are open: the clock of idle_ticks, idle_timeout_s.
  void schedule_sweep();
  void sweep();
  void shutdown_io();

  kit::TcpListener listener_;                             // the listening socket, bound in the constructor
  kit::IoThread io_thread_;                               // runs io_
  kit::ReadSplit read_split_;                             // tells a lone client (I/O thread)
  kit::DirectReads<WsSession> direct_;                    // the lone client read without the event loop (I/O thread)
  std::uint64_t next_session_ = 1;                        // numbers connections in logs (I/O thread)
  std::unordered_set<std::shared_ptr<WsSession>> sessions_;  // open connections (I/O thread)
  std::atomic<std::size_t> count_{0};                     // sessions_.size(), for any thread
  std::vector<std::shared_ptr<WsSession>> touched_;       // messages queued, not yet written (I/O thread)
  kit::PeerCounts per_peer_;                              // max_connections_per_peer (I/O thread)
  std::uint32_t tick_ = 0;                                // sweeps so far (I/O thread)
  std::optional<boost::asio::steady_timer> sweep_timer_;  // while sessions are open
  bool sweeping_ = false;                                 // a sweep is scheduled
  std::optional<StaticFiles> web_;                        // the web app's files (none: `web` false)
  OriginPolicy origins_;                                  // allowed_origins, bound to the port
  std::chrono::milliseconds keepalive_;                   // keepalive_s (WsLimits::keepalive)
  kit::HeldBytes held_;                                   // what all sessions hold (max_buffered_bytes; I/O thread)
};

}  // namespace simgate::websocket

#endif  // SIMGATE_PLUGINS_WEBSOCKET_WEBSOCKET_REQUEST_MANAGER_H_
