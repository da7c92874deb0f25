// simgate/core/simulation_gate.h — where transports meet the simulation loop.
//
// One SimulationGate is shared by the simulation loop and every request manager of a
// process (the gateway's Simulation hands it to each manager). It does two things:
//
//  - Wake-up. Transports signal() when they hand over work (a request, a cancel, an async
//    completion); the loop wait_until()s its next physics step and wakes at once on a
//    signal. Signals are not lost: one that arrives before the wait makes it return at once.
//  - The simulation lock. Simulation state (MuJoCo data, components, services) is touched
//    only by the thread that holds the lock. The simulation thread takes it to process
//    requests and to step; it does not hold it while it waits for the next step. A
//    transport thread that finds it free (try_lock) runs its requests at once instead of
//    waking the simulation thread: no thread hand-off between a request and its reply
//    (RequestManager::run_or_submit). While the loop steps, or when another thread holds
//    the lock, requests are queued and the holder's next process() runs them.
//
// It also holds the input tap (input_tap.h), if any: what records every input that reaches
// the simulation; managers and the stream hub of the gate call it.
//
// The lock is a plain mutex (BasicLockable: std::lock_guard<SimulationGate> works). Holders
// must not block on anything else that a lock waiter may hold.
#ifndef SIMGATE_CORE_SIMULATION_GATE_H_
#define SIMGATE_CORE_SIMULATION_GATE_H_

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <limits>
#include <mutex>

namespace simgate {

class InputTap;

class SimulationGate {
 public:
  using Clock = std::chrono::steady_clock;

  // ---- wake-up ----

  // Any thread. Never blocks for long.
  void signal();
  // The waiting thread (without the lock). Returns true if signalled (and consumes the
  // signal), false on timeout.
  bool wait_until(Clock::time_point deadline);
  bool wait_for(std::chrono::nanoseconds timeout) { return wait_until(Clock::now() + timeout); }
  // Consumes a pending signal without waiting.
  bool consume();
  // Any thread. The next wait ends no later than `when` (the earliest of those asked for
  // wins; a wait under way is shortened). Once a wait has ended on it, it is forgotten: the
  // asker asks again for its next time (RequestManager does after every process()).
  void wake_at(Clock::time_point when);

  // ---- the simulation lock ----

  void lock() { state_mutex_.lock(); }
  bool try_lock() { return state_mutex_.try_lock(); }
  void unlock() { state_mutex_.unlock(); }

  // ---- the input tap (under the simulation lock) ----

  // `tap` (not owned; null: none) is told of every input from now on, until it is replaced.
  void set_input_tap(InputTap* tap) { input_tap_ = tap; }
  InputTap* input_tap() const { return input_tap_; }

 private:
  std::atomic<bool> pending_{false};   // a signal not yet consumed
  std::atomic<bool> sleeping_{false};  // the waiter is (about to be) blocked on cv_
  // wake_at()'s earliest time (Clock ticks since its epoch); the maximum when there is none
  std::atomic<Clock::rep> wake_at_{std::numeric_limits<Clock::rep>::max()};
  std::mutex wait_mutex_;          // guards the cv_ hand-off
  std::condition_variable cv_;     // where the waiter blocks
  std::mutex state_mutex_;         // the simulation lock
  InputTap* input_tap_ = nullptr;  // under the simulation lock
};

}  // namespace simgate

#endif  // SIMGATE_CORE_SIMULATION_GATE_H_
