// RequestManager: the hand-over of requests between transport threads and the simulation
// thread (through the Inbox, request_inbox.h: submit, run_or_submit, cancel, post), process()
// under the simulation lock, the clients a transport has, and the shutdown
// (abandon_pending). Running a request (sync and async services, cancels):
// request_execution.cc; its outcome to the transport (the Handoff): request_delivery.cc; its
// service table (registration, access lists, lookup): request_manager_services.cc;
// deadlines: request_deadlines.cc; other worlds: request_manager_worlds.cc.
#include "simgate/core/request_manager.h"

#include <atomic>
#include <map>
#include <optional>
#include <span>
#include <utility>
#include <variant>

#include "simgate/core/log.h"
#include "request_inbox.h"
#include "request_worlds.h"

namespace simgate {

RequestManager::RequestManager(std::string name)
    : name_(std::move(name)),
      inbox_(std::make_shared<detail::Inbox>()),
      handoff_(std::make_unique<detail::Handoff>()),
      gate_(inbox_->gate()),
      worlds_(std::make_unique<Worlds>()) {}

RequestManager::~RequestManager() = default;

void RequestManager::set_gate(std::shared_ptr<SimulationGate> gate) {
  gate_ = gate;
  inbox_->set_gate(std::move(gate));
}

std::string RequestManager::datastream_class(StreamDirection direction) const {
  return "simgate." + transport_name_ +
         (direction == StreamDirection::out ? ".publisher" : ".reader");
}

void RequestManager::set_streams(std::shared_ptr<StreamHub> hub, std::string transport) {
  stream_hub_ = std::move(hub);
  transport_name_ = std::move(transport);
  streams_ = make_streams();
}

// ---- transport side

RequestId RequestManager::new_request_id() {
  static std::atomic<RequestId> next{1};  // process-wide: ids never collide across managers
  return next.fetch_add(1, std::memory_order_relaxed);
}

void RequestManager::submit(RequestId id, Call call) {
  if (has_worlds()) [[unlikely]] {
    RequestManager* target = route(id, call);
    if (target && target != this) return target->submit(id, std::move(call));
  }
  const auto deadline = detail::deadline_for(call, max_wait_);
  inbox_->push(detail::Inbox::Request{id, std::move(call), deadline});
}

void RequestManager::submit_batch(std::vector<std::pair<RequestId, Call>> calls) {
  if (has_worlds()) [[unlikely]] {
    // each call to its world's manager (a batch's calls of one world stay together there)
    std::map<RequestManager*, std::vector<std::pair<RequestId, Call>>> by_target;
    for (auto& [id, call] : calls) {
      RequestManager* target = route(id, call);
      by_target[target ? target : this].emplace_back(id, std::move(call));
    }
    for (auto& [target, mine] : by_target)
      if (target == this)
        inbox_->push_requests(mine, max_wait_, /*wake=*/true);
      else
        target->submit_batch(std::move(mine));
    return;
  }
  inbox_->push_requests(calls, max_wait_, /*wake=*/true);
}

bool RequestManager::run_or_submit(std::vector<std::pair<RequestId, Call>> calls) {
  return run_or_submit(std::span(calls), /*refilled=*/false);
}

bool RequestManager::run_or_submit(std::span<std::pair<RequestId, Call>> calls, bool refilled) {
  if (has_worlds()) [[unlikely]] {
    for (const auto& [id, call] : calls)
      if (world_address(call.component)) return run_or_submit_across_worlds(calls, refilled);
  }
  return run_or_submit_here(calls, refilled);
}

bool RequestManager::run_or_submit_here(std::span<std::pair<RequestId, Call>> calls,
                                        bool refilled) {
  std::unique_lock lock(*gate_, std::try_to_lock);
  if (!lock) {
    // the holder (stepping, or another transport) may be past our queue: queue them and
    // make sure its next process() comes
    inbox_->push_requests(calls, max_wait_, /*wake=*/true);
    return false;
  }
  if (inbox_->closed()) {
    // abandon_pending() ran: the inbox refuses them (shutdown), delivered here
    inbox_->push_requests(calls, max_wait_, /*wake=*/false);
    process_locked();
    return true;
  }
  // whatever this manager had queued runs first, then these, straight from the vector (no
  // signal: waking the simulation thread for work done here would only make it compete
  // for the CPU)
  process_locked();
  {
    const detail::Executing executing(inbox_.get());
    for (auto& [id, call] : calls)
      execute_and_deliver(id, call, refilled, detail::deadline_for(call, max_wait_));
  }
  // completions these produced at once (preemption of a running request, an async service
  // that finished in its start method); the calls stay where they are, for the caller to
  // reuse
  process_locked();
  return true;
}

bool RequestManager::run_or_submit(RequestId id, Call call) {
  std::vector<std::pair<RequestId, Call>> calls;
  calls.emplace_back(id, std::move(call));
  return run_or_submit(std::move(calls));
}

void RequestManager::cancel(RequestId id, std::function<void(bool)> done) {
  if (has_worlds()) [[unlikely]] {
    std::shared_ptr<RequestManager> world;
    {
      std::lock_guard lock(worlds_->mutex);
      if (auto it = worlds_->sent.find(id); it != worlds_->sent.end()) world = it->second;
    }
    if (world) return world->cancel(id, std::move(done));
  }
  inbox_->push(detail::Inbox::Cancel{id, std::move(done)});
}

void RequestManager::post(std::function<void()> task) {
  inbox_->push(detail::Inbox::Task{std::move(task)});
}

void RequestManager::answer_in_order(RequestId id, Outcome outcome) {
  post([this, id, outcome = std::move(outcome)]() mutable {
    complete_request(id, std::move(outcome));
  });
}

// ---- simulation thread

std::size_t RequestManager::process(std::chrono::nanoseconds wait) {
  if (wait.count() > 0 && inbox_->empty()) gate_->wait_for(wait);
  std::lock_guard lock(*gate_);
  return process_locked();
}

std::size_t RequestManager::process_locked() {
  if (!started_) {
    started_ = true;
    start();
  }

  // the inbox's work vectors (their capacity is reused); emptied however this ends, so that
  // nothing handled here can be swapped back into the queue
  auto& events = inbox_->work_events;
  auto& finished = inbox_->work_finished;
  auto& progress = inbox_->work_progress;
  struct Clear {
    detail::Inbox& inbox;
    ~Clear() {
      inbox.work_events.clear();
      inbox.work_finished.clear();
      inbox.work_progress.clear();
    }
  } clear_on_exit{*inbox_};
  inbox_->take(events, finished, progress);
  std::size_t handled = events.size() + finished.size() + progress.size();

  // completions that arrived before these requests go out first, each call's progress
  // reports before its outcome
  for (auto& [id, value] : progress) deliver_progress(id, std::move(value));
  for (auto& [id, outcome] : finished) deliver(id, std::move(outcome));

  // what the requests below finish on this thread is taken after them (Inbox::finished)
  std::optional<detail::Executing> executing(std::in_place, inbox_.get());
  for (auto& event : events) {
    if (auto* r = std::get_if<detail::Inbox::Request>(&event)) {
      execute_and_deliver(r->id, r->call, /*refilled=*/false, r->deadline);
    } else if (auto* c = std::get_if<detail::Inbox::Cancel>(&event)) {
      execute_cancel(c->id, c->done);
    } else if (auto* t = std::get_if<detail::Inbox::Task>(&event)) {
      try {
        t->run();
      } catch (const std::exception& e) {
        log::error(name_, ": posted task threw: ", e.what());
      }
    }
  }

  // requests past their deadline are interrupted here, their timeouts delivered below
  if (!deadlines_.empty()) [[unlikely]]
    expire_deadlines();
  executing.reset();
  // completions produced while executing (immediate completion, preemption, cancel, timeout);
  // requests that arrived meanwhile wait for the next process(), which the gate makes immediate
  events.clear();
  finished.clear();
  progress.clear();
  inbox_->take_finished(finished, progress);
  for (auto& [id, value] : progress) deliver_progress(id, std::move(value));
  for (auto& [id, outcome] : finished) deliver(id, std::move(outcome));
  return handled + finished.size() + progress.size();
}

bool RequestManager::client_connected(std::uint64_t client) const {
  if (parent_) return parent_->client_connected(client);  // a world's: the transport knows
  if (client == 0) return false;
  std::lock_guard lock(connected_mutex_);
  return connected_.contains(client);
}

void RequestManager::client_arrived(std::uint64_t client) {
  if (client == 0) return;
  std::lock_guard lock(connected_mutex_);
  connected_.insert(client);
}

void RequestManager::client_left(std::uint64_t client) {
  std::lock_guard lock(connected_mutex_);
  connected_.erase(client);
}

void RequestManager::abandon_pending(const std::string& reason) {
  std::lock_guard lock(*gate_);
  inbox_->close();
  // running async requests: finish them (the component may still hold the completion;
  // its later completed() is then ignored)
  auto running = std::move(running_);
  running_.clear();
  deadlines_.clear();
  for (auto& [id, entry] : running) {
    auto& [state, slot] = entry;
    if (slot->running == state) {
      slot->running.reset();
      slot->running_completion = Completion();
    }
    Completion{state}.finish(Outcome::failed(Failure::shutdown, reason));
  }
  // deliver everything queued: refused requests and these shutdowns (progress reports
  // still queued are of calls that end now: dropped)
  std::vector<std::pair<RequestId, Outcome>> finished;
  std::vector<std::pair<RequestId, json>> progress;
  inbox_->take_finished(finished, progress);
  for (auto& [id, outcome] : finished) deliver(id, std::move(outcome));
}

}  // namespace simgate
