#include <chrono>
#include <cmath>

#include "simgate/core/errors.h"
#include "simgate/sim/supervision.h"

namespace simgate::sim {

TimeServices::TimeServices(Simulation& sim) : Component("time"), sim_(sim) {
  epoch_ = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count() -
           sim.sim_time();
  add_service("now", &TimeServices::now).doc("Simulated time, seconds since the epoch");
  // no local policy: a second sleep follows the transport's global policy (MORSE: FAILED)
  add_async_service("sleep", &TimeServices::sleep, {"time"}).doc("Completes after `time` simulated seconds");
  add_service("statistics", &TimeServices::statistics)
      .doc("Simulated time, wall time, measured and target real-time factor, steps");
  add_service("mode", &TimeServices::mode).doc("The time strategy");
}

double TimeServices::now() const { return epoch_ + sim_.sim_time(); }

void TimeServices::sleep(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0)
    throw ServiceError("time sleep: expected a non-negative number of seconds", Failure::bad_arguments,
                       {{"parameter", "time"}});
  wake_at_ = sim_.sim_time() + seconds;
}

void TimeServices::default_action() {
  // half a step of slack absorbs floating-point accumulation in mjData::time
  if (has_running_request() && sim_.sim_time() + 0.5 * sim_.timestep() >= wake_at_)
    completed(Status::success);
}

json TimeServices::statistics() const {
  SimulationStatistics s = sim_.statistics();
  return {{"sim_time", s.sim_time},
          {"wall_time", s.wall_time},
          {"realtime_factor", s.realtime_factor},
          {"target_realtime_factor", s.target_factor},
          {"steps", s.steps},
          {"timestep", s.timestep},
          {"overruns", s.overruns}};
}

std::string TimeServices::mode() const {
  return sim_.realtime_factor() == 0 ? "FixedSimulationStep (as fast as possible)" : "FixedSimulationStep";
}

}  // namespace simgate::sim
