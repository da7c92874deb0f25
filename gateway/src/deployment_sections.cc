// deployment_sections.cc — the sections of a deployment file, each checked with its JSON
// path: "scene" (its MJCF file, timestep, realtime factor, divergence policy), "worlds" (the
// count, the limits, each world's scene), "spawn" (the directories fragments come from), one
// transport (its plugin, options, allow and deny lists, console) and one robot with its
// components (names, types, bodies, options, frequencies), also a robot spawned at run time
// (parse_robot_section). The file as a whole and the mapping's rules: deployment.cc.
#include <algorithm>
#include <filesystem>
#include <optional>
#include <set>

#include "deployment_parsing.h"
#include "simgate/core/streams.h"
#include "simgate/gateway/deployment.h"
#include "simgate/sim/run_policy.h"

namespace simgate::gateway {

namespace fs = std::filesystem;

namespace {

// Robot and component names: letters, digits, '_' and '-' (the '.' joins robot and component).
void check_name(const std::string& name, const std::string& path) {
  bool ok = !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-';
  });
  if (!ok)
    throw ConfigError(path + ": expected a name made of letters, digits, '_' and '-', found " +
                      describe_json(name));
}

// 'simulation.quit' as the user wrote it, or, when it is long or not printable ASCII, its
// bounded JSON preview (an error message must not carry a whole 10 MB value nor control
// characters).
std::string quoted_pattern(const std::string& pattern) {
  bool plain = pattern.size() <= 60 && std::all_of(pattern.begin(), pattern.end(), [](char c) {
                 return c >= 0x20 && c < 0x7f && c != '\'';
               });
  return plain ? "'" + pattern + "'" : json_preview(json(pattern));
}

// A transport's "allow" or "deny": an array of service patterns (service_access.h), each
// checked; every malformed one is reported.
std::vector<std::string> pattern_list(const json& value, const std::string& path) {
  const std::string expected =
      "expected a service pattern \"component.service\" ('*': any characters), found ";
  if (!value.is_array())
    throw ConfigError(
        path +
        ": expected an array of service patterns (\"simulation.quit\", \"robot.*\"), found " +
        describe_json(value));
  ConfigErrors errors;
  std::vector<std::string> out;
  for (std::size_t i = 0; i < value.size(); ++i) {
    const std::string at = path + "[" + std::to_string(i) + "]";
    if (!value[i].is_string()) {
      errors.add(at + ": " + expected + describe_json(value[i]));
      continue;
    }
    std::string pattern = value[i].get<std::string>();
    if (std::string why = ServiceAccess::pattern_error(pattern); !why.empty())
      errors.add(at + ": " + expected + quoted_pattern(pattern) + ", which " + why);
    out.push_back(std::move(pattern));
  }
  errors.throw_if_any();
  return out;
}

ComponentConfig parse_component(ConfigObject& o, const std::string& full_prefix,
                                const std::string& default_body, const std::string& default_type) {
  ComponentConfig c;
  c.path = o.path();
  std::string name = o.required_string("name");
  check_name(name, o.path_of("name"));
  c.name = full_prefix + name;
  c.type = default_type.empty() ? o.required_string("type") : o.get_string("type", default_type);
  c.body = o.get_string("body", default_body.empty() ? name : default_body);
  auto options = o.get_object("options");
  c.options = options ? options->raw() : json::object();
  // a component's stream rate (robots have no stream: the key is theirs to refuse)
  if (!full_prefix.empty() && o.has("frequency"))
    c.frequency = o.get_number("frequency", StreamHub::k_default_frequency, 1e-3, 1e6);
  return c;
}

// A scene file the config names at `path` (scene.mjcf, worlds.scenes.<k>): `name`, relative to
// `base_dir` unless absolute, an existing file; its path, normalised.
std::string mjcf_file(const std::string& name, const std::string& base_dir,
                      const std::string& path) {
  const fs::path file = fs::path(name).is_absolute() ? fs::path(name) : fs::path(base_dir) / name;
  std::error_code ec;
  if (!fs::is_regular_file(file, ec))
    throw ConfigError(path + ": expected an MJCF file, found '" + file.string() +
                      "' (no such file)");
  return file.lexically_normal().string();
}

