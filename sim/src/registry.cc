#include "simgate/sim/registry.h"

#include <algorithm>
#include <stdexcept>

#include "simgate/core/errors.h"
#include "simgate/core/suggest.h"
#include "helpers.h"

namespace simgate::sim {

namespace {
std::string kind_name(Kind kind) { return kind == Kind::robot ? "robot" : "component"; }
}  // namespace

void ComponentContext::fail(const std::string& where, const std::string& message) const {
  throw ConfigError(spec_.path + (where.empty() ? "" : "." + where) + ": " + message);
}

Robot& ComponentContext::robot() const {
  if (!robot_) fail("type", "component type '" + spec_.type + "' must belong to a robot");
  return *robot_;
}

DifferentialDrive& ComponentContext::drive() const {
  Robot& r = robot();
  DifferentialDrive* d = r.drive();
  if (!d) {
    auto* entry = sim_.find(r.name());
    fail("type", "component type '" + spec_.type +
                     "' needs a robot that can drive (type ground_robot); robot '" + r.name() +
                     "' is of type '" + (entry ? entry->type : "?") + "'");
  }
  return *d;
}

int ComponentContext::body() const {
  int id = sim_.model().body_id(spec_.body);
  if (id < 0)
    fail("body", "expected the name of a body of scene '" + sim_.model().source() + "', found '" +
                     spec_.body + "' (no such body)");
  if (id == 0) fail("body", "expected a body other than the world body");
  return id;
}

int ComponentContext::free_joint() const {
  int b = body();
  int j = sim_.model().free_joint_of(b);
  if (j < 0)
    fail("body", "component type '" + spec_.type + "' needs a body with a free joint; body '" +
                     spec_.body + "' has none (add <freejoint/> to it in the MJCF)");
  return j;
}

int ComponentContext::actuator_option(const std::string& key, const std::string& fallback) const {
  std::string name = options_.get_string(key, fallback);
  int id = sim_.model().actuator_id(name);
  if (id < 0)
    throw ConfigError(options_.path_of(key) + ": expected the name of an actuator of scene '" +
                      sim_.model().source() + "', found '" + name + "' (no such actuator)");
  return id;
}

namespace {
// Every SIMGATE_BUILTIN_TYPE, in load order (a function's static: filled before main, by the
// static objects of libsimgate_sim's files).
std::vector<ComponentType>& builtins() {
  static std::vector<ComponentType> types;
  return types;
}
}  // namespace

detail::BuiltinTypeRegistrar::BuiltinTypeRegistrar(ComponentType type) {
  builtins().push_back(std::move(type));
}

void register_builtin_components(ComponentRegistry& registry) {
  for (const ComponentType& type : builtins()) registry.add(type);
}

void ComponentRegistry::add(std::string name, Kind kind, std::string doc,
                            ComponentFactory factory) {
  add(ComponentType{nullptr, name, kind, std::move(doc), std::move(factory), ""});
}

json ComponentRegistry::options_schema(Kind kind) const {
  json rules = json::array();
  for (const auto& [name, type] : types_) {
    if (type.kind != kind || !type.options_declared) continue;
    json options = {{"type", "object"}};
    if (type.options.empty()) {
      options["maxProperties"] = 0;
    } else {
      options["additionalProperties"] = false;
      json properties = json::object();
      for (const OptionSpec& o : type.options) {
        json schema = o.schema;
        schema["description"] = o.doc;
        properties[o.name] = std::move(schema);
      }
      options["properties"] = std::move(properties);
    }
    // a robot's type may be left out (it is then "robot"): the rule applies when it is given
    json condition = {{"properties", {{"type", {{"const", name}}}}}};
    if (kind == Kind::robot) condition["required"] = json::array({"type"});
    rules.push_back({{"if", std::move(condition)},
                     {"then", {{"properties", {{"options", std::move(options)}}}}}});
  }
  return rules;
}

void ComponentRegistry::add(ComponentType type) {
  std::string name = type.name;
  types_[name] = std::move(type);
}

const ComponentType* ComponentRegistry::find(const std::string& name) const {
  auto it = types_.find(name);
  return it == types_.end() ? nullptr : &it->second;
}

std::vector<std::string> ComponentRegistry::names(Kind kind) const {
  std::vector<std::string> out;
  for (const auto& [name, t] : types_)
    if (t.kind == kind) out.push_back(name);
  return out;
}

const ComponentType& ComponentRegistry::type_of(Kind kind, const ComponentSpec& spec) const {
  const ComponentType* type = find(spec.type);
  if (!type)
    throw ConfigError(spec.path + ".type: expected a " + kind_name(kind) + " type (" +
                      join(names(kind)) + "), found '" + spec.type + "' (unknown type" +
                      suggestion(spec.type, names(kind)) + ")");
  if (type->kind != kind)
    throw ConfigError(spec.path + ".type: expected a " + kind_name(kind) + " type (" +
                      join(names(kind)) + "), found '" + spec.type + "', which is a " +
                      kind_name(type->kind) + " type");
  return *type;
}

std::unique_ptr<SimComponent> ComponentRegistry::create(Kind kind, const ComponentSpec& spec,
                                                        const json& options, Simulation& sim,
                                                        Robot* robot) const {
  const ComponentType* type = &type_of(kind, spec);
  ConfigObject object(options.is_null() ? json::object() : options, spec.path + ".options");
  std::vector<std::string> declared;
  for (const OptionSpec& o : type->options) declared.push_back(o.name);
  // what the type does not declare is refused before it is built, naming what it declares
  if (type->options_declared) object.allow_only(declared);
  ComponentContext context(sim, spec, object, robot);
  auto component = type->factory(context);
  object.finish();
  if (type->options_declared)
    for (const std::string& key : object.asked())
      if (std::find(declared.begin(), declared.end(), key) == declared.end())
        throw std::logic_error("component type '" + spec.type + "' read option '" + key +
                               "', which it does not declare (its SIMGATE_BUILTIN_TYPE)");
  json configuration = {{"type", spec.type}, {"options", object.raw()}};
  if (!spec.body.empty()) configuration["body"] = spec.body;
  int body = spec.body.empty() ? -1 : sim.model().body_id(spec.body);
  component->add_object_services(std::move(configuration), body, robot ? robot->body() : body);
  return component;
}

}  // namespace simgate::sim
