// `simgate mcp`: an MCP server on standard input and output, for agents that launch one (a
// desktop agent's "command"): each line read is one JSON-RPC message, POSTed to an mcp
// transport's streamable HTTP endpoint; each answer (the JSON of a response, or each event of
// a stream: progress, then the result) is written as one line. The MCP stdio transport is
// newline-delimited JSON-RPC, so the bridge parses nothing but the headers it must carry: the
// session's id once initialize answered it, and the token.
//
// With --url: a running simgate's endpoint. Otherwise the simulation runs in this process, from
// CONFIG (which must have an mcp transport) or --model (served by an mcp transport on a port the
// kernel picks), its log on stderr; it stops when standard input ends.
//
// Each message is posted on a connection of its own, on a thread of its own (at most
// k_max_in_flight at once), so that a notifications/cancelled reaches the server while the call
// it cancels still streams; once initialize answered, one more thread holds the session's GET
// stream and forwards its notifications. Lines are written whole, one writer at a time.
#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdlib>
#include <iostream>
#include <limits>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/http.hpp>

#include "commands.h"
#include "simgate/core/errors.h"
#include "simgate/core/log.h"

namespace simgate::gateway {

namespace {

namespace asio = boost::asio;
namespace http = boost::beast::http;

// "http://host:port/path" split; UsageError naming --url otherwise.
struct Endpoint {
  std::string host, port, path;
  static Endpoint parse(const std::string& url) {
    const std::string scheme = "http://";
    if (url.rfind(scheme, 0) != 0)
      throw UsageError(
          "--url: expected http://HOST:PORT/PATH (the mcp transport's endpoint), found '" + url +
          "'");
    const std::string rest = url.substr(scheme.size());
    const std::size_t slash = rest.find('/');
    const std::string authority = rest.substr(0, slash);
    Endpoint e;
    e.path = slash == std::string::npos ? "/" : rest.substr(slash);
    const std::size_t colon = authority.rfind(':');
    if (colon == std::string::npos || colon + 1 == authority.size()) {
      e.host = authority;
      e.port = "80";
    } else {
      e.host = authority.substr(0, colon);
      e.port = authority.substr(colon + 1);
    }
    if (e.host.size() > 2 && e.host.front() == '[' && e.host.back() == ']')
      e.host = e.host.substr(1, e.host.size() - 2);
    if (e.host.empty()) throw UsageError("--url: no host in '" + url + "'");
    return e;
  }
};

class StdioBridge {
 public:
  StdioBridge(Endpoint endpoint, std::string token)
      : endpoint_(std::move(endpoint)), token_(std::move(token)) {}

  // Reads standard input to its end, posting each line; returns once every answer is written.
  void run() {
    std::string line;
    while (std::getline(std::cin, line)) {
      if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
      std::unique_lock lock(mutex_);
      room_.wait(lock, [&] { return in_flight_ < k_max_in_flight; });
      ++in_flight_;
      workers_.emplace_back([this, message = std::move(line)] {
        post(message);
        std::lock_guard done(mutex_);
        --in_flight_;
        room_.notify_all();
      });
    }
    for (auto& w : workers_) w.join();
    end_session();  // the server ends the session's GET stream too
    if (events_.joinable()) events_.join();
  }

  static constexpr int k_max_in_flight = 64;

 private:
  // One line on standard output, whole.
  void write_line(std::string_view text) {
    std::lock_guard lock(out_mutex_);
    std::cout << text << '\n' << std::flush;
  }

  // An error response to `message` when it is a request (its id), written as a line; nothing
  // for a notification.
  void write_error(const std::string& message, const std::string& why) {
    const json parsed = json::parse(message, nullptr, false);
    if (!parsed.is_object() || !parsed.contains("id")) {
      log::warning("simgate mcp: ", why);
      return;
    }
    write_line(json{{"jsonrpc", "2.0"},
                    {"id", parsed["id"]},
                    {"error", {{"code", -32603}, {"message", "simgate mcp: " + why}}}}
                   .dump());
  }

