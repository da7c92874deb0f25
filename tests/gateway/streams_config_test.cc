// GatewayStreamsConfig: the "streams" section and a component's "frequency": which
// transports carry which component's data stream, checked like the rest of the file.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "simgate/core/errors.h"
#include "simgate/gateway/gateway.h"
#include "simgate/sim/supervision.h"
#include "test_support.h"

namespace simgate::gateway {
namespace {

using testing::demo_config;
using ::testing::HasSubstr;

json with_streams(json streams) {
  json c = demo_config();
  c["transports"]["jsonrpc"] = {{"plugin", "jsonrpc"}, {"options", {{"port", 0}}}};
  c["streams"] = std::move(streams);
  return c;
}

// Builds (check only) and returns the streams the simulation got, or the errors.
struct Built {
  std::vector<StreamInfo> streams;  // all transports'
  std::vector<std::string> errors;
  std::vector<std::string> warnings;
};
Built build(const json& config) {
  Built out;
  try {
    Deployment d = parse_deployment(config, SIMGATE_SOURCE_DIR "/config");
    auto registry = sim::builtin_registry();
    Gateway g(d, registry, GatewayOptions{true, std::nullopt, {}});
    for (const auto& s : g.simulation().streams().statistics()) out.streams.push_back(s.info);
    out.warnings = g.warnings();
  } catch (const ConfigError& e) {
    out.errors = e.errors();
  }
  return out;
}

TEST(GatewayStreamsConfigTest, WithoutTheSectionNothingStreams) {
  json c = demo_config();
  c.erase("streams");
  Built b = build(c);
  EXPECT_TRUE(b.errors.empty()) << ::testing::PrintToString(b.errors);
  EXPECT_TRUE(b.streams.empty());
}

TEST(GatewayStreamsConfigTest, NamesGlobsAndDefaultMapAsServicesDo) {
  json c = with_streams({{"robot.pose", {"socket", "jsonrpc"}}, {"robot.*", {"jsonrpc"}}});
  c["robots"][0]["components"][3]["frequency"] = 25;
  Built b = build(c);
  ASSERT_TRUE(b.errors.empty()) << ::testing::PrintToString(b.errors);
  // robot.* matches every component; those without a stream (the robot itself) are skipped
  std::map<std::string, StreamInfo> by_name;
  for (const auto& s : b.streams) by_name[s.component] = s;
  ASSERT_TRUE(by_name.count("robot.pose"));
  EXPECT_EQ(by_name["robot.pose"].transports, (std::vector<std::string>{"socket", "jsonrpc"}));
  EXPECT_EQ(by_name["robot.pose"].frequency, 25);
  EXPECT_EQ(by_name["robot.motion"].transports, (std::vector<std::string>{"jsonrpc"}));
  EXPECT_EQ(by_name["robot.motion"].direction, StreamDirection::in);
  EXPECT_EQ(by_name["robot.teleport"].kind, "teleport");
  EXPECT_EQ(by_name["robot.waypoint"].fields,
            (std::vector<std::string>{"x", "y", "z", "tolerance", "speed"}));
  EXPECT_FALSE(by_name.count("robot"));  // the robot itself has no stream
  EXPECT_EQ(b.streams.size(), 4u);

  Built d = build(with_streams({{"default", {"socket"}}}));
  ASSERT_TRUE(d.errors.empty()) << ::testing::PrintToString(d.errors);
  EXPECT_EQ(d.streams.size(), 4u);
  for (const auto& s : d.streams)
    if (s.component == "robot.pose") {
      EXPECT_EQ(s.frequency, StreamHub::k_default_frequency);
    }
}

TEST(GatewayStreamsConfigTest, MistakesAreErrorsNamingThePath) {
  auto error_text = [](const json& config) {
    std::string out;
    for (const auto& e : build(config).errors) out += e + "\n";
    return out;
  };
  EXPECT_THAT(error_text(with_streams({{"robot.pose", {"sockte"}}})),
              HasSubstr("streams.robot.pose[0]: expected a transport declared in \"transports\""));
  EXPECT_THAT(error_text(with_streams({{"robot.poze", {"socket"}}})),
              HasSubstr("streams.robot.poze: expected a component name or a glob matching one"));
  EXPECT_THAT(error_text(with_streams({{"robot.pose", "socket"}})),
              HasSubstr("streams.robot.pose"));
  // named exactly, a component without a stream is a mistake
  EXPECT_THAT(error_text(with_streams({{"robot", {"socket"}}})),
              HasSubstr("streams.robot: component 'robot' (type ground_robot) has no data stream"));
  json c = demo_config();
  c["robots"][0]["components"][3]["frequency"] = 0;
  EXPECT_THAT(error_text(c), HasSubstr("robots[0].components[3].frequency"));
  c["robots"][0]["components"][3]["frequency"] = "fast";
  EXPECT_THAT(error_text(c), HasSubstr("robots[0].components[3].frequency"));
  json robot = demo_config();
  robot["robots"][0]["frequency"] = 10;  // robots have no stream
  EXPECT_THAT(error_text(robot), HasSubstr("robots[0].frequency"));
}

TEST(GatewayStreamsConfigTest, ARuleObjectsFrequencyOverridesTheComponents) {
  json c = with_streams({{"robot.pose", {{"transports", {"socket"}}, {"frequency", 12}}},
                         {"robot.motion", {{"transports", {"jsonrpc"}}}}});
  c["robots"][0]["components"][3]["frequency"] = 25;  // robot.pose's own
  Built b = build(c);
  ASSERT_TRUE(b.errors.empty()) << ::testing::PrintToString(b.errors);
  std::map<std::string, StreamInfo> by_name;
  for (const auto& s : b.streams) by_name[s.component] = s;
  EXPECT_EQ(by_name["robot.pose"].frequency, 12);
  EXPECT_EQ(by_name["robot.pose"].transports, (std::vector<std::string>{"socket"}));
  EXPECT_EQ(by_name["robot.motion"].transports, (std::vector<std::string>{"jsonrpc"}));
  // the default rule's frequency, for what it maps
  Built d = build(with_streams({{"default", {{"transports", {"socket"}}, {"frequency", 7}}}}));
  ASSERT_TRUE(d.errors.empty()) << ::testing::PrintToString(d.errors);
  for (const auto& s : d.streams)
    EXPECT_EQ(s.frequency, s.component == "robot.pose" ? 7 : 0) << s.component;
  // a glob's
  Built g = build(with_streams({{"robot.*", {{"transports", {"socket"}}, {"frequency", 5}}}}));
  ASSERT_TRUE(g.errors.empty()) << ::testing::PrintToString(g.errors);
  for (const auto& s : g.streams)
    EXPECT_EQ(s.frequency, s.component == "robot.pose" ? 5 : 0) << s.component;
}

TEST(GatewayStreamsConfigTest, ACameraTakesItsRulesFrequencyAsItsFrameRate) {
  json c = with_streams({{"robot.camera", {{"transports", {"jsonrpc"}}, {"frequency", 4}}}});
  c["robots"][0]["components"].push_back({{"name", "camera"},
                                          {"type", "video_camera"},
                                          {"frequency", 5},
                                          {"options", {{"cam_width", 32}}}});
  Built b = build(c);
  ASSERT_TRUE(b.errors.empty()) << ::testing::PrintToString(b.errors);
  ASSERT_EQ(b.streams.size(), 1u);
  EXPECT_EQ(b.streams[0].frequency, 4);
}

TEST(GatewayStreamsConfigTest, TheSimulationStreamsItsBodyPosesWhenNamed) {
  Built b = build(with_streams({{"robot.pose", {"socket"}}, {"simulation", {"jsonrpc"}}}));
  ASSERT_TRUE(b.errors.empty()) << ::testing::PrintToString(b.errors);
  ASSERT_EQ(b.streams.size(), 2u);
  // after the robots' streams (the socket transport numbers its stream ports in this order)
  EXPECT_EQ(b.streams[1].component, "simulation");
  EXPECT_EQ(b.streams[1].kind, "body_poses");
  EXPECT_EQ(b.streams[1].direction, StreamDirection::out);
  EXPECT_EQ(b.streams[1].transports, (std::vector<std::string>{"jsonrpc"}));
  EXPECT_EQ(b.streams[1].frequency, sim::SupervisionServices::k_body_poses_frequency);
  EXPECT_EQ(b.streams[1].frequency, 30);

  Built f = build(
      with_streams({{"simulation", {{"transports", {"jsonrpc", "socket"}}, {"frequency", 15}}}}));
  ASSERT_TRUE(f.errors.empty()) << ::testing::PrintToString(f.errors);
  ASSERT_EQ(f.streams.size(), 1u);
  EXPECT_EQ(f.streams[0].frequency, 15);
  EXPECT_EQ(f.streams[0].transports, (std::vector<std::string>{"jsonrpc", "socket"}));
}

// A file written before the simulation could stream keeps its streams (and the socket's
// stream ports): "default" and globs map the robots' components only.
TEST(GatewayStreamsConfigTest, DefaultAndGlobsDoNotMapThePseudoComponents) {
  for (const json& streams :
       {json{{"default", {"socket"}}}, json{{"*", {"socket"}}}, json{{"sim*", {"socket"}}}}) {
    Built b = build(with_streams(streams));
    ASSERT_TRUE(b.errors.empty()) << streams.dump() << ::testing::PrintToString(b.errors);
    for (const auto& s : b.streams) EXPECT_NE(s.component, "simulation") << streams.dump();
  }
}

TEST(GatewayStreamsConfigTest, RuleObjectMistakesAreErrorsNamingThePath) {
  auto error_text = [](const json& config) {
    std::string out;
    for (const auto& e : build(config).errors) out += e + "\n";
    return out;
  };
  EXPECT_THAT(
      error_text(with_streams({{"simulation", {{"frequency", 30}}}})),
      HasSubstr(
          "streams.simulation.transports: expected an array of the transport names that carry the "
          "stream, found nothing"));
  EXPECT_THAT(
      error_text(with_streams({{"simulation", {{"transports", {"jsonrpc"}}, {"frequency", 0}}}})),
      HasSubstr("streams.simulation.frequency: expected a number from 0.001 to"));
  EXPECT_THAT(error_text(with_streams(
                  {{"simulation", {{"transports", {"jsonrpc"}}, {"frequency", "fast"}}}})),
              HasSubstr("streams.simulation.frequency: expected a number"));
  EXPECT_THAT(
      error_text(with_streams({{"simulation", {{"transports", {"jsonrpc"}}, {"rate", 30}}}})),
      HasSubstr("streams.simulation.rate: unknown key"));
  EXPECT_THAT(
      error_text(with_streams({{"simulation", {{"transports", {"jsonrcp"}}}}})),
      HasSubstr(
          "streams.simulation.transports[0]: expected a transport declared in \"transports\""));
  EXPECT_THAT(error_text(with_streams({{"simulation", {{"transports", "jsonrpc"}}}})),
              HasSubstr("streams.simulation.transports: expected an array of transport names"));
  EXPECT_THAT(
      error_text(with_streams({{"simulation", "jsonrpc"}})),
      HasSubstr(
          "streams.simulation: expected an array of transport names or an object {\"transports\": "
          "[...], \"frequency\": Hz}, found string"));
  // named exactly, a pseudo-component without a stream is a mistake, as a component is
  EXPECT_THAT(error_text(with_streams({{"time", {"socket"}}})),
              HasSubstr("streams.time: component 'time' (type time) has no data stream"));
  // "services" rules stay lists
  json services = with_streams({{"robot.pose", {"socket"}}});
  services["services"]["simulation"] = {{"transports", {"socket"}}};
  EXPECT_THAT(error_text(services),
              HasSubstr("services.simulation: expected an array of transport names, found object"));
}

TEST(GatewayStreamsConfigTest, ARulesFrequencyOnAnInputStreamIsAWarning) {
  json c = demo_config();
  c["streams"] = {{"robot.motion", {{"transports", {"socket"}}, {"frequency", 10}}}};
  Built b = build(c);
  ASSERT_TRUE(b.errors.empty()) << ::testing::PrintToString(b.errors);
  ASSERT_EQ(b.warnings.size(), 1u) << ::testing::PrintToString(b.warnings);
  EXPECT_THAT(b.warnings[0],
              HasSubstr("streams.robot.motion.frequency: component 'robot.motion' (type motion_vw) "
                        "has no output stream: the frequency is not used"));
}

TEST(GatewayStreamsConfigTest, AFrequencyWithoutAnOutputStreamIsAWarning) {
  json c = demo_config();
  c["robots"][0]["components"][0]["frequency"] = 10;  // robot.motion: an input stream
  Built b = build(c);
  ASSERT_TRUE(b.errors.empty()) << ::testing::PrintToString(b.errors);
  ASSERT_EQ(b.warnings.size(), 1u) << ::testing::PrintToString(b.warnings);
  EXPECT_THAT(
      b.warnings[0],
      HasSubstr("robots[0].components[0].frequency: component 'robot.motion' (type motion_vw) "
                "has no output stream"));
}

TEST(GatewayStreamsConfigTest, ACameraTakesTheFrequencyAsItsFrameRateWithoutAWarning) {
  json c = demo_config();
  c["robots"][0]["components"].push_back({{"name", "camera"},
                                          {"type", "video_camera"},
                                          {"frequency", 5},
                                          {"options", {{"cam_width", 32}}}});
  Deployment d = parse_deployment(c, SIMGATE_SOURCE_DIR "/config");
  auto registry = sim::builtin_registry();
  Gateway g(d, registry, GatewayOptions{true, std::nullopt, {}});
  EXPECT_TRUE(g.warnings().empty()) << ::testing::PrintToString(g.warnings());
  const sim::ComponentEntry* camera = g.simulation().find("robot.camera");
  ASSERT_NE(camera, nullptr);
  const json properties =
      static_cast<const sim::SimComponent&>(*camera->component).get_properties()["properties"];
  EXPECT_EQ(properties["frequency"], 5.0);
  EXPECT_EQ(properties["cam_width"], 32);
}

}  // namespace
}  // namespace simgate::gateway
