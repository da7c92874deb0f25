// Test helper (nan_sweep_test.cc): NanSweep sends NaN, infinities and absurd magnitudes to
// every number every service of a simulation takes, found by introspection (the services'
// descriptors and parameter schemas, and every component's properties), and reports what
// let one through. ValidValues and builtin_valid_calls() give it the valid calls it cannot
// derive from the schemas (joint and actuator names, maps, trajectories).
//
// Threads: the test's own; it drives the simulation itself (process_requests, step).
#ifndef SIMGATE_TESTS_SIM_NAN_SWEEP_H_
#define SIMGATE_TESTS_SIM_NAN_SWEEP_H_

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <tuple>
#include <utility>
#include <vector>

#include "sim_fixture.h"

namespace simgate::sim::testing {

// What no service may accept for a number: not a number, infinities, and magnitudes far
// beyond every bound of bounds.h (which MuJoCo's own checks would only catch at 1e10).
inline const double k_bad_values[] = {std::numeric_limits<double>::quiet_NaN(), k_inf, -k_inf,
                                      1e300, -1e300};

inline std::string spell(double v) {
  if (std::isnan(v)) return "NaN";
  std::ostringstream out;
  out << v;
  return out.str();
}

// Whether a JSON schema admits numbers anywhere (a number, an optional one, a list or map
// of numbers).
inline bool admits_numbers(const json& schema) {
  if (!schema.is_object()) return false;
  if (auto t = schema.find("type"); t != schema.end())
    for (const json& type : t->is_array() ? *t : json::array({*t}))
      if (type == "number" || type == "integer") return true;
  for (const char* key : {"items", "additionalProperties"})
    if (auto it = schema.find(key); it != schema.end() && admits_numbers(*it)) return true;
  return false;
}

// The JSON pointers of every number inside `value`.
inline void number_leaves(const json& value, const json::json_pointer& at,
                          std::vector<json::json_pointer>& out) {
  if (value.is_number()) {
    out.push_back(at);
  } else if (value.is_array()) {
    for (std::size_t i = 0; i < value.size(); ++i) number_leaves(value[i], at / i, out);
  } else if (value.is_object()) {
    for (auto it = value.begin(); it != value.end(); ++it) number_leaves(*it, at / it.key(), out);
  }
}

// Every qpos, qvel, ctrl and act is finite; otherwise what is not.
inline std::string non_finite_state(const mjModel* m, const mjData* d) {
  auto first_bad = [](const char* what, const mjtNum* v, int n) -> std::string {
    for (int i = 0; i < n; ++i)
      if (!std::isfinite(v[i]))
        return std::string(what) + "[" + std::to_string(i) + "] = " + spell(v[i]);
    return "";
  };
  for (auto bad : {first_bad("qpos", d->qpos, m->nq), first_bad("qvel", d->qvel, m->nv),
                   first_bad("ctrl", d->ctrl, m->nu), first_bad("act", d->act, m->na)})
    if (!bad.empty()) return bad;
  return "";
}

// Valid argument lists (each: every parameter, positionally) for one service.
using ValidCalls = std::vector<json>;
// By "<component type>.<service>"; empty: the model has nothing it applies to.
using ValidCallTable =
    std::map<std::string, std::function<ValidCalls(const std::string& component)>>;

// Runs the sweep over every component of a simulation served by `rm`; collects findings.
class NanSweep {
 public:
  NanSweep(Simulation& sim, RecordingManager& rm, ValidCallTable table)
      : sim_(sim), rm_(rm), table_(std::move(table)) {}

  // Every problem found, one line each ("robot.motion.set_speed(/0 = NaN): SUCCESS").
  std::vector<std::string> run() {
    for (const auto& e : sim_.components()) {
      for (const auto& service : e->component->services()) sweep_service(*e, service->descriptor());
      if (e->sim_component) sweep_properties(*e);
    }
    return findings_;
  }
  // Lets `"<type>.<service>"` accept the finite `value` at `slot` (a JSON pointer into its
  // arguments), for `reason`: a magnitude that never reaches MuJoCo and means something.
  // Never for a NaN or an infinity.
  void tolerate(std::string type_service, std::string slot, double value, std::string reason) {
    if (!std::isfinite(value))
      throw std::invalid_argument("the sweep tolerates no NaN or infinity");
    tolerated_[{std::move(type_service), std::move(slot), value}] = std::move(reason);
  }
  // "<component>.<service>" of every service swept with bad numbers, and of every property.
  const std::set<std::string>& swept() const { return swept_; }
  std::size_t bad_calls() const { return bad_calls_; }

