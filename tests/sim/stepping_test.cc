// SimStepping: simulation get_simulation_state / pause / play / step n, time set_time_scale,
// lockstep (a simulation started paused and driven by steps is bit-for-bit repeatable) and
// the lockstep barrier of several stepping clients (lockstep_join, lockstep_step), on the
// demo scene with the real loop running on its own thread.
#include <cstring>
#include <limits>
#include <thread>

#include "sim_fixture.h"

namespace simgate::sim {
namespace {

using ::testing::HasSubstr;

constexpr auto k_deadline = std::chrono::seconds(30);

class SimSteppingTest : public testing::DemoSim {
 protected:
  // The loop on its own thread, as the gateway runs it.
  void run_loop() {
    thread_ = std::thread([this] { sim_->run(); });
  }
  void TearDown() override {
    stop_loop();
    DemoSim::TearDown();
  }
  void stop_loop() {
    if (sim_) sim_->request_stop();
    if (thread_.joinable()) thread_.join();
  }
  // A call queued for the loop; waits (bounded) for its answer.
  Outcome ask(const std::string& component, const std::string& service,
              json params = json::array()) {
    return wait(rm_->call(component, service, std::move(params)));
  }
  // A call run on this thread when the lock is free, as a TCP transport runs it.
  Outcome ask_here(const std::string& component, const std::string& service,
                   json params = json::array()) {
    return wait(rm_->call_here(component, service, std::move(params)));
  }
  Outcome wait(RequestId id) {
    auto o = rm_->wait(id, k_deadline);
    EXPECT_TRUE(o.has_value()) << "request " << id << " not answered";
    return o.value_or(Outcome::failed(Failure::internal, "not answered"));
  }
  json state() {
    Outcome o = ask("simulation", "get_simulation_state");
    EXPECT_EQ(o.status, Status::success) << o.message;
    return o.value.value_or(json::object());
  }

