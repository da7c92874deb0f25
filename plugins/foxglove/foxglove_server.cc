#include "foxglove_server.h"

#include "foxglove_client.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <boost/asio/post.hpp>

#include "simgate/core/log.h"
#include "simgate/core/plugin.h"
#include "simgate/core/streams.h"
#include "simgate/core/text.h"

namespace simgate::foxglove {

namespace asio = boost::asio;
namespace http = boost::beast::http;
using asio::ip::tcp;

// ---- options and life cycle

FoxgloveServer::Settings FoxgloveServer::Settings::parse(const json& options) {
  json rest = options.is_null() ? json::object() : options;
  Settings s;
  s.websocket = kit::WebSocketOptions::take(rest);
  ConfigObject config(rest, "");
  kit::TcpOptions defaults;
  defaults.port = k_default_port;
  s.tcp = kit::TcpOptions::read(config, defaults, "foxglove");
  s.stream_queue = static_cast<std::size_t>(config.get_int("stream_queue", 4, 1, 1024));
  s.time_hz = config.get_number("time_hz", 30, 0, 1000);
  s.rewind_interval_s = config.get_number("rewind_interval_s", 1, 0, 86'400);
  s.rewind_states = static_cast<std::size_t>(config.get_int("rewind_states", 60, 1, 100'000));
  s.tcp.finish(config);
  return s;
}

std::vector<std::string> FoxgloveServer::validate_options(const json& options) {
  return Settings::parse(options).tcp.warnings;
}

FoxgloveServer::FoxgloveServer(const json& options) : FoxgloveServer(Settings::parse(options)) {}

FoxgloveServer::FoxgloveServer(Settings settings)
    : RequestManager("Foxglove service manager"),
      WebSocketServer(name(), settings.tcp),
      settings_(std::move(settings)),
      // bound now, so that a port in use fails the creation of the transport
      listener_(io_, name(), settings_.tcp.host, settings_.tcp.port),
      io_thread_(io_, name(), settings_.tcp.io_spin),
      time_timer_(io_),
      session_id_(std::to_string(std::chrono::duration_cast<std::chrono::milliseconds>(
                                     std::chrono::system_clock::now().time_since_epoch())
                                     .count())) {
  set_global_policy(settings_.tcp.global_policy);
  settings_.websocket.origins.bind(settings_.tcp.host, listener_.port());
  for (const auto& w : settings_.tcp.warnings) log::warning(name(), ": ", w);
}

FoxgloveServer::~FoxgloveServer() { stop(); }

std::vector<std::string> FoxgloveServer::endpoints() const {
  std::string endpoint = listener_.endpoint();  // "tcp://host:port" -> "ws://host:port/"
  if (endpoint.starts_with("tcp://")) endpoint.replace(0, 3, "ws");
  return {endpoint + "/"};
}

void FoxgloveServer::start() {
  kit::TcpListener::Handlers handlers{
      [this](tcp::socket socket) { accept(std::move(socket)); },
      [this](const tcp::endpoint& peer) { return refusal_reason(peer); },
      [](const std::string& why) { return kit::unavailable_response(why + "\n"); }};
  if (!io_thread_.start(
          [this, handlers = std::move(handlers)]() mutable {
            // outcomes produced on other threads are handed to this one
            deliver_on_this_thread([this] { asio::post(io_, [this] { flush_replies(); }); });
            listener_.start(std::move(handlers));
            log_observer_ = log::add_observer(
                [this](log::Level level, std::string_view text) { log_line(level, text); });
            refresh_catalog();
            ask_replay_range();
            tick_time();
          },
          direct_reads()))
    return;
  log::info("foxglove: listening on ", endpoints().front(),
            " (open it in Foxglove: Open connection, Foxglove WebSocket)");
}

void FoxgloveServer::stop() {
  if (!io_thread_.stop([this] { shutdown_io(); })) return;
  deliver_on_any_thread();  // the connections are gone: outcomes from now on go nowhere
  abandon_pending("the foxglove transport has stopped");
}

void FoxgloveServer::shutdown_io() {
  // a tick already due when the timer is cancelled still runs: it must not arm it again,
  // or the I/O thread never ends (FoxgloveGatewayTest.ItStopsWhileItsTimeTicks)
  stopping_ = true;
  if (log_observer_ != 0) log::remove_observer(std::exchange(log_observer_, 0));
  time_timer_.cancel();
  listener_.close();
  close_all();
  pending_.clear();
}

void FoxgloveServer::accept(tcp::socket socket) {
  kit::ConnectionLimits limits = kit::ConnectionLimits::from(settings_.tcp);
  // a client that lets its replies pile up stops being read at half the unsent budget
  limits.pause_at_unsent_bytes = settings_.tcp.max_unsent_bytes / 2;
  limits.read_bytes = kit::WebSocketConnection::k_read_bytes;
  kit::WebSocketServer& server = *this;
  const std::uint64_t number = next_client_++;
  client_arrived(number);
  add(std::make_shared<Client>(std::move(socket), server, limits, settings_.websocket.keepalive,
                               name(), number));
}

void FoxgloveServer::flush_replies() {
  deliver_handed_over();
  flush_touched();
}

// ---- the handshake

std::string FoxgloveServer::subprotocol(const kit::HttpRequest& request) const {
  const auto it = request.find(http::field::sec_websocket_protocol);
  if (it == request.end()) return {};
  return pick_subprotocol(std::string_view(it->value().data(), it->value().size()));
}

std::string FoxgloveServer::refuse_upgrade(const kit::HttpRequest& request) {
  if (std::string refused = settings_.websocket.refuse_upgrade(request, name(), k_server);
      !refused.empty())
    return refused;
  if (!subprotocol(request).empty()) return {};
  // as Foxglove's own servers do: no common subprotocol, no connection
  return kit::plain_http_response(
      request, http::status::bad_request,
      std::string(k_server) + ": offer the WebSocket subprotocol " + std::string(k_subprotocol) +
          " (or " + std::string(k_sdk_subprotocol) +
          ") in Sec-WebSocket-Protocol; this port speaks Foxglove's WebSocket protocol "
          "(docs/transports/foxglove.md)\n",
      k_server);
}

kit::HttpResponse FoxgloveServer::on_http_request(const kit::HttpRequest& request) {
  return kit::HttpResponse{kit::plain_http_response(
      request, http::status::not_found,
      std::string(k_server) + ": Foxglove's WebSocket protocol; open " + endpoints().front() +
          " in Foxglove or Lichtblick (Open connection, Foxglove WebSocket; "
          "docs/transports/foxglove.md)\n",
      k_server)};
}

std::vector<std::string> FoxgloveServer::capabilities() const {
  std::vector<std::string> all{"clientPublish", "parameters", "parametersSubscribe", "services",
                               "time"};
  if (playback_offered()) all.push_back("playbackControl");
  return all;
}

void FoxgloveServer::on_open(kit::WebSocketConnection& connection) {
  // the greeting: who we are, then every channel and service there is now
  std::optional<std::pair<std::uint64_t, std::uint64_t>> range;
  if (playback_offered()) range = playback_range();
  connection.queue_text(server_info(
      k_server, capabilities(), {"json"},
      json{{"simgate", "Foxglove WebSocket transport"}, {"subprotocol", connection.subprotocol()}},
      session_id_, range));
  std::vector<Channel> channels;
  for (const auto& c : channels_) channels.push_back(c.channel);
  connection.queue_text(advertise(channels));
  if (!services_.empty()) connection.queue_text(advertise_services(services_));
}

// ---- messages (I/O thread)

void FoxgloveServer::on_message(kit::WebSocketConnection& connection, std::string_view text) {
  Client& client = static_cast<Client&>(connection);
  const ClientText message = read_text(text);
  if (const auto* s = std::get_if<Subscribe>(&message)) {
    subscribe(client, *s);
  } else if (const auto* u = std::get_if<Unsubscribe>(&message)) {
    unsubscribe(client, *u);
  } else if (const auto* a = std::get_if<ClientAdvertise>(&message)) {
    advertise_publications(client, *a);
  } else if (const auto* ua = std::get_if<ClientUnadvertise>(&message)) {
    for (std::uint32_t id : ua->channel_ids)
      if (!client.publications.erase(id))
        complain(client, Level::warning,
                 "unadvertise: no client channel " + std::to_string(id) + " on this connection");
  } else if (const auto* get = std::get_if<GetParameters>(&message)) {
    get_parameters(client, *get);
  } else if (const auto* set = std::get_if<SetParameters>(&message)) {
    set_parameters(client, *set);
  } else if (const auto* s = std::get_if<SubscribeParameterUpdates>(&message)) {
    if (s->names.empty()) client.all_parameters = true;
    client.parameters.insert(s->names.begin(), s->names.end());
    get_parameters(client, GetParameters{s->names, ""});  // their values now; then changes
    poll_parameters();
  } else if (const auto* us = std::get_if<UnsubscribeParameterUpdates>(&message)) {
    if (us->names.empty()) {
      client.all_parameters = false;
      client.parameters.clear();
    }
    for (const auto& n : us->names) client.parameters.erase(n);
  } else if (const auto* other = std::get_if<OtherOp>(&message)) {
    complain(client, Level::error,
             "op '" + other->op +
                 "' is not served here (this server's capabilities: " + join(capabilities()) + ")");
  } else {
    complain(client, Level::error, std::get<Malformed>(message).reason);
  }
}

void FoxgloveServer::on_binary_message(kit::WebSocketConnection& connection,
                                       std::string_view data) {
  Client& client = static_cast<Client&>(connection);
  const ClientBinary message = read_binary(data);
  if (const auto* call = std::get_if<ServiceCallRequest>(&message)) {
    call_service(client, *call);
  } else if (const auto* published = std::get_if<ClientMessageData>(&message)) {
    publish(client, *published);
  } else if (const auto* playback = std::get_if<PlaybackControlRequest>(&message)) {
    control_playback(client, *playback);
  } else {
    complain(client, Level::error, std::get<Malformed>(message).reason);
  }
}

void FoxgloveServer::on_refused_message(kit::WebSocketConnection& connection, std::size_t bytes,
                                        bool /*binary*/) {
  complain(static_cast<Client&>(connection), Level::error,
           "a message of " + std::to_string(bytes) + " bytes is over max_message_bytes (" +
               std::to_string(settings_.tcp.max_message_bytes) + "); it was skipped");
}

void FoxgloveServer::on_messages_done(kit::Connection& /*connection*/, bool /*read_finished*/) {
  // the calls read so far go to the core together: run here when the simulation lock is
  // free (their answers are queued at once), else on the simulation thread
  if (!calls_.empty()) run_or_submit(std::exchange(calls_, {}));
}

void FoxgloveServer::on_closed(kit::Connection& connection) {
  Client& client = static_cast<Client&>(connection);
  for (auto& [id, sub] : client.subscriptions)
    if (sub.stream) streams()->unsubscribe(sub.stream);
  client.subscriptions.clear();
  if (settings_.tcp.cancel_on_disconnect) {
    // its calls still running end: nobody waits for them
    for (const auto& [id, pending] : pending_)
      if (pending.client.expired() || pending.client.lock().get() == &client) cancel(id);
  }
  client_left(client.number());
}

void FoxgloveServer::complain(Client& client, Level level, std::string_view message) {
  log::debug(name(), ": ", client.label(), ": ", message);
  client.queue_text(status(level, message));
}

// ---- services

void FoxgloveServer::call_service(Client& client, const ServiceCallRequest& request) {
  const auto service = std::find_if(services_.begin(), services_.end(), [&](const ServiceDef& s) {
    return s.id == request.service_id;
  });
  const auto fail = [&](const std::string& why) {
    client.queue_text(service_call_failure(request.service_id, request.call_id, why));
  };
  if (service == services_.end())
    return fail("no service " + std::to_string(request.service_id) +
                " (advertiseServices lists those there are)");
  if (request.encoding != "json")
    return fail("the request's encoding is '" + std::string(request.encoding.substr(0, 40)) +
                "': this server takes json (serverInfo's supportedEncodings)");
  json params = json::object();
  if (!request.payload.empty()) {
    params = json::parse(request.payload, nullptr, /*allow_exceptions=*/false);
    if (params.is_discarded())
      return fail("the request is not JSON: " + quoted_prefix(request.payload, 60));
    if (!params.is_object() && !params.is_array() && !params.is_null())
      return fail(service->name + " takes a JSON object of its parameters (" +
                  service->request_schema.value("description", std::string()) + "), not " +
                  quoted_prefix(request.payload, 60));
  }
  const RequestId id = new_request_id();
  pending_[id] = PendingCall{std::static_pointer_cast<Client>(client.shared_from_this()),
                             request.service_id, request.call_id};
  client.expect_reply();
  Call call{service->component, service->service, std::move(params)};
  call.client = client.number();
  calls_.emplace_back(id, std::move(call));
}

void FoxgloveServer::on_service_completion(RequestId id, Outcome&& outcome) {
  // the I/O thread (deliver_on_this_thread): inside run_or_submit, or flush_replies()
  if (parameter_completion(id, outcome) || playback_completion(id, outcome)) return;
  for (auto& [component, scene] : scenes_) {
    if (scene.call != id) continue;
    scene.call = 0;
    const std::string prefix = world_prefix(component);
    if (outcome.status == Status::success && outcome.value) {
      scene.geometry = std::move(*outcome.value);
      scene.frames = SceneFrames::from_geometry(scene.geometry, prefix);
    } else if (!scene.refused) {
      scene.refused = true;
      log::warning(name(), ": /", prefix, "tf and /", prefix, "scene stay empty: ", component,
                   " get_scene_geometry answered ", to_string(outcome.status), " (",
                   outcome.message, "); serve the ", component,
                   " component through this transport");
    }
    return;
  }
  auto it = pending_.find(id);
  if (it == pending_.end()) return;
  const PendingCall pending = it->second;
  pending_.erase(it);
  auto client = pending.client.lock();
  if (!client || client->closed()) return;
  client->replied();
  if (outcome.status == Status::success) {
    const json& value = outcome.value ? *outcome.value : json();
    const std::string payload = dump(value);
    client->queue_with([&](std::string& out) {
      kit::WebSocketConnection::append_frame_head(out, kit::FrameParser::k_binary,
                                                  13 + 4 + payload.size());
      append_service_call_response(out, pending.service_id, pending.call_id, "json", payload);
    });
    return;
  }
  std::string why(to_string(outcome.status));
  if (!outcome.message.empty()) why += ": " + outcome.message;
  client->queue_text(service_call_failure(pending.service_id, pending.call_id, why));
}

}  // namespace simgate::foxglove

SIMGATE_TRANSPORT_PLUGIN(foxglove, simgate::foxglove::FoxgloveServer, "0.1.0", "host", "port",
                         "max_connections", "max_connections_per_peer", "max_message_bytes",
                         "max_unsent_bytes", "max_buffered_bytes", "max_in_flight", "io_spin_us",
                         "on_disconnect", "global_policy", "idle_timeout_s", "idle_evict_s",
                         "line_timeout_s", "progress_interval_ms", "allowed_origins", "keepalive_s",
                         "auth", "stream_queue", "time_hz", "rewind_interval_s", "rewind_states")
