// Test helper: a simulation of any MJCF model (inline or a file) whose robots are plain
// Robots on chosen bodies and whose components come from the built-in registry, served by a
// RecordingManager (sim_fixture.h), stepped as fast as possible by the test itself.
#ifndef SIMGATE_TESTS_SIM_MJCF_FIXTURE_H_
#define SIMGATE_TESTS_SIM_MJCF_FIXTURE_H_

#include <chrono>
#include <cmath>
#include <string>
#include <thread>

#include "sim_fixture.h"

namespace simgate::sim::testing {

class MjcfSim : public ::testing::Test {
 protected:
  void TearDown() override {
    rm_.reset();
    sim_.reset();
  }

  void load_string(const std::string& xml) { start(Model::load_string(xml, "test.xml")); }
  void load_file(const std::string& path) { start(Model::load_file(path)); }

  // A robot rooted at `body` (a name, or "#<id>" for unnamed bodies).
  Robot& add_robot(const std::string& name, const std::string& body) {
    const int id =
        body.rfind('#', 0) == 0 ? std::stoi(body.substr(1)) : sim_->model().body_id(body);
    EXPECT_GT(id, 0) << "no body " << body;
    auto robot = std::make_unique<Robot>(name, *sim_, id);
    Robot& r = *robot;
    sim_->add_component(std::move(robot), "robot", "", true);
    return r;
  }
  // Creates component "<robot>.<short_name>" of `type` (throws ConfigError as the gateway
  // would report it), bound to `body` ("": none; the gateway gives its robot's).
  void add_component(Robot& robot, const std::string& short_name, const std::string& type,
                     json options = json::object(), const std::string& body = "") {
    const std::string path = "robots[0].components[" + std::to_string(components_++) + "]";
    auto c = registry_.create(Kind::component, {robot.name() + "." + short_name, type, body, path},
                              options, *sim_, &robot);
    sim_->add_component(std::move(c), type, robot.name());
  }
  // The ConfigError's message creating such a component, or "" when it is accepted.
  std::string config_error(Robot& robot, const std::string& type, json options = json::object()) {
    try {
      registry_.create(Kind::component,
                       {robot.name() + ".probe", type, "", "robots[0].components[9]"}, options,
                       *sim_, &robot);
    } catch (const ConfigError& e) {
      return e.what();
    }
    return "";
  }
  // Serves every component added so far; call once, after the last add_component.
  void serve() {
    add_world_components(*sim_);
    rm_ = std::make_shared<RecordingManager>();
    for (auto& e : sim_->components()) {
      rm_->register_component(*e->component);
      e->interfaces.push_back("test");
    }
    sim_->add_request_manager(rm_, "test");
  }

  Outcome call(const std::string& component, const std::string& service,
               json params = json::array()) {
    RequestId id = rm_->call(component, service, std::move(params));
    sim_->process_requests();
    auto o = rm_->outcome(id);
    EXPECT_TRUE(o.has_value()) << component << " " << service << " not answered";
    return o.value_or(Outcome::failed(Failure::internal, "no answer"));
  }
  json value(const std::string& component, const std::string& service,
             json params = json::array()) {
    Outcome o = call(component, service, std::move(params));
    EXPECT_EQ(o.status, Status::success) << component << " " << service << ": " << o.message;
    return o.value.value_or(json());
  }
  // Steps and serves until request `id` has its outcome (an async service: a camera's render
  // thread, a capture over several steps), at most `limit` of wall time.
  Outcome step_until_outcome(RequestId id, std::chrono::seconds limit = std::chrono::seconds(60)) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < deadline) {
      sim_->process_requests();
      if (auto o = rm_->outcome(id)) return *o;
      sim_->step();
      if (auto o = rm_->outcome(id)) return *o;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    ADD_FAILURE() << "no outcome within " << limit.count() << " s";
    return Outcome::failed(Failure::internal, "no answer");
  }
  void run_for(double seconds) {
    const int n = static_cast<int>(std::lround(seconds / sim_->timestep()));
    for (int i = 0; i < n; ++i) sim_->step();
  }

