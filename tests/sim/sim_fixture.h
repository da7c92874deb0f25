// Test helpers: a request manager that records outcomes, and a fixture holding the demo
// scene with its robot (motion, waypoint, teleport, pose) and human, as fast as possible.
#ifndef SIMGATE_TESTS_SIM_SIM_FIXTURE_H_
#define SIMGATE_TESTS_SIM_SIM_FIXTURE_H_

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <condition_variable>
#include <map>
#include <cstring>
#include <limits>
#include <vector>
#include <mutex>

#include "simgate/core/request_manager.h"
#include "simgate/sim/components.h"
#include "simgate/sim/registry.h"
#include "simgate/sim/simulation.h"
#include "simgate/sim/supervision.h"

namespace simgate::sim::testing {

constexpr double k_nan = std::numeric_limits<double>::quiet_NaN();
constexpr double k_inf = std::numeric_limits<double>::infinity();

// a and b hold the same numbers, bit for bit
inline bool same_bits(const std::vector<mjtNum>& a, const std::vector<mjtNum>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(mjtNum)) == 0;
}

class RecordingManager : public RequestManager {
 public:
  RecordingManager() : RequestManager("Test service manager") {}
  ~RecordingManager() override { stop(); }

  // Like a real transport: what is still pending ends with Failure::shutdown.
  void stop() override { abandon_pending(); }

  RequestId call(const std::string& component, const std::string& service,
                 json params = json::array()) {
    RequestId id = new_request_id();
    submit(id, Call{component, service, std::move(params)});
    return id;
  }
  // As a TCP transport calls: runs the request on this thread when the simulation lock is
  // free (run_or_submit), otherwise queues it.
  RequestId call_here(const std::string& component, const std::string& service,
                      json params = json::array()) {
    RequestId id = new_request_id();
    run_or_submit(id, Call{component, service, std::move(params)});
    return id;
  }
  // A call whose transport sends it the attachments raw (Call::raw_attachments: DDS to a
  // client reading its replies' images).
  RequestId call_raw(const std::string& component, const std::string& service,
                     json params = json::array()) {
    RequestId id = new_request_id();
    Call c{component, service, std::move(params)};
    c.raw_attachments = true;
    submit(id, std::move(c));
    return id;
  }
  // A call whose client asked for progress reports (Call::progress).
  RequestId call_with_progress(const std::string& component, const std::string& service,
                               json params = json::array()) {
    RequestId id = new_request_id();
    Call c{component, service, std::move(params)};
    c.progress = true;
    submit(id, std::move(c));
    return id;
  }
  // The progress reports request `id` got so far, in order.
  std::vector<json> progress(RequestId id) {
    std::lock_guard lock(mutex_);
    auto it = progress_.find(id);
    return it == progress_.end() ? std::vector<json>{} : it->second;
  }
  std::optional<Outcome> outcome(RequestId id) {
    std::lock_guard lock(mutex_);
    auto it = outcomes_.find(id);
    if (it == outcomes_.end()) return std::nullopt;
    return it->second;
  }
  // Waits (bounded) for an outcome delivered by another thread's process().
  std::optional<Outcome> wait(RequestId id, std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    cv_.wait_for(lock, timeout, [&] { return outcomes_.count(id) > 0; });
    auto it = outcomes_.find(id);
    if (it == outcomes_.end()) return std::nullopt;
    return it->second;
  }

 protected:
  void on_service_completion(RequestId id, Outcome&& outcome) override {
    std::lock_guard lock(mutex_);
    outcomes_[id] = std::move(outcome);
    cv_.notify_all();
  }
  void on_service_progress(RequestId id, json&& value) override {
    std::lock_guard lock(mutex_);
    progress_[id].push_back(std::move(value));
  }

 private:
  std::mutex mutex_;                                 // guards outcomes_
  std::condition_variable cv_;                       // outcome arrived
  std::map<RequestId, Outcome> outcomes_;            // delivered outcomes
  std::map<RequestId, std::vector<json>> progress_;  // delivered progress reports
};

// Every qpos, qvel and ctrl of `sim` is a finite number.
inline bool state_is_finite(const Simulation& sim) {
  const mjModel* m = sim.m();
  const mjData* d = sim.d();
  for (int i = 0; i < m->nq; ++i)
    if (!std::isfinite(d->qpos[i])) return false;
  for (int i = 0; i < m->nv; ++i)
    if (!std::isfinite(d->qvel[i])) return false;
  for (int i = 0; i < m->nu; ++i)
    if (!std::isfinite(d->ctrl[i])) return false;
  return true;
}

