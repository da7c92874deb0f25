// SimEntities: the entities and process groups of `simulation` (sim/src/entities.cc,
// process_services.cc) on the demo scene, and on an inline scene with a mocap body.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "sim_fixture.h"
#include "simgate/core/log.h"

namespace simgate::sim::testing {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::IsEmpty;

class SimEntitiesTest : public DemoSim {
 protected:
  // The demo body's position and quaternion [qx, qy, qz, qw], from MuJoCo.
  std::vector<double> pose_of(const std::string& body) const {
    const int b = sim_->model().body_id(body);
    const mjtNum* p = sim_->d()->xpos + 3 * b;
    const mjtNum* q = sim_->d()->xquat + 4 * b;
    return {p[0], p[1], p[2], q[1], q[2], q[3], q[0]};
  }
  std::vector<double> qpos() const { return {sim_->d()->qpos, sim_->d()->qpos + sim_->m()->nq}; }
  std::vector<double> qvel() const { return {sim_->d()->qvel, sim_->d()->qvel + sim_->m()->nv}; }
  void steps(int n) {
    for (int i = 0; i < n; ++i) sim_->step();
  }
  // A refusal: FAILED, bad arguments, naming `parameter`, state untouched.
  void expect_refused(const json& params, const std::string& service, const std::string& parameter,
                      const std::string& text) {
    const std::vector<double> q = qpos(), v = qvel();
    Outcome o = call("simulation", service, params);
    EXPECT_EQ(o.status, Status::failed) << params.dump();
    EXPECT_EQ(o.failure, Failure::bad_arguments) << params.dump() << ": " << o.message;
    EXPECT_EQ(o.data.value("parameter", ""), parameter) << params.dump() << ": " << o.message;
    EXPECT_THAT(o.message, HasSubstr(text)) << params.dump();
    EXPECT_EQ(qpos(), q) << params.dump();
    EXPECT_EQ(qvel(), v) << params.dump();
  }
};

TEST_F(SimEntitiesTest, SetObjectPositionPlacesAFreeBodyAtRestAndReturnsNothing) {
  steps(10);
  Outcome o =
      call("simulation", "set_object_position", {"crate1", {1.0, -1.0, 0.7}, {0.0, 0.0, 0.5}});
  ASSERT_EQ(o.status, Status::success) << o.message;
  EXPECT_FALSE(o.value.has_value());  // MORSE returns None
  const std::vector<double> p = pose_of("crate1");
  EXPECT_DOUBLE_EQ(p[0], 1.0);
  EXPECT_DOUBLE_EQ(p[1], -1.0);
  EXPECT_DOUBLE_EQ(p[2], 0.7);
  // yaw 0.5 about z: [0, 0, sin 0.25, cos 0.25]
  EXPECT_NEAR(p[5], std::sin(0.25), 1e-12);
  EXPECT_NEAR(p[6], std::cos(0.25), 1e-12);
  const int dof =
      sim_->m()->jnt_dofadr[sim_->model().free_joint_of(sim_->model().body_id("crate1"))];
  for (int i = 0; i < 6; ++i) EXPECT_EQ(sim_->d()->qvel[dof + i], 0.0);
}

TEST_F(SimEntitiesTest, SetObjectPositionWithoutOrientationKeepsIt) {
  ASSERT_EQ(
      call("simulation", "set_object_position", {"crate2", {0, 3, 0.2}, {0.1, 0.2, 0.3}}).status,
      Status::success);
  const std::vector<double> before = pose_of("crate2");
  for (json orientation : {json(nullptr), json::array()}) {
    ASSERT_EQ(
        call("simulation", "set_object_position", {"crate2", {1, 3, 0.2}, orientation}).status,
        Status::success);
    const std::vector<double> after = pose_of("crate2");
    for (int i = 3; i < 7; ++i) EXPECT_NEAR(after[i], before[i], 1e-12) << orientation.dump();
  }
  // the orientation may be left out altogether (its default)
  ASSERT_EQ(call("simulation", "set_object_position", {"crate2", {2, 3, 0.2}}).status,
            Status::success);
  EXPECT_DOUBLE_EQ(pose_of("crate2")[0], 2.0);
}

TEST_F(SimEntitiesTest, MovingTheRobotsRootMovesWhatItsComponentsRead) {
  ASSERT_EQ(
      call("simulation", "set_object_position", {"robot", {4.0, 5.0, 0.1}, {0, 0, 1.0}}).status,
      Status::success);
  json p = pose();  // robot.pose get_local_data, read right away
  EXPECT_DOUBLE_EQ(p["x"].get<double>(), 4.0);
  EXPECT_DOUBLE_EQ(p["y"].get<double>(), 5.0);
  EXPECT_NEAR(p["yaw"].get<double>(), 1.0, 1e-12);
  // and the robot drives on from there
  ASSERT_EQ(call("robot.motion", "set_speed", {0.5, 0.0}).status, Status::success);
  run_for(1.0);
  json moved = pose();
  EXPECT_GT(std::hypot(moved["x"].get<double>() - 4.0, moved["y"].get<double>() - 5.0), 0.2);
}

TEST_F(SimEntitiesTest, GetObjectPoseIsWhatGetSceneObjectsSays) {
  ASSERT_EQ(
      call("simulation", "set_object_position", {"human", {-1, 2, 0.05}, {0, 0, -2.0}}).status,
      Status::success);
  json pose = call("simulation", "get_object_pose", {"human"}).value.value();
  json scene = call("simulation", "get_scene_objects").value.value();
  EXPECT_EQ(pose[0], scene["human"][1]);
  EXPECT_EQ(pose[1], scene["human"][2]);
  EXPECT_NEAR(pose[1][2].get<double>(), std::sin(-1.0), 1e-12);  // qz of yaw -2
}

TEST_F(SimEntitiesTest, BoundingBoxesCoverTheBodyAndWhatHangsFromItInItsFrameAndTheWorlds) {
  ASSERT_EQ(
      call("simulation", "set_object_position", {"crate1", {1, 1, 1}, {0, 0, M_PI / 4}}).status,
      Status::success);
  json local = call("simulation", "get_object_bbox", {"crate1"}).value.value();
  json global = call("simulation", "get_object_global_bbox", {"crate1"}).value.value();
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(local[0][k].get<double>(), -0.2, 1e-12);
    EXPECT_NEAR(local[1][k].get<double>(), 0.2, 1e-12);
  }
  // turned 45 degrees: the world box is sqrt(2) wider in x and y
  EXPECT_NEAR(global[0][0].get<double>(), 1 - 0.2 * std::sqrt(2), 1e-12);
  EXPECT_NEAR(global[1][1].get<double>(), 1 + 0.2 * std::sqrt(2), 1e-12);
  EXPECT_NEAR(global[0][2].get<double>(), 0.8, 1e-12);
  EXPECT_NEAR(global[1][2].get<double>(), 1.2, 1e-12);
  // the robot's box holds its wheels (0.21 out, 0.02 thick): its subtree, not its chassis alone (0.17)
  json robot = call("simulation", "get_object_bbox", {"robot"}).value.value();
  EXPECT_NEAR(robot[1][1].get<double>(), 0.23, 1e-9);
  EXPECT_NEAR(robot[0][1].get<double>(), -0.23, 1e-9);
  EXPECT_NEAR(robot[1][0].get<double>(), 0.25, 1e-9);  // chassis front
  // a wheel alone: a cylinder 0.1 in radius along y
  json wheel = call("simulation", "get_object_bbox", {"robot_left_wheel"}).value.value();
  EXPECT_NEAR(wheel[1][0].get<double>(), 0.1, 1e-9);
  EXPECT_NEAR(wheel[1][1].get<double>(), 0.02, 1e-9);
}

