#include "simgate/core/wakeup.h"

#include <thread>

namespace simgate {

void Wakeup::signal() {
  pending_.store(true);  // seq_cst: pairs with sleeping_ (Dekker)
  // only pay for the mutex when the waiter may be blocked
  if (sleeping_.load()) {
    std::lock_guard lock(mutex_);
    cv_.notify_one();
  }
}

bool Wakeup::consume() { return pending_.exchange(false, std::memory_order_acq_rel); }

bool Wakeup::wait_until(Clock::time_point deadline) {
  if (consume()) return true;
  // spin briefly: a request often arrives within microseconds of the previous reply
  if (spin_.count() > 0) {
    auto spin_end = std::min(deadline, Clock::now() + spin_);
    while (Clock::now() < spin_end) {
      if (pending_.load(std::memory_order_relaxed) && consume()) return true;
#if defined(__x86_64__) || defined(__i386__)
      __builtin_ia32_pause();
#endif
    }
  }
  std::unique_lock lock(mutex_);
  sleeping_.store(true);
  cv_.wait_until(lock, deadline, [this] { return pending_.load(); });
  sleeping_.store(false);
  lock.unlock();
  return consume();
}

}  // namespace simgate
