// The state group of `simulation` (world_services.h, docs/world/state.md): reset with a
// scope, and in-memory snapshots (save_state, restore_state, list_states, drop_state).
//
// A snapshot is a PhysicsState (physics_state.h): every part of mjData that the next step
// reads. Restoring it and stepping gives, bit for bit, what stepping from the moment it was
// saved gave (the components' own commands aside: see restore below). A snapshot also keeps
// each object's state by name (object_state.h): once the model has changed (a spawn, a
// delete), it is put back object by object, bodies, joints and actuators matched by name;
// the restore reports what the saved state had that the world no longer has (missing) and
// what the world has that it did not (kept as they are). A spawn and its delete leave every
// object's state as saved: stepping on gives the same bits.
//
// A snapshot belongs to the client that saved it (CallContext::client(): a connection of a
// transport, a DDS client): any client may restore it, only its client drops it while that
// client is connected; once it has left, anyone may, and a save that finds every slot taken
// makes room by dropping the oldest snapshot of a client that left. One client keeps at
// most k_max_states_per_client, so that no client takes every slot (issue #35, item 10).
// The host (no request) is trusted with all of them.
//
// Whatever puts the world somewhere else (a reset, a restore) ends the async requests of
// the components it moves PREEMPTED, saying why: a goto or a trajectory started in the old
// state means nothing in the new one. When simulated time jumps (reset everything, restore),
// the running `time sleep` calls end the same way: their wake-up time was of the old clock.
#include <algorithm>
#include <cstdint>
#include <map>
#include <memory>
#include <string>

#include "simgate/core/call_context.h"
#include "simgate/core/errors.h"
#include "simgate/core/log.h"
#include "simgate/core/request_manager.h"
#include "simgate/sim/object_state.h"
#include "simgate/sim/physics_state.h"
#include "simgate/sim/sim_component.h"
#include "simgate/sim/world_services.h"

namespace simgate::sim {

namespace {

// Snapshots kept at once: each holds a copy of the state (a few KiB for the demo, a few
// hundred for a large model); a client that saves in a loop without dropping meets this.
constexpr std::size_t k_max_states = 64;
// Snapshots one client keeps at once.
constexpr std::size_t k_max_states_per_client = 16;

// Who saved a snapshot: a client of a transport, or the host (transport "").
struct Owner {
  std::string transport;     // the configuration's name of the caller's transport
  std::uint64_t client = 0;  // Call::client within it (0: the transport does not say)

  // The caller of the service running now.
  static Owner caller() {
    const CallContext* context = CallContext::current();
    if (!context) return {};
    return {context->manager().transport_name(), context->client()};
  }
  bool host() const { return transport.empty(); }
  bool operator==(const Owner&) const = default;
  std::string describe() const {
    if (host()) return "the host";
    return "a client of transport '" + transport + "'" +
           (client ? " (client #" + std::to_string(client) + ")" : "");
  }
};

// A saved state (physics_state.h): what the next step reads, the same by object, and whose
// it is.
struct Snapshot : PhysicsState {
  ObjectState objects;  // put back when the model changed since
  Owner owner;
};

json to_json(const ObjectState::Unmatched& u) {
  return {
      {"missing",
       {{"bodies", u.missing_bodies},
        {"joints", u.missing_joints},
        {"actuators", u.missing_actuators}}},
      {"kept",
       {{"bodies", u.kept_bodies}, {"joints", u.kept_joints}, {"actuators", u.kept_actuators}}}};
}

// Ends what `e` is running PREEMPTED with `reason`: its slot's request (through
// interrupt(), which stops what it moves) and the calls of its concurrent services.
void end_requests(ComponentEntry& e, const std::string& reason) {
  AsyncSlot& slot = *e.component->async_slot();
  if (slot.busy()) {
    const auto state = slot.running;
    state->interrupt_reason = Failure::preempted;
    state->interrupt_message = reason;
    if (slot.interrupt) slot.interrupt();
    Completion{state}(Status::preempted);  // ignored if interrupt() ended it
  }
  for (const Completion& call : slot.running_concurrent()) {
    Outcome o;
    o.status = Status::preempted;
    o.failure = Failure::preempted;
    o.message = reason;
    call.finish(std::move(o));
  }
}

// Ends every robot's running requests (what moves stops first, in the world it was started in).
void end_robots_requests(Simulation& sim, const std::string& reason) {
  for (auto& e : sim.components())
    if (e->is_robot || !e->robot.empty()) end_requests(*e, reason);
}

// Ends the time component's sleeps (simulated time jumped).
void end_sleeps(Simulation& sim, const std::string& reason) {
  if (ComponentEntry* time = sim.find("time")) end_requests(*time, reason);
}

class WorldState {
 public:
  explicit WorldState(Simulation& sim) : sim_(sim) {}

