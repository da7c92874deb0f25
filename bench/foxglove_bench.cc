// foxglove_bench.cc — issue #38's target: "transforms at 60 Hz for 50 bodies plus a 640x480
// camera at 10 Hz to 4 clients at real-time factor >= 0.99".
//
// A Gateway is built, as `simgate run` builds one, from a deployment made here: the scene
// --mjcf (bench/pendulums50.xml), a robot "rig" with a video_camera of 640x480 at 10 Hz
// seeing the scene from its MJCF camera "overview", the foxglove transport on an ephemeral
// loopback port carrying the `simulation` stream (body poses, hence /tf) at --frequency and
// the camera's. It runs at real time in this process. A client thread measures two phases of
// `seconds` of wall time each: nobody connected, then `clients` Foxglove clients
// (ws_client.h, subprotocol foxglove.websocket.v1), each subscribed to /tf and /rig/camera
// and reading every Message Data, timed from the moment every client has one of each. The
// real-time factor of a phase is the simulated time its steps covered over its wall time.
//
// Threads: main (the gateway's loop) and the client thread.
#include "foxglove_bench.h"

#include <poll.h>

#include <algorithm>
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
#include "ws_client.h"

namespace simgate::bench {

namespace {

constexpr const char* k_camera_topic = "/rig/camera";

// What one client received in the timed phase.
struct Received {
  std::uint64_t transforms = 0, images = 0;  // Message Data on /tf, on the camera
  std::uint64_t bytes = 0;                   // their payloads
};

struct FoxglovePhase : RealtimePhase {
  std::vector<Received> clients;
};

// A Foxglove client: its connection and the channel ids it learnt from advertise.
struct Client {
  std::unique_ptr<WebSocketClient> ws;
  std::int64_t tf = -1, camera = -1;  // channel ids (-1: not advertised yet)
  bool subscribed = false;
  Received received;
};

// A Message Data's subscription id (opcode 0x01, u32 LE), or -1 for any other message.
std::int64_t subscription_of(std::string_view message) {
  if (message.size() < 13 || static_cast<unsigned char>(message[0]) != 0x01) return -1;
  std::uint32_t id = 0;
  for (int i = 4; i >= 1; --i) id = (id << 8) | static_cast<unsigned char>(message[i]);
  return id;
}

}  // namespace

json run_foxglove_rtf(const std::string& mjcf, int clients, double frequency, double seconds) {
  namespace gw = simgate::gateway;
  log::set_level(log::Level::warning);
  const std::string scene = std::filesystem::absolute(mjcf).string();
  json document = {
      {"scene", {{"mjcf", scene}, {"timestep", 0.002}, {"realtime_factor", 1.0}}},
      {"transports",
       {{"foxglove", {{"plugin", "foxglove"}, {"options", {{"host", "127.0.0.1"}, {"port", 0}}}}}}},
      {"robots",
       {{{"name", "rig"},
         {"type", "robot"},
         {"body", "rig"},
         {"components",
          {{{"name", "camera"},
            {"type", "video_camera"},
            {"frequency", 10},
            {"options", {{"camera", "overview"}, {"cam_width", 640}, {"cam_height", 480}}}}}}}}},
      {"services", {{"default", {"foxglove"}}}},
      {"streams",
       {{"simulation", {{"transports", {"foxglove"}}, {"frequency", frequency}}},
        {"rig.camera", {"foxglove"}}}},
      {"log_level", "warning"}};
  const gw::Deployment deployment = gw::parse_deployment(
      document, std::filesystem::path(scene).parent_path().string(), "foxglove_bench");
  const auto registry = sim::builtin_registry();
  gw::Gateway gateway(deployment, registry, {});
  gateway.start();
  const std::uint16_t port = endpoint_port(gateway.endpoints().at("foxglove").at(0));
  const double timestep = gateway.simulation().timestep();

  FoxglovePhase without, with;
  std::size_t bodies = 0, image_bytes = 0;
  std::string error;
  std::thread client_thread([&] {
    try {
      auto measure = [&](RealtimePhase& phase, auto&& during) {
        measure_realtime_phase(
            phase, seconds, timestep, [&] { return gateway.simulation().steps(); }, during);
      };
      // phase 1: nobody connected
      measure(without, [](Clock::time_point end) { std::this_thread::sleep_until(end); });

      // phase 2: the clients, each subscribed to /tf and the camera once they are advertised
      std::vector<Client> all(static_cast<std::size_t>(clients));
      std::vector<pollfd> fds;
      for (Client& c : all) {
        c.ws = std::make_unique<WebSocketClient>(port, "foxglove.websocket.v1");
        fds.push_back({c.ws->fd(), POLLIN, 0});
      }
      const auto on_message = [&](Client& c, bool binary, std::string_view message) {
        if (!binary) {
          if (message.find("\"advertise\"") == std::string_view::npos) return;
          const json advertised = json::parse(message);
          for (const json& channel : advertised.at("channels")) {
            if (channel.at("topic") == "/tf") c.tf = channel.at("id").get<std::int64_t>();
            if (channel.at("topic") == k_camera_topic)
              c.camera = channel.at("id").get<std::int64_t>();
          }
          if (!c.subscribed && c.tf >= 0 && c.camera >= 0) {
            c.ws->send_text(R"({"op":"subscribe","subscriptions":[{"id":1,"channelId":)" +
                            std::to_string(c.tf) + R"(},{"id":2,"channelId":)" +
                            std::to_string(c.camera) + "}]}");
            c.subscribed = true;
          }
          return;
        }
        const std::int64_t subscription = subscription_of(message);
        if (subscription == 1) {
          ++c.received.transforms;
          if (bodies == 0) bodies = json::parse(message.substr(13)).at("transforms").size();
        } else if (subscription == 2) {
          ++c.received.images;
          image_bytes = message.size() - 13;
        } else {
          return;
        }
        c.received.bytes += message.size();
      };
      auto read_until = [&](Clock::time_point end, bool until_each_has_both) {
        while (Clock::now() < end) {
          if (until_each_has_both && std::all_of(all.begin(), all.end(), [](const Client& c) {
                return c.received.transforms > 0 && c.received.images > 0;
              }))
            return;
          if (::poll(fds.data(), fds.size(), 20) <= 0) continue;
          for (std::size_t i = 0; i < all.size(); ++i) {
            if (!(fds[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
            all[i].ws->read_messages([&](bool binary, std::string_view message) {
              on_message(all[i], binary, message);
            });
          }
        }
        if (until_each_has_both)
          throw std::runtime_error("not every client had a /tf message and an image within 60 s");
      };
      read_until(Clock::now() + std::chrono::seconds(60), true);
      for (Client& c : all) c.received = Received{};
      measure(with, [&](Clock::time_point end) { read_until(end, false); });
      for (const Client& c : all) with.clients.push_back(c.received);
    } catch (const std::exception& e) {
      error = e.what();
    }
    gateway.stop();
  });
  gateway.run();
  client_thread.join();
  gateway.shutdown();
  if (!error.empty()) throw std::runtime_error(error);
  auto per_client = [&](auto count) {
    json rates = json::array();
    for (const Received& r : with.clients)
      rates.push_back(static_cast<double>(count(r)) / with.wall_s);
    const auto [low, high] = std::minmax_element(rates.begin(), rates.end());
    return json{{"min", *low}, {"max", *high}};
  };
  std::uint64_t bytes = 0;
  for (const Received& r : with.clients) bytes += r.bytes;
  auto phase_json = [](const RealtimePhase& p) {
    return json{{"wall_s", p.wall_s},
                {"realtime_factor", p.realtime_factor},
                {"gateway_cpu_per_s", p.cpu_s / p.wall_s}};
  };
  return {
      {"mode", "foxglove_rtf"},
      {"mjcf", scene},
      {"clients", clients},
      {"frequency_hz", frequency},
      {"bodies", bodies},
      {"image_message_bytes", image_bytes},
      {"timestep", timestep},
      {"without", phase_json(without)},
      {"with", phase_json(with)},
      {"transforms_per_s_per_client", per_client([](const Received& r) { return r.transforms; })},
      {"images_per_s_per_client", per_client([](const Received& r) { return r.images; })},
      {"mib_per_s", static_cast<double>(bytes) / with.wall_s / (1 << 20)},
      {"ratio", with.realtime_factor / without.realtime_factor}};
}

}  // namespace simgate::bench