  std::thread thread_;
};

class SimPausedTest : public SimSteppingTest {
 protected:
  SimPausedTest() { options_.start_paused = true; }
};

TEST_F(SimPausedTest, StartsPausedAndTimeStandsStillWhileRequestsAreServed) {
  run_loop();
  const json first = state();
  EXPECT_EQ(first["state"], "paused");
  EXPECT_EQ(first["sim_time"], 0.0);
  EXPECT_EQ(first["steps"], 0u);
  EXPECT_EQ(first["dynamics_suspended"], false);
  // served while paused, and nothing moves
  for (int i = 0; i < 50; ++i) {
    Outcome o = ask("time", "statistics");
    ASSERT_EQ(o.status, Status::success);
    EXPECT_EQ((*o.value)["steps"], 0u);
    EXPECT_EQ((*o.value)["state"], "paused");
  }
}

TEST_F(SimPausedTest, StepTakesExactlyNStepsAndAnswersTheNewTime) {
  run_loop();
  Outcome o = ask("simulation", "step", {10});
  ASSERT_EQ(o.status, Status::success) << o.message;
  EXPECT_EQ((*o.value)["steps_done"], 10u);
  const json s = state();
  EXPECT_EQ(s["steps"], 10u);
  EXPECT_EQ(s["state"], "paused");
  EXPECT_DOUBLE_EQ((*o.value)["sim_time"].get<double>(), s["sim_time"].get<double>());
  EXPECT_NEAR(s["sim_time"].get<double>(), 10 * sim_->timestep(), 1e-12);
  // the default is one step
  EXPECT_EQ(ask("simulation", "step").status, Status::success);
  EXPECT_EQ(state()["steps"], 11u);
}

TEST_F(SimPausedTest, StepRunsOnTheCallersThreadWhenTheLockIsFree) {
  run_loop();
  // as the socket and JSON-RPC transports call: the steps are taken on this thread and the
  // answer is here when run_or_submit returns (or queued to the loop if it held the lock)
  for (int i = 0; i < 100; ++i)
    ASSERT_EQ(ask_here("simulation", "step", {1}).status, Status::success);
  EXPECT_EQ(state()["steps"], 100u);
  // a long run is left to the loop after the caller's short budget, and still completes
  Outcome o = ask_here("simulation", "step", {5000});
  ASSERT_EQ(o.status, Status::success) << o.message;
  EXPECT_EQ(state()["steps"], 5100u);
}

TEST_F(SimPausedTest, StepRefusesBadCountsNamingN) {
  run_loop();
  for (const json& n :
       {json(0), json(-1), json(1.5), json(1e9), json(std::numeric_limits<double>::quiet_NaN()),
        json(std::numeric_limits<double>::infinity()), json("ten"), json(2'000'000)}) {
    Outcome o = ask("simulation", "step", {n});
    EXPECT_EQ(o.status, Status::failed) << n.dump();
    EXPECT_EQ(o.failure, Failure::bad_arguments) << n.dump();
    EXPECT_THAT(o.message + o.data.dump(), HasSubstr("\"n\""))
        << n.dump() << ": " << o.message << " " << o.data.dump();
  }
  EXPECT_EQ(state()["steps"], 0u);
}

TEST_F(SimPausedTest, CancelEndsAStepPreemptedWithTheStepsDone) {
  run_loop();
  RequestId id = rm_->call("simulation", "step", {1'000'000});
  // it runs (the loop takes the steps one by one); then its client cancels it
  for (int i = 0; i < 100000 && state()["steps"].get<std::uint64_t>() == 0; ++i) {}
  rm_->cancel(id);
  Outcome o = wait(id);
  ASSERT_EQ(o.status, Status::preempted);
  EXPECT_EQ(o.failure, Failure::cancelled);
  const std::uint64_t done = (*o.value)["steps_done"];
  EXPECT_GT(done, 0u);
  EXPECT_LT(done, 1'000'000u);
  EXPECT_EQ((*o.value)["steps_requested"], 1'000'000u);
  // nothing is owed any more: the simulation is paused where the cancel found it
  const json s = state();
  EXPECT_EQ(s["state"], "paused");
  EXPECT_EQ(s["steps"], done);
  EXPECT_EQ(s["owed_steps"], 0u);
}

TEST_F(SimPausedTest, ANewStepPreemptsTheRunningOne) {
  run_loop();
  RequestId first = rm_->call("simulation", "step", {1'000'000});
  Outcome second = ask("simulation", "step", {5});
  EXPECT_EQ(second.status, Status::success) << second.message;
  Outcome o = wait(first);
  ASSERT_EQ(o.status, Status::preempted);
  EXPECT_EQ(o.failure, Failure::preempted);
  EXPECT_EQ(state()["steps"], (*o.value)["steps_done"].get<std::uint64_t>() + 5);
}

TEST_F(SimPausedTest, PauseAndPlayEndARunningStepPreempted) {
  run_loop();
  RequestId id = rm_->call("simulation", "step", {1'000'000});
  EXPECT_EQ(ask("simulation", "pause").status, Status::success);
  Outcome o = wait(id);
  ASSERT_EQ(o.status, Status::preempted);
  EXPECT_THAT(o.message, HasSubstr("pause"));
  EXPECT_EQ(state()["state"], "paused");

  id = rm_->call("simulation", "step", {1'000'000});
  EXPECT_EQ(ask("simulation", "play").status, Status::success);
  o = wait(id);
  ASSERT_EQ(o.status, Status::preempted);
  EXPECT_THAT(o.message, HasSubstr("play"));
}

TEST_F(SimSteppingTest, StepIsRefusedWhilePlaying) {
  run_loop();
  Outcome o = ask("simulation", "step", {1});
  EXPECT_EQ(o.status, Status::failed);
  EXPECT_THAT(o.message, HasSubstr("pause it first"));
}

TEST_F(SimSteppingTest, PauseStopsTimeAndPlayResumesIt) {
  run_loop();
  ASSERT_EQ(ask("simulation", "pause").status, Status::success);
  const json paused = state();
  EXPECT_EQ(paused["state"], "paused");
  for (int i = 0; i < 20; ++i) {
    const json again = state();
    EXPECT_EQ(again["sim_time"], paused["sim_time"]);
    EXPECT_EQ(again["steps"], paused["steps"]);
  }
  ASSERT_EQ(ask("simulation", "play").status, Status::success);
  EXPECT_EQ(state()["state"], "playing");
  // the loop steps again (bounded wait, counted in answers)
  bool moved = false;
  for (int i = 0; i < 100000 && !moved; ++i) moved = state()["steps"] != paused["steps"];
  EXPECT_TRUE(moved);
}

TEST_F(SimSteppingTest, StateReportsSuspendedDynamicsAndTheFactors) {
  EXPECT_EQ(call("simulation", "suspend_dynamics").status, Status::success);
  Outcome o = call("simulation", "get_simulation_state");
  ASSERT_EQ(o.status, Status::success);
  EXPECT_EQ((*o.value)["dynamics_suspended"], true);
  EXPECT_EQ((*o.value)["state"], "playing");
  EXPECT_EQ((*o.value)["target_realtime_factor"], 0.0);
  EXPECT_EQ(call("simulation", "restore_dynamics").status, Status::success);
  EXPECT_EQ((*call("simulation", "get_simulation_state").value)["dynamics_suspended"], false);
}

TEST_F(SimSteppingTest, SetTimeScaleChangesTheFactorModeAndStatistics) {
  Outcome o = call("time", "set_time_scale", {0.5});
  ASSERT_EQ(o.status, Status::success) << o.message;
  EXPECT_EQ(o.value, json(true));  // as MORSE
  EXPECT_EQ(sim_->realtime_factor(), 0.5);
  EXPECT_EQ((*call("time", "statistics").value)["target_realtime_factor"], 0.5);
  EXPECT_EQ(*call("time", "mode").value, "FixedSimulationStep");
  EXPECT_EQ((*call("simulation", "get_simulation_state").value)["target_realtime_factor"], 0.5);
  EXPECT_EQ(call("time", "set_time_scale", {0}).status, Status::success);
  EXPECT_EQ(*call("time", "mode").value, "FixedSimulationStep (as fast as possible)");
  // 1e-300 and 1e-7: a step period no clock holds (1e-300 ran at full speed: issue #35, item 10)
  for (const json& bad : {json(-1), json(std::numeric_limits<double>::quiet_NaN()),
                          json(std::numeric_limits<double>::infinity()), json(1e300), json("fast"),
                          json(1e-300), json(1e-7)}) {
    Outcome refused = call("time", "set_time_scale", {bad});
    EXPECT_EQ(refused.status, Status::failed) << bad.dump();
    EXPECT_EQ(refused.failure, Failure::bad_arguments) << bad.dump();
    EXPECT_THAT(refused.message + refused.data.dump(), HasSubstr("value")) << bad.dump();
  }
  EXPECT_EQ(sim_->realtime_factor(), 0.0);
}

TEST_F(SimSteppingTest, ANewTimeScaleTakesEffectAtOnceInTheRunningLoop) {
  // one step every 100 s of wall time: the loop sleeps until then, unless the new pace wakes it
  ASSERT_EQ(call("time", "set_time_scale", {0.00002}).status, Status::success);
  run_loop();
  ASSERT_EQ(ask("time", "set_time_scale", {0}).status, Status::success);
  bool stepping = false;
  for (int i = 0; i < 100000 && !stepping; ++i)
    stepping = state()["steps"].get<std::uint64_t>() > 100;
  EXPECT_TRUE(stepping);
}

// ---- the lockstep barrier: several clients step together (issue #35, item 11)

class SimLockstepBarrierTest : public SimPausedTest {
 protected:
  // A participant's lockstep_join call: it runs as long as the participant takes part.
  RequestId join(const std::string& name) {
    return rm_->call("simulation", "lockstep_join", {name});
  }
  RequestId ask_steps(const std::string& name, std::int64_t n) {
    return rm_->call("simulation", "lockstep_step", {name, n});
  }
  std::uint64_t steps() { return state()["steps"].get<std::uint64_t>(); }
  json lockstep() { return state()["lockstep"]; }
};

TEST_F(SimLockstepBarrierTest, OneParticipantAskingTakesNoStepTillEveryParticipantHasAsked) {
  run_loop();
  const RequestId a = join("a");
  const RequestId b = join("b");
  EXPECT_EQ(lockstep()["participants"], json({"a", "b"}));
  const RequestId a_asks = ask_steps("a", 5);
  // answered after a's ask was handled (one queue, in order): no step, a waits
  EXPECT_EQ(steps(), 0u);
  EXPECT_EQ(lockstep()["waiting"], json({"a"}));
  EXPECT_EQ(lockstep()["n"], 5);
  EXPECT_FALSE(rm_->outcome(a_asks));
  // b asks: the steps are taken once, and both asks complete with them
  const RequestId b_asks = ask_steps("b", 5);
  for (RequestId id : {a_asks, b_asks}) {
    Outcome o = wait(id);
    ASSERT_EQ(o.status, Status::success) << o.message;
    EXPECT_EQ((*o.value)["steps_done"], 5u);
    EXPECT_NEAR((*o.value)["sim_time"].get<double>(), 5 * sim_->timestep(), 1e-12);
  }
  EXPECT_EQ(steps(), 5u);  // not 10: two clients stepping no longer advance the world twice
  EXPECT_EQ(lockstep()["waiting"], json::array());
  // the next barrier gathers anew
  const RequestId b_again = ask_steps("b", 2);
  EXPECT_EQ(steps(), 5u);
  const RequestId a_again = ask_steps("a", 2);
  EXPECT_EQ(wait(b_again).status, Status::success);
  EXPECT_EQ(wait(a_again).status, Status::success);
  EXPECT_EQ(steps(), 7u);
  // the joins still run: both are still participants
  EXPECT_FALSE(rm_->outcome(a));
  EXPECT_FALSE(rm_->outcome(b));
}

TEST_F(SimLockstepBarrierTest, AParticipantWhoLeavesReleasesTheBarrierTheOthersWaitAt) {
  run_loop();
  join("a");
  const RequestId b = join("b");
  const RequestId a_asks = ask_steps("a", 3);
  EXPECT_EQ(steps(), 0u);
  // b's client leaves (a transport cancels a leaving client's calls): a no longer waits for b
  rm_->cancel(b);
  EXPECT_EQ(wait(b).status, Status::preempted);
  Outcome o = wait(a_asks);
  ASSERT_EQ(o.status, Status::success) << o.message;
  EXPECT_EQ((*o.value)["steps_done"], 3u);
  EXPECT_EQ(steps(), 3u);
  EXPECT_EQ(lockstep()["participants"], json({"a"}));
  // b is unknown now
  Outcome unknown = ask("simulation", "lockstep_step", {"b", 1});
  EXPECT_EQ(unknown.status, Status::failed);
  EXPECT_EQ(unknown.failure, Failure::bad_arguments);
  EXPECT_THAT(unknown.message,
              HasSubstr("participant = \"b\" is not in the lockstep (participants: a)"));
}

TEST_F(SimLockstepBarrierTest, ALeavingParticipantsOwnAskEndsPreempted) {
  run_loop();
  const RequestId a = join("a");
  join("b");
  const RequestId a_asks = ask_steps("a", 1);
  rm_->cancel(a);  // its join only: a leaves, its ask cannot stand
  Outcome o = wait(a_asks);
  EXPECT_EQ(o.status, Status::preempted);
  EXPECT_THAT(o.message, HasSubstr("left the lockstep"));
  EXPECT_EQ(steps(), 0u);
  EXPECT_EQ(lockstep()["participants"], json({"b"}));
}

TEST_F(SimLockstepBarrierTest, APlainStepIsRefusedWhileParticipantsTakePart) {
  run_loop();
  const RequestId a = join("a");
  Outcome o = ask("simulation", "step", {1});
  EXPECT_EQ(o.status, Status::failed);
  EXPECT_THAT(
      o.message,
      HasSubstr("simulation step: the simulation is stepped in lockstep (participants: a)"));
  EXPECT_EQ(steps(), 0u);
  // once the last participant has left, anyone steps again
  rm_->cancel(a);
  wait(a);
  EXPECT_EQ(ask("simulation", "step", {1}).status, Status::success);
  EXPECT_EQ(steps(), 1u);
}

TEST_F(SimLockstepBarrierTest, AJoinEndsARunningStepPreempted) {
  run_loop();
  const RequestId running = rm_->call("simulation", "step", {1'000'000});
  join("a");
  Outcome o = wait(running);
  ASSERT_EQ(o.status, Status::preempted);
  EXPECT_THAT(o.message, HasSubstr("lockstep"));
  const json s = state();
  EXPECT_EQ(s["owed_steps"], 0u);
  EXPECT_EQ(s["steps"], (*o.value)["steps_done"]);
}

TEST_F(SimLockstepBarrierTest, BadAsksAreRefusedClearly) {
  run_loop();
  join("a");
  join("b");
  // n as `step` checks it, in lockstep_step's words
  for (const json& n : {json(0), json(-1), json(1.5), json(2'000'000), json("ten")}) {
    Outcome o = ask("simulation", "lockstep_step", {"a", n});
    EXPECT_EQ(o.status, Status::failed) << n.dump();
    EXPECT_EQ(o.failure, Failure::bad_arguments) << n.dump();
    EXPECT_THAT(o.message + o.data.dump(), HasSubstr("\"n\"")) << n.dump() << ": " << o.message;
  }
  EXPECT_THAT(ask("simulation", "lockstep_step", {"a", 0}).message,
              HasSubstr("simulation lockstep_step: n = 0 is out of range: expected an integer from "
                        "1 to 1000000"));
  // nobody of that name
  Outcome unknown = ask("simulation", "lockstep_step", {"c", 1});
  EXPECT_EQ(unknown.failure, Failure::bad_arguments);
  EXPECT_THAT(unknown.message,
              HasSubstr("participant = \"c\" is not in the lockstep (participants: a, b)"));
  // a name taken
  Outcome taken = ask("simulation", "lockstep_join", {"a"});
  EXPECT_EQ(taken.status, Status::failed);
  EXPECT_THAT(taken.message, HasSubstr("participant 'a' is already in the lockstep"));
  // another n than the barrier's, and a second ask of one participant
  const RequestId a_asks = ask_steps("a", 4);
  Outcome mismatch = ask("simulation", "lockstep_step", {"b", 3});
  EXPECT_EQ(mismatch.failure, Failure::bad_arguments);
  EXPECT_THAT(mismatch.message, HasSubstr("n = 3, but the barrier waits for n = 4 (asked by a)"));
  Outcome twice = ask("simulation", "lockstep_step", {"a", 4});
  EXPECT_EQ(twice.status, Status::failed);
  EXPECT_THAT(twice.message, HasSubstr("participant 'a' already waits at the barrier"));
  EXPECT_EQ(steps(), 0u);
  // the barrier still stands: b's right ask releases it
  EXPECT_EQ(ask("simulation", "lockstep_step", {"b", 4}).status, Status::success);
  EXPECT_EQ(wait(a_asks).status, Status::success);
  EXPECT_EQ(steps(), 4u);
}

TEST_F(SimLockstepBarrierTest, TheJoinsFirstProgressReportNamesTheParticipant) {
  run_loop();
  const RequestId named = rm_->call_with_progress("simulation", "lockstep_join", {"robot_a"});
  const RequestId unnamed = rm_->call_with_progress("simulation", "lockstep_join", json::array());
  EXPECT_EQ(lockstep()["participants"], json({"robot_a", "p1"}));
  // reports made while a request runs go out at the end of its turn, after the sync answers
  // of that turn: one more answer comes after them
  state();
  const std::vector<json> first = rm_->progress(named);
  ASSERT_FALSE(first.empty());
  EXPECT_EQ(first[0]["participant"], "robot_a");
  const std::vector<json> second = rm_->progress(unnamed);
  ASSERT_FALSE(second.empty());
  EXPECT_EQ(second[0]["participant"], "p1");
  EXPECT_EQ(second[0]["participants"], json({"robot_a", "p1"}));
}

TEST_F(SimLockstepBarrierTest, PlayEndsTheWaitingAsksAndLockstepStepIsRefusedWhilePlaying) {
  run_loop();
  join("a");
  join("b");
  const RequestId a_asks = ask_steps("a", 1);
  ASSERT_EQ(ask("simulation", "play").status, Status::success);
  Outcome o = wait(a_asks);
  ASSERT_EQ(o.status, Status::preempted);
  EXPECT_THAT(o.message, HasSubstr("simulation play resumed the simulation"));
  EXPECT_EQ((*o.value)["steps_done"], 0u);
  Outcome playing = ask("simulation", "lockstep_step", {"a", 1});
  EXPECT_EQ(playing.status, Status::failed);
  EXPECT_THAT(playing.message,
              HasSubstr("simulation lockstep_step: the simulation is playing; pause it first"));
  // the participants stay: paused again, they step together as before
  ASSERT_EQ(ask("simulation", "pause").status, Status::success);
  EXPECT_EQ(lockstep()["participants"], json({"a", "b"}));
}

TEST_F(SimLockstepBarrierTest, PauseEndsTheBarriersStepsPreemptedWithTheStepsDone) {
  run_loop();
  join("a");
  join("b");
  const RequestId a_asks = ask_steps("a", 1'000'000);
  const RequestId b_asks = ask_steps("b", 1'000'000);
  ASSERT_EQ(ask("simulation", "pause").status, Status::success);
  std::uint64_t done = 0;
  for (RequestId id : {a_asks, b_asks}) {
    Outcome o = wait(id);
    ASSERT_EQ(o.status, Status::preempted);
    EXPECT_THAT(o.message, HasSubstr("simulation pause stopped the steps"));
    EXPECT_EQ((*o.value)["steps_requested"], 1'000'000u);
    done = (*o.value)["steps_done"];
  }
  const json s = state();
  EXPECT_EQ(s["steps"], done);
  EXPECT_EQ(s["owed_steps"], 0u);
  EXPECT_EQ(s["lockstep"]["stepping"], false);
  // and the next barrier works
  const RequestId a_again = ask_steps("a", 1);
  EXPECT_EQ(ask("simulation", "lockstep_step", {"b", 1}).status, Status::success);
  EXPECT_EQ(wait(a_again).status, Status::success);
  EXPECT_EQ(steps(), done + 1);
}

// ---- lockstep: the same requests and steps from the same start give the same state

struct Trace {
  std::vector<mjtNum> qpos, qvel;
};

class LockstepRun : public SimPausedTest {
 public:
  void TestBody() override {}
  void start() {
    SetUp();
    run_loop();
  }
  // The same script for every run: motion commands between runs of steps, through both
  // the loop's queue and the caller's thread.
  Trace drive() {
    EXPECT_EQ(ask("robot.motion", "set_speed", {0.8, 0.3}).status, Status::success);
    EXPECT_EQ(ask_here("simulation", "step", {250}).status, Status::success);
    EXPECT_EQ(ask("human", "move", {0.5, -0.2}).status, Status::success);
    RequestId go = rm_->call("robot.waypoint", "goto", {1.0, -2.0, 0.0, 0.1, 0.6});
    EXPECT_EQ(ask("simulation", "step", {300}).status, Status::success);
    for (int i = 0; i < 50; ++i)
      EXPECT_EQ(ask_here("simulation", "step", {1}).status, Status::success);
    EXPECT_EQ(ask("robot.waypoint", "stop").status, Status::success);
    EXPECT_EQ(ask("simulation", "step", {400}).status, Status::success);
    rm_->cancel(go);
    EXPECT_EQ(wait(go).status, Status::preempted);
    stop_loop();
    const mjModel* m = sim_->m();
    const mjData* d = sim_->d();
    return {{d->qpos, d->qpos + m->nq}, {d->qvel, d->qvel + m->nv}};
  }
  void finish() { TearDown(); }
};

using testing::same_bits;

TEST(SimLockstepTest, TheSameRequestsAndStepsGiveBitIdenticalStates) {
  std::vector<Trace> traces;
  for (int run = 0; run < 2; ++run) {
    LockstepRun r;
    r.start();
    traces.push_back(r.drive());
    r.finish();
  }
  ASSERT_FALSE(traces[0].qpos.empty());
  EXPECT_TRUE(same_bits(traces[0].qpos, traces[1].qpos));
  EXPECT_TRUE(same_bits(traces[0].qvel, traces[1].qvel));
  // and the robot did move: the comparison is of something
  mjtNum moved = 0;
  for (std::size_t i = 0; i < traces[0].qvel.size(); ++i) moved += std::abs(traces[0].qvel[i]);
  EXPECT_GT(moved, 0.0);
}

}  // namespace
}  // namespace simgate::sim
