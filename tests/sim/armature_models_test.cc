// ArmatureModelsTest: the armature and its pose sensor on the models Debian's
// libmujoco-samples ships (/usr/share/mujoco/model): humanoid.xml (a free root joint that
// is not an armature joint, 21 hinges driven by motors, so kinematically) and
// slider_crank.xml (unnamed bodies and joints, slider-crank transmissions); and the
// project's tests/models/tendon_arm.xml (two hinges moved by muscles through tendons:
// kinematic too; an unnamed root body), in place of arm26.xml, which MuJoCo 4.0 refuses. And the
// configuration errors of the `joints` option.
#include "armature_fixture.h"

namespace simgate::sim {
namespace {

using testing::ArmatureSim;
using testing::debian_model;
using ::testing::HasSubstr;
using testing::message;

class ArmatureModelsTest : public ArmatureSim {
 protected:
  void build_file(const std::string& relative, const std::string& robot, const std::string& body,
                  json options = json::object()) {
    const std::string path = debian_model(relative);
    ASSERT_TRUE(std::filesystem::exists(path))
        << path << " missing: apt-get install libmujoco-samples";
    build(Model::load_file(path), robot, body, std::move(options));
  }
  void build_own(const std::string& name, const std::string& robot, const std::string& body) {
    build(Model::load_file(testing::test_model(name)), robot, body);
  }
};

TEST_F(ArmatureModelsTest, HumanoidHingesMoveKinematicallyAtTheAskedSpeed) {
  build_file("humanoid/humanoid.xml", "humanoid", "torso");
  json joints = *arm("get_joints").value;
  ASSERT_EQ(joints.size(), 21u);  // every hinge; the free joint 'root' is not one
  EXPECT_EQ(joints.front(), "abdomen_z");
  EXPECT_EQ(joints.back(), "left_elbow");
  // motors are not position servos: the elbow is set kinematically, 0.5 rad at 1 rad/s
  const double t0 = sim_->sim_time();
  RequestId id = start("rotate", {"right_elbow", 0.5, 1.0});
  run_until(t0 + 0.25);
  EXPECT_NEAR(qpos("right_elbow"), 0.25, 0.02);
  run_until(t0 + 0.49);
  EXPECT_FALSE(rm_->outcome(id).has_value());
  auto done = run_until_answered(id, 0.1);
  ASSERT_TRUE(done.has_value());
  EXPECT_EQ(done->status, Status::success);
  run_for(1.0);  // held while the humanoid falls
  EXPECT_NEAR(qpos("right_elbow"), 0.5, 0.02);
  EXPECT_NEAR(pose("get_joint", {"right_elbow"}).value->get<double>(), qpos("right_elbow"), 1e-12);
  EXPECT_TRUE(state_is_finite());
}

// The README's demo (issue #35): a hinge held away from its spring's rest (abdomen_y: stiffness
// 10, held at 0.3 rad) while the knee motors push. Holding it by overwriting its qvel with 0
// every step fed the free base's spin (the joint's coupling to it), and MuJoCo's accelerations
// passed 1e10 after 247 steps (1.2 s); the held velocity is now reached by an impulse along
// the joint, whose reaction the robot takes. 2000 steps: 10 s of the humanoid on the floor.
TEST_F(ArmatureModelsTest, HumanoidHeldAgainstItsJointSpringWithItsKneesPushingDoesNotDiverge) {
  build_file("humanoid/humanoid.xml", "humanoid", "torso");
  ASSERT_EQ(arm("set_rotation", {"abdomen_y", 0.3}).status, Status::success);
  for (const char* knee : {"right_knee", "left_knee"})
    sim_->d()->ctrl[sim_->model().actuator_id(knee)] = 1.0;
  for (int i = 0; i < 2000 && sim_->statistics().bad_states == 0; ++i) {
    sim_->process_requests();
    sim_->step();
  }
  EXPECT_EQ(sim_->statistics().bad_states, 0u) << "diverged at t = " << sim_->sim_time();
  EXPECT_NEAR(sim_->sim_time(), 10.0, 1e-6);
  // held: where each step starts (a step moves it by what the physics does within it)
  EXPECT_NEAR(qpos("abdomen_y"), 0.3, 0.05);
  EXPECT_TRUE(state_is_finite());
}

TEST_F(ArmatureModelsTest, HumanoidRangesComeFromTheModelInRadians) {
  build_file("humanoid/humanoid.xml", "humanoid", "torso");
  Outcome o = arm("set_rotation", {"right_elbow", 1.0});
  EXPECT_EQ(o.status, Status::failed);
  EXPECT_THAT(message(o),
              HasSubstr("outside the range of joint 'right_elbow': [-1.5708, 0.872665] rad"));
  EXPECT_THAT(message(arm("set_rotation", {"root", 0.1})), HasSubstr("no joint 'root'"));
}

TEST_F(ArmatureModelsTest, HumanoidFollowsATrajectoryOfTwoNamedJoints) {
  build_file("humanoid/humanoid.xml", "humanoid", "torso");
  const double t0 = sim_->sim_time();
  json trajectory = {{"joint_names", {"left_elbow", "right_elbow"}},
                     {"points", {{{"positions", {-0.8, -0.8}}, {"time_from_start", 1.0}}}}};
  RequestId id = start("trajectory", {trajectory});
  run_until(t0 + 0.5);
  EXPECT_NEAR(qpos("left_elbow"), -0.4, 0.02);
  EXPECT_NEAR(qpos("right_elbow"), -0.4, 0.02);
  auto done = run_until_answered(id, 1.0);
  ASSERT_TRUE(done.has_value());
  EXPECT_EQ(done->status, Status::success);
  EXPECT_NEAR(qpos("left_elbow"), -0.8, 0.02);
}

TEST_F(ArmatureModelsTest, TendonArmHingesMovedByMusclesAreSetKinematically) {
  // its root body is unnamed: MuJoCo's id makes its name, body1
  build_own("tendon_arm.xml", "arm", "body1");
  EXPECT_EQ(arm("get_joints").value, json({"shoulder", "elbow"}));
  ASSERT_EQ(arm("set_rotation", {"elbow", 1.0}).status, Status::success);
  run_for(1.0);
  EXPECT_NEAR(qpos("elbow"), 1.0, 1e-3);
  // compiled from degrees: 0 to 120
  EXPECT_THAT(message(arm("set_rotation", {"elbow", -0.5})),
              HasSubstr("outside the range of joint 'elbow': [0, 2.0944] rad"));
  // the shoulder swung while the elbow was held: it goes from where it is
  const double t0 = sim_->sim_time(), from = qpos("shoulder");
  RequestId id = start("rotate", {"shoulder", 0.5, 0.5});
  auto done = run_until_answered(id, 1.1);
  ASSERT_TRUE(done.has_value());
  EXPECT_EQ(done->status, Status::success);
  EXPECT_GE(sim_->sim_time(), t0 + std::abs(0.5 - from) / 0.5 - 1e-9);
  EXPECT_NEAR(qpos("shoulder"), 0.5, 1e-3);
  json state = *pose("get_state").value;
  EXPECT_NEAR(state["shoulder"]["position"].get<double>(), qpos("shoulder"), 1e-12);
}

TEST_F(ArmatureModelsTest, SliderCrankUnnamedJointsAreNamedByTheirIds) {
  build_file("slider_crank/slider_crank.xml", "crank", "body1");
  // body1 and its child hold joint0 and joint1; joint2 is on another top-level body
  EXPECT_EQ(arm("get_joints").value, json({"joint0", "joint1"}));
  // unlimited: a bare SUCCESS (null)
  EXPECT_EQ(arm("get_IK_limits", {"joint0"}).value.value_or(json()), json(nullptr));
  const double t0 = sim_->sim_time();
  RequestId id = start("rotate_joints", {json{{"joint0", 1.0}}, 2.0});
  run_until(t0 + 0.25);
  EXPECT_NEAR(qpos("joint0"), 0.5, 0.01);
  auto done = run_until_answered(id, 0.5);
  ASSERT_TRUE(done.has_value());
  EXPECT_EQ(done->status, Status::success);
  EXPECT_NEAR(qpos("joint0"), 1.0, 0.01);
  EXPECT_THAT(message(arm("set_rotation", {"joint2", 0.1})),
              HasSubstr("(its joints: joint0, joint1)"));
  EXPECT_TRUE(state_is_finite());
}

// ---- configuration -------------------------------------------------------------------------

class ArmatureConfigTest : public ArmatureSim {
 protected:
  // The ConfigError creating an armature with `options` on `body` of the inline arm.
  std::string config_error(const std::string& body, json options) {
    sim_ = std::make_unique<Simulation>(
        Model::load_string(testing::two_link_arm_xml(), "two_link_arm.xml"),
        SimulationOptions{std::nullopt, 0.0});
    auto registry = builtin_registry();
    try {
      registry.create(Kind::component, {"arm.arm", "armature", body, "robots[0].components[0]"},
                      options, *sim_, nullptr);
    } catch (const ConfigError& e) {
      return e.what();
    }
    ADD_FAILURE() << "no ConfigError for " << options.dump();
    return "";
  }
};

TEST_F(ArmatureConfigTest, TheJointsOptionChoosesAndOrdersTheJoints) {
  build_arm({{"joints", {"slider", "shoulder"}}});
  EXPECT_EQ(arm("get_joints").value, json({"slider", "shoulder"}));
  EXPECT_EQ(pose("get_joints").value, json({"slider", "shoulder"}));
  EXPECT_THAT(message(arm("rotate", {"elbow", 0.1})), HasSubstr("(its joints: slider, shoulder)"));
}

TEST_F(ArmatureConfigTest, UnknownOrUnsuitableJointsAreConfigErrorsNamingThePath) {
  EXPECT_THAT(config_error("arm", {{"joints", {"shoulder", "elbo"}}}),
              HasSubstr("robots[0].components[0].options.joints[1]: no joint 'elbo' in the subtree "
                        "of body 'arm'; "
                        "did you mean 'elbow'? (its joints: shoulder, elbow, slider)"));
  EXPECT_THAT(
      config_error("arm", {{"joints", {"box_free"}}}),
      HasSubstr("options.joints[0]: joint 'box_free' is a free joint, not an armature joint"));
  EXPECT_THAT(
      config_error("fore", {{"joints", {"shoulder"}}}),
      HasSubstr(
          "options.joints[0]: joint 'shoulder' is not in the subtree of body 'fore' (its joints: "
          "elbow, slider)"));
  EXPECT_THAT(config_error("arm", {{"joints", {"elbow", "elbow"}}}),
              HasSubstr("joint 'elbow' is listed twice"));
  EXPECT_THAT(config_error("arm", {{"joints", json::array()}}),
              HasSubstr("expected a non-empty list"));
  EXPECT_THAT(
      config_error("box", json::object()),
      HasSubstr(
          "robots[0].components[0].body: body 'box' has no hinge or slide joint in its subtree"));
  EXPECT_THAT(config_error("arm", {{"radial_speed", 0}}), HasSubstr("options.radial_speed"));
  EXPECT_THAT(config_error("arm", {{"radial_sped", 1}}), HasSubstr("radial_sped"));
}

}  // namespace
}  // namespace simgate::sim
