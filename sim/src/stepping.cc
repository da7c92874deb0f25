// The stepping group of `simulation` (world_services.h, docs/world/stepping.md):
// get_simulation_state, pause, play, the async step n, and the lockstep barrier's
// lockstep_join and lockstep_step (lockstep.cc, stepping.h).
//
// `step n` is a request for n steps of a paused simulation (Simulation::owe_steps). The
// thread that runs the request takes them at once, for up to Simulation::k_inline_step_budget
// (a client driving the simulation step by step pays no hand-off to the simulation thread
// and back); the loop takes what is left, one step per iteration with requests served
// between two, so a cancel, a pause or a new step can stop it. The request ends SUCCESS
// with the new simulated time after the last step, or PREEMPTED with the steps done.
#include <cstdint>
#include <memory>

#include "simgate/core/errors.h"
#include "simgate/sim/world_services.h"
#include "stepping.h"

namespace simgate::sim {

void check_step_count(const char* service, std::int64_t n) {
  if (n < 1 || n > k_max_steps)
    throw ServiceError(std::string(service) + ": n = " + std::to_string(n) +
                           " is out of range: expected an integer from 1 to " +
                           std::to_string(k_max_steps),
                       Failure::bad_arguments, {{"parameter", "n"}});
}

void check_paused(const char* service, const Simulation& sim) {
  if (!sim.paused())
    throw ServiceError(
        std::string(service) + ": the simulation is playing; pause it first (simulation pause)",
        Failure::service_error, {{"state", to_string(sim.run_state())}});
}

namespace {

// The one step request running (`simulation`'s async slot holds at most one), and the
// lockstep barrier beside it.
class Stepping {
 public:
  explicit Stepping(Simulation& sim)
      : sim_(sim),
        lockstep_(
            std::make_shared<Lockstep>(sim, [this](const char* why) { stop_stepping(why); })) {}

  Lockstep& lockstep() { return *lockstep_; }

  json state() const {
    const SimulationStatistics s = sim_.statistics();
    // the clients connected now: each transport counts its own (connections; DDS: request writers)
    std::size_t clients = 0;
    json by_transport = json::object();
    for (const auto& manager : sim_.request_managers()) {
      const std::size_t n = manager->client_count();  // read once: the total is the parts' sum
      clients += n;
      by_transport[manager->transport_name()] = n;
    }
    json last = nullptr;
    if (const auto& dv = sim_.last_divergence()) last = to_json(*dv);
    return {{"state", to_string(sim_.run_state())},
            {"sim_time", s.sim_time},
            {"steps", s.steps},
            {"timestep", s.timestep},
            {"realtime_factor", s.recent_factor},
            {"target_realtime_factor", s.target_factor},
            {"dynamics_suspended", sim_.dynamics_suspended()},
            {"owed_steps", sim_.owed_steps()},
            {"clients", clients},
            {"clients_by_transport", by_transport},
            {"on_divergence", to_string(sim_.on_divergence())},
            {"divergences", s.bad_states},
            {"last_divergence", last},
            {"lockstep", lockstep_->state()}};
  }

  std::string pause() {
    stop_stepping("simulation pause stopped the steps");
    lockstep_->stop_steps("simulation pause stopped the steps");
    sim_.set_paused(true);
    return "Simulation is paused";
  }

  std::string play() {
    stop_stepping("simulation play resumed the simulation");
    lockstep_->stop_all("simulation play resumed the simulation");
    sim_.set_paused(false);
    return "Simulation is playing";
  }

  void step(Completion done, std::int64_t n) {
    check_step_count("simulation step", n);
    check_paused("simulation step", sim_);
    // clients stepping in lockstep: one step of another client would move them all unasked
    if (std::string why; lockstep_->refuses_plain_steps("simulation step", why))
      throw ServiceError(why, Failure::service_error, {{"lockstep", lockstep_->state()}});
    // a step request preempted by this one was settled by the slot (interrupt) already
    requested_ = static_cast<std::uint64_t>(n);
    done_ = done;
    sim_.owe_steps(requested_, [this] {
      done_(Status::success, json{{"sim_time", sim_.sim_time()}, {"steps_done", requested_}});
      done_ = Completion();
    });
    sim_.take_owed_steps(std::chrono::steady_clock::now() + Simulation::k_inline_step_budget);
  }

