// SimNanSweep (issue #18, "Bad input"): a NaN, an infinity or an absurd magnitude sent to any
// number a service takes is refused, and nothing of it reaches MuJoCo.
//
// The sweep finds the numbers by introspection, not by a list: every service of every
// component (its descriptor's parameter schemas) and every property. For each service it
// makes valid calls (numbers from the schemas' defaults or 0; strings, maps, lists and
// trajectories from a table of valid calls per component type and service, which must
// cover every service that takes a number: a new one without an entry fails the sweep),
// checks they succeed, then replaces one number at a time (a number parameter, an optional
// one given as null, each value of a map or a list, each field of a trajectory point) with
// NaN, +inf, -inf, 1e300 and -1e300. Each such call must end FAILED (an async one: at once,
// never started), qpos, qvel, ctrl and act must stay finite right after it and after three
// more steps, simulated time must advance, and MuJoCo must find no bad state or control.
// set_property gets the same values for every property of every component.
//
// The sweep itself is in nan_sweep.h. A sweep that cannot fail would prove nothing: the Careless component below writes its
// input unchecked, in each way a real one could, and the sweep is shown to catch each.
#include <atomic>
#include <cmath>
#include <map>
#include <set>
#include <string>

#include "mjcf_fixture.h"
#include "nan_sweep.h"
#include "simgate/core/log.h"

namespace simgate::sim {
namespace {

using ::testing::Contains;
using ::testing::HasSubstr;
using ::testing::IsEmpty;
using testing::NanSweep;
using ::testing::Not;
using testing::RecordingManager;
using testing::ValidCalls;
using testing::ValidCallTable;
using testing::ValidValues;

// ---- scenes ----------------------------------------------------------------------------------

// Every component type on one scene: a ground robot (motion_vw, waypoint, teleport, pose,
// imu, odometry, laser_scanner, proximity), a human, and a fixed-base arm (armature on a
// position-servoed shoulder, a motor-driven elbow and a slide joint, armature_pose,
// actuators of several kinds, one with an activation, and MJCF sensors) near a wall.
const char* k_every_type_xml = R"(
<mujoco model="nan_sweep">
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="10 10 0.1"/>
    <geom name="wall" type="box" pos="4 0 0.5" size="0.1 3 0.5"/>
    <body name="robot" pos="0 0 0.1">
      <freejoint name="robot_root"/>
      <geom name="robot_chassis" type="box" size="0.25 0.17 0.05" pos="0 0 0.06" mass="6"/>
      <geom name="robot_caster" type="sphere" size="0.05" pos="-0.2 0 -0.05" contype="0" conaffinity="0" mass="0.2"/>
      <site name="robot_top" pos="0 0 0.15"/>
      <body name="robot_left_wheel" pos="0.1 0.21 0">
        <joint name="robot_left_wheel_joint" type="hinge" axis="0 1 0" damping="0.01"/>
        <geom type="cylinder" size="0.1 0.02" zaxis="0 1 0" mass="0.5"/>
      </body>
      <body name="robot_right_wheel" pos="0.1 -0.21 0">
        <joint name="robot_right_wheel_joint" type="hinge" axis="0 1 0" damping="0.01"/>
        <geom type="cylinder" size="0.1 0.02" zaxis="0 1 0" mass="0.5"/>
      </body>
    </body>
    <body name="human" pos="-2 2 0.05">
      <freejoint name="human_root"/>
      <geom type="box" size="0.2 0.25 0.05" mass="50"/>
      <geom type="capsule" fromto="0 0 0.3 0 0 1.5" size="0.18" mass="20"/>
    </body>
    <body name="arm" pos="2 -2 0.1">
      <geom type="cylinder" size="0.05 0.05" mass="1" contype="0" conaffinity="0"/>
      <site name="arm_base" pos="0 0 0.05"/>
      <body name="upper" pos="0 0 0.1">
        <joint name="shoulder" type="hinge" axis="0 0 1" limited="true" range="-1.5 1.5" damping="2"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="0.5" contype="0" conaffinity="0"/>
        <body name="fore" pos="0.3 0 0">
          <joint name="elbow" type="hinge" axis="0 1 0" limited="true" range="-2 2" damping="0.5"/>
          <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.02" mass="0.3" contype="0" conaffinity="0"/>
          <body name="finger" pos="0.2 0 0">
            <joint name="finger_slide" type="slide" axis="1 0 0" limited="true" range="0 0.1" damping="1"/>
            <geom type="box" size="0.02 0.02 0.02" mass="0.1" contype="0" conaffinity="0"/>
            <site name="tip"/>
          </body>
        </body>
      </body>
    </body>
    <body name="crate" pos="3 2 0.2">
      <freejoint/>
      <geom type="box" size="0.2 0.2 0.2" mass="4"/>
    </body>
  </worldbody>
  <contact>
    <pair geom1="robot_caster" geom2="floor" condim="1"/>
  </contact>
  <actuator>
    <velocity name="robot_left_motor" joint="robot_left_wheel_joint" kv="8" ctrllimited="true" ctrlrange="-30 30"/>
    <velocity name="robot_right_motor" joint="robot_right_wheel_joint" kv="8" ctrllimited="true" ctrlrange="-30 30"/>
    <position name="shoulder_servo" joint="shoulder" kp="20" ctrllimited="true" ctrlrange="-1.5 1.5"/>
    <motor name="elbow_motor" joint="elbow" ctrllimited="true" ctrlrange="-2 2"/>
    <motor name="finger_motor" joint="finger_slide" ctrllimited="false"/>
    <general name="finger_filter" joint="finger_slide" dyntype="filter" dynprm="0.05" gainprm="1"
             ctrllimited="true" ctrlrange="-1 1"/>
  </actuator>
  <sensor>
    <accelerometer name="arm_acc" site="arm_base"/>
    <gyro name="arm_gyro" site="arm_base"/>
    <jointpos name="shoulder_pos" joint="shoulder"/>
    <jointvel name="elbow_vel" joint="elbow"/>
    <framepos name="tip_pos" objtype="site" objname="tip"/>
    <actuatorfrc name="elbow_force" actuator="elbow_motor"/>
  </sensor>
</mujoco>)";

class SimNanSweepTest : public ::testing::Test {
 protected:
  void TearDown() override {
    rm_.reset();
    sim_.reset();
    log::set_sink({});
  }
  // The Careless component's damage makes MuJoCo and the simulation warn, as they should:
  // counted, not printed.
  void count_warnings() {
    log::set_sink([this](log::Level level, std::string_view) {
      if (level == log::Level::warning) ++warnings_;
    });
  }

