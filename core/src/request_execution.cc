// request_execution.cc — RequestManager running a request under the simulation lock: a sync
// service called and its outcome made (execute: lookup, arguments bound, exceptions turned into
// failures), an async one started in its component's slot (the running one's policy, then the
// manager's) or beside it (concurrent), a running one interrupted (preemption, cancel, timeout)
// and cancels; the debug log of each request's outcome and time. The hand-over of requests:
// request_manager.cc; outcomes to the transport: request_delivery.cc.
#include <cstdio>
#include <span>
#include <string>
#include <utility>

#include "simgate/core/call_context.h"
#include "simgate/core/errors.h"
#include "simgate/core/input_tap.h"
#include "simgate/core/log.h"
#include "simgate/core/request_manager.h"
#include "request_inbox.h"

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
  // lent by find_service, given back when this returns (RAII: also when a service throws)
  struct Lent {
    RequestManager& manager;
    std::uint64_t version = 0;
    std::shared_ptr<Service> service;
    ~Lent() { manager.return_service(std::move(service), version); }
  } lent{*this, 0, nullptr};
  lent.service = find_service(call, lent.version);
  if (!lent.service) {
    out = unknown_service(call);
    return true;
  }
  const Service* service = lent.service.get();
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

}  // namespace simgate
