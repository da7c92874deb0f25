// The `actuators` component (ActuatorSet) and what it shares with `sensors`: the names of
// unnamed MJCF objects and the choice of a robot's objects from the component's options.
#include <cstdio>

#include "simgate/core/errors.h"
#include "simgate/core/suggest.h"
#include "simgate/sim/actuator_kind.h"
#include "simgate/sim/actuators_sensors.h"
#include "simgate/sim/bounds.h"
#include "helpers.h"

namespace simgate::sim {

namespace {
std::string quoted(const std::string& s) { return "'" + s + "'"; }

// "an actuator", "a sensor"
std::string a_or_an(const std::string& word) {
  return (word.find_first_of("aeiou") == 0 ? "an " : "a ") + word;
}

// What actuator `a` moves, for list_actuators: {"joint": "elbow"}, {"site": "crank",
// "slidersite": "slider"}...
void add_target(json& out, const mjModel* m, int a) {
  const int id = m->actuator_trnid[2 * a], second = m->actuator_trnid[2 * a + 1];
  switch (m->actuator_trntype[a]) {
    case mjTRN_JOINT:
    case mjTRN_JOINTINPARENT: out["joint"] = mujoco_name(m, mjOBJ_JOINT, id); break;
    case mjTRN_TENDON: out["tendon"] = mujoco_name(m, mjOBJ_TENDON, id); break;
    case mjTRN_SITE: out["site"] = mujoco_name(m, mjOBJ_SITE, id); break;
    case mjTRN_SLIDERCRANK:
      out["site"] = mujoco_name(m, mjOBJ_SITE, id);
      out["slidersite"] = mujoco_name(m, mjOBJ_SITE, second);
      break;
    case mjTRN_BODY: out["body"] = mujoco_name(m, mjOBJ_BODY, id); break;
    default: break;
  }
}

// "drives joint 'elbow' of body 'forearm'": where an actuator acts, for refusals.
std::string actuator_target(const mjModel* m, int a) {
  json target = json::object();
  add_target(target, m, a);
  std::string out = "drives";
  for (auto it = target.begin(); it != target.end(); ++it)
    out += " " + it.key() + " '" + it.value().get<std::string>() + "'";
  return out;
}

json range_or_null(bool limited, const mjtNum* range) {
  return limited ? json::array({range[0], range[1]}) : json();
}
}  // namespace

// ---- shared with `sensors` ---------------------------------------------------------------------

namespace detail {

std::vector<std::string> mjcf_names(const mjModel* m, int object, int count,
                                    const std::function<std::string(int)>& type_of) {
  std::vector<std::string> names(count);
  std::map<std::string, int> rank;  // per type: how many seen so far, named or not
  for (int i = 0; i < count; ++i) {
    const std::string type = type_of(i);
    const int n = rank[type]++;
    const char* given = mj_id2name(m, object, i);
    names[i] = given && *given ? given : type + "_" + std::to_string(n);
  }
  return names;
}

std::vector<int> select_objects(ComponentContext& c, const Selection& s) {
  const std::string& key = s.option;
  const Robot& robot = c.robot();
  const std::string robot_text =
      "robot '" + robot.name() + "' (body '" + c.sim().model().body_name(robot.body()) + "')";
  std::vector<std::string> owned_names;
  for (std::size_t i = 0; i < s.names.size(); ++i)
    if (s.owned[i]) owned_names.push_back(s.names[i]);

  std::vector<int> chosen;
  if (auto listed = c.options().get_json(key)) {
    const std::string path = c.options().path_of(key);
    if (!listed->is_array() || listed->empty())
      throw ConfigError(path + ": expected a non-empty list of " + s.what + " names, found " +
                        describe_json(*listed));
    for (std::size_t k = 0; k < listed->size(); ++k) {
      const json& item = (*listed)[k];
      const std::string where = path + "[" + std::to_string(k) + "]";
      if (!item.is_string())
        throw ConfigError(where + ": expected the name of " + a_or_an(s.what) + ", found " +
                          describe_json(item));
      const std::string name = item.get<std::string>();
      int id = -1;
      for (std::size_t i = 0; i < s.names.size(); ++i)
        if (s.names[i] == name) id = static_cast<int>(i);
      if (id < 0)
        throw ConfigError(where + ": expected the name of " + a_or_an(s.what) + " of " +
                          robot_text + " (" +
                          (owned_names.empty() ? "it has none" : join(owned_names)) + "), found '" +
                          name + "' (no such " + s.what + did_you_mean(name, owned_names) + ")");
      if (!s.owned[id] && !s.unattached[id])
        throw ConfigError(
            where + ": " + s.what + " '" + name + "' " + s.where(id) + ", outside " + robot_text +
            (owned_names.empty() ? "" : "; its " + s.what + "s: " + join(owned_names)));
      for (int previous : chosen)
        if (previous == id)
          throw ConfigError(where + ": " + s.what + " '" + name + "' is listed twice");
      chosen.push_back(id);
    }
  } else {
    for (std::size_t i = 0; i < s.names.size(); ++i)
      if (s.owned[i]) chosen.push_back(static_cast<int>(i));
    if (chosen.empty())
      c.fail("type", "component type '" + c.spec().type + "' needs " + s.what + "s, and " +
                         robot_text + " has none (no MJCF " + s.what + " " + s.acting +
                         " a body of its subtree)");
  }

  // a generated name must not be the name of another object the model names so
  for (int id : chosen)
    for (std::size_t other = 0; other < s.names.size(); ++other)
      if (static_cast<int>(other) != id && s.names[other] == s.names[id])
        throw ConfigError(c.spec().path + ": " + s.what + "s " + std::to_string(id) + " and " +
                          std::to_string(other) + " of scene '" + c.sim().model().source() +
                          "' are both called " + quoted(s.names[id]) +
                          " (one unnamed, named after its type and rank): name it in the MJCF");
  return chosen;
}

}  // namespace detail

// ---- actuators -----------------------------------------------------------------------------

ActuatorSet::ActuatorSet(ComponentContext& c) : SimComponent(c.name(), c.sim()) {
  const mjModel* m = c.sim().m();
  const int root = c.robot().body();
  detail::Selection selection;
  selection.option = "actuators";
  selection.what = "actuator";
  selection.acting = "acting on";
  selection.names =
      detail::mjcf_names(m, mjOBJ_ACTUATOR, m->nu, [m](int a) { return actuator_type(m, a); });
  for (int a = 0; a < m->nu; ++a) {
    selection.owned.push_back(actuator_in_subtree(m, a, root));
    selection.unattached.push_back(false);
  }
  selection.where = [m](int a) { return actuator_target(m, a); };

  description_ = json::object();
  for (int id : detail::select_objects(c, selection)) {
    const bool limited = m->actuator_ctrllimited[id];
    const mjtNum* ctrl = m->actuator_ctrlrange + 2 * id;
    Actuator a{selection.names[id], id, limited, limited ? ctrl[0] : -bounds::control,
               limited ? ctrl[1] : bounds::control};
    by_name_[a.name] = actuators_.size();
    names_.push_back(a.name);
    actuators_.push_back(a);

    json entry = {{"type", actuator_type(m, id)}};
    add_target(entry, m, id);
    entry["ctrlrange"] = range_or_null(limited, ctrl);
    entry["forcerange"] =
        range_or_null(m->actuator_forcelimited[id], m->actuator_forcerange + 2 * id);
    const mjtNum* gear = m->actuator_gear + 6 * id;
    // a site transmits a wrench (6 numbers); every other transmission one scalar
    entry["gear"] = m->actuator_trntype[id] == mjTRN_SITE
                        ? json::array({gear[0], gear[1], gear[2], gear[3], gear[4], gear[5]})
                        : json(gear[0]);
    description_[a.name] = std::move(entry);
  }

  add_property("actuators", [this] { return json(names_); });
  add_property("count", [this] { return json(actuators_.size()); });
  add_service("set_controls", &ActuatorSet::set_controls, {"controls"})
      .doc("Sets the controls {actuator: value} (all or none: each checked against its ctrlrange)");
  add_service("set_control", &ActuatorSet::set_control, {"name", "value"})
      .doc("Sets one actuator's control (checked against its ctrlrange)");
  add_service("get_controls", &ActuatorSet::get_controls)
      .doc("The current controls {actuator: value}");
  add_service("list_actuators", &ActuatorSet::list_actuators)
      .doc(
          "Each actuator: type, what it drives (joint, tendon, site, body), ctrlrange, forcerange, "
          "gear");
  // {actuator: control}, as set_controls
  declare_input_stream("controls", names_, [this](const json& command) {
    std::map<std::string, double> controls;
    for (auto it = command.begin(); it != command.end(); ++it)
      if (it.key() != "timestamp") controls[it.key()] = command_number(command, it.key());
    set_controls(controls);
  });
}

const ActuatorSet::Actuator& ActuatorSet::find(const std::string& name,
                                               const std::string& parameter) const {
  auto it = by_name_.find(name);
  if (it != by_name_.end()) return actuators_[it->second];
  throw ServiceError("no actuator '" + name + "' in " + this->name() +
                         " (actuators: " + join(names_) + ")" + did_you_mean(name, names_),
                     Failure::bad_arguments, {{"parameter", parameter}, {"expected", names_}});
}

void ActuatorSet::check(const Actuator& a, double value, const std::string& parameter) const {
  if (a.limited)
    bounds::require_between(parameter, value, a.low, a.high,
                            "(the ctrlrange of actuator '" + a.name + "')");
  else
    bounds::require_within(
        parameter, value, bounds::control,
        "(actuator '" + a.name + "' has no ctrlrange: the bound of every unlimited control)");
}

void ActuatorSet::set_controls(const std::map<std::string, double>& controls) {
  // every name, then every value: a refusal leaves every control as it was
  std::vector<std::pair<const Actuator*, double>> accepted;
  accepted.reserve(controls.size());
  for (const auto& [name, value] : controls) accepted.emplace_back(&find(name, "controls"), value);
  for (const auto& [actuator, value] : accepted)
    check(*actuator, value, "controls." + actuator->name);
  for (const auto& [actuator, value] : accepted) data()->ctrl[actuator->id] = value;
}

void ActuatorSet::set_control(const std::string& name, double value) {
  const Actuator& a = find(name, "name");
  check(a, value, "value");
  data()->ctrl[a.id] = value;
}

json ActuatorSet::get_controls() const {
  json out = json::object();
  for (const Actuator& a : actuators_) out[a.name] = data()->ctrl[a.id];
  return out;
}

SIMGATE_BUILTIN_TYPE(
    actuators,
    builtin_type<ActuatorSet>(
        "actuators", Kind::component,
        "the robot's MJCF actuators: set_controls, set_control, get_controls, list_actuators",
        "docs/components/actuators-and-sensors.md",
        {{"actuators",
          {{"type", "array"},
           {"minItems", 1},
           {"uniqueItems", true},
           {"items", {{"type", "string"}}}},
          "only these of the robot's MJCF actuators (default: every one acting on its subtree)"}}));

}  // namespace simgate::sim
