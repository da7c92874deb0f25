#include "simgate/sim/worlds.h"

#include <mujoco/mujoco.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <exception>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

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

// ---- Worlds

namespace {

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

}  // namespace

// What a call knows of each world it steps (not in an anonymous namespace: Worlds::Call holds
// them).
namespace worlds_call {

// One of `reads` in one world: its service, and its arguments bound (into the call's params).
struct Read {
  const Service* service = nullptr;
  BoundArguments args{0};
};

// One world's part of a call.
struct Slot {
  unsigned world = 0;
  std::uint64_t turn = 0;  // the world's turn this call steps it in
  // checked: its controls (a control left out: NaN, kept), or keep them all
  std::optional<std::vector<double>> action;
  std::vector<Read> reads;       // the services read after its steps, bound to its components
  std::uint64_t generation = 0;  // its model's when the call was checked
  bool checked = false;          // the world was there to check (else: deleted, or stopping)
  json result;                   // what the reply says of it
};

}  // namespace worlds_call

using worlds_call::Read;
using worlds_call::Slot;

namespace {

// `reads[i]` ({"component", "service", "params"}) as the caller may ask it, in any world.
// Throws ServiceError (bad_arguments) when not. Where the call arrives (its caller known).
void check_read(const json& read, std::size_t i) {
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
  if (!caller_may_call(component, name))
    refuse(where, "simgate has no service " + component + "." + name + " this caller may call");
}

// `reads[i]`, checked by check_read(), bound in `world`: a synchronous service of one of its
// components. Throws ServiceError (bad_arguments) when not.
Read bind_read(Simulation& world, unsigned index, const json& read, std::size_t i) {
  const std::string where = "reads[" + std::to_string(i) + "]";
  const std::string& component = read["component"].get_ref<const std::string&>();
  const std::string& name = read["service"].get_ref<const std::string&>();
  const ComponentEntry* entry = world.find(component);
  const Service* service = nullptr;
  if (entry)
    for (const auto& s : entry->component->services())
      if (s->descriptor().name == name) service = s.get();
  if (!service)
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

// Slot `i` of a call checked in its world (`world`, locked): its action against the world's
// actuators (`actions`: the call's), its reads bound (`reads`: the call's). Throws
// ServiceError (bad_arguments, naming the parameter) when they do not fit.
void check_slot(Slot& slot, Simulation& world, std::size_t i, const json& actions,
                const json& reads) {
  slot.generation = world.model_generation();
  for (std::size_t r = 0; r < reads.size(); ++r)
    slot.reads.push_back(bind_read(world, slot.world, reads[r], r));
  if (actions.is_null() || actions[i].is_null()) return;
  const std::string where = "actions[" + std::to_string(i) + "]";
  const mjModel* m = world.m();
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
      if (!v.is_number()) refuse(parameter, "expected a number or null, found " + describe_json(v));
      if (limited)
        bounds::require_between(parameter, value, low, high, "");
      else
        bounds::require_within(parameter, value, bounds::control, "");
    }
    controls.push_back(value);
  }
  slot.action = std::move(controls);
}

// `slot`'s world (`sim`, locked) given its controls, `n` steps (fewer when it diverges, or
// when `stop` gives a reason between two steps), then read; what happened in slot.result.
void take_steps(Simulation& sim, Slot& slot, std::int64_t n,
                const std::vector<std::string>& observed, bool base64,
                const std::function<const char*()>& stop) {
  json& out = slot.result;
  if (slot.action)
    for (std::size_t j = 0; j < slot.action->size(); ++j)
      if (!std::isnan((*slot.action)[j])) sim.d()->ctrl[j] = (*slot.action)[j];
  const std::uint64_t steps_before = sim.steps(), divergences_before = sim.divergences();
  for (std::int64_t taken = 0; taken < n; ++taken) {
    if (const char* reason = stop()) {
      out["steps_done"] = sim.steps() - steps_before;
      out["error"] = "world " + std::to_string(slot.world) + " " + reason + " after " +
                     std::to_string(sim.steps() - steps_before) + " of its " + std::to_string(n) +
                     " steps";
      return;
    }
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
  if (slot.reads.empty()) return;
  json& results = out["reads"] = json::array();
  for (std::size_t r = 0; r < slot.reads.size(); ++r) {
    try {
      std::optional<json> value =
          slot.reads[r].service->invoke(slot.reads[r].args.span(), Completion());
      results.push_back(value ? std::move(*value) : json());
    } catch (const std::exception& e) {
      out["error"] = "reads[" + std::to_string(r) + "] (" +
                     slot.reads[r].service->descriptor().qualified_name() + "): " + e.what();
      return;
    }
  }
}

}  // namespace

