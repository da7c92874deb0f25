// RequestManager's deadlines: async requests watched until their deadline (Call::timeout, or
// the manager's max wait), kept in a min-heap that process_locked() checks when it is not
// empty; the gate wakes the thread that waits in process() (or the simulation loop) when the
// earliest is due (SimulationGate::wake_at). A request past its deadline ends FAILED with
// Failure::timeout: the component is interrupted as a cancel interrupts it, and the timeout
// stands whatever the component completes afterwards (CallState::timed_out).
#include <algorithm>
#include <string>

#include "simgate/core/input_tap.h"
#include "simgate/core/log.h"
#include "simgate/core/request_manager.h"
#include "request_inbox.h"

namespace simgate {
namespace {

// std::push_heap keeps the greatest first: ordering by "later than" keeps the earliest first
constexpr auto k_later = [](const auto& a, const auto& b) { return a.at > b.at; };

}  // namespace

Outcome RequestManager::timeout_outcome(std::string_view qualified, std::chrono::milliseconds limit,
                                        bool from_call, std::string_view what) {
  std::string message(qualified);
  message += ": no reply within ";
  message += std::to_string(limit.count());
  message += from_call ? " ms (deadline); " : " ms (the server's max wait); ";
  message += what;
  const std::size_t dot = qualified.rfind('.');
  json data{{"timeout_ms", limit.count()}, {"limit", from_call ? "deadline" : "max_wait"}};
  if (dot != std::string_view::npos) {
    data["component"] = std::string(qualified.substr(0, dot));
    data["service"] = std::string(qualified.substr(dot + 1));
  }
  return Outcome::failed(Failure::timeout, std::move(message), std::move(data));
}

void RequestManager::watch_deadline(RequestId id, const Call& call,
                                    std::chrono::steady_clock::time_point deadline) {
  auto it = running_.find(id);
  if (it == running_.end()) return;  // it ended in its start method, already delivered
  deadlines_.push_back(Deadline{deadline, id, it->second.first, detail::wait_limit(call, max_wait_),
                                detail::limit_from_call(call, max_wait_)});
  std::push_heap(deadlines_.begin(), deadlines_.end(), k_later);
  // entries of requests that ended early stay until their time: drop them when they are
  // many more than the requests still running (amortised: at most once per that many)
  if (deadlines_.size() > 64 && deadlines_.size() > 4 * running_.size()) {
    std::erase_if(deadlines_, [](const Deadline& d) {
      auto state = d.state.lock();
      return !state || state->finished.load();
    });
    std::make_heap(deadlines_.begin(), deadlines_.end(), k_later);
  }
  if (!deadlines_.empty() && deadlines_.front().at == deadline) gate_->wake_at(deadline);
}

void RequestManager::expire_deadlines() {
  const auto now = std::chrono::steady_clock::now();
  while (!deadlines_.empty() && deadlines_.front().at <= now) {
    std::pop_heap(deadlines_.begin(), deadlines_.end(), k_later);
    Deadline expired = std::move(deadlines_.back());
    deadlines_.pop_back();
    auto state = expired.state.lock();
    if (!state || state->finished.load()) continue;  // it ended in time
    auto it = running_.find(expired.id);
    if (it == running_.end() || it->second.first != state) continue;
    const std::shared_ptr<AsyncSlot> slot = it->second.second;
    if (InputTap* tap = gate_->input_tap()) [[unlikely]]
      tap->request_interrupted(*this, expired.id, Failure::timeout);
    Outcome timeout =
        timeout_outcome(state->service, expired.limit, expired.from_call, "interrupted");
    log::debug(name_, ": ", timeout.message);
    // from now on, however it ends, its outcome is this timeout (Completion::finish reads the
    // message and the data once it sees timed_out, which is set after them)
    state->timeout_data = std::move(timeout.data);
    if (!state->concurrent && slot->running == state) {
      // the component stops as for a cancel (interrupt() ends it; if it does not, it is ended)
      interrupt_running(*slot, Failure::timeout, std::move(timeout.message));
    } else {
      // a call of a concurrent service: ended through its completion (the component sees it
      // done())
      state->interrupt_reason = Failure::timeout;
      state->interrupt_message = std::move(timeout.message);
      state->timed_out.store(true, std::memory_order_release);
      if (Completion{state}.finish(Outcome{})) run_interrupt_hook(*state);
    }
  }
  if (!deadlines_.empty()) gate_->wake_at(deadlines_.front().at);
}

}  // namespace simgate
