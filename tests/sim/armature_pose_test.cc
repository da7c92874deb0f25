// ArmaturePoseTest: MORSE's armature pose sensor: joint names, state (position, velocity,
// actuator effort), one joint, segment lengths and get_local_data, on the inline two-link
// arm and on Debian's humanoid (motor efforts).
#include "armature_fixture.h"

namespace simgate::sim {
namespace {

using testing::ArmatureSim;
using testing::debian_model;
using ::testing::HasSubstr;
using testing::message;

class ArmaturePoseTest : public ArmatureSim {
 protected:
  void SetUp() override { build_arm(); }
};

TEST_F(ArmaturePoseTest, GetJointsListsThemFromRootToTip) {
  EXPECT_EQ(pose("get_joints").value, json({"shoulder", "elbow", "slider"}));
}

TEST_F(ArmaturePoseTest, GetStateReadsPositionVelocityAndEffort) {
  // the slider kinematically, the elbow's servo along a ramp (its force overcomes damping)
  const double t0 = sim_->sim_time();
  RequestId id = start(
      "trajectory", {json{{"joint_names", {"elbow", "slider"}},
                          {"points", {{{"positions", {0.4, 0.08}}, {"time_from_start", 2.0}}}}}});
  run_until(t0 + 1.0);
  json state = *pose("get_state").value;
  EXPECT_NEAR(state["slider"]["position"].get<double>(), 0.04, 1e-5);
  EXPECT_NEAR(state["slider"]["velocity"].get<double>(), 0.04, 1e-3);
  EXPECT_EQ(state["slider"]["effort"], 0.0);  // no actuator
  EXPECT_EQ(state["elbow"]["position"].get<double>(), qpos("elbow"));
  EXPECT_EQ(state["elbow"]["velocity"].get<double>(), qvel("elbow"));
  // the servo's force, kp (ctrl - qpos), as MuJoCo computed it in the last step
  const int dof = sim_->m()->jnt_dofadr[sim_->model().joint_id("elbow")];
  EXPECT_EQ(state["elbow"]["effort"].get<double>(), sim_->d()->qfrc_actuator[dof]);
  EXPECT_NE(state["elbow"]["effort"].get<double>(), 0.0);
  EXPECT_TRUE(run_until_answered(id, 3.0).has_value());
}

TEST_F(ArmaturePoseTest, GetJointReadsOnePositionAndNamesTheValidJoints) {
  ASSERT_EQ(arm("set_translation", {"slider", 0.03}).status, Status::success);
  EXPECT_EQ(pose("get_joint", {"slider"}).value, json(0.03));
  Outcome o = pose("get_joint", {"sliders"});
  EXPECT_EQ(o.status, Status::failed);
  EXPECT_THAT(message(o),
              HasSubstr("no joint 'sliders' in this armature; did you mean 'slider'? (its joints: "
                        "shoulder, elbow, slider)"));
}

TEST_F(ArmaturePoseTest, GetJointsLengthIsTheDistanceToTheNextJoint) {
  json lengths = *pose("get_joints_length").value;
  EXPECT_NEAR(lengths["shoulder"].get<double>(), 0.4, 1e-9);
  EXPECT_NEAR(lengths["elbow"].get<double>(), 0.3, 1e-9);
  // the tip: the far side of its body's box, from the slider's anchor at its centre
  EXPECT_NEAR(lengths["slider"].get<double>(), 0.02 * std::sqrt(3.0), 1e-9);
  // a rigid segment keeps its length whatever the pose
  ASSERT_EQ(arm("set_rotations", {json{0.5, -1.0}}).status, Status::success);
  ASSERT_EQ(arm("set_translation", {"slider", 0.06}).status, Status::success);
  lengths = *pose("get_joints_length").value;
  EXPECT_NEAR(lengths["shoulder"].get<double>(), 0.4, 1e-9);
  EXPECT_NEAR(lengths["elbow"].get<double>(), 0.3, 1e-9);
  EXPECT_NEAR(lengths["slider"].get<double>(), 0.02 * std::sqrt(3.0), 1e-9);
}

TEST_F(ArmaturePoseTest, GetLocalDataIsMorsesJointDictionaryWithATimestamp) {
  ASSERT_EQ(arm("set_rotation", {"shoulder", 0.25}).status, Status::success);
  run_for(0.1);
  json data = *pose("get_local_data").value;
  EXPECT_EQ(data.size(), 4u);
  EXPECT_EQ(data["shoulder"].get<double>(), qpos("shoulder"));
  EXPECT_EQ(data["slider"].get<double>(), qpos("slider"));
  EXPECT_DOUBLE_EQ(data["timestamp"].get<double>(), sim_->sim_time());
}

class ArmaturePoseHumanoidTest : public ArmatureSim {};

TEST_F(ArmaturePoseHumanoidTest, EffortIsTheMotorsForceThroughItsGear) {
  const std::string path = debian_model("humanoid/humanoid.xml");
  ASSERT_TRUE(std::filesystem::exists(path))
      << path << " missing: apt-get install libmujoco-samples";
  build(Model::load_file(path), "humanoid", "torso");
  // right_elbow's <motor gear="40">: a control of 0.5 gives 20 N m on the joint
  sim_->d()->ctrl[sim_->model().actuator_id("right_elbow")] = 0.5;
  sim_->step();
  json state = *pose("get_state").value;
  EXPECT_NEAR(state["right_elbow"]["effort"].get<double>(), 20.0, 1e-9);
  EXPECT_EQ(state["left_elbow"]["effort"], 0.0);
  EXPECT_EQ(state.size(), 21u);
}

}  // namespace
}  // namespace simgate::sim
