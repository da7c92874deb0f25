// `simgate watch` and `simgate publish` (see commands.h): a component's data stream
// (docs/streams.md) from a shell, through the socket, jsonrpc or websocket transport.
//
// Each transport reaches a stream its own way, behind a StreamLink: the socket transport
// gives a TCP port per stream (`simulation get_stream_port`; samples and commands are lines
// on it), JSON-RPC and WebSocket subscribe (`rpc.subscribe` -> `rpc.sample` notifications)
// and publish (`rpc.publish`, answered). DDS streams are typed topics of their own, which a
// line of JSON would not do justice to: those commands refuse it and say where to look.
#include <sys/socket.h>

#include <algorithm>
#include <atomic>
#include <climits>
#include <csignal>
#include <iostream>
#include <thread>
#include <type_traits>

#include "commands.h"
#include "simgate/client/client.h"
#include "simgate/client/jsonrpc_client.h"
#include "simgate/client/line_connection.h"
#include "simgate/client/socket_client.h"
#include "simgate/client/websocket_client.h"
#include "simgate/core/suggest.h"

namespace simgate::gateway {

namespace {

using Clock = std::chrono::steady_clock;

// How often a wait looks whether Ctrl-C came (where the wait can be cut in slices).
constexpr auto k_stop_check = std::chrono::milliseconds(100);

// ---- Ctrl-C, SIGTERM and a closed stdout end the command cleanly (exit 0)

std::atomic<bool> g_stop_requested{false};
std::atomic<int> g_fd_to_interrupt{-1};  // a socket a blocking read waits on, or -1

extern "C" void on_stop_signal(int) {
  g_stop_requested.store(true);
  // a blocked read of that socket returns at once (shutdown is async-signal-safe)
  if (int fd = g_fd_to_interrupt.load(); fd >= 0) ::shutdown(fd, SHUT_RDWR);
}

// While it lives: SIGINT and SIGTERM ask to stop; SIGPIPE is ignored, so that writing to a
// closed stdout (`| head -3`) fails instead of killing the process. Restores the previous
// dispositions when it ends.
class StopSignals {
 public:
  StopSignals() {
    g_stop_requested = false;
    g_fd_to_interrupt = -1;
    struct sigaction stop{};
    stop.sa_handler = on_stop_signal;
    sigemptyset(&stop.sa_mask);
    ::sigaction(SIGINT, &stop, &old_int_);
    ::sigaction(SIGTERM, &stop, &old_term_);
    struct sigaction ignore{};
    ignore.sa_handler = SIG_IGN;
    sigemptyset(&ignore.sa_mask);
    ::sigaction(SIGPIPE, &ignore, &old_pipe_);
  }
  ~StopSignals() {
    g_fd_to_interrupt = -1;
    ::sigaction(SIGINT, &old_int_, nullptr);
    ::sigaction(SIGTERM, &old_term_, nullptr);
    ::sigaction(SIGPIPE, &old_pipe_, nullptr);
  }
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

  static bool stop_requested() { return g_stop_requested.load(); }
  // A stop signal shuts `fd` down, for reads that cannot wait in slices.
  static void interrupt_on_stop(int fd) {
    g_fd_to_interrupt = fd;
    if (stop_requested() && fd >= 0) ::shutdown(fd, SHUT_RDWR);
  }