// A world, and the order calls step it in.
struct Worlds::World {
  Simulation* sim = nullptr;
  std::uint64_t next_turn = 0;       // the next call's (under world 0's lock and mutex_)
  std::uint64_t turn = 0;            // the turn of the call that has the world now (mutex_)
  int using_it = 0;                  // pool threads checking or stepping it now (mutex_)
  std::atomic<bool> leaving{false};  // remove(): a call stepping it stops at its next step
};

// One step_many call, from its arrival to its reply. The pool runs it as one batch: task 0
// waits for the call's turn on each of its worlds and checks it there; tasks 1..N step a world
// each once the check is done. The call has its worlds from that check until their steps end.
struct Worlds::Call {
  Completion done;
  std::int64_t n = 0;
  std::vector<std::string> observed;
  bool base64 = false;
  json actions;  // the call's, checked in each world
  json reads;    // the call's: each slot's bound reads point into it
  std::vector<Slot> slots;
  // each slot's world (kept: a deleted one says so by `leaving`)
  std::vector<std::shared_ptr<World>> worlds;
  bool checked = false;            // task 0 ended (mutex_)
  std::optional<Outcome> refusal;  // what task 0 refused the call with
};

Worlds::Worlds(std::size_t threads)
    : pool_(threads == 0 ? std::max(1u, std::thread::hardware_concurrency()) : threads) {}

Worlds::~Worlds() {
  // the worlds may be gone (the gateway's shutdown stopped this first): none is touched here
  request_stop();
  pool_.wait_idle();
}

void Worlds::add(unsigned index, Simulation& world) {
  auto entry = std::make_shared<World>();
  entry->sim = &world;
  std::lock_guard lock(mutex_);
  worlds_[index] = std::move(entry);
}

void Worlds::remove(unsigned index) {
  std::unique_lock lock(mutex_);
  const auto it = worlds_.find(index);
  if (it == worlds_.end()) return;
  it->second->leaving = true;
  changed_.notify_all();  // calls waiting for their turn on it give up
  changed_.wait(lock, [&] { return it->second->using_it == 0; });
  worlds_.erase(it);
}

void Worlds::request_stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  changed_.notify_all();  // calls waiting for their turn give up
}

void Worlds::stop() {
  request_stop();
  {
    // world 0's lock, which step_many holds: a call that saw no stop has been submitted
    std::unique_lock<SimulationGate> gate;
    if (const auto it = worlds_.find(0); it != worlds_.end())
      gate = std::unique_lock(*it->second->sim->gate());
  }
  pool_.wait_idle();
}

std::string Worlds::index_list() const {
  std::string out;
  for (const auto& [index, world] : worlds_)
    out += (out.empty() ? "" : ", ") + std::to_string(index);
  return out;
}

