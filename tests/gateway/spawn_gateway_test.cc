// GatewaySpawn: `simulation spawn_entity` / `delete_entity` end to end (docs/world/spawn.md):
// a gateway from the demo config with the socket, JSON-RPC and DDS transports on loopback,
// fragments inline and from the config's spawn.allowed_dirs, the change seen through every
// transport.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <thread>

#include "simgate/gateway/gateway.h"
#include "in_process_gateway.h"
#include "test_support.h"

namespace simgate::gateway {
namespace {

using testing::LineClient;
using testing::payload;
using testing::rpc;

constexpr const char* k_ball = "<body><freejoint/><geom type='sphere' size='0.1' mass='1'/></body>";

class GatewaySpawnTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::filesystem::create_directories(dir_.file("fragments"));
    dir_.write("fragments/crate.xml",
               "<mujoco><worldbody><body><freejoint/><geom type='box' size='.2 .2 .2' "
               "mass='2'/></body></worldbody>"
               "</mujoco>");
    json config = testing::demo_config(4.0);
    config["transports"]["jsonrpc"] = {{"plugin", "jsonrpc"}, {"options", {{"port", 0}}}};
    config["services"] = {{"default", json::array({"socket", "jsonrpc"})}};
#ifdef SIMGATE_TEST_WITH_DDS
    config["transports"]["dds"] = {{"plugin", "dds"}, {"options", {{"partition", partition_}}}};
    config["services"]["default"].push_back("dds");
#endif
    config["spawn"] = {{"allowed_dirs", json::array({dir_.file("fragments")})}};
    // the streams of a robot spawned as "arm2", on every transport
    config["streams"]["arm2*"] = config["services"]["default"];
    gateway_ = std::make_unique<testing::InProcessGateway>(config);
  }
  int port(const std::string& transport) { return gateway_->port(transport); }

  testing::TempDir dir_;
  std::string partition_ = "simgate-spawn-test-" + std::to_string(::getpid());
  std::unique_ptr<testing::InProcessGateway> gateway_;
};

TEST_F(GatewaySpawnTest, SpawnThroughTheSocketDeleteThroughJsonRpc) {
  LineClient socket(port("socket")), jsonrpc(port("jsonrpc"));
  // MORSE's text protocol: id component service [params]
  const std::string spawned = socket.request(
      "1", "simulation spawn_entity " + json::array({"ball", k_ball, {1.0, 2.0, 0.5}}).dump());
  EXPECT_EQ(spawned, "1 SUCCESS {\"model_generation\": 1, \"name\": \"ball\"}");
  // every transport sees the new world
  json objects = rpc(jsonrpc, 1, "simulation.get_scene_objects")["result"];
  ASSERT_TRUE(objects.contains("ball")) << objects.dump();
  EXPECT_NEAR(objects["ball"][1][1].get<double>(), 2.0, 1e-3);
  // named params, a fragment file from the allowed directory
  json crate = rpc(
      jsonrpc, 2, "simulation.spawn_entity",
      {{"name", "crate9"}, {"mjcf", "crate.xml"}, {"pose", {-1.0, -1.0, 0.3, 0.0, 0.0, 0.0, 1.0}}});
  EXPECT_EQ(crate["result"], json({{"name", "crate9"}, {"model_generation", 2}})) << crate.dump();
  json deleted = rpc(jsonrpc, 3, "simulation.delete_entity", {"ball"});
  EXPECT_EQ(deleted["result"], json({{"name", "ball"}, {"model_generation", 3}})) << deleted.dump();
  json after = payload(socket.request("2", "simulation get_scene_objects"));
  EXPECT_FALSE(after.contains("ball"));
  EXPECT_TRUE(after.contains("crate9"));
  // the robot still answers through both
  EXPECT_EQ(socket.request("3", "robot.motion set_speed [0.5, 0]"), "3 SUCCESS");
}

