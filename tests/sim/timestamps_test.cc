// SimTimestamps: every sensor's `timestamp` is Simulation::state_time(), the simulated time
// of the state its values describe. mj_step evaluates poses, velocities and MJCF sensors on
// the state it starts from, then integrates: after a step they are one timestep older than
// mjData::time, and pose, the native sensors and `sensors` all say so, to the bit, as a
// <clock> sensor does. A teleport, a joint set at once, a reset, a bad state's recovery and
// suspended dynamics evaluate the current state: then every timestamp is the current time.
// armature_pose reads qpos, the integrated state: its timestamp is always the current time.
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <memory>

#include "mjcf_fixture.h"

namespace simgate::sim {
namespace {

using testing::MjcfSim;

// A rover (free body, a mast on a kinematic hinge, an imu site) dropped from 0.3 m, so its
// pose changes every step; a ball for its proximity sensor; a wall for its laser.
const char* k_scene = R"(
<mujoco model="timestamps">
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <geom name="wall" type="box" pos="2 0 0.5" size="0.1 2 0.5"/>
    <body name="rover" pos="0 0 0.3">
      <freejoint name="rover_free"/>
      <geom type="box" size="0.2 0.1 0.05" mass="2"/>
      <site name="rover_imu" pos="0 0 0.05"/>
      <body name="mast" pos="0 0 0.1">
        <joint name="mast_hinge" type="hinge" axis="0 0 1"/>
        <geom type="cylinder" size="0.02 0.05" mass="0.1"/>
      </body>
    </body>
    <body name="ball" pos="1 1 0.1">
      <freejoint/>
      <geom type="sphere" size="0.1" mass="1"/>
    </body>
  </worldbody>
  <sensor>
    <clock name="clock"/>
    <framepos name="rover_pos" objtype="xbody" objname="rover"/>
    <jointpos name="mast_angle" joint="mast_hinge"/>
  </sensor>
</mujoco>)";

// The components whose get_local_data describes the evaluated state.
const char* const k_sensors[] = {"rover.pose",     "rover.sensors", "rover.imu",
                                 "rover.odometry", "rover.laser",   "rover.proximity"};

class SimTimestampsTest : public MjcfSim {
 protected:
  void SetUp() override {
    load_string(k_scene);
    add_robot("rover", "rover");
    add_robot("ball", "ball");
    add("pose", "pose");
    add("sensors", "sensors", {{"sensors", {"clock", "rover_pos", "mast_angle"}}});
    add("imu", "imu", {{"site", "rover_imu"}});
    add("odometry", "odometry");
    add("laser", "laser_scanner", {{"scan_window", 10}, {"resolution", 5}});
    add("proximity", "proximity");
    add("teleport", "teleport");
    add("arm", "armature");
    add("arm_pose", "armature_pose");
    serve();
  }
  // A component of the rover, on its root body (as the gateway binds it by default).
  void add(const std::string& short_name, const std::string& type, json options = json::object()) {
    Robot& rover = static_cast<Robot&>(*sim_->find("rover")->component);
    sim_->add_component(
        registry_.create(Kind::component,
                         {"rover." + short_name, type, "rover", "robots[0].components[0]"}, options,
                         *sim_, &rover),
        type, "rover");
  }

