// web_bench.cc — issue #23's browser target: "pushing poses at 60 Hz to 20 browsers keeps the
// real-time factor >= 0.99".
//
// A Gateway is built from the web app's deployment (config/demo.json: the websocket transport
// the page talks to) as `simgate run` builds it, its transports on ephemeral loopback ports,
// the `simulation` component's body_poses stream mapped to the websocket transport at
// --frequency. It runs at real time in this process. A client thread measures two phases of
// `seconds` of wall time each: nobody connected, then `clients` WebSocket connections (what a
// browser page opens: the HTTP upgrade, then JSON-RPC text messages), each subscribed with
// rpc.subscribe to `simulation` and reading every rpc.sample, timed from the moment every
// client has its first sample. The real-time factor of a phase is the simulated time its
// steps covered over its wall time. The client is a few lines of RFC 6455 over a plain socket
// (masked text frames out, unmasked frames in), one thread polling every connection, as the
// page's browser would read them: not Beast, so that the server's side alone is measured.
//
// Threads: main (the gateway's loop) and the client thread.
#include "web_bench.h"

#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "simgate/core/log.h"
#include "simgate/gateway/deployment.h"
#include "simgate/gateway/gateway.h"
#include "simgate/sim/registry.h"

namespace simgate::bench {

namespace {

// One WebSocket client connection: the upgrade, masked text messages out, whole messages in.
class WebSocketClient {
 public:
  explicit WebSocketClient(std::uint16_t port) : fd_(connect_loopback(port)) {
    send_all(
        "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n");
    const auto deadline = Clock::now() + std::chrono::seconds(30);
    std::size_t end;
    while ((end = buffer_.find("\r\n\r\n")) == std::string::npos) {
      if (Clock::now() >= deadline || !read_some(100))
        throw std::runtime_error("no WebSocket handshake answer");
    }
    if (!buffer_.starts_with("HTTP/1.1 101"))
      throw std::runtime_error("the WebSocket upgrade was refused: " +
                               buffer_.substr(0, buffer_.find('\r')));
    buffer_.erase(0, end + 4);
  }
  ~WebSocketClient() { ::close(fd_); }
  WebSocketClient(const WebSocketClient&) = delete;
  WebSocketClient& operator=(const WebSocketClient&) = delete;

  int fd() const { return fd_; }

  // One text message, in one masked frame (a client's frames are masked, RFC 6455 5.3).
  void send_text(std::string_view text) {
    static constexpr std::array<unsigned char, 4> k_mask = {0x5a, 0x17, 0xc3, 0x9e};
    std::string frame(1, static_cast<char>(0x81));  // FIN, text
    const std::size_t n = text.size();
    if (n < 126) {
      frame += static_cast<char>(0x80 | n);
    } else if (n < 65536) {
      frame += static_cast<char>(0x80 | 126);
      frame += static_cast<char>(n >> 8), frame += static_cast<char>(n & 0xff);
    } else {
      frame += static_cast<char>(0x80 | 127);
      for (int shift = 56; shift >= 0; shift -= 8) frame += static_cast<char>((n >> shift) & 0xff);
    }
    frame.append(reinterpret_cast<const char*>(k_mask.data()), k_mask.size());
    for (std::size_t i = 0; i < n; ++i) frame += static_cast<char>(text[i] ^ k_mask[i % 4]);
    send_all(frame);
  }

  // Reads what the socket holds (it is readable) and hands each whole message to `on_message`.
  template <class F>
  void read_messages(F&& on_message) {
    if (!read_some(0)) throw std::runtime_error("the WebSocket connection closed");
    std::size_t at = 0;
    for (;;) {
      if (buffer_.size() - at < 2) break;
      const auto byte = [&](std::size_t i) { return static_cast<unsigned char>(buffer_[at + i]); };
      const unsigned opcode = byte(0) & 0x0f;
      std::uint64_t length = byte(1) & 0x7f;
      std::size_t header = 2;
      if (length == 126) {
        if (buffer_.size() - at < 4) break;
        length = (static_cast<std::uint64_t>(byte(2)) << 8) | byte(3);
        header = 4;
      } else if (length == 127) {
        if (buffer_.size() - at < 10) break;
        length = 0;
        for (int i = 2; i < 10; ++i) length = (length << 8) | byte(i);
        header = 10;
      }
      if (buffer_.size() - at < header + length) break;
      const std::string_view payload(buffer_.data() + at + header, length);
      if (opcode == 0x8) throw std::runtime_error("the server closed the WebSocket");
      if (opcode == 0x1 || opcode == 0x0)
        on_message(payload);  // text (the server sends whole ones)
      at += header + length;  // pings are not answered: runs are short
    }
    buffer_.erase(0, at);
  }

 private:
  void send_all(std::string_view bytes) {
    while (!bytes.empty()) {
      const ssize_t n = ::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL);
      if (n <= 0) throw std::runtime_error("send failed on a WebSocket connection");
      bytes.remove_prefix(static_cast<std::size_t>(n));
    }
  }
  // Appends what arrives within `timeout_ms`; false when the peer closed.
  bool read_some(int timeout_ms) {
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) return true;
    char chunk[65536];
    const ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
    if (n <= 0) return false;
    buffer_.append(chunk, static_cast<std::size_t>(n));
    return true;
  }

