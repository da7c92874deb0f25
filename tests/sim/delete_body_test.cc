// SimDeleteBody: `simulation delete_entity` of a body of the scene (spawn.cc, model_edit.cc
// without_body, model_remap.h): the body's subtree and what refers to it leave the scene,
// everything after it moves down in MuJoCo's numbering, and the components after it
// (a robot, its actuators and sensors) re-resolve their ids and keep reading and driving
// the right objects. What a component uses and the world are refused, and the world is
// unchanged.
#include <gtest/gtest.h>

#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "sim_fixture.h"
#include "simgate/sim/model_edit.h"

namespace simgate::sim {
namespace {

// A table (with a lamp on a hinge, a tendon, a motor, sensors and an equality that refer to
// them) and a ball come BEFORE the robot: deleting the table moves every id of the robot.
constexpr const char* k_delete_body_scene = R"(<mujoco model="delete-test">
  <option timestep="0.002" integrator="implicit"/>
  <worldbody>
    <geom name="floor" type="plane" size="20 20 0.1"/>
    <body name="table" pos="3 3 0.3">
      <joint name="table_slide" type="slide" axis="1 0 0"/>
      <geom name="table_top" type="box" size="0.5 0.5 0.05" mass="5"/>
      <site name="table_site"/>
      <body name="lamp" pos="0 0 0.2">
        <joint name="lamp_hinge" type="hinge" axis="0 0 1"/>
        <geom name="lamp_geom" type="sphere" size="0.05" mass="0.1"/>
      </body>
    </body>
    <body name="ball" pos="-3 3 0.1">
      <freejoint name="ball_root"/>
      <geom name="ball_geom" type="sphere" size="0.1" mass="1"/>
    </body>
    <body name="robot" pos="0 0 0.1">
      <freejoint name="robot_root"/>
      <geom name="robot_chassis" type="box" size="0.25 0.17 0.05" pos="0 0 0.06" mass="6"/>
      <geom name="robot_caster" type="sphere" size="0.05" pos="-0.2 0 -0.05" contype="0" conaffinity="0" mass="0.2"/>
      <body name="robot_left_wheel" pos="0.1 0.21 0">
        <joint name="robot_left_wheel_joint" type="hinge" axis="0 1 0" armature="0.01" damping="0.01"/>
        <geom type="cylinder" size="0.1 0.02" zaxis="0 1 0" mass="0.5"/>
      </body>
      <body name="robot_right_wheel" pos="0.1 -0.21 0">
        <joint name="robot_right_wheel_joint" type="hinge" axis="0 1 0" armature="0.01" damping="0.01"/>
        <geom type="cylinder" size="0.1 0.02" zaxis="0 1 0" mass="0.5"/>
      </body>
    </body>
  </worldbody>
  <contact>
    <pair geom1="robot_caster" geom2="floor" condim="1"/>
    <exclude body1="table" body2="ball"/>
  </contact>
  <tendon>
    <fixed name="table_tendon"><joint joint="table_slide" coef="1"/><joint joint="lamp_hinge" coef="1"/></fixed>
  </tendon>
  <equality><joint joint1="lamp_hinge" joint2="table_slide"/></equality>
  <actuator>
    <position name="table_motor" joint="table_slide" kp="10"/>
    <motor name="tendon_motor" tendon="table_tendon"/>
    <velocity name="robot_left_motor" joint="robot_left_wheel_joint" kv="8" ctrlrange="-30 30" ctrllimited="true"/>
    <velocity name="robot_right_motor" joint="robot_right_wheel_joint" kv="8" ctrlrange="-30 30" ctrllimited="true"/>
  </actuator>
  <sensor>
    <jointpos name="table_position" joint="table_slide"/>
    <actuatorfrc name="tendon_force" actuator="tendon_motor"/>
    <framepos name="ball_position" objtype="body" objname="ball"/>
    <jointvel name="left_wheel_speed" joint="robot_left_wheel_joint"/>
  </sensor>
</mujoco>)";

class SimDeleteBodyTest : public ::testing::Test {
 protected:
  void SetUp() override { build(k_delete_body_scene); }
  void TearDown() override {
    rm_.reset();
    sim_.reset();
  }