  void load(Model model) {
    sim_ = std::make_unique<Simulation>(std::move(model), SimulationOptions{std::nullopt, 0.0});
  }
  // Created through the registry, as the gateway creates them.
  Robot& add_robot(const std::string& name, const std::string& type, const std::string& body) {
    auto robot = registry_.create(Kind::robot,
                                  {name, type, body, "robots[" + std::to_string(robots_++) + "]"},
                                  json::object(), *sim_, nullptr);
    Robot& r = static_cast<Robot&>(*robot);
    sim_->add_component(std::move(robot), type, "", true);
    return r;
  }
  void add_component(Robot& robot, const std::string& short_name, const std::string& type,
                     json options = json::object()) {
    const std::string path = "robots[0].components[" + std::to_string(components_++) + "]";
    sim_->add_component(registry_.create(Kind::component,
                                         {robot.name() + "." + short_name, type,
                                          sim_->model().body_name(robot.body()), path},
                                         options, *sim_, &robot),
                        type, robot.name());
  }
  void serve() {
    add_world_components(*sim_);
    rm_ = std::make_shared<RecordingManager>();
    for (auto& e : sim_->components()) {
      rm_->register_component(*e->component);
      e->interfaces.push_back("test");
    }
    sim_->add_request_manager(rm_, "test");
  }
  // Every component type of the registry's built-ins on k_every_type_xml.
  void build_every_type() {
    load(Model::load_string(k_every_type_xml, "nan_sweep.xml"));
    Robot& robot = add_robot("robot", "ground_robot", "robot");
    for (auto type : {"motion_vw", "waypoint", "teleport", "pose", "odometry", "proximity"})
      add_component(robot, type, type);
    add_component(robot, "imu", "imu", {{"site", "robot_top"}});
    add_component(robot, "laser", "laser_scanner", {{"site", "robot_top"}, {"resolution", 5}});
    add_component(robot, "camera", "video_camera",
                  {{"site", "robot_top"}, {"cam_width", 16}, {"cam_height", 16}});
    add_component(robot, "depth", "depth_camera",
                  {{"site", "robot_top"}, {"cam_width", 16}, {"cam_height", 16}});
    add_robot("human", "human", "human");
    Robot& arm = add_robot("arm", "robot", "arm");
    for (auto type : {"armature", "armature_pose", "actuators", "sensors"})
      add_component(arm, type, type);
    // a robot of type mjcf on a plain body (the gateway gives it generic components; here it
    // offers its object services, which the sweep covers)
    add_robot("crate", "mjcf", "crate");
  }
  std::vector<std::string> sweep(ValidCallTable extra = {}) {
    ValidValues values(*sim_, *rm_);
    ValidCallTable table = builtin_valid_calls(values);
    table.merge(extra);
    NanSweep sweep(*sim_, *rm_, std::move(table));
    // two finite magnitudes that mean something and reach nothing
    sweep.tolerate("time.sleep", "/0", 1e300,
                   "a duration on the simulated clock: such a sleep never ends, and its client "
                   "cancels it (MORSE's "
                   "sleep has no bound; bench/attacks holds connections with time sleep [1e9])");
    sweep.tolerate("armature.trajectory", "/0/starttime", -1e300,
                   "a start in the past is now, as in MORSE (ROS clients send 0 for now); only a "
                   "start too far "
                   "ahead is refused");
    std::vector<std::string> findings = sweep.run();
    swept_ = sweep.swept();
    bad_calls_ = sweep.bad_calls();
    return findings;
  }

