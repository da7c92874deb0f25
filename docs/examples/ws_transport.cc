// ws_transport.cc — a complete WebSocket transport on simgate's transport kit: the second
// example of docs/writing-a-transport.md, built and tested with the tree
// (tests/kit/ws_transport_test.cc).
//
// Protocol "wsjson": one request per WebSocket text message,
// {"id": <any>, "call": "<component>.<service>", "params": <array or object>}; one reply per
// text message, {"id": <the same>, "status": "SUCCESS|FAILED|PREEMPTED", "value": <JSON>}.
// The kit does the rest: options, listener, I/O thread, the HTTP upgrade and the pages that
// may open it (`allowed_origins`), frames, ping/pong, the close handshake, limits, timeouts,
// coalesced writes, direct reads.
#include <memory>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include <boost/asio/post.hpp>

#include "simgate/core/config.h"
#include "simgate/core/plugin.h"
#include "simgate/kit/origin_policy.h"
#include "simgate/kit/tcp_server.h"
#include "simgate/kit/websocket_connection.h"

namespace wsjson {

namespace asio = boost::asio;
namespace kit = simgate::kit;
using simgate::json;
using Request = boost::beast::http::request<boost::beast::http::string_body>;

class WsTransport : public simgate::RequestManager, private kit::WebSocketServer {
 public:
  explicit WsTransport(const json& options) : WsTransport(parse(options)) {}
  ~WsTransport() override {
    stop();
    abandon_pending("the wsjson transport has stopped");
  }
  static void validate_options(const json& options) { (void)parse(options); }

  void start() override {
    kit::TcpListener::Handlers handlers{
        [this](asio::ip::tcp::socket socket) { accept(std::move(socket)); },
        [this](const asio::ip::tcp::endpoint& peer) { return refusal_reason(peer); },
        [](const std::string& why) { return kit::unavailable_response(why + "\n"); }};
    io_thread_.start(
        [this, handlers = std::move(handlers)]() mutable {
          // outcomes produced on other threads are handed to this one, the I/O thread
          deliver_on_this_thread([this] { asio::post(io_, [this] { flush_replies(); }); });
          listener_.start(std::move(handlers));
        },
        direct_reads());
  }
  void stop() override {
    if (io_thread_.stop([this] { shutdown_io(); })) deliver_on_any_thread();
  }
  std::vector<std::string> endpoints() const override {
    return {"ws" + listener_.endpoint().substr(3) + "/"};
  }
  std::size_t client_count() const override { return connection_count(); }

 protected:
  // The I/O thread: the reply goes to the connection that asked, if it is still there.
  void on_service_completion(simgate::RequestId id, simgate::Outcome&& outcome) override {
    auto it = pending_.find(id);
    if (it == pending_.end()) return;
    const Pending pending = std::move(it->second);
    pending_.erase(it);
    auto connection = pending.connection.lock();
    if (!connection) return;
    const json value = outcome.value                                ? *outcome.value
                       : outcome.status == simgate::Status::success ? json(nullptr)
                                                                    : json(outcome.message);
    reply(*connection, pending.client_id, to_string(outcome.status), value);
    connection->replied();
  }

 private:
  struct Settings {
    kit::TcpOptions tcp;
    kit::OriginPolicy origins;
  };
  // Where a request's reply goes.
  struct Pending {
    std::weak_ptr<kit::WebSocketConnection> connection;
    json client_id;
  };

  explicit WsTransport(Settings settings)
      : RequestManager("wsjson service manager"),
        WebSocketServer(name(), settings.tcp),
        options_(std::move(settings.tcp)),
        origins_(std::move(settings.origins)),
        listener_(io_, name(), options_.host,
                  options_.port),  // bound now: a port in use fails here
        io_thread_(io_, name(), options_.io_spin) {
    set_global_policy(options_.global_policy);
    origins_.bind(options_.host, listener_.port());
  }

  static Settings parse(const json& options) {
    json rest = options.is_null() ? json::object() : options;
    Settings s;
    s.origins = kit::OriginPolicy::take(rest);  // "allowed_origins"
    simgate::ConfigObject config(rest, "");
    kit::TcpOptions defaults;
    defaults.port = 8100;
    s.tcp = kit::TcpOptions::read(config, defaults, "wsjson");
    s.tcp.finish(config);  // unknown keys are refused
    return s;
  }

