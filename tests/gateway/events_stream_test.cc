// The simulation's event stream, end to end (issue #35): a gateway whose world diverges in
// its first step (gravity of 1e11 m/s²: MuJoCo's accelerations are beyond its 1e10) streams
// `simulation.events` on the socket, JSON-RPC and WebSocket transports; a client of each,
// subscribed before, is told {"event": "diverged", ...} when a client's `simulation step`
// diverges, and a JSON-RPC client that plays on hears "resumed", "diverged" and "paused".
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "in_process_gateway.h"
#include "ws_test_client.h"

namespace simgate::gateway::testing {
namespace {

using namespace std::chrono_literals;
using websocket_test::WsClient;

// A ball in a world whose gravity no step survives.
constexpr const char* k_diverging_scene = R"(<mujoco>
  <option gravity="0 0 -1e11"/>
  <worldbody>
    <body name="ball" pos="0 0 1"><freejoint name="ball_free"/><geom type="sphere" size="0.1"/></body>
  </worldbody>
</mujoco>)";

json events_config(const TempDir& dir) {
  const std::string scene = dir.write("diverging.xml", k_diverging_scene);
  const json everywhere = {"socket", "jsonrpc", "websocket"};
  return {{"scene", {{"mjcf", scene}, {"start_paused", true}, {"on_divergence", "pause"}}},
          {"transports",
           {{"socket", {{"plugin", "socket"}, {"options", {{"port", 0}, {"stream_port", 0}}}}},
            {"jsonrpc", {{"plugin", "jsonrpc"}, {"options", {{"port", 0}}}}},
            {"websocket", {{"plugin", "websocket"}, {"options", {{"port", 0}}}}}}},
          {"services", {{"simulation", everywhere}, {"time", everywhere}}},
          {"streams", {{"simulation.events", everywhere}}},
          {"log_level", "error"}};
}

// The next rpc.sample's params from a JSON-RPC line client (responses and other
// notifications skipped); null on timeout.
json next_rpc_sample(LineClient& c) {
  for (int lines = 0; lines < 1000; ++lines) {
    auto line = c.read_line();
    if (!line) return nullptr;
    json m = json::parse(*line);
    if (m.value("method", "") == "rpc.sample") return m["params"];
  }
  return nullptr;
}

// The same from a WebSocket client.
json next_ws_sample(WsClient& c) {
  for (int messages = 0; messages < 1000; ++messages) {
    json m = c.receive();
    if (m.is_null()) return m;
    if (m.value("method", "") == "rpc.sample") return m["params"];
  }
  return nullptr;
}

// Waits (bounded) until the events stream has `n` subscribers: a socket reader's
// subscription starts on the transport's thread once its connection is accepted.
void wait_for_subscribers(LineClient& service, int n) {
  for (int i = 0; i < 500; ++i) {
    const json stream = stream_of(
        payload(service.request("w" + std::to_string(i), "simulation get_stream_statistics")),
        "simulation.events");
    if (stream.value("subscribers", 0) >= n) return;
    std::this_thread::sleep_for(10ms);
  }
  FAIL() << "the events stream never had " << n << " subscribers";
}

TEST(EventsStreamTest, EveryTransportsSubscriberIsToldOfADivergence) {
  TempDir dir;
  InProcessGateway g(events_config(dir));
  LineClient service(g.port("socket"));
  // listed as any stream is: an output stream of kind "events", at no frequency
  EXPECT_EQ(payload(service.request("1", "simulation list_streams")), json({"simulation.events"}));
  const json listed = stream_of(payload(service.request("2", "simulation get_stream_statistics")),
                                "simulation.events");
  EXPECT_EQ(listed["kind"], "events");
  EXPECT_EQ(listed["direction"], "OUT");
  EXPECT_EQ(listed["frequency"], 0);
  const json port =
      payload(service.request("3", "simulation get_stream_port [\"simulation.events\"]"));
  ASSERT_TRUE(port.is_number_integer()) << port;

  // a reader of each transport
  LineClient socket_reader(port.get<int>());
  LineClient rpc_client(g.port("jsonrpc"));
  const json streams = rpc(rpc_client, 1, "rpc.streams")["result"];
  ASSERT_EQ(streams.size(), 1u) << streams;
  EXPECT_EQ(streams[0]["component"], "simulation.events");
  ASSERT_TRUE(
      rpc(rpc_client, 2, "rpc.subscribe", {{"component", "simulation.events"}}).contains("result"));
  WsClient ws(static_cast<std::uint16_t>(g.port("websocket")));
  ws.send(json{{"jsonrpc", "2.0"},
               {"id", 1},
               {"method", "rpc.subscribe"},
               {"params", {{"component", "simulation.events"}}}});
  ASSERT_TRUE(ws.receive().contains("result"));
  wait_for_subscribers(service, 3);

  // a client steps the world: the step diverges, its request fails and everyone is told
  const std::string stepped = service.request("4", "simulation step [1]");
  EXPECT_EQ(stepped.rfind("4 FAILED \"the simulation diverged", 0), 0u) << stepped;
  const json by_socket = json::parse(socket_reader.read_line().value_or("null"));
  const json by_rpc = next_rpc_sample(rpc_client);
  const json by_ws = next_ws_sample(ws);
  ASSERT_TRUE(by_socket.is_object()) << by_socket;
  ASSERT_TRUE(by_rpc.is_object()) << by_rpc;
  ASSERT_TRUE(by_ws.is_object()) << by_ws;
  EXPECT_EQ(by_rpc["component"], "simulation.events");
  EXPECT_EQ(by_ws["component"], "simulation.events");
  for (const json& event : {by_socket, by_rpc["data"], by_ws["data"]}) {
    EXPECT_EQ(event["event"], "diverged") << event;
    EXPECT_EQ(event["action"], "pause") << event;
    EXPECT_EQ(event["quantity"].get<std::string>().rfind("qacc[", 0), 0u) << event;
    EXPECT_EQ(event["sim_time"], 0.0) << event;
    EXPECT_EQ(event["divergences"], 1) << event;
  }
  // what get_simulation_state says of it is what the event said
  const json last =
      payload(service.request("5", "simulation get_simulation_state"))["last_divergence"];
  for (const char* key : {"sim_time", "step", "quantity", "where", "action", "resumed_at"})
    EXPECT_EQ(by_socket[key], last[key]) << key;
}

TEST(EventsStreamTest, AClientThatPlaysOnHearsItResumedThenDivergedThenPausedByThePolicy) {
  TempDir dir;
  InProcessGateway g(events_config(dir));
  LineClient rpc_client(g.port("jsonrpc"));
  ASSERT_TRUE(
      rpc(rpc_client, 1, "rpc.subscribe", {{"component", "simulation.events"}}).contains("result"));
  // the subscription is the hub's once rpc.subscribe has answered
  rpc_client.send(R"({"jsonrpc":"2.0","id":2,"method":"simulation.play"})"
                  "\n");
  std::vector<json> told;
  for (int i = 0; i < 3; ++i) {
    const json sample = next_rpc_sample(rpc_client);
    ASSERT_TRUE(sample.is_object()) << i;
    told.push_back(sample["data"]);
  }
  EXPECT_EQ(told[0]["event"], "resumed");
  EXPECT_EQ(told[0]["by"], "jsonrpc");
  EXPECT_EQ(told[1]["event"], "diverged");
  EXPECT_EQ(told[2]["event"], "paused");
  EXPECT_EQ(told[2]["by"], "simulation");
}

}  // namespace
}  // namespace simgate::gateway::testing
