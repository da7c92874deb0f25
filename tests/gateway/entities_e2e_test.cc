// GatewayEntities: the entities and process groups of `simulation` and the `communication`
// pseudo-component (docs/world/entities.md) end to end: a gateway on the demo scene serving
// the MORSE socket protocol, JSON-RPC and DDS (loopback, a partition of its own), driven by
// real clients; and `simulation terminate` ending a real simgate process.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <set>
#include <thread>

#include "simgate/client/client.h"
#include "simgate/gateway/gateway.h"
#include "in_process_gateway.h"
#include "test_support.h"

namespace simgate::gateway {
namespace {

using ::testing::HasSubstr;
using testing::LineClient;
using testing::payload;
using testing::rpc;
using ::testing::StartsWith;

const char* k_entity_services[] = {
    "set_object_position", "get_object_pose",  "get_object_bbox",  "get_object_global_bbox",
    "set_object_dynamics", "get_entity_state", "set_entity_state", "list_entities",
    "terminate",           "set_log_level"};
// terminate and set_log_level are process-wide: served by the socket console only
bool process_wide(const char* service) {
  return std::string(service) == "terminate" || std::string(service) == "set_log_level";
}

#ifdef SIMGATE_TEST_WITH_DDS
// A DDS domain and partition of this process and test, on loopback.
json dds_options() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  return {{"domain", 20 + getpid() % 200},
          {"partition",
           "simgate-test-" + std::to_string(getpid()) + "-" + (info ? info->name() : "none")},
          {"config", std::string("file://") + SIMGATE_LOOPBACK_DDS_XML}};
}
#endif

// The demo, every component on every transport built here; DDS on loopback in a partition
// of this process and test.
json every_transport_config() {
  json c = testing::demo_config(1.0);
  std::vector<std::string> all = {"socket"};
#ifdef SIMGATE_TEST_WITH_JSONRPC
  c["transports"]["jsonrpc"] = {{"plugin", "jsonrpc"}, {"options", {{"port", 0}}}};
  all.push_back("jsonrpc");
#endif
#ifdef SIMGATE_TEST_WITH_DDS
  c["transports"]["dds"] = {{"plugin", "dds"}, {"options", dds_options()}};
  all.push_back("dds");
#endif
  // no rule for communication: it goes with simulation
  c["services"] = {{"default", all}};
  return c;
}

class GatewayEntitiesTest : public ::testing::Test {
 protected:
  int port(const std::string& transport) { return gateway_.port(transport); }

