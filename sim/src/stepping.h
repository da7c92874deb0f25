// sim/src/stepping.h — what the stepping services share (private to libsimgate_sim):
// the rules every request for steps follows, and the lockstep barrier (lockstep.cc) that
// lets several clients step one paused simulation together. docs/world/stepping.md.
//
// Terms (lockstep):
//  - participant: a client taking part in the lockstep. It joins with `simulation
//    lockstep_join [participant]`, a concurrent async call that never ends by itself: it
//    stays a participant while that call runs. Cancelling the call, its client leaving (every
//    transport cancels a leaving client's calls: on_disconnect "cancel"), its deadline, a
//    divergence or the shutdown end the call and the membership with it, so a client that
//    crashed never holds the others. Named by the client (`participant`) or by the simulation
//    ("p1", "p2"...); the join's first progress report says which.
//  - barrier: the `simulation lockstep_step [participant, n]` calls waiting for steps. It
//    gathers until every participant has asked, all for the same n; then it is released: the
//    n steps are taken once, by the machinery `simulation step` uses (Simulation::owe_steps:
//    the thread that releases it steps for a short budget, the loop takes the rest), and
//    every call of the barrier completes SUCCESS {sim_time, steps_done}. A participant that
//    leaves may release the barrier the others wait at. Asks that arrive while a released
//    barrier's steps are still being taken gather for the next one.
//  - active: the lockstep has participants, or a released barrier's steps are still being
//    taken. Meanwhile a plain `simulation step` is refused: it would move every participant
//    without its asking.
//
// Threads: under the simulation lock, as every service.
#ifndef SIMGATE_SIM_SRC_STEPPING_H_
#define SIMGATE_SIM_SRC_STEPPING_H_

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "simgate/core/service.h"
#include "simgate/sim/simulation.h"

namespace simgate::sim {

// More than this in one request is a mistake (a typo, a unit error): 1e6 steps are half an
// hour of simulated time at the demo's 2 ms, and about a minute of stepping.
constexpr std::int64_t k_max_steps = 1'000'000;

// Refuses (ServiceError, bad_arguments, parameter "n") an n outside 1..k_max_steps, in the
// words of `service` ("simulation step").
void check_step_count(const char* service, std::int64_t n);
// Refuses (ServiceError) a request for steps while the simulation plays.
void check_paused(const char* service, const Simulation& sim);

class Lockstep : public std::enable_shared_from_this<Lockstep> {
 public:
  // `stop_plain_step(why)` ends a running `simulation step` PREEMPTED saying why (stepping.cc):
  // a join ends it, as the lockstep takes the stepping over.
  Lockstep(Simulation& sim, std::function<void(const char* why)> stop_plain_step);

  // simulation lockstep_join [participant]: `call` runs while the client takes part.
  void join(Completion call, const std::string& participant);
  // simulation lockstep_step participant [n]: `call` waits at the barrier.
  void step(Completion call, const std::string& participant, std::int64_t n);

  // Whether a plain `simulation step` must be refused; then `why` says so, in the words of
  // `service`.
  bool refuses_plain_steps(const char* service, std::string& why);
  // pause: the steps being taken stop, and the calls they were for end PREEMPTED with the
  // steps done (a gathering barrier waits on: it moved nothing yet).
  void stop_steps(const char* why);
  // play: the same, and the calls of a gathering barrier end PREEMPTED too (a playing
  // simulation takes no lockstep steps).
  void stop_all(const char* why);
  // get_simulation_state's "lockstep": {participants, waiting (the names that asked), n (the
  // barrier's, or null), stepping (a released barrier's steps are being taken)}.
  json state();

 private:
  struct Participant {
    std::string name;       // as the client gave it, or made up
    Completion membership;  // its lockstep_join call
    Completion asked;       // its lockstep_step call at the gathering barrier (empty: none)
  };

  // Forgets what has ended: participants whose join ended (their ask ends PREEMPTED), asks
  // that ended (cancelled, timed out), a released barrier whose steps were forgiven
  // elsewhere (a divergence).
  void prune();
  // Releases the barrier when every participant has asked and no steps are being taken:
  // `inline_steps` takes them on this thread for the short budget (a request's thread),
  // else leaves them all to the loop (a hook run inside the core's cancel).
  void release_if_complete(bool inline_steps);
  // The last step of the released barrier was taken: its calls complete.
  void released_steps_done();
  // Ends `calls` PREEMPTED with `why` and the steps done of n.
  void preempt(std::vector<Completion>& calls, const char* why, std::uint64_t steps_done,
               std::uint64_t n);
  Participant* find(const std::string& name);
  std::vector<std::string> names() const;
  std::vector<std::string> waiting_names() const;
  // "a, b" or "none"
  std::string names_text() const;

  Simulation& sim_;
  std::function<void(const char*)> stop_plain_step_;  // ends a running `simulation step`
  std::vector<Participant> participants_;             // in the order they joined
  std::uint64_t gathering_n_ = 0;     // the n the gathering barrier asks (0: no ask)
  bool stepping_ = false;             // a released barrier's steps are owed
  std::uint64_t released_n_ = 0;      // its n
  std::vector<Completion> released_;  // its calls
  std::uint64_t next_number_ = 1;     // for names made up: "p1", "p2"...
};

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_SRC_STEPPING_H_
