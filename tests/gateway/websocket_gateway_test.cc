// The websocket transport in a gateway: the demo robot's services and its pose stream served
// over JSON-RPC on WebSocket; a Beast client (tests/websocket/ws_test_client.h) discovers
// them, calls one, subscribes to the pose and reads rpc.sample notifications.
#include <gtest/gtest.h>

#include <chrono>
#include <set>

#include "in_process_gateway.h"
#include "ws_test_client.h"

namespace simgate::gateway::testing {
namespace {

using websocket_test::WsClient;

json websocket_config() {
  json c = demo_config();
  c["transports"]["websocket"] = {{"plugin", "websocket"}, {"options", {{"port", 0}}}};
  c["services"]["simulation"] = {"socket", "websocket"};
  c["services"]["robot.*"] = {"socket", "websocket"};
  c["streams"] = {{"robot.pose", {"websocket"}}};
  c["robots"][0]["components"][3]["frequency"] = 50;  // robot.pose
  return c;
}

// The response to `id`, skipping notifications (bounded).
json response(WsClient& c, int id) {
  for (int messages = 0; messages < 10000; ++messages) {
    json m = c.receive();
    if (m.is_null()) return m;
    if (m.contains("id") && m["id"] == id) return m;
  }
  return nullptr;
}

json call(WsClient& c, int id, const std::string& method, json params = nullptr) {
  json request{{"jsonrpc", "2.0"}, {"id", id}, {"method", method}};
  if (!params.is_null()) request["params"] = std::move(params);
  c.send(request);
  return response(c, id);
}

TEST(WebSocketGatewayTest, ReportsAWsEndpointAndDiscoverListsTheServicesItServes) {
  InProcessGateway g(websocket_config());
  const std::string endpoint = g.gateway().endpoints().at("websocket").at(0);
  EXPECT_TRUE(endpoint.starts_with("ws://127.0.0.1:")) << endpoint;
  WsClient c(static_cast<std::uint16_t>(g.port("websocket")));
  json discover = call(c, 1, "rpc.discover");
  ASSERT_TRUE(discover.contains("result")) << discover.dump();
  std::set<std::string> methods;
  for (const auto& m : discover["result"]["methods"]) methods.insert(m["name"].get<std::string>());
  EXPECT_TRUE(methods.count("robot.motion.set_speed")) << discover.dump().substr(0, 2000);
  EXPECT_TRUE(methods.count("simulation.list_robots"));
  json robots = call(c, 2, "simulation.list_robots");
  EXPECT_TRUE(robots.contains("result")) << robots.dump();
}

TEST(WebSocketGatewayTest, PoseSamplesComeAsNotificationsUntilUnsubscribed) {
  InProcessGateway g(websocket_config());
  WsClient c(static_cast<std::uint16_t>(g.port("websocket")));
  json subscribed = call(c, 1, "rpc.subscribe", {{"component", "robot.pose"}});
  ASSERT_TRUE(subscribed.contains("result")) << subscribed.dump();
  const json id = subscribed["result"]["subscription"];
  std::uint64_t last_seq = 0;
  int samples = 0;
  for (int messages = 0; messages < 1000 && samples < 5; ++messages) {
    json m = c.receive();
    ASSERT_FALSE(m.is_null()) << c.error.message();
    if (m.value("method", "") != "rpc.sample") continue;
    EXPECT_EQ(m["params"]["subscription"], id);
    EXPECT_EQ(m["params"]["component"], "robot.pose");
    EXPECT_GT(m["params"]["seq"].get<std::uint64_t>(), last_seq);
    EXPECT_TRUE(m["params"]["data"].contains("x")) << m.dump();
    last_seq = m["params"]["seq"];
    ++samples;
  }
  EXPECT_EQ(samples, 5);
  EXPECT_EQ(call(c, 2, "rpc.unsubscribe", {{"subscription", id}})["result"], true);
}

}  // namespace
}  // namespace simgate::gateway::testing
