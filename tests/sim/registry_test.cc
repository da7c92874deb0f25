// SimRegistry: components created by type name; errors name the JSON path, what was
// expected and what was found; new types join without touching the gateway.
#include <gtest/gtest.h>

#include "sim_fixture.h"

namespace simgate::sim {
namespace {

using ::testing::HasSubstr;

class SimRegistryTest : public ::testing::Test {
 protected:
  SimRegistryTest()
      : sim_(Model::load_file(testing::demo_scene()), SimulationOptions{std::nullopt, 0.0}) {}

  std::string error_of(Kind kind, ComponentSpec spec, json options = json::object(),
                       Robot* robot = nullptr) {
    try {
      registry_.create(kind, spec, options, sim_, robot);
    } catch (const ConfigError& e) {
      return e.what();
    }
    return "";
  }
  Robot* add_robot(const std::string& type, const std::string& name, const std::string& body) {
    auto r = registry_.create(Kind::robot, {name, type, body, "robots[0]"}, json::object(), sim_,
                              nullptr);
    auto* p = static_cast<Robot*>(r.get());
    sim_.add_component(std::move(r), type, "", true);
    return p;
  }

  Simulation sim_;
  ComponentRegistry registry_ = builtin_registry();
};

TEST_F(SimRegistryTest, UnknownTypeNamesPathAndKnownTypes) {
  std::string e =
      error_of(Kind::component, {"robot.x", "motion_wv", "robot", "robots[0].components[2]"});
  EXPECT_THAT(e, HasSubstr("robots[0].components[2].type"));
  EXPECT_THAT(e, HasSubstr("motion_wv"));
  EXPECT_THAT(e, HasSubstr("motion_vw"));  // lists what exists
}

TEST_F(SimRegistryTest, RobotTypeUsedAsComponentIsRejected) {
  std::string e =
      error_of(Kind::component, {"robot.x", "human", "robot", "robots[0].components[0]"});
  EXPECT_THAT(e, HasSubstr("which is a robot type"));
}

TEST_F(SimRegistryTest, MissingBodyNamesTheBodyAndScene) {
  std::string e = error_of(Kind::robot, {"robot", "ground_robot", "robto", "robots[0]"});
  EXPECT_THAT(e, HasSubstr("robots[0].body"));
  EXPECT_THAT(e, HasSubstr("'robto'"));
  EXPECT_THAT(e, HasSubstr("demo.xml"));
}

TEST_F(SimRegistryTest, MissingActuatorNamesTheOption) {
  std::string e = error_of(Kind::robot, {"robot", "ground_robot", "robot", "robots[0]"},
                           {{"left_actuator", "no_such_motor"}});
  EXPECT_THAT(e, HasSubstr("robots[0].options.left_actuator"));
  EXPECT_THAT(e, HasSubstr("no_such_motor"));
}

// A two-wheeled robot whose wheels are driven by the actuators given (MJCF elements).
std::string wheeled_scene(const std::string& left, const std::string& right) {
  return R"(<mujoco>
  <worldbody>
    <body name="bot" pos="0 0 0.1">
      <freejoint/>
      <geom type="box" size="0.2 0.15 0.05" mass="5"/>
      <body name="bot_left_wheel" pos="0 0.2 0">
        <joint name="left" type="hinge" axis="0 1 0"/>
        <geom type="cylinder" size="0.1 0.02" zaxis="0 1 0" mass="0.5"/>
      </body>
      <body name="bot_right_wheel" pos="0 -0.2 0">
        <joint name="right" type="hinge" axis="0 1 0"/>
        <geom type="cylinder" size="0.1 0.02" zaxis="0 1 0" mass="0.5"/>
      </body>
    </body>
  </worldbody>
  <actuator>)" +
         left + right + R"(</actuator>
</mujoco>)";
}