void Worlds::each_locked(const std::function<void(unsigned, const Simulation&)>& read) const {
  for (const auto& [index, world] : worlds_) {
    std::unique_lock<SimulationGate> lock;
    if (index != 0) lock = std::unique_lock(*world->sim->gate());  // world 0's is the caller's
    read(index, *world->sim);
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
      .offer_async_service("step_many",
                           [this](Completion done, json worlds, std::int64_t n, json actions,
                                  json observe, json reads, std::string encoding) {
                             step_many(done, worlds, n, std::move(actions), observe,
                                       std::move(reads), encoding);
                           },
                           {Param("worlds", nullptr), Param("n", 1), Param("actions", nullptr),
                            Param("observe", default_observation()), Param("reads", json::array()),
                            Param("encoding", "json")})
      .concurrent()
      .doc(
          "steps many worlds in one call: for each of `worlds` (all when null) sets its "
          "actuators' controls to its entry of `actions` (one number per actuator; null keeps "
          "them, a null control keeps that one), takes `n` steps, and reads `observe` (qpos, "
          "qvel, act, ctrl, sensordata; as numbers, or with `encoding` base64 each array's "
          "float64 little-endian bytes in base64) and `reads` (services of each world, "
          "[{component, service, params}]); the worlds step in parallel, off the caller's thread "
          "(docs/worlds.md)");
}

void Worlds::step_many(const Completion& done, const json& worlds, std::int64_t n, json actions,
                       const json& observe, json reads, const std::string& encoding) {
  if (stopping_.load())
    throw ServiceError("simulation step_many: simgate is stopping", Failure::shutdown);
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
  for (std::size_t r = 0; r < reads.size(); ++r) check_read(reads[r], r);

  auto call = std::make_shared<Call>();
  call->done = done;
  call->n = n;
  call->observed = std::move(observed);
  call->base64 = base64;
  call->actions = std::move(actions);
  call->reads = std::move(reads);
  call->slots.resize(named.size());
  call->worlds.resize(named.size());
  {
    // the call's turn on each world: calls that name a world step it in the order they came
    std::lock_guard lock(mutex_);
    for (std::size_t i = 0; i < named.size(); ++i) {
      call->slots[i].world = named[i];
      call->worlds[i] = worlds_.at(named[i]);
      call->slots[i].turn = call->worlds[i]->next_turn++;
    }
  }
  pool_.submit(
      1 + call->slots.size(),
      [this, call](std::size_t task) {
        if (task == 0)
          check_call(*call);
        else
          step_slot(*call, task - 1);
      },
      [call] {
        if (call->refusal) {
          call->done.finish(std::move(*call->refusal));
          return;
        }
        json reply = json::array();
        for (Slot& slot : call->slots) reply.push_back(std::move(slot.result));
        call->done(Status::success, json{{"worlds", std::move(reply)}});
      });
}

bool Worlds::take(World& world) {
  if (world.leaving) return false;
  ++world.using_it;
  return true;
}

void Worlds::release(World& world, bool pass_turn) {
  bool wake = pass_turn;  // a call may wait for its turn
  {
    std::lock_guard lock(mutex_);
    --world.using_it;
    if (pass_turn) ++world.turn;
    wake = wake || world.leaving;  // remove() waits for the uses to end
  }
  if (wake) changed_.notify_all();
}

void Worlds::check_call(Call& call) {
  // the call's turn on every world (earlier calls naming it are done with it), then each
  // world checked under its lock; a world deleted meanwhile is not checked (its slot says so)
  {
    std::unique_lock lock(mutex_);
    for (std::size_t i = 0; i < call.slots.size(); ++i) {
      const World& world = *call.worlds[i];
      changed_.wait(lock,
                    [&] { return stopping_ || world.leaving || world.turn == call.slots[i].turn; });
    }
  }
  for (std::size_t i = 0; i < call.slots.size() && !call.refusal; ++i) {
    Slot& slot = call.slots[i];
    World* world = nullptr;
    {
      std::lock_guard lock(mutex_);
      if (!stopping_ && take(*call.worlds[i])) world = call.worlds[i].get();
    }
    if (!world) continue;
    try {
      std::lock_guard gate(*world->sim->gate());
      check_slot(slot, *world->sim, i, call.actions, call.reads);
      slot.checked = true;
    } catch (const ServiceError& e) {
      json data = e.data();
      data["component"] = "simulation";
      data["service"] = "step_many";
      call.refusal = Outcome::failed(e.failure(), e.message(), std::move(data));
    }
    release(*world, false);
  }
  {
    std::lock_guard lock(mutex_);
    call.checked = true;
  }
  changed_.notify_all();
}

void Worlds::step_slot(Call& call, std::size_t i) {
  Slot& slot = call.slots[i];
  json& out = slot.result;
  out = json{{"world", slot.world}};
  const std::string name = "world " + std::to_string(slot.world);
  World* world = nullptr;
  {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return call.checked; });
    if (take(*call.worlds[i])) world = call.worlds[i].get();
  }
  // the call has the world's turn since its check: pass it on whatever happens here
  if (!world || call.refusal || !slot.checked || stopping_) {
    if (!call.refusal) {
      out["steps_done"] = 0;
      out["error"] = world && stopping_ ? "simgate is stopping: " + name + " was not stepped"
                                        : name +
                                              " was deleted (simulation delete_world) before "
                                              "its turn: not stepped";
    }
    if (world) release(*world, true);
    return;
  }
  {
    Simulation& sim = *world->sim;
    std::lock_guard gate(*sim.gate());
    const OutsideRequest outside;  // default actions see no caller (as `simulation step`)
    try {
      if (sim.model_generation() != slot.generation) {
        out["steps_done"] = 0;
        out["error"] = name +
                       "'s model was replaced (a spawn or a delete) after this call "
                       "was checked: not stepped";
      } else {
        take_steps(sim, slot, call.n, call.observed, call.base64, [&]() -> const char* {
          if (world->leaving.load(std::memory_order_relaxed))
            return "was deleted (simulation delete_world) during this call";
          if (stopping_.load(std::memory_order_relaxed)) return "stopped: simgate is stopping";
          if (call.done.done())
            return "stopped: the call ended (cancelled, timed out or its client left)";
          return nullptr;
        });
      }
    } catch (const std::exception& e) {
      out["error"] = e.what();
    }
  }
  release(*world, true);
}

}  // namespace simgate::sim