  // Every step: the steps done so far, to a client that asked for progress (issue #20).
  void report_progress() {
    if (!done_.progress_due()) return;
    done_.progress(
        json{{"steps_done", requested_ - sim_.owed_steps()}, {"steps_requested", requested_}});
  }

  // The running step request is interrupted (cancel, a new step, another async request of
  // `simulation`, shutdown): it ends PREEMPTED with the steps done, its reason kept.
  void interrupted() { end_early(nullptr); }

 private:
  // pause and play while steps run: the request ends PREEMPTED, saying why
  void stop_stepping(const char* why) {
    if (done_ && !done_.done()) end_early(why);
  }

  void end_early(const char* why) {
    const std::uint64_t left = sim_.forgive_owed_steps();
    if (!done_ || done_.done()) return;
    json value{{"sim_time", sim_.sim_time()},
               {"steps_done", requested_ - left},
               {"steps_requested", requested_}};
    if (why) {
      Outcome o;
      o.status = Status::preempted;
      o.failure = Failure::preempted;
      o.message = why;
      o.value = std::move(value);
      done_.finish(std::move(o));
    } else {
      // the reason the core gave the interruption (cancelled by its client, preempted by...)
      done_(Status::preempted, std::move(value));
    }
    done_ = Completion();
  }

  Simulation& sim_;
  std::shared_ptr<Lockstep> lockstep_;  // the lockstep barrier (stepping.h)
  std::uint64_t requested_ = 0;         // n of the running request
  Completion done_;                     // the running request (empty when none)
};

}  // namespace

void add_stepping_services(SupervisionServices& simulation, Simulation& sim) {
  auto stepping = std::make_shared<Stepping>(sim);
  simulation.offer_service("get_simulation_state", [stepping] { return stepping->state(); })
      .doc(
          "{state, sim_time, steps, timestep, realtime_factor (measured over the last second of "
          "playing), "
          "target_realtime_factor, dynamics_suspended, owed_steps, clients, on_divergence, "
          "divergences, "
          "last_divergence, lockstep}");
  simulation.offer_service("pause", [stepping] { return stepping->pause(); })
      .not_replayed()
      .doc("Stop time and physics (requests are still served); ends a running step PREEMPTED");
  simulation.offer_service("play", [stepping] { return stepping->play(); })
      .not_replayed()
      .doc("Resume time and physics at the real-time factor; ends a running step PREEMPTED");
  simulation
      .offer_async_service(
          "step",
          [stepping](Completion done, std::int64_t n) { stepping->step(std::move(done), n); },
          {{"n", 1}})
      .interruptible()
      .not_replayed()
      .doc(
          "Paused only: take n steps as fast as possible; SUCCESS {sim_time, steps_done}, or "
          "PREEMPTED with the "
          "steps done");
  simulation.on_interrupt("step", [stepping] { stepping->interrupted(); });
  simulation
      .offer_async_service("lockstep_join",
                           [stepping](Completion call, const std::string& participant) {
                             stepping->lockstep().join(std::move(call), participant);
                           },
                           {{"participant", ""}})
      .concurrent()
      .not_replayed()
      .doc(
          "Take part in the lockstep until this call ends (cancel it, or leave): the simulation "
          "steps when "
          "every participant has asked (lockstep_step); the first progress report names the "
          "participant");
  simulation
      .offer_async_service(
          "lockstep_step",
          [stepping](Completion call, const std::string& participant, std::int64_t n) {
            stepping->lockstep().step(std::move(call), participant, n);
          },
          {"participant", {"n", 1}})
      .concurrent()
      .not_replayed()
      .doc(
          "Paused only: wait at the lockstep barrier until every participant has asked for the "
          "same n, then "
          "the n steps are taken once; SUCCESS {sim_time, steps_done}");
  simulation.on_step([stepping] { stepping->report_progress(); });
}

}  // namespace simgate::sim
