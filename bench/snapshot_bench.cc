// snapshot_bench.cc — simgate_bench_sim's modes for issue #19: snapshots of the simulation's
// state and the spawning of an entity, each against the bare MuJoCo call doing the same work.
//
// Modes (--mode):
//   snapshot issue #19's snapshots: `simulation save_state` and `restore_state` on --mjcf
//            (run as a transport runs them: RequestManager::on_incoming_request, arguments
//            bound from JSON), against mj_copyData of the same model, in alternating batches
//            for --duration seconds. Prints µs per call (medians of the batches).
//   spawn    issue #19's spawn target: `simulation spawn_entity` of one free body on the
//            scene --mjcf (the demo's), from the request to its SUCCESS (validation, the
//            recompilation on the worker, the swap at the next step: the simulation steps as
//            fast as possible meanwhile), then `delete_entity` of it, in rounds for
//            --duration seconds (at least 20), each beside the edit alone
//            (with_entity, the worker's share, on the main thread) and a bare mj_loadXML
//            of the same scene. Prints ms p50 and p99 of the four.
#include "snapshot_bench.h"

#include <algorithm>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <mujoco/mujoco.h>

#include "simgate/core/request_manager.h"
#include "simgate/sim/model_edit.h"
#include "simgate/sim/simulation.h"
#include "simgate/sim/supervision.h"

namespace simgate::bench {
namespace {

// Runs services in the calling thread (snapshot mode); outcomes are only counted.
class DirectManager : public simgate::RequestManager {
 public:
  DirectManager() : RequestManager("Bench service manager") {}
  // One sync call; throws unless it succeeded.
  simgate::json call(const std::string& service, simgate::json params = simgate::json::array()) {
    auto outcome =
        on_incoming_request(new_request_id(), {"simulation", service, std::move(params)});
    if (!outcome || outcome->status != simgate::Status::success)
      throw std::runtime_error("simulation " + service +
                               " failed: " + (outcome ? outcome->message : "async"));
    return outcome->value.value_or(simgate::json());
  }

 protected:
  void on_service_completion(simgate::RequestId, simgate::Outcome&&) override {}
};

}  // namespace

json run_snapshot(const std::string& mjcf, double duration_s) {
  simgate::sim::Simulation sim(simgate::sim::Model::load_file(mjcf), {std::nullopt, 0.0});
  add_world_components(sim);
  auto rm = std::make_shared<DirectManager>();
  rm->register_component(*sim.find("simulation")->component);
  sim.add_request_manager(rm, "bench");
  std::lock_guard lock(*sim.gate());
  // a state worth saving: a second of motion
  for (int i = 0; i < 500; ++i) sim.step();
  mjData* copy = mj_makeData(sim.m());
  const std::int64_t handle = rm->call("save_state").get<std::int64_t>();

  constexpr int batch = 50;  // saves per batch: below the 64 states kept at once
  std::vector<double> save_us, restore_us, copy_us;
  auto per_call = [](Clock::time_point t0, Clock::time_point t1) {
    return std::chrono::duration<double, std::micro>(t1 - t0).count() / batch;
  };
  const auto end = Clock::now() + seconds(duration_s);
  while (Clock::now() < end || save_us.empty()) {
    std::vector<std::int64_t> handles;
    auto t0 = Clock::now();
    for (int i = 0; i < batch; ++i) handles.push_back(rm->call("save_state").get<std::int64_t>());
    auto t1 = Clock::now();
    save_us.push_back(per_call(t0, t1));
    for (auto h : handles) rm->call("drop_state", {h});

    t0 = Clock::now();
    for (int i = 0; i < batch; ++i) rm->call("restore_state", {handle});
    t1 = Clock::now();
    restore_us.push_back(per_call(t0, t1));

    t0 = Clock::now();
    for (int i = 0; i < batch; ++i) mj_copyData(copy, sim.m(), sim.d());
    t1 = Clock::now();
    copy_us.push_back(per_call(t0, t1));
  }
  mj_deleteData(copy);
  auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  return {{"mode", "snapshot"},
          {"batches", save_us.size()},
          {"save_state_us", median(save_us)},
          {"restore_state_us", median(restore_us)},
          {"mj_copyData_us", median(copy_us)},
          {"nq", sim.m()->nq},
          {"nv", sim.m()->nv}};
}

// ---- spawn ----------------------------------------------------------------------------------

namespace {

// Keeps the outcomes of the requests it submits (the simulation thread delivers them).
class SpawnBenchManager : public simgate::RequestManager {
 public:
  SpawnBenchManager() : RequestManager("spawn bench") {}
  ~SpawnBenchManager() override { stop(); }
  void stop() override { abandon_pending(); }
  simgate::RequestId call(const std::string& service, json params) {
    simgate::RequestId id = new_request_id();
    submit(id, simgate::Call{"simulation", service, std::move(params)});
    return id;
  }
  std::optional<simgate::Outcome> take(simgate::RequestId id) {
    auto it = outcomes_.find(id);
    if (it == outcomes_.end()) return std::nullopt;
    simgate::Outcome o = std::move(it->second);
    outcomes_.erase(it);
    return o;
  }