  std::string reset(const std::string& scope, const std::string& robot) {
    if (scope == "all") {
      if (!robot.empty()) refuse_robot_with(scope);
      end_robots_requests(sim_,
                          "simulation reset (all): every object went back to its initial state");
      sim_.reset_all();
      end_sleeps(sim_, "simulation reset (all): simulated time went back to 0");
      return "Simulation reset: objects and time restored to their initial state";
    }
    if (scope == "state") {
      if (!robot.empty()) refuse_robot_with(scope);
      end_robots_requests(sim_,
                          "simulation reset (state): every object went back to its initial state");
      sim_.reset();
      return "Objects restored to initial position";
    }
    if (scope == "robot") {
      reset_robot(robot);
      return "Robot '" + robot + "' restored to its initial state";
    }
    throw ServiceError(
        "simulation reset: scope = \"" + scope +
            "\": expected \"all\" (objects and time), "
            "\"state\" (objects; time goes on) or \"robot\" (one robot, named by `robot`)",
        Failure::bad_arguments, {{"parameter", "scope"}});
  }

  std::uint64_t save_state() {
    const Owner owner = Owner::caller();
    // (a transport that does not number its clients: they are not told apart, nor limited)
    if (!owner.host() && owner.client != 0) {
      const auto own = std::count_if(snapshots_.begin(), snapshots_.end(), [&](const auto& entry) {
        return entry.second.owner == owner;
      });
      if (static_cast<std::size_t>(own) >= k_max_states_per_client)
        throw ServiceError(
            "simulation save_state: this client keeps " + std::to_string(own) +
                " saved states already (the most one client keeps): drop one first (simulation "
                "drop_state handle)",
            Failure::service_error, {{"limit", k_max_states_per_client}});
    }
    if (snapshots_.size() >= k_max_states && !drop_one_left_behind())
      throw ServiceError(
          "simulation save_state: " + std::to_string(k_max_states) +
              " states are saved already (the limit), by clients still connected: drop one first "
              "(simulation drop_state handle)",
          Failure::service_error, {{"limit", k_max_states}});
    Snapshot s;
    s.owner = owner;
    s.capture(sim_.m(), sim_.d(), sim_.model_generation());
    s.objects.capture(sim_.m(), sim_.d());
    const std::uint64_t handle = next_handle_++;
    snapshots_.emplace(handle, std::move(s));
    return handle;
  }

  json restore_state(std::int64_t handle) {
    const Snapshot& s = find(handle, "restore_state");
    const bool exact = s.fits(sim_.m(), sim_.model_generation());
    ObjectState::Unmatched unmatched;
    jump_back(
        sim_,
        "simulation restore_state: the simulation went back to state " + std::to_string(handle),
        [&] {
          if (exact) {
            sim_.restore_physics(s);
          } else {
            // the model changed since: object by object, by name
            unmatched = sim_.restore_objects(s.objects, s.time());
            if (!unmatched.empty())
              log::info("simulation restore_state: state ", handle, " of model generation ",
                        s.generation(), " restored by name into generation ",
                        sim_.model_generation(), ": ", to_json(unmatched).dump());
          }
          return s.time();
        },
        {{"handle", handle}});
    json out = to_json(unmatched);
    out["sim_time"] = s.time();
    out["exact"] = exact;
    return out;
  }

