// ModelRobots: which bodies of any MJCF model become robots, with which generic components,
// under which names (sim/model_robots.h; what `simgate run --model` serves).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "simgate/sim/model_robots.h"

namespace simgate::sim {
namespace {

using Components = std::vector<std::string>;

// an arm (hinges, a position servo, a touch sensor), a body with only a sensor, a free box,
// an unnamed body with a slide joint and a motor on it, an unnamed one with a slide joint
// only (a particle: scenery), bodies whose names need care
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
      <joint name="rail" type="slide" axis="1 0 0"/>
      <geom type="box" size="0.1 0.1 0.1"/>
    </body>
    <body pos="3 1 0">
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
    <motor name="rail_motor" joint="rail"/>
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
  EXPECT_EQ(robots[0].components,
            (Components{"armature", "armature_pose", "actuators", "sensors"}));
  // a sensor alone makes a robot of it
  EXPECT_EQ(robots[1].name, "beacon");
  EXPECT_EQ(robots[1].components, (Components{"sensors"}));
  // the crate (a free joint only) is an object: skipped; the unnamed body is body<id>; the
  // next (body6: a slide joint, nothing acting on it, nothing sensing it) is scenery
  EXPECT_EQ(robots[2].name, "body5");
  EXPECT_EQ(robots[2].body, "body5");
  EXPECT_EQ(robots[2].components, (Components{"armature", "armature_pose", "actuators"}));
  // reserved and taken names get a suffix
  EXPECT_EQ(robots[3].name, "simulation_2");
  EXPECT_EQ(robots[3].body, "simulation");
  EXPECT_EQ(robots[4].name, "arm_v2_2");
  EXPECT_EQ(robots[4].body, "arm_v2");
}

// issue #36, item 6: MuJoCo's composite, replicate and flex particles (bodies that only slide
// or float, nothing acting on or sensing them) are scenery, not robots (Debian's composite
// samples were 1000 robots of 27 000 services); a floating base gets pose and odometry
TEST(ModelRobotsTest, ParticlesAreSceneryAndAFloatingBaseGetsPoseAndOdometry) {
  Model model = Model::load_string(R"(<mujoco><worldbody>
    <body name="drone" pos="0 0 1"><freejoint/><geom type="box" size="0.2 0.2 0.05"/>
      <body name="gimbal"><joint name="pan" type="hinge"/><geom type="sphere" size="0.05"/></body></body>
    <replicate count="20" offset="0.1 0 0">
      <body name="bead" pos="0 2 0.1"><joint type="slide" axis="1 0 0"/><joint type="slide" axis="0 1 0"/>
        <geom type="sphere" size="0.02"/></body>
    </replicate>
    <flexcomp name="cloth" type="grid" count="4 4 1" spacing="0.1 0.1 0.1" pos="0 -2 1" radius="0.01" dim="2"/>
  </worldbody></mujoco>)");
  std::vector<ModelRobot> robots = find_model_robots(model);
  ASSERT_EQ(robots.size(), 1u);
  EXPECT_EQ(robots[0].name, "drone");
  EXPECT_EQ(robots[0].components, (Components{"armature", "armature_pose", "pose", "odometry"}));
}

TEST(ModelRobotsTest, DebiansSampleModels) {
  const std::string dir = "/usr/share/mujoco/model/";
  auto robots = find_model_robots(Model::load_file(dir + "humanoid/humanoid.xml"));
  ASSERT_EQ(robots.size(), 1u);
  EXPECT_EQ(robots[0].name, "torso");
  EXPECT_EQ(robots[0].components,
            (Components{"armature", "armature_pose", "actuators", "pose", "odometry"}));
  robots = find_model_robots(
      Model::load_file(std::string(SIMGATE_SOURCE_DIR) + "/tests/models/tendon_arm.xml"));
  ASSERT_EQ(robots.size(), 1u);
  EXPECT_EQ(robots[0].components, (Components{"armature", "armature_pose", "actuators"}));
  robots = find_model_robots(Model::load_file(dir + "slider_crank/slider_crank.xml"));
  ASSERT_EQ(robots.size(), 2u);
}

}  // namespace
}  // namespace simgate::sim
