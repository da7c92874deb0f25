// The `actuators` component: a robot's MJCF actuators driven by name through MuJoCo's
// controls, on an inline arm and on Debian's MuJoCo samples (muscles on tendons, the
// humanoid's motors, slider-cranks, adhesion); refusals leave every control as it was.
#include <cmath>
#include <limits>

#include "mjcf_fixture.h"
#include "simgate/sim/actuator_kind.h"

namespace simgate::sim {
namespace {

using ::testing::HasSubstr;
using testing::MjcfSim;
using testing::mujoco_sample;
using testing::test_model;

class ActuatorSetTest : public MjcfSim {
 protected:
  void SetUp() override {
    load_string(testing::arm_and_block_xml());
    Robot& arm = add_robot("arm", "base");
    add_robot("block", "block");
    add_component(arm, "actuators", "actuators");
    serve();
  }
};

TEST_F(ActuatorSetTest, ListActuatorsSaysTypeTargetAndRanges) {
  json list = value("arm.actuators", "list_actuators");
  EXPECT_EQ(list["shoulder_servo"], json({{"type", "position"},
                                          {"joint", "shoulder"},
                                          {"ctrlrange", {-1.5, 1.5}},
                                          {"forcerange", nullptr},
                                          {"gear", 1.0},
                                          {"index", 0}}));
  EXPECT_EQ(list["elbow_motor"]["type"], "motor");
  EXPECT_EQ(list["elbow_motor"]["index"], 1);  // its place in MuJoCo's ctrl
  EXPECT_EQ(list["motor_1"]["index"], 2);
  EXPECT_EQ(list["elbow_motor"]["forcerange"], json({-5.0, 5.0}));
  // unnamed: its type and its rank among the model's motors (elbow_motor is motor 0)
  EXPECT_EQ(list["motor_1"]["joint"], "finger_slide");
  EXPECT_EQ(list["motor_1"]["ctrlrange"], nullptr);
  EXPECT_EQ(list.size(), 3u);
}

TEST_F(ActuatorSetTest, PropertiesNameAndCountTheActuators) {
  json p = value("arm.actuators", "get_properties")["properties"];
  EXPECT_EQ(p["actuators"], json({"shoulder_servo", "elbow_motor", "motor_1"}));
  EXPECT_EQ(p["count"], 3);
}

TEST_F(ActuatorSetTest, PositionServoBringsItsJointToTheTarget) {
  EXPECT_EQ(call("arm.actuators", "set_controls", {{{"shoulder_servo", 0.8}}}).status,
            Status::success);
  EXPECT_EQ(ctrl("shoulder_servo"), 0.8);
  // the servo's force is kp times the error, on the state the step starts from
  const double before = qpos("shoulder");
  sim_->step();
  EXPECT_NEAR(sim_->d()->actuator_force[0], 20 * (0.8 - before), 1e-9);
  // overdamped (damping 2 against kp 20: a time constant near 0.1 s): there after 3 s
  run_for(3.0);
  EXPECT_NEAR(qpos("shoulder"), 0.8, 1e-3);
  EXPECT_NEAR(qvel("shoulder"), 0.0, 1e-3);
}

TEST_F(ActuatorSetTest, MotorTorqueThatCancelsGravityHoldsTheArm) {
  // gravity about the elbow: 9.81 * (0.5 kg at 0.15 m + 0.1 kg at 0.3 m), as MuJoCo's bias
  const int elbow_dof = sim_->m()->jnt_dofadr[sim_->model().joint_id("elbow")];
  const double holding = sim_->d()->qfrc_bias[elbow_dof];
  EXPECT_NEAR(holding, -9.81 * (0.5 * 0.15 + 0.1 * 0.3), 1e-6);
  EXPECT_EQ(call("arm.actuators", "set_control", {"elbow_motor", holding}).status, Status::success);
  run_for(1.0);
  EXPECT_NEAR(qpos("elbow"), 0.0, 1e-3);
  EXPECT_NEAR(sim_->d()->actuator_force[1], holding, 1e-9);
  // without it, the arm falls
  EXPECT_EQ(call("arm.actuators", "set_control", {"elbow_motor", 0.0}).status, Status::success);
  run_for(0.5);
  EXPECT_GT(qpos("elbow"), 0.5);
}

TEST_F(ActuatorSetTest, GetControlsReadsEveryControl) {
  call("arm.actuators", "set_controls", {{{"shoulder_servo", 0.25}, {"motor_1", -3.0}}});
  EXPECT_EQ(value("arm.actuators", "get_controls"),
            json({{"shoulder_servo", 0.25}, {"elbow_motor", 0.0}, {"motor_1", -3.0}}));
}

TEST_F(ActuatorSetTest, OutOfRangeIsRefusedNamingActuatorValueAndRangeAndNothingIsApplied) {
  Outcome o =
      call("arm.actuators", "set_controls", {{{"shoulder_servo", 0.5}, {"elbow_motor", 3.0}}});
  EXPECT_EQ(o.status, Status::failed);
  EXPECT_EQ(o.failure, Failure::bad_arguments);
  EXPECT_THAT(
      o.message,
      HasSubstr("controls.elbow_motor = 3 is out of bounds: expected a finite number from -2 to "
                "2 (the ctrlrange of actuator 'elbow_motor')"));
  // the valid one was not applied either
  EXPECT_EQ(ctrl("shoulder_servo"), 0.0);
  EXPECT_EQ(ctrl("elbow_motor"), 0.0);
  // one at a time alike, the bound itself accepted
  EXPECT_THAT(
      call("arm.actuators", "set_control", {"shoulder_servo", -1.6}).message,
      HasSubstr("value = -1.6 is out of bounds: expected a finite number from -1.5 to 1.5"));
  EXPECT_EQ(call("arm.actuators", "set_control", {"shoulder_servo", -1.5}).status, Status::success);
}

TEST_F(ActuatorSetTest, UnknownNamesFailNamingTheValidOnes) {
  Outcome o =
      call("arm.actuators", "set_controls", {{{"sholder_servo", 0.1}, {"elbow_motor", 1.0}}});
  EXPECT_EQ(o.status, Status::failed);
  EXPECT_EQ(o.failure, Failure::bad_arguments);
  EXPECT_THAT(o.message,
              HasSubstr("no actuator 'sholder_servo' in arm.actuators (actuators: shoulder_servo, "
                        "elbow_motor, motor_1) (did you mean 'shoulder_servo'?)"));
  EXPECT_EQ(ctrl("elbow_motor"), 0.0);
  EXPECT_THAT(call("arm.actuators", "set_control", {"wrist", 0.1}).message,
              HasSubstr("no actuator 'wrist'"));
}

TEST_F(ActuatorSetTest, AControlWithoutRangeIsBoundedBySanity) {
  EXPECT_EQ(call("arm.actuators", "set_control", {"motor_1", 1e5}).status, Status::success);
  Outcome o = call("arm.actuators", "set_control", {"motor_1", 1e7});
  EXPECT_EQ(o.status, Status::failed);
  EXPECT_THAT(
      o.message,
      HasSubstr("value = 1e+07 is out of bounds: expected a finite number within ±1e+06 (actuator "
                "'motor_1' has no ctrlrange"));
  EXPECT_EQ(sim_->d()->ctrl[2], 1e5);  // motor_1 is unnamed in the MJCF
}

TEST_F(ActuatorSetTest, NonFiniteAndNonNumericValuesNeverReachMuJoCo) {
  const double nan = std::numeric_limits<double>::quiet_NaN(),
               inf = std::numeric_limits<double>::infinity();
  for (const std::string name : {"shoulder_servo", "elbow_motor", "motor_1"}) {
    for (double bad : {nan, inf, -inf}) {
      EXPECT_EQ(call("arm.actuators", "set_control", {name, bad}).status, Status::failed)
          << name << " " << bad;
      EXPECT_EQ(call("arm.actuators", "set_controls", {{{name, bad}}}).status, Status::failed)
          << name << " " << bad;
    }
    EXPECT_EQ(call("arm.actuators", "set_controls", {{{name, "fast"}}}).failure,
              Failure::bad_arguments);
    EXPECT_EQ(call("arm.actuators", "set_controls", {{{name, json::array({1.0})}}}).failure,
              Failure::bad_arguments);
  }
  // a list where a map is expected, a missing value, a name that is not a string
  EXPECT_EQ(call("arm.actuators", "set_controls", {json::array({0.1, 0.2})}).status,
            Status::failed);
  EXPECT_EQ(call("arm.actuators", "set_control", {"elbow_motor"}).status, Status::failed);
  EXPECT_EQ(call("arm.actuators", "set_control", {1, 0.1}).status, Status::failed);
  EXPECT_TRUE(state_is_finite());
  const double before = sim_->sim_time();
  run_for(0.1);
  EXPECT_GT(sim_->sim_time(), before + 0.09);
  EXPECT_TRUE(state_is_finite());
  EXPECT_EQ(value("arm.actuators", "get_controls"),
            json({{"shoulder_servo", 0.0}, {"elbow_motor", 0.0}, {"motor_1", 0.0}}));
}

TEST_F(ActuatorSetTest, ResetObjectsSetsEveryControlBackToZero) {
  call("arm.actuators", "set_controls", {{{"shoulder_servo", 1.0}, {"elbow_motor", 1.0}}});
  run_for(0.2);
  EXPECT_EQ(call("simulation", "reset_objects").status, Status::success);
  EXPECT_EQ(value("arm.actuators", "get_controls"),
            json({{"shoulder_servo", 0.0}, {"elbow_motor", 0.0}, {"motor_1", 0.0}}));
}

// ---- configuration ---------------------------------------------------------------------------

class ActuatorSetConfigTest : public MjcfSim {
 protected:
  void SetUp() override { load_string(testing::arm_and_block_xml()); }
};

TEST_F(ActuatorSetConfigTest, OptionActuatorsRestrictsTheSet) {
  Robot& arm = add_robot("arm", "base");
  add_component(arm, "servo", "actuators", {{"actuators", {"shoulder_servo"}}});
  serve();
  EXPECT_EQ(value("arm.servo", "get_controls"), json({{"shoulder_servo", 0.0}}));
  EXPECT_THAT(call("arm.servo", "set_control", {"elbow_motor", 1.0}).message,
              HasSubstr("(actuators: shoulder_servo)"));
}

TEST_F(ActuatorSetConfigTest, UnknownListedNamesAreConfigErrorsWithTheirPath) {
  Robot& arm = add_robot("arm", "base");
  EXPECT_THAT(
      config_error(arm, "actuators", {{"actuators", {"shoulder_servo", "elbow_motr"}}}),
      HasSubstr(
          "robots[0].components[9].options.actuators[1]: expected the name of an actuator of robot "
          "'arm' (body 'base') (shoulder_servo, elbow_motor, motor_1), found 'elbow_motr' (no such "
          "actuator (did you mean 'elbow_motor'?))"));
  EXPECT_THAT(config_error(arm, "actuators", {{"actuators", json::array()}}),
              HasSubstr("options.actuators: expected a non-empty list of actuator names"));
  EXPECT_THAT(config_error(arm, "actuators", {{"actuators", "shoulder_servo"}}),
              HasSubstr("expected a non-empty list of actuator names, found string"));
  EXPECT_THAT(config_error(arm, "actuators", {{"actuators", {"elbow_motor", "elbow_motor"}}}),
              HasSubstr("actuators[1]: actuator 'elbow_motor' is listed twice"));
  EXPECT_THAT(config_error(arm, "actuators", {{"actuator", {"elbow_motor"}}}),
              HasSubstr("options.actuator: unknown key (did you mean 'actuators'?"));
}

TEST_F(ActuatorSetConfigTest, AnotherRobotsActuatorsAreNotItsOwn) {
  Robot& block = add_robot("block", "block");
  EXPECT_THAT(config_error(block, "actuators"),
              HasSubstr("needs actuators, and robot 'block' (body 'block') has none"));
  EXPECT_THAT(
      config_error(block, "actuators", {{"actuators", {"elbow_motor"}}}),
      HasSubstr(
          "actuators[0]: actuator 'elbow_motor' drives joint 'elbow', outside robot 'block'"));
}

TEST_F(ActuatorSetConfigTest, AGeneratedNameTakenByAnotherActuatorIsAConfigError) {
  sim_.reset();
  load_string(
      R"(<mujoco><worldbody><body name="b"><joint name="j"/><geom size="0.1"/></body></worldbody>
    <actuator><motor name="motor_1" joint="j"/><motor joint="j"/></actuator></mujoco>)");
  Robot& robot = add_robot("r", "b");
  EXPECT_THAT(config_error(robot, "actuators"), HasSubstr("are both called 'motor_1'"));
}

// ---- Debian's MuJoCo samples -----------------------------------------------------------------

TEST_F(MjcfSim, TendonArmMusclesPullOnTheirTendonsWithinTheirRange) {
  load_file(test_model("tendon_arm.xml"));
  Robot& arm = add_robot("arm", "#1");  // the arm's root body has no name
  add_component(arm, "actuators", "actuators");
  serve();
  json list = value("arm.actuators", "list_actuators");
  ASSERT_EQ(list.size(), 6u);
  EXPECT_EQ(list["SF"]["type"], "muscle");
  EXPECT_EQ(list["SF"]["tendon"], "SF");
  EXPECT_EQ(list["SF"]["ctrlrange"], json({0.0, 1.0}));
  // refused below the range, then the shoulder flexor bends the shoulder (counter-clockwise)
  EXPECT_EQ(call("arm.actuators", "set_controls", {{{"SF", -0.5}}}).status, Status::failed);
  const double start = qpos("shoulder");
  EXPECT_EQ(call("arm.actuators", "set_controls", {{{"SF", 1.0}}}).status, Status::success);
  run_for(1.0);
  EXPECT_GT(qpos("shoulder"), start + 0.2);
}

TEST_F(MjcfSim, HumanoidMotorsAreTheTorsosActuators) {
  load_file(mujoco_sample("humanoid/humanoid.xml"));
  Robot& humanoid = add_robot("humanoid", "torso");
  add_component(humanoid, "actuators", "actuators");
  serve();
  json list = value("humanoid.actuators", "list_actuators");
  EXPECT_EQ(static_cast<int>(list.size()), sim_->m()->nu);
  json controls = json::object();
  for (auto it = list.begin(); it != list.end(); ++it) {
    EXPECT_EQ(it.value()["type"], "motor") << it.key();
    EXPECT_EQ(it.value()["ctrlrange"], json({-1.0, 1.0})) << it.key();
    controls[it.key()] = 0.4;
  }
  EXPECT_EQ(call("humanoid.actuators", "set_controls", {controls}).status, Status::success);
  for (int a = 0; a < sim_->m()->nu; ++a) EXPECT_EQ(sim_->d()->ctrl[a], 0.4);
  run_for(0.2);
  EXPECT_TRUE(state_is_finite());
}

TEST_F(MjcfSim, SliderCranksBelongToTheBodyOfTheirCrank) {
  load_file(mujoco_sample("slider_crank/slider_crank.xml"));
  Robot& first = add_robot("crank", "#1");
  Robot& third = add_robot("broken", "#3");
  add_component(first, "actuators", "actuators");
  add_component(third, "actuators", "actuators");
  serve();
  json list = value("crank.actuators", "list_actuators");
  EXPECT_EQ(list.size(), 2u);
  EXPECT_EQ(list["forward"]["type"], "position");
  EXPECT_EQ(list["forward"]["site"], "cranksite");
  EXPECT_EQ(list["forward"]["slidersite"], "slidersite");
  EXPECT_EQ(list["backward"]["site"], "cranksite2");
  EXPECT_EQ(value("broken.actuators", "get_properties")["properties"]["actuators"],
            json({"broken"}));
}

TEST_F(MjcfSim, AdhesionActuatorsActOnABody) {
  load_file(test_model("adhesion_crane.xml"));
  const mjModel* m = sim_->m();
  int adhere = sim_->model().actuator_id("adhere_winch");
  ASSERT_GE(adhere, 0);
  EXPECT_STREQ(actuator_type(m, adhere), "adhesion");
  EXPECT_STREQ(actuator_type(m, sim_->model().actuator_id("winch")), "position");
}

}  // namespace
}  // namespace simgate::sim