 private:
  struct sigaction old_int_{}, old_term_{}, old_pipe_{};
};

// Sleeps until `when`, or less when a stop is asked.
void sleep_until_or_stop(Clock::time_point when) {
  while (!StopSignals::stop_requested() && Clock::now() < when)
    std::this_thread::sleep_for(std::min<Clock::duration>(k_stop_check, when - Clock::now()));
}

// The time left until `until` (milliseconds::max() for none), at least 1 ms.
std::chrono::milliseconds time_left(Clock::time_point until) {
  if (until == Clock::time_point::max()) return std::chrono::milliseconds::max();
  return std::max(std::chrono::milliseconds(1),
                  std::chrono::duration_cast<std::chrono::milliseconds>(until - Clock::now()));
}

// ---- which streams a transport carries

struct StreamEntry {
  std::string component;  // robot.pose
  std::string direction;  // OUT (samples) or IN (commands)
  std::string kind;       // pose, velocity, ...
};

std::vector<StreamEntry> stream_entries(const json& list) {
  std::vector<StreamEntry> entries;
  for (const auto& s : list)
    if (s.is_object())
      entries.push_back({s.value("component", std::string("?")),
                         s.value("direction", std::string("?")),
                         s.value("kind", std::string("?"))});
  return entries;
}

// "robot.pose (OUT pose), robot.motion (IN velocity)" of the streams going `direction`
// ("" for all).
std::string describe(const std::vector<StreamEntry>& entries, const std::string& direction = "") {
  std::string text;
  for (const auto& e : entries)
    if (direction.empty() || e.direction == direction)
      text += (text.empty() ? "" : ", ") + e.component + " (" + e.direction + " " + e.kind + ")";
  return text.empty() ? "none" : text;
}

// Throws (exit 1) unless `component` has a stream going `direction` on this transport; the
// message says which streams there are.
void require_stream(const std::vector<StreamEntry>& entries, const std::string& component,
                    const std::string& direction, const std::string& transport,
                    const std::string& command) {
  const bool out = direction == "OUT";
  for (const auto& e : entries) {
    if (e.component != component) continue;
    if (e.direction == direction) return;
    throw std::runtime_error(
        command + ": " + component + " is an " + (out ? "input" : "output") + " stream (" +
        e.direction + " " + e.kind + "): " +
        (out ? "it takes commands (simgate publish " + component + " JSON_OBJECT)"
             : "it has samples to read (simgate watch " + component + ")") +
        "; the " + (out ? "output" : "input") + " streams of the " + transport +
        " transport: " + describe(entries, direction));
  }
  std::vector<std::string> names;
  for (const auto& e : entries) names.push_back(e.component);
  throw std::runtime_error(command + ": " + component + " has no stream on the " + transport +
                           " transport" + did_you_mean(component, names) +
                           "; its streams: " + describe(entries) +
                           " (the configuration's \"streams\" section says which transports carry "
                           "which, docs/streams.md)");
}

// ---- one transport's way to a stream

class StreamLink {
 public:
  virtual ~StreamLink() = default;
  // The streams the transport carries; nullopt when it cannot tell (then the server's own
  // error speaks when the stream is used).
  virtual std::optional<std::vector<StreamEntry>> streams() = 0;
  // Starts receiving the samples of an output stream.
  virtual void subscribe(const std::string& component) = 0;
  // The next sample as one line of JSON; nullopt once `until` passed or a stop was asked.
  virtual std::optional<std::string> next_sample(Clock::time_point until) = 0;
  // Ends the subscription (best effort: the connection's end ends it too).
  virtual void unsubscribe() = 0;
  // Sends one command to an input stream; throws (exit 1) when the server refuses it.
  virtual void publish(const std::string& component, const json& data) = 0;
  // What the commands sent came to, for the line `publish` prints.
  virtual std::string published(int sent) const = 0;
};

std::string commands_text(int n) { return std::to_string(n) + (n == 1 ? " command" : " commands"); }

// MORSE's way: a TCP port per stream, one JSON object a line, nothing answered on it.
class SocketStreamLink : public StreamLink {
 public:
  SocketStreamLink(const ClientTarget& target, std::string command)
      : command_(std::move(command)),
        timeout_(target.timeout),
        client_(client::make_client("socket", target.options)) {}

  std::optional<std::vector<StreamEntry>> streams() override {
    Outcome stats = client_->call("simulation", "get_stream_statistics", json::array(), timeout_);
    if (stats.status != Status::success || !stats.value || !stats.value->is_array())
      return std::nullopt;
    return stream_entries(*stats.value);
  }

  void subscribe(const std::string& component) override { open(component); }

  std::optional<std::string> next_sample(Clock::time_point until) override {
    while (!StopSignals::stop_requested() && Clock::now() < until) {
      auto line = stream_->read_line(std::min(k_stop_check, time_left(until)));
      if (!line) continue;
      if (!line->empty() && line->back() == '\r') line->pop_back();
      if (!line->empty()) return line;
    }
    return std::nullopt;
  }

  void unsubscribe() override {
    if (stream_) stream_->close();
  }

  void publish(const std::string& component, const json& data) override {
    if (!stream_) open(component);
    stream_->send_line(data.dump());
  }

  std::string published(int sent) const override {
    return commands_text(sent) + " written to stream port " + std::to_string(port_) +
           " (the socket transport answers nothing there; simgate call simulation "
           "get_stream_statistics counts refusals)";
  }

