// The mcp transport's resources (mcp_server.h): the scene and each output stream the transport
// carries, read and subscribed to; the session's GET stream, where notifications go.
//
// Threads: the I/O thread, except wake_streams() (the thread that holds the simulation lock)
// and on_services_changed() (the thread that changed the services), which only post.
#include <boost/asio/post.hpp>

#include "mcp_server.h"
#include "simgate/core/log.h"
#include "simgate/jsonrpc/protocol.h"

namespace simgate::mcp {

namespace asio = boost::asio;
namespace code = jsonrpc::code;

namespace {

constexpr std::string_view k_scene_uri = "simgate://scene";
constexpr std::string_view k_stream_prefix = "simgate://streams/";
// MCP's error for a resource that does not exist (the specification's -32002).
constexpr int k_resource_not_found = -32002;

std::string stream_uri(const std::string& component) {
  return std::string(k_stream_prefix) + component;
}

json notification(std::string method, json params = json::object()) {
  return {{"jsonrpc", "2.0"}, {"method", std::move(method)}, {"params", std::move(params)}};
}

// A sample as a resource's contents: its JSON ({"seq", "time", "data"}) as text, and an
// image record's PNG as a blob of its own (the record's text keeps the rest).
json sample_contents(const std::string& uri, const StreamSample& sample) {
  json data = sample.data();
  json contents = json::array();
  if (data.is_object()) {
    auto image = data.find("image");
    auto format = data.find("format");
    if (image != data.end() && image->is_string() && format != data.end() && *format == "png") {
      contents.push_back({{"uri", uri}, {"mimeType", "image/png"}, {"blob", std::move(*image)}});
      *image = "(the image/png contents)";
    }
  }
  const json text = {{"seq", sample.seq()}, {"time", sample.time()}, {"data", std::move(data)}};
  json item = {{"uri", uri}, {"mimeType", "application/json"}, {"text", jsonrpc::dump(text)}};
  contents.insert(contents.begin(), std::move(item));
  return {{"contents", std::move(contents)}};
}

}  // namespace

json McpServer::resource_list() const {
  json list = json::array();
  if (may_call("simulation", "get_scene_objects"))
    list.push_back({{"uri", k_scene_uri},
                    {"name", "scene"},
                    {"title", "The scene"},
                    {"mimeType", "application/json"},
                    {"description",
                     "The scene's objects: robots, their components, the other bodies and where "
                     "they are (simulation get_scene_objects)"}});
  if (!streams()) return list;
  for (const StreamInfo& info : streams()->streams(transport_name())) {
    if (info.direction != StreamDirection::out) continue;
    std::string description =
        "The latest sample of " + info.component + "'s " + info.kind + " stream";
    if (info.frequency > 0) description += " (" + jsonrpc::dump(json(info.frequency)) + " Hz)";
    description +=
        ": {seq, time (simulated s), data}; subscribe for notifications/resources/"
        "updated";
    list.push_back({{"uri", stream_uri(info.component)},
                    {"name", info.component},
                    {"title", info.component + " (" + info.kind + ")"},
                    {"mimeType", "application/json"},
                    {"description", std::move(description)}});
  }
  return list;
}

McpServer::StreamWatch* McpServer::watch(const std::string& component) {
  if (auto it = watches_.find(component); it != watches_.end()) return &it->second;
  if (!streams()) return nullptr;
  const std::optional<StreamInfo> info = streams()->find(component, transport_name());
  if (!info || info->direction != StreamDirection::out) return nullptr;
  // the newest sample is all a resource is: one kept
  SubscriberOptions options{1, "mcp resource " + stream_uri(component), [this] { wake_streams(); }};
  auto subscription = streams()->subscribe(component, transport_name(), std::move(options));
  if (!subscription) return nullptr;
  StreamWatch& w = watches_[component];
  w.subscription = std::move(subscription);
  return &w;
}

void McpServer::release_watch(const std::string& component) {
  auto it = watches_.find(component);
  if (it == watches_.end() || !it->second.sessions.empty() || !it->second.reads.empty()) return;
  streams()->unsubscribe(it->second.subscription);
  watches_.erase(it);
}

void McpServer::unwatch_all(Session& session) {
  for (const std::string& component : session.watched) {
    if (auto it = watches_.find(component); it != watches_.end())
      it->second.sessions.erase(session.id);
    release_watch(component);
  }
  session.watched.clear();
}

void McpServer::read_resource(kit::HttpConnection& connection, const json& id, const json& params) {
  const std::string uri = params.is_object() && params.contains("uri") && params["uri"].is_string()
                              ? params["uri"].get<std::string>()
                              : std::string();
  if (uri == k_scene_uri && may_call("simulation", "get_scene_objects")) {
    Pending pending;
    pending.connection =
        std::static_pointer_cast<kit::HttpConnection>(connection.shared_from_this());
    pending.id = id;
    pending.resource = uri;
    const RequestId request = new_request_id();
    pending_.emplace(request, std::move(pending));
    calls_.emplace_back(request, Call{"simulation", "get_scene_objects", json::object()});
    return;  // answered when the call ends (on_messages_done submits it)
  }
  if (uri.starts_with(k_stream_prefix)) {
    const std::string component = uri.substr(k_stream_prefix.size());
    if (StreamWatch* w = watch(component)) {
      if (w->latest && !w->sessions.empty())  // watched: its newest sample is current
        return respond_json(connection, 200,
                            jsonrpc::result_response(id, sample_contents(uri, *w->latest)));
      // the stream's next sample (the hub gives a new subscriber one at its next turn)
      w->reads.push_back(
          {std::static_pointer_cast<kit::HttpConnection>(connection.shared_from_this()), id});
      return;
    }
  }
  respond_json(connection, 200,
               jsonrpc::error_response(id, k_resource_not_found,
                                       "Resource not found: " + quoted_prefix(uri, 120) +
                                           " (resources/list lists them)",
                                       json{{"uri", uri}}));
}

void McpServer::watch_resource(kit::HttpConnection& connection, Session& session, const json& id,
                               const json& params, bool subscribe) {
  const std::string uri = params.is_object() && params.contains("uri") && params["uri"].is_string()
                              ? params["uri"].get<std::string>()
                              : std::string();
  const std::string component =
      uri.starts_with(k_stream_prefix) ? uri.substr(k_stream_prefix.size()) : std::string();
  if (!subscribe) {
    if (session.watched.erase(component)) {
      if (auto it = watches_.find(component); it != watches_.end())
        it->second.sessions.erase(session.id);
      release_watch(component);
    }
    return respond_json(connection, 200, jsonrpc::result_response(id, json::object()));
  }
  StreamWatch* w = component.empty() ? nullptr : watch(component);
  if (!w)
    return respond_json(
        connection, 200,
        jsonrpc::error_response(id, k_resource_not_found,
                                "Resource not found: " + quoted_prefix(uri, 120) +
                                    " (the streams' resources can be subscribed to: "
                                    "simgate://streams/<component>)",
                                json{{"uri", uri}}));
  w->sessions.insert(session.id);
  session.watched.insert(component);
  respond_json(connection, 200, jsonrpc::result_response(id, json::object()));
}

void McpServer::open_events(kit::HttpConnection& connection, const kit::HttpRequest& request) {
  const std::optional<std::string_view> accept = kit::header_value(request, "Accept");
  if (!accept || accept->find("text/event-stream") == std::string_view::npos)
    return connection.respond(406, "text/plain; charset=utf-8",
                              "simgate mcp transport: GET opens a stream of events: Accept: "
                              "text/event-stream\n");
  const std::optional<std::string_view> id = kit::header_value(request, "Mcp-Session-Id");
  if (!id)
    return respond_error(connection, 400, nullptr, code::invalid_request,
                         "no Mcp-Session-Id header: initialize first");
  auto found = sessions_.find(std::string(*id));
  if (found == sessions_.end())
    return respond_error(connection, 404, nullptr, code::invalid_request,
                         "no session " + quoted_prefix(*id, 40) + " (ended, or never made)");
  Session& session = found->second;
  session.used = std::chrono::steady_clock::now();
  // a call's stream resumed (its client's connection dropped)
  if (const auto last = kit::header_value(request, "Last-Event-ID"))
    return resume_stream(connection, session, *last);
  // one stream per session: a new one (a client reconnecting) replaces the old
  if (auto old = session.events.lock(); old && old->streaming()) old->end_events();
  session.events = std::static_pointer_cast<kit::HttpConnection>(connection.shared_from_this());
  session.used = std::chrono::steady_clock::now();
  connection.begin_events();
}

void McpServer::notify(Session& session, const json& message) {
  auto events = session.events.lock();
  if (!events || events->closed() || !events->streaming()) return;
  events->queue_droppable_event(jsonrpc::dump(message));
}

void McpServer::on_services_changed() {
  tools_stale_.store(true, std::memory_order_relaxed);
  // a robot's components come together: one announcement for the burst
  if (changes_posted_.exchange(true, std::memory_order_acq_rel)) return;
  asio::post(io_, [this] { announce_changes(); });
}

void McpServer::announce_changes() {
  changes_posted_.store(false, std::memory_order_release);
  if (stopping_) return;
  const json tools = notification("notifications/tools/list_changed");
  const json resources = notification("notifications/resources/list_changed");
  for (auto& [id, session] : sessions_) {
    notify(session, tools);
    notify(session, resources);
  }
  flush_touched();
}

void McpServer::wake_streams() {
  if (streams_woken_.exchange(true, std::memory_order_acq_rel)) return;
  asio::post(io_, [this] { drain_streams(); });
}

void McpServer::drain_streams() {
  streams_woken_.store(false, std::memory_order_release);
  if (stopping_) return;
  const auto now = std::chrono::steady_clock::now();
  std::vector<std::string> ended, ended_reads;
  for (auto& [component, w] : watches_) {
    samples_.clear();
    w.subscription->take(samples_);
    if (!samples_.empty()) {
      w.latest = samples_.back();
      w.updated = true;
    }
    const std::string uri = stream_uri(component);
    if (w.latest && !w.reads.empty()) {
      for (PendingRead& read : std::exchange(w.reads, {})) {
        auto connection = read.connection.lock();
        if (!connection || connection->closed() || !connection->answering()) continue;
        respond_json(*connection, 200,
                     jsonrpc::result_response(read.id, sample_contents(uri, *w.latest)));
      }
      if (w.sessions.empty()) ended_reads.push_back(component);
    }
    if (w.updated && now - w.notified >= k_update_interval) {
      w.updated = false;
      w.notified = now;
      const json updated = notification("notifications/resources/updated", {{"uri", uri}});
      for (const std::string& id : w.sessions)
        if (auto s = sessions_.find(id); s != sessions_.end()) notify(s->second, updated);
    }
    if (w.subscription->closed()) ended.push_back(component);
  }
  for (const std::string& component : ended) {
    // its component was deleted: the reads are answered, the subscribers told
    StreamWatch& w = watches_[component];
    for (PendingRead& read : w.reads)
      if (auto connection = read.connection.lock(); connection && connection->answering())
        respond_json(*connection, 200,
                     jsonrpc::error_response(read.id, k_resource_not_found,
                                             "Resource not found: " + stream_uri(component) +
                                                 " (its component was removed)"));
    for (const std::string& id : w.sessions)
      if (auto s = sessions_.find(id); s != sessions_.end()) s->second.watched.erase(component);
    watches_.erase(component);
  }
  // a watch only reads waited for ends with them
  for (const std::string& component : ended_reads) release_watch(component);
  flush_touched();
}

void McpServer::finish_resource_read(kit::HttpConnection& connection, const Pending& pending,
                                     Outcome&& outcome) {
  if (outcome.status != Status::success)
    return respond_json(
        connection, 200,
        jsonrpc::error_response(pending.id, code::internal_error,
                                "reading " + pending.resource + ": " + outcome.message));
  json item = {{"uri", pending.resource},
               {"mimeType", "application/json"},
               {"text", jsonrpc::dump(outcome.value.value_or(nullptr))}};
  json contents = json::array();
  contents.push_back(std::move(item));
  respond_json(connection, 200,
               jsonrpc::result_response(pending.id, {{"contents", std::move(contents)}}));
}

}  // namespace simgate::mcp
