// ArmatureTest: MORSE's armature services on an inline two-link arm (servo-driven hinges, a
// kinematic slide joint), stepped in simulated time: instant sets, rotations at a speed,
// trajectories (linear and Hermite), preemption, cancel, reset, and every bad input refused
// before it reaches MuJoCo.
#include <limits>

#include "armature_fixture.h"

namespace simgate::sim {
namespace {

using testing::ArmatureSim;
using ::testing::HasSubstr;
using testing::message;

using testing::k_inf;
using testing::k_nan;

class ArmatureTest : public ArmatureSim {
 protected:
  void SetUp() override { build_arm(); }
};

// Cubic Hermite between (0, p0, v0) and (h, p1, v1), at time t: the textbook formula.
double hermite(double p0, double v0, double p1, double v1, double h, double t) {
  const double s = t / h;
  return (2 * s * s * s - 3 * s * s + 1) * p0 + (s * s * s - 2 * s * s + s) * h * v0 +
         (-2 * s * s * s + 3 * s * s) * p1 + (s * s * s - s * s) * h * v1;
}

TEST_F(ArmatureTest, ListsTheSubtreeHingeAndSlideJointsFromRootToTip) {
  // the free box is not part of the arm
  EXPECT_EQ(arm("get_joints").value, json({"shoulder", "elbow", "slider"}));
  json dofs = *arm("get_dofs").value;
  EXPECT_EQ(dofs["shoulder"], json({0.0, 0.0, 1.0}));
  EXPECT_EQ(dofs["slider"], json({1.0, 0.0, 0.0}));
  EXPECT_EQ(arm("get_IK_limits", {"slider"}).value, json({0.0, 0.1}));
  EXPECT_EQ(arm("list_IK_targets").value, json::array());
  EXPECT_EQ(arm("get_properties").value->at("properties")["radial_speed"], 0.8);
}

TEST_F(ArmatureTest, SetRotationAndTranslationMoveAtOnceAndHold) {
  ASSERT_EQ(arm("set_rotation", {"elbow", 0.7}).status, Status::success);
  ASSERT_EQ(arm("set_translation", {"slider", 0.05}).status, Status::success);
  EXPECT_DOUBLE_EQ(qpos("elbow"), 0.7);
  EXPECT_DOUBLE_EQ(ctrl("elbow_servo"), 0.7);  // its servo holds it there
  EXPECT_DOUBLE_EQ(qpos("slider"), 0.05);
  run_for(1.0);
  EXPECT_NEAR(qpos("elbow"), 0.7, 0.01);
  EXPECT_NEAR(qpos("slider"), 0.05, 1e-6);  // held kinematically
}

TEST_F(ArmatureTest, SetRotationsTakesAListInJointOrderOrAnObject) {
  ASSERT_EQ(arm("set_rotations", {json{0.3, -0.4}}).status, Status::success);
  EXPECT_DOUBLE_EQ(qpos("shoulder"), 0.3);
  EXPECT_DOUBLE_EQ(qpos("elbow"), -0.4);
  ASSERT_EQ(arm("set_rotations", {json{{"elbow", 0.2}}}).status, Status::success);
  EXPECT_DOUBLE_EQ(qpos("shoulder"), 0.3);
  EXPECT_DOUBLE_EQ(qpos("elbow"), 0.2);
  ASSERT_EQ(arm("set_translations", {json{{"slider", 0.02}}}).status, Status::success);
  EXPECT_DOUBLE_EQ(qpos("slider"), 0.02);
}

TEST_F(ArmatureTest, TranslateReachesTheTargetWhenItsSpeedSaysAndNotBefore) {
  // kinematic: 0.08 m at 0.04 m/s takes exactly 2 s
  const double t0 = sim_->sim_time();
  RequestId id = start("translate", {"slider", 0.08, 0.04});
  run_until(t0 + 1.0);
  EXPECT_NEAR(qpos("slider"), 0.04, 1e-5);
  EXPECT_NEAR(qvel("slider"), 0.04, 1e-3);
  run_until(t0 + 1.99);
  EXPECT_FALSE(rm_->outcome(id).has_value());
  auto done = run_until_answered(id, 0.02);
  ASSERT_TRUE(done.has_value());
  EXPECT_EQ(done->status, Status::success);
  EXPECT_GE(sim_->sim_time(), t0 + 2.0 - 1e-9);
  EXPECT_NEAR(qpos("slider"), 0.08, 1e-5);
}

TEST_F(ArmatureTest, RotateDrivesTheServoAlongTheRampThenWaitsForArrival) {
  // 1 rad at 0.5 rad/s: the servo's target ramps for 2 s, the joint follows with a lag
  const double t0 = sim_->sim_time();
  RequestId id = start("rotate", {"shoulder", 1.0, 0.5});
  run_until(t0 + 1.0);
  EXPECT_NEAR(ctrl("shoulder_servo"), 0.5, 1e-9);
  EXPECT_NEAR(qpos("shoulder"), 0.5, 0.1);
  run_until(t0 + 1.99);
  EXPECT_FALSE(rm_->outcome(id).has_value());
  auto done = run_until_answered(id, 2.0);
  ASSERT_TRUE(done.has_value());
  EXPECT_EQ(done->status, Status::success);
  EXPECT_NEAR(qpos("shoulder"), 1.0, 0.01);
  run_for(1.0);  // and stays there
  EXPECT_NEAR(qpos("shoulder"), 1.0, 0.01);
}

TEST_F(ArmatureTest, AServoJointThatHasNotArrivedBySettleTimeoutFailsNamingIt) {
  // the servo lags its ramp by about damping * speed / kp = 0.03 rad: with no time to
  // settle, the motion's end finds the shoulder short of its target
  ASSERT_EQ(arm("set_property", {"settle_timeout", 0.0}).status, Status::success);
  const double t0 = sim_->sim_time();
  RequestId id = start("rotate", {"shoulder", 1.0, 0.5});
  auto o = run_until_answered(id, 2.1);
  ASSERT_TRUE(o.has_value());
  EXPECT_EQ(o->status, Status::failed);
  EXPECT_GE(sim_->sim_time(), t0 + 2.0 - 1e-9);
  EXPECT_THAT(message(*o), HasSubstr("joint 'shoulder' is at 0.9"));
  EXPECT_THAT(message(*o), HasSubstr("rad, target 1 (0 s after the motion's end"));
  // it stays commanded to its target, and gets there
  run_for(1.0);
  EXPECT_NEAR(qpos("shoulder"), 1.0, 0.01);
}

TEST_F(ArmatureTest, RotateJointsMovesEachJointAtTheSpeedAndEndsWithTheLast) {
  const double t0 = sim_->sim_time();
  RequestId id = start("rotate_joints", {json{{"shoulder", 0.6}, {"elbow", -0.3}}, 0.3});
  run_until(t0 + 1.0);
  EXPECT_NEAR(ctrl("elbow_servo"), -0.3, 1e-9);    // arrived after 1 s
  EXPECT_NEAR(ctrl("shoulder_servo"), 0.3, 1e-9);  // half way
  run_until(t0 + 1.99);
  EXPECT_FALSE(rm_->outcome(id).has_value());
  auto done = run_until_answered(id, 2.0);
  ASSERT_TRUE(done.has_value());
  EXPECT_EQ(done->status, Status::success);
  EXPECT_NEAR(qpos("shoulder"), 0.6, 0.01);
  EXPECT_NEAR(qpos("elbow"), -0.3, 0.01);
}

TEST_F(ArmatureTest, WithoutASpeedRotationsUseRadialSpeed) {
  ASSERT_EQ(arm("set_property", {"linear_speed", 0.1}).status, Status::success);
  const double t0 = sim_->sim_time();
  RequestId id = start("translate", {"slider", 0.05});  // 0.5 s at 0.1 m/s
  run_until(t0 + 0.25);
  EXPECT_NEAR(qpos("slider"), 0.025, 1e-5);
  auto done = run_until_answered(id, 0.5);
  ASSERT_TRUE(done.has_value());
  EXPECT_EQ(done->status, Status::success);
  // rotate: MORSE's radial_speed, 0.8 rad/s
  RequestId rotate = start("rotate", {"elbow", 0.4, nullptr});
  const double t1 = sim_->sim_time();
  run_until(t1 + 0.25);
  EXPECT_NEAR(ctrl("elbow_servo"), 0.2, 1e-9);
  EXPECT_TRUE(run_until_answered(rotate, 2.5).has_value());
}

TEST_F(ArmatureTest, ASecondRotatePreemptsTheFirstWhichHoldsWhereItWas) {
  RequestId first = start("rotate", {"shoulder", 1.0, 0.5});
  run_for(0.5);
  const double at_preemption = qpos("shoulder");
  RequestId second = start("rotate", {"elbow", 0.3, 1.0});
  auto preempted = rm_->outcome(first);
  ASSERT_TRUE(preempted.has_value());
  EXPECT_EQ(preempted->status, Status::preempted);
  EXPECT_EQ(preempted->failure, Failure::preempted);
  EXPECT_DOUBLE_EQ(ctrl("shoulder_servo"), at_preemption);
  auto done = run_until_answered(second, 3.0);
  ASSERT_TRUE(done.has_value());
  EXPECT_EQ(done->status, Status::success);
  EXPECT_NEAR(qpos("shoulder"), at_preemption, 0.01);
  EXPECT_NEAR(qpos("elbow"), 0.3, 0.01);
}

TEST_F(ArmatureTest, CancelHoldsTheJointWhereItIs) {
  const double t0 = sim_->sim_time();
  RequestId id = start("translate", {"slider", 0.1, 0.02});
  run_until(t0 + 1.0);
  rm_->cancel(id);
  sim_->process_requests();
  auto o = rm_->outcome(id);
  ASSERT_TRUE(o.has_value());
  EXPECT_EQ(o->status, Status::preempted);
  EXPECT_EQ(o->failure, Failure::cancelled);
  const double held = qpos("slider");
  EXPECT_NEAR(held, 0.02, 1e-5);
  run_for(1.0);
  EXPECT_NEAR(qpos("slider"), held, 1e-6);
}

TEST_F(ArmatureTest, TrajectoryInterpolatesLinearlyInSimulatedTime) {
  const double t0 = sim_->sim_time();
  json trajectory = {{"points",
                      {{{"positions", {0.4, -0.4, 0.05}}, {"time_from_start", 1.0}},
                       {{"positions", {0.8, 0.0, 0.1}}, {"time_from_start", 2.0}}}}};
  RequestId id = start("trajectory", {trajectory});
  run_until(t0 + 0.5);
  EXPECT_NEAR(qpos("slider"), 0.025, 1e-5);        // kinematic: on the path
  EXPECT_NEAR(ctrl("shoulder_servo"), 0.2, 1e-9);  // servo: its target on the path
  EXPECT_NEAR(ctrl("elbow_servo"), -0.2, 1e-9);
  run_until(t0 + 1.5);
  EXPECT_NEAR(qpos("slider"), 0.075, 1e-5);
  EXPECT_NEAR(ctrl("shoulder_servo"), 0.6, 1e-9);
  EXPECT_NEAR(ctrl("elbow_servo"), -0.2, 1e-9);
  run_until(t0 + 1.99);
  EXPECT_FALSE(rm_->outcome(id).has_value());
  auto done = run_until_answered(id, 2.0);
  ASSERT_TRUE(done.has_value());
  EXPECT_EQ(done->status, Status::success);
  EXPECT_NEAR(qpos("shoulder"), 0.8, 0.01);
  EXPECT_NEAR(qpos("elbow"), 0.0, 0.01);
  EXPECT_NEAR(qpos("slider"), 0.1, 1e-5);
}

TEST_F(ArmatureTest, TrajectoryWithVelocitiesIsCubicHermite) {
  const double t0 = sim_->sim_time();
  json trajectory = {{"points",
                      {{{"positions", {0.0, 0.0, 0.05}},
                        {"velocities", {0.0, 0.0, 0.1}},
                        {"time_from_start", 1.0}},
                       {{"positions", {0.0, 0.0, 0.1}},
                        {"velocities", {0.0, 0.0, 0.0}},
                        {"time_from_start", 2.0}}}}};
  RequestId id = start("trajectory", {trajectory});
  for (double t : {0.25, 0.5, 0.75, 1.25, 1.5, 1.75}) {
    run_until(t0 + t);
    const double expected =
        t < 1 ? hermite(0.0, 0.0, 0.05, 0.1, 1.0, t) : hermite(0.05, 0.1, 0.1, 0.0, 1.0, t - 1);
    EXPECT_NEAR(qpos("slider"), expected, 1e-5) << "t = " << t;
  }
  EXPECT_NE(hermite(0.0, 0.0, 0.05, 0.1, 1.0, 0.5), 0.025);  // not the linear path
  auto done = run_until_answered(id, 1.0);
  ASSERT_TRUE(done.has_value());
  EXPECT_EQ(done->status, Status::success);
}

TEST_F(ArmatureTest, TrajectoryStartsAtStarttimeOnTheClockOfTimeNow) {
  const double now = call("time", "now").value->get<double>();
  const double t0 = sim_->sim_time();
  json trajectory = {{"starttime", now + 1.0},
                     {"joint_names", {"slider"}},
                     {"points", {{{"positions", {0.1}}, {"time_from_start", 1.0}}}}};
  RequestId id = start("trajectory", {trajectory});
  run_until(t0 + 0.9);
  EXPECT_NEAR(qpos("slider"), 0.0, 1e-6);
  run_until(t0 + 1.5);
  EXPECT_NEAR(qpos("slider"), 0.05, 1e-5);
  auto done = run_until_answered(id, 1.0);
  ASSERT_TRUE(done.has_value());
  EXPECT_EQ(done->status, Status::success);
}

TEST_F(ArmatureTest, ATrajectoryIsNotPreemptedByANewRequest) {
  // MORSE: trajectory has no interruption policy; the transport's global one (reject) holds
  json trajectory = {{"points", {{{"positions", {0.1, 0.1, 0.01}}, {"time_from_start", 1.0}}}}};
  RequestId id = start("trajectory", {trajectory});
  Outcome refused = arm("rotate", {"elbow", 0.3});
  EXPECT_EQ(refused.status, Status::failed);
  EXPECT_EQ(refused.failure, Failure::busy);
  EXPECT_FALSE(rm_->outcome(id).has_value());
  // a joint the motion drives cannot be set under it either
  Outcome set = arm("set_rotation", {"elbow", 0.3});
  EXPECT_EQ(set.status, Status::failed);
  EXPECT_THAT(message(set), HasSubstr("joint 'elbow' is being moved by arm.arm.trajectory"));
}

TEST_F(ArmatureTest, ResetDropsTheMotionAndTheHolds) {
  RequestId id = start("rotate", {"shoulder", 1.0, 0.5});
  run_for(0.5);
  ASSERT_EQ(call("simulation", "reset_objects").status, Status::success);
  auto o = rm_->outcome(id);
  ASSERT_TRUE(o.has_value());
  EXPECT_EQ(o->status, Status::preempted);
  EXPECT_DOUBLE_EQ(qpos("shoulder"), 0.0);
  run_for(0.5);
  EXPECT_DOUBLE_EQ(ctrl("shoulder_servo"), 0.0);
  EXPECT_NEAR(qpos("shoulder"), 0.0, 1e-6);
}

// ---- bad input -----------------------------------------------------------------------------

struct BadCall {
  std::string service;
  json params;
  std::string expected;  // in the FAILED message
};

class ArmatureBadInputTest : public ArmatureTest {
 protected:
  // Each call ends FAILED with `expected` in its message, and MuJoCo's state is untouched.
  void expect_refused(const std::vector<BadCall>& calls) {
    const mjModel* m = sim_->m();
    for (const auto& c : calls) {
      std::vector<double> before(sim_->d()->qpos, sim_->d()->qpos + m->nq);
      before.insert(before.end(), sim_->d()->qvel, sim_->d()->qvel + m->nv);
      before.insert(before.end(), sim_->d()->ctrl, sim_->d()->ctrl + m->nu);
      RequestId id = rm_->call(arm_name_, c.service, c.params);
      sim_->process_requests();
      auto o = rm_->outcome(id);
      ASSERT_TRUE(o.has_value()) << c.service << " " << c.params.dump() << " did not end at once";
      EXPECT_EQ(o->status, Status::failed) << c.service << " " << c.params.dump();
      EXPECT_THAT(message(*o), HasSubstr(c.expected)) << c.service << " " << c.params.dump();
      std::vector<double> after(sim_->d()->qpos, sim_->d()->qpos + m->nq);
      after.insert(after.end(), sim_->d()->qvel, sim_->d()->qvel + m->nv);
      after.insert(after.end(), sim_->d()->ctrl, sim_->d()->ctrl + m->nu);
      EXPECT_EQ(before, after) << c.service << " " << c.params.dump() << " changed the state";
    }
    // the simulation goes on, with finite state
    const double t = sim_->sim_time();
    run_for(0.1);
    EXPECT_GT(sim_->sim_time(), t + 0.09);
    EXPECT_TRUE(state_is_finite());
    EXPECT_EQ(call("time", "statistics").value->at("bad_states"), 0);
  }
};

TEST_F(ArmatureBadInputTest, UnknownJointsAreRefusedNamingTheValidOnes) {
  const std::string valid = "(its joints: shoulder, elbow, slider)";
  expect_refused({
      {"rotate", {"elbw", 0.5}, "no joint 'elbw' in this armature; did you mean 'elbow'? " + valid},
      {"translate", {"slide", 0.01}, "did you mean 'slider'?"},
      {"set_rotation", {"wrist", 0.1}, "no joint 'wrist' in this armature " + valid},
      {"set_translation", {"wrist", 0.1}, valid},
      {"get_IK_limits", {"wrist"}, valid},
      {"rotate_joints", {json{{"wrist", 0.1}}}, valid},
      {"translate_joints", {json{{"wrist", 0.01}}}, valid},
      {"set_rotations", {json{{"wrist", 0.1}}}, valid},
      {"set_translations", {json{{"wrist", 0.01}}}, valid},
      {"trajectory",
       {json{{"joint_names", {"wrist"}},
             {"points", {{{"positions", {0.1}}, {"time_from_start", 1}}}}}},
       "joint_names[0]: no joint 'wrist'"},
  });
}

TEST_F(ArmatureBadInputTest, JointsOfTheWrongKindAreRefusedNamingTheirKind) {
  expect_refused({
      {"set_rotation", {"slider", 0.01}, "joint 'slider' is prismatic (a slide joint, metres)"},
      {"rotate", {"slider", 0.01}, "joint 'slider' is prismatic"},
      {"rotate_joints", {json{{"slider", 0.01}}}, "joint 'slider' is prismatic"},
      {"set_rotations", {json{0.1, 0.1, 0.01}}, "joint 'slider' is prismatic"},
      {"set_translation", {"elbow", 0.01}, "joint 'elbow' is revolute (a hinge joint, radians)"},
      {"translate", {"shoulder", 0.01}, "joint 'shoulder' is revolute"},
      {"translate_joints", {json{{"elbow", 0.01}}}, "joint 'elbow' is revolute"},
      {"set_translations", {json{0.01}}, "joint 'shoulder' is revolute"},
  });
}

TEST_F(ArmatureBadInputTest, NanAndInfinityAreRefusedForEveryNumber) {
  for (double bad : {k_nan, k_inf, -k_inf}) {
    auto point = [bad](const std::string& field) {
      json p = {{"positions", {0.1, 0.1, 0.01}}, {"time_from_start", 1.0}};
      if (field == "time_from_start")
        p[field] = bad;
      else if (field == "positions")
        p[field] = {0.1, bad, 0.01};
      else
        p[field] = {0.0, bad, 0.0};
      return json{{"points", {p}}};
    };
    expect_refused({
        {"set_rotation", {"elbow", bad}, "rotation = "},
        {"set_translation", {"slider", bad}, "translation = "},
        {"set_rotations", {json{0.1, bad}}, "rotations[1] = "},
        {"set_rotations", {json{{"elbow", bad}}}, "rotations.elbow = "},
        {"set_translations", {json{{"slider", bad}}}, "translations.slider = "},
        {"rotate", {"elbow", bad}, "rotation = "},
        {"rotate", {"elbow", 0.1, bad}, "speed = "},
        {"translate", {"slider", bad}, "translation = "},
        {"translate", {"slider", 0.01, bad}, "speed = "},
        {"rotate_joints", {json{{"elbow", bad}}}, "joint_rotations.elbow = "},
        {"rotate_joints", {json{{"elbow", 0.1}}, bad}, "speed = "},
        {"translate_joints", {json{{"slider", bad}}}, "joint_translations.slider = "},
        {"translate_joints", {json{{"slider", 0.01}}, bad}, "speed = "},
        {"trajectory", {point("time_from_start")}, "points[0].time_from_start = "},
        {"trajectory", {point("positions")}, "points[0].positions[1]: "},
        {"trajectory", {point("velocities")}, "points[0].velocities[1]: "},
        {"trajectory", {point("accelerations")}, "points[0].accelerations[1]: "},
        {"trajectory", {point("effort")}, "points[0].effort[1]: "},
        {"trajectory",
         {json{{"starttime", bad}, {"points", point("positions")["points"]}}},
         "starttime"},
        {"set_property", {"radial_speed", bad}, "radial_speed = "},
        {"set_property", {"linear_speed", bad}, "linear_speed = "},
        {"set_property", {"angle_tolerance", bad}, "angle_tolerance = "},
        {"set_property", {"distance_tolerance", bad}, "distance_tolerance = "},
        {"set_property", {"settle_timeout", bad}, "settle_timeout = "},
    });
  }
}

TEST_F(ArmatureBadInputTest, TargetsOutsideTheRangeAreRefusedNamingIt) {
  auto at = [](json positions) {
    return json{{"points", {{{"positions", positions}, {"time_from_start", 1}}}}};
  };
  expect_refused({
      {"set_rotation",
       {"elbow", 2.5},
       "rotation = 2.5 is outside the range of joint 'elbow': [-2, 2] rad"},
      {"rotate", {"elbow", -3.0}, "[-2, 2] rad"},
      {"set_translation",
       {"slider", 0.2},
       "translation = 0.2 is outside the range of joint 'slider': [0, 0.1] m"},
      {"translate_joints", {json{{"slider", -0.01}}}, "[0, 0.1] m"},
      // inside the joint's range, beyond its servo's ctrlrange
      {"set_rotation",
       {"shoulder", 1.3},
       "beyond what the position servo of joint 'shoulder' can reach: [-1.2, 1.2]"},
      {"trajectory",
       {at({0.1, 0.1, 0.5})},
       "points[0].positions[2] = 0.5 is outside the range of joint 'slider'"},
      {"rotate", {"elbow", 0.1, 0.0}, "speed must be positive"},
      {"rotate", {"elbow", 0.1, -1.0}, "speed = -1 is out of bounds"},
      {"rotate", {"elbow", 0.1, 1e6}, "speed = 1e+06 is out of bounds"},
  });
}

TEST_F(ArmatureBadInputTest, MalformedTrajectoriesAreRefusedNamingTheField) {
  auto point = [](json positions, double t) {
    return json{{"positions", positions}, {"time_from_start", t}};
  };
  const json p3 = {0.1, 0.1, 0.01};
  expect_refused({
      {"trajectory", {json{{"points", json::array()}}}, "points: empty"},
      {"trajectory", {json::object()}, "points: missing"},
      {"trajectory",
       {json{{"points", {point(p3, 1), point(p3, 1)}}}},
       "points[1].time_from_start: 1 is not after points[0].time_from_start (1): times must "
       "increase"},
      {"trajectory", {json{{"points", {point(p3, 2), point(p3, 1)}}}}, "points[1].time_from_start"},
      {"trajectory",
       {json{{"points", {point(p3, -1)}}}},
       "points[0].time_from_start = -1 is out of bounds"},
      {"trajectory",
       {json{{"points", {point(p3, 1), point({0.1, 0.1}, 2)}}}},
       "points[1].positions: has 2 values; expected 3 (one per joint: shoulder, elbow, slider)"},
      {"trajectory",
       {json{{"points", {point(p3, 1), point({0.1, 0.1, 0.01, 0.0}, 2)}}}},
       "has 4 values"},
      {"trajectory",
       {json{{"points", {json{{"time_from_start", 1}}}}}},
       "points[0].positions: missing"},
      {"trajectory",
       {json{{"points", {json{{"positions", p3}}}}}},
       "points[0].time_from_start: missing"},
      {"trajectory",
       {json{{"points", {json{{"positions", p3}, {"time_from_start", "1"}}}}}},
       "points[0].time_from_start: expected a number"},
      {"trajectory",
       {json{{"points",
              {json{{"positions", p3}, {"velocities", {0, 0, 0}}, {"time_from_start", 1}},
               point(p3, 2)}}}},
       "points[1].velocities: missing while points[0] has them"},
      {"trajectory",
       {json{{"points", {json{{"positions", p3}, {"time_from_star", 1}}}}}},
       "points[0].time_from_star: unknown field"},
      {"trajectory", {json{{"points", {point(p3, 1)}}, {"start", 0}}}, "start: unknown field"},
      {"trajectory",
       {json{{"points", {point({0.1, "x", 0.01}, 1)}}}},
       "points[0].positions[1]: expected a number"},
      {"trajectory", {json{{"points", "none"}}}, "points: expected an array"},
      {"trajectory", {json{1, 2}}, "trajectory: expected an object"},
      {"trajectory",
       {json{{"joint_names", {"elbow", "elbow"}}, {"points", {point({0.1, 0.1}, 1)}}}},
       "joint_names[1]: joint 'elbow' is named twice"},
      {"trajectory",
       {json{{"starttime", 1e12}, {"points", {point(p3, 1)}}}},
       "expected at most 1e+06 s ahead"},
      {"set_rotations",
       {json{0.1, 0.1, 0.01, 0.0}},
       "rotations has 4 values; this armature has 3 joints"},
      {"set_rotations", {json("0.1")}, "rotations: expected a list of rad"},
      {"set_rotations", {json::array()}, "rotations is empty"},
      {"rotate_joints", {json::object()}, "joint_rotations is empty"},
  });
}

}  // namespace
}  // namespace simgate::sim
