// SimLoop: the real step loop — requests are served as they arrive (not once per frame),
// pacing never steps early, stop ends run().
#include <atomic>
#include <limits>
#include <thread>

#include "sim_fixture.h"

namespace simgate::sim {
namespace {

constexpr const char* k_loop_scene = R"(<mujoco><option timestep="0.01"/><worldbody>
  <body name="ball" pos="0 0 1"><freejoint/><geom type="sphere" size=".1"/></body>
</worldbody></mujoco>)";

class SimLoopTest : public ::testing::Test {
 protected:
  void start(double timestep, double factor) {
    SimulationOptions options = options_;
    options.timestep = timestep;
    options.realtime_factor = factor;
    sim_ = std::make_unique<Simulation>(Model::load_string(k_loop_scene), options);
    add_world_components(*sim_);
    rm_ = std::make_shared<testing::RecordingManager>();
    for (auto& e : sim_->components()) rm_->register_component(*e->component);
    sim_->add_request_manager(rm_, "test");
    thread_ = std::thread([this] { sim_->run(); });
  }
  void TearDown() override {
    if (sim_) sim_->request_stop();
    if (thread_.joinable()) thread_.join();
    rm_.reset();
    sim_.reset();
  }
  Outcome call(const std::string& c, const std::string& s, json params = json::array()) {
    auto o = rm_->wait(rm_->call(c, s, std::move(params)), std::chrono::seconds(20));
    EXPECT_TRUE(o.has_value()) << c << " " << s;
    return o.value_or(Outcome::failed(Failure::internal, "timeout"));
  }