TEST_F(SimEntitiesTest, AFrozenBodyStaysPutUntilReleasedThenFallsWithItsVelocity) {
  ASSERT_EQ(call("simulation", "set_object_position", {"crate1", {3, -2, 1.5}}).status,
            Status::success);
  steps(50);  // falling
  const int dof =
      sim_->m()->jnt_dofadr[sim_->model().free_joint_of(sim_->model().body_id("crate1"))];
  const double falling = sim_->d()->qvel[dof + 2];
  EXPECT_LT(falling, -0.5);
  Outcome frozen = call("simulation", "set_object_dynamics", {"crate1", false});
  ASSERT_EQ(frozen.status, Status::success) << frozen.message;
  EXPECT_EQ(frozen.value, json(false));  // MORSE returns the state
  const std::vector<double> held = pose_of("crate1");
  steps(500);
  EXPECT_EQ(pose_of("crate1"), held);  // exactly: physics does not move it
  EXPECT_EQ(call("simulation", "get_entity_state", {"crate1"}).value.value()["twist"]["linear"],
            json({0.0, 0.0, 0.0}));
  // placed while frozen: held there
  ASSERT_EQ(call("simulation", "set_object_position", {"crate1", {2, -2, 2.0}}).status,
            Status::success);
  steps(100);
  EXPECT_DOUBLE_EQ(pose_of("crate1")[2], 2.0);
  // released: it goes on with the velocity it had
  EXPECT_EQ(call("simulation", "set_object_dynamics", {"crate1", true}).value, json(true));
  EXPECT_DOUBLE_EQ(sim_->d()->qvel[dof + 2], falling);
  steps(100);
  EXPECT_LT(pose_of("crate1")[2], 1.9);
}