TEST_F(GatewaySpawnTest, BadInputIsFailedNamingTheParameterOnEveryTransport) {
  LineClient socket(port("socket")), jsonrpc(port("jsonrpc"));
  EXPECT_EQ(socket.request("1", "simulation spawn_entity [\"crate1\", \"<body/>\", [0, 0, 1]]"),
            "1 FAILED \"name 'crate1' is taken: the world already has a body called so\"");
  json outside = rpc(jsonrpc, 1, "simulation.spawn_entity", {"x", "/etc/hostname", {0, 0, 1}});
  EXPECT_EQ(outside["error"]["code"], -32602) << outside.dump();
  EXPECT_EQ(outside["error"]["data"]["parameter"], "mjcf") << outside.dump();
  json broken = rpc(jsonrpc, 2, "simulation.spawn_entity",
                    {"x", "<body><geom type='mesh' mesh='no'/></body>", {0, 0, 1}});
  EXPECT_EQ(broken["error"]["code"], -32602) << broken.dump();
  EXPECT_NE(broken["error"]["message"].get<std::string>().find("does not compile"),
            std::string::npos);
  json scene_body = rpc(jsonrpc, 3, "simulation.delete_entity", {"robot_left_wheel"});
  EXPECT_NE(scene_body["error"]["message"].get<std::string>().find("is part of robot 'robot'"),
            std::string::npos)
      << scene_body.dump();
  // nothing changed
  EXPECT_EQ(payload(socket.request("2", "simulation get_scene_objects")).size(), 4u);
}

TEST_F(GatewaySpawnTest, IntrospectionListsTheServices) {
  LineClient socket(port("socket")), jsonrpc(port("jsonrpc"));
  int found = 0;
  for (const auto& s : payload(socket.request("1", "simulation list_services")))
    if (s["component"] == "simulation" &&
        (s["name"] == "spawn_entity" || s["name"] == "delete_entity"))
      ++found;
  EXPECT_EQ(found, 2);
  int discovered = 0;
  const json discover = rpc(jsonrpc, 1, "rpc.discover");
  for (const auto& m : discover["result"]["methods"])
    if (m["name"] == "simulation.spawn_entity" || m["name"] == "simulation.delete_entity")
      ++discovered;
  EXPECT_EQ(discovered, 2) << discover.dump().substr(0, 2000);
}

// An arm on a hinge, with a position servo and a joint sensor, spawned as a robot.
constexpr const char* k_arm = R"(<mujoco>
  <worldbody><body><geom type="box" size=".1 .1 .05" mass="2"/>
    <body name="arm2_link" pos="0 0 .1"><joint name="arm2_hinge" axis="0 0 1"/>
      <geom type="capsule" size=".03" fromto="0 0 0 .3 0 0" mass=".5"/></body></body></worldbody>
  <actuator><position name="arm2_servo" joint="arm2_hinge" kp="20" dampratio="1" ctrlrange="-1.5 1.5"/></actuator>
  <sensor><jointpos name="arm2_angle" joint="arm2_hinge"/></sensor>
</mujoco>)";