 protected:
  void on_service_completion(simgate::RequestId id, simgate::Outcome&& outcome) override {
    outcomes_[id] = std::move(outcome);
  }

 private:
  std::map<simgate::RequestId, simgate::Outcome> outcomes_;  // answered, not yet taken
};

}  // namespace

json run_spawn(const std::string& mjcf, double duration) {
  using simgate::bench::ns_between;
  namespace sim = simgate::sim;
  sim::Simulation simulation(sim::Model::load_file(mjcf),
                             sim::SimulationOptions{std::nullopt, 0.0});
  add_world_components(simulation);
  auto manager = std::make_shared<SpawnBenchManager>();
  manager->register_component(*simulation.find("simulation")->component);
  simulation.add_request_manager(manager, "bench");
  // a request's nanoseconds from submission to its outcome, the loop stepping meanwhile
  auto timed = [&](const std::string& service, json params) {
    const auto start = Clock::now();
    const simgate::RequestId id = manager->call(service, std::move(params));
    for (;;) {
      simulation.process_requests();
      if (auto o = manager->take(id)) {
        if (o->status != simgate::Status::success)
          throw std::runtime_error(service + ": " + o->message);
        return ns_between(start, Clock::now());
      }
      simulation.step();
    }
  };
  const std::string ball = "<body><freejoint/><geom type='sphere' size='0.1' mass='1'/></body>";
  std::vector<std::int64_t> spawn, remove, compile, load;
  const auto end = Clock::now() + std::chrono::duration<double>(duration);
  while (Clock::now() < end || spawn.size() < 20) {
    spawn.push_back(timed("spawn_entity", json::array({"bench_ball", ball, {1.0, 1.0, 0.5}})));
    remove.push_back(timed("delete_entity", json::array({"bench_ball"})));
    // the worker's share alone: the same edit, on this thread
    auto start = Clock::now();
    sim::with_entity(sim::EditBase::of(simulation.model()), "bench_ball",
                     sim::entity_document(ball, "bench_ball", {}));
    compile.push_back(ns_between(start, Clock::now()));
    char error[1024] = "";
    start = Clock::now();
    mjModel* m = mj_loadXML(mjcf.c_str(), nullptr, error, sizeof error);
    load.push_back(ns_between(start, Clock::now()));
    if (!m) throw std::runtime_error(std::string("mj_loadXML: ") + error);
    mj_deleteModel(m);
  }
  auto ms = [](std::vector<std::int64_t> samples) {
    std::sort(samples.begin(), samples.end());
    return json{{"p50_ms", simgate::bench::quantile(samples, 0.5) / 1e6},
                {"p99_ms", simgate::bench::quantile(samples, 0.99) / 1e6}};
  };
  return json{{"mode", "spawn"},
              {"model", mjcf},
              {"rounds", spawn.size()},
              {"spawn_entity", ms(spawn)},
              {"delete_entity", ms(remove)},
              {"with_entity", ms(compile)},
              {"mj_loadXML", ms(load)},
              {"model_generation", simulation.model_generation()}};
}

}  // namespace simgate::bench
