// simgate/sim/run_policy.h — what a deployment says of how the simulation runs, as words:
// the divergence policy (scene.on_divergence) and the slowest pace (scene.realtime_factor).
//
// Header-only and free of MuJoCo: the configuration parser (gateway/src/deployment_sections.cc, and
// the fuzz target that feeds it) checks these words without the simulation library. What
// each policy does is Simulation's (simulation.h, docs/world/divergence.md).
#ifndef SIMGATE_SIM_RUN_POLICY_H_
#define SIMGATE_SIM_RUN_POLICY_H_

#include <cstdint>
#include <string_view>

namespace simgate::sim {

// What the simulation does when MuJoCo finds a bad state in a step (a NaN, an infinity or a
// magnitude beyond 1e10 in qpos, qvel or qacc: the model diverged), scene.on_divergence. In
// every case the divergence is counted and described (Simulation::last_divergence, `simulation
// get_simulation_state`), logged, and every async request in flight ends FAILED saying why.
enum class DivergencePolicy : std::uint8_t {
  pause,    // the step is undone (the state before it put back) and the simulation pauses
  restore,  // the last automatic checkpoint (one per Simulation::k_checkpoint_interval of
            // simulated time) is put back, time included, and the simulation goes on
  reset,    // every object back to its initial state, time going on (reset_objects)
};

// "pause", "restore", "reset": the words of the configuration and of the wire.
constexpr const char* to_string(DivergencePolicy policy) {
  switch (policy) {
    case DivergencePolicy::pause: return "pause";
    case DivergencePolicy::restore: return "restore";
    case DivergencePolicy::reset: return "reset";
  }
  return "unknown";
}

// Parses those words; false for anything else.
constexpr bool parse_divergence_policy(std::string_view text, DivergencePolicy& out) {
  for (auto p : {DivergencePolicy::pause, DivergencePolicy::restore, DivergencePolicy::reset})
    if (text == to_string(p)) {
      out = p;
      return true;
    }
  return false;
}

// The slowest pace, in simulated seconds per wall second (a simulated second per ~12 wall
// days): slower, a step's period would pass what the clock holds. 0 is "as fast as possible".
inline constexpr double k_min_realtime_factor = 1e-6;

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_RUN_POLICY_H_