  std::unique_ptr<Simulation> sim_;
  std::shared_ptr<RecordingManager> rm_;
  ComponentRegistry registry_ = builtin_registry();
  std::set<std::string> swept_;
  std::size_t bad_calls_ = 0;
  std::atomic<int> warnings_{0};  // see count_warnings()

 private:
  int robots_ = 0;
  int components_ = 0;
};

std::string lines(const std::vector<std::string>& findings) {
  std::string out;
  for (const auto& f : findings) out += "\n  " + f;
  return out;
}

TEST_F(SimNanSweepTest, EveryNumberOfEveryServiceAndPropertyRefusesNaNAndInfinities) {
  build_every_type();
  serve();
  // every registered component type is on the scene
  std::set<std::string> types;
  for (const auto& e : sim_->components()) types.insert(e->type);
  for (const auto& name : registry_.names(Kind::component))
    EXPECT_TRUE(types.count(name)) << name << " not swept";
  for (const auto& name : registry_.names(Kind::robot))
    EXPECT_TRUE(types.count(name)) << name << " not swept";

  const std::vector<std::string> findings = sweep();
  EXPECT_THAT(findings, IsEmpty()) << lines(findings);
  // what introspection found: the numbers of these services at least (a sweep of nothing
  // would pass too)
  for (auto service : {"robot.motion_vw.set_speed",
                       "robot.waypoint.goto",
                       "robot.waypoint.setdest",
                       "robot.teleport.translate",
                       "robot.teleport.rotate",
                       "robot.proximity.set_range",
                       "human.move",
                       "arm.armature.set_rotation",
                       "arm.armature.set_rotations",
                       "arm.armature.set_translation",
                       "arm.armature.set_translations",
                       "arm.armature.rotate",
                       "arm.armature.rotate_joints",
                       "arm.armature.translate",
                       "arm.armature.translate_joints",
                       "arm.armature.trajectory",
                       "arm.actuators.set_control",
                       "arm.actuators.set_controls",
                       "time.sleep",
                       "robot.laser.set_property(laser_range)",
                       "arm.armature.set_property(settle_timeout)",
                       "robot.set_property(wheel_radius)",
                       "simulation.step",
                       "simulation.restore_state",
                       "simulation.drop_state",
                       "time.set_time_scale",
                       "simulation.set_object_position",
                       "simulation.set_entity_state"})
    EXPECT_TRUE(swept_.count(service)) << service << " was not swept";
  EXPECT_GT(bad_calls_, 400u);
  EXPECT_EQ(sim_->statistics().bad_states, 0u);
}

TEST_F(SimNanSweepTest, DebiansHumanoidWithEveryGenericComponentRefusesThemToo) {
  load(Model::load_file(testing::mujoco_sample("humanoid/humanoid.xml")));
  Robot& humanoid = add_robot("humanoid", "robot", "torso");
  for (auto type : {"armature", "armature_pose", "actuators", "imu", "odometry", "proximity"})
    add_component(humanoid, type, type);
  add_component(humanoid, "laser", "laser_scanner", {{"resolution", 10}});
  serve();
  const std::vector<std::string> findings = sweep();
  EXPECT_THAT(findings, IsEmpty()) << lines(findings);
  EXPECT_TRUE(swept_.count("humanoid.armature.trajectory"));
  EXPECT_TRUE(swept_.count("humanoid.actuators.set_controls"));
  EXPECT_TRUE(swept_.count("simulation.set_entity_state"));
}

// ---- the sweep can fail ----------------------------------------------------------------------

// Takes client numbers into MuJoCo unchecked, in each way a real component could: a plain
// number into ctrl, a map into qvel, a field of a JSON object into qpos, a check made after
// the write, an async service that starts with whatever it got, and a property.
class Careless : public SimComponent {
 public:
  explicit Careless(ComponentContext& c) : SimComponent(c.name(), c.sim()) {
    add_service("set_ctrl", &Careless::set_ctrl, {"value"});
    add_service("set_velocities", &Careless::set_velocities, {"velocities"});
    add_service("set_height", &Careless::set_height, {"pose"});
    add_service("checks_too_late", &Careless::checks_too_late, {"value"});
    add_async_service("drive_for", &Careless::drive_for, {"seconds"});
    add_service("vague", &Careless::vague, {"speed"});
    add_property(
        "gain", [this] { return json(sim().d()->ctrl[1]); },
        [this](const json& v) { sim().d()->ctrl[1] = v.get<double>(); });
  }
  void set_ctrl(double value) { data()->ctrl[0] = value; }
  void set_velocities(const std::map<std::string, double>& velocities) {
    for (const auto& [joint, v] : velocities)
      data()->qvel[model()->jnt_dofadr[sim().model().joint_id(joint)]] = v;
  }
  void set_height(const json& pose) { data()->qpos[2] = pose.at("z").get<double>(); }
  void checks_too_late(double value) {
    data()->qpos[0] = value;
    if (!std::isfinite(value)) throw ServiceError("value must be finite", Failure::bad_arguments);
  }
  void drive_for(double seconds) { until_ = data()->time + seconds; }
  // safe, but its refusal does not say which number was wrong
  void vague(double speed) {
    if (!(std::abs(speed) <= 1e3)) throw ServiceError("invalid input", Failure::bad_arguments);
  }
  void default_action() override {
    if (has_running_request() && data()->time >= until_) completed(Status::success);
  }

