// A component library with one component type, `odometer` (docs/writing-a-component.md):
// the distance its robot has travelled. Built as libsimgate_components_odometer.so with
// simgate_add_component_library(odometer odometer_library.cc); a config loads it with
// "component_libraries": ["odometer"].
#include "simgate/sim/bounds.h"             // the sane range of client numbers
#include "simgate/sim/component_library.h"  // SIMGATE_COMPONENT_LIBRARY, ComponentRegistry
#include "simgate/sim/sim_component.h"

namespace odometer {

class Odometer : public simgate::sim::SimComponent {
 public:
  explicit Odometer(simgate::sim::ComponentContext& c)
      : SimComponent(c.name(), c.sim()), robot_(c.robot()) {
    // options are read (and type-checked) here; keys nobody reads are config errors
    min_step_ = c.options().get_number("min_step", 1e-4, 0.0, 1.0);
    last_ = robot_.position();
    add_service("get_distance", &Odometer::get_distance)
        .doc("Metres travelled since start or reset");
    add_async_service("wait_distance", &Odometer::wait_distance, {"distance"})
        .interruptible()
        .doc("Completes once the robot has travelled `distance` more metres");
    // MORSE's properties: get_properties shows it, set_property changes it
    add_number_property("min_step", min_step_, 0.0, 1.0, "m");
  }

  // sync: the return value is the result (SUCCESS <json>)
  double get_distance() const { return total_; }

  // async: start the task and return; a throw ends the request FAILED
  void wait_distance(double distance) {
    if (!(distance > 0) || distance > simgate::sim::bounds::position)
      throw simgate::ServiceError("distance must be positive and at most 1e6 m",
                                  simgate::Failure::bad_arguments, {{"parameter", "distance"}});
    goal_ = total_ + distance;
  }

  // every step: measure, and finish the running request when done
  void default_action() override {
    Eigen::Vector3d p = robot_.position();
    double step = (p - last_).head<2>().norm();
    if (step >= min_step_) {
      total_ += step;
      last_ = p;
    }
    if (has_running_request() && total_ >= goal_) completed(simgate::Status::success, total_);
  }

  // after `simulation reset_objects` (and after the simulation recovered from a bad state,
  // the same way)
  void on_reset() override {
    total_ = 0;
    last_ = robot_.position();
  }

 private:
  simgate::sim::Robot& robot_;  // whose distance is measured
  double min_step_;             // metres; smaller moves are ignored
  Eigen::Vector3d last_;        // position at the last counted move
  double total_ = 0;            // metres travelled
  double goal_ = 0;             // total_ at which wait_distance completes
};

void register_types(simgate::sim::ComponentRegistry& registry) {
  registry.add<Odometer>("odometer", simgate::sim::Kind::component,
                         "distance travelled by the robot");
}

}  // namespace odometer

SIMGATE_COMPONENT_LIBRARY(odometer, "0.1.0", odometer::register_types)