  void accept(asio::ip::tcp::socket socket) {
    kit::ConnectionLimits limits = kit::ConnectionLimits::from(options_);
    limits.pause_at_unanswered = options_.max_in_flight;  // backpressure: reading waits for answers
    kit::WebSocketServer& server = *this;
    add(std::make_shared<kit::WebSocketConnection>(
        std::move(socket), server, limits, std::chrono::seconds(150), name(), ++connections_));
  }

  // ---- kit::WebSocketServer: the protocol (I/O thread)
  void on_message(kit::WebSocketConnection& connection, std::string_view text) override {
    const json request = json::parse(text, nullptr, /*allow_exceptions=*/false);
    const json id = request.is_object() ? request.value("id", json()) : json();
    const std::string call = request.is_object() ? request.value("call", "") : "";
    const auto dot = call.rfind('.');
    if (dot == std::string::npos || dot == 0 || dot + 1 == call.size())
      return reply(connection, id, "FAILED",
                   "expected {\"id\", \"call\": \"component.service\", \"params\"}");
    const simgate::RequestId request_id = new_request_id();
    pending_[request_id] = Pending{
        std::static_pointer_cast<kit::WebSocketConnection>(connection.shared_from_this()), id};
    connection.expect_reply();
    calls_.emplace_back(request_id, simgate::Call{call.substr(0, dot), call.substr(dot + 1),
                                                  request.value("params", json::array())});
  }
  void on_refused_message(kit::WebSocketConnection& connection, std::size_t bytes,
                          bool binary) override {
    reply(connection, nullptr, "FAILED",
          binary ? "binary messages are not requests"
                 : std::to_string(bytes) + " bytes: over max_message_bytes");
  }
  void on_messages_done(kit::Connection&, bool) override {
    // the calls read so far go to the core together: run here when the simulation lock is
    // free (their replies are queued at once), else on the simulation thread
    if (!calls_.empty()) run_or_submit(std::exchange(calls_, {}));
  }
  void on_closed(kit::Connection&) override {}  // its pending calls still end (reply() drops them)
  kit::HttpResponse on_http_request(const Request&) override {
    return kit::HttpResponse{
        "HTTP/1.1 404 Not Found\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"};
  }
  std::string refuse_upgrade(const Request& request) override {
    // a page of another site must not drive the simulation (cross-site WebSocket hijacking)
    const auto it = request.find(boost::beast::http::field::origin);
    if (it == request.end() ||
        origins_.allows(std::string_view(it->value().data(), it->value().size())))
      return {};
    return "HTTP/1.1 403 Forbidden\r\nContent-Length: 0\r\nConnection: close\r\n\r\n";
  }

  void reply(kit::WebSocketConnection& connection, const json& id, std::string_view status,
             const json& value) {
    // invalid UTF-8 in a service's string is replaced, never thrown
    connection.queue_text(json{{"id", id}, {"status", status}, {"value", value}}.dump(
        -1, ' ', false, json::error_handler_t::replace));
  }
  // I/O thread, woken by the core: the outcomes of the simulation thread, one write each.
  void flush_replies() {
    deliver_handed_over();
    flush_touched();
  }
  void shutdown_io() {
    listener_.close();
    close_all();
    pending_.clear();
  }

  kit::TcpOptions options_;
  kit::OriginPolicy origins_;
  asio::io_context io_;
  kit::TcpListener listener_;
  kit::IoThread io_thread_;
  std::uint64_t connections_ = 0;                                    // numbers connections in logs
  std::unordered_map<simgate::RequestId, Pending> pending_;          // unanswered requests
  std::vector<std::pair<simgate::RequestId, simgate::Call>> calls_;  // read, not yet run
};

}  // namespace wsjson

SIMGATE_TRANSPORT_PLUGIN(wsjson, wsjson::WsTransport, "0.1.0", "host", "port", "max_connections",
                         "max_message_bytes", "max_unsent_bytes", "max_in_flight", "io_spin_us",
                         "on_disconnect", "global_policy", "idle_timeout_s", "idle_evict_s",
                         "line_timeout_s", "max_buffered_bytes", "max_connections_per_peer", "auth",
                         "progress_interval_ms", "allowed_origins")
