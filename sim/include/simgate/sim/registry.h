// simgate/sim/registry.h — creating components by type name from the configuration.
//
// A ComponentRegistry maps a type name ("motion_vw", "ground_robot") to a factory. A robot
// type creates a Robot; a component type creates a SimComponent that belongs to a robot.
// New types join by calling add() — a built-in in the file that defines it
// (SIMGATE_BUILTIN_TYPE, gathered by register_builtin_components()), a component library's
// in the library a config names (component_library.h), or in any program that owns a
// registry — without touching the gateway.
//
// A type declares its options (OptionSpec: the key, its JSON Schema with bounds and default,
// one line of doc): the one place they are written. The deployment's JSON Schema
// (config/schema/deployment.schema.json) and the docs' options tables are checked against the
// built-ins' declarations (tests/sim/registry_options_test.cc), an option the config gives
// and the type does not declare is refused naming the declared ones, and a component that
// reads an undeclared option is a programming error (std::logic_error).
//
// A factory receives a ComponentContext: the component's name, its JSON path in the
// config, its options (a ConfigObject: read them with the typed getters; keys nobody reads
// are reported as errors), the simulation and the parent robot. Helpers resolve MuJoCo
// names and throw ConfigError naming the JSON path, what was expected and what was found.
//
// Threads: creation happens before the simulation runs, on the thread that builds it.
#ifndef SIMGATE_SIM_REGISTRY_H_
#define SIMGATE_SIM_REGISTRY_H_

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "simgate/core/config.h"
#include "simgate/sim/sim_component.h"

namespace simgate::sim {

enum class Kind { robot, component };

// Where a component comes from in the config.
struct ComponentSpec {
  std::string name;  // full name: "robot" or "robot.motion"
  std::string type;  // registry type name
  std::string body;  // MuJoCo body it binds to (components default to their robot's)
  std::string path;  // JSON path of its config object, "robots[0].components[1]"
  std::optional<double> frequency = std::nullopt;  // its `frequency` (Hz) when the config gives one
};

class ComponentContext {
 public:
  ComponentContext(Simulation& sim, const ComponentSpec& spec, ConfigObject& options, Robot* robot)
      : sim_(sim), spec_(spec), options_(options), robot_(robot) {}

  Simulation& sim() const { return sim_; }
  const std::string& name() const { return spec_.name; }
  const ComponentSpec& spec() const { return spec_; }
  // The component's "options" object.
  ConfigObject& options() const { return options_; }
  // The parent robot; throws ConfigError for components without one.
  Robot& robot() const;
  // The parent robot's drive; throws ConfigError naming the robot's type otherwise.
  DifferentialDrive& drive() const;

  // The bound body id; throws "<path>.body: no body 'x' in scene '<file>'".
  int body() const;
  // The free joint of the bound body; throws when it has none.
  int free_joint() const;
  // Reads option `key` (default `fallback`) and resolves it as an actuator name.
  int actuator_option(const std::string& key, const std::string& fallback) const;

  [[noreturn]] void fail(const std::string& where, const std::string& message) const;

 private:
  Simulation& sim_;            // the simulation being built
  const ComponentSpec& spec_;  // name, type, body, path
  ConfigObject& options_;      // the component's options
  Robot* robot_;               // parent robot (null for robots)
};

using ComponentFactory = std::function<std::unique_ptr<SimComponent>(ComponentContext&)>;

// One option of a component type, as the config spells it and the schema and docs show it.
struct OptionSpec {
  std::string name;  // "laser_range"
  // its JSON Schema: {"type": "number", "minimum": 0.001, "maximum": 10000, "default": 30}
  json schema;
  std::string doc;  // what it does, one line: "maximum range, m"
};

struct ComponentType {
  // the component library its code is in (null for types linked in): first, so that it is
  // released only after the factory below, whose code it holds, is destroyed
  std::shared_ptr<void> library;
  std::string name;          // "motion_vw"
  Kind kind;                 // robot or component
  std::string doc;           // one line
  ComponentFactory factory;  // creates it
  std::string origin;        // where it comes from: "built in", "component library 'x' (path)"
  // what its "options" object may hold; unchecked unless declared (a library's type may not)
  std::vector<OptionSpec> options = {};
  bool options_declared = false;  // options is the whole list (every built-in)
  std::string doc_page = {};  // the docs/ page that documents it ("docs/components/armature.md")
};

class ComponentRegistry {
 public:
  // Adds or replaces a type.
  void add(std::string name, Kind kind, std::string doc, ComponentFactory factory);
  void add(ComponentType type);
  // Shorthand for a class constructible from (ComponentContext&).
  template <class T>
  void add(std::string name, Kind kind, std::string doc) {
    add(std::move(name), kind, std::move(doc),
        [](ComponentContext& c) -> std::unique_ptr<SimComponent> {
          return std::make_unique<T>(c);
        });
  }

