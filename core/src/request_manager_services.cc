// RequestManager's service table: registration (services, components, async slots) and
// unregistration (a component removed at run time, its running requests ended), the
// allow/deny lists (set_access), what clients may see of it (descriptors, services,
// components, may_call), and the lookup of a request's service with the refusal that names
// what there is instead (find_service, unknown_service). The table is guarded by
// table_mutex_; find_service's memory of the last lookup is the simulation lock holder's.
#include <algorithm>
#include <tuple>

#include "simgate/core/log.h"
#include "simgate/core/request_manager.h"
#include "simgate/core/text.h"

#include "request_worlds.h"
#include "simgate/core/suggest.h"
#include "request_worlds.h"

namespace simgate {
namespace {

// "a, b or c"
std::string join_or(const std::vector<std::string>& items) {
  std::string out;
  for (std::size_t i = 0; i < items.size(); ++i)
    out += (i == 0 ? "" : i + 1 == items.size() ? " or " : ", ") + items[i];
  return out;
}

}  // namespace

// ---- registration

ServiceBuilder RequestManager::add_service(std::shared_ptr<Service> service) {
  const auto& d = service->descriptor();
  if (d.is_async && !service->slot()) service->set_slot(slot_for(d.component));
  std::lock_guard lock(table_mutex_);
  auto& slot = services_[d.component][d.name];
  if (slot) log::debug(name_, ": service ", d.qualified_name(), " registered again, replacing it");
  slot = std::move(service);
  table_version_.fetch_add(1, std::memory_order_acq_rel);
  return ServiceBuilder(*slot);
}

void RequestManager::register_component(Component& component) {
  for (const auto& service : component.services()) add_service(service);
  {
    // a component without services is still known (so errors say "no service", not "no component")
    std::lock_guard lock(table_mutex_);
    services_.try_emplace(component.name());
  }
  notify_services_changed();
}

bool RequestManager::unregister_component(const std::string& component, const std::string& reason) {
  // its requests running here end first, each through its completion (delivered by process())
  std::vector<std::shared_ptr<detail::CallState>> ending;
  for (auto it = running_.begin(); it != running_.end();) {
    auto& [state, slot] = it->second;
    if (slot->component != component) {
      ++it;
      continue;
    }
    if (slot->running == state) {
      slot->running.reset();
      slot->running_completion = Completion();
    }
    std::erase(slot->concurrent, state);
    ending.push_back(state);
    it = running_.erase(it);
  }
  for (auto& state : ending)
    Completion{state}.finish(Outcome::failed(Failure::service_error, reason));
  bool served = false;
  {
    std::lock_guard lock(table_mutex_);
    served = services_.erase(component) > 0;
    slots_.erase(component);
    table_version_.fetch_add(1, std::memory_order_acq_rel);
  }
  last_lookup_ = LastLookup{};  // it may hold one of the services
  if (!served) return false;
  notify_services_changed();
  return true;
}

void RequestManager::notify_services_changed() {
  try {
    on_services_changed();
  } catch (const std::exception& e) {
    log::error(name_, ": on_services_changed threw: ", e.what());
  }
}

std::shared_ptr<AsyncSlot> RequestManager::slot_for(const std::string& component) {
  std::lock_guard lock(table_mutex_);
  auto& slot = slots_[component];
  if (!slot) {
    slot = std::make_shared<AsyncSlot>();
    slot->component = component;
    // free functions have no interrupt(): the running request simply ends PREEMPTED
    slot->interrupt = [raw = slot.get()] {
      if (raw->busy()) raw->running_completion(Status::preempted);
    };
  }
  return slot;
}

void RequestManager::set_access(ServiceAccess access) {
  // the worlds' managers keep to the same lists (of their own components' names)
  for (const unsigned world : worlds())
    if (auto manager = worlds_->find(world)) manager->set_access(access);
  std::lock_guard lock(table_mutex_);
  access_ = std::move(access);
  // the previous lookup (find_service) may be a service the new lists deny
  table_version_.fetch_add(1, std::memory_order_acq_rel);
}

ServiceAccess RequestManager::access() const {
  std::lock_guard lock(table_mutex_);
  return access_;
}

std::vector<ServiceDescriptor> RequestManager::descriptors() const {
  std::vector<ServiceDescriptor> out;
  {
    std::lock_guard lock(table_mutex_);
    for (const auto& [component, table] : services_)
      for (const auto& [name, service] : table)
        if (access_.allows(service->descriptor())) out.push_back(service->descriptor());
  }
  // the worlds' services, under their prefix
  for (const unsigned world : worlds())
    if (auto manager = worlds_->find(world))
      for (ServiceDescriptor d : manager->descriptors()) {
        d.component = world_name(world) + "/" + d.component;
        out.push_back(std::move(d));
      }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
    return std::tie(a.component, a.name) < std::tie(b.component, b.name);
  });
  return out;
}

std::map<std::string, std::vector<std::string>> RequestManager::services() const {
  std::map<std::string, std::vector<std::string>> out;
  for (const auto& d : descriptors()) out[d.component].push_back(d.name);
  return out;
}

bool RequestManager::serves_component(const std::string& component) const {
  if (const auto address = world_address(component); address && has_worlds()) {
    const auto [world, name_at] = *address;
    const std::string name = component.substr(name_at);
    if (world == 0) return serves_component(name);
    auto manager = worlds_->find(world);
    return manager && manager->serves_component(name);
  }
  std::lock_guard lock(table_mutex_);
  return services_.count(component) > 0;
}