  // Writes the data of each whole event (up to a blank line) at the start of `pending`, one
  // line each, and takes them out.
  void write_events(std::string& pending) {
    for (std::size_t end; (end = pending.find("\n\n")) != std::string::npos;) {
      const std::string event = pending.substr(0, end);
      pending.erase(0, end + 2);
      std::size_t at = 0;
      while (at < event.size()) {
        std::size_t eol = event.find('\n', at);
        if (eol == std::string::npos) eol = event.size();
        const std::string_view field(event.data() + at, eol - at);
        if (field.rfind("data: ", 0) == 0 && field.size() > 6) write_line(field.substr(6));
        at = eol + 1;
      }
    }
  }

  std::string session() {
    std::lock_guard lock(mutex_);
    return session_;
  }

  // A request to the endpoint, connected: its Host, the session's id once there is one, the
  // token when there is one.
  template <class Body>
  http::request<Body> connected_request(http::verb verb, asio::ip::tcp::socket& socket) {
    asio::ip::tcp::resolver resolver(socket.get_executor());
    asio::connect(socket, resolver.resolve(endpoint_.host, endpoint_.port));
    http::request<Body> request{verb, endpoint_.path, 11};
    request.set(http::field::host, endpoint_.host + ":" + endpoint_.port);
    if (const std::string id = session(); !id.empty()) request.set("Mcp-Session-Id", id);
    if (!token_.empty()) request.set(http::field::authorization, "Bearer " + token_);
    return request;
  }

  // POSTs `message` (or, with an empty one, GETs the session's stream of notifications) and
  // writes what answers it.
  void post(const std::string& message) {
    try {
      asio::io_context io;
      asio::ip::tcp::socket socket(io);
      auto request = connected_request<http::string_body>(
          message.empty() ? http::verb::get : http::verb::post, socket);
      if (message.empty()) {
        request.set(http::field::accept, "text/event-stream");
      } else {
        request.set(http::field::content_type, "application/json");
        request.set(http::field::accept, "application/json, text/event-stream");
      }
      request.body() = message;
      request.prepare_payload();
      http::write(socket, request);

      // a stream's events are written as its chunks arrive; a JSON answer is read whole
      boost::beast::flat_buffer buffer;
      http::response_parser<http::string_body> parser;
      parser.body_limit(std::numeric_limits<std::uint64_t>::max());
      std::string pending;
      auto on_chunk = [&](std::uint64_t, boost::beast::string_view data,
                          boost::system::error_code&) -> std::size_t {
        pending.append(data.data(), data.size());
        write_events(pending);
        return data.size();
      };
      parser.on_chunk_body(on_chunk);  // kept by reference: it outlives the read
      http::read(socket, buffer, parser);
      const auto& head = parser.get();
      if (auto id = head.find("Mcp-Session-Id"); id != head.end()) {
        std::lock_guard lock(mutex_);
        const bool first = session_.empty();
        session_.assign(id->value().data(), id->value().size());
        // the session's own notifications (resources updated, tools changed) come on a GET
        if (first) events_ = std::thread([this] { post({}); });
      }
      const auto type = head[http::field::content_type];
      const bool events = std::string_view(type.data(), type.size()).find("text/event-stream") !=
                          std::string_view::npos;
      if (events && !head.chunked()) {  // an HTTP/1.0-style stream, to the connection's end
        pending += head.body();
        pending += "\n\n";
        write_events(pending);
      }
      const std::string& body = head.body();
      const unsigned status = head.result_int();
      if (events || status == 202) return;
      // a JSON-RPC answer (a result, or an error with its reason), or a plain refusal
      const json answer = json::parse(body, nullptr, false);
      if (answer.is_object() && answer.contains("jsonrpc"))
        write_line(answer.dump());
      else
        write_error(message, "HTTP " + std::to_string(status) + ": " + body.substr(0, 300));
    } catch (const std::exception& e) {
      write_error(message, "cannot reach " + endpoint_.host + ":" + endpoint_.port +
                               endpoint_.path + ": " + e.what());
    }
  }