TEST_F(SimEntitiesTest, AFrozenBodyFollowsResetObjectsAndStaysFrozen) {
  ASSERT_EQ(call("simulation", "set_object_position", {"crate2", {0, 0, 3}}).status,
            Status::success);
  ASSERT_EQ(call("simulation", "set_object_dynamics", {"crate2", false}).status, Status::success);
  // freezing twice is harmless
  ASSERT_EQ(call("simulation", "set_object_dynamics", {"crate2", false}).status, Status::success);
  steps(20);
  EXPECT_DOUBLE_EQ(pose_of("crate2")[2], 3.0);
  ASSERT_EQ(call("simulation", "reset_objects").status, Status::success);
  steps(200);
  const std::vector<double> p = pose_of("crate2");
  EXPECT_DOUBLE_EQ(p[0], -3.0);  // its initial place (demo.xml), held there
  EXPECT_DOUBLE_EQ(p[2], 0.2);
}

TEST_F(SimEntitiesTest, EntityStateRoundTripsPoseAndTwistInTheWorldFrame) {
  json state = {
      {"pose",
       {{"position", {1.0, 2.0, 3.0}}, {"orientation", {0.0, 0.0, std::sin(0.6), std::cos(0.6)}}}},
      {"twist", {{"linear", {0.5, -0.25, 1.0}}, {"angular", {0.1, 0.2, 0.3}}}}};
  Outcome set = call("simulation", "set_entity_state", {"crate1", state});
  ASSERT_EQ(set.status, Status::success) << set.message;
  json got = call("simulation", "get_entity_state", {"crate1"}).value.value();
  EXPECT_EQ(set.value, got);  // it returns the new state
  for (const char* key : {"position", "orientation"})
    for (std::size_t i = 0; i < state["pose"][key].size(); ++i)
      EXPECT_NEAR(got["pose"][key][i].get<double>(), state["pose"][key][i].get<double>(), 1e-12)
          << key << i;
  for (const char* key : {"linear", "angular"})
    for (std::size_t i = 0; i < 3; ++i)
      EXPECT_NEAR(got["twist"][key][i].get<double>(), state["twist"][key][i].get<double>(), 1e-12)
          << key << i;
  // the orientation is get_scene_objects' [qx, qy, qz, qw]
  EXPECT_EQ(got["pose"]["orientation"],
            call("simulation", "get_scene_objects").value.value()["crate1"][2]);
}

