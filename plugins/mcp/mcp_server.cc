#include "mcp_server.h"

#include <sys/random.h>

#include <algorithm>
#include <cmath>

#include <boost/asio/post.hpp>
#include <boost/beast/http/verb.hpp>

#include "simgate/core/config.h"
#include "simgate/core/log.h"
#include "simgate/core/plugin.h"
#include "simgate/core/text.h"
#include "simgate/jsonrpc/protocol.h"

namespace simgate::mcp {

namespace asio = boost::asio;
namespace http = boost::beast::http;
using asio::ip::tcp;
namespace code = jsonrpc::code;

namespace {

constexpr const char* k_server = "simgate mcp transport";
constexpr const char* k_version = "0.1.0";
// The deepest nesting of brackets a message may have (the JSON-RPC transports' max_depth).
constexpr std::size_t k_max_depth = 128;

// A session id: 128 random bits from the kernel, as hex (the spec: globally unique and
// cryptographically secure).
std::string new_session_id() {
  std::uint8_t bytes[16];
  std::size_t got = 0;
  while (got < sizeof bytes) {
    const ssize_t n = getrandom(bytes + got, sizeof bytes - got, 0);
    if (n > 0) got += static_cast<std::size_t>(n);
  }
  std::string id;
  append_hex(id, bytes, sizeof bytes);
  return id;
}

// {"jsonrpc":"2.0","id":<id>,"result":<result_text>}
std::string result_line(const json& id, std::string_view result_text) {
  std::string out = R"({"jsonrpc":"2.0","id":)";
  out += jsonrpc::dump(id);
  out += R"(,"result":)";
  out += result_text;
  out += '}';
  return out;
}

// Whether the Accept header `accept` takes `type` (or anything).
bool accepts(std::optional<std::string_view> accept, std::string_view type) {
  if (!accept) return false;
  return accept->find(type) != std::string_view::npos ||
         accept->find("*/*") != std::string_view::npos;
}

}  // namespace

// ---- options

McpServer::Settings McpServer::Settings::parse(const json& options) {
  json rest = options.is_null() ? json::object() : options;
  Settings s;
  s.origins = kit::OriginPolicy::take(rest);
  ConfigObject config(rest, "");
  kit::TcpOptions defaults;
  defaults.port = k_default_port;
  defaults.max_connections = 256;
  s.tcp = kit::TcpOptions::read(config, defaults, "mcp");
  s.path = config.get_string("path", "/mcp");
  if (s.path.empty() || s.path.front() != '/' || s.path.find_first_of("?# ") != std::string::npos)
    throw ConfigError("path: expected an absolute path such as \"/mcp\", found \"" + s.path + "\"");
  s.max_sessions = static_cast<std::size_t>(config.get_int("max_sessions", 64, 1, 100'000));
  s.session_timeout =
      std::chrono::seconds(config.get_int("session_timeout_s", 1800, 10, 7 * 86'400));
  s.max_calls_per_s = config.get_number("max_calls_per_s", 50, 0.1, 1e6);
  s.resume_window = std::chrono::milliseconds(
      std::llround(config.get_number("resume_window_s", 30, 0, 3600) * 1000));
  s.tcp.finish(config);
  return s;
}

std::vector<std::string> McpServer::validate_options(const json& options) {
  return Settings::parse(options).tcp.warnings;
}

McpServer::McpServer(const json& options) : McpServer(Settings::parse(options)) {}

McpServer::McpServer(Settings settings)
    : RequestManager("MCP service manager"),
      HttpServer(name(), settings.tcp),
      settings_(std::move(settings)),
      listener_(io_, name(), settings_.tcp.host, settings_.tcp.port),
      io_thread_(io_, name(), settings_.tcp.io_spin),
      session_timer_(io_) {
  set_global_policy(settings_.tcp.global_policy);
  set_progress_interval(settings_.tcp.progress_interval);
  // detached streams are expired within half their window (at least every 10 s)
  sweep_interval_ = std::clamp<std::chrono::milliseconds>(
      settings_.resume_window / 2, std::chrono::milliseconds(100), k_session_sweep);
  settings_.origins.bind(settings_.tcp.host, listener_.port());
  for (const auto& w : settings_.tcp.warnings) log::warning(name(), ": ", w);
}

McpServer::~McpServer() { stop(); }

std::vector<std::string> McpServer::endpoints() const {
  std::string endpoint = listener_.endpoint();  // "tcp://host:port" -> "http://host:port/mcp"
  if (endpoint.starts_with("tcp://")) endpoint.replace(0, 3, "http");
  return {endpoint + settings_.path};
}

// ---- life cycle

void McpServer::start() {
  kit::TcpListener::Handlers handlers{
      [this](tcp::socket socket) { accept(std::move(socket)); },
      [this](const tcp::endpoint& peer) { return refusal_reason(peer); },
      [](const std::string& why) { return kit::unavailable_response(why + "\n"); }};
  if (!io_thread_.start(
          [this, handlers = std::move(handlers)]() mutable {
            deliver_on_this_thread([this] { asio::post(io_, [this] { flush_replies(); }); });
            listener_.start(std::move(handlers));
            sweep_sessions();
          },
          direct_reads()))
    return;
  log::info("mcp: listening on ", endpoints().front(),
            " (an MCP client's streamable HTTP transport; docs/transports/mcp.md)");
}

void McpServer::stop() {
  if (!io_thread_.stop([this] { shutdown_io(); })) return;
  deliver_on_any_thread();
  abandon_pending("the mcp transport has stopped");
}

void McpServer::shutdown_io() {
  stopping_ = true;
  session_timer_.cancel();
  listener_.close();
  close_all();
  pending_.clear();
  for (auto& [component, w] : watches_) streams()->unsubscribe(w.subscription);
  watches_.clear();
  for (const auto& [id, session] : sessions_) client_left(session.number);
  sessions_.clear();
  session_count_.store(0, std::memory_order_relaxed);
}

void McpServer::accept(tcp::socket socket) {
  kit::HttpServer& server = *this;
  add(std::make_shared<kit::HttpConnection>(std::move(socket), server,
                                            kit::ConnectionLimits::from(settings_.tcp), name(),
                                            next_connection_++, k_server));
}

void McpServer::flush_replies() {
  deliver_handed_over();
  flush_touched();
}

// ---- HTTP

void McpServer::respond_json(kit::HttpConnection& connection, unsigned status, const json& body,
                             const std::string& headers) {
  connection.respond(status, "application/json", jsonrpc::dump(body), headers);
}

void McpServer::respond_error(kit::HttpConnection& connection, unsigned status, const json& id,
                              int error_code, std::string message) {
  log::debug(name(), ": ", connection.label(), ": ", message);
  respond_json(connection, status, jsonrpc::error_response(id, error_code, std::move(message)));
}

void McpServer::on_request(kit::HttpConnection& connection, kit::HttpRequest&& request) {
  const std::string_view target(request.target().data(), request.target().size());
  const std::string_view path = target.substr(0, target.find('?'));
  // DNS rebinding: a page of another site must not reach the endpoint (the spec's MUST)
  const std::optional<std::string_view> origin = kit::header_value(request, "Origin");
  if (!settings_.origins.allows(origin)) {
    log::warning(name(), ": a request from a page of origin '", origin->substr(0, 200),
                 "' refused (allowed_origins: ", settings_.origins.describe(), ")");
    return respond_error(connection, 403, nullptr, code::invalid_request,
                         "requests from pages of origin '" + std::string(origin->substr(0, 200)) +
                             "' are not allowed (allowed: " + settings_.origins.describe() +
                             "; the transport's option allowed_origins, docs/security.md)");
  }
  if (settings_.tcp.auth.required_for(connection.peer())) {
    const std::optional<std::string> token = kit::bearer_token(request);
    if (!token) {
      return connection.respond(
          401, "application/json",
          jsonrpc::dump(jsonrpc::error_response(
              nullptr, code::unauthorized,
              "this endpoint requires a token: the header Authorization: Bearer TOKEN "
              "(docs/security.md)")),
          "WWW-Authenticate: Bearer realm=\"simgate\"\r\n");
    }
    if (!connection.present_token(*token)) {
      log::warning(name(), ": ", connection.label(), ": a wrong token; the connection closes");
      connection.close_after_answer();  // one guess per connection (kit/auth.h)
      return respond_error(connection, 403, nullptr, code::unauthorized, "wrong token");
    }
  }
  if (path != settings_.path) {
    return connection.respond(404, "text/plain; charset=utf-8",
                              std::string(k_server) + ": the MCP endpoint is " +
                                  endpoints().front() + " (docs/transports/mcp.md)\n");
  }
  switch (request.method()) {
    case http::verb::post: return on_post(connection, request);
    case http::verb::delete_: {
      const std::optional<std::string_view> id = kit::header_value(request, "Mcp-Session-Id");
      if (!id)
        return respond_error(connection, 400, nullptr, code::invalid_request,
                             "no Mcp-Session-Id header");
      const std::string key(*id);
      if (!sessions_.count(key))
        return respond_error(connection, 404, nullptr, code::invalid_request,
                             "no session " + quoted_prefix(key, 40) + " (ended, or never made)");
      end_session(key, "the client ended it (DELETE)");
      return connection.respond(200, "text/plain; charset=utf-8", "");
    }
    case http::verb::get: return open_events(connection, request);
    default:
      return connection.respond(405, "text/plain; charset=utf-8",
                                std::string(k_server) +
                                    ": POST a JSON-RPC message, GET the session's notifications, "
                                    "or DELETE the session\n",
                                "Allow: GET, POST, DELETE\r\n");
  }
}

void McpServer::on_post(kit::HttpConnection& connection, const kit::HttpRequest& request) {
  const std::optional<std::string_view> type = kit::header_value(request, "Content-Type");
  if (!type || type->find("application/json") == std::string_view::npos)
    return respond_error(connection, 415, nullptr, code::invalid_request,
                         "the body must be one JSON-RPC message, Content-Type: application/json");
  const std::optional<std::string_view> accept = kit::header_value(request, "Accept");
  const bool events = accepts(accept, "text/event-stream");
  if (!accepts(accept, "application/json") && !events)
    return respond_error(connection, 406, nullptr, code::invalid_request,
                         "the Accept header must list application/json and text/event-stream");

  // the common shape read in one pass (jsonrpc's fast path); anything else, errors included,
  // through the parser
  jsonrpc::Request rpc;
  if (!jsonrpc::parse_request_fast(request.body(), k_max_depth, rpc)) {
    // the parser recurses: a message nesting deeper than any MCP message does is refused unread
    if (json_nests_deeper_than(request.body(), k_max_depth))
      return respond_error(
          connection, 400, nullptr, code::invalid_request,
          "the message nests deeper than " + std::to_string(k_max_depth) + " levels");
    json message = json::parse(request.body(), nullptr, /*allow_exceptions=*/false);
    if (message.is_discarded())
      return respond_error(connection, 400, nullptr, code::parse_error,
                           "the body is not JSON: " + quoted_prefix(request.body(), 60));
    if (message.is_array())
      return respond_error(
          connection, 400, nullptr, code::invalid_request,
          "a batch: MCP takes one message per request since its revision 2025-06-18");
    // a response to a request of ours (we send none): taken note of
    if (message.is_object() && !message.contains("method") &&
        (message.contains("result") || message.contains("error")))
      return connection.respond(202, "text/plain; charset=utf-8", "");
    if (std::optional<json> refusal = jsonrpc::parse_request(message, rpc))
      return respond_json(connection, 400, *refusal);
  }
  if (rpc.has_id && !rpc.id.is_string() && !rpc.id.is_number_integer())
    return respond_error(connection, 400, nullptr, code::invalid_request,
                         "an MCP request's id is a string or an integer, not " + rpc.id.dump());

  if (rpc.method == "initialize") {
    if (!rpc.has_id)
      return respond_error(connection, 400, nullptr, code::invalid_request,
                           "initialize is a request: it needs an id");
    return initialize(connection, rpc.id, rpc.params);
  }
  const std::optional<std::string_view> session_id = kit::header_value(request, "Mcp-Session-Id");
  if (!session_id)
    return respond_error(connection, 400, rpc.has_id ? rpc.id : json(nullptr),
                         code::invalid_request,
                         "no Mcp-Session-Id header: initialize first, then send the id it "
                         "answered with in every request");
  auto found = sessions_.find(std::string(*session_id));
  if (found == sessions_.end())
    return respond_error(connection, 404, rpc.has_id ? rpc.id : json(nullptr),
                         code::invalid_request,
                         "no session " + quoted_prefix(*session_id, 40) +
                             " (ended, or never made): initialize again");
  Session& session = found->second;
  if (const auto version = kit::header_value(request, "MCP-Protocol-Version");
      version && !is_served_version(*version))
    return respond_error(
        connection, 400, rpc.has_id ? rpc.id : json(nullptr), code::invalid_request,
        "MCP-Protocol-Version " + quoted_prefix(*version, 40) + " is not served here (served: " +
            join(std::vector<std::string>(k_protocol_versions.begin(), k_protocol_versions.end())) +
            ")");
  session.used = std::chrono::steady_clock::now();
  if (!rpc.has_id) {
    on_notification(session, rpc.method, rpc.params);
    return connection.respond(202, "text/plain; charset=utf-8", "");
  }
  if (rpc.method == "tools/call") return call_tool(connection, session, events, rpc.id, rpc.params);
  on_method(connection, session, rpc.id, rpc.method, rpc.params);
}

// ---- sessions

void McpServer::initialize(kit::HttpConnection& connection, const json& id, const json& params) {
  if (!params.is_object() || !params.contains("protocolVersion") ||
      !params["protocolVersion"].is_string())
    return respond_error(connection, 200, id, code::invalid_params,
                         "initialize takes {protocolVersion, capabilities, clientInfo}");
  if (sessions_.size() >= settings_.max_sessions)
    return respond_error(connection, 503, id, code::overloaded,
                         std::to_string(sessions_.size()) +
                             " sessions are open (max_sessions): end one (DELETE), or wait "
                             "for an idle one to end (session_timeout_s)");
  Session session;
  session.id = new_session_id();
  session.number = next_session_++;
  session.version = negotiate_version(params["protocolVersion"].get<std::string>());
  session.used = session.refilled = std::chrono::steady_clock::now();
  session.tokens = std::max(1.0, settings_.max_calls_per_s);
  std::string who = "an MCP client";
  if (auto info = params.find("clientInfo"); info != params.end() && info->is_object())
    who = info->value("name", who) + " " + info->value("version", "");
  log::info("mcp: session ", session.number, " opened by ", quoted_prefix(who, 80), " (",
            connection.label(), "), protocol ", session.version);
  client_arrived(session.number);
  const std::string header = "Mcp-Session-Id: " + session.id + "\r\n";
  respond_json(connection, 200,
               jsonrpc::result_response(id, initialize_result(session.version, k_version)), header);
  sessions_.emplace(session.id, std::move(session));
  session_count_.store(sessions_.size(), std::memory_order_relaxed);
}

void McpServer::end_session(const std::string& id, const char* why) {
  auto it = sessions_.find(id);
  if (it == sessions_.end()) return;
  for (const auto& [key, request] : it->second.calls) cancel(request);
  unwatch_all(it->second);
  if (auto events = it->second.events.lock(); events && events->streaming()) events->end_events();
  log::info("mcp: session ", it->second.number, " ended: ", why);
  client_left(it->second.number);
  sessions_.erase(it);
  session_count_.store(sessions_.size(), std::memory_order_relaxed);
}

void McpServer::sweep_sessions() {
  if (stopping_) return;
  const auto now = std::chrono::steady_clock::now();
  std::vector<std::string> idle;
  for (const auto& [id, session] : sessions_)
    if (session.calls.empty() && now - session.used > settings_.session_timeout) idle.push_back(id);
  for (const auto& id : idle) end_session(id, "unused for session_timeout_s");
  expire_streams(now);
  session_timer_.expires_after(sweep_interval_);
  session_timer_.async_wait([this](const boost::system::error_code& ec) {
    if (!ec) sweep_sessions();
  });
}

bool McpServer::take_call_token(Session& session) {
  const auto now = std::chrono::steady_clock::now();
  const double rate = settings_.max_calls_per_s;
  session.tokens = std::min(
      std::max(1.0, rate),
      session.tokens + rate * std::chrono::duration<double>(now - session.refilled).count());
  session.refilled = now;
  if (session.tokens < 1.0) return false;
  session.tokens -= 1.0;
  return true;
}

// ---- methods

const std::map<std::string, Tool>& McpServer::tools() {
  if (tools_stale_.exchange(false, std::memory_order_relaxed)) {
    std::vector<std::string> skipped;
    tools_ = make_tools(descriptors(), skipped);
    if (skipped != skipped_tools_ && !skipped.empty())
      log::warning(name(), ": no tool for ", join(skipped),
                   ": another service's tool has its name already");
    skipped_tools_ = std::move(skipped);
  }
  return tools_;
}

void McpServer::on_method(kit::HttpConnection& connection, Session& session, const json& id,
                          const std::string& method, json& params) {
  if (method == "ping")
    return respond_json(connection, 200, jsonrpc::result_response(id, json::object()));
  if (method == "resources/list")
    return respond_json(connection, 200,
                        jsonrpc::result_response(id, {{"resources", resource_list()}}));
  if (method == "resources/templates/list")
    return respond_json(connection, 200,
                        jsonrpc::result_response(id, {{"resourceTemplates", json::array()}}));
  if (method == "resources/read") return read_resource(connection, id, params);
  if (method == "resources/subscribe" || method == "resources/unsubscribe")
    return watch_resource(connection, session, id, params, method == "resources/subscribe");
  if (method == "tools/list") {
    json list = json::array();
    for (const auto& [tool_name, tool] : tools()) list.push_back(tool_definition(tool));
    return respond_json(connection, 200,
                        jsonrpc::result_response(id, {{"tools", std::move(list)}}));
  }
  if (method == "prompts/list")
    return respond_error(connection, 200, id, code::method_not_found,
                         "prompts/list: this server offers tools and resources, no prompts (its "
                         "capabilities say so)");
  respond_error(connection, 200, id, code::method_not_found,
                "no method '" + method.substr(0, 80) +
                    "' (this server: initialize, ping, tools/list, tools/call, resources/list, "
                    "resources/read, resources/subscribe, resources/unsubscribe)");
}

void McpServer::on_notification(Session& session, const std::string& method, const json& params) {
  if (method != "notifications/cancelled") return;  // initialized, roots changed, ...: noted
  if (!params.is_object() || !params.contains("requestId")) return;
  const auto it = session.calls.find(jsonrpc::dump(params["requestId"]));
  if (it == session.calls.end()) return;  // ended already, or never ours: the spec says ignore
  if (auto p = pending_.find(it->second); p != pending_.end()) p->second.cancelled = true;
  cancel(it->second);
}

void McpServer::call_tool(kit::HttpConnection& connection, Session& session, bool events,
                          const json& id, json& params) {
  if (!params.is_object() || !params.contains("name") || !params["name"].is_string())
    return respond_error(connection, 200, id, code::invalid_params,
                         "tools/call takes {name, arguments}: the tool's name is missing");
  const std::string tool_name = params["name"].get<std::string>();
  const auto& all = tools();
  const auto tool = all.find(tool_name);
  if (tool == all.end())
    return respond_error(
        connection, 200, id, code::invalid_params,
        "Unknown tool: " + quoted_prefix(tool_name, 80) + " (tools/list lists them)");
  json arguments = params.contains("arguments") ? std::move(params["arguments"]) : json::object();
  if (arguments.is_null()) arguments = json::object();
  if (!arguments.is_object())
    return respond_error(connection, 200, id, code::invalid_params,
                         tool_name + " takes an object of named arguments, not " +
                             quoted_prefix(arguments.dump(), 60));
  const std::string key = jsonrpc::dump(id);
  if (session.calls.count(key))
    return respond_error(connection, 200, id, code::invalid_request,
                         "the id " + key.substr(0, 40) + " is in use by a call still running");
  if (!take_call_token(session)) {
    log::debug(name(), ": session ", session.number, ": over max_calls_per_s");
    return respond_json(connection, 429,
                        jsonrpc::error_response(id, code::overloaded,
                                                "over this session's rate limit (max_calls_per_s " +
                                                    std::to_string(settings_.max_calls_per_s) +
                                                    "): try again shortly"),
                        "Retry-After: 1\r\n");
  }
  std::string why;
  const std::chrono::milliseconds deadline = take_deadline(arguments, tool->second, why);
  if (!why.empty())
    return respond_json(
        connection, 200,
        jsonrpc::result_response(id, tool_result(Outcome::failed(Failure::bad_arguments, why))));
  Pending pending;
  pending.connection = std::static_pointer_cast<kit::HttpConnection>(connection.shared_from_this());
  pending.session = session.id;
  pending.id = id;
  // a long call (an async service's) may stream its progress; a quick one that only waits
  // for the simulation lock answers as JSON
  pending.events = events && tool->second.service.is_async;
  if (auto meta = params.find("_meta"); meta != params.end() && meta->is_object())
    if (auto token = meta->find("progressToken"); token != meta->end())
      pending.progress_token = *token;
  Call call{tool->second.service.component, tool->second.service.name, std::move(arguments)};
  call.client = session.number;
  call.timeout = deadline;
  call.progress = events && !pending.progress_token.is_null();
  const RequestId request = new_request_id();
  session.calls.emplace(key, request);
  pending_.emplace(request, std::move(pending));
  calls_.emplace_back(request, std::move(call));
  submitted_.push_back(request);
}

void McpServer::on_messages_done(kit::Connection& /*connection*/, bool /*read_finished*/) {
  if (calls_.empty()) return;
  run_or_submit(std::exchange(calls_, {}));
  // a call still running answers as a stream of events, when its client takes one: its
  // progress goes there, and a long call's connection shows it is alive
  for (RequestId request : std::exchange(submitted_, {})) {
    auto it = pending_.find(request);
    if (it == pending_.end() || !it->second.events) continue;
    auto connection = it->second.connection.lock();
    if (!connection || connection->closed() || connection->streaming()) continue;
    begin_call_stream(request, it->second, *connection);
    connection->flush_writes();
  }
}

void McpServer::on_closed(kit::Connection& connection) {
  if (stopping_) return;
  // a stream it carried waits for its client to resume it (resume_window_s); a call that was
  // to answer here as JSON cannot be answered any more: cancelled (on_disconnect "let_run":
  // it runs on)
  detach_streams(connection);
  expire_streams(std::chrono::steady_clock::now());
  if (!settings_.tcp.cancel_on_disconnect) return;
  for (auto& [request, pending] : pending_) {
    if (pending.stream != 0) continue;
    auto owner = pending.connection.lock();
    if (!owner || owner.get() == &connection) {
      pending.cancelled = true;
      cancel(request);
    }
  }
}

// ---- the core's answers (I/O thread)

void McpServer::on_service_completion(RequestId id, Outcome&& outcome) {
  auto it = pending_.find(id);
  if (it == pending_.end()) return;
  Pending pending = std::move(it->second);
  pending_.erase(it);
  if (auto s = sessions_.find(pending.session); s != sessions_.end())
    s->second.calls.erase(jsonrpc::dump(pending.id));
  if (pending.stream != 0) {
    // a cancelled call's stream ends without a result (the spec: no response to a request
    // the client cancelled); a detached one keeps it for its client's resume
    if (!pending.cancelled || outcome.status == Status::success)
      stream_event(pending, result_line(pending.id, tool_result_text(std::move(outcome))), false);
    return end_call_stream(pending);
  }
  auto connection = pending.connection.lock();
  if (!connection || connection->closed() || !connection->answering()) return;
  if (!pending.resource.empty())
    return finish_resource_read(*connection, pending, std::move(outcome));
  connection->respond(200, "application/json",
                      result_line(pending.id, tool_result_text(std::move(outcome))));
}

void McpServer::on_service_progress(RequestId id, json&& value) {
  auto it = pending_.find(id);
  if (it == pending_.end() || it->second.progress_token.is_null()) return;
  Pending& pending = it->second;
  if (pending.stream == 0) return;
  stream_event(
      pending,
      jsonrpc::dump(progress_notification(pending.progress_token, ++pending.reports, value)), true);
}

}  // namespace simgate::mcp

SIMGATE_TRANSPORT_PLUGIN(mcp, simgate::mcp::McpServer, "0.1.0", "host", "port", "max_connections",
                         "max_connections_per_peer", "max_message_bytes", "max_unsent_bytes",
                         "max_buffered_bytes", "max_in_flight", "io_spin_us", "on_disconnect",
                         "global_policy", "idle_timeout_s", "idle_evict_s", "line_timeout_s",
                         "progress_interval_ms", "allowed_origins", "auth", "path", "max_sessions",
                         "session_timeout_s", "max_calls_per_s", "resume_window_s")
