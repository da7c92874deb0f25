// SimWorldState: simulation reset with a scope, and in-memory snapshots (save_state,
// restore_state, list_states, drop_state) on the demo scene, driven step by step.
#include <cstring>
#include <limits>

#include "mjcf_fixture.h"
#include "sim_fixture.h"
#include "simgate/core/streams.h"

namespace simgate::sim {
namespace {

using ::testing::HasSubstr;

std::vector<mjtNum> copy(const mjtNum* v, int n) { return {v, v + n}; }

using testing::same_bits;

class SimWorldStateTest : public testing::DemoSim {
 protected:
  std::vector<mjtNum> qpos() { return copy(sim_->d()->qpos, sim_->m()->nq); }
  std::vector<mjtNum> qvel() { return copy(sim_->d()->qvel, sim_->m()->nv); }
  // qpos addresses of a robot's root free joint
  int root_qpos(const std::string& body) {
    const int b = mj_name2id(sim_->m(), mjOBJ_BODY, body.c_str());
    return sim_->m()->jnt_qposadr[sim_->m()->body_jntadr[b]];
  }
  std::uint64_t save() {
    Outcome o = call("simulation", "save_state");
    EXPECT_EQ(o.status, Status::success) << o.message;
    return o.value.value_or(json(0)).get<std::uint64_t>();
  }
};

TEST_F(SimWorldStateTest, RestoreThenStepIsBitIdenticalToTheOriginalContinuing) {
  ASSERT_EQ(call("robot.motion", "set_speed", {0.7, 0.4}).status, Status::success);
  ASSERT_EQ(call("human", "move", {0.5, 0.1}).status, Status::success);
  run_for(0.3);
  const std::uint64_t handle = save();
  const double saved_time = sim_->sim_time();
  run_for(0.5);
  const auto qpos_a = qpos();
  const auto qvel_a = qvel();
  const double time_a = sim_->sim_time();

  Outcome o = call("simulation", "restore_state", {handle});
  ASSERT_EQ(o.status, Status::success) << o.message;
  EXPECT_EQ((*o.value)["sim_time"], saved_time);
  EXPECT_EQ(sim_->sim_time(), saved_time);
  // components were reset (commands dropped): the client gives the robot's speed again
  // (the human's step was an action, not a command: it is in the saved state)
  ASSERT_EQ(call("robot.motion", "set_speed", {0.7, 0.4}).status, Status::success);
  run_for(0.5);
  EXPECT_EQ(sim_->sim_time(), time_a);
  EXPECT_TRUE(same_bits(qpos(), qpos_a));
  EXPECT_TRUE(same_bits(qvel(), qvel_a));
}

// Restoring a state changes the world under every client: simulation.events says so (it
// said nothing before), with the state's handle, who asked, and the time it went back to.
TEST_F(SimWorldStateTest, RestoringAStateIsAnnouncedOnTheEventStream) {
  sim_->streams().add(*sim_->find("simulation.events")->component, "events", {"test"});
  auto events = sim_->streams().subscribe("simulation.events", "test", {64, "test", {}});
  run_for(0.2);
  const std::uint64_t handle = save();
  const double saved_time = sim_->sim_time();
  run_for(0.3);
  ASSERT_EQ(call("simulation", "restore_state", {handle}).status, Status::success);
  std::vector<SamplePtr> samples;
  events->take(samples);
  ASSERT_EQ(samples.size(), 1u);
  const json event = samples[0]->data();
  EXPECT_EQ(event["event"], "restored");
  EXPECT_EQ(event["handle"], handle);
  EXPECT_EQ(event["timestamp"], saved_time);
  EXPECT_EQ(event["by"], "test");
}

TEST_F(SimWorldStateTest, ListAndDropStates) {
  const std::uint64_t a = save();
  run_for(0.1);
  const std::uint64_t b = save();
  EXPECT_NE(a, b);
  Outcome list = call("simulation", "list_states");
  ASSERT_EQ(list.status, Status::success);
  ASSERT_EQ(list.value->size(), 2u);
  EXPECT_EQ((*list.value)[0]["handle"], a);
  EXPECT_EQ((*list.value)[1]["handle"], b);
  EXPECT_EQ((*list.value)[0]["sim_time"], 0.0);
  EXPECT_EQ((*list.value)[1]["exact"], true);
  EXPECT_EQ(call("simulation", "drop_state", {a}).status, Status::success);
  EXPECT_EQ(call("simulation", "list_states").value->size(), 1u);
  // a dropped or unknown handle is refused, naming the parameter
  for (const json& bad : {json(a), json(0), json(-3), json(999), json(1.5), json("one"),
                          json(std::numeric_limits<double>::quiet_NaN())}) {
    for (auto service : {"restore_state", "drop_state"}) {
      Outcome o = call("simulation", service, {bad});
      EXPECT_EQ(o.status, Status::failed) << service << " " << bad.dump();
      EXPECT_EQ(o.failure, Failure::bad_arguments) << service << " " << bad.dump();
      EXPECT_THAT(o.message + o.data.dump(), HasSubstr("handle")) << service << " " << bad.dump();
    }
  }
}

TEST_F(SimWorldStateTest, SavingBeyondTheLimitFails) {
  std::size_t saved = 0;
  Outcome o;
  for (int i = 0; i < 1000; ++i) {
    o = call("simulation", "save_state");
    if (o.status != Status::success) break;
    ++saved;
  }
  EXPECT_EQ(saved, 64u);
  EXPECT_EQ(o.status, Status::failed);
  EXPECT_THAT(o.message, HasSubstr("drop one first"));
  // a drop makes room
  EXPECT_EQ(call("simulation", "drop_state", {1}).status, Status::success);
  EXPECT_EQ(call("simulation", "save_state").status, Status::success);
}

// A state of another model generation goes back by name (it was refused before issue #36):
// the same scene compiled anew matches object for object, nothing missing, nothing kept.
TEST_F(SimWorldStateTest, AStateOfAnotherModelGenerationIsRestoredByName) {
  ASSERT_EQ(call("robot.motion", "set_speed", {0.7, 0.4}).status, Status::success);
  run_for(0.3);
  const std::uint64_t handle = save();
  const auto saved_qpos = qpos();
  const auto saved_qvel = qvel();
  run_for(0.3);
  sim_->replace_model(Model::load_file(testing::demo_scene()));  // as a spawn does
  EXPECT_EQ((*call("simulation", "list_states").value)[0]["exact"], false);
  Outcome o = call("simulation", "restore_state", {handle});
  ASSERT_EQ(o.status, Status::success) << o.message;
  EXPECT_EQ((*o.value)["exact"], false);
  for (const char* part : {"missing", "kept"})
    for (const char* kind : {"bodies", "joints", "actuators"})
      EXPECT_TRUE((*o.value)[part][kind].empty()) << part << " " << kind << ": " << o.value->dump();
  EXPECT_TRUE(same_bits(qpos(), saved_qpos));
  EXPECT_TRUE(same_bits(qvel(), saved_qvel));
}

TEST_F(SimWorldStateTest, RestoreEndsRunningRequestsPreempted) {
  const std::uint64_t handle = save();
  RequestId go = rm_->call("robot.waypoint", "goto", {3.0, 0.0, 0.0});
  RequestId nap = rm_->call("time", "sleep", {100.0});
  run_for(0.1);
  ASSERT_FALSE(rm_->outcome(go).has_value());
  ASSERT_EQ(call("simulation", "restore_state", {handle}).status, Status::success);
  sim_->process_requests();
  for (RequestId id : {go, nap}) {
    auto o = rm_->outcome(id);
    ASSERT_TRUE(o.has_value());
    EXPECT_EQ(o->status, Status::preempted);
    EXPECT_THAT(o->message, HasSubstr("restore_state"));
  }
}

TEST_F(SimWorldStateTest, ResetAllPutsObjectsAndTimeBackToTheStart) {
  const auto start = qpos();
  ASSERT_EQ(call("robot.motion", "set_speed", {1.0, 0.5}).status, Status::success);
  RequestId nap = rm_->call("time", "sleep", {100.0});
  run_for(0.4);
  ASSERT_GT(sim_->sim_time(), 0.3);
  Outcome o = call("simulation", "reset", {"all"});
  ASSERT_EQ(o.status, Status::success) << o.message;
  EXPECT_EQ(sim_->sim_time(), 0.0);
  EXPECT_TRUE(same_bits(qpos(), start));
  sim_->process_requests();
  auto slept = rm_->outcome(nap);
  ASSERT_TRUE(slept.has_value());
  EXPECT_EQ(slept->status, Status::preempted);
  EXPECT_THAT(slept->message, HasSubstr("time went back to 0"));
  // the default scope is "all"
  run_for(0.1);
  EXPECT_EQ(call("simulation", "reset").status, Status::success);
  EXPECT_EQ(sim_->sim_time(), 0.0);
}

TEST_F(SimWorldStateTest, ResetStateKeepsTimeGoing) {
  const auto start = qpos();
  ASSERT_EQ(call("robot.motion", "set_speed", {1.0, 0.5}).status, Status::success);
  run_for(0.4);
  const double t = sim_->sim_time();
  ASSERT_EQ(call("simulation", "reset", {"state"}).status, Status::success);
  EXPECT_EQ(sim_->sim_time(), t);
  EXPECT_TRUE(same_bits(qpos(), start));
}

TEST_F(SimWorldStateTest, ResetOneRobotLeavesTheOthersAndTimeAlone) {
  const auto start = qpos();
  ASSERT_EQ(call("robot.motion", "set_speed", {1.0, 0.5}).status, Status::success);
  ASSERT_EQ(call("human", "move", {0.5, 0.0}).status, Status::success);
  RequestId go = rm_->call("robot.waypoint", "goto", {3.0, 0.0, 0.0});
  run_for(0.4);
  const double t = sim_->sim_time();
  const int robot = root_qpos("robot");
  const int human = root_qpos("human");
  const auto moved = qpos();
  ASSERT_NE(moved[robot], start[robot]);
  ASSERT_NE(moved[human], start[human]);

  Outcome o = call("simulation", "reset", {"robot", "robot"});
  ASSERT_EQ(o.status, Status::success) << o.message;
  EXPECT_EQ(sim_->sim_time(), t);
  const auto now = qpos();
  for (int i = 0; i < 7; ++i) {
    EXPECT_EQ(now[robot + i], start[robot + i]) << i;
    EXPECT_EQ(now[human + i], moved[human + i]) << i;
  }
  sim_->process_requests();
  auto went = rm_->outcome(go);
  ASSERT_TRUE(went.has_value());
  EXPECT_EQ(went->status, Status::preempted);
  EXPECT_THAT(went->message, HasSubstr("robot 'robot'"));
}

TEST_F(SimWorldStateTest, ResetRefusesUnknownScopesAndNames) {
  struct Bad {
    json params;
    const char* parameter;
  };
  for (const Bad& bad : {Bad{{"everything"}, "scope"}, Bad{{"robot", "nobody"}, "robot"},
                         Bad{{"robot", "robot.motion"}, "robot"}, Bad{{"robot"}, "robot"},
                         Bad{{"all", "robot"}, "robot"}, Bad{{42}, "scope"}}) {
    Outcome o = call("simulation", "reset", bad.params);
    EXPECT_EQ(o.status, Status::failed) << bad.params.dump();
    EXPECT_EQ(o.failure, Failure::bad_arguments) << bad.params.dump();
    EXPECT_THAT(o.message + o.data.dump(), HasSubstr(bad.parameter))
        << bad.params.dump() << ": " << o.message;
  }
}

TEST_F(SimWorldStateTest, ResetObjectsIsUnchanged) {
  Outcome o = call("simulation", "reset_objects");
  ASSERT_EQ(o.status, Status::success);
  EXPECT_EQ(o.value, json("Objects restored to initial position"));
}

// Resetting a robot zeroes its actuators' activations where MuJoCo 4 keeps them
// (actuator_actadr). The 2.2.2 layout (stateful actuators last) wrote act[-1] for a filter
// actuator before a motor, and left its activation as it was.
class SimResetRobotTest : public testing::MjcfSim {};

TEST_F(SimResetRobotTest, ResettingARobotZeroesItsActivationsWhereverTheyAre) {
  load_string(R"(<mujoco>
    <worldbody><body name="arm"><joint name="hinge"/><geom type="capsule" size=".05" fromto="0 0 0 .3 0 0"/></body></worldbody>
    <actuator>
      <general name="filtered" joint="hinge" dyntype="filter" dynprm="0.5"/>
      <motor name="plain" joint="hinge"/>
    </actuator>
  </mujoco>)");
  add_robot("arm", "arm");
  serve();
  const int filtered = sim_->model().actuator_id("filtered");
  const int act = sim_->m()->actuator_actadr[filtered];
  ASSERT_EQ(act, 0);
  sim_->d()->act[act] = 0.75;
  ASSERT_EQ(call("simulation", "reset", {"robot", "arm"}).status, Status::success);
  EXPECT_EQ(sim_->d()->act[act], 0.0);
}

}  // namespace
}  // namespace simgate::sim