  // component -> its get_local_data's timestamp
  std::map<std::string, double> timestamps() {
    std::map<std::string, double> out;
    for (const char* c : k_sensors) out[c] = value(c, "get_local_data")["timestamp"].get<double>();
    return out;
  }
  // Every sensor's timestamp, and the <clock> sensor, read exactly `expected`.
  void expect_all_stamped(double expected, const std::string& when) {
    for (const auto& [component, t] : timestamps())
      EXPECT_EQ(t, expected) << component << " " << when;
    EXPECT_EQ(value("rover.sensors", "get_local_data")["clock"].get<double>(), expected) << when;
    EXPECT_EQ(sim_->state_time(), expected) << when;
  }
};

TEST_F(SimTimestampsTest, BeforeTheFirstStepEverythingIsOfTheLoadedState) {
  expect_all_stamped(0.0, "at load");
  EXPECT_EQ(value("rover.arm_pose", "get_local_data")["timestamp"], 0.0);
}

TEST_F(SimTimestampsTest, AfterAStepEverySensorStampsTheStateTheStepStartedFrom) {
  run_for(0.05);  // falling
  for (int i = 0; i < 3; ++i) {
    const double started = sim_->sim_time();
    sim_->step();
    ASSERT_GT(sim_->sim_time(), started);
    expect_all_stamped(started, "after a step from t=" + std::to_string(started));
    // pose and the framepos sensor are one evaluation: the same z, to the bit
    json pose = value("rover.pose", "get_local_data");
    json sensors = value("rover.sensors", "get_local_data");
    EXPECT_EQ(pose["z"].get<double>(), sensors["rover_pos"][2].get<double>());
    // while qpos, integrated since, is one step lower: the timestamps are not a formality
    const int z = sim_->m()->jnt_qposadr[sim_->model().joint_id("rover_free")] + 2;
    EXPECT_LT(sim_->d()->qpos[z], pose["z"].get<double>());
    // armature_pose reads qpos: the current time
    EXPECT_EQ(value("rover.arm_pose", "get_local_data")["timestamp"].get<double>(),
              sim_->sim_time());
  }
}

TEST_F(SimTimestampsTest, AfterATeleportEveryTimestampIsTheCurrentTime) {
  run_for(0.05);
  ASSERT_EQ(call("rover.teleport", "translate", {0.0, 0.0, 0.5}).status, Status::success);
  expect_all_stamped(sim_->sim_time(), "after a teleport");
  const int z = sim_->m()->jnt_qposadr[sim_->model().joint_id("rover_free")] + 2;
  EXPECT_EQ(value("rover.pose", "get_local_data")["z"].get<double>(), sim_->d()->qpos[z]);
  // and the next step is again one step behind
  const double started = sim_->sim_time();
  sim_->step();
  expect_all_stamped(started, "after the step that followed");
}

TEST_F(SimTimestampsTest, AfterAJointIsSetAtOnceEveryTimestampIsTheCurrentTime) {
  run_for(0.02);
  ASSERT_EQ(call("rover.arm", "set_rotation", {"mast_hinge", 0.5}).status, Status::success);
  expect_all_stamped(sim_->sim_time(), "after set_rotation");
  EXPECT_EQ(value("rover.sensors", "get_local_data")["mast_angle"].get<double>(), 0.5);
}

TEST_F(SimTimestampsTest, AfterAResetEveryTimestampIsTheCurrentTime) {
  run_for(0.05);
  ASSERT_EQ(call("simulation", "reset_objects").status, Status::success);
  EXPECT_GT(sim_->sim_time(), 0.04);
  expect_all_stamped(sim_->sim_time(), "after reset_objects");
}

TEST_F(SimTimestampsTest, AfterABadStateIsRecoveredEveryTimestampIsTheCurrentTime) {
  run_for(0.02);
  // what a careless component could do: MuJoCo resets its data, the simulation recovers
  sim_->d()->qvel[0] = std::numeric_limits<double>::quiet_NaN();
  sim_->step();
  ASSERT_EQ(sim_->statistics().bad_states, 1u);
  expect_all_stamped(sim_->sim_time(), "after a bad state's recovery");
}

TEST_F(SimTimestampsTest, WhileDynamicsAreSuspendedTheFrozenStateIsOfTheCurrentTime) {
  run_for(0.05);
  ASSERT_EQ(call("simulation", "suspend_dynamics").status, Status::success);
  sim_->step();
  const double z = value("rover.pose", "get_local_data")["z"].get<double>();
  for (int i = 0; i < 3; ++i) {
    sim_->step();
    expect_all_stamped(sim_->sim_time(), "suspended");
    EXPECT_EQ(value("rover.pose", "get_local_data")["z"].get<double>(), z);  // nothing moves
  }
  ASSERT_EQ(call("simulation", "restore_dynamics").status, Status::success);
  const double started = sim_->sim_time();
  sim_->step();
  expect_all_stamped(started, "restored");
}

TEST_F(MjcfSim, WithTheRk4IntegratorEachStepIsEvaluatedWhereItEnded) {
  // RK4's last intermediate stage would leave xpos of no particular time, the sensors of the
  // step's start: the simulation evaluates the end state, and every sensor says so
  load_string(R"(<mujoco><option integrator="RK4" timestep="0.01"/><worldbody>
    <body name="ball" pos="0 0 1"><freejoint name="ball_free"/><geom type="sphere" size="0.1"/></body></worldbody>
    <sensor><framepos name="z" objtype="xbody" objname="ball"/><clock name="clock"/></sensor></mujoco>)");
  Robot& ball = add_robot("ball", "ball");
  sim_->add_component(
      registry_.create(Kind::component, {"ball.pose", "pose", "ball", "robots[0].components[0]"},
                       json::object(), *sim_, &ball),
      "pose", "ball");
  add_component(ball, "sensors", "sensors", {{"sensors", {"z", "clock"}}});
  serve();
  run_for(0.2);
  json pose = value("ball.pose", "get_local_data");
  json sensors = value("ball.sensors", "get_local_data");
  EXPECT_EQ(pose["timestamp"].get<double>(), sim_->sim_time());
  EXPECT_EQ(sensors["timestamp"].get<double>(), sim_->sim_time());
  EXPECT_EQ(sensors["clock"].get<double>(), sim_->sim_time());
  EXPECT_EQ(pose["z"].get<double>(), sensors["z"][2].get<double>());
  EXPECT_EQ(pose["z"].get<double>(), sim_->d()->qpos[2]);  // the free joint's z: where it is now
  EXPECT_LT(pose["z"].get<double>(), 0.9);                 // it fell
}

TEST_F(MjcfSim, AnRk4StepGivesBitForBitWhatMjStepAndAnEvaluationGive) {
  // Simulation::take_mj_step leaves out mj_step's own evaluation when the state and its
  // inputs are the ones the previous step's evaluation saw, and its position and velocity
  // stages when only the inputs changed: the same numbers, to the bit, as mj_step then
  // mj_forward (the reference, a copy stepped alongside) with controls kept for a few steps
  // then changed, applied forces and the solver's warm start changed between two steps,
  // contacts, an accelerometer (acceleration stage), a mocap body and a joint moved between
  // two steps (which need the whole evaluation)
  load_string(R"(<mujoco><option integrator="RK4" timestep="0.005"/><worldbody>
    <geom type="plane" size="5 5 0.1"/>
    <body name="target" mocap="true" pos="0 1 0.5"><geom type="box" size="0.05 0.05 0.05" contype="0" conaffinity="0"/></body>
    <body name="arm" pos="0 0 0.3"><joint name="hinge" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.04"/><site name="tip" pos="0.3 0 0"/>
      <body pos="0.3 0 0"><joint name="slide" type="slide" axis="1 0 0" range="-0.1 0.1"/>
        <geom type="sphere" size="0.06"/></body></body>
    <body name="ball" pos="0.5 0.5 0.2"><freejoint/><geom type="sphere" size="0.08"/></body>
  </worldbody>
  <equality><weld body1="target" body2="ball" active="false"/></equality>
  <actuator><motor joint="hinge" gear="2"/><position joint="slide" kp="50"/></actuator>
  <sensor><accelerometer site="tip"/><framepos objtype="xbody" objname="ball"/></sensor></mujoco>)");
  mjModel* m = sim_->m();
  mjData* d = sim_->d();
  std::unique_ptr<mjData, void (*)(mjData*)> ref(mj_makeData(m), mj_deleteData);
  mj_copyData(ref.get(), m, d);
  const auto same = [&](const char* what, const mjtNum* a, const mjtNum* b, int n, int step) {
    ASSERT_EQ(std::memcmp(a, b, sizeof(mjtNum) * static_cast<std::size_t>(n)), 0)
        << what << " differs after step " << step;
  };
  for (int step = 1; step <= 400; ++step) {
    const int held = step / 3 * 3;  // controls kept for three steps
    const double ctrl[2] = {std::sin(held * 0.05), 0.1 * std::cos(held * 0.03)};
    for (mjData* data : {d, ref.get()}) {
      data->ctrl[0] = ctrl[0];
      data->ctrl[1] = ctrl[1];
      if (step == 100) data->qfrc_applied[0] = 0.3;        // an applied force...
      if (step == 110) data->xfrc_applied[6 * 4 + 2] = 5;  // ...and one on the ball
      if (step == 121)                                     // as restoring a state does
        for (int k = 0; k < m->nv; ++k) data->qacc_warmstart[k] += 1e-3;
      if (step == 150) data->mocap_pos[0] = 0.2;  // moved between two steps
      if (step == 250) data->eq_active[0] = 1;    // the weld switched on
    }
    if (step == 300) {  // a joint set at once, as a teleport does, then evaluated
      d->qpos[0] = ref->qpos[0] = 0.4;
      sim_->forward();
      mj_forward(m, ref.get());
    }
    sim_->step();
    mj_step(m, ref.get());
    mj_forward(m, ref.get());
    same("qpos", d->qpos, ref->qpos, m->nq, step);
    same("qvel", d->qvel, ref->qvel, m->nv, step);
    same("qacc", d->qacc, ref->qacc, m->nv, step);
    same("qacc_warmstart", d->qacc_warmstart, ref->qacc_warmstart, m->nv, step);
    same("sensordata", d->sensordata, ref->sensordata, m->nsensordata, step);
    same("xpos", d->xpos, ref->xpos, 3 * m->nbody, step);
  }
  EXPECT_GT(sim_->d()->ncon, 0);  // the ball lies on the plane
}

}  // namespace
}  // namespace simgate::sim
