// GatewayStreamsConfig: the "streams" section and a component's "frequency": which
// transports carry which component's data stream, checked like the rest of the file.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "simgate/core/errors.h"
#include "simgate/gateway/gateway.h"
#include "test_support.h"

namespace simgate::gateway {
namespace {

using ::testing::HasSubstr;
using testing::demo_config;

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
  EXPECT_EQ(by_name["robot.waypoint"].fields, (std::vector<std::string>{"x", "y", "z", "tolerance", "speed"}));
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
  EXPECT_THAT(error_text(with_streams({{"robot.pose", "socket"}})), HasSubstr("streams.robot.pose"));
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

TEST(GatewayStreamsConfigTest, AFrequencyWithoutAnOutputStreamIsAWarning) {
  json c = demo_config();
  c["robots"][0]["components"][0]["frequency"] = 10;  // robot.motion: an input stream
  Built b = build(c);
  ASSERT_TRUE(b.errors.empty()) << ::testing::PrintToString(b.errors);
  ASSERT_EQ(b.warnings.size(), 1u) << ::testing::PrintToString(b.warnings);
  EXPECT_THAT(b.warnings[0], HasSubstr("robots[0].components[0].frequency: component 'robot.motion' (type motion_vw) "
                                       "has no output stream"));
}

TEST(GatewayStreamsConfigTest, ACameraTakesTheFrequencyAsItsFrameRateWithoutAWarning) {
  json c = demo_config();
  c["robots"][0]["components"].push_back(
      {{"name", "camera"}, {"type", "video_camera"}, {"frequency", 5}, {"options", {{"cam_width", 32}}}});
  Deployment d = parse_deployment(c, SIMGATE_SOURCE_DIR "/config");
  auto registry = sim::builtin_registry();
  Gateway g(d, registry, GatewayOptions{true, std::nullopt, {}});
  EXPECT_TRUE(g.warnings().empty()) << ::testing::PrintToString(g.warnings());
  const sim::ComponentEntry* camera = g.simulation().find("robot.camera");
  ASSERT_NE(camera, nullptr);
  const json properties = static_cast<const sim::SimComponent&>(*camera->component).get_properties()["properties"];
  EXPECT_EQ(properties["frequency"], 5.0);
  EXPECT_EQ(properties["cam_width"], 32);
}

}  // namespace
}  // namespace simgate::gateway