TEST_F(SimEntitiesTest, SetEntityStateKeepsWhatItIsNotGiven) {
  json spin = {{"twist", {{"angular", {0.0, 0.0, 2.0}}}}};
  ASSERT_EQ(call("simulation", "set_entity_state", {"crate1", spin}).status, Status::success);
  json before = call("simulation", "get_entity_state", {"crate1"}).value.value();
  ASSERT_EQ(call("simulation", "set_entity_state",
                 {"crate1", {{"pose", {{"position", {0.0, 4.0, 0.5}}}}}})
                .status,
            Status::success);
  json after = call("simulation", "get_entity_state", {"crate1"}).value.value();
  EXPECT_EQ(after["pose"]["position"], json({0.0, 4.0, 0.5}));
  for (int i = 0; i < 4; ++i)
    EXPECT_NEAR(after["pose"]["orientation"][i].get<double>(),
                before["pose"]["orientation"][i].get<double>(), 1e-12);
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(after["twist"]["angular"][i].get<double>(),
                before["twist"]["angular"][i].get<double>(), 1e-12);
}

TEST_F(SimEntitiesTest, ListEntitiesFiltersBySubstringOrGlob) {
  auto list = [&](const std::string& filter) {
    return call("simulation", "list_entities", {filter}).value.value();
  };
  EXPECT_EQ(call("simulation", "list_entities").value.value(),
            json({"robot", "robot_left_wheel", "robot_right_wheel", "human", "crate1", "crate2"}));
  EXPECT_EQ(list("crate"), json({"crate1", "crate2"}));
  EXPECT_EQ(list("*wheel"), json({"robot_left_wheel", "robot_right_wheel"}));
  EXPECT_EQ(list("crate?"), json({"crate1", "crate2"}));
  EXPECT_EQ(list("r*t"), json({"robot"}));
  EXPECT_EQ(list("nothing"), json::array());
  EXPECT_EQ(list(std::string(200, '*') + "x"), json::array());  // no blow-up
}

TEST_F(SimEntitiesTest, UnknownNamesAreRefusedWithAClosestMatch) {
  expect_refused({"crat1", {0, 0, 1}}, "set_object_position", "object_name",
                 "Object 'crat1' does not appear in the scene. Did you mean 'crate1'?");
  expect_refused({"world", {0, 0, 1}}, "set_object_position", "object_name",
                 "does not appear in the scene");
  for (const char* service : {"get_object_pose", "get_object_bbox", "get_object_global_bbox"})
    expect_refused({"nobody"}, service, "object_name", "list_entities lists them");
  expect_refused({"nobody", false}, "set_object_dynamics", "object_name", "does not appear");
  expect_refused({"humam"}, "get_entity_state", "name", "Did you mean 'human'?");
  expect_refused({"humam", {{"pose", {{"position", {0, 0, 1}}}}}}, "set_entity_state", "name",
                 "Did you mean");
}

TEST_F(SimEntitiesTest, BodiesWithoutAFreeJointCannotBePlacedNorFrozen) {
  expect_refused({"robot_left_wheel", {0, 0, 1}}, "set_object_position", "object_name",
                 "Object 'robot_left_wheel' cannot be placed: it hangs from 'robot' by joint "
                 "'robot_left_wheel_joint'");
  expect_refused({"robot_left_wheel", false}, "set_object_dynamics", "object_name",
                 "cannot have its dynamics switched: it hangs from 'robot'");
  expect_refused({"robot_left_wheel", {{"pose", {{"position", {0, 0, 1}}}}}}, "set_entity_state",
                 "name", "cannot be placed");
}

