// SimBadState: when MuJoCo finds a bad number in qpos, qvel or qacc it resets its data in the
// middle of mj_step (2.2.2: time back to 0, components never told, only the first time
// logged). The simulation detects it after every step, logs every occurrence (a flood in
// bounded form), and recovers by its divergence policy (scene.on_divergence): `reset` takes
// the path `simulation reset_objects` takes (components get on_reset(), simulated time goes
// on); `pause` undoes the step and pauses; `restore` goes back to the last checkpoint. Every
// async request in flight ends FAILED saying why, get_simulation_state tells what happened,
// and the simulation.events stream tells its subscribers as it happens ("diverged", then
// "paused" or "reset"). A bad control is logged and dropped, without a reset.
#include <cmath>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "simgate/core/log.h"
#include "sim_fixture.h"

namespace simgate::sim {
namespace {

using testing::DemoSim;
using ::testing::HasSubstr;

using testing::k_nan;

// Counts the resets it is told about.
class ResetProbe : public SimComponent {
 public:
  explicit ResetProbe(Simulation& sim, std::string name = "probe")
      : SimComponent(std::move(name), sim) {}
  void on_reset() override { ++resets; }
  int resets = 0;
};

// Its on_reset() throws, as a buggy component's may.
class FaultyReset : public SimComponent {
 public:
  explicit FaultyReset(Simulation& sim) : SimComponent("faulty", sim) {}
  void on_reset() override { throw std::runtime_error("deliberate on_reset failure"); }
};

class SimBadStateTest : public DemoSim {
 protected:
  void SetUp() override {
    DemoSim::SetUp();
    sim_->set_on_divergence(policy_);
    probe_ = static_cast<ResetProbe*>(
        sim_->add_component(std::make_unique<ResetProbe>(*sim_), "probe").component.get());
    log::set_sink([this](log::Level level, std::string_view text) {
      std::lock_guard lock(lines_mutex_);
      if (level == log::Level::warning) warnings_.emplace_back(text);
    });
  }
  void TearDown() override {
    log::set_sink({});
    DemoSim::TearDown();
  }

  // Warning lines containing `text`.
  std::vector<std::string> warnings_with(const std::string& text) {
    std::lock_guard lock(lines_mutex_);
    std::vector<std::string> out;
    for (const auto& line : warnings_)
      if (line.find(text) != std::string::npos) out.push_back(line);
    return out;
  }
  json statistics() { return call("time", "statistics").value.value_or(json::object()); }
  std::uint64_t bad_states() { return statistics().value("bad_states", std::uint64_t{0}); }
  // Address of a free joint's first qpos / dof.
  int qpos_of(const std::string& joint) {
    return sim_->m()->jnt_qposadr[sim_->model().joint_id(joint)];
  }
  int dof_of(const std::string& joint) {
    return sim_->m()->jnt_dofadr[sim_->model().joint_id(joint)];
  }
  // Writes into MuJoCo's state as a faulty component (or a bug) would: under the lock.
  template <class F>
  void corrupt(F&& write) {
    std::lock_guard lock(*sim_->gate());
    write(sim_->d());
  }

  json simulation_state() {
    return call("simulation", "get_simulation_state").value.value_or(json::object());
  }

  // Subscribes to the simulation's event stream (carried by the test transport).
  std::shared_ptr<StreamSubscription> subscribe_to_events() {
    sim_->streams().add(*sim_->find("simulation.events")->component, "events", {"test"});
    return sim_->streams().subscribe("simulation.events", "test", {64, "test", {}});
  }
  // The events the subscription holds, oldest first.
  static std::vector<json> events_of(StreamSubscription& subscription) {
    std::vector<SamplePtr> samples;
    subscription.take(samples);
    std::vector<json> out;
    for (const auto& s : samples) out.push_back(s->data());
    return out;
  }

