#include "simgate/core/simulation_gate.h"

#include <algorithm>

namespace simgate {

void SimulationGate::signal() {
  pending_.store(true);  // seq_cst: pairs with sleeping_ (Dekker)
  // only pay for the mutex when the waiter may be blocked
  if (sleeping_.load()) {
    std::lock_guard lock(wait_mutex_);
    cv_.notify_one();
  }
}

bool SimulationGate::consume() { return pending_.exchange(false, std::memory_order_acq_rel); }

void SimulationGate::wake_at(Clock::time_point when) {
  const Clock::rep ticks = when.time_since_epoch().count();
  Clock::rep current = wake_at_.load();
  while (ticks < current) {
    if (wake_at_.compare_exchange_weak(current, ticks)) {
      // seq_cst: pairs with sleeping_ as signal() does; a waiter that is blocked re-reads it
      if (sleeping_.load()) {
        std::lock_guard lock(wait_mutex_);
        cv_.notify_one();
      }
      return;
    }
  }
}

bool SimulationGate::wait_until(Clock::time_point deadline) {
  if (consume()) return true;
  // no spinning: a request that finds the lock free runs on its transport's thread, so a
  // waiting simulation thread only needs waking for queued work (the loop is stepping, or
  // an async completion came from another thread), or for a request manager's deadline
  std::unique_lock lock(wait_mutex_);
  sleeping_.store(true);
  while (!pending_.load()) {
    const Clock::rep timer = wake_at_.load();
    const Clock::time_point until = std::min(deadline, Clock::time_point(Clock::duration(timer)));
    if (cv_.wait_until(lock, until) != std::cv_status::timeout) continue;  // notified: look again
    // the timer came due: forgotten, unless someone asked for an earlier time meanwhile
    Clock::rep due = timer;
    if (until.time_since_epoch().count() == timer)
      wake_at_.compare_exchange_strong(due, std::numeric_limits<Clock::rep>::max());
    break;
  }
  sleeping_.store(false);
  lock.unlock();
  return consume();
}

}  // namespace simgate