  void build(const std::string& xml, const std::string& path = "") {
    rm_.reset();
    Model model =
        path.empty() ? Model::load_string(xml, "delete_test.xml") : Model::load_file(path);
    sim_ = std::make_unique<Simulation>(std::move(model), SimulationOptions{std::nullopt, 0.0});
    auto registry = builtin_registry();
    auto robot = registry.create(Kind::robot, {"robot", "ground_robot", "robot", "robots[0]"},
                                 json::object(), *sim_, nullptr);
    auto* r = static_cast<Robot*>(robot.get());
    sim_->add_component(std::move(robot), "ground_robot", "", true);
    int i = 0;
    for (auto type : {"motion_vw", "pose", "sensors", "armature_pose", "waypoint"}) {
      std::string short_name = type == std::string("motion_vw") ? "motion" : type;
      const std::string path = "robots[0].components[" + std::to_string(i++) + "]";
      auto c = registry.create(Kind::component, {"robot." + short_name, type, "robot", path},
                               json::object(), *sim_, r);
      sim_->add_component(std::move(c), type, "robot");
    }
    // a component of the robot bound to a body of the scene outside the robot
    sim_->add_component(
        registry.create(Kind::component,
                        {"robot.ball_pose", "pose", "ball", "robots[0].components[5]"},
                        json::object(), *sim_, r),
        "pose", "robot");
    add_world_components(*sim_);
    rm_ = std::make_shared<testing::RecordingManager>();
    for (auto& e : sim_->components()) rm_->register_component(*e->component);
    sim_->add_request_manager(rm_, "test");
  }

  Outcome call(const std::string& component, const std::string& service,
               json params = json::array()) {
    RequestId id = rm_->call(component, service, std::move(params));
    sim_->process_requests();
    return rm_->outcome(id).value_or(Outcome::failed(Failure::internal, "no answer"));
  }
  // Waits for `id` without stepping (the compile happens on a worker): nothing moves meanwhile.
  Outcome answer_without_stepping(RequestId id) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (std::chrono::steady_clock::now() < deadline) {
      sim_->process_requests();
      if (auto o = rm_->outcome(id)) return *o;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    ADD_FAILURE() << "request " << id << " not answered within 30 s";
    return Outcome::failed(Failure::internal, "no answer");
  }
  Outcome remove(const std::string& name) {
    return answer_without_stepping(rm_->call("simulation", "delete_entity", {name}));
  }
  void run_for(double seconds) {
    const int n = static_cast<int>(seconds / sim_->timestep());
    for (int i = 0; i < n; ++i) {
      sim_->process_requests();
      sim_->step();
    }
  }
  int body(const std::string& name) const { return sim_->model().body_id(name); }
  const mjtNum* qpos_of(const std::string& joint) const {
    return sim_->d()->qpos + sim_->m()->jnt_qposadr[sim_->model().joint_id(joint)];
  }
  // A refused delete: FAILED, bad arguments, the message naming `why`, nothing changed.
  void expect_refused(const std::string& name, const std::string& why) {
    const int nbody = sim_->m()->nbody;
    const std::uint64_t generation = sim_->model_generation();
    const Outcome o = remove(name);
    EXPECT_EQ(o.status, Status::failed) << name;
    EXPECT_EQ(o.failure, Failure::bad_arguments) << o.message;
    EXPECT_NE(o.message.find(why), std::string::npos) << o.message;
    EXPECT_EQ(sim_->m()->nbody, nbody);
    EXPECT_EQ(sim_->model_generation(), generation);
  }