 private:
  void sweep_service(const ComponentEntry& e, const ServiceDescriptor& service) {
    bool takes_numbers = false;
    for (const auto& p : service.params)
      takes_numbers = takes_numbers || admits_numbers(p.schema) || p.schema.empty();
    // set_property: swept per property, below
    if (!takes_numbers || service.name == "set_property") return;
    const std::string name = service.qualified_name();
    std::optional<ValidCalls> calls = valid_calls(e, service);
    if (!calls) {
      findings_.push_back(name + ": takes numbers, but the sweep knows no valid call (add '" +
                          e.type + "." + service.name + "' to the table of valid calls)");
      return;
    }
    for (const json& args : *calls) {
      // each valid call from the initial state (simulation reset_objects' path): what the
      // previous ones left (joints held kinematically, a humanoid lying on the floor with
      // a limb set into it) must not be blamed on the next bad number
      sim_.reset();
      // the valid call first: a refusal below must be the bad number's doing
      Outcome valid = call(service, args);
      if (valid.status != Status::success) {
        findings_.push_back(name + " " + args.dump() + ": the valid call ended " +
                            std::string(to_string(valid.status)) + ": " + valid.message);
        continue;
      }
      check_state(name + " (valid call)");
      for (const json::json_pointer& slot : number_slots(service, args))
        for (double bad : k_bad_values) {
          json bad_args = args;
          bad_args[slot] = bad;
          const std::string what = name + "(" + slot.to_string() + " = " + spell(bad) + ")";
          Outcome o = call(service, bad_args);
          ++bad_calls_;
          swept_.insert(name);
          if (tolerated_.count({e.type + "." + service.name, slot.to_string(), bad}))
            ;  // its outcome is the service's business; the state is checked all the same
          else if (o.status != Status::failed)
            findings_.push_back(what + ": ended " + std::string(to_string(o.status)) +
                                (o.value ? " " + o.value->dump() : std::string()) +
                                ", expected FAILED");
          else if (!names_the_parameter(o.message, service, slot))
            findings_.push_back(what + ": FAILED without naming the parameter: " + o.message);
          check_state(what);
        }
    }
  }

  // The rule: a refusal names the parameter ("x = nan is out of bounds...",
  // "controls.elbow_motor = inf...", "points[1].positions[0]: nan is not...").
  static bool names_the_parameter(const std::string& message, const ServiceDescriptor& service,
                                  const json::json_pointer& slot) {
    const std::string path = slot.to_string();  // "/0/points/1/positions/0"
    const std::size_t index = std::stoul(path.substr(1, path.find('/', 1) - 1));
    if (index < service.params.size() &&
        message.find(service.params[index].name) != std::string::npos)
      return true;
    // deeper: the key or index it sits at
    const std::string last = slot.back();
    const bool is_index = !last.empty() && std::all_of(last.begin(), last.end(), ::isdigit);
    return message.find(is_index ? "[" + last + "]" : last) != std::string::npos;
  }

  // Where the sweep puts bad numbers: every number of the valid arguments, and each
  // parameter that admits numbers but was given none (an optional number left null).
  std::vector<json::json_pointer> number_slots(const ServiceDescriptor& service,
                                               const json& args) const {
    std::vector<json::json_pointer> slots;
    for (std::size_t i = 0; i < service.params.size() && i < args.size(); ++i) {
      const std::size_t before = slots.size();
      number_leaves(args[i], json::json_pointer() / i, slots);
      if (slots.size() == before && admits_numbers(service.params[i].schema))
        slots.push_back(json::json_pointer() / i);
    }
    return slots;
  }

  // The table's calls, or, when every parameter is a number, its default or 0.
  std::optional<ValidCalls> valid_calls(const ComponentEntry& e,
                                        const ServiceDescriptor& service) const {
    if (auto it = table_.find(e.type + "." + service.name); it != table_.end())
      return it->second(e.component->name());
    if (auto it = table_.find(e.component->name() + "." + service.name); it != table_.end())
      return it->second(e.component->name());
    json args = json::array();
    for (const auto& p : service.params) {
      const json type = p.schema.value("type", json());
      if (type != "number" && type != json::array({"number", "null"})) return std::nullopt;
      args.push_back(p.default_value ? *p.default_value : json(0.0));
    }
    return ValidCalls{args};
  }