// "worlds"."scenes": {"<k>": "file.xml"}: world k's scene instead of the config's, k from 1 to
// the count - 1, the file found as scene.mjcf is. Every wrong entry is reported.
void parse_world_scenes(ConfigObject& worlds, const std::string& base_dir, Deployment& d) {
  auto scenes = worlds.get_object("scenes");
  if (!scenes) return;
  const std::string indices = d.worlds > 1
                                  ? "1 to " + std::to_string(d.worlds - 1) +
                                        ", as \"count\": " + std::to_string(d.worlds) + " gives"
                                  : "none: \"count\" is 1";
  ConfigErrors errors;
  for (auto it = scenes->raw().begin(); it != scenes->raw().end(); ++it) {
    errors.check([&] {
      const std::string& key = it.key();
      const std::string at = scenes->path_of(key);
      // the key: a world's index in decimal, as "w<k>" names it
      const bool digits =
          !key.empty() && key.size() <= 3 && (key == "0" || key[0] != '0') &&
          std::all_of(key.begin(), key.end(), [](char c) { return c >= '0' && c <= '9'; });
      const unsigned index = digits ? static_cast<unsigned>(std::stoul(key)) : 0;
      if (index == 0 || index >= d.worlds)
        throw ConfigError(
            at + ": expected the index of a world after world 0 as the key (" + indices +
            "), found " + describe_json(json(key)) +
            (digits && index == 0 ? " (world 0 runs the config's scene, scene.mjcf)" : ""));
      if (!it.value().is_string())
        throw ConfigError(at + ": expected an MJCF file, found " + describe_json(it.value()));
      d.world_scenes[index] = mjcf_file(it.value().get<std::string>(), base_dir, at);
    });
  }
  errors.throw_if_any();
}

// Whether a transport is a console by default (service_access.h): the MORSE socket
// transport bound to a loopback address (its default, 127.0.0.1), the operator's telnet.
bool console_by_default(const TransportConfig& tc) {
  if (tc.plugin != "socket") return false;
  const auto host = tc.options.find("host");
  if (host == tc.options.end()) return true;
  if (!host->is_string()) return false;  // the plugin refuses it
  const std::string h = host->get<std::string>();
  return h == "localhost" || h == "::1" || h.rfind("127.", 0) == 0;
}

}  // namespace

void parse_scene(ConfigObject& root, const std::string& base_dir, Deployment& d) {
  auto scene_object = root.get_object("scene");
  if (!scene_object) root.fail("scene", "an object {\"mjcf\": \"path/to/scene.xml\", ...}");
  ConfigObject& scene = *scene_object;
  ConfigErrors errors;
  errors.check(
      [&] { d.mjcf = mjcf_file(scene.required_string("mjcf"), base_dir, scene.path_of("mjcf")); });
  errors.check([&] {
    if (scene.has("timestep")) d.timestep = scene.get_number("timestep", 0.002, 1e-6, 1.0);
  });
  errors.check([&] {
    auto factor = scene.get_json("realtime_factor");
    if (!factor) return;
    if (factor->is_string() && factor->get<std::string>() == "max") {
      d.realtime_factor = 0;
    } else if (factor->is_number() && factor->get<double>() <= 1e6 &&
               (factor->get<double>() == 0 ||
                factor->get<double>() >= sim::k_min_realtime_factor)) {
      d.realtime_factor = factor->get<double>();
    } else {
      throw ConfigError(
          scene.path_of("realtime_factor") +
          ": expected 0 (as fast as possible), \"max\" or a number from 1e-06 to 1e+06, found " +
          describe_json(*factor));
    }
  });
  errors.check([&] { d.start_paused = scene.get_bool("start_paused", false); });
  errors.check([&] {
    d.on_divergence = scene.get_string("on_divergence", d.on_divergence);
    sim::DivergencePolicy policy;
    if (!sim::parse_divergence_policy(d.on_divergence, policy))
      throw ConfigError(
          scene.path_of("on_divergence") +
          ": expected \"pause\" (undo the step and pause), "
          "\"restore\" (the last checkpoint) or \"reset\" (the initial state), found " +
          describe_json(json(d.on_divergence)));
  });
  errors.check([&] { scene.finish(); });
  errors.throw_if_any();
}

// "worlds": N, or {"count": N, "max": M, "max_memory_mb": B, "threads": T, "scenes": {...}}
// (docs/configuration.md#worlds).
void parse_worlds(ConfigObject& root, const std::string& base_dir, Deployment& d) {
  if (!root.has("worlds")) return;
  constexpr auto k_max = static_cast<long long>(Deployment::k_max_worlds);
  const json& value = root.raw().at("worlds");
  if (!value.is_object()) {
    d.worlds = static_cast<unsigned>(root.get_int("worlds", 1, 1, k_max));
    d.max_worlds = std::max(d.worlds, Deployment::k_default_max_worlds);
    return;
  }
  auto worlds = *root.get_object("worlds");
  d.worlds = static_cast<unsigned>(worlds.get_int("count", 1, 1, k_max));
  d.max_worlds = static_cast<unsigned>(
      worlds.get_int("max", std::max(d.worlds, Deployment::k_default_max_worlds), d.worlds, k_max));
  d.world_threads = static_cast<unsigned>(worlds.get_int("threads", 0, 0, 256));
  d.max_world_memory_bytes =
      static_cast<std::uint64_t>(worlds.get_int("max_memory_mb", 0, 0, 1'000'000)) * 1'000'000;
  ConfigErrors errors;
  errors.check([&] { parse_world_scenes(worlds, base_dir, d); });
  errors.check([&] { worlds.finish(); });
  errors.throw_if_any();
}

