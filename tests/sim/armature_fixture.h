// Test helpers for the armature and armature_pose components: a simulation of one model
// (inline MJCF or a file) with one robot carrying an armature ("<robot>.arm") and an
// armature pose sensor ("<robot>.pose"), stepped as fast as possible by the test.
#ifndef SIMGATE_TESTS_SIM_ARMATURE_FIXTURE_H_
#define SIMGATE_TESTS_SIM_ARMATURE_FIXTURE_H_

#include <cmath>
#include <filesystem>

#include "sim_fixture.h"
#include "simgate/sim/armature.h"

namespace simgate::sim::testing {

// A fixed-base arm in the horizontal plane (hinges about z: gravity puts no load on them):
// shoulder and elbow driven by position servos (the shoulder's ctrlrange narrower than its
// range), a slide joint at the tip with no actuator (driven kinematically), limited to
// [0, 0.1] m, and a free-floating box that is not part of the arm.
inline const char* two_link_arm_xml() {
  return R"(
<mujoco model="two_link_arm">
  <compiler angle="radian"/>
  <option timestep="0.002"/>
  <worldbody>
    <geom type="plane" size="3 3 .1"/>
    <body name="arm" pos="0 0 0.5">
      <geom type="cylinder" size="0.05 0.05" mass="2"/>
      <body name="upper">
        <joint name="shoulder" type="hinge" axis="0 0 1" limited="true" range="-1.5 1.5" damping="12"/>
        <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.03" mass="1"/>
        <body name="fore" pos="0.4 0 0">
          <joint name="elbow" type="hinge" axis="0 0 1" limited="true" range="-2 2" damping="3"/>
          <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.025" mass="0.5"/>
          <body name="finger" pos="0.3 0 0">
            <joint name="slider" type="slide" axis="1 0 0" limited="true" range="0 0.1"/>
            <geom type="box" size="0.02 0.02 0.02" mass="0.1"/>
          </body>
        </body>
      </body>
    </body>
    <body name="box" pos="1 1 0.2">
      <freejoint name="box_free"/>
      <geom type="box" size="0.1 0.1 0.1" mass="1"/>
    </body>
  </worldbody>
  <!-- the base's cylinder and the upper arm's capsule overlap at the shoulder: their contact
       pushes on the arm (MuJoCo 4.0's contact point, a hair off the hinge axis, turns the
       shoulder by 1e-5 rad in 0.5 s; 2.2.2's pushed along the axis) -->
  <contact><exclude body1="arm" body2="upper"/></contact>
  <actuator>
    <position name="shoulder_servo" joint="shoulder" kp="200" ctrllimited="true" ctrlrange="-1.2 1.2"/>
    <position name="elbow_servo" joint="elbow" kp="100"/>
  </actuator>
</mujoco>)";
}

inline std::string debian_model(const std::string& relative) {
  return "/usr/share/mujoco/model/" + relative;
}

class ArmatureSim : public ::testing::Test {
 protected:
  void TearDown() override {
    rm_.reset();
    sim_.reset();
  }

  // Builds the simulation: robot `robot` on `body`, its armature "<robot>.arm" and armature
  // pose "<robot>.pose" (both with `options`).
  void build(Model model, const std::string& robot, const std::string& body,
             json options = json::object()) {
    sim_ = std::make_unique<Simulation>(std::move(model), SimulationOptions{std::nullopt, 0.0});
    auto registry = builtin_registry();
    auto r = registry.create(Kind::robot, {robot, "robot", body, "robots[0]"}, json::object(),
                             *sim_, nullptr);
    auto* robot_ptr = static_cast<Robot*>(r.get());
    sim_->add_component(std::move(r), "robot", "", true);
    auto arm = registry.create(Kind::component,
                               {robot + ".arm", "armature", body, "robots[0].components[0]"},
                               options, *sim_, robot_ptr);
    arm_ = static_cast<Armature*>(arm.get());
    sim_->add_component(std::move(arm), "armature", robot);
    sim_->add_component(
        registry.create(Kind::component,
                        {robot + ".pose", "armature_pose", body, "robots[0].components[1]"},
                        options, *sim_, robot_ptr),
        "armature_pose", robot);
    add_world_components(*sim_);
    rm_ = std::make_shared<RecordingManager>();
    for (auto& e : sim_->components()) {
      rm_->register_component(*e->component);
      e->interfaces.push_back("test");
    }
    sim_->add_request_manager(rm_, "test");
    arm_name_ = robot + ".arm";
    pose_name_ = robot + ".pose";
  }
  void build_arm(json options = json::object()) {
    build(Model::load_string(two_link_arm_xml(), "two_link_arm.xml"), "arm", "arm",
          std::move(options));
  }

  // A sync call (or the start of an async one that fails at once), answered.
  Outcome call(const std::string& component, const std::string& service,
               json params = json::array()) {
    RequestId id = rm_->call(component, service, std::move(params));
    sim_->process_requests();
    auto o = rm_->outcome(id);
    EXPECT_TRUE(o.has_value()) << component << " " << service << " not answered";
    return o.value_or(Outcome::failed(Failure::internal, "no answer"));
  }
  Outcome arm(const std::string& service, json params = json::array()) {
    return call(arm_name_, service, params);
  }
  Outcome pose(const std::string& service, json params = json::array()) {
    return call(pose_name_, service, params);
  }
  // Starts an async armature service; it must still be running.
  RequestId start(const std::string& service, json params) {
    RequestId id = rm_->call(arm_name_, service, std::move(params));
    sim_->process_requests();
    auto o = rm_->outcome(id);
    EXPECT_FALSE(o.has_value()) << service
                                << " ended at once: " << (o && o->value ? o->value->dump() : "");
    return id;
  }
  // Steps (processing requests) until simulated time reaches `t`.
  void run_until(double t) {
    while (sim_->sim_time() < t - 0.5 * sim_->timestep()) {
      sim_->process_requests();
      sim_->step();
    }
    sim_->process_requests();
  }
  void run_for(double seconds) { run_until(sim_->sim_time() + seconds); }
  // Steps until `id` is answered or `seconds` of simulated time pass.
  std::optional<Outcome> run_until_answered(RequestId id, double seconds) {
    const double end = sim_->sim_time() + seconds;
    while (sim_->sim_time() < end) {
      sim_->process_requests();
      if (auto o = rm_->outcome(id)) return o;
      sim_->step();
    }
    sim_->process_requests();
    return rm_->outcome(id);
  }

  double qpos(const std::string& joint) {
    return sim_->d()->qpos[sim_->m()->jnt_qposadr[sim_->model().joint_id(joint)]];
  }
  double qvel(const std::string& joint) {
    return sim_->d()->qvel[sim_->m()->jnt_dofadr[sim_->model().joint_id(joint)]];
  }
  double ctrl(const std::string& actuator) {
    return sim_->d()->ctrl[sim_->model().actuator_id(actuator)];
  }
  // Every qpos, qvel and ctrl of the model is a finite number.
  bool state_is_finite() { return testing::state_is_finite(*sim_); }

  std::unique_ptr<Simulation> sim_;
  std::shared_ptr<RecordingManager> rm_;
  Armature* arm_ = nullptr;  // owned by sim_
  std::string arm_name_;     // "<robot>.arm"
  std::string pose_name_;    // "<robot>.pose"
};

// The message of a FAILED outcome.
inline std::string message(const Outcome& o) {
  if (!o.value) return o.message;
  return o.value->is_string() ? o.value->get<std::string>() : o.value->dump();
}

}  // namespace simgate::sim::testing

#endif  // SIMGATE_TESTS_SIM_ARMATURE_FIXTURE_H_