 private:
  // Connects to the component's stream port, on the host of the service port.
  void open(const std::string& component) {
    Outcome port =
        client_->call("simulation", "get_stream_port", json::array({component}), timeout_);
    if (port.status != Status::success || !port.value || !port.value->is_number_integer())
      throw std::runtime_error(
          command_ + ": " + component + ": simulation get_stream_port: " +
          (port.message.empty()
               ? (port.value ? port.value->dump() : std::string(to_string(port.status)))
               : port.message));
    port_ = port.value->get<int>();
    // on the service port's host, with its token if it asked for one
    stream_ = dynamic_cast<client::SocketClient&>(*client_).open_stream_port(
        "simgate " + command_, static_cast<std::uint16_t>(port_), timeout_);
  }

  std::string command_;                             // watch or publish, for messages
  std::chrono::milliseconds timeout_;               // --timeout
  std::unique_ptr<client::Client> client_;          // the service port
  std::unique_ptr<client::LineConnection> stream_;  // the stream port, once open
  int port_ = 0;                                    // its number
};

// JSON-RPC's way (over TCP lines or WebSocket messages): rpc.subscribe, rpc.sample
// notifications, rpc.unsubscribe; rpc.publish, answered. `Rpc` has request() and receive()
// (JsonRpcClient, WebSocketClient).
template <class Rpc>
class RpcStreamLink : public StreamLink {
 public:
  RpcStreamLink(const ClientTarget& target, std::string command)
      : command_(std::move(command)),
        transport_(target.transport),
        timeout_(target.timeout),
        client_(client::make_client(target.transport, target.options)),
        rpc_(dynamic_cast<Rpc&>(*client_)) {}

  std::optional<std::vector<StreamEntry>> streams() override {
    json response = rpc_.request("rpc.streams", nullptr, timeout_);
    if (!response.contains("result") || !response["result"].is_array()) return std::nullopt;
    return stream_entries(response["result"]);
  }

  void subscribe(const std::string& component) override {
    // a read of the WebSocket cannot be cut in slices (a timeout breaks it): Ctrl-C shuts
    // its socket down instead
    if constexpr (std::is_same_v<Rpc, client::WebSocketClient>)
      StopSignals::interrupt_on_stop(rpc_.native_handle());
    json response = rpc_.request("rpc.subscribe", {{"component", component}}, timeout_);
    if (!response.contains("result")) throw refusal("rpc.subscribe", component, response);
    component_ = component;
    subscription_ = response["result"].value("subscription", json());
  }

  std::optional<std::string> next_sample(Clock::time_point until) override {
    while (!StopSignals::stop_requested() && Clock::now() < until) {
      std::optional<json> message;
      if constexpr (std::is_same_v<Rpc, client::WebSocketClient>) {
        message = rpc_.receive(time_left(until));
      } else {
        message = rpc_.receive(std::min(k_stop_check, time_left(until)));
      }
      if (!message) {
        if (rpc_.closed()) return std::nullopt;  // a WebSocket read that timed out
        continue;
      }
      if (!message->is_object() || !message->contains("params")) continue;
      const json& params = (*message)["params"];
      if (!params.is_object() || params.value("subscription", json()) != subscription_) continue;
      const std::string method = message->value("method", "");
      if (method == "rpc.sample") return params.value("data", json()).dump();
      if (method == "rpc.unsubscribed")
        throw std::runtime_error(command_ + ": " + component_ +
                                 ": the stream ended: " + params.value("reason", std::string("?")));
    }
    return std::nullopt;
  }

  void unsubscribe() override {
    if (subscription_.is_null() || rpc_.closed()) return;
    try {
      rpc_.request("rpc.unsubscribe", {{"subscription", subscription_}}, timeout_);
    } catch (const client::ClientError&) {
      // the subscription ends with the connection anyway
    }
  }

  void publish(const std::string& component, const json& data) override {
    json response =
        rpc_.request("rpc.publish", {{"component", component}, {"data", data}}, timeout_);
    if (!response.contains("result")) throw refusal("rpc.publish", component, response);
    ++(response["result"].value("applied", false) ? applied_ : queued_);
  }

  std::string published(int sent) const override {
    return commands_text(sent) + " published (" + std::to_string(applied_) + " applied at once, " +
           std::to_string(queued_) + " at the simulation's next turn)";
  }

 private:
  // The server's error response as a failure of this command (exit 1).
  std::runtime_error refusal(const std::string& method, const std::string& component,
                             const json& response) const {
    const json error = response.value("error", json::object());
    std::string text = command_ + ": " + component + ": " + transport_ + " " + method +
                       " refused: " + error.value("message", response.dump());
    const json data = error.value("data", json::object());
    if (data.is_object() && data.contains("streams"))
      text += " (streams: " + data["streams"].dump() + ")";
    return std::runtime_error(text);
  }

