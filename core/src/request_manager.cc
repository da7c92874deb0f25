// RequestManager: the hand-over of requests and outcomes between transport threads and the
// simulation thread (through the Inbox and the Handoff, request_inbox.h), execution of sync
// and async services, cancels and delivery. Its service table (registration, access lists,
// lookup): request_manager_services.cc; deadlines: request_deadlines.cc.
#include "simgate/core/request_manager.h"

#include <atomic>
#include <iterator>
#include <optional>
#include <thread>
#include <utility>
#include <cstdio>
#include <span>
#include <variant>

#include "simgate/core/call_context.h"
#include "simgate/core/errors.h"
#include "simgate/core/input_tap.h"
#include "simgate/core/log.h"
#include "request_inbox.h"
#include "request_worlds.h"

namespace simgate {
namespace detail {

// Once a call has run, what its params hold. nlohmann's destructor first moves an array's
// elements to a heap-allocated stack (to avoid deep recursion): the usual positional
// arguments, an array of scalars, are cleared here instead, one allocation less per
// request. A call object its transport refills (`refilled`) keeps an array of numbers,
// booleans and nulls as it is (it holds no memory, and the next parse overwrites it in
// place); anything else it held is released, so that call objects kept from read to read
// never hold on to a large request.
void release_params(json& params, bool refilled) noexcept {
  if (params.is_array()) {
    auto& elements = params.get_ref<json::array_t&>();
    bool holds_memory = false;
    for (const auto& e : elements) {
      if (e.is_structured() && !refilled) return;  // destroyed with the call, as a whole
      holds_memory = holds_memory || e.is_string() || e.is_structured() || e.is_binary();
    }
    if (!refilled || holds_memory) elements.clear();
  } else if (refilled && !params.is_null()) {
    params = nullptr;  // named arguments, or a scalar the core refused
  }
}

// "12 us", "3.40 ms", "1.53 s": how long a request took, for the debug log.
std::string format_duration(std::chrono::steady_clock::duration d) {
  const double us = std::chrono::duration<double, std::micro>(d).count();
  char text[32];
  if (us < 1000)
    std::snprintf(text, sizeof text, "%.0f us", us);
  else if (us < 1e6)
    std::snprintf(text, sizeof text, "%.2f ms", us / 1e3);
  else
    std::snprintf(text, sizeof text, "%.2f s", us / 1e6);
  return text;
}

}  // namespace detail

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

// ---- the hand-off to the delivery thread

void RequestManager::deliver_on_this_thread(std::function<void()> wake) {
  handoff_->wake = std::move(wake);
  // published after `wake`: a thread that sees the id sees the function
  delivery_thread_.store(std::this_thread::get_id(), std::memory_order_release);
}

void RequestManager::deliver_on_any_thread() {
  delivery_thread_.store(std::thread::id{}, std::memory_order_release);
}

std::size_t RequestManager::deliver_handed_over() {
  if (!handoff_->waiting()) return 0;
  // a local vector (with a kept one's capacity): on_service_completion may, in principle,
  // lead here again
  std::vector<detail::Handoff::Item> items;
  items.swap(handoff_->spare);
  handoff_->take(items);
  for (auto& [id, outcome, progress] : items) {
    if (progress)
      call_progress(id, std::move(*outcome.value));
    else
      call_completion(id, std::move(outcome));
  }
  const std::size_t n = items.size();
  items.clear();
  if (items.capacity() <= 4096) handoff_->spare.swap(items);
  return n;
}

void RequestManager::complete_request(RequestId id, Outcome&& outcome) {
  deliver(id, std::move(outcome));
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

std::optional<Outcome> RequestManager::on_incoming_request(RequestId id, const Call& call) {
  Outcome outcome;
  if (run_request(id, call, outcome)) return outcome;
  if (const auto deadline = detail::deadline_for(call, max_wait_);
      deadline != detail::Clock::time_point{})
    watch_deadline(id, call, deadline);
  return std::nullopt;
}

void RequestManager::execute_and_deliver(RequestId id, Call& call, bool refilled,
                                         std::chrono::steady_clock::time_point deadline) {
  if (deadline != detail::Clock::time_point{} && detail::Clock::now() >= deadline) [[unlikely]] {
    // it waited for the lock past its deadline: its client has given up, nothing runs
    requests_handled_.store(requests_handled_.load(std::memory_order_relaxed) + 1,
                            std::memory_order_relaxed);
    deliver(id, timeout_outcome(call.component + "." + call.service,
                                detail::wait_limit(call, max_wait_),
                                detail::limit_from_call(call, max_wait_),
                                "not run (it waited for the simulation lock)"));
    detail::release_params(call.params, refilled);
    return;
  }
  // one Outcome object for every request: its string and JSON members are reset, not
  // rebuilt, and the transport reads (or moves) it in place
  if (run_request(id, call, outcome_))
    deliver(id, std::move(outcome_));
  else if (deadline != detail::Clock::time_point{}) [[unlikely]]
    watch_deadline(id, call, deadline);  // an async service started
  detail::release_params(call.params, refilled);
}

bool RequestManager::run_request(RequestId id, const Call& call, Outcome& out) {
  // debug logging is looked at once per request (an atomic load): when it is off, nothing
  // else is paid
  if (!log::enabled(log::Level::debug)) [[likely]]
    return execute(id, call, out, {});
  const auto started = std::chrono::steady_clock::now();
  if (!execute(id, call, out, started)) return false;  // async: logged when it ends (deliver)
  log_outcome(call.component, call.service, out, started, "in");
  return true;
}

void RequestManager::log_outcome(std::string_view component, std::string_view service,
                                 const Outcome& outcome,
                                 std::chrono::steady_clock::time_point started,
                                 std::string_view took) const {
  const auto elapsed = std::chrono::steady_clock::now() - started;
  std::string reason;
  if (outcome.status != Status::success && !outcome.message.empty())
    reason = " (" + outcome.message + ")";
  log::debug(name_, ": ", component, " ", service, " -> ", to_string(outcome.status), reason, " ",
             took, " ", detail::format_duration(elapsed));
}

bool RequestManager::execute(RequestId id, const Call& call, Outcome& out,
                             std::chrono::steady_clock::time_point started) {
  // only the lock holder writes it: a plain store, no read-modify-write
  requests_handled_.store(requests_handled_.load(std::memory_order_relaxed) + 1,
                          std::memory_order_relaxed);
  // a recorder writes the request down before it acts (its end: deliver())
  if (InputTap* tap = gate_->input_tap()) [[unlikely]]
    tap->request_started(*this, id, call);
  std::shared_ptr<Service> service = find_service(call);
  if (!service) {
    out = unknown_service(call);
    return true;
  }
  const ServiceDescriptor& d = service->descriptor();

  try {
    // the service may ask who calls (call_context.h): what this transport serves bounds
    // what it may see and act on
    CallContext context(*this, id, call.raw_attachments, call.client);
    BoundArguments args = bind_arguments(d, call.params);
    if (d.is_async) {
      start_async(id, *service, args.span(), call.progress, started);
      return false;
    }
    out.status = Status::success;
    out.failure = Failure::none;
    out.message.clear();
    out.data = nullptr;
    out.attachments.clear();
    out.value = service->invoke(args.span(), Completion());
    if (out.value && out.value->is_null()) out.value.reset();  // as Outcome::success
    out.attachments = context.take_attachments();
    return true;
  } catch (const ServiceError& e) {
    json data = e.data();
    data["component"] = d.component;
    data["service"] = d.name;
    out = Outcome::failed(e.failure(), e.message(), std::move(data));
  } catch (const std::exception& e) {
    log::warning(name_, ": ", d.qualified_name(), " threw: ", e.what());
    out = Outcome::failed(Failure::internal,
                          "Internal error in service " + d.qualified_name() + ": " + e.what(),
                          json{{"component", d.component}, {"service", d.name}});
  } catch (...) {
    out = Outcome::failed(Failure::internal,
                          "Internal error in service " + d.qualified_name() + ": unknown exception",
                          json{{"component", d.component}, {"service", d.name}});
  }
  return true;
}

void RequestManager::start_async(RequestId id, const Service& service,
                                 std::span<const json* const> args, bool wants_progress,
                                 std::chrono::steady_clock::time_point started) {
  const ServiceDescriptor& d = service.descriptor();
  AsyncSlot& slot = *service.slot();
  if (d.concurrent) {
    start_concurrent(id, service, args, wants_progress, started);
    return;
  }

  // one async request per component: the running service's local policy decides, then ours
  if (slot.busy()) {
    const std::string running = slot.running->service;
    Policy policy = slot.running_policy;
    if (policy == Policy::noninterruptible)
      throw ServiceAlreadyRunning(
          "A non-interruptible service (" + running + ") is already running", running);
    if (policy == Policy::unspecified && global_policy_ == GlobalPolicy::reject)
      throw ServiceAlreadyRunning(
          "A service (" + running + ") is already running. I do not know what to do.", running);
    interrupt_running(slot, Failure::preempted,
                      "preempted by a new request for " + d.qualified_name());
  }

  auto state = std::make_shared<detail::CallState>();
  state->id = id;
  state->service = d.qualified_name();
  state->sink = inbox_;
  state->started = started;
  if (wants_progress) state->progress_interval = progress_interval_;
  Completion completion(state);
  slot.running = state;
  slot.running_policy = d.policy;
  slot.running_completion = completion;
  running_[id] = {state, service.slot()};

  try {
    service.invoke(args, completion);  // the start method's return value is informative only
  } catch (...) {
    running_.erase(id);
    if (slot.running == state) {
      slot.running.reset();
      slot.running_completion = Completion();
    }
    if (state->finished.exchange(true)) {
      // it completed and then threw: the completion stands
      log::warning(name_, ": ", d.qualified_name(), " threw after completing; exception ignored");
      return;
    }
    throw;  // reported by execute()
  }
}

void RequestManager::start_concurrent(RequestId id, const Service& service,
                                      std::span<const json* const> args, bool wants_progress,
                                      std::chrono::steady_clock::time_point started) {
  const ServiceDescriptor& d = service.descriptor();
  AsyncSlot& slot = *service.slot();
  auto state = std::make_shared<detail::CallState>();
  state->id = id;
  state->service = d.qualified_name();
  state->sink = inbox_;
  state->concurrent = true;
  state->started = started;
  if (wants_progress) state->progress_interval = progress_interval_;
  // the slot lists its component's concurrent calls (for shutdown); finished ones go now
  std::erase_if(slot.concurrent, [](const auto& s) { return s->finished.load(); });
  slot.concurrent.push_back(state);
  running_[id] = {state, service.slot()};

  try {
    service.invoke(args, Completion(state));
  } catch (...) {
    running_.erase(id);
    std::erase(slot.concurrent, state);
    if (state->finished.exchange(true)) {
      log::warning(name_, ": ", d.qualified_name(), " threw after completing; exception ignored");
      return;
    }
    throw;  // reported by execute()
  }
}

void RequestManager::interrupt_running(AsyncSlot& slot, Failure reason, std::string message) {
  auto state = slot.running;
  state->interrupt_reason = reason;
  state->interrupt_message = std::move(message);
  // its deadline passed: the outcome is the timeout however it ends (Completion::finish)
  if (reason == Failure::timeout) state->timed_out.store(true, std::memory_order_release);
  try {
    if (slot.interrupt) slot.interrupt();
  } catch (const std::exception& e) {
    log::error(name_, ": interrupt() of ", slot.component, " threw: ", e.what());
  }
  // an interrupt() override that forgot Component::interrupt(): end it anyway
  if (!state->finished) Completion{state}(Status::preempted);
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

void RequestManager::run_interrupt_hook(detail::CallState& state) {
  if (!state.on_interrupt) return;
  try {
    std::exchange(state.on_interrupt, nullptr)();
  } catch (const std::exception& e) {
    log::error(name_, ": the interrupt hook of ", state.service, " threw: ", e.what());
  }
}

void RequestManager::execute_cancel(RequestId id, const std::function<void(bool)>& done) {
  bool found = false;
  auto it = running_.find(id);
  if (it != running_.end()) {
    auto& [state, slot] = it->second;
    if (InputTap* tap = gate_->input_tap();
        tap && !state->finished && (state->concurrent || slot->running == state)) [[unlikely]]
      tap->request_interrupted(*this, id, Failure::cancelled);
    if (state->concurrent) {
      // that one call ends, through its completion; the component sees it done()
      Outcome cancelled;
      cancelled.status = Status::preempted;
      cancelled.failure = Failure::cancelled;
      cancelled.message = "cancelled by its client";
      found = Completion{state}.finish(std::move(cancelled));
      if (found) run_interrupt_hook(*state);
    } else if (!state->finished && slot->running == state) {
      interrupt_running(*slot, Failure::cancelled, "cancelled by its client");
      found = true;
    }
  }
  if (done) {
    try {
      done(found);
    } catch (const std::exception& e) {
      log::error(name_, ": cancel callback threw: ", e.what());
    }
  }
}

void RequestManager::deliver_progress(RequestId id, json&& value) {
  // a call still running here, or in a world (a report that raced its call's end has no one
  // to go to)
  if (!running_.contains(id) && !sent_to_world(id)) return;
  hand_progress_to_transport(id, std::move(value));
}

void RequestManager::hand_progress_to_transport(RequestId id, json&& value) {
  const std::thread::id delivery_thread = delivery_thread_.load(std::memory_order_acquire);
  if (delivery_thread != std::thread::id{} && delivery_thread != std::this_thread::get_id()) {
    Outcome carrier;
    carrier.value = std::move(value);
    if (handoff_->push(id, std::move(carrier), /*progress=*/true)) {
      try {
        handoff_->wake();
      } catch (const std::exception& e) {
        log::error(name_, ": waking the transport's thread failed: ", e.what());
      }
    }
    return;
  }
  // on the delivery thread, after what was handed over before it; or without one
  if (delivery_thread != std::thread::id{}) deliver_handed_over();
  call_progress(id, std::move(value));
}

void RequestManager::on_service_progress(RequestId, json&&) {}

void RequestManager::call_progress(RequestId id, json&& value) {
  try {
    on_service_progress(id, std::move(value));
  } catch (const std::exception& e) {
    log::error(name_, ": on_service_progress threw: ", e.what());
  } catch (...) {
    log::error(name_, ": on_service_progress threw");
  }
}

void RequestManager::deliver(RequestId id, Outcome&& outcome) {
  if (InputTap* tap = gate_->input_tap()) [[unlikely]]
    tap->request_ended(*this, id, outcome);
  // sync requests never were there
  if (!running_.empty()) {
    auto it = running_.find(id);
    if (it != running_.end()) {
      const detail::CallState& state = *it->second.first;
      if (state.started != std::chrono::steady_clock::time_point{}) [[unlikely]] {
        // debug logging was on when it started: "component service -> STATUS after 1.53 s"
        const std::string_view qualified = state.service;
        const std::size_t dot = qualified.rfind('.');
        log_outcome(qualified.substr(0, dot), qualified.substr(dot + 1), outcome, state.started,
                    "after");
      }
      running_.erase(it);
    }
  }
  hand_to_transport(id, std::move(outcome));
}

void RequestManager::hand_to_transport(RequestId id, Outcome&& outcome) {
  const std::thread::id delivery_thread = delivery_thread_.load(std::memory_order_acquire);
  if (delivery_thread != std::thread::id{}) {
    if (delivery_thread != std::this_thread::get_id()) {
      // produced elsewhere (the simulation thread): the transport's thread delivers it
      if (handoff_->push(id, std::move(outcome))) {
        try {
          handoff_->wake();
        } catch (const std::exception& e) {
          log::error(name_, ": waking the transport's thread failed: ", e.what());
        }
      }
      return;
    }
    // on the delivery thread (run_or_submit): after those produced before it
    deliver_handed_over();
  }
  call_completion(id, std::move(outcome));
}

void RequestManager::call_completion(RequestId id, Outcome&& outcome) {
  try {
    on_service_completion(id, std::move(outcome));
  } catch (const std::exception& e) {
    log::error(name_, ": on_service_completion threw: ", e.what());
  } catch (...) {
    log::error(name_, ": on_service_completion threw an unknown exception");
  }
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
