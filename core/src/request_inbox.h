// request_inbox.h (private to libsimgate_core) — the hand-over points of a RequestManager:
// the Inbox (requests, cancels, tasks, completions and progress reports from any thread, taken
// by process() under the simulation lock) and the Handoff (outcomes on their way to a
// transport's delivery thread). Used by RequestManager's sources: request_manager.cc,
// request_execution.cc, request_delivery.cc, request_deadlines.cc, request_manager_worlds.cc.
#ifndef SIMGATE_CORE_SRC_REQUEST_INBOX_H_
#define SIMGATE_CORE_SRC_REQUEST_INBOX_H_

#include <atomic>
#include <chrono>
#include <functional>
#include <iterator>
#include <memory>
#include <mutex>
#include <span>
#include <utility>
#include <variant>
#include <vector>

#include "simgate/core/request_manager.h"

namespace simgate::detail {

using Clock = std::chrono::steady_clock;

// The longest a call may wait for its reply: the shorter of its own timeout and the
// manager's max wait, either zero when absent; zero when neither is set.
inline std::chrono::milliseconds wait_limit(const Call& call, std::chrono::milliseconds max_wait) {
  if (call.timeout.count() <= 0)
    return max_wait.count() > 0 ? max_wait : std::chrono::milliseconds{0};
  return max_wait.count() > 0 && max_wait < call.timeout ? max_wait : call.timeout;
}
// Whether that limit is the call's own timeout (else the max wait).
inline bool limit_from_call(const Call& call, std::chrono::milliseconds max_wait) {
  return call.timeout.count() > 0 && (max_wait.count() <= 0 || call.timeout <= max_wait);
}
// When that wait ends, counted from now; the epoch when there is no limit (then the clock is
// not read: a call without a deadline costs two comparisons).
inline Clock::time_point deadline_for(const Call& call, std::chrono::milliseconds max_wait) {
  const auto limit = wait_limit(call, max_wait);
  return limit.count() > 0 ? Clock::now() + limit : Clock::time_point{};
}

class Inbox;

// The inbox whose requests this thread is executing, if any (Executing): what finishes
// there is taken by the process_locked() that follows on this thread.
inline thread_local const Inbox* t_executing = nullptr;

// Marks the calling thread as executing `inbox`'s requests for its lifetime.
class Executing {
 public:
  explicit Executing(const Inbox* inbox) : previous_(std::exchange(t_executing, inbox)) {}
  ~Executing() { t_executing = previous_; }
  Executing(const Executing&) = delete;
  Executing& operator=(const Executing&) = delete;

 private:
  const Inbox* previous_;  // restored at destruction
};

// The hand-over point between transport threads and the simulation thread.
class Inbox : public CompletionSink {
 public:
  // `deadline`: when its wait for a reply ends (deadline_for(), at submission); the epoch
  // when it has none
  struct Request {
    RequestId id;
    Call call;
    Clock::time_point deadline;
  };
  struct Cancel {
    RequestId id;
    std::function<void(bool)> done;
  };
  struct Task {
    std::function<void()> run;
  };
  using Event = std::variant<Request, Cancel, Task>;

  // any thread; signals the gate
  void push(Event event) {
    queue([&] { add(std::move(event)); }, true);
  }
  // requests moved out of `calls`, each with its deadline (`max_wait`: the manager's);
  // `wake`: see push()
  void push_requests(std::span<std::pair<RequestId, Call>> calls,
                     std::chrono::milliseconds max_wait, bool wake) {
    queue(
        [&] {
          for (auto& [id, call] : calls) {
            const Clock::time_point deadline = deadline_for(call, max_wait);
            add(Request{id, std::move(call), deadline});
          }
        },
        wake);
  }
  // A completion, or a progress report, produced by a request this inbox's process_locked()
  // is running on this thread (an async service done in its start method: `simulation step
  // 1` on a paused simulation) is delivered by that process_locked() before it returns:
  // waking the simulation thread would only make it compete for the CPU and the lock.
  void finished(RequestId id, Outcome outcome) override {
    queue([&] { finished_.emplace_back(id, std::move(outcome)); }, t_executing != this);
  }
  void progressed(RequestId id, json value) override {
    queue([&] { progress_.emplace_back(id, std::move(value)); }, t_executing != this);
  }