// "spawn": {"allowed_dirs": [...]}: the directories `simulation spawn_entity` may read
// fragment files from, each an existing directory (relative to the config file).
void parse_spawn(ConfigObject& root, const std::string& base_dir, Deployment& d) {
  auto spawn_object = root.get_object("spawn");
  if (!spawn_object) return;
  ConfigObject& spawn = *spawn_object;
  ConfigErrors errors;
  errors.check([&] {
    auto dirs = spawn.get_json("allowed_dirs");
    if (!dirs) return;
    const std::string path = spawn.path_of("allowed_dirs");
    if (!dirs->is_array())
      throw ConfigError(path + ": expected an array of directories, found " + describe_json(*dirs));
    for (std::size_t i = 0; i < dirs->size(); ++i) {
      const json& dir = (*dirs)[i];
      const std::string at = path + "[" + std::to_string(i) + "]";
      if (!dir.is_string() || dir.get<std::string>().empty())
        throw ConfigError(at + ": expected a directory, found " + describe_json(dir));
      fs::path resolved = fs::path(dir.get<std::string>()).is_absolute()
                              ? fs::path(dir.get<std::string>())
                              : fs::path(base_dir) / dir.get<std::string>();
      std::error_code ec;
      if (!fs::is_directory(resolved, ec))
        throw ConfigError(at + ": expected a directory, found '" + resolved.string() +
                          "' (no such directory)");
      d.spawn_allowed_dirs.push_back(fs::canonical(resolved).string());
    }
  });
  errors.check([&] { spawn.finish(); });
  errors.throw_if_any();
}

TransportConfig parse_transport(const std::string& name, const json& value,
                                const std::string& path) {
  check_name(name, path);
  ConfigObject t(value, path);
  TransportConfig tc;
  tc.name = name;
  tc.path = path;
  tc.plugin = t.get_string("plugin", name);
  auto options = t.get_object("options");
  tc.options = options ? options->raw() : json::object();
  // both lists are checked, and every key, before the first error is thrown
  ConfigErrors errors;
  std::optional<std::vector<std::string>> allow;
  std::vector<std::string> deny;
  errors.check([&] {
    if (auto value = t.get_json("allow")) allow = pattern_list(*value, t.path_of("allow"));
  });
  errors.check([&] {
    if (auto value = t.get_json("deny")) deny = pattern_list(*value, t.path_of("deny"));
  });
  bool console = false;
  errors.check([&] { console = t.get_bool("console", console_by_default(tc)); });
  errors.check([&] { t.finish(); });
  errors.throw_if_any();
  tc.access = ServiceAccess(std::move(allow), std::move(deny), console);
  return tc;
}

// One robot and its components at `path` (names checked for uniqueness against `names`), or
// nullopt when it has errors, which are recorded in `errors`.
std::optional<RobotConfig> parse_robot(const json& value, const std::string& path,
                                       std::set<std::string>& names, ConfigErrors& errors) {
  const std::size_t errors_before = errors.errors().size();
  std::optional<ConfigObject> r;
  RobotConfig rc;
  bool named = errors.check([&] {
    r.emplace(value, path);
    rc.robot = parse_component(*r, "", "", "robot");
    if (!names.insert(rc.robot.name).second)
      throw ConfigError(
          r->path_of("name") + ": expected a unique name, found '" + rc.robot.name +
          "' a second time" +
          (std::count(k_pseudo_components.begin(), k_pseudo_components.end(), rc.robot.name)
               ? " (reserved)"
               : ""));
  });
  if (!named) return std::nullopt;
  errors.check([&] {
    auto components = r->get_json("components");
    if (!components) return;
    if (!components->is_array()) r->fail("components", "an array of components");
    for (std::size_t j = 0; j < components->size(); ++j)
      errors.check([&] {
        ConfigObject c((*components)[j], path + ".components[" + std::to_string(j) + "]");
        ComponentConfig cc = parse_component(c, rc.robot.name + ".", rc.robot.body, "");
        c.finish();
        if (!names.insert(cc.name).second)
          throw ConfigError(c.path_of("name") + ": expected a unique name, found '" + cc.name +
                            "' a second time");
        rc.components.push_back(std::move(cc));
      });
  });
  errors.check([&] { r->finish(); });
  if (errors.errors().size() != errors_before) return std::nullopt;
  return rc;
}

RobotConfig parse_robot_section(const json& section, const std::string& path,
                                std::set<std::string> taken) {
  taken.insert(k_pseudo_components.begin(), k_pseudo_components.end());
  taken.insert(k_stream_only_components.begin(), k_stream_only_components.end());
  ConfigErrors errors;
  std::optional<RobotConfig> robot = parse_robot(section, path, taken, errors);
  errors.throw_if_any();
  return std::move(*robot);
}

}  // namespace simgate::gateway
