#include "simgate/core/simulation_gate.h"

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

bool SimulationGate::wait_until(Clock::time_point deadline) {
  if (consume()) return true;
  // no spinning: a request that finds the lock free runs on its transport's thread, so a
  // waiting simulation thread only needs waking for queued work (the loop is stepping, or
  // an async completion came from another thread)
  std::unique_lock lock(wait_mutex_);
  sleeping_.store(true);
  cv_.wait_until(lock, deadline, [this] { return pending_.load(); });
  sleeping_.store(false);
  lock.unlock();
  return consume();
}

}  // namespace simgate