 private:
  double until_ = 0;
};

TEST_F(SimNanSweepTest, ItCatchesAServiceThatWritesItsInputUnchecked) {
  count_warnings();
  registry_.add<Careless>("careless", Kind::component,
                          "writes client numbers into MuJoCo unchecked");
  build_every_type();
  Robot& robot = static_cast<Robot&>(*sim_->find("robot")->component);
  add_component(robot, "careless", "careless");
  serve();
  const std::vector<std::string> findings = sweep(
      {{"careless.set_velocities",
        [](const std::string&) {
          return ValidCalls{
              {json{{"robot_left_wheel_joint", 0.0}, {"robot_right_wheel_joint", 0.0}}}};
        }},
       {"careless.set_height", [](const std::string&) { return ValidCalls{{json{{"z", 0.1}}}}; }}});
  // each careless way is caught; every other component still has nothing to report
  auto found = [&findings](const std::string& text) {
    std::vector<std::string> out;
    for (const auto& f : findings)
      if (f.find(text) != std::string::npos) out.push_back(f);
    return out;
  };
  EXPECT_THAT(found("robot.careless.set_ctrl(/0 = NaN): ended SUCCESS"), Not(IsEmpty()))
      << lines(findings);
  EXPECT_THAT(found("robot.careless.set_ctrl(/0 = NaN): right after it ctrl[0] = NaN"),
              Not(IsEmpty()));
  EXPECT_THAT(
      found("robot.careless.set_velocities(/0/robot_right_wheel_joint = inf): right after it qvel"),
      Not(IsEmpty()));
  EXPECT_THAT(found("robot.careless.set_height(/0/z = -inf): right after it qpos[2] = -inf"),
              Not(IsEmpty()));
  // 1e300 is finite: the state check alone would miss it; the SUCCESS does not
  EXPECT_THAT(found("robot.careless.set_height(/0/z = 1e+300): ended SUCCESS"), Not(IsEmpty()));
  // refused, but after the damage
  EXPECT_THAT(found("robot.careless.checks_too_late(/0 = NaN): right after it qpos[0] = NaN"),
              Not(IsEmpty()));
  EXPECT_THAT(found("robot.careless.drive_for(/0 = -inf): ended SUCCESS"), Not(IsEmpty()));
  EXPECT_THAT(found("robot.careless.set_property(gain) = NaN: ended SUCCESS"), Not(IsEmpty()));
  EXPECT_THAT(
      found("robot.careless.vague(/0 = inf): FAILED without naming the parameter: invalid input"),
      Not(IsEmpty()));
  EXPECT_THAT(found("MuJoCo found a bad state"), Not(IsEmpty()));
  for (const auto& f : findings)
    EXPECT_THAT(f, HasSubstr("careless")) << "only Careless is careless";
  EXPECT_GT(warnings_.load(), 0);  // and the simulation said so
}

TEST_F(SimNanSweepTest, AServiceTakingNumbersWithNoKnownValidCallFailsTheSweep) {
  count_warnings();
  registry_.add<Careless>("careless", Kind::component,
                          "writes client numbers into MuJoCo unchecked");
  load(Model::load_string(k_every_type_xml, "nan_sweep.xml"));
  Robot& robot = add_robot("robot", "robot", "robot");
  add_component(robot, "careless", "careless");
  serve();
  // set_velocities and set_height take a map and an object: no valid call can be guessed
  EXPECT_THAT(sweep(), Contains(HasSubstr(
                           "robot.careless.set_height: takes numbers, but the sweep knows no valid "
                           "call (add 'careless.set_height' to the table of valid calls)")));
}

}  // namespace
}  // namespace simgate::sim