  void sweep_properties(const ComponentEntry& e) {
    const std::string& component = e.component->name();
    for (const Property& property : e.sim_component->properties()) {
      const std::string name = component + ".set_property(" + property.name + ")";
      const json before = property.get();
      swept_.insert(name);
      for (double bad : k_bad_values) {
        const std::string what = name + " = " + spell(bad);
        RequestId id = rm_.call(component, "set_property", json::array({property.name, bad}));
        Outcome o = answer(id);
        ++bad_calls_;
        if (o.status != Status::failed)
          findings_.push_back(what + ": ended " + std::string(to_string(o.status)));
        else if (o.message.find(property.name) == std::string::npos)
          findings_.push_back(what + ": FAILED without naming the property: " + o.message);
        // a read-only property cannot be set, and may follow the state the sweep steps (a
        // camera's pose): only a settable one must keep its value
        if (property.set && property.get() != before)
          findings_.push_back(what + ": the property changed from " + before.dump() + " to " +
                              property.get().dump());
        check_state(what);
      }
    }
  }

  // Calls and waits for the outcome: a sync service answers at once; an async one that
  // started runs (bounded) to its end.
  Outcome call(const ServiceDescriptor& service, const json& args) {
    RequestId id = rm_.call(service.component, service.name, args);
    sim_.process_requests();
    if (auto o = rm_.outcome(id)) return *o;
    if (!service.is_async) return Outcome::failed(Failure::internal, "no answer");
    // started: a valid call runs to its end; a bad one should never have started
    for (int i = 0; i < k_async_steps; ++i) {
      sim_.step();
      sim_.process_requests();
      if (auto o = rm_.outcome(id)) return *o;
      // work of another thread (a camera's render) needs wall time, not steps
      if (i >= k_async_steps / 5 && i % 50 == 0)
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    rm_.cancel(id);
    sim_.process_requests();
    return rm_.outcome(id).value_or(
        Outcome::failed(Failure::internal, "still running after a cancel"));
  }
  Outcome answer(RequestId id) {
    sim_.process_requests();
    return rm_.outcome(id).value_or(Outcome::failed(Failure::internal, "no answer"));
  }

  // Finite state right after `what` and after three steps, time going on, no bad state.
  void check_state(const std::string& what) {
    const mjModel* m = sim_.m();
    const mjData* d = sim_.d();
    bool broken = false;
    if (std::string bad = non_finite_state(m, d); !bad.empty()) {
      findings_.push_back(what + ": right after it " + bad);
      broken = true;
    }
    const double t = sim_.sim_time();
    for (int i = 0; i < 3; ++i) sim_.step();
    if (std::string bad = non_finite_state(m, d); !bad.empty()) {
      findings_.push_back(what + ": three steps later " + bad);
      broken = true;
    }
    if (!(std::abs(sim_.sim_time() - (t + 3 * sim_.timestep())) < 1e-9)) {
      findings_.push_back(what + ": simulated time went from " + spell(t) + " to " +
                          spell(sim_.sim_time()));
      broken = true;
    }
    const std::uint64_t bad_states = sim_.statistics().bad_states;
    if (bad_states != bad_states_) {
      findings_.push_back(what + ": MuJoCo found a bad state (" + std::to_string(bad_states) +
                          " so far)");
      bad_states_ = bad_states;
    }
    // the simulation leaves a warning's counter at 1 once it happened
    for (int k : {mjWARN_BADCTRL, mjWARN_BADQPOS, mjWARN_BADQVEL, mjWARN_BADQACC})
      if (d->warning[k].number != 0 && !warned_.count(k)) {
        findings_.push_back(what + ": MuJoCo warning " + std::to_string(k) +
                            " (a bad ctrl, qpos, qvel or qacc)");
        warned_.insert(k);
      }
    // one finding is enough: the next checks start from a sound state
    if (broken) sim_.reset();
  }

  static constexpr int k_async_steps = 5000;  // a valid async call's bound

  Simulation& sim_;
  RecordingManager& rm_;
  ValidCallTable table_;
  std::vector<std::string> findings_;
  std::set<std::string> swept_;
  std::map<std::tuple<std::string, std::string, double>, std::string> tolerated_;  // see tolerate()
  std::set<int> warned_;          // MuJoCo warnings already reported
  std::uint64_t bad_states_ = 0;  // bad states already reported
  std::size_t bad_calls_ = 0;
};

// ---- valid calls -----------------------------------------------------------------------------

// What the table needs to know of a simulation: joints and actuators by component.
class ValidValues {
 public:
  ValidValues(Simulation& sim, RecordingManager& rm) : sim_(sim), rm_(rm) {}