  DivergencePolicy policy_ = DivergencePolicy::reset;  // the tests below: the reset path
  ResetProbe* probe_ = nullptr;
  std::mutex lines_mutex_;             // the sink may be called from any thread
  std::vector<std::string> warnings_;  // every warning logged during the test
};

TEST_F(SimBadStateTest, AHugeQposIsLoggedAndRecoveredThroughTheResetPathKeepingTime) {
  call("robot.motion", "set_speed", {1.0, 0.0});
  run_for(0.5);
  ASSERT_GT(pose()["x"].get<double>(), 0.2);
  const double before = sim_->sim_time();
  corrupt([&](mjData* d) { d->qpos[qpos_of("robot_root")] = 1e11; });  // beyond mjMAXVAL
  sim_->step();
  // time went on by one step (MuJoCo alone took it back to 0.002)
  EXPECT_NEAR(sim_->sim_time(), before + sim_->timestep(), 1e-9);
  // the reset path ran: components were told, the world is at its initial state
  EXPECT_EQ(probe_->resets, 1);
  EXPECT_NEAR(pose()["x"].get<double>(), 0.0, 1e-6);
  EXPECT_EQ(bad_states(), 1u);
  auto lines = warnings_with("simulation: bad state");
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_THAT(lines[0], HasSubstr("qpos"));
  EXPECT_THAT(lines[0], HasSubstr("joint 'robot_root' of body 'robot'"));
  EXPECT_THAT(lines[0], HasSubstr("t=0.5"));
  // and it keeps stepping: the robot obeys a new command (the old one was dropped by on_reset)
  run_for(0.5);
  EXPECT_NEAR(pose()["x"].get<double>(), 0.0, 0.01);
  EXPECT_NEAR(sim_->sim_time(), before + sim_->timestep() + 0.5, 0.01);
  call("robot.motion", "set_speed", {1.0, 0.0});
  run_for(0.5);
  EXPECT_GT(pose()["x"].get<double>(), 0.2);
}

TEST_F(SimBadStateTest, ANanQvelIsRecoveredTheSameWay) {
  run_for(0.2);
  const double before = sim_->sim_time();
  corrupt([&](mjData* d) { d->qvel[dof_of("human_root") + 1] = k_nan; });
  sim_->step();
  EXPECT_GT(sim_->sim_time(), before);
  EXPECT_EQ(probe_->resets, 1);
  auto lines = warnings_with("simulation: bad state");
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_THAT(lines[0], HasSubstr("qvel"));
  EXPECT_THAT(lines[0], HasSubstr("joint 'human_root' of body 'human'"));
  run_for(0.2);
  EXPECT_NEAR(sim_->sim_time(), before + sim_->timestep() + 0.2, 0.01);
}

TEST_F(SimBadStateTest, AHugeAccelerationIsRecoveredTheSameWay) {
  run_for(0.2);
  const double before = sim_->sim_time();
  // a force no body of the scene can take: qacc beyond mjMAXVAL
  corrupt([&](mjData* d) { d->qfrc_applied[dof_of("human_root")] = 1e20; });
  sim_->step();
  EXPECT_GT(sim_->sim_time(), before);
  EXPECT_EQ(probe_->resets, 1);
  auto lines = warnings_with("simulation: bad state");
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_THAT(lines[0], HasSubstr("qacc"));
  EXPECT_EQ(sim_->d()->qfrc_applied[dof_of("human_root")], 0.0);  // the force went with the state
  run_for(0.2);
  EXPECT_NEAR(pose()["z"].get<double>(), 0.1, 0.01);  // the robot stands where it started
}

TEST_F(SimBadStateTest, RunningRequestsEndFailedSayingWhy) {
  // before, they went on in a world they were not started in, and their clients were never
  // told (issue #35, item 1)
  RequestId sleep = rm_->call("time", "sleep", {0.5});
  RequestId go = rm_->call("robot.waypoint", "goto", {1.0, 0.0, 0.0, 0.2});
  sim_->process_requests();
  run_for(0.2);
  corrupt([&](mjData* d) { d->qpos[qpos_of("robot_root")] = k_nan; });
  sim_->step();
  EXPECT_EQ(probe_->resets, 1);
  sim_->process_requests();  // the manager hands the outcomes over
  for (RequestId id : {sleep, go}) {
    auto o = rm_->outcome(id);
    ASSERT_TRUE(o.has_value());
    EXPECT_EQ(o->status, Status::failed);
    EXPECT_THAT(o->message, HasSubstr("the simulation diverged in the step from t=0.2"));
    EXPECT_THAT(o->message, HasSubstr("qpos"));
    EXPECT_THAT(o->message, HasSubstr("restored the initial state"));
  }
  // the goto was stopped: the robot stays where the reset put it
  run_for(0.3);
  EXPECT_NEAR(pose()["x"].get<double>(), 0.0, 0.01);
  json state = simulation_state();
  EXPECT_EQ(state["divergences"], 1);
  EXPECT_EQ(state["on_divergence"], "reset");
  EXPECT_EQ(state["last_divergence"]["action"], "reset");
  EXPECT_EQ(state["last_divergence"]["where"], "joint 'robot_root' of body 'robot'");
}

TEST_F(SimBadStateTest, AFloodIsCountedInFullAndLoggedInBoundedForm) {
  run_for(0.01);
  double last = sim_->sim_time();
  for (int i = 0; i < 120; ++i) {
    corrupt([&](mjData* d) { d->qpos[qpos_of("human_root")] = 1e12; });
    sim_->step();
    ASSERT_GT(sim_->sim_time(), last) << "time went back at bad state " << i + 1;
    last = sim_->sim_time();
  }
  EXPECT_EQ(probe_->resets, 120);
  EXPECT_EQ(bad_states(), 120u);
  // the first ten, then the 100th: eleven lines for 120 bad states
  auto lines = warnings_with("simulation: bad state");
  ASSERT_EQ(lines.size(), 11u);
  EXPECT_THAT(lines[9], HasSubstr("further bad states are counted"));
  EXPECT_THAT(lines[10], HasSubstr("bad state 100"));
  // MuJoCo's own message appears once: its counter is not zeroed by the recoveries
  EXPECT_EQ(warnings_with("MuJoCo: Nan, Inf or huge value in QPOS").size(), 1u);
}

TEST_F(SimBadStateTest, ABadControlIsLoggedAndDroppedWithoutAReset) {
  run_for(0.1);
  const double before = sim_->sim_time();
  const int left = sim_->model().actuator_id("robot_left_motor");
  corrupt([&](mjData* d) { d->ctrl[left] = k_nan; });
  sim_->step();
  EXPECT_NEAR(sim_->sim_time(), before + sim_->timestep(), 1e-9);
  EXPECT_EQ(probe_->resets, 0);  // the state itself was sound
  EXPECT_EQ(sim_->d()->ctrl[left], 0.0);
  auto lines = warnings_with("simulation: bad control");
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_THAT(lines[0], HasSubstr("actuator 'robot_left_motor'"));
  // once dropped, nothing more to say
  run_for(0.1);
  EXPECT_EQ(warnings_with("simulation: bad control").size(), 1u);
  EXPECT_EQ(bad_states(), 0u);
}

TEST_F(SimBadStateTest, AComponentWhoseOnResetThrowsIsSwitchedOffAndTheOthersAreResetAllTheSame) {
  sim_->add_component(std::make_unique<FaultyReset>(*sim_), "faulty");
  // reset after the faulty one: a throw used to end the reset there (and reset_objects FAILED)
  auto& later = static_cast<ResetProbe&>(
      *sim_->add_component(std::make_unique<ResetProbe>(*sim_, "later"), "probe").component);
  EXPECT_EQ(call("simulation", "reset_objects").status, Status::success);
  EXPECT_EQ(later.resets, 1);
  EXPECT_FALSE(sim_->find("faulty")->active);
  // the recovery from a bad state takes the same path: the step does not throw
  run_for(0.1);
  corrupt([&](mjData* d) { d->qpos[qpos_of("robot_root")] = 1e11; });
  EXPECT_NO_THROW(sim_->step());
  EXPECT_EQ(later.resets, 2);
}

TEST_F(SimBadStateTest, SubscribersOfTheEventStreamHearOfTheDivergenceThenOfTheReset) {
  auto events = subscribe_to_events();
  run_for(0.1);
  const double before = sim_->sim_time();
  corrupt([&](mjData* d) { d->qpos[qpos_of("robot_root")] = 1e11; });
  sim_->step();
  const std::vector<json> told = events_of(*events);
  ASSERT_EQ(told.size(), 2u);
  // the divergence, with get_simulation_state's last_divergence fields, then what was done
  EXPECT_EQ(told[0]["event"], "diverged");
  EXPECT_EQ(told[0]["action"], "reset");
  EXPECT_EQ(told[0]["quantity"].get<std::string>().substr(0, 5), "qpos[");
  EXPECT_THAT(told[0]["where"].get<std::string>(), HasSubstr("robot_root"));
  EXPECT_NEAR(told[0]["sim_time"].get<double>(), before, 1e-12);
  EXPECT_EQ(told[0]["divergences"], 1);
  EXPECT_THAT(told[0]["message"].get<std::string>(), HasSubstr("the simulation diverged"));
  json last = simulation_state()["last_divergence"];
  for (const char* key : {"sim_time", "step", "quantity", "where", "action", "resumed_at"})
    EXPECT_EQ(told[0][key], last[key]) << key;
  EXPECT_EQ(told[1]["event"], "reset");
  EXPECT_EQ(told[1]["by"], "simulation");
  EXPECT_NEAR(told[1]["timestamp"].get<double>(), last["resumed_at"].get<double>(), 1e-12);
}

// ---- the default policy: pause in the state before the bad step

class SimDivergencePauseTest : public SimBadStateTest {
 protected:
  SimDivergencePauseTest() { policy_ = DivergencePolicy::pause; }
};

TEST_F(SimDivergencePauseTest, TheStepIsUndoneAndTheSimulationPausesTellingEveryone) {
  EXPECT_EQ(SimulationOptions{}.on_divergence, DivergencePolicy::pause);  // the default
  call("robot.motion", "set_speed", {1.0, 0.0});
  run_for(0.5);
  RequestId sleep = rm_->call("time", "sleep", {5.0});
  sim_->process_requests();
  const double x = sim_->d()->qpos[qpos_of("robot_root")];
  const double before = sim_->sim_time();
  const std::uint64_t steps = sim_->steps();
  // a force no body of the scene can take: MuJoCo resets in the step (before: the world
  // went back to its initial state and only the log said so)
  corrupt([&](mjData* d) { d->qfrc_applied[dof_of("human_root")] = 1e20; });
  sim_->step();
  // the world as the step found it: same time, same pose, not counted as a step
  EXPECT_EQ(sim_->sim_time(), before);
  EXPECT_EQ(sim_->steps(), steps);
  EXPECT_EQ(sim_->d()->qpos[qpos_of("robot_root")], x);
  EXPECT_EQ(sim_->d()->qfrc_applied[dof_of("human_root")],
            1e20);  // the cause is still there, to be seen
  EXPECT_TRUE(sim_->paused());
  EXPECT_EQ(probe_->resets, 0);
  sim_->process_requests();
  auto o = rm_->outcome(sleep);
  ASSERT_TRUE(o.has_value());
  EXPECT_EQ(o->status, Status::failed);
  EXPECT_THAT(o->message, HasSubstr("paused in the state before that step"));
  json state = simulation_state();
  EXPECT_EQ(state["state"], "paused");
  EXPECT_EQ(state["divergences"], 1);
  const json& last = state["last_divergence"];
  EXPECT_EQ(last["action"], "pause");
  EXPECT_EQ(last["quantity"].get<std::string>().substr(0, 5), "qacc[");
  EXPECT_NEAR(last["sim_time"].get<double>(), before, 1e-12);
  EXPECT_EQ(last["step"], steps);
  EXPECT_NEAR(last["resumed_at"].get<double>(), before, 1e-12);
  auto lines = warnings_with("simulation: bad state");
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_THAT(lines[0], HasSubstr("scene.on_divergence pause"));
  // the client removes the cause and plays on from there
  corrupt([&](mjData* d) { d->qfrc_applied[dof_of("human_root")] = 0; });
  EXPECT_EQ(call("simulation", "play").status, Status::success);
  sim_->step();
  EXPECT_GT(sim_->sim_time(), before);
  EXPECT_GT(sim_->d()->qpos[qpos_of("robot_root")], x);
}

TEST_F(SimDivergencePauseTest,
       SubscribersOfTheEventStreamHearOfTheDivergenceThenOfThePauseAndOfThePlay) {
  auto events = subscribe_to_events();
  run_for(0.2);
  const double before = sim_->sim_time();
  corrupt([&](mjData* d) { d->qfrc_applied[dof_of("human_root")] = 1e20; });
  sim_->step();
  std::vector<json> told = events_of(*events);
  ASSERT_EQ(told.size(), 2u);
  EXPECT_EQ(told[0]["event"], "diverged");
  EXPECT_EQ(told[0]["action"], "pause");
  EXPECT_EQ(told[0]["quantity"].get<std::string>().substr(0, 5), "qacc[");
  EXPECT_NEAR(told[0]["resumed_at"].get<double>(), before, 1e-12);
  EXPECT_NEAR(told[0]["timestamp"].get<double>(), before, 1e-12);  // not MuJoCo's reset clock
  EXPECT_EQ(told[1]["event"], "paused");
  EXPECT_EQ(told[1]["by"], "simulation");  // its policy, not a client
  EXPECT_NEAR(told[1]["timestamp"].get<double>(), before, 1e-12);
  // a client plays on: told too, naming the transport its request came through
  corrupt([&](mjData* d) { d->qfrc_applied[dof_of("human_root")] = 0; });
  EXPECT_EQ(call("simulation", "play").status, Status::success);
  told = events_of(*events);
  ASSERT_EQ(told.size(), 1u);
  EXPECT_EQ(told[0]["event"], "resumed");
  EXPECT_EQ(told[0]["by"], "test");
}

TEST_F(SimDivergencePauseTest, AStepRequestThatDivergesEndsFailedWithTheStepsLeftForgiven) {
  EXPECT_EQ(call("simulation", "pause").status, Status::success);
  corrupt([&](mjData* d) { d->qpos[qpos_of("robot_root")] = 1e11; });
  RequestId stepping = rm_->call("simulation", "step", {100});
  sim_->process_requests();
  for (int i = 0; i < 10 && sim_->owed_steps() > 0; ++i)
    sim_->take_owed_steps(std::chrono::steady_clock::now());
  auto o = rm_->outcome(stepping);
  ASSERT_TRUE(o.has_value());
  EXPECT_EQ(o->status, Status::failed);
  EXPECT_THAT(o->message, HasSubstr("the simulation diverged"));
  EXPECT_EQ(sim_->owed_steps(), 0u);
  EXPECT_EQ(sim_->sim_time(), 0.0);
}

// ---- restore: the last checkpoint

class SimDivergenceRestoreTest : public SimBadStateTest {
 protected:
  SimDivergenceRestoreTest() { policy_ = DivergencePolicy::restore; }
};

TEST_F(SimDivergenceRestoreTest, TheLastCheckpointIsPutBackAndTheSimulationGoesOn) {
  call("robot.motion", "set_speed", {1.0, 0.0});
  run_for(1.5);  // a checkpoint at 1 s
  corrupt([&](mjData* d) { d->qpos[qpos_of("robot_root")] = 1e11; });
  sim_->step();
  EXPECT_FALSE(sim_->paused());
  EXPECT_NEAR(sim_->sim_time(), 1.0, 2 * sim_->timestep());
  EXPECT_EQ(probe_->resets, 1);
  json last = simulation_state()["last_divergence"];
  EXPECT_EQ(last["action"], "restore");
  EXPECT_NEAR(last["resumed_at"].get<double>(), 1.0, 2 * sim_->timestep());
  EXPECT_THAT(warnings_with("simulation: bad state").at(0),
              HasSubstr("went back to its checkpoint of t=1"));
  run_for(0.1);
  EXPECT_GT(sim_->sim_time(), 1.05);
}

TEST_F(SimDivergenceRestoreTest, WithoutACheckpointYetTheInitialStateIsTaken) {
  // a state that diverges in its first step is no checkpoint: the world resets
  corrupt([&](mjData* d) { d->qpos[qpos_of("robot_root")] = 1e11; });
  sim_->step();
  EXPECT_EQ(simulation_state()["last_divergence"]["action"], "reset");
  EXPECT_NEAR(pose()["x"].get<double>(), 0.0, 1e-6);
  EXPECT_EQ(probe_->resets, 1);
}

}  // namespace
}  // namespace simgate::sim
