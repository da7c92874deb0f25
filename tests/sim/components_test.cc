// SimComponents: the built-in robot, actuators and sensors really move the robot through
// MuJoCo (wheels driven by actuators), with MORSE's service names, results and errors.
#include "sim_fixture.h"

namespace simgate::sim {
namespace {

using testing::DemoSim;
using ::testing::HasSubstr;

class SimComponentsTest : public DemoSim {};

TEST_F(SimComponentsTest, SetSpeedDrivesTheRobotThroughItsWheels) {
  EXPECT_EQ(call("robot.motion", "set_speed", {0.5, 0.0}).status, Status::success);
  run_for(2.0);
  json p = pose();
  EXPECT_NEAR(p["x"].get<double>(), 1.0, 0.15);
  EXPECT_NEAR(p["y"].get<double>(), 0.0, 0.05);
  // the wheels turn: the motion comes from the actuators, not from a teleport
  int joint = sim_->model().joint_id("robot_left_wheel_joint");
  EXPECT_GT(sim_->d()->qvel[sim_->m()->jnt_dofadr[joint]], 3.0);
}

TEST_F(SimComponentsTest, AngularSpeedTurnsCounterClockwise) {
  call("robot.motion", "set_speed", {0.0, 0.5});
  run_for(2.0);
  EXPECT_NEAR(pose()["yaw"].get<double>(), 1.0, 0.2);
}

TEST_F(SimComponentsTest, StopHaltsTheRobot) {
  call("robot.motion", "set_speed", {1.0, 0.0});
  run_for(1.0);
  EXPECT_EQ(call("robot.motion", "stop").status, Status::success);
  run_for(1.0);
  double x = pose()["x"].get<double>();
  run_for(1.0);
  EXPECT_NEAR(pose()["x"].get<double>(), x, 0.01);
}

TEST_F(SimComponentsTest, WrongArityFailsWithThePhrasePymorseMapsToTypeError) {
  Outcome o = call("robot.motion", "set_speed", {1.0});
  EXPECT_EQ(o.status, Status::failed);
  EXPECT_THAT(o.message, HasSubstr("wrong # of parameters"));
}

TEST_F(SimComponentsTest, NonNumericSpeedFails) {
  Outcome o = call("robot.motion", "set_speed", {"fast", 0});
  EXPECT_EQ(o.status, Status::failed);
  EXPECT_EQ(o.failure, Failure::bad_arguments);
}

TEST_F(SimComponentsTest, GotoArrivesAndCompletesWithArrived) {
  RequestId id = rm_->call("robot.waypoint", "goto", {2.0, 1.0, 0.0, 0.2, 1.0});
  sim_->process_requests();
  EXPECT_FALSE(rm_->outcome(id).has_value());  // async: still running
  EXPECT_EQ(call("robot.waypoint", "get_status").value, json("Transit"));
  auto o = step_until(id, 10000);  // 20 s of simulated time at most
  ASSERT_TRUE(o.has_value());
  EXPECT_EQ(o->status, Status::success);
  EXPECT_EQ(o->value, json("Arrived"));
  json p = pose();
  EXPECT_LT(std::hypot(p["x"].get<double>() - 2.0, p["y"].get<double>() - 1.0), 0.2 + 0.05);
  EXPECT_EQ(call("robot.waypoint", "get_status").value, json("Arrived"));
}

TEST_F(SimComponentsTest, GotoDefaultsToToleranceHalfAMetre) {
  RequestId id = rm_->call("robot.waypoint", "goto", {3.0, 0.0, 0.0});
  auto o = step_until(id, 10000);
  ASSERT_TRUE(o.has_value());
  EXPECT_EQ(o->status, Status::success);
  EXPECT_NEAR(pose()["x"].get<double>(), 2.5, 0.15);
}

TEST_F(SimComponentsTest, CancelPreemptsGotoAndStopsTheRobot) {
  RequestId id = rm_->call("robot.waypoint", "goto", {10.0, 0.0, 0.0});
  EXPECT_FALSE(step_until(id, 500).has_value());  // 1 s: under way
  double x_moving = pose()["x"].get<double>();
  EXPECT_GT(x_moving, 0.3);
  rm_->cancel(id);
  auto o = step_until(id, 10);
  ASSERT_TRUE(o.has_value());
  EXPECT_EQ(o->status, Status::preempted);
  EXPECT_EQ(o->failure, Failure::cancelled);
  run_for(1.0);  // braking
  double x = pose()["x"].get<double>();
  run_for(1.0);
  EXPECT_NEAR(pose()["x"].get<double>(), x, 0.01);
  EXPECT_LT(x, 3.0);
}

TEST_F(SimComponentsTest, SecondGotoPreemptsTheFirst) {
  RequestId first = rm_->call("robot.waypoint", "goto", {10.0, 0.0, 0.0});
  step_until(first, 100);
  RequestId second = rm_->call("robot.waypoint", "goto", {1.0, 0.0, 0.0, 0.2});
  sim_->process_requests();
  auto o1 = rm_->outcome(first);
  ASSERT_TRUE(o1.has_value());
  EXPECT_EQ(o1->status, Status::preempted);
  auto o2 = step_until(second, 5000);
  ASSERT_TRUE(o2.has_value());
  EXPECT_EQ(o2->status, Status::success);
  EXPECT_NEAR(pose()["x"].get<double>(), 1.0, 0.25);
}

TEST_F(SimComponentsTest, StopKeepsGotoPendingAndResumeContinues) {
  RequestId id = rm_->call("robot.waypoint", "goto", {2.0, 0.0, 0.0, 0.2});
  step_until(id, 300);
  EXPECT_EQ(call("robot.waypoint", "stop").value, json("Stop"));
  EXPECT_FALSE(step_until(id, 1000).has_value());  // pending, robot halted
  EXPECT_EQ(call("robot.waypoint", "get_status").value, json("Stop"));
  double x = pose()["x"].get<double>();
  run_for(0.5);
  EXPECT_NEAR(pose()["x"].get<double>(), x, 0.02);
  EXPECT_EQ(call("robot.waypoint", "resume").value, json("Transit"));
  auto o = step_until(id, 5000);
  ASSERT_TRUE(o.has_value());
  EXPECT_EQ(o->status, Status::success);
  EXPECT_EQ(call("robot.waypoint", "get_status").value, json("Arrived"));
}

TEST_F(SimComponentsTest, SetdestIsFalseWhenAlreadyThere) {
  EXPECT_EQ(call("robot.waypoint", "setdest", {0.1, 0.0, 0.0}).value, json(false));
  EXPECT_EQ(call("robot.waypoint", "setdest", {2.0, 0.0, 0.0}).value, json(true));
  run_for(3.0);
  EXPECT_EQ(call("robot.waypoint", "get_status").value, json("Arrived"));
}

TEST_F(SimComponentsTest, TeleportTranslatesAndRotates) {
  EXPECT_EQ(call("robot.teleport", "translate", {1.0, 2.0}).status, Status::success);
  json p = pose();
  EXPECT_NEAR(p["x"].get<double>(), 1.0, 1e-6);
  EXPECT_NEAR(p["y"].get<double>(), 2.0, 1e-6);
  EXPECT_EQ(call("robot.teleport", "rotate", {0.0, 0.0, 0.5}).status, Status::success);
  EXPECT_NEAR(pose()["yaw"].get<double>(), 0.5, 1e-6);
  EXPECT_EQ(call("robot.teleport", "translate", json::array()).status,
            Status::failed);  // x is required
}

TEST_F(SimComponentsTest, PoseReportsPositionAndOrientation) {
  json p = pose();
  for (auto key : {"x", "y", "z", "roll", "pitch", "yaw"}) EXPECT_TRUE(p.contains(key)) << key;
  EXPECT_NEAR(p["z"].get<double>(), 0.1, 0.01);
}

TEST_F(SimComponentsTest, HumanRefusesNegativeSpeed) {
  Outcome o = call("human", "move", {-1.0, 0.0});
  EXPECT_EQ(o.status, Status::failed);
  EXPECT_EQ(o.value, json("Our human cannot walk at negative speed!"));
}

TEST_F(SimComponentsTest, HumanMoveStepsForwardAndTurns) {
  int body = sim_->model().body_id("human");
  Eigen::Vector3d before = body_position(*sim_, body);
  EXPECT_EQ(call("human", "move", {1.0, 1.5707963}).status, Status::success);
  Eigen::Vector3d after = body_position(*sim_, body);
  EXPECT_NEAR(after.x() - before.x(), 1.0, 1e-6);
  EXPECT_NEAR(to_roll_pitch_yaw(body_orientation(*sim_, body)).z(), 1.5707963, 1e-5);
  call("human", "move", {1.0, 0.0});
  EXPECT_NEAR(body_position(*sim_, body).y() - after.y(), 1.0, 1e-5);  // now walking along +y
}

}  // namespace
}  // namespace simgate::sim
