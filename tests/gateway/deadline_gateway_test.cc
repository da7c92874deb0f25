// GatewayDeadline: the deployment's "requests": {"max_wait_ms": N} bounds every request of
// every transport, and the socket transport's "timeouts" option gives calls theirs, through a
// gateway on the demo scene: a goto far away ends FAILED (timeout) and the robot stops (its
// waypoint was interrupted). Bad values are ConfigErrors naming their path. No timed
// assertions: short limits on a goto that would take far longer, generous waits.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <thread>

#include "simgate/gateway/gateway.h"
#include "in_process_gateway.h"
#include "test_support.h"

namespace simgate::gateway {
namespace {

using ::testing::HasSubstr;
using testing::LineClient;

class GatewayDeadlineTest : public ::testing::Test {
 protected:
  void start(const json& config) { gateway_ = std::make_unique<testing::InProcessGateway>(config); }
  int port() { return gateway_->port(); }

  std::unique_ptr<testing::InProcessGateway> gateway_;
};

TEST_F(GatewayDeadlineTest, TheServersMaxWaitEndsAFarGotoFailedAndTheRobotStops) {
  json config = testing::demo_config();
  config["requests"] = {{"max_wait_ms", 300}};
  start(config);
  LineClient c(port());
  EXPECT_EQ(c.request("g1", "robot.waypoint goto [50.0, 0.0, 0.0]"),
            "g1 FAILED \"robot.waypoint.goto: no reply within 300 ms (the server's max wait); "
            "interrupted\"");
  // interrupted: the waypoint's interrupt() made its destination where the robot is
  EXPECT_EQ(c.request("s", "robot.waypoint get_status"), "s SUCCESS \"Arrived\"");
  // sync requests are answered as ever
  EXPECT_EQ(c.request("t", "robot.motion set_speed [0.0, 0.0]"), "t SUCCESS");
}

TEST_F(GatewayDeadlineTest, ASocketServiceDeadlineShorterThanTheMaxWaitWins) {
  json config = testing::demo_config();
  config["requests"] = {{"max_wait_ms", 600000}};
  config["transports"]["socket"]["options"]["timeouts"] = {
      {"services", {{"robot.waypoint.goto", 300}}}};
  start(config);
  LineClient c(port());
  EXPECT_EQ(c.request("g1", "robot.waypoint goto [50.0, 0.0, 0.0]"),
            "g1 FAILED \"robot.waypoint.goto: no reply within 300 ms (deadline); interrupted\"");
  EXPECT_EQ(c.request("s", "robot.waypoint get_status"), "s SUCCESS \"Arrived\"");
}

TEST(GatewayDeadlineConfigTest, BadMaxWaitsAreConfigErrorsNamingTheirPath) {
  const std::vector<std::pair<json, std::string>> bad = {
      {5, "requests"},
      {{{"max_wait_ms", -1}}, "requests.max_wait_ms"},
      {{{"max_wait_ms", 1.5}}, "requests.max_wait_ms"},
      {{{"max_wait_ms", "100"}}, "requests.max_wait_ms"},
      {{{"max_wait_ms", 1e12}}, "requests.max_wait_ms"},
      {{{"max_wiat_ms", 100}}, "requests.max_wiat_ms"},
  };
  for (const auto& [value, path] : bad) {
    json config = testing::demo_config();
    config["requests"] = value;
    try {
      parse_deployment(config, SIMGATE_SOURCE_DIR "/config");
      ADD_FAILURE() << "requests " << value.dump() << " accepted";
    } catch (const ConfigError& e) {
      EXPECT_THAT(e.what(), HasSubstr(path)) << value.dump();
    }
  }
  json config = testing::demo_config();
  config["requests"] = {{"max_wait_ms", 2000}};
  EXPECT_EQ(parse_deployment(config, SIMGATE_SOURCE_DIR "/config").max_wait,
            std::chrono::milliseconds(2000));
  config.erase("requests");
  EXPECT_EQ(parse_deployment(config, SIMGATE_SOURCE_DIR "/config").max_wait,
            std::chrono::milliseconds(0));
}

}  // namespace
}  // namespace simgate::gateway
