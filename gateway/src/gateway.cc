#include "simgate/gateway/gateway.h"

#include <algorithm>
#include <filesystem>

#include "simgate/core/errors.h"
#include "simgate/core/log.h"

namespace simgate::gateway {

namespace {
std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& i : items) out += (out.empty() ? "" : ", ") + i;
  return out;
}
}  // namespace

Gateway::Gateway(const Deployment& deployment, const sim::ComponentRegistry& registry, GatewayOptions options)
    : deployment_(deployment), options_(std::move(options)) {
  // the scene
  sim::SimulationOptions sim_options;
  sim_options.timestep = deployment_.timestep;
  sim_options.realtime_factor = options_.realtime_factor.value_or(deployment_.realtime_factor);
  try {
    simulation_ = std::make_unique<sim::Simulation>(sim::Model::load_file(deployment_.mjcf), sim_options);
  } catch (const std::exception& e) {
    throw ConfigError("scene.mjcf: expected a loadable MJCF scene, found an error: " + std::string(e.what()));
  }
  // robots, components, pseudo-components
  build_components(registry);
  simulation_->add_supervision_services();
  // plugins, then (unless checking) the transports with their components
  load_transports();
}

Gateway::~Gateway() {
  try {
    shutdown();
  } catch (const std::exception& e) {
    log::error("gateway: shutdown: ", e.what());
  }
}

void Gateway::build_components(const sim::ComponentRegistry& registry) {
  sim::Simulation& sim = *simulation_;
  for (const auto& r : deployment_.robots) {
    sim::ComponentSpec spec{r.robot.name, r.robot.type, r.robot.body, r.robot.path};
    auto robot = registry.create(sim::Kind::robot, spec, r.robot.options, sim, nullptr);
    auto* robot_ptr = static_cast<sim::Robot*>(robot.get());
    sim.add_component(std::move(robot), r.robot.type, "", true);
    for (const auto& c : r.components) {
      sim::ComponentSpec cspec{c.name, c.type, c.body, c.path};
      auto component = registry.create(sim::Kind::component, cspec, c.options, sim, robot_ptr);
      sim.add_component(std::move(component), c.type, r.robot.name, false);
    }
  }
}

void Gateway::load_transports() {
  // plugins are searched next to the config file too
  std::vector<std::string> dirs = options_.plugin_dirs;
  if (!deployment_.base_dir.empty()) dirs.push_back(deployment_.base_dir);
  for (const auto& t : deployment_.transports) {
    Transport transport;
    transport.name = t.name;
    try {
      transport.plugin = load_transport_plugin(t.plugin, dirs);
    } catch (const std::exception& e) {
      throw ConfigError(t.path + ".plugin: expected a loadable transport plugin, found an error: " + e.what());
    }
    // option keys are checked even when nothing is created
    std::vector<std::string> known = transport.plugin->option_keys();
    if (!t.options.is_object())
      throw ConfigError(t.path + ".options: expected an object, found " + describe_json(t.options));
    for (auto it = t.options.begin(); it != t.options.end(); ++it)
      if (std::find(known.begin(), known.end(), it.key()) == known.end())
        throw ConfigError(t.path + ".options." + it.key() + ": unknown key (known keys: " + join(known) + ")");
    // which components it serves
    std::vector<std::string>& served = served_[t.name];
    for (const auto& name : deployment_.component_names()) {
      auto list = deployment_.transports_for(name);
      if (std::find(list.begin(), list.end(), t.name) != list.end()) served.push_back(name);
    }
    transports_.push_back(std::move(transport));
  }
  if (options_.check_only) return;

  // create every transport (sockets are bound here), then register the components
  for (auto& transport : transports_) {
    const TransportConfig& t = *std::find_if(deployment_.transports.begin(), deployment_.transports.end(),
                                             [&](const TransportConfig& c) { return c.name == transport.name; });
    transport.manager = transport.plugin->create(t.options, t.path + ".options");
    for (const auto& name : served_[t.name]) {
      sim::ComponentEntry* entry = simulation_->find(name);
      transport.manager->register_component(*entry->component);
      entry->interfaces.push_back(t.name);
    }
    simulation_->add_request_manager(transport.manager, t.name);
  }
}

void Gateway::start() {
  for (auto& t : transports_)
    if (t.manager) t.manager->start();
}

std::map<std::string, std::vector<std::string>> Gateway::endpoints() const {
  std::map<std::string, std::vector<std::string>> out;
  for (const auto& t : transports_)
    if (t.manager) out[t.name] = t.manager->endpoints();
  return out;
}

void Gateway::run() {
  if (options_.check_only) return;
  simulation_->run();
}

void Gateway::stop() {
  if (simulation_) simulation_->request_stop();
}

void Gateway::shutdown() {
  if (!simulation_) return;
  // the simulation holds the last references to the managers: it destroys them before
  // the components they refer to
  for (auto& t : transports_) t.manager.reset();
  simulation_->shutdown();
  simulation_.reset();
  transports_.clear();  // the plugin libraries last
}

}  // namespace simgate::gateway
