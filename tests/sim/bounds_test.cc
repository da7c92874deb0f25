// SimBounds: every service that writes simulation state from a client's numbers refuses a
// non-finite number or one beyond its documented bound (docs/configuration.md), FAILED with
// a message naming the parameter, its value and the bound, and changes nothing. Before these
// checks `human move [1e300, 0]` or `teleport translate [1e308]` succeeded and MuJoCo reset
// the whole world at the next step.
#include <cmath>
#include <limits>

#include "sim_fixture.h"

namespace simgate::sim {
namespace {

using testing::DemoSim;
using ::testing::HasSubstr;

using testing::k_inf;
using testing::k_nan;

class SimBoundsTest : public DemoSim {
 protected:
  // The refusal of a call: FAILED as invalid arguments, naming the parameter.
  Outcome refused(const std::string& component, const std::string& service, json params,
                  const std::string& parameter) {
    Outcome o = call(component, service, std::move(params));
    EXPECT_EQ(o.status, Status::failed) << component << " " << service << ": " << o.message;
    EXPECT_EQ(o.failure, Failure::bad_arguments) << o.message;
    EXPECT_EQ(o.data.is_object() ? o.data.value("parameter", "") : "", parameter) << o.data.dump();
    return o;
  }
  Eigen::Vector3d position_of(const std::string& body) {
    return body_position(*sim_, sim_->model().body_id(body));
  }
};

TEST_F(SimBoundsTest, HumanMoveRefusesAHugeStepNamingItsValueAndTheBound) {
  const Eigen::Vector3d before = position_of("human");
  Outcome o = refused("human", "move", {1e300, 0.0}, "speed");
  EXPECT_EQ(o.message,
            "speed = 1e+300 is out of bounds: expected a finite number from 0 to 1e+06 m");
  EXPECT_EQ(o.value, json(o.message));  // the FAILED payload every transport sends
  EXPECT_EQ(position_of("human"), before);
  // after the refusal the world steps on as before: nothing was reset
  const double t = sim_->sim_time();
  run_for(0.1);
  EXPECT_GT(sim_->sim_time(), t);
  EXPECT_NEAR((position_of("human") - before).norm(), 0.0, 0.01);
}

TEST_F(SimBoundsTest, HumanMoveRefusesNonFiniteNumbers) {
  EXPECT_THAT(refused("human", "move", {k_nan, 0.0}, "speed").message,
              HasSubstr("speed = nan is out of bounds"));
  EXPECT_THAT(
      refused("human", "move", {1.0, k_inf}, "rotation").message,
      HasSubstr("rotation = inf is out of bounds: expected a finite number within ±1000 rad"));
  EXPECT_THAT(refused("human", "move", {1.0, 1e4}, "rotation").message,
              HasSubstr("rotation = 10000"));
  // MORSE's own message for a negative speed is kept, word for word
  EXPECT_EQ(call("human", "move", {-1.0, 0.0}).value,
            json("Our human cannot walk at negative speed!"));
}

TEST_F(SimBoundsTest, HumanMoveRefusesAStepOutOfTheWorld) {
  ASSERT_EQ(call("human", "move", {999000.0, 0.0}).status, Status::success);  // x = -2 + 999000
  const Eigen::Vector3d before = position_of("human");
  Outcome o = refused("human", "move", {5000.0, 0.0}, "speed");
  EXPECT_THAT(o.message, HasSubstr("speed = 5000 would take body 'human' to x = 1.004e+06, beyond "
                                   "the world bound ±1e+06 m"));
  EXPECT_EQ(position_of("human"), before);
}

TEST_F(SimBoundsTest, TeleportTranslateRefusesHugeAndNonFiniteDisplacements) {
  const Eigen::Vector3d before = position_of("robot");
  EXPECT_EQ(refused("robot.teleport", "translate", {1e308, 0.0, 0.0}, "x").message,
            "x = 1e+308 is out of bounds: expected a finite number within ±1e+06 m");
  EXPECT_THAT(refused("robot.teleport", "translate", {0.0, k_nan}, "y").message,
              HasSubstr("y = nan"));
  EXPECT_THAT(refused("robot.teleport", "translate", json{{"x", 0.0}, {"z", -k_inf}}, "z").message,
              HasSubstr("z = -inf"));
  EXPECT_EQ(position_of("robot"), before);
}

TEST_F(SimBoundsTest, TeleportTranslateRefusesToLeaveTheWorldStepByStep) {
  // each displacement is in bounds; the third would end beyond the world's edge
  ASSERT_EQ(call("robot.teleport", "translate", {0.0, 600000.0}).status, Status::success);
  ASSERT_EQ(call("robot.teleport", "translate", {0.0, 300000.0}).status, Status::success);
  const Eigen::Vector3d before = position_of("robot");
  Outcome o = refused("robot.teleport", "translate", {0.0, 300000.0}, "y");
  EXPECT_THAT(
      o.message,
      HasSubstr(
          "y = 300000 would take body 'robot' to y = 1.2e+06, beyond the world bound ±1e+06 m"));
  EXPECT_EQ(position_of("robot"), before);
}

TEST_F(SimBoundsTest, TeleportRotateRefusesHugeAngles) {
  EXPECT_EQ(refused("robot.teleport", "rotate", {0.0, 0.0, 1e300}, "yaw").message,
            "yaw = 1e+300 is out of bounds: expected a finite number within ±1000 rad");
  EXPECT_THAT(refused("robot.teleport", "rotate", {k_nan}, "roll").message,
              HasSubstr("roll = nan"));
  EXPECT_EQ(call("robot.teleport", "rotate", {0.0, 0.0, 1000.0}).status,
            Status::success);  // the bound itself
}

TEST_F(SimBoundsTest, SetSpeedRefusesHugeSpeedsInsteadOfScalingThemDown) {
  EXPECT_EQ(refused("robot.motion", "set_speed", {1e300, 0.0}, "v").message,
            "v = 1e+300 is out of bounds: expected a finite number within ±1000 m/s");
  EXPECT_EQ(refused("robot.motion", "set_speed", {0.0, -1e9}, "w").message,
            "w = -1e+09 is out of bounds: expected a finite number within ±1000 rad/s");
  EXPECT_THAT(refused("robot.motion", "set_speed", {k_inf, 0.0}, "v").message,
              HasSubstr("v = inf"));
  // nothing was commanded: the robot stays put
  run_for(0.5);
  EXPECT_NEAR(pose()["x"].get<double>(), 0.0, 0.01);
  // in bounds: accepted (the wheels' own limit then scales it, as documented)
  EXPECT_EQ(call("robot.motion", "set_speed", {1000.0, -1000.0}).status, Status::success);
}

TEST_F(SimBoundsTest, WaypointRefusesTargetsAndSpeedsOutOfBounds) {
  EXPECT_EQ(refused("robot.waypoint", "goto", {1e300, 0.0, 0.0}, "x").message,
            "x = 1e+300 is out of bounds: expected a finite number within ±1e+06 m");
  EXPECT_THAT(refused("robot.waypoint", "goto", {1.0, k_nan, 0.0}, "y").message,
              HasSubstr("y = nan"));
  EXPECT_THAT(
      refused("robot.waypoint", "goto", {1.0, 0.0, 0.0, 0.5, 1e9}, "speed").message,
      HasSubstr("speed = 1e+09 is out of bounds: expected a finite number from 0 to 1000 m/s"));
  EXPECT_THAT(refused("robot.waypoint", "goto", {1.0, 0.0, 0.0, 0.5, 0.0}, "speed").message,
              HasSubstr("speed must be positive"));
  EXPECT_THAT(refused("robot.waypoint", "goto", {1.0, 0.0, 0.0, -1.0}, "tolerance").message,
              HasSubstr("tolerance = -1 is out of bounds"));
  EXPECT_THAT(refused("robot.waypoint", "setdest", {0.0, 0.0, k_inf}, "z").message,
              HasSubstr("z = inf"));
  // nothing started: no goto runs, the status is unchanged
  EXPECT_FALSE(sim_->find("robot.waypoint")->component->has_running_request());
  EXPECT_EQ(call("robot.waypoint", "get_status").value, json("Arrived"));
}

TEST_F(SimBoundsTest, InBoundsValuesAreAcceptedAsBefore) {
  EXPECT_EQ(call("robot.teleport", "translate", {1000000.0}).status,
            Status::success);  // the bound itself
  EXPECT_EQ(call("robot.teleport", "translate", {-1000000.0}).status, Status::success);
  EXPECT_EQ(call("human", "move", {0.0, -1000.0}).status, Status::success);
  EXPECT_EQ(call("robot.waypoint", "setdest", {-1e6, 1e6, 0.0, 0.0, 1000.0}).status,
            Status::success);
}

}  // namespace
}  // namespace simgate::sim
