// request_delivery.cc — RequestManager handing outcomes and progress reports to its transport:
// on the transport's own thread when it named one (deliver_on_this_thread: produced elsewhere,
// they are handed over through the Handoff with one wake per burst, and delivered in order by
// deliver_handed_over), else where they are produced; the recorder told of each request's end,
// the debug log of an async one. Execution: request_execution.cc.
#include <thread>
#include <utility>
#include <vector>

#include "simgate/core/input_tap.h"
#include "simgate/core/log.h"
#include "simgate/core/request_manager.h"
#include "request_inbox.h"

namespace simgate {

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

}  // namespace simgate
