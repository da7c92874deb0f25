// deployment_parsing.h — what the parts of the deployment file's parser share (private to
// the gateway): the sections deployment_sections.cc reads for parse_deployment
// (deployment.cc), and the glob match of the mapping's rules (deployment_mapping.cc, and
// parse_deployment's check that a rule matches something).
#ifndef SIMGATE_GATEWAY_SRC_DEPLOYMENT_PARSING_H_
#define SIMGATE_GATEWAY_SRC_DEPLOYMENT_PARSING_H_

#include <fnmatch.h>

#include <optional>
#include <set>
#include <string>

#include "simgate/core/config.h"
#include "simgate/gateway/deployment.h"

namespace simgate::gateway {

// Whether a rule's key is a glob ('*', '?', '[...]'), and whether `name` matches it.
inline bool is_glob(const std::string& pattern) {
  return pattern.find_first_of("*?[") != std::string::npos;
}

inline bool glob_matches(const std::string& pattern, const std::string& name) {
  return fnmatch(pattern.c_str(), name.c_str(), 0) == 0;
}

// The sections (deployment_sections.cc). Each throws ConfigError (parse_robot: records its
// errors in `errors`), for parse_deployment to record and go on with the next section.
//
// "scene" (required): its MJCF file (relative to `base_dir`), timestep, realtime_factor,
// start_paused, on_divergence; every wrong key reported at once.
void parse_scene(ConfigObject& root, const std::string& base_dir, Deployment& d);
// "worlds": N, or {"count": N, "max": M, "max_memory_mb": B, "threads": T, "scenes": {...}}
// (docs/configuration.md#worlds).
void parse_worlds(ConfigObject& root, const std::string& base_dir, Deployment& d);
// "spawn": {"allowed_dirs": [...]}: the directories `simulation spawn_entity` may read
// fragment files from, each an existing directory (relative to the config file).
void parse_spawn(ConfigObject& root, const std::string& base_dir, Deployment& d);
// One transport of "transports" (`name`: its key): its plugin, options, "allow" and "deny"
// lists and "console"; every error of it in one ConfigError.
TransportConfig parse_transport(const std::string& name, const json& value,
                                const std::string& path);
// One robot and its components at `path` (names checked for uniqueness against `names`), or
// nullopt when it has errors, which are recorded in `errors`.
std::optional<RobotConfig> parse_robot(const json& value, const std::string& path,
                                       std::set<std::string>& names, ConfigErrors& errors);

}  // namespace simgate::gateway

#endif  // SIMGATE_GATEWAY_SRC_DEPLOYMENT_PARSING_H_