  testing::InProcessGateway gateway_{every_transport_config()};
};

TEST_F(GatewayEntitiesTest, TheSocketSpeaksMorsesWire) {
  LineClient c(port("socket"));
  EXPECT_EQ(
      c.request("1", "simulation set_object_position [\"crate1\", [1.0, 2.0, 0.2], [0, 0, 0.5]]"),
      "1 SUCCESS");
  json pose = payload(c.request("2", "simulation get_object_pose [\"crate1\"]"));
  EXPECT_NEAR(pose[0][0].get<double>(), 1.0, 1e-3);
  EXPECT_NEAR(pose[0][1].get<double>(), 2.0, 1e-3);
  EXPECT_NEAR(pose[1][2].get<double>(), std::sin(0.25), 1e-3);
  // MORSE returns the state (simgate sends falsy values too: docs/transports/socket.md)
  EXPECT_EQ(c.request("3", "simulation set_object_dynamics [\"crate1\", false]"),
            "3 SUCCESS false");
  EXPECT_EQ(c.request("4", "simulation set_object_dynamics [\"crate1\", true]"), "4 SUCCESS true");
  EXPECT_EQ(c.request("5", "simulation list_entities [\"crate\"]"),
            "5 SUCCESS [\"crate1\", \"crate2\"]");
  EXPECT_EQ(c.request("6", "simulation set_object_position [\"crat1\", [0, 0, 1]]"),
            "6 FAILED \"Object 'crat1' does not appear in the scene. Did you mean 'crate1'?\"");
  // NaN reaches the socket's parser as MORSE's json.loads takes it; it is refused
  EXPECT_THAT(c.request("7", "simulation set_object_position [\"crate2\", [NaN, 0, 1]]"),
              StartsWith("7 FAILED \"position[0] = nan is out of bounds"));
  json view = payload(c.request("8", "communication distance_and_view [\"robot\", \"human\"]"));
  EXPECT_NEAR(view[0].get<double>(), std::sqrt(8.0), 0.1);
  EXPECT_EQ(view[1], true);
  EXPECT_EQ(c.request("9", "communication distance_and_view [\"robot\", \"nobody\"]"),
            "9 FAILED \"nobody does not exist in the simulation \"");
  EXPECT_THAT(c.request("10", "communication distance_and_view"),
              HasSubstr("10 FAILED \"parameters expected for service"));
  EXPECT_THAT(c.request("11", "simulation set_log_level [\"robot\", \"LOUD\"]"),
              StartsWith("11 FAILED \"Unknown level: 'LOUD'"));
  // introspection lists them
  std::set<std::string> listed;
  for (const auto& d : payload(c.request("12", "simulation list_services")))
    listed.insert(d["component"].get<std::string>() + "." + d["name"].get<std::string>());
  for (const char* s : k_entity_services)
    EXPECT_TRUE(listed.count(std::string("simulation.") + s)) << s;
  EXPECT_TRUE(listed.count("communication.distance_and_view"));
  // and the simulation runs on
  EXPECT_THAT(c.request("13", "simulation list_robots"), StartsWith("13 SUCCESS"));
}

#ifdef SIMGATE_TEST_WITH_JSONRPC

TEST_F(GatewayEntitiesTest, JsonRpcTakesNamedParametersAndReportsTheBadOne) {
  LineClient c(port("jsonrpc"));
  json state = {{"pose", {{"position", {0.0, -3.0, 1.0}}, {"orientation", {0.0, 0.0, 0.0, 1.0}}}},
                {"twist", {{"linear", {0.0, 0.0, 0.0}}, {"angular", {0.0, 0.0, 1.5}}}}};
  json set = rpc(c, 1, "simulation.set_entity_state", {{"name", "crate2"}, {"state", state}});
  ASSERT_TRUE(set.contains("result")) << set;
  EXPECT_NEAR(set["result"]["twist"]["angular"][2].get<double>(), 1.5, 1e-9);
  json got = rpc(c, 2, "simulation.get_entity_state", {{"name", "crate2"}});
  ASSERT_TRUE(got.contains("result")) << got;
  EXPECT_TRUE(got["result"].contains("pose") && got["result"].contains("twist"));
  json bad = rpc(c, 3, "simulation.set_entity_state",
                 {{"name", "crate2"}, {"state", {{"pose", {{"orientation", {0, 0, 0, 0}}}}}}});
  ASSERT_TRUE(bad.contains("error")) << bad;
  EXPECT_EQ(bad["error"]["code"], -32602);  // invalid params
  EXPECT_EQ(bad["error"]["data"]["parameter"], "state.pose.orientation");
  json bbox = rpc(c, 4, "simulation.get_object_global_bbox", {"human"});
  ASSERT_TRUE(bbox.contains("result")) << bbox;
  EXPECT_GT(bbox["result"][1][2].get<double>(), 1.5);  // the human is about 1.7 m tall
  json view =
      rpc(c, 5, "communication.distance_and_view", {{"robot1", "human"}, {"robot2", "robot"}});
  ASSERT_TRUE(view.contains("result")) << view;
  EXPECT_EQ(view["result"][1], true);
  std::set<std::string> discovered;
  const json discovery = rpc(c, 6, "rpc.discover");
  for (const auto& m : discovery["result"]["methods"])
    discovered.insert(m["name"].get<std::string>());
  EXPECT_TRUE(discovery.contains("result")) << discovery.dump().substr(0, 500);
  for (const char* s : k_entity_services)
    EXPECT_EQ(discovered.count(std::string("simulation.") + s), process_wide(s) ? 0u : 1u) << s;
  EXPECT_TRUE(discovered.count("communication.distance_and_view"));
}
#endif

#ifdef SIMGATE_TEST_WITH_DDS
TEST_F(GatewayEntitiesTest, DdsClientsReachThemToo) {
  auto client = client::make_client("dds", dds_options());
  Outcome listed =
      client->call("simulation", "list_entities", {"*wheel"}, std::chrono::seconds(20));
  ASSERT_EQ(listed.status, Status::success) << listed.message;
  EXPECT_EQ(listed.value, json({"robot_left_wheel", "robot_right_wheel"}));
  Outcome bbox = client->call("simulation", "get_object_bbox", {"robot"}, std::chrono::seconds(20));
  ASSERT_EQ(bbox.status, Status::success) << bbox.message;
  EXPECT_NEAR(bbox.value.value()[1][1].get<double>(), 0.23, 1e-6);
  Outcome view = client->call("communication", "distance_and_view", {"robot", "nobody"},
                              std::chrono::seconds(20));
  EXPECT_EQ(view.status, Status::failed);
  EXPECT_EQ(view.message, "nobody does not exist in the simulation ");
  std::set<std::string> catalog;
  for (const auto& d : client->list_services(std::chrono::seconds(20)))
    catalog.insert(d["component"].get<std::string>() + "." + d["name"].get<std::string>());
  for (const char* s : k_entity_services)
    EXPECT_EQ(catalog.count(std::string("simulation.") + s), process_wide(s) ? 0u : 1u) << s;
  EXPECT_TRUE(catalog.count("communication.distance_and_view"));
}
#endif

// terminate: the process ends at once with status 0, without finalization: no reply, the
// connections dropped, the endpoints file left behind (quit removes it).
TEST(GatewayTerminateTest, TerminateEndsTheProcessAtOnceWithoutFinalization) {
  testing::TempDir dir;
  const std::string config = dir.write("demo.json", testing::demo_config().dump());
  const std::string endpoints = dir.file("endpoints.json");
  testing::Process p({testing::simgate_binary(), "run", config, "--endpoints-file", endpoints},
                     dir.file(""));
  json e = json::parse(testing::wait_for_file(endpoints), nullptr, false);
  ASSERT_TRUE(e.contains("socket")) << p.err();
  LineClient c(testing::port_of(e["socket"][0].get<std::string>()));
  EXPECT_THAT(c.request("1", "simulation list_robots"), StartsWith("1 SUCCESS"));
  // who changes the log level is logged, before the change (issue #35, item 5)
  EXPECT_EQ(c.request("l", "simulation set_log_level [\"robot\", \"INFO\"]"), "l SUCCESS");
  c.send("2 simulation terminate\n");
  EXPECT_EQ(p.wait(), 0) << p.err();
  EXPECT_TRUE(c.closed_by_server());
  EXPECT_THAT(c.other_lines(), ::testing::IsEmpty());  // no reply
  EXPECT_THAT(
      p.err(),
      HasSubstr(
          "simulation: log level warning -> info (asked by Socket service manager, request "));
  EXPECT_THAT(p.err(), HasSubstr("terminate requested: exiting now, without finalization"));
  EXPECT_TRUE(std::filesystem::exists(endpoints));
}

}  // namespace
}  // namespace simgate::gateway
