// simgate/sim/supervision.h — the `simulation` and `time` pseudo-components (MORSE's
// supervision and time services).
//
// simulation: list_robots, details (the shape pymorse reads at connect: robots with their
// components, services and service interfaces; no stream interfaces), list_services (every
// component's services with parameters), reset_objects, activate / deactivate
// component_name, suspend_dynamics / restore_dynamics, get_scene_objects, quit (the loop
// stops after this step; the reply is sent first).
//
// The mapping is a boundary (CallContext, core/call_context.h): called through a transport,
// list_robots, details and list_services describe only the components that transport
// serves (a robot appears when it or one of its components is served), and activate /
// deactivate refuse any other component exactly as they refuse one that does not exist.
// Of those components' services, details and list_services show only the ones the
// transport's allow and deny lists let its clients call (service_access.h); list_services
// gives each the transports through which it can be called.
// get_scene_objects lists bodies, not components: the whole scene. reset_objects and
// suspend/restore_dynamics act on the world as a whole. Called directly (no request: the
// host, tests), everything is visible.
// simulation's output stream, kind "body_poses" (carried when the configuration's "streams"
// section names `simulation`, at k_body_poses_frequency unless it says otherwise): every
// body's world pose, {timestamp, generation, poses: [[x, y, z, qw, qx, qy, qz], ...]}, for a
// client that draws the scene from get_scene_geometry (docs/world/scene_geometry.md).
// simulation.events: the simulation's event stream (events.h).
// time: now (simulated time, seconds since the epoch at start), async sleep t (completes
// when t simulated seconds have passed; a concurrent service: every caller sleeps on its
// own), statistics, mode, set_time_scale value (the real-time factor, changed at run time).
//
// Threads: simulation thread only.
#ifndef SIMGATE_SIM_SUPERVISION_H_
#define SIMGATE_SIM_SUPERVISION_H_

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "simgate/core/component.h"
#include "simgate/sim/events.h"
#include "simgate/sim/simulation.h"

namespace simgate::sim {

class SupervisionServices : public Component {
 public:
  explicit SupervisionServices(Simulation& sim);

  // The body_poses stream's samples per simulated second when the configuration gives none
  // (a browser redraws at 60 Hz at most; half of that is smooth and half the traffic).
  static constexpr double k_body_poses_frequency = 30;

  std::vector<std::string> list_robots() const;
  json details() const;
  json list_services() const;
  // Each data stream the caller's transport carries, with its counters (streams.h).
  json get_stream_statistics() const;
  std::string reset_objects();
  void activate(const std::string& component_name);
  void deactivate(const std::string& component_name);
  std::string suspend_dynamics();
  std::string restore_dynamics();
  json get_scene_objects() const;
  void quit();

  // ---- the world-control groups (world_services.h) ----
  // Services of `simulation` defined outside this class register through these, exactly
  // as the class's own do (same arguments as Component::add_service / add_async_service).
  template <class F>
  ServiceBuilder offer_service(std::string name, F fn, std::vector<Param> params = {}) {
    return add_service(std::move(name), std::move(fn), std::move(params));
  }
  template <class F>
  ServiceBuilder offer_async_service(std::string name, F fn, std::vector<Param> params = {}) {
    return add_async_service(std::move(name), std::move(fn), std::move(params));
  }
  // `fn` runs in default_action() (every step, before physics), after those added before.
  void on_step(std::function<void()> fn);
  // `fn` stops what the async service `service` started when its request is interrupted
  // (cancel, preemption, shutdown); the request then ends PREEMPTED (Component::interrupt).
  void on_interrupt(const std::string& service, std::function<void()> fn);

  void default_action() override;
  void interrupt() override;

 private:
  void set_active(const std::string& component_name, bool active);
  // Whether the caller sees the robot: it serves the robot or one of its components.
  bool robot_visible(const ComponentEntry& robot) const;
  // A component the caller's transport serves, or whose stream it carries (outside a
  // request: every component).
  bool visible(const ComponentEntry& e) const;
  // `details`' stream_interfaces of `component`: [[datastream class, "IN" | "OUT"], ...]
  // for the transports that carry its stream and the caller sees.
  json stream_interfaces(const std::string& component) const;
  json body_tree(int body) const;

  Simulation& sim_;                                               // supervised
  std::vector<std::function<void()>> step_hooks_;                 // on_step, in order
  std::map<std::string, std::function<void()>> interrupt_hooks_;  // on_interrupt, by service
};

class TimeServices : public Component {
 public:
  explicit TimeServices(Simulation& sim);

  double now() const;
  void sleep(Completion done, double seconds);
  json statistics() const;
  std::string mode() const;
  // MORSE's time scale: the real-time factor from now on (0 = as fast as possible).
  bool set_time_scale(double value);

  void default_action() override;

 private:
  // One caller's sleep.
  struct Sleep {
    Completion done;  // its call
    double wake_at;   // simulated time at which it completes
  };

  Simulation& sim_;            // whose clock
  double epoch_;               // wall-clock seconds since the epoch when the simulation started
  std::vector<Sleep> sleeps_;  // the sleeps running, in the order they started
};

// Adds the world's pseudo-components to `sim`: `simulation`, `simulation.events` (the
// stream Simulation::announce publishes to), `time` and `communication`. Before run().
void add_world_components(Simulation& sim);

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_SUPERVISION_H_
