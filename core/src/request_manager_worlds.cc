// request_manager_worlds.cc — a transport's RequestManager routing calls to other worlds
// (issue #43): each world is a simulation under its own lock, served by a WorldManager
// this manager owns; calls of "w<k>/<component>" go there, outcomes come back here.
#include <charconv>
#include <string>

#include "request_inbox.h"
#include "request_worlds.h"
#include "simgate/core/request_manager.h"
#include "simgate/core/text.h"

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

// streams() of a transport's manager: world 0's hub under its names, each attached world's
// under "w<k>/". A world's stream is looked for in the hub its manager has now: a world
// detached is no longer reached (its subscriptions were closed when its streams left).
class RequestManager::WorldStreams final : public StreamDirectory {
 public:
  explicit WorldStreams(RequestManager& transport) : transport_(transport) {}

  std::vector<StreamInfo> streams(std::string_view transport) const override {
    std::vector<StreamInfo> out = hub().streams(transport);
    if (!transport_.has_worlds()) return out;
    for (const auto& [world, manager] : world_managers()) {
      if (!manager->stream_hub_) continue;
      for (StreamInfo& info : manager->stream_hub_->streams(transport)) {
        info.component = world_name(world) + "/" + info.component;
        out.push_back(std::move(info));
      }
    }
    return out;
  }

  std::optional<StreamInfo> find(std::string_view component,
                                 std::string_view transport) const override {
    const Target t = target(component);
    if (!t.hub) return std::nullopt;
    auto info = t.hub->find(t.name, transport);
    if (info) info->component = std::string(component);
    return info;
  }

  std::shared_ptr<StreamSubscription> subscribe(std::string_view component,
                                                std::string_view transport,
                                                SubscriberOptions options) override {
    const Target t = target(component);
    if (!t.hub) return nullptr;
    if (t.name.size() != component.size()) options.address = std::string(component);
    return t.hub->subscribe(t.name, transport, std::move(options));
  }

  void unsubscribe(const std::shared_ptr<StreamSubscription>& subscription) override {
    if (!subscription) return;
    // a world gone took its subscriptions with it (closed)
    if (const Target t = target(subscription->component()); t.hub) t.hub->unsubscribe(subscription);
  }

  PublishResult publish(std::string_view component, std::string_view transport,
                        json command) override {
    const Target t = target(component);
    if (!t.hub) return {.error = std::string(component) + ": " + transport_.no_world(t.world)};
    return t.hub->publish(t.name, transport, std::move(command));
  }

  bool note_refused(std::string_view component, std::string_view transport,
                    std::string reason) override {
    const Target t = target(component);
    return t.hub && t.hub->note_refused(t.name, transport, std::move(reason));
  }

  std::optional<json> sample_now(std::string_view component) const override {
    const Target t = target(component);
    if (!t.hub) return std::nullopt;
    if (!t.gate) return t.hub->sample_now(t.name);  // world 0's: the caller holds its lock
    std::lock_guard lock(*t.gate);
    return t.hub->sample_now(t.name);
  }

  double time() const override { return hub().time(); }

 private:
  // Where a stream's address leads: a hub (null: no world of that number), its name there,
  // the world's gate to lock for sample_now (null: world 0's, the caller's own), the world.
  struct Target {
    std::shared_ptr<StreamHub> hub;
    std::string_view name;
    std::shared_ptr<SimulationGate> gate;
    unsigned world = 0;
  };

  StreamHub& hub() const { return *transport_.stream_hub_; }

  std::vector<std::pair<unsigned, std::shared_ptr<RequestManager>>> world_managers() const {
    std::lock_guard lock(transport_.worlds_->mutex);
    return {transport_.worlds_->managers.begin(), transport_.worlds_->managers.end()};
  }

  Target target(std::string_view component) const {
    const auto address = world_address(component);
    if (!address) return {transport_.stream_hub_, component, nullptr};
    const auto [world, name_at] = *address;
    const std::string_view name = component.substr(name_at);
    if (world == 0) return {transport_.stream_hub_, name, nullptr};
    const auto manager = transport_.worlds_->find(world);
    if (!manager) return {nullptr, name, nullptr, world};
    return {manager->stream_hub_, name, manager->gate(), world};
  }

  RequestManager& transport_;
};

std::shared_ptr<StreamDirectory> RequestManager::make_streams() {
  if (!stream_hub_) return nullptr;
  if (parent_) return stream_hub_;
  return std::make_shared<WorldStreams>(*this);
}

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

std::string RequestManager::no_world(unsigned world) const {
  return "no world '" + world_name(world) + "' (the worlds here: " + join(world_names()) + ")";
}

std::vector<std::string> RequestManager::world_names() const {
  std::vector<std::string> out{"w0"};
  for (const unsigned world : worlds()) out.push_back(world_name(world));
  return out;
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