// A spawned robot comes with its components (a config's robot section), served at once by
// every transport the mapping gives its names, listed by each one's introspection, and gone
// again with its body (issue #36).
TEST_F(GatewaySpawnTest, ASpawnedRobotServesItsComponentsOnEveryTransport) {
  LineClient socket(port("socket")), jsonrpc(port("jsonrpc"));
  const json robot = {{"type", "robot"},
                      {"components", json::array({{{"name", "pose"}, {"type", "pose"}},
                                                  {{"name", "actuators"}, {"type", "actuators"}},
                                                  {{"name", "sensors"}, {"type", "sensors"}}})}};
  json spawned =
      rpc(jsonrpc, 1, "simulation.spawn_entity",
          {{"name", "arm2"}, {"mjcf", k_arm}, {"pose", {2.0, 2.0, 0.05}}, {"robot", robot}});
  EXPECT_EQ(spawned["result"], json({{"name", "arm2"}, {"model_generation", 1}})) << spawned.dump();
  // MORSE's socket protocol: listed, and served
  EXPECT_NE(payload(socket.request("1", "simulation list_robots")).dump().find("\"arm2\""),
            std::string::npos);
  int listed = 0;
  for (const auto& s : payload(socket.request("2", "simulation list_services")))
    listed += s["component"].get<std::string>().starts_with("arm2.");
  EXPECT_GE(listed, 5);
  EXPECT_EQ(socket.request("3", "arm2.actuators set_control [\"arm2_servo\", 0.8]"), "3 SUCCESS");
  const json pose = payload(socket.request("4", "arm2.pose get_local_data"));
  EXPECT_NEAR(pose["x"].get<double>(), 2.0, 1e-3) << pose;
  // JSON-RPC: discovered and called
  const json discover = rpc(jsonrpc, 2, "rpc.discover");
  bool discovered = false;
  for (const auto& m : discover["result"]["methods"])
    discovered |= m["name"] == "arm2.sensors.get_local_data";
  EXPECT_TRUE(discovered);
  // the servo turns the hinge there (critically damped: within a second or so of simulated time)
  json angle;
  for (int i = 0; i < 100; ++i) {
    angle = rpc(jsonrpc, 3, "arm2.sensors.get_local_data")["result"];
    if (std::abs(angle["arm2_angle"].get<double>() - 0.8) < 0.02) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_NEAR(angle["arm2_angle"].get<double>(), 0.8, 0.02) << angle;
#ifdef SIMGATE_TEST_WITH_DDS
  {
    // DDS: the catalog is published anew with it
    auto [code, out] =
        testing::run_simgate({"list", "--transport", "dds", "--partition", partition_}, dir_);
    EXPECT_EQ(code, 0) << out;
    EXPECT_NE(out.find("arm2.actuators"), std::string::npos) << out;
  }
#endif
  // its pose stream, on the socket transport (a stream port opened for it) and JSON-RPC
  // (rpc.subscribe); DDS's topics: DdsStreamsTest.ASpawnedRobotsPoseTopicIsWrittenAtOnce
  for (const std::string transport : {"socket", "jsonrpc"}) {
    auto [code, out] =
        testing::run_simgate({"watch", "--transport", transport, "--port",
                              std::to_string(port(transport)), "arm2.pose", "--count", "1"},
                             dir_);
    EXPECT_EQ(code, 0) << transport << ": " << out;
    EXPECT_NE(out.find("\"x\":2.0"), std::string::npos) << transport << ": " << out;
  }
  // deleted with its body: every transport forgets it
  json deleted = rpc(jsonrpc, 4, "simulation.delete_entity", {"arm2"});
  EXPECT_EQ(deleted["result"], json({{"name", "arm2"}, {"model_generation", 2}})) << deleted.dump();
  EXPECT_EQ(socket.request("5", "arm2.pose get_local_data").substr(0, 8), "5 FAILED");
  for (const auto& s : payload(socket.request("6", "simulation list_services")))
    EXPECT_FALSE(s["component"].get<std::string>().starts_with("arm2")) << s;
}

// A URDF robot spawns too, its transmissions' joints driven by actuators, and a robot of type
// "mjcf" gets the generic components of what it has.
TEST_F(GatewaySpawnTest, AUrdfRobotSpawnsWithTheGenericComponentsOfItsActuators) {
  std::ifstream in(SIMGATE_SOURCE_DIR "/tests/models/urdf_arm.urdf");
  std::stringstream urdf;
  urdf << in.rdbuf();
  LineClient jsonrpc(port("jsonrpc"));
  json spawned = rpc(jsonrpc, 1, "simulation.spawn_entity",
                     {{"name", "arm3"},
                      {"mjcf", urdf.str()},
                      {"pose", {-2.0, 3.0, 0.0}},
                      {"robot", {{"type", "mjcf"}}}});
  EXPECT_EQ(spawned["result"]["name"], "arm3") << spawned.dump();
  const json actuators = rpc(jsonrpc, 2, "arm3.actuators.list_actuators")["result"];
  EXPECT_TRUE(actuators.contains("shoulder_servo")) << actuators.dump();
  EXPECT_EQ(actuators["shoulder_servo"]["type"], "position") << actuators.dump();
  EXPECT_TRUE(
      rpc(jsonrpc, 3, "arm3.actuators.set_control", {"shoulder_servo", 0.5}).contains("result"));
}

// A robot section that is wrong is refused before anything compiles, or, when a component
// cannot be made with the body in the world, after: either way nothing is spawned.
TEST_F(GatewaySpawnTest, ABadRobotSectionSpawnsNothing) {
  LineClient socket(port("socket")), jsonrpc(port("jsonrpc"));
  auto spawn = [&](int id, const json& robot) {
    return rpc(jsonrpc, id, "simulation.spawn_entity",
               {{"name", "arm2"}, {"mjcf", k_arm}, {"pose", {2.0, 2.0, 0.05}}, {"robot", robot}});
  };
  const json unknown_type =
      spawn(1, {{"components", json::array({{{"name", "x"}, {"type", "motion_wv"}}})}});
  EXPECT_EQ(unknown_type["error"]["code"], -32602) << unknown_type.dump();
  EXPECT_EQ(unknown_type["error"]["data"]["parameter"], "robot") << unknown_type.dump();
  EXPECT_NE(unknown_type["error"]["message"].get<std::string>().find("robot.components[0].type"),
            std::string::npos)
      << unknown_type.dump();
  const json named = spawn(2, {{"name", "other"}});
  EXPECT_NE(named["error"]["message"].get<std::string>().find("robot.name"), std::string::npos)
      << named.dump();
  const json not_object = spawn(3, json::array({1}));
  EXPECT_EQ(not_object["error"]["data"]["parameter"], "robot") << not_object.dump();
  // known types, but an actuator the body does not have: found once the body is in the world
  const json missing_actuator = spawn(
      4, {{"components", json::array({{{"name", "actuators"},
                                       {"type", "actuators"},
                                       {"options", {{"actuators", json::array({"nope"})}}}}})}});
  EXPECT_EQ(missing_actuator["error"]["code"], -32602) << missing_actuator.dump();
  EXPECT_NE(missing_actuator["error"]["message"].get<std::string>().find("nothing was spawned"),
            std::string::npos)
      << missing_actuator.dump();
  EXPECT_FALSE(payload(socket.request("1", "simulation get_scene_objects")).contains("arm2"));
  EXPECT_EQ(payload(socket.request("2", "simulation list_robots")),
            json::array({"robot", "human"}));
  // the name is free again: a good one spawns
  EXPECT_EQ(spawn(5, {{"type", "robot"}})["result"]["name"], "arm2");
}

// Deleting a robot's body deletes the robot: its request in flight gets its one answer,
// FAILED with the reason, and no transport lists its components any more.
TEST_F(GatewaySpawnTest, DeletingARobotEndsItsRequestsAndEveryTransportForgetsIt) {
  LineClient socket(port("socket")), jsonrpc(port("jsonrpc"));
  socket.send("1 robot.waypoint goto [20.0, 0.0, 0.0, 0.1, 0.5]\n");
  // the goto runs (a sync call behind it on the same connection is answered first)
  EXPECT_EQ(socket.request("2", "robot.waypoint get_status"), "2 SUCCESS \"Transit\"");
  json deleted = rpc(jsonrpc, 1, "simulation.delete_entity", {"robot"});
  EXPECT_EQ(deleted["result"], json({{"name", "robot"}, {"model_generation", 1}}))
      << deleted.dump();
  EXPECT_EQ(socket.read_line(),
            "1 FAILED \"robot 'robot' was deleted by simulation.delete_entity\"");
  for (const auto& s : payload(socket.request("3", "simulation list_services")))
    EXPECT_FALSE(s["component"].get<std::string>().starts_with("robot")) << s;
  const json robots = payload(socket.request("4", "simulation details"))["robots"];
  ASSERT_EQ(robots.size(), 1u) << robots;
  EXPECT_EQ(robots[0]["name"], "human");
  const json discover = rpc(jsonrpc, 2, "rpc.discover");
  for (const auto& m : discover["result"]["methods"])
    EXPECT_FALSE(m["name"].get<std::string>().starts_with("robot.")) << m["name"];
  EXPECT_EQ(socket.request("5", "robot.pose get_local_data").substr(0, 8), "5 FAILED");
  // the human, now first among the robots, still walks
  EXPECT_EQ(socket.request("6", "human move [1.0, 0.0]"), "6 SUCCESS");
  EXPECT_FALSE(payload(socket.request("7", "simulation get_scene_objects")).contains("robot"));
#ifdef SIMGATE_TEST_WITH_DDS
  // a DDS client that joins now lists no robot service either
  auto [code, out] =
      testing::run_simgate({"list", "--transport", "dds", "--partition", partition_}, dir_);
  EXPECT_EQ(code, 0) << out;
  EXPECT_EQ(out.find("robot."), std::string::npos) << out;
  EXPECT_NE(out.find("human"), std::string::npos) << out;
#endif
}

#ifdef SIMGATE_TEST_WITH_DDS
TEST_F(GatewaySpawnTest, SpawnThroughDds) {
  auto [code, out] = testing::run_simgate(
      {"call", "--transport", "dds", "--partition", partition_, "simulation", "spawn_entity",
       "dds_ball", json(k_ball).dump(),
       // a leading space: CLI11 splits a bracketed argument "[a, b]" at its commas
       " [0.5, -0.5, 1]"},
      dir_);
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find("\"dds_ball\""), std::string::npos) << out;
  LineClient socket(port("socket"));
  EXPECT_TRUE(payload(socket.request("1", "simulation get_scene_objects")).contains("dds_ball"));
}
#endif

}  // namespace
}  // namespace simgate::gateway