  // Waits (bounded: 10 s) until the loop has taken `n` steps.
  void wait_for_steps(std::uint64_t n) {
    for (int i = 0; i < 2000 && sim_->steps() < n; ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  // `component service`'s answer once its `key` counts one or more (bounded: 10 s), or the last.
  json answer_once_counted(const std::string& component, const std::string& service,
                           const char* key) {
    json answer;
    for (int i = 0; i < 2000; ++i) {
      answer = call(component, service).value.value_or(json::object());
      if (answer.value(key, 0) >= 1) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return answer;
  }

  SimulationOptions options_;  // start() sets the timestep and the factor
  std::unique_ptr<Simulation> sim_;
  std::shared_ptr<testing::RecordingManager> rm_;
  std::thread thread_;
};

// A transport serves before the loop runs (they start first): get_simulation_state's
// statistics, read under the lock while run() begins, see the loop's start written under it
// too (ThreadSanitizer saw a race here when run() wrote it unlocked: E2E.worlds, whose
// worlds' loops start while clients call).
TEST_F(SimLoopTest, StatisticsReadWhileTheLoopStartsAreUnderTheLock) {
  sim_ = std::make_unique<Simulation>(Model::load_string(k_loop_scene), options_);
  std::atomic<bool> reading{true};
  std::thread reader([&] {
    for (int i = 0; i < 200000 && reading.load(); ++i) {
      std::lock_guard lock(*sim_->gate());
      (void)sim_->statistics();
    }
  });
  thread_ = std::thread([this] { sim_->run(); });
  wait_for_steps(3);
  reading = false;
  reader.join();
  std::lock_guard lock(*sim_->gate());
  EXPECT_GT(sim_->statistics().wall_time, 0.0);
}

TEST_F(SimLoopTest, RequestsAreServedBetweenStepsNotOncePerFrame) {
  // one step every 30 s of wall time: every answer below arrives long before the next step
  start(30.0, 1.0);
  // the first step happens at once; wait (bounded) for it
  wait_for_steps(1);
  ASSERT_EQ(sim_->steps(), 1u);
  for (int i = 0; i < 20; ++i) {
    Outcome o = call("time", "statistics");
    ASSERT_EQ(o.status, Status::success);
    EXPECT_EQ((*o.value)["steps"].get<std::uint64_t>(), 1u);  // answered without stepping
  }
}

TEST_F(SimLoopTest, AsFastAsPossibleRunsMoreThanRealTime) {
  start(0.01, 0.0);
  // wait (bounded) until 1000 steps have run: 10 s of simulated time
  for (int i = 0; i < 2000 && sim_->steps() < 1000; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_GE(sim_->steps(), 1000u);
}

TEST_F(SimLoopTest, QuitEndsTheLoop) {
  start(0.01, 1.0);
  EXPECT_EQ(call("simulation", "quit").status, Status::success);
  thread_.join();  // returns: the loop ended by itself
  EXPECT_TRUE(sim_->stop_requested());
}

TEST_F(SimLoopTest, ShutdownAnswersPendingAsyncRequests) {
  start(0.01, 1.0);
  RequestId id = rm_->call("time", "sleep", {1000.0});
  // make sure it started, then stop
  EXPECT_EQ(call("time", "now").status, Status::success);
  sim_->request_stop();
  thread_.join();
  sim_->shutdown();
  auto o = rm_->outcome(id);
  ASSERT_TRUE(o.has_value());
  EXPECT_NE(o->status, Status::success);
  EXPECT_EQ(o->failure, Failure::shutdown);
}

TEST_F(SimLoopTest, ATransportThreadRunsRequestsItselfWhileTheLoopWaits) {
  // one step every 30 s: the loop waits, the simulation lock is free
  start(30.0, 1.0);
  wait_for_steps(1);
  ASSERT_EQ(sim_->steps(), 1u);
  RequestId id = rm_->new_request_id();
  // the loop may still be finishing its first iteration: retry (bounded) until the lock is free
  bool ran_here = false;
  for (int i = 0; i < 200 && !ran_here; ++i) {
    ran_here = rm_->run_or_submit(id, Call{"time", "statistics", json::array()});
    if (!ran_here) {
      ASSERT_TRUE(rm_->wait(id, std::chrono::seconds(20)));
      id = rm_->new_request_id();
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  }
  ASSERT_TRUE(ran_here);
  // answered before run_or_submit returned, without a step
  auto o = rm_->outcome(id);
  ASSERT_TRUE(o);
  EXPECT_EQ((*o->value)["steps"].get<std::uint64_t>(), 1u);
}

TEST_F(SimLoopTest, ABadStateWhileRunningIsRecoveredAndTheLoopGoesOn) {
  options_.on_divergence = DivergencePolicy::reset;
  start(0.01, 1.0);
  wait_for_steps(10);
  ASSERT_GE(sim_->steps(), 10u);
  // what a faulty component would do: a NaN into MuJoCo's state, under the simulation lock
  double before = 0;
  {
    std::lock_guard lock(*sim_->gate());
    before = sim_->sim_time();
    sim_->d()->qvel[0] = std::numeric_limits<double>::quiet_NaN();
  }
  // the loop's next step finds it and recovers (bounded wait, no timing asserted)
  json s = answer_once_counted("time", "statistics", "bad_states");
  ASSERT_EQ(s.value("bad_states", 0), 1);
  EXPECT_GT(s["sim_time"].get<double>(), before);  // MuJoCo alone restarted it from 0
  // and the loop goes on stepping from there
  const std::uint64_t steps = s["steps"].get<std::uint64_t>();
  wait_for_steps(steps + 10);
  EXPECT_GE(sim_->steps(), steps + 10);
  EXPECT_GT(call("time", "statistics").value.value_or(json::object()).value("sim_time", 0.0),
            before + 0.05);
}

TEST_F(SimLoopTest, ABadStateWhileRunningPausesTheLoopUntilAClientPlaysAgain) {
  start(0.01, 1.0);  // the default policy: pause
  wait_for_steps(10);
  ASSERT_GE(sim_->steps(), 10u);
  {
    std::lock_guard lock(*sim_->gate());
    sim_->d()->qvel[0] = std::numeric_limits<double>::quiet_NaN();
  }
  json state = answer_once_counted("simulation", "get_simulation_state", "divergences");
  ASSERT_EQ(state.value("divergences", 0), 1) << state;
  EXPECT_EQ(state["state"], "paused");
  const std::uint64_t steps = state["steps"].get<std::uint64_t>();
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(sim_->steps(), steps);  // paused: no step of its own
  // the client removes the cause and plays: the loop steps again
  {
    std::lock_guard lock(*sim_->gate());
    sim_->d()->qvel[0] = 0;
  }
  EXPECT_EQ(call("simulation", "play").status, Status::success);
  wait_for_steps(steps + 10);
  EXPECT_GE(sim_->steps(), steps + 10);
  EXPECT_EQ(call("simulation", "get_simulation_state")
                .value.value_or(json::object())
                .value("divergences", 0),
            1);
}

// Counts what it sees: a service must never run while a step is under way.
class StepProbe : public Component {
 public:
  StepProbe() : Component("probe") { add_service("look", &StepProbe::look); }
  void default_action() override {
    stepping_ = true;
    std::this_thread::yield();  // widen the window a concurrent service would fall in
    stepping_ = false;
  }
  int look() {
    if (stepping_) ++overlaps;
    return ++looks;
  }
  int overlaps = 0, looks = 0;

 private:
  bool stepping_ = false;
};

TEST(SimLoopLockTest, ServicesNeverRunDuringAStepWhicheverThreadRunsThem) {
  auto sim =
      std::make_unique<Simulation>(Model::load_string(k_loop_scene), SimulationOptions{0.001, 0.0});
  auto& probe = static_cast<StepProbe&>(
      *sim->add_component(std::make_unique<StepProbe>(), "probe").component);
  auto rm = std::make_shared<testing::RecordingManager>();
  rm->register_component(probe);
  sim->add_request_manager(rm, "test");
  std::thread loop([&] { sim->run(); });
  // as fast as possible: the loop holds the lock nearly always; requests run inline when
  // they catch it free and are queued otherwise
  std::vector<RequestId> ids;
  for (int i = 0; i < 500; ++i) {
    RequestId id = rm->new_request_id();
    rm->run_or_submit(id, Call{"probe", "look", json::array()});
    ids.push_back(id);
  }
  for (RequestId id : ids) ASSERT_TRUE(rm->wait(id, std::chrono::seconds(20)));
  sim->request_stop();
  loop.join();
  EXPECT_EQ(probe.looks, 500);
  EXPECT_EQ(probe.overlaps, 0);
  rm.reset();
  sim.reset();
}

TEST(SimLoopOptionsTest, InvalidPacingIsRejected) {
  EXPECT_THROW(Simulation(Model::load_string(k_loop_scene), SimulationOptions{std::nullopt, -1.0}),
               std::invalid_argument);
  EXPECT_THROW(Simulation(Model::load_string(k_loop_scene), SimulationOptions{0.0, 1.0}),
               std::invalid_argument);
}

}  // namespace
}  // namespace simgate::sim
