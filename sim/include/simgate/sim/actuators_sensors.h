// simgate/sim/actuators_sensors.h — a robot's MJCF actuators and MJCF sensors as components.
//
// Two generic component types give a client what the model itself declares, for any robot:
//
//  - `actuators` (ActuatorSet): the MuJoCo actuators that move the robot (actuator_kind.h
//    says which belong to it), their controls read and written by name:
//    `set_controls {name: value}`, `set_control name value`, `get_controls` -> {name: value},
//    `list_actuators` -> {name: {"type", "joint" | "tendon" | "site" | "body", "ctrlrange",
//    "forcerange", "gear", "index" (its place in MuJoCo's ctrl, as simulation step_many's
//    actions order the controls)}}. A control is refused (never clamped) when it is not a finite
//    number, lies outside the ctrlrange of a ctrllimited actuator, or beyond ±bounds::control
//    for an unlimited one; set_controls checks every name and value first and changes
//    nothing unless all pass. MuJoCo keeps a control until it is set again; reset_objects
//    sets every control to 0 (mj_resetData).
//  - `sensors` (MjcfSensors): the model's <sensor> elements whose object (site, joint, body,
//    geom, camera, tendon, actuator) is attached to the robot's subtree. `get_local_data`
//    -> {name: value (a number for one-dimensional sensors, an array otherwise),
//    "timestamp": simulated seconds}.
//
// Option `actuators` / `sensors`: a list of names restricting the component to those (each
// must be the robot's; a sensor attached to no object, such as <clock>, only through this
// list). Unnamed MJCF actuators and sensors are called "<type>_<n>": the type
// (actuator_type(), or the sensor's MJCF element) and n, counting from 0, the rank among the
// model's actuators or sensors of that type, named or not (so naming one never renames
// another). A generated name equal to a given one is a ConfigError.
//
// When the values are from: MuJoCo evaluates sensors inside mj_step, on the state the step
// starts from, then integrates. After a step the sensor values therefore describe the state
// one timestep before mjData::time; after a reset, a teleport or a joint set at once (which
// evaluate the current state) they describe the current state. "timestamp" is
// Simulation::state_time(), which follows both, as every sensor's timestamp does. Reading
// them changes nothing (no mj_forward).
//
// Everything a query needs (names, addresses, the JSON of list_actuators and the
// properties) is computed at construction: the model does not change while it runs.
//
// Threads: simulation thread (under the simulation lock), like every SimComponent.
#ifndef SIMGATE_SIM_ACTUATORS_SENSORS_H_
#define SIMGATE_SIM_ACTUATORS_SENSORS_H_

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "simgate/sim/registry.h"
#include "simgate/sim/sim_component.h"

namespace simgate::sim {

class ActuatorSet : public SimComponent {
 public:
  explicit ActuatorSet(ComponentContext& context);

  // All or nothing: every name known, every value acceptable, then all are written to ctrl.
  void set_controls(const std::map<std::string, double>& controls);
  void set_control(const std::string& name, double value);
  json get_controls() const;
  // description_ with each actuator's "index" (in MuJoCo's ctrl: step_many's actions)
  json list_actuators() const {
    json out = description_;
    for (const Actuator& a : actuators_) out[a.name]["index"] = a.id;
    return out;
  }
  void on_model_changed(const ModelRemap& remap) override {
    for (auto& a : actuators_) a.id = remap.actuator_of(a.id);
  }

  // The actuators' names, in MuJoCo's order.
  const std::vector<std::string>& names() const { return names_; }

 private:
  struct Actuator {
    std::string name;  // MJCF name or generated "<type>_<n>"
    int id;            // MuJoCo actuator index
    bool limited;      // ctrllimited: the value must lie in [low, high]
    double low, high;  // the ctrlrange when limited, else ±bounds::control
  };
  // The actuator called `name`, or a ServiceError naming the valid ones (`parameter`: the
  // service parameter that carried it).
  const Actuator& find(const std::string& name, const std::string& parameter) const;
  // Throws unless `value` suits `a` (`parameter` names it in the refusal).
  void check(const Actuator& a, double value, const std::string& parameter) const;

  std::vector<Actuator> actuators_;             // in MuJoCo's order
  std::map<std::string, std::size_t> by_name_;  // name -> index in actuators_
  std::vector<std::string> names_;              // the names, in MuJoCo's order
  json description_;                            // list_actuators' answer
};

class MjcfSensors : public SimComponent {
 public:
  explicit MjcfSensors(ComponentContext& context);

  // {name: value, ..., "timestamp": seconds}; one pass over precomputed addresses.
  json get_local_data() const;
  void on_model_changed(const ModelRemap& remap) override;

  const std::vector<std::string>& names() const { return names_; }

 private:
  struct Sensor {
    std::string name;  // MJCF name or generated "<type>_<n>"
    int id;            // MuJoCo sensor id
    int address;       // into mjData::sensordata
    int dim;           // number of values
  };

  std::vector<Sensor> sensors_;     // in MuJoCo's order
  std::vector<std::string> names_;  // the names, in MuJoCo's order
  json description_;                // the "sensors" property
};

namespace detail {
// Which of the model's actuators or sensors a component takes (actuator_set.cc).
struct Selection {
  std::string option;                     // the option listing names: "actuators"
  std::string what;                       // "actuator", "sensor"
  std::string acting;                     // "acting on", "attached to" (for "has none")
  std::vector<std::string> names;         // every object of the model, by MuJoCo id
  std::vector<bool> owned;                // by id: attached to the robot's subtree
  std::vector<bool> unattached;           // by id: attached to no object (may be listed)
  std::function<std::string(int)> where;  // by id: "drives joint 'j'", for refusals
};
// The ids the component takes: the owned ones, or those option `option` lists (each known,
// owned or unattached, listed once). Throws ConfigError naming the JSON path, the valid
// names and a likely one; also when two of the names of a chosen object coincide.
std::vector<int> select_objects(ComponentContext& context, const Selection& selection);
// Every object's name (see "Unnamed" above): MJCF name, or "<type_of(id)>_<rank>".
// `object`: mjOBJ_ACTUATOR or mjOBJ_SENSOR.
std::vector<std::string> mjcf_names(const mjModel* m, int object, int count,
                                    const std::function<std::string(int)>& type_of);
}  // namespace detail

// The MJCF element name of a MuJoCo sensor type ("accelerometer", "jointpos"), or "user".
const char* sensor_type_name(int type);

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_ACTUATORS_SENSORS_H_
