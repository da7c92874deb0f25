#include "simgate/gateway/gateway.h"

#include <algorithm>
#include <filesystem>

#include "listeners.h"
#include "simgate/core/errors.h"
#include "simgate/sim/component_library.h"
#include "simgate/sim/model_robots.h"
#include "simgate/sim/supervision.h"
#include "simgate/core/log.h"
#include "simgate/core/suggest.h"

namespace simgate::gateway {

// Robots spawned at run time (simulation spawn_entity's `robot` section), checked and built as
// the config's robots are, and served as the config's mapping says of their names.
class Gateway::SpawnedRobots : public sim::Simulation::RobotFactory {
 public:
  SpawnedRobots(Gateway& gateway, sim::Simulation& sim, World* world)
      : gateway_(gateway), sim_(sim), world_(world) {}

  void check(const std::string& name, const json& section) const override {
    config_of(name, section);
  }
  void build(const std::string& name, const json& section) override {
    gateway_.add_spawned_robot(sim_, world_, config_of(name, section));
  }

 private:
  [[noreturn]] static void refuse(const std::string& message) {
    throw ServiceError(message, Failure::bad_arguments, {{"parameter", "robot"}});
  }

  // The section as a config's robot: named and bodied after the entity, its names free,
  // its types known.
  RobotConfig config_of(const std::string& name, const json& section) const {
    for (const char* key : {"name", "body"})
      if (section.contains(key))
        refuse(std::string("robot.") + key +
               ": the spawned entity gives its robot its name and its body ('" + name +
               "'); leave it out");
    json document = section;
    document["name"] = name;
    document["body"] = name;
    std::set<std::string> taken;
    for (const auto& entry : sim_.components()) taken.insert(entry->component->name());
    try {
      RobotConfig r = parse_robot_section(document, "robot", std::move(taken));
      ConfigErrors errors;
      errors.check([&] {
        gateway_.registry_.type_of(sim::Kind::robot,
                                   {r.robot.name, r.robot.type, "", r.robot.path});
      });
      for (const auto& c : r.components)
        errors.check([&] {
          gateway_.registry_.type_of(sim::Kind::component, {c.name, c.type, "", c.path});
        });
      errors.throw_if_any();
      return r;
    } catch (const ConfigError& e) {
      refuse(e.what());
    }
  }

