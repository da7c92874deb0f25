#include "websocket_request_manager.h"

#include <cmath>
#include <sstream>

#include <boost/beast/http/status.hpp>
#include <boost/beast/http/write.hpp>

#include "simgate/jsonrpc/protocol.h"
#include "simgate/core/log.h"
#include "simgate/core/plugin.h"

namespace simgate::websocket {

namespace asio = boost::asio;
namespace http = boost::beast::http;
using asio::ip::tcp;
using jsonrpc::dump;
using jsonrpc::error_response;
using jsonrpc::code::invalid_request;
using jsonrpc::code::overloaded;

WebSocketRequestManager::Settings WebSocketRequestManager::Settings::parse(const json& options) {
  // the web app's keys first, so that JSON-RPC's parser sees only its own
  json rest = options.is_null() ? json::object() : options;
  Settings s;
  s.web = WebOptions::take(rest);
  s.websocket = kit::WebSocketOptions::take(rest);
  s.rpc = jsonrpc::Options::parse(rest, "websocket", k_default_port);
  return s;
}

WebSocketRequestManager::WebSocketRequestManager(const json& options)
    : WebSocketRequestManager(Settings::parse(options)) {}

WebSocketRequestManager::WebSocketRequestManager(Settings s)
    : JsonRpcEngine("WebSocket service manager", "websocket", std::move(s.rpc)),
      WebSocketServer(name(), options_.tcp),
      // bound now, so that a port in use fails the creation of the transport
      listener_(io_, name(), options_.tcp.host, options_.tcp.port),
      io_thread_(io_, name(), options_.tcp.io_spin),
      websocket_(std::move(s.websocket)) {
  websocket_.origins.bind(options_.tcp.host, listener_.port());
  if (s.web.enabled) web_.emplace(s.web.root, "simgate websocket transport", port_text());
}

WebSocketRequestManager::~WebSocketRequestManager() { stop(); }

std::vector<std::string> WebSocketRequestManager::endpoints() const {
  // "tcp://host:port" -> "ws://host:port/"
  std::string endpoint = listener_.endpoint();
  if (endpoint.starts_with("tcp://")) endpoint.replace(0, 3, "ws");
  return {endpoint + "/"};
}

void WebSocketRequestManager::start() {
  kit::TcpListener::Handlers handlers{
      [this](tcp::socket socket) { accept(std::move(socket)); },
      [this](const tcp::endpoint& peer) { return refusal_reason(peer); },
      [](const std::string& why) {
        // the client is still sending its HTTP request: an HTTP answer, the JSON-RPC error
        // as its body
        const std::string body =
            dump(error_response(nullptr, overloaded, "Overloaded: " + why)) + "\n";
        return kit::unavailable_response(body, "application/json");
      }};
  if (io_thread_.start(
          [this, handlers = std::move(handlers)]() mutable {
            deliver_here();
            listener_.start(std::move(handlers));
          },
          direct_reads())) {
    log::info("websocket: listening on ", endpoints().front());
    if (web_) {
      std::string page = endpoints().front();
      page.replace(0, 2, "http");  // "ws://" -> "http://"
      std::error_code ec;
      if (std::filesystem::is_directory(web_->root(), ec))
        log::info("websocket: web app on ", page, " (files from ", web_->root().string(), ")");
      else
        log::warning("websocket: no web app: ", web_->root().string(),
                     " is not a directory (build the tree, or set web_root; docs/web.md)");
    }
  }
}

void WebSocketRequestManager::stop() {
  if (!io_thread_.stop([this] { shutdown_io(); })) return;
  finish_stop();
}

void WebSocketRequestManager::shutdown_io() {
  stop_io();
  listener_.close();
  close_all();
}

void WebSocketRequestManager::accept(tcp::socket socket) {
  kit::ConnectionLimits limits = kit::ConnectionLimits::from(options_.tcp);
  // a client that lets its replies pile up stops being read at half the unsent budget
  limits.pause_at_unsent_bytes = options_.tcp.max_unsent_bytes / 2;
  limits.read_bytes = WsSession::k_read_bytes;
  kit::WebSocketServer& server = *this;
  const std::uint64_t number = next_session_++;
  client_arrived(number);
  add(std::make_shared<WsSession>(std::move(socket), server, limits, websocket_.keepalive, name(),
                                  number));
}

// ---- kit::WebSocketServer: the framing (I/O thread)

void WebSocketRequestManager::on_message(kit::WebSocketConnection& session, std::string_view text) {
  handle_message(static_cast<WsSession&>(session), text);
}

void WebSocketRequestManager::on_refused_message(kit::WebSocketConnection& session,
                                                 std::size_t bytes, bool binary) {
  if (binary) {
    session.queue_text(
        dump(error_response(nullptr, invalid_request,
                            "Invalid Request: a binary message (send JSON-RPC as text messages)",
                            json{{"reason", "binary message"}, {"bytes", bytes}})));
    return;
  }
  const auto max = options_.tcp.max_message_bytes;
  session.queue_text(dump(error_response(
      nullptr, invalid_request,
      "Invalid Request: message exceeds max_message_bytes (" + std::to_string(max) + ")",
      json{{"reason", "message too large"}, {"bytes", bytes}, {"max_message_bytes", max}})));
}

void WebSocketRequestManager::on_messages_done(kit::Connection& /*session*/, bool read_finished) {
  // the calls of a read go to the core together; they are answered at its end
  if (read_finished) flush_submissions();
}

std::string WebSocketRequestManager::port_text() const {
  return "simgate websocket transport: JSON-RPC 2.0 over WebSocket; connect with a WebSocket "
         "client to " +
         endpoints().front() + " (docs/transports/websocket.md)\n";
}

kit::HttpResponse WebSocketRequestManager::on_http_request(
    const http::request<http::string_body>& request) {
  // past the memory cap (clients that do not read): nothing more is held for a new one
  if (held().over()) {
    log::warning(name(), ": HTTP request answered 503: the transport holds more than ",
                 held().max(), " bytes for its clients (max_buffered_bytes)");
    return kit::HttpResponse{kit::plain_http_response(
        request, http::status::service_unavailable,
        "503 the server holds too much for its clients now (max_buffered_bytes); try again later\n",
        k_server)};
  }
  // the web app's files
  if (web_) return web_->answer(request);
  // no web app (`web` false): a short text says what this port is
  return kit::HttpResponse{
      kit::plain_http_response(request, http::status::not_found, port_text(), k_server)};
}

std::string WebSocketRequestManager::refuse_upgrade(
    const http::request<http::string_body>& request) {
  // a page of another site must not drive the simulation (cross-site WebSocket hijacking)
  return websocket_.refuse_upgrade(request, name(), k_server);
}

void WebSocketRequestManager::on_closed(kit::Connection& session) {
  session_closed(static_cast<WsSession&>(session));
}

}  // namespace simgate::websocket

SIMGATE_TRANSPORT_PLUGIN(websocket, simgate::websocket::WebSocketRequestManager, "0.1.0", "host",
                         "port", "max_message_bytes", "max_depth", "max_in_flight",
                         "max_unsent_bytes", "max_buffered_bytes", "max_connections",
                         "max_connections_per_peer", "idle_timeout_s", "idle_evict_s",
                         "line_timeout_s", "io_spin_us", "on_disconnect", "global_policy", "auth",
                         "progress_interval_ms", "stream_queue", "web", "web_root",
                         "allowed_origins", "keepalive_s")
