// GatewayIntegration: gateways built from configs on ephemeral ports, driven over real
// sockets with the MORSE text protocol.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <set>
#include <thread>

#include "simgate/core/log.h"
#include "simgate/gateway/gateway.h"
#include "in_process_gateway.h"
#include "test_support.h"

namespace simgate::gateway {
namespace {

using ::testing::HasSubstr;
using testing::LineClient;
using ::testing::Not;
using testing::payload;
using testing::rpc;
using ::testing::StartsWith;

class GatewayIntegrationTest : public ::testing::Test {
 protected:
  void start(const json& config, GatewayOptions options = {}) {
    gateway_ = std::make_unique<testing::InProcessGateway>(config, std::move(options));
  }
  int port(const std::string& transport = "socket") { return gateway_->port(transport); }

  std::unique_ptr<testing::InProcessGateway> gateway_;
};

TEST_F(GatewayIntegrationTest, ServesTheSupervisionServices) {
  start(testing::socket_demo_config());
  LineClient c(port());
  std::string line = c.request("1", "simulation list_robots");
  EXPECT_EQ(line, "1 SUCCESS [\"robot\", \"human\"]");
  json details = payload(c.request("0", "simulation details []"));
  EXPECT_EQ(details["robots"][0]["components"]["robot.motion"]["service_interfaces"],
            json({"socket"}));
}

// issue #18: component types as plugins. The docs' odometer library, named in the config,
// found in a --plugin-path directory, served like a built-in.
TEST_F(GatewayIntegrationTest, AComponentLibraryNamedInTheConfigServesItsTypes) {
  json config = testing::demo_config(4.0);
  config["component_libraries"] = {"odometer"};
  config["robots"][0]["components"].push_back({{"name", "odometer"}, {"type", "odometer"}});
  GatewayOptions options;
  options.plugin_dirs = {SIMGATE_BINARY_DIR "/example-plugins"};
  start(config, options);
  LineClient c(port());
  EXPECT_EQ(c.request("1", "robot.motion set_speed [1.0, 0.0]"), "1 SUCCESS");
  std::string reply = c.request("2", "robot.odometer wait_distance [0.3]");
  ASSERT_THAT(reply, StartsWith("2 SUCCESS "));
  EXPECT_GE(std::stod(reply.substr(10)), 0.3);
  json services = payload(c.request("3", "simulation list_services"));
  EXPECT_THAT(services.dump(), HasSubstr("\"component\":\"robot.odometer\""));
  EXPECT_THAT(services.dump(), HasSubstr("wait_distance"));
}

// issue #18: a robot of type mjcf gets the generic components of what its subtree has; a
// component the config names so wins; the mapping may name the generated components.
TEST_F(GatewayIntegrationTest, AnMjcfRobotGetsTheGenericComponentsOfItsSubtree) {
  json config = testing::demo_config(4.0);
  config["robots"][0] = {{"name", "robot"},
                         {"type", "mjcf"},
                         {"components",
                          {{{"name", "actuators"},
                            {"type", "actuators"},
                            {"options", {{"actuators", {"robot_left_motor"}}}}}}}};
  config["services"] = {{"default", {"socket"}}, {"robot.armature_pose", json::array()}};
  config.erase("streams");  // the demo's name robot.pose and robot.motion
  start(config);
  const Deployment& d = gateway_->gateway().deployment();
  std::vector<std::string> names;
  for (const auto& c : d.robots[0].components) names.push_back(c.name);
  // (the demo robot has a free joint: a floating base, with pose and odometry)
  EXPECT_EQ(names,
            (std::vector<std::string>{"robot.actuators", "robot.armature", "robot.armature_pose",
                                      "robot.pose", "robot.odometry"}));
  LineClient c(port());
  // the config's own actuators component: one of the two wheel motors
  json actuators = payload(c.request("1", "robot.actuators list_actuators"));
  EXPECT_EQ(actuators.size(), 1u) << actuators;
  EXPECT_TRUE(actuators.contains("robot_left_motor")) << actuators;
  // the generated armature: the wheels' hinge joints
  json joints = payload(c.request("2", "robot.armature get_joints"));
  EXPECT_EQ(joints, json({"robot_left_wheel_joint", "robot_right_wheel_joint"}));
  // mapped to no transport: not reachable
  EXPECT_THAT(c.request("3", "robot.armature_pose get_state"), HasSubstr("FAILED"));
}

TEST(GatewayComponentLibraryTest, AMissingOrBrokenLibraryIsAConfigErrorNamingItsPlace) {
  json config = testing::demo_config();
  config["component_libraries"] = {"no_such_library",
                                   SIMGATE_TEST_PLUGIN_DIR "/libsimgate_transport_socket.so"};
  GatewayOptions options;
  options.check_only = true;
  sim::ComponentRegistry registry = sim::builtin_registry();
  try {
    Gateway g(parse_deployment(config, SIMGATE_SOURCE_DIR "/config"), registry, options);
    FAIL() << "accepted";
  } catch (const ConfigError& e) {
    const std::string text = e.what();
    EXPECT_THAT(
        text,
        HasSubstr(
            "component_libraries[0]: expected a loadable component library, found an error: "
            "component library 'no_such_library': no libsimgate_components_no_such_library.so "
            "found; paths tried:"));
    EXPECT_THAT(text, HasSubstr("component_libraries[1]: expected a loadable component library"));
  }
  config["component_libraries"] = {42};
  EXPECT_THROW(parse_deployment(config, SIMGATE_SOURCE_DIR "/config"), ConfigError);
}

TEST_F(GatewayIntegrationTest, DrivesTheRobotThroughItsWheels) {
  start(testing::demo_config(4.0));
  LineClient c(port());
  EXPECT_EQ(c.request("1", "robot.motion set_speed [0.5, 0.0]"), "1 SUCCESS");
  // wait one simulated second through the time service itself
  EXPECT_EQ(c.request("2", "time sleep [1.0]"), "2 SUCCESS");
  json pose = payload(c.request("3", "robot.pose get_local_data"));
  EXPECT_GT(pose["x"].get<double>(), 0.2);
  EXPECT_EQ(c.request("4", "robot.motion stop"), "4 SUCCESS");
}

TEST_F(GatewayIntegrationTest, GotoArrivesAndIsAnsweredOnCompletion) {
  start(testing::demo_config(4.0));
  LineClient c(port());
  c.send("g1 robot.waypoint goto [1.5, 0.0, 0.0, 0.2]\n");
  // other requests are answered while the goto runs
  EXPECT_EQ(c.request("s1", "robot.waypoint get_status"), "s1 SUCCESS \"Transit\"");
  EXPECT_EQ(c.wait_for("g1", std::chrono::seconds(60)), "g1 SUCCESS \"Arrived\"");
  json pose = payload(c.request("p", "robot.pose get_local_data"));
  EXPECT_NEAR(pose["x"].get<double>(), 1.5, 0.25);
}

TEST_F(GatewayIntegrationTest, CancelPreemptsTheGotoAndTheRobotStops) {
  start(testing::demo_config(4.0));
  LineClient c(port());
  c.send("g1 robot.waypoint goto [20.0, 0.0, 0.0]\n");
  EXPECT_EQ(c.request("w", "time sleep [0.5]"), "w SUCCESS");
  c.send("g1 cancel\n");
  EXPECT_EQ(c.wait_for("g1"), "g1 PREEMPTED");
  EXPECT_EQ(c.request("w2", "time sleep [1.0]"), "w2 SUCCESS");  // braking
  double x1 = payload(c.request("p1", "robot.pose get_local_data"))["x"].get<double>();
  EXPECT_EQ(c.request("w3", "time sleep [1.0]"), "w3 SUCCESS");
  double x2 = payload(c.request("p2", "robot.pose get_local_data"))["x"].get<double>();
  EXPECT_NEAR(x2, x1, 0.01);
}

TEST_F(GatewayIntegrationTest, ComponentNotMappedToATransportIsUnreachableThroughIt) {
  json config = testing::demo_config();
  config["transports"]["private"] = {{"plugin", "socket"}, {"options", {{"port", 0}}}};
  config["services"] = {{"default", json::array({"socket"})},
                        {"robot.teleport", json::array({"private"})}};
  start(config);
  LineClient pub(port("socket")), priv(port("private"));
  EXPECT_THAT(pub.request("1", "robot.teleport translate [1.0]"), StartsWith("1 FAILED"));
  EXPECT_THAT(pub.request("2", "robot.teleport translate [1.0]"),
              HasSubstr("has not been registered"));
  EXPECT_EQ(priv.request("3", "robot.teleport translate [1.0]"), "3 SUCCESS");
  EXPECT_THAT(priv.request("4", "simulation list_robots"), StartsWith("4 FAILED"));
  // details describes only what the transport serves (issue #17, item 6): not even that
  // robot.teleport exists elsewhere
  json details = payload(pub.request("5", "simulation details"));
  EXPECT_FALSE(details["robots"][0]["components"].contains("robot.teleport"));
  EXPECT_EQ(details["robots"][0]["components"]["robot.motion"]["service_interfaces"],
            json({"socket"}));
}

// ---- the mapping is a boundary (issue #17, item 6) ----
#ifdef SIMGATE_TEST_WITH_JSONRPC

// The demo on a socket and a JSON-RPC transport, split: the socket transport serves the
// ground robot and its components; JSON-RPC serves the human; both serve robot.pose,
// `simulation` and `time`.
json split_config() {
  json config = testing::demo_config(4.0);
  config["transports"]["jsonrpc"] = {{"plugin", "jsonrpc"}, {"options", {{"port", 0}}}};
  config["services"] = {{"default", json::array({"socket"})},
                        {"human", json::array({"jsonrpc"})},
                        {"robot.pose", json::array({"socket", "jsonrpc"})},
                        {"simulation", json::array({"socket", "jsonrpc"})},
                        {"time", json::array({"socket", "jsonrpc"})}};
  return config;
}

// The names of the components a list of service descriptors covers.
std::set<std::string> components_of(const json& descriptors, const char* key = "component") {
  std::set<std::string> out;
  for (const auto& d : descriptors) out.insert(d.value(key, std::string()));
  return out;
}

// `error` with every occurrence of `name` replaced by "NAME" (to compare two refusals).
json with_name_hidden(json error, const std::string& name) {
  std::string text = error.dump();
  for (auto at = text.find(name); at != std::string::npos; at = text.find(name, at + 4))
    text.replace(at, name.size(), "NAME");
  return json::parse(text);
}

TEST_F(GatewayIntegrationTest, AJsonRpcClientCannotDeactivateASocketOnlyComponentNorFreezeItsGoto) {
  start(split_config());
  LineClient socket(port("socket")), jsonrpc(port("jsonrpc"));
  socket.send("g robot.waypoint goto [1.5, 0.0, 0.0, 0.3]\n");
  EXPECT_EQ(socket.request("s", "robot.waypoint get_status"), "s SUCCESS \"Transit\"");
  // refused exactly as a component that does not exist: nothing shows through
  json unserved = rpc(jsonrpc, 1, "simulation.deactivate", {"robot.waypoint"});
  json missing = rpc(jsonrpc, 2, "simulation.deactivate", {"robot.nowhere"});
  ASSERT_TRUE(unserved.contains("error")) << unserved;
  EXPECT_EQ(unserved["error"]["message"], "Component 'robot.waypoint' not found. Can't deactivate");
  EXPECT_EQ(with_name_hidden(unserved["error"], "robot.waypoint"),
            with_name_hidden(missing["error"], "robot.nowhere"));
  // the socket client's goto goes on and arrives
  EXPECT_EQ(socket.wait_for("g", std::chrono::seconds(60)), "g SUCCESS \"Arrived\"");
  // what JSON-RPC serves it may act on; the socket client still acts on its own
  EXPECT_EQ(rpc(jsonrpc, 3, "simulation.deactivate", {"human"})["result"], nullptr);
  EXPECT_EQ(rpc(jsonrpc, 4, "simulation.activate", {"human"})["result"], nullptr);
  EXPECT_EQ(socket.request("d", "simulation deactivate [\"robot.waypoint\"]"), "d SUCCESS");
  EXPECT_EQ(socket.request("a", "simulation activate [\"robot.waypoint\"]"), "a SUCCESS");
  // and the other way round: the socket client cannot touch the JSON-RPC-only human
  EXPECT_EQ(socket.request("h", "simulation deactivate [\"human\"]"),
            "h FAILED \"Component 'human' not found. Can't deactivate\"");
}

TEST_F(GatewayIntegrationTest, IntrospectionShowsEachTransportOnlyWhatItServes) {
  start(split_config());
  LineClient socket(port("socket")), jsonrpc(port("jsonrpc"));
  const std::set<std::string> on_socket{"robot",          "robot.motion",   "robot.pose",
                                        "robot.teleport", "robot.waypoint", "simulation",
                                        "time",           "communication"};
  // communication goes with simulation
  const std::set<std::string> on_jsonrpc{"human", "robot.pose", "simulation", "time",
                                         "communication"};

  // list_robots: a robot is there when it or one of its components is served
  EXPECT_EQ(socket.request("1", "simulation list_robots"), "1 SUCCESS [\"robot\"]");
  EXPECT_EQ(rpc(jsonrpc, 1, "simulation.list_robots")["result"], json({"robot", "human"}));

  // list_services and the transport's own introspection agree
  std::set<std::string> socket_listed =
      components_of(payload(socket.request("2", "simulation list_services")));
  socket_listed.insert("robot");  // a ground_robot has no services of its own
  EXPECT_EQ(socket_listed, on_socket);
  std::set<std::string> jsonrpc_listed =
      components_of(rpc(jsonrpc, 2, "simulation.list_services")["result"]);
  EXPECT_EQ(jsonrpc_listed, on_jsonrpc);
  EXPECT_EQ(components_of(rpc(jsonrpc, 3, "rpc.discover")["result"]["methods"], "x-component"),
            on_jsonrpc);

  // details: robots with the served components only
  json socket_details = payload(socket.request("3", "simulation details"));
  ASSERT_EQ(socket_details["robots"].size(), 1u);
  EXPECT_EQ(socket_details["robots"][0]["components"].size(), 4u);
  json jsonrpc_details = rpc(jsonrpc, 4, "simulation.details")["result"];
  ASSERT_EQ(jsonrpc_details["robots"].size(), 2u);
  json robot = jsonrpc_details["robots"][0];
  EXPECT_EQ(robot["name"], "robot");
  EXPECT_FALSE(robot.contains("services"));
  EXPECT_EQ(robot["components"].size(), 1u);
  EXPECT_EQ(robot["components"]["robot.pose"]["service_interfaces"],
            json({"jsonrpc", "socket"}));  // in name order
  EXPECT_EQ(jsonrpc_details["robots"][1]["services"],
            json({"move", "get_properties", "set_property", "get_configurations"}));

  // `simgate list` through each transport
  testing::TempDir dir;
  auto [scode, sout] =
      testing::run_simgate({"list", "--port", std::to_string(port("socket"))}, dir);
  EXPECT_EQ(scode, 0) << sout;
  EXPECT_THAT(sout, HasSubstr("robot.waypoint goto("));
  EXPECT_THAT(sout, Not(HasSubstr("human move")));
  auto [jcode, jout] = testing::run_simgate(
      {"list", "--transport", "jsonrpc", "--port", std::to_string(port("jsonrpc"))}, dir);
  EXPECT_EQ(jcode, 0) << jout;
  EXPECT_THAT(jout, HasSubstr("human move("));
  EXPECT_THAT(jout, Not(HasSubstr("robot.waypoint")));
}

// ---- allow / deny lists (issue #17, access control) ----

// The demo on a socket and a JSON-RPC transport that both serve every component, JSON-RPC
// narrowed by its lists: the robot, `simulation` and `time now`, but never
// `simulation quit` nor the teleport.
json access_config() {
  json config = testing::demo_config(4.0);
  config["transports"]["jsonrpc"] = {{"plugin", "jsonrpc"},
                                     {"options", {{"port", 0}}},
                                     {"allow", {"robot.*", "simulation.*", "time.now"}},
                                     {"deny", {"simulation.quit", "robot.teleport.*"}}};
  config["services"] = {{"default", json::array({"socket", "jsonrpc"})}};
  config.erase(
      "streams");  // the socket transport's own stream services would be listed on it alone
  return config;
}

// What access_config() lets a JSON-RPC client call.
bool callable_through_jsonrpc(const std::string& qualified) {
  auto starts = [&](const std::string& prefix) { return qualified.rfind(prefix, 0) == 0; };
  // quit, terminate and set_log_level are process-wide: JSON-RPC is no console
  const bool process_wide = qualified == "simulation.quit" || qualified == "simulation.terminate" ||
                            qualified == "simulation.set_log_level";
  return (starts("robot.") && !starts("robot.teleport.")) ||
         (starts("simulation.") && !process_wide) || qualified == "time.now";
}

// "component.service" of each descriptor of a list_services answer.
std::set<std::string> qualified_names(const json& descriptors) {
  std::set<std::string> out;
  for (const auto& d : descriptors)
    out.insert(d.at("component").get<std::string>() + "." + d.at("name").get<std::string>());
  return out;
}

TEST_F(GatewayIntegrationTest, ADeniedServiceIsRefusedThroughJsonRpcAsAnUnknownOneAndDoesNotRun) {
  start(access_config());
  LineClient socket(port("socket")), jsonrpc(port("jsonrpc"));
  // refused exactly as a service that does not exist: -32601, the same message and data
  json quit = rpc(jsonrpc, 1, "simulation.quit");
  json missing = rpc(jsonrpc, 2, "simulation.quiet");
  ASSERT_TRUE(quit.contains("error")) << quit;
  EXPECT_EQ(quit["error"]["code"], -32601);
  EXPECT_EQ(with_name_hidden(quit["error"], "quit"), with_name_hidden(missing["error"], "quiet"));
  EXPECT_THAT(quit["error"]["message"].get<std::string>(),
              Not(HasSubstr("quit,")));  // not among "services: ..."
  // the teleport did not move the robot; human is not on the allow list
  EXPECT_EQ(rpc(jsonrpc, 3, "robot.teleport.translate", {5.0})["error"]["code"], -32601);
  EXPECT_EQ(rpc(jsonrpc, 4, "human.move", {0.5, 0.0})["error"]["code"], -32601);
  EXPECT_EQ(rpc(jsonrpc, 5, "time.sleep", {0.1})["error"]["code"], -32601);
  json pose = rpc(jsonrpc, 6, "robot.pose.get_local_data")["result"];
  EXPECT_LT(pose["x"].get<double>(), 1.0) << pose;
  // what the lists allow runs, and the simulation did not quit
  EXPECT_TRUE(rpc(jsonrpc, 7, "time.now")["result"].is_number());
  EXPECT_EQ(rpc(jsonrpc, 8, "robot.motion.set_speed", {0.0, 0.0})["result"], nullptr);
  // the same services run through the socket transport, which has no lists
  EXPECT_EQ(socket.request("t", "robot.teleport translate [0.5]"), "t SUCCESS");
  EXPECT_EQ(socket.request("h", "human move [0.0, 0.0]"), "h SUCCESS");
  EXPECT_EQ(socket.request("q", "simulation quit"), "q SUCCESS");
  gateway_->join();  // the loop ends: quit ran, through the socket transport only
}

TEST_F(GatewayIntegrationTest, OnlyTheSocketConsoleEndsTheProcessOrChangesItsLogLevel) {
  // the shipped demo: before, the web app's console (JSON-RPC over WebSocket) ended it with
  // one simulation.terminate, and any client could set the log level off (issue #35, item 5)
  json config = testing::demo_config(4.0);
  config["transports"]["jsonrpc"] = {{"plugin", "jsonrpc"}, {"options", {{"port", 0}}}};
  config["services"] = {{"default", json::array({"socket", "jsonrpc"})}};
  config.erase("streams");
  start(config);
  LineClient socket(port("socket")), jsonrpc(port("jsonrpc"));
  for (const char* method : {"simulation.terminate", "simulation.quit"}) {
    json refused = rpc(jsonrpc, 1, method);
    ASSERT_TRUE(refused.contains("error")) << refused;
    EXPECT_EQ(refused["error"]["code"], -32601);
    EXPECT_THAT(refused["error"]["message"].get<std::string>(),
                HasSubstr("acts on the whole process, and this transport is not a console"))
        << refused;
  }
  const log::Level level_before = log::level();
  json level = rpc(jsonrpc, 2, "simulation.set_log_level", {"simulation", "off"});
  EXPECT_EQ(level["error"]["code"], -32601) << level;
  EXPECT_EQ(log::level(), level_before);
  // introspection leaves them out on JSON-RPC, shows them on the socket console
  std::set<std::string> listed =
      qualified_names(rpc(jsonrpc, 3, "simulation.list_services")["result"]);
  EXPECT_FALSE(listed.count("simulation.terminate") || listed.count("simulation.quit") ||
               listed.count("simulation.set_log_level"));
  std::set<std::string> on_console =
      qualified_names(payload(socket.request("1", "simulation list_services")));
  EXPECT_TRUE(on_console.count("simulation.terminate") &&
              on_console.count("simulation.set_log_level"));
  // the process still runs, and the socket console may end it
  EXPECT_TRUE(rpc(jsonrpc, 4, "time.now")["result"].is_number());
  EXPECT_EQ(socket.request("l", "simulation set_log_level [\"simulation\", \"WARNING\"]"),
            "l SUCCESS");
  EXPECT_EQ(socket.request("q", "simulation quit"), "q SUCCESS");
  gateway_->join();
}

TEST_F(GatewayIntegrationTest, IntrospectionOnEachTransportListsExactlyTheCallableServices) {
  start(access_config());
  LineClient socket(port("socket")), jsonrpc(port("jsonrpc"));
  // the socket transport: everything
  std::set<std::string> all =
      qualified_names(payload(socket.request("1", "simulation list_services")));
  ASSERT_TRUE(all.count("simulation.quit") && all.count("human.move") &&
              all.count("robot.teleport.translate"));
  std::set<std::string> expected;
  for (const auto& name : all)
    if (callable_through_jsonrpc(name)) expected.insert(name);
  ASSERT_TRUE(expected.count("robot.motion.set_speed") && expected.count("time.now"));

  // JSON-RPC: list_services, rpc.discover and `simgate list` show exactly what it may call
  json listed = rpc(jsonrpc, 1, "simulation.list_services")["result"];
  EXPECT_EQ(qualified_names(listed), expected);
  for (const auto& d : listed) {  // each service's transports: where it is callable
    if (d["component"] == "robot.motion") {
      EXPECT_EQ(d["transports"], json({"jsonrpc", "socket"})) << d;
    }
  }
  std::set<std::string> discovered;
  const json discovery = rpc(jsonrpc, 2, "rpc.discover");
  for (const auto& m : discovery["result"]["methods"])
    discovered.insert(m["name"].get<std::string>());
  EXPECT_EQ(discovered, expected);
  json from_socket = payload(socket.request("2", "simulation list_services"));
  for (const auto& d : from_socket) {
    if (d["component"] == "robot.teleport") {
      EXPECT_EQ(d["transports"], json({"socket"})) << d;
    }
  }

  // details: the components it serves, with only their callable services
  json details = rpc(jsonrpc, 3, "simulation.details")["result"];
  ASSERT_EQ(details["robots"].size(), 2u)
      << details;  // human is served (mapped), with nothing to call
  json robot = details["robots"][0];
  EXPECT_EQ(robot["components"]["robot.motion"]["services"],
            json({"set_speed", "stop", "get_properties", "set_property", "get_configurations"}));
  EXPECT_FALSE(robot["components"]["robot.teleport"].contains("services")) << robot;
  EXPECT_FALSE(details["robots"][1].contains("services")) << details["robots"][1];
  json socket_details = payload(socket.request("3", "simulation details"));
  EXPECT_TRUE(socket_details["robots"][0]["components"]["robot.teleport"].contains("services"));

  testing::TempDir dir;
  auto [code, out] = testing::run_simgate(
      {"list", "--transport", "jsonrpc", "--port", std::to_string(port("jsonrpc"))}, dir);
  EXPECT_EQ(code, 0) << out;
  EXPECT_THAT(out, HasSubstr("robot.motion set_speed("));
  EXPECT_THAT(out, Not(HasSubstr("quit")));
  EXPECT_THAT(out, Not(HasSubstr("teleport")));
  EXPECT_THAT(out, Not(HasSubstr("human")));
}
#endif

TEST_F(GatewayIntegrationTest,
       ASocketTransportRefusesADeniedServiceWithMorsesUnknownServiceAnswer) {
  json config = testing::demo_config();
  config["transports"]["socket"]["deny"] = {"robot.teleport.translate"};
  start(config);
  LineClient c(port());
  EXPECT_EQ(c.request("1", "robot.teleport translate [1.0]"),
            "1 FAILED \"The request translate has not been registered in Socket service manager: "
            "component "
            "'robot.teleport' has no service 'translate' (services: get_configurations, "
            "get_properties, rotate, "
            "set_property)\"");
  json pose = payload(c.request("2", "robot.pose get_local_data"));
  EXPECT_LT(pose["x"].get<double>(), 0.5);
  EXPECT_EQ(c.request("3", "robot.teleport rotate [0.0]"), "3 SUCCESS");
}

TEST_F(GatewayIntegrationTest, BadInputGetsAnErrorAndEveryoneKeepsBeingServed) {
  start(testing::demo_config());
  LineClient bad(port()), good(port());
  EXPECT_THAT(bad.request("1", "robot.motion set_speed [1.0"), StartsWith("1 FAILED"));
  EXPECT_THAT(bad.request("2", "robot.motion set_speed [\"fast\", 0]"), StartsWith("2 FAILED"));
  EXPECT_THAT(bad.request("3", "robot.motion set_speed [1.0]"), HasSubstr("wrong # of parameters"));
  EXPECT_THAT(bad.request("4", "nobody nothing"), StartsWith("4 FAILED"));
  EXPECT_EQ(bad.request("5", "human move [-1, 0]"),
            "5 FAILED \"Our human cannot walk at negative speed!\"");
  EXPECT_THAT(good.request("6", "simulation list_robots"), StartsWith("6 SUCCESS"));
  EXPECT_THAT(bad.request("7", "simulation list_robots"), StartsWith("7 SUCCESS"));
}

TEST_F(GatewayIntegrationTest, QuitAnswersTheCallerAndPendingClientsThenStops) {
  start(testing::demo_config());
  LineClient waiting(port()), quitter(port());
  waiting.send("g robot.waypoint goto [20.0, 0.0, 0.0]\n");
  EXPECT_EQ(waiting.request("s", "robot.waypoint get_status"), "s SUCCESS \"Transit\"");
  EXPECT_EQ(quitter.request("q", "simulation quit"), "q SUCCESS");
  gateway_->join();  // the loop ends by itself
  gateway_->gateway().shutdown();
  // the pending goto got a final answer before its connection closed
  EXPECT_THAT(waiting.wait_for("g", std::chrono::seconds(10)), StartsWith("g "));
  EXPECT_TRUE(quitter.closed_by_server());
}

}  // namespace
}  // namespace simgate::gateway