  // Standard input ended: the session ends too (its calls cancelled).
  void end_session() {
    if (session().empty()) return;
    try {
      asio::io_context io;
      asio::ip::tcp::socket socket(io);
      http::write(socket, connected_request<http::empty_body>(http::verb::delete_, socket));
      boost::beast::flat_buffer buffer;
      http::response<http::string_body> response;
      http::read(socket, buffer, response);
    } catch (const std::exception&) {
      // the server is gone already: nothing to end
    }
  }

  const Endpoint endpoint_;
  const std::string token_;
  std::mutex mutex_;  // guards session_, in_flight_, workers_
  std::condition_variable room_;
  std::string session_;
  int in_flight_ = 0;
  std::vector<std::thread> workers_;
  std::thread events_;    // the session's GET stream, forwarded
  std::mutex out_mutex_;  // one line at a time on standard output
};

// The mcp endpoint among the gateway's, or "".
std::string mcp_endpoint(const std::map<std::string, std::vector<std::string>>& endpoints) {
  for (const auto& [transport, list] : endpoints)
    for (const auto& e : list)
      if (e.rfind("http://", 0) == 0 && e.find("/mcp") != std::string::npos) return e;
  for (const auto& [transport, list] : endpoints)
    for (const auto& e : list)
      if (e.rfind("http://", 0) == 0) return e;
  return {};
}

}  // namespace

int cmd_mcp(const McpArgs& args) {
  std::string token = args.token.value_or("");
  if (token.empty())
    if (const char* env = std::getenv("SIMGATE_TOKEN")) token = env;
  if (args.url) {
    if (!args.run.config.empty() || args.run.model)
      throw UsageError(
          "--url: a running simulation's endpoint, or CONFIG / --model to run one "
          "here, not both");
    StdioBridge(Endpoint::parse(*args.url), token).run();
    return 0;
  }
  if (args.run.config.empty() && !args.run.model)
    throw UsageError(
        "simgate mcp: give --url (a running simulation's mcp endpoint), CONFIG (with "
        "an mcp transport) or --model FILE.xml");

  RunArgs run = args.run;
  GatewayOptions options;
  options.plugin_dirs = run.plugin_dirs;
  apply_log_level(run.log_level);
  std::optional<StopOnSignals> signals;
  signals.emplace();
  ConfigErrors errors;
  run.mcp_only = true;  // --model alone: served by an mcp transport on a port the kernel picks
  Deployment deployment = load_deployment_args(run, errors);
  const bool has_mcp = std::any_of(
      deployment.transports.begin(), deployment.transports.end(), [](const TransportConfig& t) {
        return t.plugin == "mcp" || t.plugin.ends_with("libsimgate_transport_mcp.so");
      });
  if (!has_mcp)
    throw ConfigError(run.config +
                      ": no mcp transport for simgate mcp to bridge to: add \"mcp\": "
                      "{\"plugin\": \"mcp\", \"options\": {\"port\": 0}} to its transports and "
                      "map the services to it (docs/transports/mcp.md)");
  auto registry = sim::builtin_registry();
  std::unique_ptr<Gateway> gateway =
      build_gateway(run, deployment, registry, options, std::move(errors));
  gateway->start();
  const std::string endpoint = mcp_endpoint(gateway->endpoints());
  if (endpoint.empty()) {
    gateway->shutdown();
    throw std::runtime_error("the mcp transport announced no http:// endpoint");
  }
  log::info("simgate mcp: standard input and output bridged to ", endpoint);
  std::atomic<bool> input_ended{false};
  std::thread bridge([&] {
    StdioBridge(Endpoint::parse(endpoint), token).run();
    input_ended = true;
    gateway->stop();  // standard input ended: so does the simulation
  });
  signals->start([&gateway] { gateway->stop(); });
  int code = 0;
  try {
    gateway->run();
  } catch (const std::exception& e) {
    log::error("simgate: the simulation stopped: ", e.what());
    code = 1;
  }
  signals.reset();
  // a signal stopped it while standard input is open: the bridge, blocked reading it, ends
  // with the process
  if (input_ended)
    bridge.join();
  else
    bridge.detach();
  gateway->shutdown();
  return code;
}

}  // namespace simgate::gateway