  const ComponentType* find(const std::string& name) const;
  std::vector<std::string> names(Kind kind) const;
  // Every type, by name.
  const std::map<std::string, ComponentType>& types() const { return types_; }
  // The JSON Schema of the options of every type of `kind` that declares them: the `allOf`
  // list of if/then rules of the deployment schema's "robot" or "component" definition.
  json options_schema(Kind kind) const;

  // The type `spec` names, which must be one of `kind`; throws ConfigError ("<path>.type:
  // expected a component type (...), found ...") otherwise.
  const ComponentType& type_of(Kind kind, const ComponentSpec& spec) const;
  // Creates one component: checks the type exists and is of `kind` (type_of), runs the
  // factory, then rejects unread option keys. Throws ConfigError.
  std::unique_ptr<SimComponent> create(Kind kind, const ComponentSpec& spec, const json& options,
                                       Simulation& sim, Robot* robot) const;

 private:
  std::map<std::string, ComponentType> types_;  // by name
};

// A built-in type, declared in the file that defines it:
//   SIMGATE_BUILTIN_TYPE(laser_scanner, builtin_type<LaserScanner>(
//       "laser_scanner", Kind::component,
//       "fan of mj_ray rays: ...", "docs/components/native-sensors.md", {{"laser_range", ...}}));
inline ComponentType builtin_type(std::string name, Kind kind, std::string doc,
                                  std::string doc_page, std::vector<OptionSpec> options,
                                  ComponentFactory factory) {
  return ComponentType{nullptr,    std::move(name),    kind, std::move(doc),     std::move(factory),
                       "built in", std::move(options), true, std::move(doc_page)};
}
// The same for a class constructible from (ComponentContext&).
template <class T>
ComponentType builtin_type(std::string name, Kind kind, std::string doc, std::string doc_page,
                           std::vector<OptionSpec> options) {
  return builtin_type(
      std::move(name), kind, std::move(doc), std::move(doc_page), std::move(options),
      [](ComponentContext& c) -> std::unique_ptr<SimComponent> { return std::make_unique<T>(c); });
}
namespace detail {
// Adds a type to the built-ins (at load time: a static object of the file that defines it).
struct BuiltinTypeRegistrar {
  explicit BuiltinTypeRegistrar(ComponentType type);
};
}  // namespace detail
#define SIMGATE_BUILTIN_TYPE(id, ...)                                                   \
  static const ::simgate::sim::detail::BuiltinTypeRegistrar simgate_builtin_type_##id { \
    __VA_ARGS__                                                                         \
  }

// The built-in types (every SIMGATE_BUILTIN_TYPE of libsimgate_sim): robots ground_robot,
// human, robot, mjcf; components motion_vw, waypoint, teleport, pose, actuators, sensors,
// armature, armature_pose, imu, odometry, laser_scanner, proximity, video_camera,
// depth_camera.
void register_builtin_components(ComponentRegistry& registry);
// A registry holding the built-ins, added as a component library is (component_library.h).
ComponentRegistry builtin_registry();

}  // namespace simgate::sim

#endif  // SIMGATE_SIM_REGISTRY_H_
