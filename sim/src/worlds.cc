#include "simgate/sim/worlds.h"

#include <mujoco/mujoco.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <exception>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "simgate/core/base64.h"
#include "simgate/core/call_context.h"
#include "simgate/core/errors.h"
#include "simgate/core/request_manager.h"
#include "simgate/core/service.h"
#include "simgate/core/simulation_gate.h"
#include "simgate/sim/bounds.h"
#include "simgate/sim/simulation.h"
#include "simgate/sim/supervision.h"

namespace simgate::sim {

// ---- TaskPool

TaskPool::TaskPool(std::size_t threads) {
  for (std::size_t i = 0; i < threads; ++i) helpers_.emplace_back([this] { help(); });
}

TaskPool::~TaskPool() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  work_.notify_all();
  for (auto& t : helpers_) t.join();
}

void TaskPool::drain(std::unique_lock<std::mutex>& lock) {
  while (task_ && next_ < count_) {
    const std::size_t i = next_++;
    ++running_;
    const auto* task = task_;
    lock.unlock();
    (*task)(i);
    lock.lock();
    if (--running_ == 0 && next_ == count_) done_.notify_all();
  }
}

void TaskPool::help() {
  std::unique_lock lock(mutex_);
  std::uint64_t seen = 0;
  for (;;) {
    work_.wait(lock, [&] { return stop_ || batch_ != seen; });
    if (stop_) return;
    seen = batch_;
    drain(lock);
  }
}

void TaskPool::run(std::size_t count, const std::function<void(std::size_t)>& task) {
  if (count == 0) return;
  std::unique_lock lock(mutex_);
  task_ = &task;
  next_ = 0;
  count_ = count;
  running_ = 0;
  ++batch_;
  if (count > 1) work_.notify_all();
  drain(lock);  // the caller works too
  done_.wait(lock, [&] { return next_ == count_ && running_ == 0; });
  task_ = nullptr;
}

// ---- Worlds