  // A service's SUCCESS value.
  json value(const std::string& component, const std::string& service, json args = json::array()) {
    RequestId id = rm_.call(component, service, std::move(args));
    sim_.process_requests();
    auto o = rm_.outcome(id);
    return o && o->status == Status::success ? o->value.value_or(json()) : json();
  }
  // An async service's SUCCESS value, served (no steps) until it answers, at most
  // `timeout` of wall time: for work of another thread (a first render makes the context).
  json await(const std::string& component, const std::string& service, json args,
             std::chrono::seconds timeout = std::chrono::seconds(60)) {
    RequestId id = rm_.call(component, service, std::move(args));
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      sim_.process_requests();
      if (auto o = rm_.outcome(id))
        return o->status == Status::success ? o->value.value_or(json()) : json();
      std::this_thread::sleep_for(std::chrono::milliseconds(1));  // the render thread works
    }
    return json();
  }
  // Makes the sweep a lockstep participant named "sweep" (its lockstep_join call runs until
  // leave_lockstep()), for lockstep_step's valid call.
  void join_lockstep(const std::string& component) {
    if (lockstep_join_ != 0) return;
    lockstep_join_ = rm_.call(component, "lockstep_join", {"sweep"});
    sim_.process_requests();
  }
  // Ends that participation: a plain `step` is refused while there is one.
  void leave_lockstep() {
    if (lockstep_join_ == 0) return;
    rm_.cancel(std::exchange(lockstep_join_, 0));
    sim_.process_requests();
  }
  // An armature's joints of a kind (mjJNT_HINGE, mjJNT_SLIDE), in get_joints' order.
  std::vector<std::string> joints(const std::string& armature, int type) {
    std::vector<std::string> out;
    for (const json& name : value(armature, "get_joints"))
      if (sim_.m()->jnt_type[sim_.model().joint_id(name.get<std::string>())] == type)
        out.push_back(name.get<std::string>());
    return out;
  }
  // A position a joint accepts: 0, or inside its range a tenth of it from the nearer end.
  double position(const std::string& joint) const {
    const mjModel* m = sim_.m();
    const int j = sim_.model().joint_id(joint);
    if (!m->jnt_limited[j]) return 0.0;
    const double low = m->jnt_range[2 * j], high = m->jnt_range[2 * j + 1],
                 margin = 0.1 * (high - low);
    return std::clamp(0.0, low + margin, high - margin);
  }
  json positions(const std::vector<std::string>& joints) const {
    json out = json::object();
    for (const auto& j : joints) out[j] = position(j);
    return out;
  }
  std::vector<std::string> actuators(const std::string& component) {
    std::vector<std::string> out;
    const json listed = value(component, "list_actuators");  // kept: items() refers to it
    for (auto it = listed.begin(); it != listed.end(); ++it) out.push_back(it.key());
    return out;
  }
  // The last body with a free joint (one `simulation set_object_position` can place): a
  // prop rather than the robot listed first, whose wheel servos a push could upset.
  std::string free_body() const {
    for (int b = sim_.m()->nbody - 1; b > 0; --b)
      if (sim_.model().free_joint_of(b) >= 0) return sim_.model().body_name(b);
    return "";
  }

