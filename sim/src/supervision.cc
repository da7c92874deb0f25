#include "simgate/sim/supervision.h"

#include <algorithm>
#include <optional>

#include "simgate/core/call_context.h"
#include "simgate/core/errors.h"
#include "simgate/core/log.h"
#include "simgate/sim/communication.h"
#include "simgate/sim/sim_component.h"
#include "simgate/sim/world_services.h"

namespace simgate::sim {

namespace {
// The services of `c` the caller may call: its transport's allow and deny lists hide the
// others (call_context.h).
json service_names(const Component& c) {
  json names = json::array();
  for (const auto& s : c.services())
    if (caller_may_call(c.name(), s->descriptor().name)) names.push_back(s->descriptor().name);
  return names;
}

// The caller's transport: the name the configuration gives it, or "" outside a request.
std::string caller_transport() {
  const CallContext* context = CallContext::current();
  return context ? context->manager().transport_name() : std::string();
}

// Whether the caller sees the stream `info`: outside a request everything, else the streams
// its own transport carries.
bool stream_visible(const StreamInfo& info) {
  if (!CallContext::current()) return true;
  const std::string transport = caller_transport();
  return std::find(info.transports.begin(), info.transports.end(), transport) !=
         info.transports.end();
}

// The stream of `component` the caller sees (stream_visible), if any.
std::optional<StreamInfo> visible_stream(const StreamHub& hub, const std::string& component) {
  if (CallContext::current()) return hub.find(component, caller_transport());
  for (const auto& s : hub.statistics())
    if (s.info.component == component) return s.info;
  return std::nullopt;
}
}  // namespace

SupervisionServices::SupervisionServices(Simulation& sim) : Component("simulation"), sim_(sim) {
  add_service("list_robots", &SupervisionServices::list_robots)
      .doc("Names of the robots this transport serves (or serves a component of)");
  add_service("details", &SupervisionServices::details)
      .doc(
          "Robots with the components this transport serves and their services (what pymorse reads "
          "at connect)");
  add_service("list_services", &SupervisionServices::list_services)
      .doc(
          "The services of every component this transport serves, with their parameters and "
          "transports");
  add_service("get_stream_statistics", &SupervisionServices::get_stream_statistics)
      .doc(
          "Each data stream this transport carries: direction, frequency, samples, subscribers, "
          "samples dropped "
          "for slow subscribers, commands applied, replaced and refused");
  add_service("reset_objects", &SupervisionServices::reset_objects)
      .doc("Restore every object's initial pose (simulated time goes on)");
  add_service("activate", &SupervisionServices::activate, {"component_name"})
      .doc("Resume the default action of a component this transport serves");
  add_service("deactivate", &SupervisionServices::deactivate, {"component_name"})
      .doc("Suspend the default action of a component this transport serves");
  add_service("suspend_dynamics", &SupervisionServices::suspend_dynamics)
      .doc("Freeze physics (time goes on)");
  add_service("restore_dynamics", &SupervisionServices::restore_dynamics).doc("Resume physics");
  add_service("get_scene_objects", &SupervisionServices::get_scene_objects)
      .doc("{name: [children, [x, y, z], [qx, qy, qz, qw]]} for every body");
  add_service("quit", &SupervisionServices::quit)
      .doc("Stop the simulation cleanly (replies are sent first)")
      .process_wide();
  add_world_services(*this, sim);
  // every body's pose, for a client that draws the scene (scene_geometry.cc)
  declare_output_stream("body_poses", [this] { return body_poses(sim_); });
}

void add_world_components(Simulation& sim) {
  sim.add_component(std::make_unique<SupervisionServices>(sim), "simulation");
  auto events = std::make_unique<SimulationEvents>();
  sim.set_events(events.get());
  sim.add_component(std::move(events), "events");
  sim.add_component(std::make_unique<TimeServices>(sim), "time");
  sim.add_component(std::make_unique<CommunicationServices>(sim), "communication");
}

void SupervisionServices::on_step(std::function<void()> fn) {
  step_hooks_.push_back(std::move(fn));
}

void SupervisionServices::on_interrupt(const std::string& service, std::function<void()> fn) {
  interrupt_hooks_[service] = std::move(fn);
}

void SupervisionServices::default_action() {
  for (auto& hook : step_hooks_) hook();
}

void SupervisionServices::interrupt() {
  const std::string running = running_service();  // "simulation.<service>"
  const auto hook = interrupt_hooks_.find(running.substr(running.find('.') + 1));
  if (hook != interrupt_hooks_.end()) hook->second();
  Component::interrupt();
}

bool SupervisionServices::visible(const ComponentEntry& e) const {
  // the caller's side of the mapping (call_context.h): a component its transport serves, or
  // one whose data stream it carries
  return caller_serves(e.component->name()) ||
         (e.component->stream() && visible_stream(sim_.streams(), e.component->name()));
}

bool SupervisionServices::robot_visible(const ComponentEntry& robot) const {
  if (visible(robot)) return true;
  // a robot the caller does not serve still holds the components it does (pymorse builds
  // robot.component proxies from `details`)
  const std::string& name = robot.component->name();
  for (const auto& c : sim_.components())
    if (c->robot == name && visible(*c)) return true;
  return false;
}

std::vector<std::string> SupervisionServices::list_robots() const {
  std::vector<std::string> names;
  for (const auto& r : sim_.components())
    if (r->is_robot && robot_visible(*r)) names.push_back(r->component->name());
  return names;
}

json SupervisionServices::details() const {
  json robots = json::array();
  for (const auto& r : sim_.components()) {
    if (!r->is_robot || !robot_visible(*r)) continue;
    const std::string& name = r->component->name();
    json robot{{"name", name}, {"type", r->type}, {"components", json::object()}};
    // robot-level services (note MORSE's spelling: services_interfaces)
    if (visible(*r) && !r->interfaces.empty()) {
      if (json services = service_names(*r->component); !services.empty()) {
        robot["services"] = std::move(services);
        robot["services_interfaces"] = r->interfaces;
      }
    }
    for (const auto& c : sim_.components()) {
      if (c->robot != name || !visible(*c)) continue;
      json component{{"type", c->type}};
      // services only where a transport serves them and the caller may call some
      if (!c->interfaces.empty() && caller_serves(c->component->name())) {
        if (json services = service_names(*c->component); !services.empty()) {
          component["services"] = std::move(services);
          component["service_interfaces"] = c->interfaces;
        }
      }
      // MORSE's [[datastream class, "IN" | "OUT"]], one per transport that carries the stream
      if (json streams = stream_interfaces(c->component->name()); !streams.empty())
        component["stream_interfaces"] = std::move(streams);
      robot["components"][c->component->name()] = std::move(component);
    }
    robots.push_back(std::move(robot));
  }
  return {{"robots", std::move(robots)}, {"environment", sim_.model().source()}};
}

json SupervisionServices::stream_interfaces(const std::string& component) const {
  json out = json::array();
  const std::optional<StreamInfo> info = visible_stream(sim_.streams(), component);
  if (!info) return out;
  for (const auto& t : info->transports) {
    const RequestManager* manager = sim_.request_manager(t);
    out.push_back({manager ? manager->datastream_class(info->direction) : "simgate." + t,
                   to_string(info->direction)});
  }
  return out;
}

json SupervisionServices::get_stream_statistics() const {
  json out = json::array();
  for (const auto& s : sim_.streams().statistics()) {
    if (!stream_visible(s.info)) continue;
    json entry{{"component", s.info.component},
               {"direction", to_string(s.info.direction)},
               {"kind", s.info.kind},
               {"transports", s.info.transports}};
    if (s.info.direction == StreamDirection::out) {
      entry["frequency"] = s.info.frequency;
      entry["samples"] = s.samples;
      entry["subscribers"] = s.subscribers;
      entry["dropped"] = s.dropped;
      if (s.info.pushed) entry["skipped"] = s.skipped;
    } else {
      entry["fields"] = s.info.fields;
      entry["commands"] = s.commands;
      entry["replaced"] = s.replaced;
      entry["refused"] = s.refused;
      if (!s.last_refusal.empty()) entry["last_refusal"] = s.last_refusal;
    }
    out.push_back(std::move(entry));
  }
  return out;
}

json SupervisionServices::list_services() const {
  json out = json::array();
  for (const auto& c : sim_.components()) {
    if (!visible(*c)) continue;
    const std::string& component = c->component->name();
    for (const auto& s : c->component->services()) {
      const std::string& name = s->descriptor().name;
      if (!caller_may_call(component, name)) continue;  // the caller's allow/deny lists
      json d = s->descriptor().to_json();
      // the transports through which it can be called: those serving the component whose
      // lists let it through
      json transports = json::array();
      for (const auto& t : c->interfaces) {
        const RequestManager* manager = sim_.request_manager(t);
        if (!manager || manager->may_call(component, name)) transports.push_back(t);
      }
      d["transports"] = std::move(transports);
      out.push_back(std::move(d));
    }
  }
  // the caller's transport's own services, which no component holds (the socket transport's
  // `simulation get_stream_port`, MORSE's datastream services): callable through it alone
  if (const CallContext* context = CallContext::current()) {
    auto held_by_a_component = [&](const ServiceDescriptor& d) {
      const auto* owner = sim_.find(d.component);
      if (!owner) return false;
      const auto& services = owner->component->services();
      return std::any_of(services.begin(), services.end(),
                         [&](const auto& s) { return s->descriptor().name == d.name; });
    };
    for (const auto& d : context->manager().descriptors()) {
      if (held_by_a_component(d)) continue;
      json entry = d.to_json();
      entry["transports"] = json::array({context->manager().transport_name()});
      out.push_back(std::move(entry));
    }
  }
  return out;
}

std::string SupervisionServices::reset_objects() {
  sim_.reset();
  return "Objects restored to initial position";
}

void SupervisionServices::set_active(const std::string& component_name, bool active) {
  // a component the calling transport does not serve gets the answer a missing one gets:
  // the mapping is a boundary, and its other side does not show through
  ComponentEntry* e = sim_.find(component_name);
  if (!e || !visible(*e))
    throw ServiceError("Component '" + component_name + "' not found. Can't " +
                           (active ? "activate" : "deactivate"),
                       Failure::bad_arguments, {{"parameter", "component_name"}});
  e->active = active;
}

void SupervisionServices::activate(const std::string& component_name) {
  set_active(component_name, true);
}
void SupervisionServices::deactivate(const std::string& component_name) {
  set_active(component_name, false);
}

std::string SupervisionServices::suspend_dynamics() {
  sim_.set_dynamics_suspended(true);
  return "Physics is suspended";
}

std::string SupervisionServices::restore_dynamics() {
  sim_.set_dynamics_suspended(false);
  return "Physics is resumed";
}

json SupervisionServices::body_tree(int body) const {
  const mjModel* m = sim_.m();
  json children = json::object();
  for (int b = body + 1; b < m->nbody; ++b)
    if (m->body_parentid[b] == body) children[sim_.model().body_name(b)] = body_tree(b);
  Eigen::Vector3d p = body_position(sim_, body);
  Eigen::Quaterniond q = body_orientation(sim_, body);
  return json::array({std::move(children), {p.x(), p.y(), p.z()}, {q.x(), q.y(), q.z(), q.w()}});
}

// Every body of the scene, whoever serves the components driving them: bodies are the
// world any client sees (as a camera would), not components, and nothing here acts on them.
json SupervisionServices::get_scene_objects() const {
  json out = json::object();
  const mjModel* m = sim_.m();
  for (int b = 1; b < m->nbody; ++b)
    if (m->body_parentid[b] == 0) out[sim_.model().body_name(b)] = body_tree(b);
  return out;
}

void SupervisionServices::quit() {
  log::info("simulation: quit requested");
  sim_.request_stop();
}

}  // namespace simgate::sim
