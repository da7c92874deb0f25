// The `sensors` component: a robot's MJCF <sensor>s read by name with get_local_data, their
// values checked against physics (gravity on an accelerometer at rest, a block's weight on a
// touch sensor) and against MuJoCo's own state (jointpos is the qpos the last step started
// from, and the timestamp says so).
#include <cmath>

#include "mjcf_fixture.h"
#include "simgate/sim/actuators_sensors.h"

namespace simgate::sim {
namespace {

using ::testing::HasSubstr;
using testing::MjcfSim;
using testing::mujoco_sample;
using testing::test_model;

class MjcfSensorsTest : public MjcfSim {
 protected:
  void SetUp() override {
    load_string(testing::arm_and_block_xml());
    Robot& arm = add_robot("arm", "base");
    Robot& block = add_robot("block", "block");
    add_component(arm, "sensors", "sensors");
    add_component(arm, "actuators", "actuators");
    add_component(block, "sensors", "sensors");
    serve();
  }
  json arm_data() { return value("arm.sensors", "get_local_data"); }
  // The arm folded down and still: the elbow hangs, the servo holds the shoulder.
  void settle() { run_for(3.0); }
};

TEST_F(MjcfSensorsTest, EachRobotReadsTheSensorsOfItsOwnSubtree) {
  json data = arm_data();
  for (auto name : {"imu_acc", "imu_gyro", "shoulder_pos", "shoulder_vel", "jointpos_1", "tip_pos",
                    "elbow_force", "timestamp"})
    EXPECT_TRUE(data.contains(name)) << name;
  EXPECT_EQ(data.size(), 8u);
  json block = value("block.sensors", "get_local_data");
  EXPECT_EQ(block.size(), 3u);  // pad_touch, block_pos, timestamp
  EXPECT_TRUE(block.contains("pad_touch"));
}

TEST_F(MjcfSensorsTest, OneValueIsANumberSeveralAreAnArray) {
  json data = arm_data();
  EXPECT_TRUE(data["shoulder_pos"].is_number());
  ASSERT_TRUE(data["imu_acc"].is_array());
  EXPECT_EQ(data["imu_acc"].size(), 3u);
  EXPECT_TRUE(data["timestamp"].is_number());
}

TEST_F(MjcfSensorsTest, AnAccelerometerAtRestReadsGravityUpwards) {
  settle();
  // held: a range-for over a member of a temporary reads freed memory
  const json data = arm_data();
  const json& acc = data["imu_acc"];
  EXPECT_NEAR(acc[0].get<double>(), 0.0, 0.05);
  EXPECT_NEAR(acc[1].get<double>(), 0.0, 0.05);
  EXPECT_NEAR(acc[2].get<double>(), 9.81, 0.05);
  for (const json& w : data["imu_gyro"]) EXPECT_NEAR(w.get<double>(), 0.0, 1e-3);
}

TEST_F(MjcfSensorsTest, ATouchSensorUnderABlockWeighsIt) {
  settle();
  json data = value("block.sensors", "get_local_data");
  EXPECT_NEAR(data["pad_touch"].get<double>(), 2 * 9.81, 0.2);
  // resting on the floor: its frame half its height up
  EXPECT_NEAR(data["block_pos"][0].get<double>(), 1.0, 1e-3);
  EXPECT_NEAR(data["block_pos"][2].get<double>(), 0.1, 2e-3);
}

TEST_F(MjcfSensorsTest, ValuesDescribeTheStateTheLastStepStartedFromAndTheTimestampSaysSo) {
  call("arm.actuators", "set_control", {"shoulder_servo", 1.0});  // the shoulder turns
  run_for(0.1);
  const double q = qpos("shoulder"), v = qvel("shoulder"), t = sim_->sim_time();
  sim_->step();
  json data = arm_data();
  EXPECT_EQ(data["shoulder_pos"].get<double>(), q);
  EXPECT_EQ(data["shoulder_vel"].get<double>(), v);
  EXPECT_DOUBLE_EQ(data["timestamp"].get<double>(), t);
  EXPECT_NE(qpos("shoulder"), q);  // the step moved on from there
  const mjtNum* tip = sim_->d()->site_xpos + 3 * mj_name2id(sim_->m(), mjOBJ_SITE, "tip");
  for (int i = 0; i < 3; ++i)
    EXPECT_EQ(data["tip_pos"][i].get<double>(), tip[i]);  // same evaluation
}

TEST_F(MjcfSensorsTest, AfterAResetTheValuesAreOfTheCurrentState) {
  call("arm.actuators", "set_control", {"shoulder_servo", 1.0});
  run_for(0.5);
  ASSERT_EQ(call("simulation", "reset_objects").status, Status::success);
  json data = arm_data();
  EXPECT_EQ(data["shoulder_pos"].get<double>(), qpos("shoulder"));
  EXPECT_EQ(data["shoulder_pos"].get<double>(), 0.0);
  EXPECT_EQ(data["timestamp"].get<double>(), sim_->sim_time());  // simulated time went on
  EXPECT_GT(sim_->sim_time(), 0.4);
}

TEST_F(MjcfSensorsTest, BeforeTheFirstStepTheValuesAreOfTheLoadedState) {
  json data = arm_data();
  EXPECT_EQ(data["timestamp"], 0.0);
  EXPECT_EQ(data["jointpos_1"], 0.0);
}

TEST_F(MjcfSensorsTest, TimestampsAdvanceWithSimulatedTime) {
  // the first step evaluates the loaded state, at time 0, once more
  EXPECT_EQ(arm_data()["timestamp"], 0.0);
  sim_->step();
  EXPECT_EQ(arm_data()["timestamp"], 0.0);
  double previous = arm_data()["timestamp"].get<double>();
  for (int i = 0; i < 5; ++i) {
    sim_->step();
    const double now = arm_data()["timestamp"].get<double>();
    EXPECT_NEAR(now - previous, sim_->timestep(), 1e-12);
    previous = now;
  }
}

TEST_F(MjcfSensorsTest, AnActuatorForceSensorReadsTheMotorsForce) {
  call("arm.actuators", "set_control", {"elbow_motor", 1.5});
  sim_->step();  // evaluates the new control
  EXPECT_DOUBLE_EQ(arm_data()["elbow_force"].get<double>(), 1.5);
}

TEST_F(MjcfSensorsTest, PropertiesGiveTypeDimensionAndObject) {
  json p = value("arm.sensors", "get_properties")["properties"];
  EXPECT_EQ(p["count"], 7);
  json s = p["sensors"];
  EXPECT_EQ(s["imu_acc"], json({{"type", "accelerometer"}, {"dim", 3}, {"site", "imu"}}));
  EXPECT_EQ(s["shoulder_pos"], json({{"type", "jointpos"}, {"dim", 1}, {"joint", "shoulder"}}));
  EXPECT_EQ(s["jointpos_1"], json({{"type", "jointpos"}, {"dim", 1}, {"joint", "elbow"}}));
  EXPECT_EQ(s["elbow_force"],
            json({{"type", "actuatorfrc"}, {"dim", 1}, {"actuator", "elbow_motor"}}));
  EXPECT_EQ(s["tip_pos"]["site"], "tip");
  json block = value("block.sensors", "get_properties")["properties"]["sensors"];
  EXPECT_EQ(block["block_pos"], json({{"type", "framepos"}, {"dim", 3}, {"xbody", "block"}}));
  EXPECT_EQ(block["pad_touch"]["type"], "touch");
}

TEST_F(MjcfSensorsTest, TheServiceTakesNoParameters) {
  EXPECT_EQ(call("arm.sensors", "get_local_data", {1}).status, Status::failed);
  EXPECT_THAT(call("arm.sensors", "get_local_data", json{{"x", 1}}).message,
              HasSubstr("no parameter named 'x'"));
}

// ---- configuration ---------------------------------------------------------------------------

class MjcfSensorsConfigTest : public MjcfSim {
 protected:
  void SetUp() override { load_string(testing::arm_and_block_xml()); }
};

TEST_F(MjcfSensorsConfigTest, OptionSensorsRestrictsTheSet) {
  Robot& arm = add_robot("arm", "base");
  add_component(arm, "imu", "sensors", {{"sensors", {"imu_gyro", "imu_acc"}}});
  serve();
  json data = value("arm.imu", "get_local_data");
  EXPECT_EQ(data.size(), 3u);
  EXPECT_TRUE(data.contains("imu_acc"));
  EXPECT_EQ(value("arm.imu", "get_properties")["properties"]["count"], 2);
}

TEST_F(MjcfSensorsConfigTest, UnknownOrForeignListedSensorsAreConfigErrors) {
  Robot& arm = add_robot("arm", "base");
  EXPECT_THAT(config_error(arm, "sensors", {{"sensors", {"imu_accel"}}}),
              HasSubstr("options.sensors[0]: expected the name of a sensor of robot 'arm' (body "
                        "'base') (imu_acc, "
                        "imu_gyro, shoulder_pos, shoulder_vel, jointpos_1, tip_pos, elbow_force), "
                        "found 'imu_accel' "
                        "(no such sensor (did you mean 'imu_acc'?))"));
  EXPECT_THAT(config_error(arm, "sensors", {{"sensors", {"pad_touch"}}}),
              HasSubstr("options.sensors[0]: sensor 'pad_touch' is attached to site 'pad' of body "
                        "'block', outside "
                        "robot 'arm' (body 'base')"));
  EXPECT_THAT(config_error(arm, "sensors", {{"sensors", {3}}}),
              HasSubstr("options.sensors[0]: expected the name of a sensor, found number 3"));
}

TEST_F(MjcfSensorsConfigTest, ARobotWithoutSensorsCannotHaveTheComponent) {
  sim_.reset();
  load_string(
      R"(<mujoco><worldbody><body name="b"><joint/><geom size="0.1"/></body></worldbody></mujoco>)");
  Robot& robot = add_robot("r", "b");
  EXPECT_THAT(config_error(robot, "sensors"),
              HasSubstr("needs sensors, and robot 'r' (body 'b') has none"));
}

TEST_F(MjcfSensorsConfigTest, GeneratedNameCollisionsAndTimestampAreRefused) {
  sim_.reset();
  load_string(
      R"(<mujoco><worldbody><body name="b"><joint name="j"/><geom size="0.1"/></body></worldbody>
    <sensor><jointpos joint="j"/><jointvel name="jointpos_0" joint="j"/></sensor></mujoco>)");
  Robot& robot = add_robot("r", "b");
  EXPECT_THAT(config_error(robot, "sensors"), HasSubstr("are both called 'jointpos_0'"));
  sim_.reset();
  load_string(
      R"(<mujoco><worldbody><body name="b"><joint name="j"/><geom size="0.1"/></body></worldbody>
    <sensor><jointpos name="timestamp" joint="j"/></sensor></mujoco>)");
  Robot& other = add_robot("r", "b");
  EXPECT_THAT(config_error(other, "sensors"), HasSubstr("is called 'timestamp'"));
}

TEST_F(MjcfSensorsConfigTest, AClockBelongsToNoRobotButCanBeListedAndAgreesWithTheTimestamp) {
  sim_.reset();
  load_string(
      R"(<mujoco><worldbody><body name="b"><joint name="j"/><geom size="0.1"/><site name="s"/></body>
    </worldbody><sensor><clock name="clock"/><framepos name="f" objtype="site" objname="s" reftype="body" refname="b"/>
    <jointvel joint="j" cutoff="2"/></sensor></mujoco>)");
  Robot& robot = add_robot("r", "b");
  add_component(robot, "sensors", "sensors");
  add_component(robot, "timed", "sensors", {{"sensors", {"clock", "f", "jointvel_0"}}});
  serve();
  EXPECT_EQ(value("r.sensors", "get_properties")["properties"]["count"], 2);  // no clock
  json p = value("r.timed", "get_properties")["properties"]["sensors"];
  EXPECT_EQ(p["clock"], json({{"type", "clock"}, {"dim", 1}}));
  EXPECT_EQ(p["f"]["reference"], json({{"body", "b"}}));
  EXPECT_EQ(p["jointvel_0"]["cutoff"], 2.0);
  // MuJoCo's own clock sensor reads the time of the state it evaluated: the timestamp
  for (int i = 0; i < 3; ++i) {
    run_for(0.01);
    json data = value("r.timed", "get_local_data");
    EXPECT_DOUBLE_EQ(data["clock"].get<double>(), data["timestamp"].get<double>());
  }
  ASSERT_EQ(call("simulation", "reset_objects").status, Status::success);
  json data = value("r.timed", "get_local_data");
  EXPECT_DOUBLE_EQ(data["clock"].get<double>(), data["timestamp"].get<double>());
  EXPECT_DOUBLE_EQ(data["timestamp"].get<double>(), sim_->sim_time());
}

TEST_F(MjcfSensorsConfigTest, TypeNamesFollowMuJoCosElements) {
  EXPECT_STREQ(sensor_type_name(mjSENS_TOUCH), "touch");
  EXPECT_STREQ(sensor_type_name(mjSENS_RANGEFINDER), "rangefinder");
  EXPECT_STREQ(sensor_type_name(mjSENS_FRAMEQUAT), "framequat");
  EXPECT_STREQ(sensor_type_name(mjSENS_SUBTREEANGMOM), "subtreeangmom");
  EXPECT_STREQ(sensor_type_name(mjSENS_USER), "user");
}

// ---- Debian's MuJoCo samples -----------------------------------------------------------------

TEST_F(MjcfSim, AnUnnamedForceSensorIsNamedAfterItsTypeAndRank) {
  load_file(test_model("adhesion_crane.xml"));
  const int site = mj_name2id(sim_->m(), mjOBJ_SITE, "force_sensor");
  ASSERT_GE(site, 0);
  // the robot: the top-level body holding the sensor's site
  int root = sim_->m()->site_bodyid[site];
  while (sim_->m()->body_parentid[root] != 0) root = sim_->m()->body_parentid[root];
  Robot& robot = add_robot("crane", "#" + std::to_string(root));
  add_component(robot, "sensors", "sensors");
  serve();
  json p = value("crane.sensors", "get_properties")["properties"]["sensors"];
  EXPECT_EQ(p["force_0"], json({{"type", "force"}, {"dim", 3}, {"site", "force_sensor"}}));
  run_for(0.5);
  json force = value("crane.sensors", "get_local_data")["force_0"];
  ASSERT_EQ(force.size(), 3u);
  for (const json& f : force) EXPECT_TRUE(std::isfinite(f.get<double>()));
}

}  // namespace
}  // namespace simgate::sim
