// simgate/sim/events.h — simulation.events: the simulation's event stream (kind "events", an
// event stream: no rate), a pseudo-component of its own because a component has one stream
// and `simulation`'s is body_poses. Its samples tell what happened to the whole world as it
// happens, whether or not a client asked: {"event": "diverged", ...}, "paused", "resumed",
// "reset", "restored", "spawned", "deleted" (Simulation::announce publishes them;
// docs/world/divergence.md). Carried when the "streams" section names it exactly.
//
// Threads: publish() under the simulation lock.
#ifndef SIMGATE_SIM_EVENTS_H_
#define SIMGATE_SIM_EVENTS_H_

#include <utility>

#include "simgate/core/component.h"

namespace simgate::sim {

class SimulationEvents : public Component {
 public:
  static constexpr const char* k_name = "simulation.events";
  SimulationEvents() : Component(k_name) { declare_event_stream("events"); }
  // Gives `event` (a JSON object with "event" and "timestamp") of simulated time `time` to
  // every subscriber. Under the simulation lock. False when nobody subscribes.
  bool publish(double time, json event) { return push_sample(time, std::move(event)); }
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_EVENTS_H_