bool RequestManager::may_call(const std::string& component, const std::string& service) const {
  if (const auto address = world_address(component); address && has_worlds()) {
    const auto [world, name_at] = *address;
    const std::string name = component.substr(name_at);
    if (world == 0) return may_call(name, service);
    auto manager = worlds_->find(world);
    return manager && manager->may_call(name, service);
  }
  std::lock_guard lock(table_mutex_);
  auto c = services_.find(component);
  if (c == services_.end()) return false;
  auto s = c->second.find(service);
  return s != c->second.end() && access_.allows(s->second->descriptor());
}

std::vector<std::string> RequestManager::components() const {
  std::vector<std::string> out;
  {
    std::lock_guard lock(table_mutex_);
    for (const auto& [component, table] : services_) out.push_back(component);
  }
  for (const unsigned world : worlds())
    if (auto manager = worlds_->find(world))
      for (const std::string& component : manager->components())
        out.push_back(world_name(world) + "/" + component);
  std::sort(out.begin(), out.end());
  return out;
}

// ---- lookup

Outcome RequestManager::unknown_service(const Call& call) const {
  std::string why;
  if (const auto address = world_address(call.component); address && address->first != 0) {
    // a world this transport does not serve (route() sends the others there)
    return Outcome::failed(
        Failure::unknown_service,
        "The request " + call.service + " has not been registered in " + name_ + ": " +
            no_world(address->first),
        json{{"component", call.component}, {"service", call.service}, {"worlds", world_names()}});
  }
  {
    std::lock_guard lock(table_mutex_);
    // only what clients may call is named: a service the access lists deny is not one of
    // the component's services, nor a suggestion (the lists must not show through)
    // components below the one named that have this service: `robot get_local_data` is
    // robot.pose's service
    std::vector<std::string> owners;
    const std::string prefix = call.component + ".";
    for (const auto& [component, table] : services_) {
      if (component.size() <= prefix.size() || component.compare(0, prefix.size(), prefix) != 0)
        continue;
      auto s = table.find(call.service);
      if (s != table.end() && access_.allows(s->second->descriptor())) owners.push_back(component);
    }
    std::sort(owners.begin(), owners.end());

    auto it = services_.find(call.component);
    if (it == services_.end()) {
      why = "no component '" + call.component + "'";
      if (owners.empty()) {
        std::vector<std::string> components;
        for (const auto& [component, table] : services_) components.push_back(component);
        std::sort(components.begin(), components.end());
        why += did_you_mean(call.component, components);
      }
    } else if (auto s = it->second.find(call.service);
               s != it->second.end() && access_.refuses_as_no_console(s->second->descriptor())) {
      // a process-wide service of a transport that is no console: said as it is
      why = call.component + "." + call.service +
            " acts on the whole process, and this transport is not a console: only consoles serve "
            "process-wide "
            "services (by default the socket transport on a loopback address; a transport's "
            "\"console\": true in "
            "the configuration, docs/configuration.md)";
    } else {
      std::vector<std::string> names;
      for (const auto& [name, s] : it->second)
        if (access_.allows(s->descriptor())) names.push_back(name);
      std::sort(names.begin(), names.end());
      std::string list;
      for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
      why = "component '" + call.component + "' has no service '" + call.service + "'" +
            (list.empty() ? "" : " (services: " + list + ")");
      if (owners.empty()) why += did_you_mean(call.service, names);
    }
    if (!owners.empty()) why += " (did you mean " + join_or(owners) + "?)";
  }
  return Outcome::failed(
      Failure::unknown_service,
      "The request " + call.service + " has not been registered in " + name_ + ": " + why,
      json{{"component", call.component}, {"service", call.service}});
}

std::shared_ptr<Service> RequestManager::find_service(const Call& call, std::uint64_t& version) {
  // a pipelining client calls the same service over and over: the previous lookup answers
  // while nothing was registered since (two string compares instead of a lock and two
  // hashed lookups), its service lent (moved out, no reference count touched)
  version = table_version_.load(std::memory_order_acquire);
  if (last_lookup_.service && last_lookup_.version == version &&
      same_text(last_lookup_.component, call.component) &&
      same_text(last_lookup_.name, call.service))
    return std::move(last_lookup_.service);
  std::shared_ptr<Service> service;
  {
    std::lock_guard lock(table_mutex_);
    auto c = services_.find(call.component);
    if (c != services_.end()) {
      auto s = c->second.find(call.service);
      // a service the access lists deny is not found: refused as unknown, before anything
      // runs (only found services are remembered above, so this costs nothing per request
      // of a pipelining client)
      if (s != c->second.end()) {
        if (access_.allows(s->second->descriptor()))
          service = s->second;
        else
          log::debug(name_, ": ", call.component, " ", call.service,
                     " refused: this transport's allow/deny lists or console rule do not let "
                     "clients call it");
      }
    }
  }
  if (service) {  // remembered, its service once it is given back
    last_lookup_.component = call.component;
    last_lookup_.name = call.service;
    last_lookup_.service.reset();
    last_lookup_.version = version;
  }
  return service;
}

void RequestManager::return_service(std::shared_ptr<Service>&& service,
                                    std::uint64_t version) noexcept {
  // back into last_lookup_ unless the call changed it: a nested call remembered its own
  // service, or unregistering a component cleared it (version 0; a found service's version
  // is at least 1, its registration's). Else dropped here.
  if (service && !last_lookup_.service && last_lookup_.version == version)
    last_lookup_.service = std::move(service);
}

}  // namespace simgate