  json list_states() const {
    const Owner caller = Owner::caller();
    json out = json::array();
    for (const auto& [handle, s] : snapshots_)
      out.push_back({{"handle", handle},
                     {"sim_time", s.time()},
                     {"model_generation", s.generation()},
                     {"exact", s.fits(sim_.m(), sim_.model_generation())},
                     {"yours", s.owner == caller},
                     {"owner_connected", connected(s.owner)}});
    return out;
  }

  bool drop_state(std::int64_t handle) {
    const Snapshot& s = find(handle, "drop_state");
    const Owner caller = Owner::caller();
    if (!caller.host() && !(s.owner == caller) && connected(s.owner))
      throw ServiceError("simulation drop_state: state " + std::to_string(handle) +
                             " was saved by " + s.owner.describe() +
                             ", still connected: only it drops its states (any client may "
                             "restore it)",
                         Failure::service_error, {{"parameter", "handle"}});
    snapshots_.erase(static_cast<std::uint64_t>(handle));
    return true;
  }

 private:
  // Whether the client that saved a snapshot is still connected (the host always is; a
  // transport that does not number its clients: assumed so).
  bool connected(const Owner& owner) const {
    if (owner.host()) return true;
    const RequestManager* manager = sim_.request_manager(owner.transport);
    return manager && (owner.client == 0 || manager->client_connected(owner.client));
  }

  // Drops the oldest snapshot whose client left; false when every one's client is here.
  bool drop_one_left_behind() {
    for (auto it = snapshots_.begin(); it != snapshots_.end(); ++it) {
      if (connected(it->second.owner)) continue;
      log::info("simulation save_state: state ", it->first, " of ", it->second.owner.describe(),
                ", which left, dropped to make room");
      snapshots_.erase(it);
      return true;
    }
    return false;
  }

  const Snapshot& find(std::int64_t handle, const char* service) const {
    const auto it =
        handle > 0 ? snapshots_.find(static_cast<std::uint64_t>(handle)) : snapshots_.end();
    if (it == snapshots_.end())
      throw ServiceError(
          std::string("simulation ") + service + ": no saved state " + std::to_string(handle) +
              ": expected a handle from simulation save_state (simulation list_states)",
          Failure::bad_arguments, {{"parameter", "handle"}});
    return it->second;
  }

  [[noreturn]] static void refuse_robot_with(const std::string& scope) {
    throw ServiceError("simulation reset: scope \"" + scope +
                           "\" resets every robot: `robot` names one only with "
                           "scope \"robot\"",
                       Failure::bad_arguments, {{"parameter", "robot"}});
  }

