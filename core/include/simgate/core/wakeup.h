// simgate/core/wakeup.h — how the simulation thread sleeps until there is work.
//
// Transports signal() from their I/O threads when they hand over a request or a
// completion; the simulation thread wait_until()s the next physics step and wakes at once
// on a signal. One Wakeup is shared by every request manager of a process (the gateway sets
// it), so a request on any transport wakes the loop. Signals are not lost: a signal that
// arrives before the wait makes the wait return immediately.
#ifndef SIMGATE_CORE_WAKEUP_H_
#define SIMGATE_CORE_WAKEUP_H_

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>

namespace simgate {

class Wakeup {
 public:
  using Clock = std::chrono::steady_clock;

  // Any thread. Never blocks for long.
  void signal();
  // Simulation thread. Returns true if signalled (and consumes the signal), false on
  // timeout. Spins for a few microseconds before sleeping, to keep round trips short.
  bool wait_until(Clock::time_point deadline);
  bool wait_for(std::chrono::nanoseconds timeout) { return wait_until(Clock::now() + timeout); }
  // Consumes a pending signal without waiting.
  bool consume();

  // How long wait_until spins before blocking (0 disables spinning).
  void set_spin(std::chrono::nanoseconds spin) { spin_ = spin; }

 private:
  std::atomic<bool> pending_{false};   // a signal not yet consumed
  std::atomic<bool> sleeping_{false};  // the waiter is (about to be) blocked on cv_
  std::mutex mutex_;                   // guards the cv_ hand-off
  std::condition_variable cv_;         // where the waiter blocks
  std::chrono::nanoseconds spin_{std::chrono::microseconds(50)};  // busy-wait budget
};

}  // namespace simgate

#endif  // SIMGATE_CORE_WAKEUP_H_
