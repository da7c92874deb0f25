#include <chrono>
#include <cmath>

#include "simgate/core/errors.h"
#include "simgate/sim/bounds.h"
#include "simgate/sim/supervision.h"
#include "helpers.h"

namespace simgate::sim {

namespace {
// A faster pace than this is a mistake (a unit error): 0 already means "as fast as possible".
constexpr double k_max_time_scale = 1e6;
}  // namespace

TimeServices::TimeServices(Simulation& sim) : Component("time"), sim_(sim) {
  epoch_ =
      std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count() -
      sim.sim_time();
  add_service("now", &TimeServices::now).doc("Simulated time, seconds since the epoch");
  // concurrent: every caller gets its own sleep (two pymorse scripts calling simu.sleep()
  // together, or a client that left with one running, never block anyone)
  add_async_service("sleep", &TimeServices::sleep, {"time"})
      .concurrent()
      .doc("Completes after `time` simulated seconds (each caller sleeps on its own)");
  add_service("statistics", &TimeServices::statistics)
      .doc(
          "Simulated time, wall time, measured and target real-time factor, steps, bad states "
          "recovered");
  add_service("mode", &TimeServices::mode).doc("The time strategy");
  add_service("set_time_scale", &TimeServices::set_time_scale, {"value"})
      .not_replayed()
      .doc("Simulated seconds per wall second from now on (0 = as fast as possible); returns true");
}

double TimeServices::now() const { return epoch_ + sim_.sim_time(); }

void TimeServices::sleep(Completion done, double seconds) {
  if (!std::isfinite(seconds) || seconds < 0)
    throw ServiceError("time sleep: expected a non-negative number of seconds",
                       Failure::bad_arguments, {{"parameter", "time"}});
  sleeps_.push_back({std::move(done), sim_.sim_time() + seconds});
}

void TimeServices::default_action() {
  if (sleeps_.empty()) return;
  // half a step of slack absorbs floating-point accumulation in mjData::time
  const double now = sim_.sim_time() + 0.5 * sim_.timestep();
  std::erase_if(sleeps_, [&](Sleep& s) {
    if (s.done.done()) return true;  // cancelled by its client, or ended at shutdown
    if (now < s.wake_at) {
      // a client that asked for progress learns how long it still sleeps (issue #20)
      if (s.done.progress_due()) s.done.progress(json{{"time_left", s.wake_at - sim_.sim_time()}});
      return false;
    }
    s.done(Status::success);
    return true;
  });
}

json TimeServices::statistics() const {
  SimulationStatistics s = sim_.statistics();
  return {{"sim_time", s.sim_time},
          {"wall_time", s.wall_time},
          {"realtime_factor", s.realtime_factor},
          {"target_realtime_factor", s.target_factor},
          {"steps", s.steps},
          {"timestep", s.timestep},
          {"overruns", s.overruns},
          {"bad_states", s.bad_states},
          {"recent_realtime_factor", s.recent_factor},
          {"stream_samples", sim_.streams().total_samples()},
          {"stream_samples_dropped", sim_.streams().total_dropped()},
          {"state", to_string(sim_.run_state())}};
}

std::string TimeServices::mode() const {
  return sim_.realtime_factor() == 0 ? "FixedSimulationStep (as fast as possible)"
                                     : "FixedSimulationStep";
}

bool TimeServices::set_time_scale(double value) {
  // 0 is "as fast as possible"
  bounds::require_between("value", value, 0, k_max_time_scale,
                          "(simulated seconds per wall second)");
  // a factor of 1e-300 would make a step period no clock holds (it ran at full speed)
  if (value > 0 && value < Simulation::k_min_realtime_factor)
    throw ServiceError("time set_time_scale: value = " + number(value) +
                           " is too slow to pace: expected 0 "
                           "(as fast as possible) or a factor from " +
                           number(Simulation::k_min_realtime_factor) +
                           " (a simulated second in about 12 days) to " + number(k_max_time_scale),
                       Failure::bad_arguments, {{"parameter", "value"}});
  sim_.set_realtime_factor(value);
  return true;
}

}  // namespace simgate::sim