TEST_F(SimEntitiesTest, BadNumbersAndShapesAreRefusedNamingTheParameter) {
  const double nan = std::nan(""), inf = INFINITY;
  expect_refused({"crate1", {0.0, nan, 1.0}}, "set_object_position", "position[1]",
                 "position[1] = nan");
  expect_refused({"crate1", {0.0, 0.0, 2e6}}, "set_object_position", "position[2]",
                 "out of bounds");
  expect_refused({"crate1", {0, 0, 1}, {0.0, inf, 0.0}}, "set_object_position", "orientation[1]",
                 "out of bounds");
  expect_refused({"crate1", {0, 0, 1}, {0, 0, 0, 1}}, "set_object_position", "orientation",
                 "[roll, pitch, yaw]");
  expect_refused({"crate1", {0, 0, 1}, "up"}, "set_object_position", "orientation", "found");
  auto state = [](json pose, json twist = nullptr) {
    json s = {{"pose", std::move(pose)}};
    if (!twist.is_null()) s["twist"] = std::move(twist);
    return s;
  };
  expect_refused({"crate1", state({{"orientation", {0, 0, 0, 0}}})}, "set_entity_state",
                 "state.pose.orientation", "is not a rotation");
  expect_refused({"crate1", state({{"orientation", {0, 0, nan, 1}}})}, "set_entity_state",
                 "state.pose.orientation[2]", "finite");
  expect_refused({"crate1", state({{"orientation", {0, 0, 1}}})}, "set_entity_state",
                 "state.pose.orientation", "[qx, qy, qz, qw]");
  expect_refused({"crate1", state({{"position", {0, 0}}})}, "set_entity_state",
                 "state.pose.position", "3 numbers");
  expect_refused({"crate1", state(json::object(), {{"linear", {inf, 0, 0}}})}, "set_entity_state",
                 "state.twist.linear[0]", "out of bounds");
  expect_refused({"crate1", state(json::object(), {{"angular", {0, 0, -1e300}}})},
                 "set_entity_state", "state.twist.angular[2]", "out of bounds");
  expect_refused({"crate1", {{"poze", json::object()}}}, "set_entity_state", "state.poze",
                 "did you mean 'pose'");
  expect_refused({"crate1", json::object()}, "set_entity_state", "state",
                 "at least one of pose, twist");
  expect_refused({"crate1", json::array()}, "set_entity_state", "state", "expected an object");
  // and the simulation goes on
  steps(10);
  EXPECT_TRUE(state_is_finite(*sim_));
  EXPECT_EQ(sim_->statistics().bad_states, 0u);
}

TEST_F(SimEntitiesTest, AFrozenBodyTakesAPoseButNoVelocity) {
  ASSERT_EQ(call("simulation", "set_object_dynamics", {"crate1", false}).status, Status::success);
  expect_refused({"crate1", {{"twist", {{"linear", {1, 0, 0}}}}}}, "set_entity_state",
                 "state.twist", "is frozen");
  ASSERT_EQ(
      call("simulation", "set_entity_state", {"crate1", {{"pose", {{"position", {1, 1, 1}}}}}})
          .status,
      Status::success);
  steps(50);
  EXPECT_DOUBLE_EQ(pose_of("crate1")[2], 1.0);
}

TEST_F(SimEntitiesTest, SetLogLevelSetsTheProcessLevelForAServedComponent) {
  const log::Level before = log::level();
  EXPECT_EQ(call("simulation", "set_log_level", {"robot.motion", "DEBUG"}).status, Status::success);
  EXPECT_EQ(log::level(), log::Level::debug);
  EXPECT_EQ(call("simulation", "set_log_level", {"simulation", "critical"}).status,
            Status::success);
  EXPECT_EQ(log::level(), log::Level::error);
  Outcome bad_level = call("simulation", "set_log_level", {"robot", "LOUD"});
  EXPECT_EQ(bad_level.status, Status::failed);
  EXPECT_THAT(bad_level.message, HasSubstr("Unknown level: 'LOUD'"));
  EXPECT_EQ(bad_level.data.value("parameter", ""), "level");
  Outcome unknown = call("simulation", "set_log_level", {"robot.motoin", "INFO"});
  EXPECT_EQ(unknown.status, Status::failed);
  EXPECT_THAT(unknown.message,
              HasSubstr("Component 'robot.motoin' not found (did you mean 'robot.motion'?)"));
  EXPECT_EQ(unknown.data.value("parameter", ""), "component");
  EXPECT_EQ(log::level(), log::Level::error);  // refusals change nothing
  log::set_level(before);
}