 private:
  Simulation& sim_;
  RecordingManager& rm_;
  RequestId lockstep_join_ = 0;  // the sweep's lockstep_join call, while it takes part
};

// Valid calls of every built-in service that takes more than plain numbers. `values` must
// outlive the table.
inline ValidCallTable builtin_valid_calls(ValidValues& values) {
  ValidValues* v = &values;
  ValidCallTable t;
  auto per_joint = [v](int type, bool with_speed) {
    return [v, type, with_speed](const std::string& c) {
      ValidCalls calls;
      for (const auto& j : v->joints(c, type)) {
        json args = {j, v->position(j)};
        if (with_speed) args.push_back(nullptr);  // the default speed
        calls.push_back(args);
      }
      return calls;
    };
  };
  // {joint: position} of every joint of a kind
  auto all_joints = [v](int type, bool with_speed) {
    return [v, type, with_speed](const std::string& c) {
      std::vector<std::string> joints = v->joints(c, type);
      if (joints.empty()) return ValidCalls{};
      json args = json::array({v->positions(joints)});
      if (with_speed) args.push_back(nullptr);
      return ValidCalls{args};
    };
  };
  // issue #19's integers: step takes them while paused (the sweep steps the simulation
  // itself, paused or not); a state's handle comes from save_state
  t["simulation.step"] = [v](const std::string& c) {
    v->value(c, "pause");
    v->leave_lockstep();
    return ValidCalls{{1}};
  };
  // the lockstep barrier's ask: the sweep alone takes part, so its ask steps at once
  t["simulation.lockstep_step"] = [v](const std::string& c) {
    v->value(c, "pause");
    v->join_lockstep(c);
    return ValidCalls{{"sweep", 1}};
  };
  // a camera captures at least one image; its first image (get_local_data, awaited)
  // makes the render context first, so that the capture takes milliseconds
  t["video_camera.capture"] = [v](const std::string& c) {
    v->await(c, "get_local_data", json::array());
    return ValidCalls{{1}};
  };
  t["depth_camera.capture"] = t["video_camera.capture"];
  // a small picture of the whole scene (the sweep spoils its width and height); a first one,
  // awaited, makes the render context, so that the sweep's take milliseconds
  t["simulation.get_snapshot"] = [v](const std::string& c) {
    v->await(c, "get_snapshot", {"", 32, 24});
    return ValidCalls{{"", 32, 24}};
  };
  t["simulation.restore_state"] = [v](const std::string& c) {
    return ValidCalls{{v->value(c, "save_state")}};
  };
  t["simulation.drop_state"] = t["simulation.restore_state"];
  t["armature.set_rotation"] = per_joint(mjJNT_HINGE, false);
  t["armature.set_translation"] = per_joint(mjJNT_SLIDE, false);
  t["armature.rotate"] = per_joint(mjJNT_HINGE, true);
  t["armature.translate"] = per_joint(mjJNT_SLIDE, true);
  t["armature.rotate_joints"] = all_joints(mjJNT_HINGE, true);
  t["armature.translate_joints"] = all_joints(mjJNT_SLIDE, true);
  t["armature.set_translations"] = all_joints(mjJNT_SLIDE, false);
  t["armature.set_rotations"] = [v, all_joints](const std::string& c) {
    ValidCalls calls = all_joints(mjJNT_HINGE, false)(c);
    // MORSE's list form, in get_joints' order: the leading hinges
    const std::vector<std::string> hinges = v->joints(c, mjJNT_HINGE);
    json list = json::array();
    for (const json& j : v->value(c, "get_joints")) {
      if (std::find(hinges.begin(), hinges.end(), j.get<std::string>()) == hinges.end()) break;
      list.push_back(v->position(j.get<std::string>()));
    }
    if (!list.empty()) calls.push_back(json::array({list}));
    return calls;
  };
  t["armature.trajectory"] = [v](const std::string& c) {
    json names = v->value(c, "get_joints");
    json start = json::array(), middle = json::array(), rest = json::array();
    for (const json& j : names) {
      const double p = v->position(j.get<std::string>());
      start.push_back(p);
      rest.push_back(0.0);
      middle.push_back(p);
    }
    // now on `time now`'s clock: every field a number the sweep can spoil
    const double now = v->value("time", "now").get<double>();
    json trajectory = {
        {"starttime", now},
        {"joint_names", names},
        {"points",
         {{{"positions", start}, {"velocities", rest}, {"time_from_start", 0.02}},
          {{"positions", middle}, {"velocities", rest}, {"time_from_start", 0.04}}}}};
    return ValidCalls{json::array({trajectory})};
  };
  t["actuators.set_control"] = [v](const std::string& c) {
    ValidCalls calls;
    for (const auto& a : v->actuators(c)) calls.push_back({a, 0.0});
    return calls;
  };
  t["actuators.set_controls"] = [v](const std::string& c) {
    json controls = json::object();
    for (const auto& a : v->actuators(c)) controls[a] = 0.0;
    return ValidCalls{json::array({controls})};
  };
  // the entities of `simulation` (sim/src/entities.cc): a free body where it starts
  t["simulation.set_object_position"] = [v](const std::string&) {
    const std::string body = v->free_body();
    if (body.empty()) return ValidCalls{};
    json pose = v->value("simulation", "get_object_pose", {body});
    return ValidCalls{{body, pose[0], {0.0, 0.0, 0.3}}};
  };
  t["simulation.set_entity_state"] = [v](const std::string&) {
    const std::string body = v->free_body();
    if (body.empty()) return ValidCalls{};
    json state = v->value("simulation", "get_entity_state", {body});
    state["twist"] = {{"linear", {0.0, 0.0, 0.1}}, {"angular", {0.0, 0.0, 0.2}}};
    return ValidCalls{{body, state}};
  };
  // a ball at a name no sweep used before (each valid call spawns one)
  t["simulation.spawn_entity"] = [](const std::string&) {
    static int spawned = 0;
    return ValidCalls{{"swept_ball_" + std::to_string(spawned++),
                       "<body><freejoint/><geom type='sphere' size='0.1' mass='1'/></body>",
                       {1.0, 1.0, 0.5}}};
  };
  return t;
}

}  // namespace simgate::sim::testing

#endif  // SIMGATE_TESTS_SIM_NAN_SWEEP_H_