  void reset_robot(const std::string& name) {
    // a robot the caller's transport does not serve is answered as one that does not exist
    ComponentEntry* entry = sim_.find(name);
    auto* robot = entry && entry->is_robot && caller_serves(name)
                      ? dynamic_cast<Robot*>(entry->component.get())
                      : nullptr;
    if (!robot)
      throw ServiceError("simulation reset: robot = \"" + name +
                             "\": expected the name of a robot (simulation "
                             "list_robots)",
                         Failure::bad_arguments, {{"parameter", "robot"}});
    // its components' requests end: a component the caller's transport does not serve is
    // beyond its reach (a JSON-RPC reset ended a socket client's goto, issue #35 item 10)
    for (auto& e : sim_.components())
      if (e->robot == name && !caller_serves(e->component->name()))
        throw ServiceError(
            "simulation reset: robot '" + name + "' has component '" + e->component->name() +
                "', which this transport does not serve: its reset would act behind that "
                "component's clients; reset it through a transport that serves all of the robot",
            Failure::service_error, {{"parameter", "robot"}, {"component", e->component->name()}});
    const std::string reason =
        "simulation reset (robot): robot '" + name + "' went back to its initial state";
    end_requests(*entry, reason);
    for (auto& e : sim_.components())
      if (e->robot == name) end_requests(*e, reason);

    // its joints to their initial values, its velocities, activations and controls to 0
    const mjModel* m = sim_.m();
    mjData* d = sim_.d();
    for (int j = 0; j < m->njnt; ++j) {
      if (!in_subtree(m, m->jnt_bodyid[j], robot->body())) continue;
      const int qpos = m->jnt_qposadr[j];
      const int dof = m->jnt_dofadr[j];
      const int nq = m->jnt_type[j] == mjJNT_FREE ? 7 : m->jnt_type[j] == mjJNT_BALL ? 4 : 1;
      const int nv = m->jnt_type[j] == mjJNT_FREE ? 6 : m->jnt_type[j] == mjJNT_BALL ? 3 : 1;
      mju_copy(d->qpos + qpos, m->qpos0 + qpos, nq);
      mju_zero(d->qvel + dof, nv);
      mju_zero(d->qacc_warmstart + dof, nv);
      mju_zero(d->qfrc_applied + dof, nv);
      for (int u = 0; u < m->nu; ++u) {
        if (m->actuator_trntype[u] != mjTRN_JOINT || m->actuator_trnid[2 * u] != j) continue;
        d->ctrl[u] = 0;
        if (m->actuator_actnum[u] > 0)
          mju_zero(d->act + m->actuator_actadr[u], m->actuator_actnum[u]);
      }
    }
    for (int b = 0; b < m->nbody; ++b)
      if (in_subtree(m, b, robot->body())) mju_zero(d->xfrc_applied + 6 * b, 6);
    sim_.forward();
    // its components let go of what they held, the robot first
    robot->on_reset();
    for (auto& e : sim_.components())
      if (e->robot == name && e->sim_component) e->sim_component->on_reset();
  }

  Simulation& sim_;
  std::map<std::uint64_t, Snapshot> snapshots_;  // by handle, oldest first
  std::uint64_t next_handle_ = 1;                // handles are never reused
};

}  // namespace

void jump_back(Simulation& sim, const std::string& why, const std::function<double()>& put_back,
               json fields) {
  end_robots_requests(sim, why);
  const double before = sim.sim_time();
  const double time = put_back();
  // what components held of the state they were in (a held joint, a motion's start) is gone
  for (auto& e : sim.components())
    if (e->sim_component) e->sim_component->on_reset();
  if (time != before) end_sleeps(sim, why);
  // every client that watches the world learns that it went back
  sim.announce("restored", std::move(fields));
}

void add_state_services(SupervisionServices& simulation, Simulation& sim) {
  auto state = std::make_shared<WorldState>(sim);
  simulation
      .offer_service("reset",
                     [state](const std::string& scope, const std::string& robot) {
                       return state->reset(scope, robot);
                     },
                     {{"scope", "all"}, {"robot", ""}})
      .doc(
          "scope \"all\": objects and time to their initial state; \"state\": objects only (time "
          "goes on); "
          "\"robot\": the robot named `robot`. Running requests of what is reset end PREEMPTED");
  simulation.offer_service("save_state", [state] { return state->save_state(); })
      .doc("Keep the whole simulation state in memory; returns its handle (an integer)");
  simulation
      .offer_service("restore_state",
                     [state](std::int64_t handle) { return state->restore_state(handle); },
                     {"handle"})
      .doc(
          "Go back to a saved state (after a spawn or a delete: object by object, by name); "
          "components are reset; "
          "returns {sim_time, exact, missing, kept}");
  simulation.offer_service("list_states", [state] { return state->list_states(); })
      .doc(
          "[{handle, sim_time, model_generation, exact, yours, owner_connected}] of the saved "
          "states");
  simulation
      .offer_service("drop_state",
                     [state](std::int64_t handle) { return state->drop_state(handle); }, {"handle"})
      .doc("Forget a saved state (one this client saved, or whose client left)");
}

}  // namespace simgate::sim
