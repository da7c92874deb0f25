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
// steps covered over its wall time. The clients are ws_client.h's, one thread polling every
// connection, as the page's browser would read them.
//
// Threads: main (the gateway's loop) and the client thread.
#include "web_bench.h"

#include "ws_client.h"

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
            pages[i]->read_messages([&](bool /*binary*/, std::string_view message) {
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