namespace {

std::size_t pool_threads(std::size_t threads) {
  if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
  return threads - 1;  // the caller is one
}

[[noreturn]] void refuse(const std::string& parameter, const std::string& message) {
  throw ServiceError("simulation step_many: " + parameter + ": " + message, Failure::bad_arguments,
                     json{{"parameter", parameter}});
}

// The arrays step_many can read of a world, by name.
const std::vector<std::string> k_observable = {"qpos", "qvel", "act", "ctrl", "sensordata"};

// An observed array as step_many's `encoding` says: JSON numbers, or (`base64`) the
// doubles' bytes, IEEE 754 binary64 little-endian, in base64 (exact, and no number to
// format or parse).
json array_of(const mjtNum* values, int count, bool base64) {
  const auto n = static_cast<std::size_t>(std::max(count, 0));
  if (base64) {
    static_assert(std::endian::native == std::endian::little && sizeof(mjtNum) == 8,
                  "encoding base64 sends the doubles' bytes as they are in memory");
    return base64_encode({reinterpret_cast<const std::uint8_t*>(values), n * sizeof(mjtNum)});
  }
  json out = json::array();
  out.get_ref<json::array_t&>().reserve(n);
  for (std::size_t i = 0; i < n; ++i) out.push_back(values[i]);
  return out;
}

json read(const Simulation& world, const std::string& what, bool base64) {
  const mjModel* m = world.m();
  const mjData* d = world.d();
  if (what == "qpos") return array_of(d->qpos, m->nq, base64);
  if (what == "qvel") return array_of(d->qvel, m->nv, base64);
  if (what == "act") return array_of(d->act, m->na, base64);
  if (what == "ctrl") return array_of(d->ctrl, m->nu, base64);
  return array_of(d->sensordata, m->nsensordata, base64);
}

// One of `reads` in one world: its service, and its arguments bound (into the call's params).
struct Read {
  const Service* service = nullptr;
  BoundArguments args{0};
};

// `reads[i]` ({"component", "service", "params"}) bound in `world`: a synchronous service
// of one of its components the caller may call. Throws ServiceError (bad_arguments) when not.
Read bind_read(Simulation& world, unsigned index, const json& read, std::size_t i) {
  const std::string where = "reads[" + std::to_string(i) + "]";
  if (!read.is_object() || !read.contains("component") || !read["component"].is_string() ||
      !read.contains("service") || !read["service"].is_string())
    refuse(where, "expected {\"component\": NAME, \"service\": NAME, \"params\": ...}, found " +
                      describe_json(read));
  for (const auto& [key, value] : read.items())
    if (key != "component" && key != "service" && key != "params")
      refuse(where + "." + key, "unknown key (component, service, params)");
  const std::string& component = read["component"].get_ref<const std::string&>();
  const std::string& name = read["service"].get_ref<const std::string&>();
  const ComponentEntry* entry = world.find(component);
  const Service* service = nullptr;
  if (entry)
    for (const auto& s : entry->component->services())
      if (s->descriptor().name == name) service = s.get();
  if (!service || !caller_may_call(component, name))
    refuse(where, "world " + std::to_string(index) + " has no service " + component + "." + name +
                      " this caller may call");
  if (service->descriptor().is_async)
    refuse(where, component + "." + name + " is asynchronous: only services that answer at once " +
                      "are read");
  static const json k_no_params;  // null
  try {
    return Read{service, bind_arguments(service->descriptor(),
                                        read.contains("params") ? read["params"] : k_no_params)};
  } catch (const ServiceError& e) {
    refuse(where + ".params", e.message());
  }
}

// One world's part of a call, checked.
struct Slot {
  unsigned world = 0;
  Simulation* sim = nullptr;
  // its controls (a control left out: NaN, kept), or keep them all
  std::optional<std::vector<double>> action;
  std::vector<Read> reads;  // the services read after its steps, bound to its components
  json result;              // what the reply says of it
};

}  // namespace

Worlds::Worlds(std::size_t threads) : pool_(pool_threads(threads)) {}

void Worlds::add(unsigned index, Simulation& world) { worlds_[index] = &world; }

void Worlds::remove(unsigned index) { worlds_.erase(index); }

std::string Worlds::index_list() const {
  std::string out;
  for (const auto& [index, world] : worlds_)
    out += (out.empty() ? "" : ", ") + std::to_string(index);
  return out;
}

void Worlds::each_locked(const std::function<void(unsigned, const Simulation&)>& read) const {
  for (const auto& [index, world] : worlds_) {
    std::unique_lock<SimulationGate> lock;
    if (index != 0) lock = std::unique_lock(*world->gate());  // world 0's is the caller's
    read(index, *world);
  }
}

std::size_t Worlds::memory_bytes() const {
  std::size_t total = 0;
  each_locked([&](unsigned, const Simulation& world) { total += world.memory_bytes(); });
  return total;
}

json Worlds::describe() const {
  json out = json::array();
  each_locked([&](unsigned index, const Simulation& world) {
    out.push_back({{"world", index},
                   {"name", RequestManager::world_name(index)},
                   {"state", to_string(world.run_state())},
                   {"sim_time", world.sim_time()},
                   {"steps", world.steps()},
                   {"actuators", world.m()->nu},
                   {"memory_bytes", world.memory_bytes()}});
  });
  return out;
}

const std::vector<std::string>& Worlds::default_observation() {
  static const std::vector<std::string> names = {"qpos", "qvel", "sensordata"};
  return names;
}