  int fd_;
  std::string buffer_;  // received, not yet handed out
};

struct WebPhase : RealtimePhase {
  std::vector<std::uint64_t> samples;  // rpc.sample messages read, per client
  std::uint64_t bytes = 0;             // their payloads' bytes
};

bool is_sample(std::string_view message) {
  return message.substr(0, 64).find("\"rpc.sample\"") != std::string_view::npos;
}

}  // namespace

json run_web_poses(const std::string& config, int clients, double frequency, double seconds) {
  namespace gw = simgate::gateway;
  log::set_level(log::Level::warning);
  json document = gw::load_config_document(config);
  std::string websocket;  // the transport the page talks to
  for (auto& [name, transport] : document.at("transports").items()) {
    json& options = transport["options"];
    options["host"] = "127.0.0.1";
    options["port"] = 0;
    if (options.contains("stream_port")) options["stream_port"] = 0;
    if (transport.value("plugin", "") == "websocket") websocket = name;
  }
  if (websocket.empty())
    throw std::runtime_error(config + " has no websocket transport (the web app's)");
  document["streams"]["simulation"] = {{"transports", {websocket}}, {"frequency", frequency}};
  document["log_level"] = "warning";
  const gw::Deployment deployment =
      gw::parse_deployment(document, std::filesystem::path(config).parent_path().string(), config);
  const auto registry = sim::builtin_registry();
  gw::Gateway gateway(deployment, registry, {});
  gateway.start();
  const std::uint16_t port = endpoint_port(gateway.endpoints().at(websocket).at(0));
  const double timestep = gateway.simulation().timestep();

  WebPhase without, with;
  std::uint64_t bodies = 0;
  std::string error;
  std::thread client([&] {
    try {
      auto measure = [&](RealtimePhase& phase, auto&& during) {
        measure_realtime_phase(
            phase, seconds, timestep, [&] { return gateway.simulation().steps(); }, during);
      };
      // phase 1: nobody connected
      measure(without, [](Clock::time_point end) { std::this_thread::sleep_until(end); });

      // phase 2: the pages, each subscribed; timed once every one has its first sample
      std::vector<std::unique_ptr<WebSocketClient>> pages;
      for (int i = 0; i < clients; ++i) {
        pages.push_back(std::make_unique<WebSocketClient>(port));
        pages.back()->send_text(
            R"({"jsonrpc":"2.0","id":1,"method":"rpc.subscribe","params":{"component":"simulation"}})");
      }
      std::vector<pollfd> fds;
      for (const auto& page : pages) fds.push_back({page->fd(), POLLIN, 0});
      std::vector<std::uint64_t> count(pages.size(), 0);
      // reads every page until `end`; a refused subscription throws
      auto read_until = [&](Clock::time_point end, bool until_each_has_one) {
        while (Clock::now() < end) {
          if (until_each_has_one &&
              std::all_of(count.begin(), count.end(), [](auto n) { return n > 0; }))
            return;
          if (::poll(fds.data(), fds.size(), 20) <= 0) continue;
          for (std::size_t i = 0; i < pages.size(); ++i) {
            if (!(fds[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
            pages[i]->read_messages([&](std::string_view message) {
              if (is_sample(message)) {
                ++count[i];
                with.bytes += message.size();
                if (bodies == 0)
                  bodies = json::parse(message).at("params").at("data").at("poses").size();
              } else if (message.find("\"error\"") != std::string_view::npos) {
                throw std::runtime_error("rpc.subscribe simulation: " +
                                         std::string(message.substr(0, 400)));
              }
            });
          }
        }
        if (until_each_has_one)
          throw std::runtime_error("not every client had a body_poses sample within 60 s");
      };
      read_until(Clock::now() + std::chrono::seconds(60), true);
      std::fill(count.begin(), count.end(), 0);
      with.bytes = 0;
      measure(with, [&](Clock::time_point end) { read_until(end, false); });
      with.samples = count;
    } catch (const std::exception& e) {
      error = e.what();
    }
    gateway.stop();
  });
  gateway.run();
  client.join();
  gateway.shutdown();
  if (!error.empty()) throw std::runtime_error(error);
  std::uint64_t total = 0, fewest = with.samples.empty() ? 0 : with.samples[0], most = 0;
  for (std::uint64_t n : with.samples)
    total += n, fewest = std::min(fewest, n), most = std::max(most, n);
  auto phase_json = [](const WebPhase& p) {
    return json{{"wall_s", p.wall_s},
                {"realtime_factor", p.realtime_factor},
                {"gateway_cpu_per_s", p.cpu_s / p.wall_s}};
  };
  return {{"mode", "web_poses"},
          {"config", config},
          {"clients", clients},
          {"frequency_hz", frequency},
          {"bodies", bodies},
          {"timestep", timestep},
          {"without", phase_json(without)},
          {"with", phase_json(with)},
          {"samples_per_s_per_client",
           {{"mean", static_cast<double>(total) / static_cast<double>(clients) / with.wall_s},
            {"min", static_cast<double>(fewest) / with.wall_s},
            {"max", static_cast<double>(most) / with.wall_s}}},
          {"mean_sample_bytes",
           total ? static_cast<double>(with.bytes) / static_cast<double>(total) : 0.0},
          {"ratio", with.realtime_factor / without.realtime_factor}};
}

}  // namespace simgate::bench