  double qpos(const std::string& joint) const {
    return sim_->d()->qpos[sim_->m()->jnt_qposadr[sim_->model().joint_id(joint)]];
  }
  double qvel(const std::string& joint) const {
    return sim_->d()->qvel[sim_->m()->jnt_dofadr[sim_->model().joint_id(joint)]];
  }
  // by MJCF name (named actuators only)
  double ctrl(const std::string& actuator) const {
    const int id = sim_->model().actuator_id(actuator);
    EXPECT_GE(id, 0) << "no actuator named " << actuator;
    return id < 0 ? std::nan("") : sim_->d()->ctrl[id];
  }
  // Every qpos, qvel and ctrl is finite.
  bool state_is_finite() const { return testing::state_is_finite(*sim_); }

  std::unique_ptr<Simulation> sim_;
  std::shared_ptr<RecordingManager> rm_;
  ComponentRegistry registry_ = builtin_registry();

 private:
  void start(Model model) {
    sim_ = std::make_unique<Simulation>(std::move(model), SimulationOptions{std::nullopt, 0.0});
  }
  int components_ = 0;  // for the JSON paths
};

// An arm on a turntable (robot "arm", body "base": position servo, motors, sensors) and a
// loose block on the floor (robot "block", body "block": a touch sensor under it). The upper
// arm starts horizontal along x; gravity pulls it down about the elbow's +y axis.
inline const char* arm_and_block_xml() {
  return R"(<mujoco model="arm_and_block">
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="3 3 0.1"/>
    <body name="base" pos="0 0 0.1">
      <joint name="shoulder" type="hinge" axis="0 0 1" damping="2"/>
      <geom type="cylinder" size="0.05 0.05" mass="1" contype="0" conaffinity="0"/>
      <site name="imu" pos="0 0 0.05"/>
      <body name="upper" pos="0 0 0.1">
        <joint name="elbow" type="hinge" axis="0 1 0" damping="0.5"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="0.5" contype="0" conaffinity="0"/>
        <site name="tip" pos="0.3 0 0"/>
        <body name="finger" pos="0.3 0 0">
          <joint name="finger_slide" type="slide" axis="1 0 0" damping="1"/>
          <geom type="box" size="0.02 0.02 0.02" mass="0.1" contype="0" conaffinity="0"/>
        </body>
      </body>
    </body>
    <body name="block" pos="1 0 0.1">
      <freejoint name="block_free"/>
      <geom type="box" size="0.1 0.1 0.1" mass="2"/>
      <site name="pad" type="box" size="0.11 0.11 0.02" pos="0 0 -0.1"/>
    </body>
  </worldbody>
  <actuator>
    <position name="shoulder_servo" joint="shoulder" kp="20" ctrllimited="true" ctrlrange="-1.5 1.5"/>
    <motor name="elbow_motor" joint="elbow" ctrllimited="true" ctrlrange="-2 2" forcelimited="true"
           forcerange="-5 5"/>
    <motor joint="finger_slide" ctrllimited="false"/>
  </actuator>
  <sensor>
    <accelerometer name="imu_acc" site="imu"/>
    <gyro name="imu_gyro" site="imu"/>
    <jointpos name="shoulder_pos" joint="shoulder"/>
    <jointvel name="shoulder_vel" joint="shoulder"/>
    <jointpos joint="elbow"/>
    <framepos name="tip_pos" objtype="site" objname="tip"/>
    <actuatorfrc name="elbow_force" actuator="elbow_motor"/>
    <touch name="pad_touch" site="pad"/>
    <framepos name="block_pos" objtype="xbody" objname="block"/>
  </sensor>
</mujoco>)";
}

inline std::string mujoco_sample(const std::string& relative) {
  return "/usr/share/mujoco/model/" + relative;
}

}  // namespace simgate::sim::testing

#endif  // SIMGATE_TESTS_SIM_MJCF_FIXTURE_H_
