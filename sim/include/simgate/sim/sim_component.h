// simgate/sim/sim_component.h — components that live in the MuJoCo world.
//
// SimComponent is a Component with access to the simulation (model, data, clock). Robot is
// the SimComponent of a robot: it is bound to a MuJoCo body (its root), and its components
// (actuators, sensors) find it as their parent. A robot that can drive offers a
// DifferentialDrive (linear and angular velocity commands), which motion_vw and waypoint
// use; the drive turns them into MuJoCo actuator controls.
//
// MORSE's object services (core/object.py): every component the registry creates also
// answers `get_properties` -> {"properties": {name: value}}, `set_property name value`
// (FAILED naming the valid names when there is no such property, or it is read-only, or
// the value is refused) and `get_configurations` -> {"configurations": {the type, body and
// options it was created with, "object_to_robot": {"translation": [x, y, z], "rotation":
// [w, x, y, z]}}} (its body's pose in its robot's root frame). A component declares its
// properties in its constructor with add_property / add_number_property; the registry
// adds the three services after the component's own (add_object_services).
//
// When the model is replaced (a spawn, a delete), every SimComponent gets
// on_model_changed() with the remap of MuJoCo ids: what it keeps of the model it re-resolves
// there (docs/writing-a-component.md).
//
// Threads: everything here runs on the simulation thread (services, default_action(),
// interrupt(), on_reset(), on_model_changed()).
#ifndef SIMGATE_SIM_SIM_COMPONENT_H_
#define SIMGATE_SIM_SIM_COMPONENT_H_

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "simgate/core/component.h"
#include "simgate/sim/model_remap.h"
#include "simgate/sim/simulation.h"

namespace simgate::sim {

// A MORSE property: a named value of a component, read by get_properties.
struct Property {
  std::string name;                      // as get_properties and set_property spell it
  std::function<json()> get;             // its current value
  std::function<void(const json&)> set;  // empty: read-only; throws ServiceError to refuse
};

class SimComponent : public Component {
 public:
  SimComponent(std::string name, Simulation& sim) : Component(std::move(name)), sim_(sim) {}

  // After `simulation reset_objects` restored the initial state, or the simulation
  // recovered from a bad state the same way (simulation.h): drop commands.
  virtual void on_reset() {}

  // Whether the component reads the `frequency` of its configuration itself (a camera's
  // frame rate), rather than only as its output stream's rate.
  virtual bool uses_frequency() const { return false; }

  // The frame the component senses from, for transports that place its data in the scene
  // (Foxglove's /tf, docs/world/scene_geometry.md): the body it is fixed to and the frame's
  // world pose now (a camera's: its optical frame, x right, y down, z forward).
  struct SensingFrame {
    int body = 0;
    Eigen::Vector3d position = Eigen::Vector3d::Zero();
    Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  };
  // Under the simulation lock. nullopt: no frame of its own (an actuator, a world service).
  virtual std::optional<SensingFrame> sensing_frame() const { return std::nullopt; }

  // After the model was replaced (Simulation::replace_model: an entity spawned, a body
  // deleted): model() is the new one, and `remap` says where each object of the old one
  // went (model_remap.h). A component that keeps MuJoCo ids (bodies, joints, geoms,
  // sites, actuators, sensors) maps each through `remap`, and re-reads what it derived
  // from them in the new model (qpos and qvel addresses, sensordata addresses, per-object
  // tables sized by the model's counts). Its objects are never removed while it lives (the
  // simulation refuses, or removes the component first). An override of a class that
  // overrides it calls the base's. The ids of add_object_services() follow on their own.
  virtual void on_model_changed(const ModelRemap& remap) { (void)remap; }
  // Simulation::replace_model: remaps the ids of add_object_services(), then
  // on_model_changed(remap).
  void model_changed(const ModelRemap& remap);
  // The body given to add_object_services() (-1: none): the body it is bound to.
  int bound_body() const { return body_; }

  // Adds get_properties, set_property and get_configurations. `configuration`: what the
  // component was created with; `body` and `robot_body`: MuJoCo body ids (-1: none) for
  // object_to_robot. Called once, by ComponentRegistry::create.
  void add_object_services(json configuration, int body, int robot_body);

  json get_properties() const;
  void set_property(const std::string& name, const json& value);
  json get_configurations() const;
  const std::vector<Property>& properties() const { return properties_; }

 protected:
  Simulation& sim() const { return sim_; }
  const mjModel* model() const { return sim_.m(); }
  mjData* data() const { return sim_.d(); }

  // A read-only property.
  void add_property(std::string name, std::function<json()> get);
  // A settable property; `set` receives the client's value and throws ServiceError
  // (Failure::bad_arguments) to refuse it.
  void add_property(std::string name, std::function<json()> get,
                    std::function<void(const json&)> set);
  // A number kept in `value`, settable to a finite number within [low, high] (`unit` for
  // the refusal's text). `value` must outlive the component (a member).
  void add_number_property(std::string name, double& value, double low, double high,
                           std::string unit);

 private:
  Simulation& sim_;                   // owns this component
  std::vector<Property> properties_;  // in declaration order
  json configuration_;                // as created (type, body, options)
  int body_ = -1;                     // for object_to_robot (-1: none)
  int robot_body_ = -1;               // the robot's root body (-1: none)
};

// A body's pose in the world frame, at Simulation::state_time().
Eigen::Vector3d body_position(const Simulation& sim, int body);
Eigen::Quaterniond body_orientation(const Simulation& sim, int body);
// Roll, pitch, yaw (ZYX convention: yaw about z, then pitch about y, then roll about x).
Eigen::Vector3d to_roll_pitch_yaw(const Eigen::Quaterniond& q);
Eigen::Quaterniond from_roll_pitch_yaw(double roll, double pitch, double yaw);

// True when `body` is `root` or one of its descendants (a robot's parts: its joints,
// actuators and sensors are those attached to bodies of its subtree).
bool in_subtree(const mjModel* m, int body, int root);

// Moves a free-joint body: sets position and orientation, zeroes its velocity, then
// Simulation::forward() (what sensors read next is of the moved body, at the current time).
void set_free_body_pose(Simulation& sim, int free_joint, const Eigen::Vector3d& position,
                        const Eigen::Quaterniond& orientation);

// Reading a command of an input stream (Component::declare_input_stream): the number under
// `key`, or `fallback` when it is absent; absent without a fallback, or not a number, is a
// ServiceError (bad_arguments) naming the key.
double command_number(const json& command, const std::string& key,
                      std::optional<double> fallback = std::nullopt);

// Linear (m/s) and angular (rad/s, counter-clockwise) velocity commands for a ground robot.
class DifferentialDrive {
 public:
  virtual ~DifferentialDrive() = default;
  virtual void set_velocity(double v, double w) = 0;
  virtual double linear_velocity() const = 0;   // the last command
  virtual double angular_velocity() const = 0;  // the last command
};

class Robot : public SimComponent {
 public:
  Robot(std::string name, Simulation& sim, int body)
      : SimComponent(std::move(name), sim), body_(body) {}

  // The root body.
  int body() const { return body_; }
  void on_model_changed(const ModelRemap& remap) override { body_ = remap.body_of(body_); }
  // The drive, or nullptr for robots that cannot drive.
  virtual DifferentialDrive* drive() { return nullptr; }

  Eigen::Vector3d position() const { return body_position(sim(), body_); }
  Eigen::Quaterniond orientation() const { return body_orientation(sim(), body_); }
  double yaw() const { return to_roll_pitch_yaw(orientation()).z(); }

 private:
  int body_;  // MuJoCo body id of the root
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_SIM_COMPONENT_H_
