// request_manager_worlds.cc — a transport's RequestManager routing calls to other worlds
// (issue #43): each world is a simulation under its own lock, served by a WorldManager
// this manager owns; calls of "w<k>/<component>" go there, outcomes come back here.
#include <charconv>
#include <string>

#include "request_inbox.h"
#include "request_worlds.h"
#include "simgate/core/request_manager.h"

namespace simgate {

// The manager of one world for one transport: an ordinary RequestManager (its world's
// gate, queue, running requests, deadlines) whose outcomes, progress and changes of its
// table go to the transport's manager.
class RequestManager::WorldManager final : public RequestManager {
 public:
  WorldManager(RequestManager& transport, unsigned world)
      : RequestManager(transport.name() + " (world w" + std::to_string(world) + ")") {
    parent_ = &transport;
  }

 protected:
  void on_service_completion(RequestId id, Outcome&& outcome) override {
    parent_->from_world(id, std::move(outcome));
  }
  void on_service_progress(RequestId id, json&& value) override {
    parent_->progress_from_world(id, std::move(value));
  }
  void on_services_changed() override { parent_->notify_services_changed(); }

 public:
  // the transport's clients are every world's (get_simulation_state counts them)
  std::size_t client_count() const override { return parent_->client_count(); }
};

std::optional<std::pair<unsigned, std::size_t>> RequestManager::world_address(
    std::string_view component) {
  // w, digits (no leading zero but "0"), '/', and a name
  if (component.size() < 4 || component[0] != 'w' || component[1] < '0' || component[1] > '9')
    return std::nullopt;
  const std::size_t slash = component.find('/', 1);
  if (slash == std::string_view::npos || slash + 1 == component.size() ||
      (component[1] == '0' && slash != 2) || slash > 10)
    return std::nullopt;
  unsigned world = 0;
  const auto [end, ec] = std::from_chars(component.data() + 1, component.data() + slash, world);
  if (ec != std::errc() || end != component.data() + slash) return std::nullopt;
  return std::pair{world, slash + 1};
}

std::shared_ptr<RequestManager> RequestManager::attach_world(
    unsigned world, const std::function<void(const std::shared_ptr<RequestManager>&)>& prepare) {
  if (world == 0) throw std::invalid_argument("world 0 is the transport's own manager");
  if (parent_) throw std::logic_error(name_ + ": a world's manager serves no worlds");
  if (auto attached = worlds_->find(world)) return attached;
  // made and prepared before routing can reach it (a call to it needs its gate)
  std::shared_ptr<RequestManager> manager = std::make_shared<WorldManager>(*this, world);
  manager->set_access(access());
  manager->set_max_wait(max_wait_);
  manager->set_global_policy(global_policy_);
  manager->set_progress_interval(progress_interval_);
  if (prepare) prepare(manager);
  {
    std::lock_guard lock(worlds_->mutex);
    auto& slot = worlds_->managers[world];
    if (slot) return slot;  // another thread attached it first
    slot = manager;
  }
  has_worlds_.store(true, std::memory_order_release);
  notify_services_changed();
  return manager;
}

void RequestManager::detach_world(unsigned world) {
  {
    std::lock_guard lock(worlds_->mutex);
    if (worlds_->managers.erase(world) == 0) return;
  }
  notify_services_changed();
}

std::vector<unsigned> RequestManager::worlds() const {
  std::vector<unsigned> out;
  std::lock_guard lock(worlds_->mutex);
  for (const auto& [world, manager] : worlds_->managers) out.push_back(world);
  return out;
}

RequestManager* RequestManager::route(RequestId id, Call& call) {
  const auto address = world_address(call.component);
  if (!address) return this;
  const auto [world, name_at] = *address;
  if (world == 0) {
    call.component.erase(0, name_at);
    return this;
  }
  std::lock_guard lock(worlds_->mutex);
  auto it = worlds_->managers.find(world);
  if (it == worlds_->managers.end()) return nullptr;  // answered here: no such world
  call.component.erase(0, name_at);
  worlds_->sent[id] = it->second;  // before it runs: its outcome may come back at once
  return it->second.get();
}

bool RequestManager::run_or_submit_across_worlds(std::span<std::pair<RequestId, Call>> calls,
                                                 bool refilled) {
  bool all_ran_here = true;
  std::size_t begin = 0;
  RequestManager* run_target = nullptr;
  const auto flush = [&](std::size_t end) {
    if (end == begin) return;
    const auto part = calls.subspan(begin, end - begin);
    // this manager's part runs as without worlds (its unknown worlds answered here)
    const bool ran = run_target == this ? run_or_submit_here(part, refilled)
                                        : run_target->run_or_submit(part, refilled);
    all_ran_here = ran && all_ran_here;
    begin = end;
  };
  for (std::size_t i = 0; i < calls.size(); ++i) {
    auto& [id, call] = calls[i];
    RequestManager* target = route(id, call);
    if (!target) target = this;  // an unknown world: this manager says so
    if (target != run_target) {
      flush(i);
      run_target = target;
    }
  }
  flush(calls.size());
  return all_ran_here;
}

void RequestManager::from_world(RequestId id, Outcome&& outcome) {
  {
    std::lock_guard lock(worlds_->mutex);
    worlds_->sent.erase(id);
  }
  if (delivery_thread_.load(std::memory_order_acquire) == std::thread::id{}) {
    // a transport without a delivery thread gets its outcomes under this manager's lock,
    // one at a time: a world's come as tasks of this manager's queue (its next process()),
    // in order with the call's progress reports
    auto carried = std::make_shared<Outcome>(std::move(outcome));
    post([this, id, carried] { call_completion(id, std::move(*carried)); });
    return;
  }
  hand_to_transport(id, std::move(outcome));
}

void RequestManager::progress_from_world(RequestId id, json&& value) {
  if (delivery_thread_.load(std::memory_order_acquire) == std::thread::id{}) {
    auto carried = std::make_shared<json>(std::move(value));
    post([this, id, carried] { call_progress(id, std::move(*carried)); });
    return;
  }
  hand_progress_to_transport(id, std::move(value));
}

bool RequestManager::sent_to_world(RequestId id) const {
  if (!has_worlds()) return false;
  std::lock_guard lock(worlds_->mutex);
  return worlds_->sent.contains(id);
}

}  // namespace simgate