  Gateway& gateway_;
  sim::Simulation& sim_;  // the world it spawns into
  World* world_;          // its record; null for world 0
};

std::shared_ptr<sim::Simulation::RobotFactory> Gateway::robot_factory(sim::Simulation& sim,
                                                                      World* world) {
  return std::make_shared<SpawnedRobots>(*this, sim, world);
}

Gateway::Gateway(const Deployment& deployment, const sim::ComponentRegistry& registry,
                 GatewayOptions options, ConfigErrors earlier)
    : deployment_(deployment),
      options_(std::move(options)),
      registry_(registry),
      warnings_(deployment.warnings) {
  // every part is checked even when another failed, the deployment's structure included:
  // all errors are reported at once
  ConfigErrors errors = std::move(earlier);
  // the scene
  sim::SimulationOptions sim_options;
  sim_options.timestep = deployment_.timestep;
  sim_options.realtime_factor = options_.realtime_factor.value_or(deployment_.realtime_factor);
  sim_options.start_paused = deployment_.start_paused;
  sim::parse_divergence_policy(deployment_.on_divergence,
                               sim_options.on_divergence);  // checked by the parser
  sim_options.spawn_allowed_dirs = deployment_.spawn_allowed_dirs;
  // (no file: the structure's error said why)
  if (!deployment_.mjcf.empty()) {
    try {
      simulation_ =
          std::make_unique<sim::Simulation>(sim::Model::load_file(deployment_.mjcf), sim_options);
    } catch (const std::exception& e) {
      errors.add("scene.mjcf: expected a loadable MJCF scene, found an error: " +
                 std::string(e.what()));
    }
  }
  // the component types the config's libraries add
  load_component_libraries(errors);
  // robots, components, pseudo-components (they need the scene)
  if (simulation_) {
    build_components(errors);
    add_world_components(*simulation_);
    add_streams(*simulation_, errors);
    add_recording_services();
    simulation_->set_robot_factory(robot_factory(*simulation_, nullptr));
    if (options_.on_simulation_built) options_.on_simulation_built(*simulation_, supervision());
    sim_options_ = sim_options;
    build_worlds(errors);
  } else {
    check_component_types(errors);
  }
  // plugins and their options
  load_plugins(errors);
  errors.throw_if_any();
  warn_about_mapping();
  if (options_.check_only) return;
  // the transports with their components (sockets are bound here)
  create_transports();
}

Gateway::~Gateway() {
  try {
    shutdown();
  } catch (const std::exception& e) {
    log::error("gateway: shutdown: ", e.what());
  }
}

std::vector<std::string> Gateway::plugin_dirs() const {
  std::vector<std::string> dirs = options_.plugin_dirs;
  if (!deployment_.base_dir.empty()) dirs.push_back(deployment_.base_dir);
  return dirs;
}

void Gateway::load_component_libraries(ConfigErrors& errors) {
  for (std::size_t i = 0; i < deployment_.component_libraries.size(); ++i) {
    const std::string& library = deployment_.component_libraries[i];
    try {
      auto types = sim::load_component_library(registry_, library, plugin_dirs());
      std::string list;
      for (const auto& t : types) list += (list.empty() ? "" : ", ") + t;
      log::info("component library '", library, "': ", list);
    } catch (const std::exception& e) {
      errors.add("component_libraries[" + std::to_string(i) +
                 "]: expected a loadable component library, found an error: " + e.what());
    }
  }
}

void Gateway::add_generic_components(sim::Simulation& sim, RobotConfig& r) {
  const int body = sim.model().body_id(r.robot.body);
  if (body <= 0) return;  // the robot's own creation reports it
  for (const std::string& type : sim::generic_components(sim.m(), body)) {
    const std::string name = r.robot.name + "." + type;
    // a component of that name in the config wins (other options, or another type)
    if (std::any_of(r.components.begin(), r.components.end(),
                    [&](const auto& c) { return c.name == name; }))
      continue;
    r.components.push_back(ComponentConfig{name, type, r.robot.body, json::object(),
                                           r.robot.path + ".generated." + type, std::nullopt});
  }
  if (r.components.empty())
    warnings_.push_back(
        r.robot.path + ": robot '" + r.robot.name + "' of type mjcf has no hinge or slide joint, " +
        "actuator or sensor under body '" + r.robot.body + "': it offers only its object services");
}

void Gateway::build_components(ConfigErrors& errors) {
  for (auto& r : deployment_.robots)
    if (r.robot.type == "mjcf") add_generic_components(*simulation_, r);
  for (const auto& r : deployment_.robots) build_robot(*simulation_, r, errors);
}

std::vector<std::string> Gateway::build_robot(sim::Simulation& sim, const RobotConfig& r,
                                              ConfigErrors& errors) {
  std::vector<std::string> added;
  sim::Robot* robot_ptr = nullptr;
  errors.check([&] {
    sim::ComponentSpec spec{r.robot.name, r.robot.type, r.robot.body, r.robot.path};
    auto robot = registry_.create(sim::Kind::robot, spec, r.robot.options, sim, nullptr);
    robot_ptr = static_cast<sim::Robot*>(robot.get());
    sim.add_component(std::move(robot), r.robot.type, "", true);
    added.push_back(r.robot.name);
  });
  if (!robot_ptr) return added;  // its components need it
  for (const auto& c : r.components)
    errors.check([&] {
      sim::ComponentSpec cspec{c.name, c.type, c.body, c.path, stream_frequency(c)};
      auto component = registry_.create(sim::Kind::component, cspec, c.options, sim, robot_ptr);
      sim.add_component(std::move(component), c.type, r.robot.name, false);
      added.push_back(c.name);
    });
  return added;
}

void Gateway::add_spawned_robot(sim::Simulation& sim, World* world, RobotConfig r) {
  if (r.robot.type == "mjcf") add_generic_components(sim, r);
  ConfigErrors errors;
  const std::vector<std::string> added = build_robot(sim, r, errors);
  if (!errors.errors().empty()) {
    for (auto it = added.rbegin(); it != added.rend(); ++it)
      sim.remove_component(*it, "robot '" + r.robot.name + "' could not be built");
    try {
      errors.throw_if_any();
    } catch (const ConfigError& e) {
      throw ServiceError(e.what(), Failure::bad_arguments, {{"parameter", "robot"}});
    }
  }
  // its streams and transports, as the config's mapping gives them to its names
  std::vector<const ComponentConfig*> configs{&r.robot};
  for (const auto& c : r.components) configs.push_back(&c);
  for (const ComponentConfig* c : configs) {
    sim::ComponentEntry* entry = sim.find(c->name);
    ConfigErrors stream_errors;
    add_stream(sim, *entry->component, c->type, stream_frequency(*c),
               StreamHub::k_default_frequency, stream_errors);
    for (const std::string& e : stream_errors.errors())
      log::warning("spawned robot '", r.robot.name, "': ", e);
    const std::vector<std::string> transports = deployment_.transports_for(c->name);
    for (std::size_t i = 0; i < transports_.size(); ++i) {
      Transport& t = transports_[i];
      if (!t.manager || std::find(transports.begin(), transports.end(), t.name) == transports.end())
        continue;
      serve_on(t, *entry, world ? *world->managers[i] : *t.manager);
      if (!world) served_[t.name].push_back(c->name);
    }
  }
  log::info("simulation: robot '", r.robot.name, "' spawned with ", added.size() - 1,
            " component(s)");
}

void Gateway::check_component_types(ConfigErrors& errors) const {
  for (const auto& r : deployment_.robots) {
    errors.check([&] {
      registry_.type_of(sim::Kind::robot, {r.robot.name, r.robot.type, r.robot.body, r.robot.path});
    });
    for (const auto& c : r.components)
      errors.check(
          [&] { registry_.type_of(sim::Kind::component, {c.name, c.type, c.body, c.path}); });
  }
}

std::optional<double> Gateway::stream_frequency(const ComponentConfig& c) const {
  if (auto rule = deployment_.stream_frequency_for(c.name)) return rule;
  return c.frequency;
}

void Gateway::config_warning(const sim::Simulation& sim, std::string warning) {
  if (&sim == simulation_.get()) warnings_.push_back(std::move(warning));
}

std::vector<std::string> Gateway::carriers(const sim::Simulation& sim, const Component& component,
                                           const std::vector<std::string>& transports) {
  // a stream is a path to what its component's services do: a transport whose lists refuse
  // one of them does not carry it (issue #35, item 8: a teleport stream on a transport
  // denying robot.teleport.*). An input stream does what any of its services do; an output
  // stream shows what get_local_data returns.
  const StreamDeclaration* stream = component.stream();
  std::vector<std::string> out;
  for (const std::string& name : transports) {
    const auto t = std::find_if(deployment_.transports.begin(), deployment_.transports.end(),
                                [&](const TransportConfig& c) { return c.name == name; });
    std::string refused;  // the first service its lists refuse
    if (t != deployment_.transports.end())
      for (const auto& service : component.services()) {
        const ServiceDescriptor& d = service->descriptor();
        if (stream->direction == StreamDirection::out && d.name != "get_local_data") continue;
        if (!t->access.allows(d.component, d.name)) {
          refused = d.qualified_name();
          break;
        }
      }
    if (refused.empty()) {
      out.push_back(name);
      continue;
    }
    config_warning(sim, t->path + ": transport '" + name + "' does not carry the " +
                            (stream->direction == StreamDirection::in ? "input" : "output") +
                            " stream of '" + component.name() + "': its allow/deny lists refuse " +
                            refused +
                            ", and a stream does what its component's services do "
                            "(docs/configuration.md, access lists)");
  }
  return out;
}

void Gateway::add_stream(sim::Simulation& sim, const Component& component, const std::string& type,
                         std::optional<double> frequency, double fallback, ConfigErrors& errors) {
  const StreamDeclaration* stream = component.stream();
  const std::vector<std::string> transports = deployment_.streams_for(component.name());
  const ServiceRule* named = deployment_.stream_rule_named(component.name());
  if (named && named->frequency && (!stream || stream->direction != StreamDirection::out))
    config_warning(sim, named->path + ".frequency: component '" + component.name() + "' (type " +
                            type + ") has no output stream: the frequency is not used");
  else if (named && named->frequency && stream->outlet && stream->pushed_frequency == 0)
    config_warning(
        sim, named->path + ".frequency: component '" + component.name() +
                 "' streams events as they happen, at no frequency: the frequency is not used");
  if (transports.empty()) return;
  if (!stream) {
    // an exact name must mean a stream; a glob may match components without one
    if (named)
      errors.add(
          named->path + ": component '" + component.name() + "' (type " + type +
          ") has no data stream (streaming types: sensors such as pose, imu, odometry, "
          "laser_scanner; "
          "actuators such as motion_vw, waypoint, teleport, armature, actuators; the simulation's "
          "body_poses)");
    return;
  }
  sim.streams().add(component, type, carriers(sim, component, transports),
                    frequency.value_or(fallback));
}

void Gateway::add_streams(sim::Simulation& sim, ConfigErrors& errors) {
  auto add = [&](const Component& component, const std::string& type,
                 std::optional<double> frequency, double fallback) {
    add_stream(sim, component, type, frequency, fallback, errors);
  };
  auto check_component = [&](const ComponentConfig& c) {
    const sim::ComponentEntry* entry = sim.find(c.name);
    if (!entry) return;  // not created: its own error is reported
    const StreamDeclaration* stream = entry->component->stream();
    const auto* sim_component = dynamic_cast<const sim::SimComponent*>(entry->component.get());
    if (c.frequency && (!stream || stream->direction != StreamDirection::out) &&
        !(sim_component && sim_component->uses_frequency()))
      config_warning(sim, c.path + ".frequency: component '" + c.name + "' (type " + c.type +
                              ") has no output stream: the frequency is not used");
    add(*entry->component, c.type, stream_frequency(c), StreamHub::k_default_frequency);
  };
  for (const auto& r : deployment_.robots) {
    check_component(r.robot);
    for (const auto& c : r.components) check_component(c);
  }
  // the pseudo-components, after the robots' (the socket transport numbers its stream ports
  // in this order): `simulation` streams its bodies' poses, `simulation.events` its events
  // (an event stream: no frequency applies)
  for (const auto* names : {&k_pseudo_components, &k_stream_only_components})
    for (const std::string& pseudo : *names)
      if (const sim::ComponentEntry* entry = sim.find(pseudo))
        add(*entry->component, entry->type, deployment_.stream_frequency_for(pseudo),
            sim::SupervisionServices::k_body_poses_frequency);
}

void Gateway::load_plugins(ConfigErrors& errors) {
  // plugins are searched next to the config file too
  const std::vector<std::string> dirs = plugin_dirs();
  std::vector<Listener> listeners;  // the TCP transports with valid options
  for (const auto& t : deployment_.transports) {
    Transport transport;
    transport.name = t.name;
    transport.config = &t;
    try {
      transport.plugin = load_transport_plugin(t.plugin, dirs);
    } catch (const std::exception& e) {
      errors.add(t.path +
                 ".plugin: expected a loadable transport plugin, found an error: " + e.what());
      continue;
    }
    // every check the plugin makes of its options, short of opening anything
    bool options_valid = errors.check([&] {
      if (!t.options.is_object())
        throw ConfigError(t.path + ".options: expected an object, found " +
                          describe_json(t.options));
      // its warnings (a deprecated key, a token file others may read): check says what run does
      for (std::string& warning : transport.plugin->validate(t.options, t.path + ".options"))
        warnings_.push_back(std::move(warning));
    });
    if (options_valid)
      if (auto listener = listener_of(transport.plugin->name(), t))
        listeners.push_back(std::move(*listener));
    // which components it serves
    std::vector<std::string>& served = served_[t.name];
    for (const auto& name : deployment_.component_names()) {
      auto list = deployment_.transports_for(name);
      if (std::find(list.begin(), list.end(), t.name) != list.end()) served.push_back(name);
    }
    transports_.push_back(std::move(transport));
  }
  // what needs every transport (two on one port), or a socket (an address of this machine)
  check_listeners(listeners, errors);
}

void Gateway::warn_about_mapping() {
  auto serves = [&](const std::string& transport, const std::string& component) {
    const auto& list = served_[transport];
    return std::find(list.begin(), list.end(), component) != list.end();
  };
  for (const std::string pseudo : {"simulation", "time"}) {
    bool reachable = std::any_of(transports_.begin(), transports_.end(),
                                 [&](const Transport& t) { return serves(t.name, pseudo); });
    if (!reachable)
      warnings_.push_back("services: no transport serves '" + pseudo + "': clients cannot " +
                          (pseudo == "simulation" ? "list robots or services, reset or quit"
                                                  : "read or wait for simulated time") +
                          " (map it, e.g. \"" + pseudo + "\": [\"" +
                          (transports_.empty() ? std::string("socket") : transports_.front().name) +
                          "\"])");
  }
  // pymorse connects by calling `simulation details` on the socket transport
  for (const auto& t : transports_) {
    if (!t.plugin || t.plugin->name() != "socket") continue;
    if (!serves(t.name, "simulation"))
      warnings_.push_back(
          t.config->path + ": the socket transport '" + t.name +
          "' does not serve 'simulation': pymorse cannot connect to it (it calls `simulation "
          "details` first); map it, e.g. \"simulation\": [\"" +
          t.name + "\"]");
    else if (!t.config->access.allows("simulation", "details"))
      warnings_.push_back(
          t.config->path + ": the socket transport '" + t.name +
          "' does not let clients call 'simulation.details': pymorse cannot connect to it (it "
          "calls `simulation details` first); let it through its allow and deny lists");
  }
  warn_about_access_lists();
}

void Gateway::warn_about_access_lists() {
  for (const auto& t : transports_) {
    const ServiceAccess& access = t.config->access;
    if (access.allows_everything()) continue;
    // the services this transport serves, as "component.service", and its components
    std::vector<std::pair<std::string, std::string>> services;
    std::vector<std::string> qualified;
    for (const auto& name : served_[t.name])
      if (const sim::ComponentEntry* entry = simulation_->find(name))
        for (const auto& service : entry->component->services()) {
          services.emplace_back(name, service->descriptor().name);
          qualified.push_back(name + "." + service->descriptor().name);
        }
    const std::vector<std::string>& components = served_[t.name];
    // a pattern that matches nothing is most likely a typo: in a deny list it leaves the
    // service it meant callable
    auto check = [&](const std::vector<std::string>& patterns, const std::string& list,
                     const char* effect) {
      for (std::size_t i = 0; i < patterns.size(); ++i) {
        const std::string& p = patterns[i];
        bool matched = std::any_of(services.begin(), services.end(), [&](const auto& s) {
          return ServiceAccess::matches(p, s.first, s.second);
        });
        if (matched) continue;
        // "robot.motion" names a component, not its services
        std::string hint =
            std::find(components.begin(), components.end(), p) != components.end()
                ? " (a pattern names services: '" + p + ".*' for every service of '" + p + "')"
                : did_you_mean(p, qualified);
        warnings_.push_back(t.config->path + "." + list + "[" + std::to_string(i) + "]: '" + p +
                            "' matches no service transport '" + t.name + "' serves: it " + effect +
                            " nothing" + hint);
      }
    };
    if (access.allow()) check(*access.allow(), "allow", "allows");
    check(access.deny(), "deny", "denies");
  }
}

void Gateway::create_transports() {
  // create every transport (sockets are bound here), then register the components
  for (auto& transport : transports_) {
    const TransportConfig& t = *transport.config;
    transport.manager = transport.plugin->create_validated(t.options, t.path + ".options");
    // the allow and deny lists first: no service is ever callable that they deny
    transport.manager->set_access(t.access);
    transport.manager->set_max_wait(deployment_.max_wait);  // requests.max_wait_ms
    for (const auto& name : served_[t.name])
      serve_on(transport, *simulation_->find(name), *transport.manager);
    simulation_->add_request_manager(transport.manager, t.name);
  }
  // the other worlds, through the same transports under their prefix
  for (auto& [index, world] : worlds_) serve_world(*world);
}

void Gateway::serve_on(Transport& transport, sim::ComponentEntry& entry, RequestManager& manager) {
  manager.register_component(*entry.component);
  entry.interfaces.push_back(transport.name);
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
  start_world_loops();
  try {
    simulation_->run();
  } catch (...) {
    stop_worlds();
    throw;
  }
  stop_worlds();
}

void Gateway::add_recording_services() {
  recorder::RecordingSetup setup;
  setup.dir = options_.record_dir;
  setup.deployment = {{"document", deployment_.document},
                      {"base_dir", deployment_.base_dir},
                      {"file", deployment_.file}};
  if (!deployment_.mjcf.empty())
    setup.attachments.push_back(std::filesystem::absolute(deployment_.mjcf).string());
  recording_ = std::make_shared<recorder::RecordingServices>(*simulation_, std::move(setup));
  recording_->add_to(supervision());
}

sim::SupervisionServices& Gateway::supervision() {
  return dynamic_cast<sim::SupervisionServices&>(*simulation_->find("simulation")->component);
}

void Gateway::start_recording(const std::string& path) {
  std::lock_guard lock(*simulation_->gate());
  recording_->start(path);
}

void Gateway::shutdown() {
  if (!simulation_) return;
  // the recording takes the run to its end, then closes its file
  if (recording_) recording_->stop();
  recording_.reset();
  // the other worlds first: no call is routed to them any more, then each answers what it
  // has left (through the transports, still there) and destroys its components
  stop_worlds();
  for (auto& [index, world] : worlds_) leave(*world);
  worlds_.clear();
  // the simulation holds the last references to the managers: it destroys them before
  // the components they refer to
  for (auto& t : transports_) t.manager.reset();
  simulation_->shutdown();
  simulation_.reset();
  transports_.clear();  // the plugin libraries last
}

}  // namespace simgate::gateway