void Worlds::add_to(SupervisionServices& world0) {
  world0
      .offer_service("step_many",
                     [this](json worlds, std::int64_t n, json actions, json observe, json reads,
                            std::string encoding) {
                       return step_many(worlds, n, actions, observe, reads, encoding);
                     },
                     {Param("worlds", nullptr), Param("n", 1), Param("actions", nullptr),
                      Param("observe", default_observation()), Param("reads", json::array()),
                      Param("encoding", "json")})
      .doc(
          "steps many worlds in one call: for each of `worlds` (all when null) sets its "
          "actuators' controls to its entry of `actions` (one number per actuator; null keeps "
          "them, a null control keeps that one), takes `n` steps, and reads `observe` (qpos, "
          "qvel, act, ctrl, sensordata; as numbers, or with `encoding` base64 each array's "
          "float64 little-endian bytes in base64) and `reads` (services of each world, "
          "[{component, service, params}]); the worlds step in parallel (docs/worlds.md)");
}

json Worlds::step_many(const json& worlds, std::int64_t n, const json& actions, const json& observe,
                       const json& reads, const std::string& encoding) {
  // ---- the arguments that need no world
  std::vector<unsigned> named;
  if (worlds.is_null()) {
    for (const auto& [index, world] : worlds_) named.push_back(index);
  } else {
    if (!worlds.is_array() || worlds.empty())
      refuse("worlds", "expected an array of world numbers (" + index_list() +
                           ") or null for all, found " + describe_json(worlds));
    for (std::size_t i = 0; i < worlds.size(); ++i) {
      const json& w = worlds[i];
      if (!w.is_number_integer() || w.get<std::int64_t>() < 0 ||
          w.get<std::int64_t>() > std::numeric_limits<unsigned>::max() ||
          !worlds_.contains(w.get<unsigned>()))
        refuse("worlds[" + std::to_string(i) + "]",
               "no world " + describe_json(w) + " (the worlds here: " + index_list() + ")");
      const auto k = w.get<unsigned>();
      if (std::find(named.begin(), named.end(), k) != named.end())
        refuse("worlds[" + std::to_string(i) + "]", "world " + std::to_string(k) + " twice");
      named.push_back(k);
    }
  }
  constexpr std::int64_t k_max_steps = 1'000'000;
  if (n < 1 || n > k_max_steps)
    refuse("n",
           "expected 1 to " + std::to_string(k_max_steps) + " steps, found " + std::to_string(n));
  if (!actions.is_null() && (!actions.is_array() || actions.size() != named.size()))
    refuse("actions", "expected one entry per world named (" + std::to_string(named.size()) +
                          ": an array of controls, or null) or null, found " +
                          describe_json(actions));
  std::vector<std::string> observed;
  if (!observe.is_array())
    refuse("observe", "expected an array of names (qpos, qvel, act, ctrl, sensordata)");
  for (std::size_t i = 0; i < observe.size(); ++i) {
    if (!observe[i].is_string() || std::find(k_observable.begin(), k_observable.end(),
                                             observe[i].get<std::string>()) == k_observable.end())
      refuse(
          "observe[" + std::to_string(i) + "]",
          "expected one of qpos, qvel, act, ctrl, sensordata, found " + describe_json(observe[i]));
    observed.push_back(observe[i].get<std::string>());
  }
  if (encoding != "json" && encoding != "base64")
    refuse("encoding",
           "expected json (numbers) or base64 (each array's float64 little-endian "
           "bytes), found '" +
               encoding + "'");
  const bool base64 = encoding == "base64";
  if (!reads.is_array())
    refuse("reads", "expected an array of {\"component\", \"service\", \"params\"}, found " +
                        describe_json(reads));

  // ---- every world named, locked in order (world 0's lock is this service's)
  std::vector<std::unique_lock<SimulationGate>> locks;
  std::vector<unsigned> in_order = named;
  std::sort(in_order.begin(), in_order.end());
  for (const unsigned k : in_order)
    if (k != 0) locks.emplace_back(*worlds_.at(k)->gate());

  // ---- the actions, checked against each world's actuators before anything changes
  std::vector<Slot> slots(named.size());
  for (std::size_t i = 0; i < named.size(); ++i) {
    Slot& slot = slots[i];
    slot.world = named[i];
    slot.sim = worlds_.at(named[i]);
    for (std::size_t r = 0; r < reads.size(); ++r)
      slot.reads.push_back(bind_read(*slot.sim, slot.world, reads[r], r));
    if (actions.is_null() || actions[i].is_null()) continue;
    const std::string where = "actions[" + std::to_string(i) + "]";
    const mjModel* m = slot.sim->m();
    const json& action = actions[i];
    if (!action.is_array() || action.size() != static_cast<std::size_t>(m->nu))
      refuse(where, "world " + std::to_string(slot.world) + " has " + std::to_string(m->nu) +
                        " actuators: expected " + std::to_string(m->nu) +
                        " numbers (or null), found " + describe_json(action));
    std::vector<double> controls;
    for (int j = 0; j < m->nu; ++j) {
      const json& v = action[static_cast<std::size_t>(j)];
      if (v.is_null()) {  // this control kept
        controls.push_back(std::numeric_limits<double>::quiet_NaN());
        continue;
      }
      const double value = v.is_number() ? v.get<double>() : 0.0;
      const bool limited = m->actuator_ctrllimited[j];
      const double low = limited ? m->actuator_ctrlrange[2 * j] : -bounds::control;
      const double high = limited ? m->actuator_ctrlrange[2 * j + 1] : bounds::control;
      if (!v.is_number() || !(value >= low && value <= high)) {
        // refused with the parameter and the range named (bounds.h); the name is made only
        // for a refusal (hundreds of controls a call)
        const std::string parameter = where + "[" + std::to_string(j) + "]";
        if (!v.is_number())
          refuse(parameter, "expected a number or null, found " + describe_json(v));
        if (limited)
          bounds::require_between(parameter, value, low, high, "");
        else
          bounds::require_within(parameter, value, bounds::control, "");
      }
      controls.push_back(value);
    }
    slot.action = std::move(controls);
  }

  // ---- each world by one thread: its controls, its n steps, what it observes
  pool_.run(slots.size(), [&](std::size_t i) {
    Slot& slot = slots[i];
    Simulation& sim = *slot.sim;
    const OutsideRequest outside;  // default actions see no caller (as `simulation step`)
    json& out = slot.result;
    out = json{{"world", slot.world}};
    try {
      if (slot.action)
        for (std::size_t j = 0; j < slot.action->size(); ++j)
          if (!std::isnan((*slot.action)[j])) sim.d()->ctrl[j] = (*slot.action)[j];
      const std::uint64_t steps_before = sim.steps(), divergences_before = sim.divergences();
      for (std::int64_t taken = 0; taken < n; ++taken) {
        sim.step();
        if (sim.divergences() != divergences_before) {
          // its policy did what it does (paused it, reset it...): it stops here
          out["diverged"] = sim.last_divergence() ? to_json(*sim.last_divergence()) : json();
          break;
        }
      }
      out["steps_done"] = sim.steps() - steps_before;
      out["sim_time"] = sim.sim_time();
      for (const std::string& what : observed) out[what] = read(sim, what, base64);
      if (!slot.reads.empty()) {
        json& results = out["reads"] = json::array();
        for (std::size_t r = 0; r < slot.reads.size(); ++r) {
          try {
            std::optional<json> value =
                slot.reads[r].service->invoke(slot.reads[r].args.span(), Completion());
            results.push_back(value ? std::move(*value) : json());
          } catch (const std::exception& e) {
            out["error"] = "reads[" + std::to_string(r) + "] (" +
                           slot.reads[r].service->descriptor().qualified_name() + "): " + e.what();
            break;
          }
        }
      }
    } catch (const std::exception& e) {
      out["error"] = e.what();
    }
  });

  json reply = json::array();
  for (Slot& slot : slots) reply.push_back(std::move(slot.result));
  return json{{"worlds", std::move(reply)}};
}

}  // namespace simgate::sim
