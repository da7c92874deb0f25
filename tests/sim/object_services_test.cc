// MORSE's object services (core/object.py) on every component the registry creates:
// get_properties, set_property (refusals name the valid properties) and get_configurations
// (how it was configured, and object_to_robot).
#include "sim_fixture.h"

namespace simgate::sim {
namespace {

using testing::DemoSim;
using ::testing::HasSubstr;

class ObjectServicesTest : public DemoSim {};

std::string answer_text(const Outcome& o) { return o.value.value_or(json()).get<std::string>(); }

TEST_F(ObjectServicesTest, EveryComponentAnswersTheThreeServices) {
  for (const auto& e : sim_->components()) {
    if (!e->sim_component) continue;  // simulation and time are not MORSE objects
    for (auto service : {"get_properties", "get_configurations"})
      EXPECT_EQ(call(e->component->name(), service).status, Status::success)
          << e->component->name() << " " << service;
  }
}

TEST_F(ObjectServicesTest, GetPropertiesListsTheValuesInMorsesEnvelope) {
  Outcome o = call("robot.waypoint", "get_properties");
  ASSERT_EQ(o.status, Status::success);
  json p = o.value->at("properties");
  EXPECT_EQ(p["max_angular_speed"], 1.5);
  EXPECT_EQ(p["heading_gain"], 2.0);
  EXPECT_EQ(p["tolerance"], 0.5);
  EXPECT_EQ(call("robot", "get_properties").value->at("properties")["wheel_radius"], 0.1);
  EXPECT_EQ(call("robot.pose", "get_properties").value, json({{"properties", json::object()}}));
}

TEST_F(ObjectServicesTest, SetPropertyChangesWhatTheComponentUses) {
  EXPECT_EQ(call("robot.waypoint", "set_property", {"max_angular_speed", 0.25}).status,
            Status::success);
  EXPECT_EQ(call("robot.waypoint", "get_properties").value->at("properties")["max_angular_speed"],
            0.25);
  // the wheel radius is what turns speed into wheel rotation: half the radius, twice the turn rate
  call("robot", "set_property", {"wheel_radius", 0.05});
  call("robot.motion", "set_speed", {0.2, 0.0});
  run_for(1.0);
  int joint = sim_->model().joint_id("robot_left_wheel_joint");
  EXPECT_NEAR(sim_->d()->qvel[sim_->m()->jnt_dofadr[joint]], 4.0, 0.5);
}

TEST_F(ObjectServicesTest, SetPropertyRefusesUnknownReadOnlyAndOutOfRangeValues) {
  Outcome unknown = call("robot.waypoint", "set_property", {"max_speed", 1.0});
  EXPECT_EQ(unknown.status, Status::failed);
  EXPECT_THAT(answer_text(unknown),
              HasSubstr("no property 'max_speed' in robot.waypoint (properties: max_angular_speed, "
                        "heading_gain, target, tolerance, speed)"));
  Outcome read_only = call("robot.waypoint", "set_property", {"target", json::array({1, 2, 3})});
  EXPECT_EQ(read_only.status, Status::failed);
  EXPECT_THAT(answer_text(read_only),
              HasSubstr("read-only (settable: max_angular_speed, heading_gain)"));
  for (json bad : {json(std::nan("")), json(1e300), json(-1.0), json("fast")}) {
    Outcome o = call("robot.waypoint", "set_property", {"heading_gain", bad});
    EXPECT_EQ(o.status, Status::failed) << bad;
  }
  EXPECT_EQ(call("robot.waypoint", "get_properties").value->at("properties")["heading_gain"], 2.0);
  EXPECT_THAT(answer_text(call("robot.pose", "set_property", {"x", 1.0})),
              HasSubstr("(it has none)"));
}

TEST_F(ObjectServicesTest, GetConfigurationsSaysHowItWasMadeAndWhereItSitsOnTheRobot) {
  json c = call("robot.pose", "get_configurations").value->at("configurations");
  EXPECT_EQ(c["type"], "pose");
  EXPECT_EQ(c["body"], "robot");
  EXPECT_EQ(c["options"], json::object());
  EXPECT_EQ(c["object_to_robot"]["translation"], json({0.0, 0.0, 0.0}));
  EXPECT_EQ(c["object_to_robot"]["rotation"], json({1.0, 0.0, 0.0, 0.0}));
}

TEST_F(ObjectServicesTest, ObjectToRobotIsTheBodysPoseInTheRobotsFrame) {
  auto registry = builtin_registry();
  Robot* robot = static_cast<Robot*>(sim_->find("robot")->component.get());
  auto wheel = registry.create(
      Kind::component, {"robot.wheel_pose", "pose", "robot_left_wheel", "robots[0].components[9]"},
      json::object(), *sim_, robot);
  call("robot.teleport", "rotate", {0.0, 0.0, 1.0});  // the frame turns with the robot
  json t = static_cast<SimComponent&>(*wheel)
               .get_configurations()["configurations"]["object_to_robot"]["translation"];
  EXPECT_NEAR(t[0].get<double>(), 0.1, 1e-6);
  EXPECT_NEAR(t[1].get<double>(), 0.21, 1e-6);
  EXPECT_NEAR(t[2].get<double>(), 0.0, 1e-6);
}

}  // namespace
}  // namespace simgate::sim