  // under the simulation lock; `events` and `finished` come empty and keep their capacity
  // for the next push (no allocation per process()). An empty inbox is seen without the
  // mutex: what is pushed after that look is signalled, and the next process() takes it.
  void take(std::vector<Event>& events, std::vector<std::pair<RequestId, Outcome>>& finished,
            std::vector<std::pair<RequestId, json>>& progress) {
    if (empty()) return;
    std::lock_guard lock(mutex_);
    events.swap(events_);
    finished.swap(finished_);
    progress.swap(progress_);
    note_queued();
  }
  // the completions and progress reports only (what `progress` holds came before them)
  void take_finished(std::vector<std::pair<RequestId, Outcome>>& finished,
                     std::vector<std::pair<RequestId, json>>& progress) {
    if (empty()) return;
    std::lock_guard lock(mutex_);
    finished.swap(finished_);
    progress.swap(progress_);
    note_queued();
  }
  bool closed() const { return closed_.load(std::memory_order_acquire); }
  bool empty() const { return !queued_.load(std::memory_order_acquire); }
  // after close(), requests are answered FAILED (shutdown) at the next process()
  void close() {
    std::lock_guard lock(mutex_);
    closed_.store(true, std::memory_order_release);
    for (auto& e : events_) refuse(std::move(e));
    events_.clear();
    note_queued();
  }

  void set_gate(std::shared_ptr<SimulationGate> g) {
    std::lock_guard lock(mutex_);
    gate_ = std::move(g);
  }
  std::shared_ptr<SimulationGate> gate() {
    std::lock_guard lock(mutex_);
    return gate_;
  }

  // what process() is working on (under the simulation lock, not mutex_)
  std::vector<Event> work_events;
  std::vector<std::pair<RequestId, Outcome>> work_finished;
  std::vector<std::pair<RequestId, json>> work_progress;

 private:
  // Runs `add` under the mutex, then signals the gate (outside it) when `wake`.
  template <class Add>
  void queue(Add&& add, bool wake) {
    std::shared_ptr<SimulationGate> gate;
    {
      std::lock_guard lock(mutex_);
      add();
      note_queued();
      gate = gate_;
    }
    if (wake) gate->signal();
  }
  // caller holds mutex_
  void note_queued() {
    queued_.store(!events_.empty() || !finished_.empty() || !progress_.empty(),
                  std::memory_order_release);
  }
  // caller holds mutex_
  void add(Event event) {
    if (closed_.load(std::memory_order_relaxed))
      refuse(std::move(event));
    else
      events_.push_back(std::move(event));
  }
  // caller holds mutex_
  void refuse(Event event) {
    if (auto* r = std::get_if<Request>(&event))
      finished_.emplace_back(r->id,
                             Outcome::failed(Failure::shutdown, "the request manager has stopped"));
    // cancels and tasks after close have nothing left to act on: dropped
  }

  std::mutex mutex_;                                     // guards everything below
  std::vector<Event> events_;                            // requests, cancels, tasks in order
  std::vector<std::pair<RequestId, Outcome>> finished_;  // async completions, any thread
  std::vector<std::pair<RequestId, json>> progress_;     // progress reports, any thread
  // signalled on every push
  std::shared_ptr<SimulationGate> gate_ = std::make_shared<SimulationGate>();
  std::atomic<bool> closed_{false};  // abandon_pending() was called (written under mutex_)
  // events_, finished_ or progress_ holds something (written under mutex_)
  std::atomic<bool> queued_{false};
};

// Outcomes (and progress reports) produced off a transport's delivery thread, on their way
// to it (RequestManager::deliver_on_this_thread).
class Handoff {
 public:
  struct Item {
    RequestId id;
    Outcome outcome;        // a progress report's value is outcome.value
    bool progress = false;  // a progress report, not the final outcome
  };

  // Any thread (under the simulation lock). Returns true when the delivery thread must be
  // woken: the first outcome since it last took them (one wake per burst).
  bool push(RequestId id, Outcome&& outcome, bool progress = false) {
    std::lock_guard lock(mutex_);
    items_.push_back(Item{id, std::move(outcome), progress});
    waiting_.store(true, std::memory_order_release);
    return !std::exchange(wake_due_, true);
  }
  // Something was pushed and not taken yet (read without the mutex: an outcome pushed under
  // the simulation lock is seen by a reader holding it, and otherwise by the woken thread).
  bool waiting() const { return waiting_.load(std::memory_order_acquire); }
  // Moves everything pushed so far to the end of `out`.
  void take(std::vector<Item>& out) {
    std::lock_guard lock(mutex_);
    waiting_.store(false, std::memory_order_release);
    wake_due_ = false;  // outcomes pushed from now on wake the thread again
    if (out.empty())
      out.swap(items_);
    else
      std::move(items_.begin(), items_.end(), std::back_inserter(out)), items_.clear();
  }

  std::function<void()> wake;  // set once, before the delivery thread is named (see deliver())
  std::vector<Item> spare;     // a taken vector kept for its capacity (the delivery thread)

 private:
  std::mutex mutex_;                  // guards items_ and wake_due_
  std::vector<Item> items_;           // in the order produced
  bool wake_due_ = false;             // a wake was sent and its thread has not taken yet
  std::atomic<bool> waiting_{false};  // items_ is not empty
};

}  // namespace simgate::detail

#endif  // SIMGATE_CORE_SRC_REQUEST_INBOX_H_