TEST_F(SimEntitiesTest, TheNewServicesAreListed) {
  json listed = call("simulation", "list_services").value.value();
  std::set<std::string> names;
  for (const auto& d : listed)
    names.insert(d["component"].get<std::string>() + " " + d["name"].get<std::string>());
  for (const char* s : {"set_object_position", "get_object_pose", "get_object_bbox",
                        "get_object_global_bbox", "set_object_dynamics", "get_entity_state",
                        "set_entity_state", "list_entities", "terminate", "set_log_level"})
    EXPECT_TRUE(names.count(std::string("simulation ") + s)) << s;
  EXPECT_TRUE(names.count("communication distance_and_view"));
}

// ---- mocap bodies -----------------------------------------------------------------------

const char* k_mocap_xml = R"(
<mujoco>
  <worldbody>
    <geom type="plane" size="5 5 0.1"/>
    <body name="target" mocap="true" pos="0 0 1">
      <geom type="sphere" size="0.1" contype="0" conaffinity="0"/>
    </body>
    <body name="ball" pos="1 0 1">
      <freejoint/>
      <geom type="sphere" size="0.1"/>
    </body>
  </worldbody>
</mujoco>)";

class SimMocapTest : public ::testing::Test {
 protected:
  void SetUp() override {
    sim_ = std::make_unique<Simulation>(Model::load_string(k_mocap_xml, "mocap.xml"),
                                        SimulationOptions{std::nullopt, 0});
    add_world_components(*sim_);
    rm_ = std::make_shared<RecordingManager>();
    for (auto& e : sim_->components()) rm_->register_component(*e->component);
    sim_->add_request_manager(rm_, "test");
  }
  Outcome call(const std::string& service, json params) {
    RequestId id = rm_->call("simulation", service, std::move(params));
    sim_->process_requests();
    return rm_->outcome(id).value_or(Outcome::failed(Failure::internal, "no answer"));
  }
  std::unique_ptr<Simulation> sim_;
  std::shared_ptr<RecordingManager> rm_;
};

TEST_F(SimMocapTest, AMocapBodyIsPlacedThroughItsMocapPoseAndHasNoVelocityNorDynamics) {
  ASSERT_EQ(call("set_object_position", {"target", {0.5, 0.5, 2.0}, {0, 0, 1}}).status,
            Status::success);
  json pose = call("get_object_pose", {"target"}).value.value();
  EXPECT_EQ(pose[0], json({0.5, 0.5, 2.0}));
  for (int i = 0; i < 100; ++i) sim_->step();
  EXPECT_EQ(call("get_object_pose", {"target"}).value.value()[0], json({0.5, 0.5, 2.0}));
  ASSERT_EQ(call("set_entity_state", {"target", {{"pose", {{"position", {1, 1, 1}}}}}}).status,
            Status::success);
  EXPECT_EQ(call("get_object_pose", {"target"}).value.value()[0], json({1.0, 1.0, 1.0}));
  Outcome moving = call("set_entity_state", {"target", {{"twist", {{"linear", {1, 0, 0}}}}}});
  EXPECT_EQ(moving.status, Status::failed);
  EXPECT_THAT(moving.message, HasSubstr("is a mocap body: it has no velocity"));
  Outcome dynamics = call("set_object_dynamics", {"target", false});
  EXPECT_EQ(dynamics.status, Status::failed);
  EXPECT_THAT(dynamics.message, HasSubstr("it is a mocap body"));
}

}  // namespace
}  // namespace simgate::sim::testing
