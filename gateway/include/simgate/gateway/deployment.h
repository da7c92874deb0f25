// simgate/gateway/deployment.h — the deployment file: what to simulate and how to serve it.
//
// One JSON file per deployment (docs/configuration.md):
//   scene       {mjcf, timestep?, realtime_factor? (number >= 0, or "max"), start_paused? (bool),
//                on_divergence? ("pause", "restore", "reset")}
//   component_libraries  [name or path of a component library (sim/component_library.h)]
//   transports  {name: {plugin?, options?, allow?, deny?}}
//   robots      [{name, type?, body?, options?, components?: [{name, type, body?, options?}]}]
//   services    {"default": [transports], "<component or glob>": [transports]}
//   streams     {"default": rule, "<component or glob>": rule}, a rule being [transports] or
//               {"transports": [transports], "frequency"?: Hz}: which transports carry a
//               component's data stream (none without it); the rule's "frequency", else the
//               component's own "frequency" (Hz), sets its output stream's rate. The
//               pseudo-components (`simulation`: body_poses; `simulation.events`: the
//               simulation's events) stream only when a rule names
//               them exactly: neither "default" nor a glob maps them, so that a file written
//               before they could stream keeps its streams (and the socket's stream ports)
//   log_level   "trace" | "debug" | "info" | "warning" | "error" | "off"
//   requests    {max_wait_ms?: the longest any request waits for its reply, 0 = no limit}
// parse_deployment() checks the structure (types, names, unknown keys, the mapping against
// the declared transports and components); the gateway then checks what needs the scene
// and the plugins (bodies, component types and options, plugin loading). Every error is a
// message that starts with the JSON path, says what was expected and what was found (and
// "did you mean" for a misspelt name); independent parts are all checked, so one
// ConfigError carries every error of the file. The forms that take a ConfigErrors record
// them instead and return what is valid, for the gateway to check the rest with it: every
// error of every section at once (`simgate check`, `run`).
//
// Mapping: a component's transports come from its exact name if listed, else from the most
// specific matching glob (the one with the most literal characters), else from "default".
// A component that nothing maps is unreachable. Without a "services" section every
// component is served by every transport. `communication` that no rule names exactly is
// served by `simulation`'s transports (MORSE serves both wherever it serves supervision).
//
// Access lists: a transport's "allow" and "deny" (arrays of service patterns,
// "simulation.quit", "robot.*": core/service_access.h) narrow the services of the
// components it serves to those its clients may call; a malformed pattern is an error, one
// that matches no service the transport serves a warning (the gateway's: it knows the
// services).
#ifndef SIMGATE_GATEWAY_DEPLOYMENT_H_
#define SIMGATE_GATEWAY_DEPLOYMENT_H_

#include <chrono>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "simgate/core/config.h"
#include "simgate/core/errors.h"
#include "simgate/core/service_access.h"