// The ConfigError of a ground_robot on `bot` in `scene`, or "".
std::string ground_robot_error(const std::string& scene) {
  Simulation sim(Model::load_string(scene), SimulationOptions{std::nullopt, 0.0});
  try {
    builtin_registry().create(Kind::robot, {"bot", "ground_robot", "bot", "robots[0]"},
                              json::object(), sim, nullptr);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(SimGroundRobotActuators, AMotorIsRefusedNamingItsTypeAndWhatIsExpected) {
  std::string e = ground_robot_error(
      wheeled_scene(R"(<motor name="bot_left_motor" joint="left"/>)",
                    R"(<velocity name="bot_right_motor" joint="right" kv="5"/>)"));
  EXPECT_EQ(
      e,
      "robots[0].options.left_actuator: actuator 'bot_left_motor' is a motor (torque: fixed gain, "
      "no bias); "
      "ground_robot drives its wheels by velocity: expected a <velocity kv=\"...\"> actuator (or a "
      "<general> "
      "one with gaintype=\"fixed\" gainprm=\"kv\", biastype=\"affine\" and biasprm=\"0 0 -kv\")");
}

TEST(SimGroundRobotActuators, APositionServoIsRefused) {
  std::string e = ground_robot_error(
      wheeled_scene(R"(<velocity name="bot_left_motor" joint="left" kv="5"/>)",
                    R"(<position name="bot_right_motor" joint="right" kp="20"/>)"));
  EXPECT_THAT(e, HasSubstr("robots[0].options.right_actuator: actuator 'bot_right_motor' is a "
                           "position servo (kp=20"));
  EXPECT_THAT(e, HasSubstr("expected a <velocity kv="));
}

TEST(SimGroundRobotActuators, AnOtherGeneralActuatorIsDescribedByItsParameters) {
  std::string e = ground_robot_error(wheeled_scene(
      R"(<general name="bot_left_motor" joint="left" gainprm="3" biastype="affine" biasprm="0 -1 -2"/>)",
      R"(<velocity name="bot_right_motor" joint="right" kv="5"/>)"));
  EXPECT_THAT(
      e,
      HasSubstr("actuator 'bot_left_motor' is a general actuator (gaintype fixed, gainprm 3 0 0; "
                "biastype affine, biasprm 0 -1 -2)"));
}

TEST(SimGroundRobotActuators, VelocityAndGeneralVelocityShapedActuatorsAreAccepted) {
  EXPECT_EQ(
      ground_robot_error(wheeled_scene(
          R"(<velocity name="bot_left_motor" joint="left" kv="5"/>)",
          R"(<general name="bot_right_motor" joint="right" gainprm="5" biastype="affine" biasprm="0 0 -5"/>)")),
      "");
}

TEST_F(SimRegistryTest, TheDemoSceneWheelsAreVelocityActuators) {
  EXPECT_EQ(error_of(Kind::robot, {"robot", "ground_robot", "robot", "robots[0]"}), "");
}

TEST_F(SimRegistryTest, UnknownOptionKeyIsAnError) {
  std::string e = error_of(Kind::robot, {"robot", "ground_robot", "robot", "robots[0]"},
                           {{"wheel_radus", 0.1}});
  EXPECT_THAT(e, HasSubstr("robots[0].options.wheel_radus"));
  EXPECT_THAT(e, HasSubstr("unknown key"));
}

TEST_F(SimRegistryTest, OptionOfTheWrongTypeIsAnError) {
  std::string e = error_of(Kind::robot, {"robot", "ground_robot", "robot", "robots[0]"},
                           {{"wheel_radius", "big"}});
  EXPECT_THAT(e, HasSubstr("robots[0].options.wheel_radius"));
  EXPECT_THAT(e, HasSubstr("expected"));
}

TEST_F(SimRegistryTest, MotionNeedsARobotThatDrives) {
  Robot* human = add_robot("human", "human", "human");
  std::string e =
      error_of(Kind::component, {"human.motion", "motion_vw", "human", "robots[0].components[0]"},
               json::object(), human);
  EXPECT_THAT(e, HasSubstr("ground_robot"));
  EXPECT_THAT(e, HasSubstr("'human'"));
}

TEST_F(SimRegistryTest, TeleportNeedsAFreeJoint) {
  Robot* robot = add_robot("ground_robot", "robot", "robot");
  std::string e = error_of(Kind::component,
                           {"robot.tp", "teleport", "robot_left_wheel", "robots[0].components[0]"},
                           json::object(), robot);
  EXPECT_THAT(e, HasSubstr("free joint"));
}

// A new component type joins the registry from the outside (no gateway change).
class Counter : public SimComponent {
 public:
  explicit Counter(ComponentContext& c) : SimComponent(c.name(), c.sim()) {
    step_ = c.options().get_int("step", 1, 1, 100);
    add_service("get", &Counter::get);
  }
  long long get() const { return count_; }
  void default_action() override { count_ += step_; }

 private:
  long long step_;       // increment per simulation step
  long long count_ = 0;  // steps seen times step_
};

TEST_F(SimRegistryTest, NewTypeJoinsTheRegistry) {
  registry_.add<Counter>("counter", Kind::component, "counts steps");
  Robot* robot = add_robot("robot", "robot", "robot");
  auto c = registry_.create(Kind::component, {"robot.counter", "counter", "robot", "x"},
                            {{"step", 2}}, sim_, robot);
  ASSERT_NE(c, nullptr);
  auto* counter = static_cast<Counter*>(c.get());
  sim_.add_component(std::move(c), "counter", "robot");
  sim_.step();
  sim_.step();
  EXPECT_EQ(counter->get(), 4);
}

// A component whose default action fails.
class Faulty : public SimComponent {
 public:
  explicit Faulty(ComponentContext& c) : SimComponent(c.name(), c.sim()) {
    add_async_service("work", [] {});
  }
  void default_action() override { throw std::runtime_error("sensor unplugged"); }
};

TEST_F(SimRegistryTest, FaultyDefaultActionDeactivatesOnlyThatComponent) {
  registry_.add<Faulty>("faulty", Kind::component, "always fails");
  registry_.add<Counter>("counter", Kind::component, "counts steps");
  Robot* robot = add_robot("robot", "robot", "robot");
  auto& faulty =
      sim_.add_component(registry_.create(Kind::component, {"robot.faulty", "faulty", "robot", "x"},
                                          json::object(), sim_, robot),
                         "faulty", "robot");
  auto c = registry_.create(Kind::component, {"robot.counter", "counter", "robot", "y"},
                            json::object(), sim_, robot);
  auto* counter = static_cast<Counter*>(c.get());
  sim_.add_component(std::move(c), "counter", "robot");
  auto rm = std::make_shared<testing::RecordingManager>();
  rm->register_component(*faulty.component);
  sim_.add_request_manager(rm, "test");
  RequestId id = rm->call("robot.faulty", "work");
  sim_.process_requests();
  sim_.step();
  sim_.step();
  sim_.process_requests();
  EXPECT_FALSE(faulty.active);
  EXPECT_EQ(counter->get(), 2);  // the others go on
  auto o = rm->outcome(id);
  ASSERT_TRUE(o.has_value());
  EXPECT_EQ(o->status, Status::failed);
  EXPECT_THAT(o->message, HasSubstr("sensor unplugged"));
  sim_.shutdown();
}

}  // namespace
}  // namespace simgate::sim
