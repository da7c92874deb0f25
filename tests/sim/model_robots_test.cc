// ModelRobots: which bodies of any MJCF model become robots, with which generic components,
// under which names (sim/model_robots.h; what `simgate run --model` serves).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "simgate/sim/model_robots.h"

namespace simgate::sim {
namespace {

using Components = std::vector<std::string>;

// an arm (hinges, a position servo, a touch sensor), a body with only a sensor, a free box,
// an unnamed body with a slide joint, bodies whose names need care
constexpr const char* k_model_robots_scene = R"(
<mujoco>
  <worldbody>
    <body name="arm.v2" pos="0 0 1">
      <joint name="shoulder" type="hinge"/>
      <geom type="capsule" size="0.05" fromto="0 0 0 0.3 0 0"/>
      <body name="forearm" pos="0.3 0 0">
        <joint name="elbow" type="hinge"/>
        <geom type="capsule" size="0.04" fromto="0 0 0 0.3 0 0"/>
        <site name="tip" pos="0.3 0 0"/>
      </body>
    </body>
    <body name="beacon" pos="2 0 0">
      <geom type="sphere" size="0.1"/>
      <site name="beacon_site"/>
    </body>
    <body name="crate" pos="1 1 0.2">
      <freejoint/>
      <geom type="box" size="0.1 0.1 0.1"/>
    </body>
    <body pos="3 0 0">
      <joint type="slide" axis="1 0 0"/>
      <geom type="box" size="0.1 0.1 0.1"/>
    </body>
    <body name="simulation" pos="4 0 0">
      <joint type="hinge"/>
      <geom type="sphere" size="0.1"/>
    </body>
    <body name="arm_v2" pos="5 0 0">
      <joint type="hinge"/>
      <geom type="sphere" size="0.1"/>
    </body>
  </worldbody>
  <actuator>
    <position name="elbow_servo" joint="elbow" kp="10"/>
  </actuator>
  <sensor>
    <touch name="tip_touch" site="tip"/>
    <framepos name="beacon_pos" objtype="site" objname="beacon_site"/>
  </sensor>
</mujoco>)";

TEST(ModelRobotsTest, EachTopLevelBodyWithJointsActuatorsOrSensorsIsARobot) {
  Model model = Model::load_string(k_model_robots_scene);
  std::vector<ModelRobot> robots = find_model_robots(model);
  ASSERT_EQ(robots.size(), 5u);
  // '.' would split component names: replaced by '_'
  EXPECT_EQ(robots[0].name, "arm_v2");
  EXPECT_EQ(robots[0].body, "arm.v2");
  EXPECT_EQ(robots[0].components, (Components{"armature", "armature_pose", "actuators", "sensors"}));
  // a sensor alone makes a robot of it
  EXPECT_EQ(robots[1].name, "beacon");
  EXPECT_EQ(robots[1].components, (Components{"sensors"}));
  // the crate (a free joint only) is an object: skipped; the unnamed body is body<id>
  EXPECT_EQ(robots[2].name, "body5");
  EXPECT_EQ(robots[2].body, "body5");
  EXPECT_EQ(robots[2].components, (Components{"armature", "armature_pose"}));
  // reserved and taken names get a suffix
  EXPECT_EQ(robots[3].name, "simulation_2");
  EXPECT_EQ(robots[3].body, "simulation");
  EXPECT_EQ(robots[4].name, "arm_v2_2");
  EXPECT_EQ(robots[4].body, "arm_v2");
}

TEST(ModelRobotsTest, DebiansSampleModels) {
  const std::string dir = "/usr/share/mujoco/model/";
  auto robots = find_model_robots(Model::load_file(dir + "humanoid/humanoid.xml"));
  ASSERT_EQ(robots.size(), 1u);
  EXPECT_EQ(robots[0].name, "torso");
  EXPECT_EQ(robots[0].components, (Components{"armature", "armature_pose", "actuators"}));
  robots = find_model_robots(Model::load_file(std::string(SIMGATE_SOURCE_DIR) + "/tests/models/tendon_arm.xml"));
  ASSERT_EQ(robots.size(), 1u);
  EXPECT_EQ(robots[0].components, (Components{"armature", "armature_pose", "actuators"}));
  robots = find_model_robots(Model::load_file(dir + "slider_crank/slider_crank.xml"));
  ASSERT_EQ(robots.size(), 2u);
}

}  // namespace
}  // namespace simgate::sim