namespace simgate::gateway {

struct TransportConfig {
  std::string name;      // key in "transports"
  std::string plugin;    // plugin name or path (default: the name)
  json options;          // passed to the plugin's create()
  ServiceAccess access;  // "allow", "deny" and "console": which served services clients may call
  std::string path;      // "transports.socket"
};

struct ComponentConfig {
  std::string name;  // full name: "robot" or "robot.motion"
  std::string type;  // registry type
  std::string body;  // MuJoCo body
  json options;      // type-specific options (object)
  std::string path;  // "robots[0].components[1]"
  // its output stream's samples per simulated second (MORSE's frequency)
  std::optional<double> frequency;
};

struct RobotConfig {
  ComponentConfig robot;                    // the robot itself
  std::vector<ComponentConfig> components;  // its actuators and sensors
};

struct ServiceRule {
  std::string pattern;                  // exact name or glob
  std::vector<std::string> transports;  // transport names
  std::string path;                     // "services.robot.*"
  // "streams" rules only: {"frequency": Hz}, overrides the component's
  std::optional<double> frequency;
};

// The components every simulation has besides the robots' (its supervision services), in
// the order they are created: never robot names; they stream only when a "streams" rule
// names them exactly.
extern const std::vector<std::string> k_pseudo_components;
// The pseudo-components that only stream, with no service (`simulation.events`, the
// simulation's event stream): never robot names either, named exactly by a "streams" rule
// to stream, and never in the services mapping (nothing to serve).
extern const std::vector<std::string> k_stream_only_components;

struct Deployment {
  std::string file;                     // the config file ("" for in-memory documents)
  std::string base_dir;                 // relative paths resolve here
  json document;                        // the document as given (what a recording keeps)
  std::string mjcf;                     // absolute or base_dir-relative, resolved
  std::optional<double> timestep;       // overrides the MJCF's
  double realtime_factor = 1.0;         // 0 = as fast as possible
  bool start_paused = false;            // lockstep: clients drive it with `simulation step`
  std::string on_divergence = "pause";  // sim::DivergencePolicy's word, checked
  // "spawn.allowed_dirs", canonical: fragment files of spawn_entity
  std::vector<std::string> spawn_allowed_dirs;
  std::vector<TransportConfig> transports;                     // sorted by name
  std::vector<std::string> component_libraries;                // names or paths, in file order
  std::vector<RobotConfig> robots;                             // in file order
  bool has_services = false;                                   // a "services" section exists
  std::vector<ServiceRule> rules;                              // exact names and globs
  std::optional<std::vector<std::string>> default_transports;  // "default"
  std::vector<ServiceRule> stream_rules;                       // "streams": exact names and globs
  std::optional<std::vector<std::string>> default_stream_transports;  // "streams"."default"
  std::optional<double> default_stream_frequency;  // "streams"."default"."frequency"
  std::optional<std::string> log_level;            // validated level name
  // "requests": {"max_wait_ms": N}: the longest any request of any transport waits for its
  // reply (RequestManager::set_max_wait); zero = no limit
  std::chrono::milliseconds max_wait{0};
  // "worlds": how many copies of the scene with its robots run, each a simulation of its own
  // (world 0, the one every client knows, and w1, w2, ...: docs/worlds.md), at start
  // ("count"); how many there may be at once with those `simulation create_world` makes
  // ("max": at least the count; default the count or 16, whichever is more); the threads
  // `simulation step_many` steps worlds on, its pool's ("threads"; 0: one per core);
  // the most memory MuJoCo may hold for all worlds together ("max_memory_mb"; 0: no bound);
  // the scene of each world at start that does not run the config's ("scenes": index, from 1
  // to worlds - 1 -> its MJCF file, resolved as `mjcf` is)
  unsigned worlds = 1;
  unsigned max_worlds = k_default_max_worlds;
  unsigned world_threads = 0;
  std::uint64_t max_world_memory_bytes = 0;
  std::map<unsigned, std::string> world_scenes;
  static constexpr unsigned k_max_worlds = 256;
  static constexpr unsigned k_default_max_worlds = 16;
  // likely mistakes that are not errors (printed by check, logged by run)
  std::vector<std::string> warnings;

  // Every component name: robots, their components, then "simulation", "time" and
  // "communication". This is
  // what "component" counts everywhere (banner, check, transports' logs).
  std::vector<std::string> component_names() const;
  // The transports that serve `component` (see the mapping rules above).
  std::vector<std::string> transports_for(const std::string& component) const;
  // The transports that carry `component`'s stream: the "streams" section, matched as
  // "services" is; without one, none.
  std::vector<std::string> streams_for(const std::string& component) const;
  // The frequency of the rule that gives `component` its stream transports (streams_for), if
  // that rule has one: it overrides the component's own "frequency".
  std::optional<double> stream_frequency_for(const std::string& component) const;
  // The "streams" rule whose key is exactly `component`, or null.
  const ServiceRule* stream_rule_named(const std::string& component) const;
};

// Validates and converts a parsed document. `base_dir` resolves relative paths. Throws one
// ConfigError carrying every error of the document's structure.
Deployment parse_deployment(const json& document, const std::string& base_dir,
                            const std::string& file = "");
// The same, recording the errors in `errors` rather than throwing them: the deployment
// holds what is valid (a robot, transport or mapping rule with an error is left out; a
// scene whose file is unusable leaves `mjcf` empty), for Gateway to check the rest.
Deployment parse_deployment(const json& document, const std::string& base_dir,
                            const std::string& file, ConfigErrors& errors);
// One robot section (a config's robots[i]; a robot spawned at run time, simulation
// spawn_entity's `robot`) at `path`, its names checked against `taken` (the components that
// exist) and the pseudo-components'. Throws one ConfigError carrying every error of it.
RobotConfig parse_robot_section(const json& section, const std::string& path,
                                std::set<std::string> taken);
// Reads and parses a file: parse_deployment, or first parse_config_text, whose error (a
// syntax error, a number beyond a double, nesting deeper than k_max_config_depth) is thrown
// as "FILE:LINE:COLUMN: <path>: ...".
Deployment load_deployment(const std::string& file);
// The same, recording the errors of the structure in `errors` (parse_deployment's second
// form); a text that is no document is still thrown.
Deployment load_deployment(const std::string& file, ConfigErrors& errors);
// The document of a deployment file, read and parsed as load_deployment does, not yet
// validated (ConfigError naming the file, located for the text's errors).
json load_config_document(const std::string& file);

}  // namespace simgate::gateway

#endif  // SIMGATE_GATEWAY_DEPLOYMENT_H_