  std::string command_;                     // watch or publish, for messages
  std::string transport_;                   // jsonrpc or websocket
  std::chrono::milliseconds timeout_;       // --timeout
  std::unique_ptr<client::Client> client_;  // the connection
  Rpc& rpc_;                                // the same, with its JSON-RPC methods
  std::string component_;                   // subscribed to
  json subscription_;                       // its id, null before
  int applied_ = 0, queued_ = 0;            // rpc.publish's answers: applied at once or not
};

std::unique_ptr<StreamLink> connect_stream_link(const ClientTarget& target,
                                                const std::string& command) {
  if (target.transport == "dds")
    throw UsageError(
        command +
        ": --transport dds: DDS carries streams as typed topics of their own "
        "(simgate/<component>, simgate/<component>/json), read and written with a DDS reader or "
        "writer: docs/transports/dds.md, \"Data streams\"; simgate " +
        command + " speaks socket, jsonrpc and websocket");
  if (target.transport == "jsonrpc")
    return std::make_unique<RpcStreamLink<client::JsonRpcClient>>(target, command);
  if (target.transport == "websocket")
    return std::make_unique<RpcStreamLink<client::WebSocketClient>>(target, command);
  return std::make_unique<SocketStreamLink>(target, command);
}

// A number > 0 and <= max (--rate).
double parse_positive(const std::string& option, const std::string& text, double max,
                      const std::string& unit) {
  try {
    std::size_t used = 0;
    double value = std::stod(text, &used);
    if (used == text.size() && value > 0 && value <= max) return value;
  } catch (const std::exception&) {}
  throw UsageError(option + ": expected a number of " + unit + " above 0, up to " +
                   std::to_string(static_cast<long>(max)) + ", found '" + text + "'");
}

}  // namespace

int cmd_watch(const WatchArgs& args) {
  const int count = args.count ? parse_int("--count", *args.count, 1, INT_MAX) : INT_MAX;
  const std::optional<double> duration =
      args.duration ? std::optional(parse_seconds("--duration", *args.duration, 0.001, 1e8))
                    : std::nullopt;
  const ClientTarget target = client_target(args.client);
  StopSignals signals;
  auto link = connect_stream_link(target, "watch");
  if (auto streams = link->streams())
    require_stream(*streams, args.component, "OUT", target.transport, "watch");
  try {
    // the duration counts from the subscription: the samples it covers
    link->subscribe(args.component);
    const auto until = duration ? Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                                     std::chrono::duration<double>(*duration))
                                : Clock::time_point::max();
    for (int printed = 0; printed < count; ++printed) {
      std::optional<std::string> sample = link->next_sample(until);
      if (!sample) break;
      std::cout << *sample << std::endl;  // a line at a time: `| head -3`, `| jq` see it now
      if (!std::cout) break;              // stdout closed: nobody reads any more
    }
  } catch (const client::ClientError&) {
    if (!StopSignals::stop_requested()) throw;
    // Ctrl-C shut the WebSocket down under a read: a clean end
  }
  link->unsubscribe();
  return 0;
}

int cmd_publish(const PublishArgs& args) {
  const json data = json::parse(args.data, nullptr, false);
  if (data.is_discarded() || !data.is_object())
    throw UsageError(
        "publish: JSON_OBJECT: expected one JSON object, such as '{\"v\": 0.5, \"w\": 0}', found " +
        (data.is_discarded() ? std::string("text that is not JSON")
                             : std::string("a JSON ") + data.type_name()) +
        ": '" + args.data + "' (quote it for the shell)");
  const int count = args.count ? parse_int("--count", *args.count, 1, 1000000) : 1;
  const double rate =
      args.rate ? parse_positive("--rate", *args.rate, 10000, "commands per second") : 10.0;
  const ClientTarget target = client_target(args.client);
  StopSignals signals;
  auto link = connect_stream_link(target, "publish");
  if (auto streams = link->streams())
    require_stream(*streams, args.component, "IN", target.transport, "publish");
  const auto period =
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / rate));
  auto next = Clock::now();
  int sent = 0;
  while (sent < count && !StopSignals::stop_requested()) {
    if (sent > 0) {
      next += period;
      sleep_until_or_stop(next);
      if (StopSignals::stop_requested()) break;
    }
    link->publish(args.component, data);
    ++sent;
  }
  std::cout << args.component << ": " << link->published(sent) << "\n";
  return 0;
}

}  // namespace simgate::gateway
