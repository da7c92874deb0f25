// divergence.cc — a step that goes wrong (Simulation, simulation.h): MuJoCo's warnings after
// each step, logged without flooding; a bad state (NaN, infinity, a magnitude beyond 1e10)
// recovered by the scene's on_divergence policy (pause: the step undone; reset; restore: the
// last checkpoint), announced and reported (last_divergence, simulation.events); the
// requests running then failed; controls that are not numbers dropped. Under the simulation
// lock, as the step is.
#include <cstdint>
#include <cstdio>
#include <string>

#include "simgate/core/log.h"
#include "simgate/sim/sim_component.h"
#include "simgate/sim/simulation.h"

#include "bad_state.h"
#include "helpers.h"

namespace simgate::sim {

namespace {

// A flood of warnings (a bad state in every step) must not fill the disk: the first ten
// occurrences of a kind are logged, then the 100th, the 1000th, ...
constexpr std::uint64_t k_logged_individually = 10;

// Whether one of the occurrences (before, after] gets a log line.
bool worth_a_line(std::uint64_t before, std::uint64_t after) {
  if (before < k_logged_individually) return true;
  for (std::uint64_t n = 100; n <= after; n *= 10) {
    if (n > before) return true;
    if (n > UINT64_MAX / 10) break;
  }
  return false;
}

// What follows a logged occurrence: its number, and how the next ones are reported.
std::string occurrence(const char* what, std::uint64_t total, const char* counted_in = "") {
  std::string text = " [" + std::string(what) + " " + std::to_string(total);
  if (total == k_logged_individually)
    return text + "; further " + what + "s are counted" + counted_in +
           " and logged at the 100th, 1000th, ...]";
  if (total > k_logged_individually) return text + "; logged at powers of ten]";
  return text + "]";
}

std::string seconds(double t) {
  char text[48];
  std::snprintf(text, sizeof text, "t=%.4f s", t);
  return text;
}

// The warnings that do not reset the state, as a user can act on them.
const char* describe_warning(int warning) {
  switch (warning) {
    case mjWARN_INERTIA: return "a (nearly) singular inertia matrix";
    // contacts and constraints share one arena, sized by <size memory="...">
    case mjWARN_CONTACTFULL:
      return "too many contacts: some were dropped (raise memory in the MJCF's <size>)";
    case mjWARN_CNSTRFULL:
      return "too many constraints: some were dropped (raise memory in the MJCF's <size>)";
    default: return "an unknown warning";
  }
}

}  // namespace

bool Simulation::check_mujoco_warnings(double time_before) {
  mjData* data = d();
  // MuJoCo's reset inside mj_step zeroes every counter, then sets the bad kind's to 1, and
  // restarts time from 0 (plus the step): a counter that moved or a clock that went back
  // tells it. The clock is the sure sign once a counter already reads 1.
  bool engine_reset = data->time < time_before + 0.5 * timestep();
  for (int k = 0; k < mjNWARNING; ++k)
    if (resets_the_state(k) && data->warning[k].number != warnings_seen_[k]) engine_reset = true;

  std::array<std::uint64_t, mjNWARNING> fresh{};  // occurrences of each kind in this step
  bool any = false;
  for (int k = 0; k < mjNWARNING; ++k) {
    const int now = data->warning[k].number;
    // after an engine reset the counters count from it (what came before in the step is lost)
    fresh[k] = engine_reset || now < warnings_seen_[k] ? now : now - warnings_seen_[k];
    any = any || fresh[k] > 0;
  }
  if (!any && !engine_reset) return false;

  const std::string when = "in the step from " + seconds(time_before);
  for (int k = 0; k < mjNWARNING; ++k) {
    if (fresh[k] == 0 || resets_the_state(k)) continue;
    const std::uint64_t before = warning_totals_[k];
    warning_totals_[k] += fresh[k];
    if (k == mjWARN_BADCTRL) {
      // MuJoCo applied no control at all in that step, and would go on so while it stays
      const std::string dropped = drop_bad_controls();
      if (worth_a_line(before, warning_totals_[k]))
        log::warning("simulation: bad control ", when,
                     ": a NaN, an infinity or a magnitude beyond 1e10 in ",
                     dropped.empty() ? std::string("a control") : dropped,
                     "; MuJoCo applied no control in that step, the simulation set it to 0",
                     occurrence("bad control", warning_totals_[k]));
    } else if (worth_a_line(before, warning_totals_[k])) {
      log::warning("simulation: MuJoCo warning ", when, ": ", describe_warning(k),
                   occurrence("warning", warning_totals_[k]));
    }
  }

  bool undone = false;
  if (engine_reset) {
    // no counter moved, yet the clock went back: something else reset MuJoCo's data
    std::string what = "simulated time went back to " + seconds(data->time);
    std::string quantity, where;
    for (int k = 0; k < mjNWARNING; ++k) {
      if (!resets_the_state(k) || fresh[k] == 0) continue;
      warning_totals_[k] += fresh[k];
      const int index = data->warning[k].lastinfo;
      quantity = bad_quantity(k, index);
      where = where_in_state(m(), k, index);
      what = "a NaN, an infinity or a magnitude beyond 1e10 in " + quantity + " (" + where + ")";
    }
    undone = diverged(time_before, what, std::move(quantity), std::move(where));
  }

  // rebase: 1 for a kind ever seen keeps MuJoCo from printing it again (it prints while the
  // counter is 0) and its int from overflowing
  for (int k = 0; k < mjNWARNING; ++k) {
    data->warning[k].number = warning_totals_[k] > 0 ? 1 : 0;
    warnings_seen_[k] = data->warning[k].number;
  }
  return undone;
}

bool Simulation::diverged(double time_before, const std::string& what, std::string quantity,
                          std::string where) {
  ++bad_states_;
  DivergencePolicy action = on_divergence_;
  // nothing to go back to (the model changed since, or no checkpoint yet): the initial state
  if ((action == DivergencePolicy::pause && !before_step_.fits(m(), model_generation_)) ||
      (action == DivergencePolicy::restore && !checkpoint_.fits(m(), model_generation_)))
    action = DivergencePolicy::reset;
  // what the world goes back to, and how it is said
  double resumed_at = 0;
  std::string done;
  switch (action) {
    case DivergencePolicy::pause:
      resumed_at = before_step_.time();
      done =
          "the simulation paused in the state before that step (simulation play goes on from "
          "there)";
      break;
    case DivergencePolicy::restore:
      resumed_at = checkpoint_.time();
      done = "the simulation went back to its checkpoint of " + seconds(checkpoint_.time()) +
             " and goes on";
      break;
    case DivergencePolicy::reset:
      // time goes on from where the step started, as if it had been a step of the reset world
      resumed_at = time_before + timestep();
      done = "the simulation restored the initial state as reset_objects does (time goes on)";
      break;
  }
  const std::string when = "in the step from " + seconds(time_before);
  const std::string reason = "the simulation diverged " + when + ": " + what + "; " + done;
  last_divergence_ =
      Divergence{time_before, steps(), std::move(quantity), std::move(where), action, resumed_at};
  // subscribers hear of the divergence first, then of what the policy does to the world
  json event = to_json(*last_divergence_);
  // of the state the bad step started from (MuJoCo's own reset left its clock elsewhere)
  event["timestamp"] = time_before;
  event["divergences"] = bad_states_;
  event["message"] = reason;
  announce("diverged", std::move(event));
  switch (action) {
    case DivergencePolicy::pause:
      // the step never happened: the world as the step found it, waiting for a client
      restore_physics(before_step_);
      forgive_owed_steps();
      set_paused(true);
      break;
    case DivergencePolicy::restore:
      restore_physics(checkpoint_);
      for (auto& e : entries_)
        if (e->sim_component) e->sim_component->on_reset();
      break;
    case DivergencePolicy::reset:
      d()->time = resumed_at;
      reset();
      break;
  }
  if (worth_a_line(bad_states_ - 1, bad_states_))
    log::warning("simulation: bad state ", when, ": ", what, " (scene.on_divergence ",
                 to_string(on_divergence_), "): ", done,
                 occurrence("bad state", bad_states_, " (time statistics: bad_states)"));
  // what was asked of the world before is void: its clients are told, not left waiting
  fail_requests(reason);
  return action == DivergencePolicy::pause;
}

json to_json(const Divergence& divergence) {
  return {{"sim_time", divergence.time},
          {"step", divergence.step},
          {"quantity", divergence.quantity},
          {"where", divergence.where},
          {"action", to_string(divergence.action)},
          {"resumed_at", divergence.resumed_at}};
}

void Simulation::fail_requests(const std::string& reason) {
  const Outcome failed = Outcome::failed(Failure::service_error, reason, json{{"diverged", true}});
  for (auto& e : entries_) {
    AsyncSlot& slot = *e->component->async_slot();
    // finished first (the one reply), then stopped: the component's own completion from
    // its interrupt() is dropped
    if (slot.busy() && slot.running_completion.finish(failed) && slot.interrupt) slot.interrupt();
    for (const Completion& call : slot.running_concurrent()) call.finish(failed);
  }
}

void Simulation::set_on_divergence(DivergencePolicy policy) {
  on_divergence_ = policy;
  checkpoint_ = PhysicsState{};  // taken anew from the next step
  next_checkpoint_ = PhysicsState{};
}

std::string Simulation::drop_bad_controls() {
  std::string names;
  for (int i = 0; i < m()->nu; ++i) {
    if (!mju_isBad(d()->ctrl[i])) continue;
    d()->ctrl[i] = 0;
    names += (names.empty() ? "the control of " : ", ") +
             name_or_index(m(), mjOBJ_ACTUATOR, i, "actuator");
  }
  return names;
}

}  // namespace simgate::sim
