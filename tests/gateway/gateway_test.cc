// GatewayIntegration: gateways built from configs on ephemeral ports, driven over real
// sockets with the MORSE text protocol.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <thread>

#include "simgate/core/log.h"
#include "simgate/gateway/gateway.h"
#include "test_support.h"

namespace simgate::gateway {
namespace {

using ::testing::HasSubstr;
using ::testing::StartsWith;
using testing::LineClient;
using testing::payload;

class GatewayIntegrationTest : public ::testing::Test {
 protected:
  void start(const json& config) {
    Deployment d = parse_deployment(config, SIMGATE_SOURCE_DIR "/config");
    gateway_ = std::make_unique<Gateway>(d, registry_);
    gateway_->start();
    thread_ = std::thread([this] { gateway_->run(); });
  }
  int port(const std::string& transport = "socket") {
    return testing::port_of(gateway_->endpoints().at(transport).at(0));
  }
  void TearDown() override {
    if (gateway_) gateway_->stop();
    if (thread_.joinable()) thread_.join();
    gateway_.reset();
  }

  sim::ComponentRegistry registry_ = sim::builtin_registry();
  std::unique_ptr<Gateway> gateway_;
  std::thread thread_;
};

TEST_F(GatewayIntegrationTest, ServesTheSupervisionServices) {
  start(testing::demo_config());
  LineClient c(port());
  std::string line = c.request("1", "simulation list_robots");
  EXPECT_EQ(line, "1 SUCCESS [\"robot\", \"human\"]");
  json details = payload(c.request("0", "simulation details []"));
  EXPECT_EQ(details["robots"][0]["components"]["robot.motion"]["service_interfaces"], json({"socket"}));
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
  config["services"] = {{"default", json::array({"socket"})}, {"robot.teleport", json::array({"private"})}};
  start(config);
  LineClient pub(port("socket")), priv(port("private"));
  EXPECT_THAT(pub.request("1", "robot.teleport translate [1.0]"), StartsWith("1 FAILED"));
  EXPECT_THAT(pub.request("2", "robot.teleport translate [1.0]"), HasSubstr("has not been registered"));
  EXPECT_EQ(priv.request("3", "robot.teleport translate [1.0]"), "3 SUCCESS");
  EXPECT_THAT(priv.request("4", "simulation list_robots"), StartsWith("4 FAILED"));
  // details says which transport serves it
  json details = payload(pub.request("5", "simulation details"));
  EXPECT_EQ(details["robots"][0]["components"]["robot.teleport"]["service_interfaces"], json({"private"}));
}

TEST_F(GatewayIntegrationTest, BadInputGetsAnErrorAndEveryoneKeepsBeingServed) {
  start(testing::demo_config());
  LineClient bad(port()), good(port());
  EXPECT_THAT(bad.request("1", "robot.motion set_speed [1.0"), StartsWith("1 FAILED"));
  EXPECT_THAT(bad.request("2", "robot.motion set_speed [\"fast\", 0]"), StartsWith("2 FAILED"));
  EXPECT_THAT(bad.request("3", "robot.motion set_speed [1.0]"), HasSubstr("wrong # of parameters"));
  EXPECT_THAT(bad.request("4", "nobody nothing"), StartsWith("4 FAILED"));
  EXPECT_EQ(bad.request("5", "human move [-1, 0]"), "5 FAILED \"Our human cannot walk at negative speed!\"");
  EXPECT_THAT(good.request("6", "simulation list_robots"), StartsWith("6 SUCCESS"));
  EXPECT_THAT(bad.request("7", "simulation list_robots"), StartsWith("7 SUCCESS"));
}

TEST_F(GatewayIntegrationTest, QuitAnswersTheCallerAndPendingClientsThenStops) {
  start(testing::demo_config());
  LineClient waiting(port()), quitter(port());
  waiting.send("g robot.waypoint goto [20.0, 0.0, 0.0]\n");
  EXPECT_EQ(waiting.request("s", "robot.waypoint get_status"), "s SUCCESS \"Transit\"");
  EXPECT_EQ(quitter.request("q", "simulation quit"), "q SUCCESS");
  thread_.join();  // the loop ends by itself
  gateway_->shutdown();
  // the pending goto got a final answer before its connection closed
  EXPECT_THAT(waiting.wait_for("g", std::chrono::seconds(10)), StartsWith("g "));
  EXPECT_TRUE(quitter.closed_by_server());
}

}  // namespace
}  // namespace simgate::gateway
