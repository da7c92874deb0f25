// UrdfTest: URDF scenes through MuJoCo's own parser, with an actuator for each joint a ROS
// <transmission> or <ros2_control> block drives (issue #36, item 4; sim/src/urdf.h), and
// the errors a broken URDF gets.
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "mjcf_fixture.h"
#include "simgate/sim/model_edit.h"

namespace simgate::sim {
namespace {

using ::testing::HasSubstr;
using testing::MjcfSim;
using testing::test_model;

TEST_F(MjcfSim, AUrdfRobotGetsAnActuatorPerTransmissionJointAndMovesThroughThem) {
  load_file(test_model("urdf_arm.urdf"));
  Robot& arm = add_robot("arm", "base");
  add_component(arm, "actuators", "actuators");
  serve();
  json list = value("arm.actuators", "list_actuators");
  ASSERT_EQ(list.size(), 3u) << list.dump();
  // position interface: a servo over the joint's range, its effort the force limit
  EXPECT_EQ(list["shoulder_servo"]["type"], "position");
  EXPECT_EQ(list["shoulder_servo"]["joint"], "shoulder");
  EXPECT_EQ(list["shoulder_servo"]["ctrlrange"], json({-1.5, 1.5}));
  // effort interface: a motor within +-effort; ros2_control's velocity command: a velocity servo
  EXPECT_EQ(list["drive_motor"]["type"], "motor");
  EXPECT_EQ(list["drive_motor"]["ctrlrange"], json({-50.0, 50.0}));
  EXPECT_EQ(list["elbow_actuator"]["type"], "velocity");
  EXPECT_EQ(list["elbow_actuator"]["ctrlrange"], json({-2.0, 2.0}));
  // the servo takes the shoulder to 0.6 rad; the elbow turns at 1 rad/s
  EXPECT_EQ(
      call("arm.actuators", "set_controls", {{{"shoulder_servo", 0.6}, {"elbow_actuator", 1.0}}})
          .status,
      Status::success);
  const double elbow0 = qpos("elbow");
  run_for(1.0);
  EXPECT_NEAR(qpos("shoulder"), 0.6, 0.05);
  EXPECT_GT(qpos("elbow"), elbow0 + 0.5);
  // outside the joint's range: refused, as for an MJCF robot
  EXPECT_EQ(call("arm.actuators", "set_controls", {{{"shoulder_servo", 2.0}}}).status,
            Status::failed);
}

// A URDF scene keeps its spec (with the transmissions' actuators), which a spawn edits.
TEST(UrdfTest, AnEntitySpawnsIntoAUrdfScene) {
  Model m = Model::load_file(test_model("urdf_arm.urdf"));
  ASSERT_TRUE(m.spec());
  Model with_ball = with_entity(
      EditBase::of(m), "ball",
      entity_document("<body pos='1 0 1'><freejoint/><geom size='.1'/></body>", "ball", {}));
  EXPECT_EQ(with_ball.model()->nu, m.model()->nu);
  EXPECT_GE(with_ball.actuator_id("shoulder_servo"), 0);
  EXPECT_EQ(with_ball.body_id("ball"), m.model()->nbody);
}

std::string text_of(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// A URDF robot spawns as an entity: its root link becomes the entity's body, named and
// placed, and its transmissions' joints get actuators, as a URDF scene's do.
TEST(UrdfTest, AUrdfRobotSpawnsWithItsTransmissionsActuators) {
  Model scene = Model::load_file(testing::demo_scene());
  EntityPose pose;
  pose.position = {3, -1, 0.5};
  const EntityDocument document =
      entity_document(text_of(test_model("urdf_arm.urdf")), "arm2", pose);
  ASSERT_TRUE(document.urdf);
  Model with_arm = with_entity(EditBase::of(scene), "arm2", document);
  const int body = with_arm.body_id("arm2");
  ASSERT_EQ(body, scene.model()->nbody);  // after the scene's bodies
  EXPECT_EQ(with_arm.model()->body_pos[3 * body], 3);
  EXPECT_EQ(with_arm.model()->body_pos[3 * body + 2], 0.5);
  for (const char* actuator : {"shoulder_servo", "drive_motor"})
    EXPECT_GE(with_arm.actuator_id(actuator), 0) << actuator;
  EXPECT_EQ(with_arm.model()->nu, scene.model()->nu + 3);
  ASSERT_EQ(with_arm.entities().size(), 1u);
  EXPECT_EQ(with_arm.entities()[0].counts.nu, 3);
}

TEST(UrdfTest, ASpawnedUrdfWithSeveralRootLinksOrABadTransmissionIsRefused) {
  Model scene = Model::load_file(testing::demo_scene());
  auto error_of = [&](const std::string& urdf) {
    try {
      with_entity(EditBase::of(scene), "r", entity_document(urdf, "r", {}));
    } catch (const MujocoError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_THAT(
      error_of(
          R"(<robot name="two"><link name="a"><inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link>
      <link name="b"><inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link></robot>)"),
      HasSubstr("entity 'r': a spawned URDF robot has one root link"));
  EXPECT_THAT(
      error_of(
          R"(<robot name="t"><link name="a"><inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link>
      <transmission name="t"><joint name="nope"><hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface></joint></transmission></robot>)"),
      HasSubstr("entity 'r': a transmission drives joint 'nope', which the robot does not have"));
}

class UrdfErrors : public ::testing::Test {
 protected:
  std::string write(const std::string& name, const std::string& text) {
    const std::string path = (dir_ / name).string();
    std::ofstream(path) << text;
    return path;
  }
  std::string error_of(const std::string& path) {
    try {
      Model::load_file(path);
    } catch (const MujocoError& e) {
      return e.what();
    }
    return "(loaded)";
  }
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("simgate-urdf-" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path dir_;
};

constexpr const char* k_link = R"(<link name="base"><inertial><mass value="1"/>
  <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="arm"><inertial><mass value="1"/>
  <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
  <limit lower="-1" upper="1" effort="5" velocity="1"/></joint>)";

TEST_F(UrdfErrors, ATransmissionOfAJointTheRobotDoesNotHaveIsRefusedNamingIt) {
  const std::string path = write(
      "bad.urdf", std::string("<robot name='r'>") + k_link +
                      "<transmission name='t'><joint "
                      "name='nope'><hardwareInterface>EffortJointInterface</hardwareInterface>"
                      "</joint></transmission></robot>");
  EXPECT_THAT(error_of(path),
              HasSubstr("scene '" + path +
                        "': a transmission drives joint 'nope', which the robot does not have"));
}

TEST_F(UrdfErrors, AnInterfaceSimgateDoesNotKnowIsRefusedNamingIt) {
  const std::string path = write(
      "bad.urdf", std::string("<robot name='r'>") + k_link +
                      "<transmission name='t'><joint "
                      "name='j'><hardwareInterface>ImpedanceJointInterface</hardwareInterface>"
                      "</joint></transmission></robot>");
  EXPECT_THAT(error_of(path),
              HasSubstr("transmission 't' drives joint 'j' through 'ImpedanceJointInterface'"));
}

TEST_F(UrdfErrors, AMissingMeshIsNamed) {
  const std::string path =
      write("mesh.urdf", R"(<robot name='r'><link name="base"><inertial><mass value="1"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><mesh filename="no_such_part.stl"/></geometry></collision></link></robot>)");
  EXPECT_THAT(error_of(path), HasSubstr("no_such_part.stl"));
}

}  // namespace
}  // namespace simgate::sim