  std::unique_ptr<Simulation> sim_;
  std::shared_ptr<testing::RecordingManager> rm_;
};

TEST_F(SimDeleteBodyTest, DeletingASceneBodyRemovesItAndWhatRefersToIt) {
  const int nbody = sim_->m()->nbody;
  const Outcome o = remove("table");
  ASSERT_EQ(o.status, Status::success) << o.message;
  EXPECT_EQ(o.value->at("model_generation"), 1);
  EXPECT_EQ(sim_->m()->nbody, nbody - 2);  // the table and its lamp
  EXPECT_EQ(body("table"), -1);
  EXPECT_EQ(body("lamp"), -1);
  const mjModel* m = sim_->m();
  for (auto [type, name] : {std::pair{mjOBJ_JOINT, "table_slide"},
                            {mjOBJ_JOINT, "lamp_hinge"},
                            {mjOBJ_GEOM, "lamp_geom"},
                            {mjOBJ_SITE, "table_site"},
                            {mjOBJ_TENDON, "table_tendon"},
                            {mjOBJ_ACTUATOR, "table_motor"},
                            {mjOBJ_ACTUATOR, "tendon_motor"},
                            {mjOBJ_SENSOR, "table_position"},
                            {mjOBJ_SENSOR, "tendon_force"}})
    EXPECT_EQ(mj_name2id(m, type, name), -1) << name;
  EXPECT_EQ(m->neq, 0);
  EXPECT_EQ(m->nexclude, 0);
  EXPECT_EQ(m->npair, 1);
  EXPECT_EQ(m->nu, 2);
  EXPECT_EQ(sim_->model().actuator_id("robot_left_motor"), 0);  // was 2
  // the scene lists it no more
  EXPECT_FALSE(call("simulation", "get_scene_objects").value->contains("table"));
}

// The robot comes after the deleted table: every id it holds moved; its pose sensor, its
// MJCF sensors, its joints and its motion still read and drive its own objects.
TEST_F(SimDeleteBodyTest, TheRobotAfterTheDeletedBodyStillReadsAndDrivesItsObjects) {
  run_for(0.2);  // settle on the floor
  const double ball_x_before = qpos_of("ball_root")[0];
  const double time = sim_->sim_time();
  ASSERT_EQ(remove("table").status, Status::success);
  EXPECT_EQ(sim_->sim_time(), time);
  EXPECT_EQ(qpos_of("ball_root")[0], ball_x_before);  // state carried by name

  const mjData* d = sim_->d();
  const int robot = body("robot");
  auto expect_pose_matches = [&] {
    const json pose = call("robot.pose", "get_local_data").value.value();
    EXPECT_NEAR(pose["x"].get<double>(), d->xpos[3 * robot], 1e-9);
    EXPECT_NEAR(pose["y"].get<double>(), d->xpos[3 * robot + 1], 1e-9);
    EXPECT_NEAR(pose["z"].get<double>(), d->xpos[3 * robot + 2], 1e-9);
  };
  expect_pose_matches();
  // the robot's pose of the ball (bound outside the robot, after the table too)
  const json ball = call("robot.ball_pose", "get_local_data").value.value();
  EXPECT_NEAR(ball["x"].get<double>(), d->xpos[3 * body("ball")], 1e-9);
  EXPECT_NEAR(ball["y"].get<double>(), d->xpos[3 * body("ball") + 1], 1e-9);

  // drive: the wheels' actuators, found by name, get the commands
  ASSERT_EQ(call("robot.motion", "set_speed", {0.5, 0.0}).status, Status::success);
  EXPECT_GT(d->ctrl[sim_->model().actuator_id("robot_left_motor")], 0.0);
  EXPECT_GT(d->ctrl[sim_->model().actuator_id("robot_right_motor")], 0.0);
  const double x0 = d->xpos[3 * robot];
  run_for(1.0);
  EXPECT_GT(d->xpos[3 * robot] - x0, 0.2);
  expect_pose_matches();

  // the MJCF sensors: the robot's wheel speed, read at its new sensordata address
  const json sensors = call("robot.sensors", "get_local_data").value.value();
  const int speed = mj_name2id(sim_->m(), mjOBJ_SENSOR, "left_wheel_speed");
  ASSERT_TRUE(sensors.contains("left_wheel_speed")) << sensors.dump();
  EXPECT_EQ(sensors["left_wheel_speed"], d->sensordata[sim_->m()->sensor_adr[speed]]);
  EXPECT_GT(std::abs(sensors["left_wheel_speed"].get<double>()), 1.0);
  // the joints: position of each wheel, read at its new qpos address
  const json joints = call("robot.armature_pose", "get_local_data").value.value();
  EXPECT_EQ(joints["robot_left_wheel_joint"], qpos_of("robot_left_wheel_joint")[0]);
  EXPECT_EQ(joints["robot_right_wheel_joint"], qpos_of("robot_right_wheel_joint")[0]);
}

TEST_F(SimDeleteBodyTest, ASpawnedEntityAfterTheSceneMovesToo) {
  const Outcome spawned = answer_without_stepping(
      rm_->call("simulation", "spawn_entity",
                {"crate",
                 "<body><freejoint/><geom type='box' size='0.1 0.1 0.1' mass='1'/></body>",
                 {2.0, -2.0, 0.1}}));
  ASSERT_EQ(spawned.status, Status::success) << spawned.message;
  const int crate_joint_before = sim_->model().free_joint_of(body("crate"));
  const double before = sim_->d()->qpos[sim_->m()->jnt_qposadr[crate_joint_before]];
  ASSERT_EQ(remove("table").status, Status::success);
  const int crate_joint = sim_->model().free_joint_of(body("crate"));
  ASSERT_GE(crate_joint, 0);
  EXPECT_EQ(crate_joint, crate_joint_before - 2);  // the table's slide and the lamp's hinge went
  EXPECT_EQ(sim_->d()->qpos[sim_->m()->jnt_qposadr[crate_joint]], before);
  // and the entity can still be deleted by its name
  ASSERT_EQ(remove("crate").status, Status::success);
  EXPECT_EQ(body("crate"), -1);
  EXPECT_EQ(call("robot.pose", "get_local_data").status, Status::success);
}

TEST_F(SimDeleteBodyTest, WhatAComponentUsesIsRefused) {
  expect_refused("ball", "holds component 'robot.ball_pose' of robot 'robot', whose robot stays");
  expect_refused("robot_left_wheel", "is part of robot 'robot''s body 'robot'");
  expect_refused("world", "is the world body");
  expect_refused("ghost", "no body or entity named 'ghost'");
  expect_refused("floor", "no body or entity named 'floor'");  // a geom
  // and the simulation runs on
  run_for(0.1);
  EXPECT_EQ(call("robot.pose", "get_local_data").status, Status::success);
}

// The spec is edited, not the scene's text (issue #36): a scene with keyframes, a body of an
// included file and an unnamed body ("body<n>") can be deleted. 2.2.2's text editing refused all three.
TEST_F(SimDeleteBodyTest, KeyframedScenesIncludedAndUnnamedBodiesCanBeDeleted) {
  std::string keyed = k_delete_body_scene;
  keyed.replace(keyed.rfind("</mujoco>"), 9,
                "<keyframe><key name='start' time='0'/></keyframe></mujoco>");
  build(keyed);
  EXPECT_EQ(remove("table").status, Status::success);
  EXPECT_EQ(sim_->m()->nkey, 1);

  const auto dir =
      std::filesystem::temp_directory_path() / ("simgate_delete_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "objects.xml") << R"(<mujoco><body name="box" pos="1 1 0.2"><freejoint/>
      <geom type="box" size="0.1 0.1 0.1" mass="1"/></body>
      <body pos="2 2 0.2"><freejoint/><geom type="sphere" size="0.1" mass="1"/></body></mujoco>)";
  std::string including = k_delete_body_scene;
  including.replace(including.find("<worldbody>") + 11, 0, "<include file='objects.xml'/>");
  std::ofstream(dir / "scene.xml") << including;
  build("", (dir / "scene.xml").string());
  const std::string unnamed = sim_->model().body_name(sim_->model().body_id("box") + 1);
  ASSERT_EQ(unnamed, "body2");
  const int bodies = sim_->m()->nbody;
  EXPECT_EQ(remove("box").status, Status::success);
  EXPECT_EQ(sim_->model().body_id("box"), -1);
  // the unnamed body moved down: it is "body1" now
  EXPECT_EQ(remove("body1").status, Status::success);
  EXPECT_EQ(sim_->m()->nbody, bodies - 2);
  EXPECT_EQ(remove("table").status, Status::success);
  std::filesystem::remove_all(dir);
}

// Deleting a robot's root body deletes the robot: its components leave the simulation and
// every request manager, their requests in flight end FAILED with the reason, and the rest
// of the world runs on.
TEST_F(SimDeleteBodyTest, DeletingARobotRemovesItsComponentsAndEndsTheirRequests) {
  const RequestId going = rm_->call("robot.waypoint", "goto", {8.0, 0.0, 0.0, 0.1, 1.0});
  sim_->process_requests();
  ASSERT_FALSE(rm_->outcome(going).has_value()) << "goto should still be running";
  const double ball_x = qpos_of("ball_root")[0];

  const Outcome o = remove("robot");
  ASSERT_EQ(o.status, Status::success) << o.message;
  sim_->process_requests();
  // the request in flight got its one answer
  const auto ended = rm_->outcome(going);
  ASSERT_TRUE(ended.has_value()) << "goto never answered";
  EXPECT_EQ(ended->status, Status::failed);
  EXPECT_NE(ended->message.find("robot 'robot' was deleted by simulation.delete_entity"),
            std::string::npos)
      << ended->message;

  // gone from the simulation, the request manager and the model
  for (auto name : {"robot", "robot.motion", "robot.pose", "robot.sensors", "robot.armature_pose",
                    "robot.waypoint", "robot.ball_pose"}) {
    EXPECT_EQ(sim_->find(name), nullptr) << name;
    EXPECT_FALSE(rm_->serves_component(name)) << name;
  }
  for (const auto& d : rm_->descriptors())
    EXPECT_FALSE(d.component.starts_with("robot")) << d.qualified_name();
  EXPECT_TRUE(sim_->robot_names().empty());
  const Outcome late = call("robot.pose", "get_local_data");
  EXPECT_EQ(late.status, Status::failed);
  EXPECT_EQ(late.failure, Failure::unknown_service) << late.message;
  const json details = call("simulation", "details").value.value();
  EXPECT_TRUE(details.at("robots").empty()) << details.dump();
  const json services = call("simulation", "list_services").value.value();
  EXPECT_EQ(services.dump().find("robot."), std::string::npos) << services.dump();
  EXPECT_EQ(body("robot"), -1);
  EXPECT_EQ(sim_->model().actuator_id("robot_left_motor"), -1);
  EXPECT_EQ(mj_name2id(sim_->m(), mjOBJ_SENSOR, "left_wheel_speed"), -1);
  EXPECT_EQ(mj_name2id(sim_->m(), mjOBJ_PAIR, nullptr), -1);
  EXPECT_EQ(sim_->m()->npair, 0);  // the caster's pair went with it

  // the rest carried across, and the world runs on
  EXPECT_EQ(qpos_of("ball_root")[0], ball_x);
  run_for(0.2);
  EXPECT_TRUE(testing::state_is_finite(*sim_));
  // and a table still deletes (a scene body deleted after a robot)
  EXPECT_EQ(remove("table").status, Status::success);
}

// The laser scanner keeps a table per geom (the robot's own): it follows spawned geoms
// (appended past its table's end) and deleted ones.
TEST_F(SimDeleteBodyTest, ALaserScannerSeesASpawnedBodyThenNotOnceDeleted) {
  auto registry = builtin_registry();
  auto* robot = static_cast<Robot*>(sim_->find("robot")->component.get());
  ComponentEntry& laser = sim_->add_component(
      registry.create(
          Kind::component, {"robot.laser", "laser_scanner", "robot", "robots[0].components[6]"},
          json{{"scan_window", 10.0}, {"resolution", 5.0}, {"laser_range", 10.0}}, *sim_, robot),
      "laser_scanner", "robot");
  rm_->register_component(*laser.component);
  auto nearest = [&] {
    const json scan = call("robot.laser", "get_local_data").value.value();
    double nearest = 1e9;
    for (const json& r : scan.at("range_list")) nearest = std::min(nearest, r.get<double>());
    return nearest;
  };
  EXPECT_NEAR(nearest(), 10.0, 1e-9);  // nothing ahead
  const Outcome spawned = answer_without_stepping(
      rm_->call("simulation", "spawn_entity",
                {"wall", "<body><geom type='box' size='0.1 1 0.5'/></body>", {2.0, 0.0, 0.5}}));
  ASSERT_EQ(spawned.status, Status::success) << spawned.message;
  EXPECT_LT(nearest(), 2.0);
  ASSERT_EQ(remove("table").status, Status::success);  // moves every geom of the robot and the wall
  EXPECT_LT(nearest(), 2.0);
  ASSERT_EQ(remove("wall").status, Status::success);
  EXPECT_NEAR(nearest(), 10.0, 1e-9);
}

TEST_F(SimDeleteBodyTest, ABodyHoldingAnotherRobotsComponentIsRefused) {
  // the robot's ball_pose makes 'ball' the robot's: deleting the ball alone is refused, and
  // deleting the robot takes ball_pose with it while the ball stays
  expect_refused("ball", "robot.ball_pose");
  ASSERT_EQ(remove("robot").status, Status::success);
  EXPECT_GE(body("ball"), 0);
  EXPECT_EQ(remove("ball").status, Status::success);
}

}  // namespace
}  // namespace simgate::sim