inline std::string demo_scene() {
  return std::string(SIMGATE_SOURCE_DIR) + "/config/scenes/demo.xml";
}
// The project's own test models (tests/models): among them, what Debian's samples showed that
// the current MuJoCo refuses in them (arm26's muscles, adhesion's <composite>)
inline std::string test_model(const std::string& name) {
  return std::string(SIMGATE_SOURCE_DIR) + "/tests/models/" + name;
}

class DemoSim : public ::testing::Test {
 protected:
  void SetUp() override {
    sim_ = std::make_unique<Simulation>(Model::load_file(demo_scene()), options_);
    auto registry = builtin_registry();
    auto robot = registry.create(Kind::robot, {"robot", "ground_robot", "robot", "robots[0]"},
                                 json::object(), *sim_, nullptr);
    auto* r = static_cast<Robot*>(robot.get());
    sim_->add_component(std::move(robot), "ground_robot", "", true);
    int i = 0;
    for (auto type : {"motion_vw", "waypoint", "teleport", "pose"}) {
      std::string short_name = type == std::string("motion_vw") ? "motion" : type;
      auto c = registry.create(Kind::component,
                               {"robot." + short_name, type, "robot",
                                "robots[0].components[" + std::to_string(i++) + "]"},
                               json::object(), *sim_, r);
      sim_->add_component(std::move(c), type, "robot");
    }
    sim_->add_component(registry.create(Kind::robot, {"human", "human", "human", "robots[1]"},
                                        json::object(), *sim_, nullptr),
                        "human", "", true);
    add_world_components(*sim_);
    rm_ = std::make_shared<RecordingManager>();
    for (auto& e : sim_->components()) {
      rm_->register_component(*e->component);
      e->interfaces.push_back("test");
    }
    sim_->add_request_manager(rm_, "test");
  }
  void TearDown() override {
    rm_.reset();
    sim_.reset();
  }

  // A sync call: submitted, processed, answered.
  Outcome call(const std::string& component, const std::string& service,
               json params = json::array()) {
    RequestId id = rm_->call(component, service, std::move(params));
    sim_->process_requests();
    auto o = rm_->outcome(id);
    EXPECT_TRUE(o.has_value()) << component << " " << service << " not answered";
    return o.value_or(Outcome::failed(Failure::internal, "no answer"));
  }
  // Steps (as the loop would, requests first) until `id` is answered, for a request whose
  // work runs on a worker meanwhile (a model compiling). Bounded by a 30 s deadline.
  Outcome finish(RequestId id) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (std::chrono::steady_clock::now() < deadline) {
      sim_->process_requests();
      if (auto o = rm_->outcome(id)) return *o;
      sim_->step();
    }
    ADD_FAILURE() << "request " << id << " not answered within 30 s";
    return Outcome::failed(Failure::internal, "no answer");
  }
  // Steps (processing requests each step) until `id` is answered or `max_steps` pass.
  // Steps as the simulation's loop does: a step owed to `simulation step` (what its caller's
  // thread did not take within its time budget, k_inline_step_budget) is taken as one, so
  // the outcome does not depend on how fast the machine is.
  std::optional<Outcome> step_until(RequestId id, int max_steps) {
    for (int i = 0; i < max_steps; ++i) {
      sim_->process_requests();
      if (auto o = rm_->outcome(id)) return o;
      if (sim_->owed_steps() > 0)
        sim_->take_owed_steps(std::chrono::steady_clock::time_point{});  // one, as the loop does
      else
        sim_->step();
    }
    sim_->process_requests();
    return rm_->outcome(id);
  }
  void run_for(double seconds) {
    int n = static_cast<int>(seconds / sim_->timestep());
    for (int i = 0; i < n; ++i) {
      sim_->process_requests();
      sim_->step();
    }
  }
  json pose() {
    Outcome o = call("robot.pose", "get_local_data");
    return o.value.value_or(json());
  }

  SimulationOptions options_{std::nullopt, 0.0};  // what SetUp() builds the simulation with
  std::unique_ptr<Simulation> sim_;
  std::shared_ptr<RecordingManager> rm_;
};

}  // namespace simgate::sim::testing

#endif  // SIMGATE_TESTS_SIM_SIM_FIXTURE_H_
