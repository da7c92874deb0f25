#include "simgate/gateway/deployment.h"

#include <fnmatch.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "simgate/core/log.h"
#include "simgate/core/streams.h"
#include "simgate/core/suggest.h"
#include "simgate/core/text.h"
#include "simgate/sim/run_policy.h"

namespace simgate::gateway {

namespace fs = std::filesystem;

const std::vector<std::string> k_pseudo_components = {"simulation", "time", "communication"};
const std::vector<std::string> k_stream_only_components = {"simulation.events"};

namespace {

bool is_glob(const std::string& pattern) {
  return pattern.find_first_of("*?[") != std::string::npos;
}

std::size_t literal_chars(const std::string& pattern) {
  return static_cast<std::size_t>(std::count_if(pattern.begin(), pattern.end(), [](char c) {
    return c != '*' && c != '?' && c != '[' && c != ']';
  }));
}

bool glob_matches(const std::string& pattern, const std::string& name) {
  return fnmatch(pattern.c_str(), name.c_str(), 0) == 0;
}

// Robot and component names: letters, digits, '_' and '-' (the '.' joins robot and component).
void check_name(const std::string& name, const std::string& path) {
  bool ok = !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-';
  });
  if (!ok)
    throw ConfigError(path + ": expected a name made of letters, digits, '_' and '-', found " +
                      describe_json(name));
}

// A JSON array of strings.
std::vector<std::string> string_list(const json& value, const std::string& path) {
  if (!value.is_array())
    throw ConfigError(path + ": expected an array of transport names, found " +
                      describe_json(value));
  std::vector<std::string> out;
  for (std::size_t i = 0; i < value.size(); ++i) {
    if (!value[i].is_string())
      throw ConfigError(path + "[" + std::to_string(i) + "]: expected a transport name, found " +
                        describe_json(value[i]));
    out.push_back(value[i].get<std::string>());
  }
  return out;
}

// A "streams" rule written as an object: {"transports": [names], "frequency": Hz (optional)}.
std::vector<std::string> stream_rule(const json& value, const std::string& path,
                                     std::optional<double>& frequency) {
  ConfigObject rule(value, path);
  auto transports = rule.get_json("transports");
  if (!transports) rule.fail("transports", "an array of the transport names that carry the stream");
  std::vector<std::string> list = string_list(*transports, rule.path_of("transports"));
  if (rule.has("frequency"))
    frequency = rule.get_number("frequency", StreamHub::k_default_frequency, 1e-3, 1e6);
  rule.allow_only({"transports", "frequency"});
  return list;
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

void check_transports(const std::vector<std::string>& list,
                      const std::vector<std::string>& transport_names, const std::string& path) {
  for (std::size_t i = 0; i < list.size(); ++i)
    if (std::find(transport_names.begin(), transport_names.end(), list[i]) == transport_names.end())
      throw ConfigError(path + "[" + std::to_string(i) +
                        "]: expected a transport declared in \"transports\" (" +
                        join(transport_names) + "), found '" + list[i] + "'" +
                        did_you_mean(list[i], transport_names));
}

}  // namespace

RobotConfig parse_robot_section(const json& section, const std::string& path,
                                std::set<std::string> taken) {
  taken.insert(k_pseudo_components.begin(), k_pseudo_components.end());
  taken.insert(k_stream_only_components.begin(), k_stream_only_components.end());
  ConfigErrors errors;
  std::optional<RobotConfig> robot = parse_robot(section, path, taken, errors);
  errors.throw_if_any();
  return std::move(*robot);
}

std::vector<std::string> Deployment::component_names() const {
  std::vector<std::string> names;
  for (const auto& r : robots) {
    names.push_back(r.robot.name);
    for (const auto& c : r.components) names.push_back(c.name);
  }
  names.insert(names.end(), k_pseudo_components.begin(), k_pseudo_components.end());
  return names;
}

namespace {

// The rule of `rules` that gives `component` its transports: its exact name, else the most
// specific matching glob (most literal characters; ties: first in key order); null when none
// does (the caller's fallback, "default", applies).
const ServiceRule* best_rule(const std::vector<ServiceRule>& rules, const std::string& component) {
  for (const auto& r : rules)
    if (!is_glob(r.pattern) && r.pattern == component) return &r;
  const ServiceRule* best = nullptr;
  for (const auto& r : rules)
    if (is_glob(r.pattern) && glob_matches(r.pattern, component) &&
        (!best || literal_chars(r.pattern) > literal_chars(best->pattern)))
      best = &r;
  return best;
}

// The transports `rules` give `component` (best_rule), else `fallback`.
std::vector<std::string> match_rules(const std::vector<ServiceRule>& rules,
                                     const std::optional<std::vector<std::string>>& fallback,
                                     const std::string& component) {
  if (const ServiceRule* r = best_rule(rules, component)) return r->transports;
  return fallback.value_or(std::vector<std::string>{});
}

bool is_pseudo_component(const std::string& name) {
  return std::find(k_pseudo_components.begin(), k_pseudo_components.end(), name) !=
             k_pseudo_components.end() ||
         std::find(k_stream_only_components.begin(), k_stream_only_components.end(), name) !=
             k_stream_only_components.end();
}

}  // namespace

std::vector<std::string> Deployment::transports_for(const std::string& component) const {
  if (!has_services) {
    std::vector<std::string> all;
    for (const auto& t : transports) all.push_back(t.name);
    return all;
  }
  // communication goes with simulation unless named (MORSE serves both on every socket)
  if (component == "communication" &&
      std::none_of(rules.begin(), rules.end(),
                   [](const ServiceRule& r) { return r.pattern == "communication"; }))
    return transports_for("simulation");
  return match_rules(rules, default_transports, component);
}

std::vector<std::string> Deployment::streams_for(const std::string& component) const {
  // a pseudo-component streams only when named (see the header)
  if (is_pseudo_component(component)) {
    const ServiceRule* r = stream_rule_named(component);
    return r ? r->transports : std::vector<std::string>{};
  }
  return match_rules(stream_rules, default_stream_transports, component);
}

std::optional<double> Deployment::stream_frequency_for(const std::string& component) const {
  if (is_pseudo_component(component)) {
    const ServiceRule* r = stream_rule_named(component);
    return r ? r->frequency : std::nullopt;
  }
  if (const ServiceRule* r = best_rule(stream_rules, component)) return r->frequency;
  return default_stream_transports ? default_stream_frequency : std::nullopt;
}

const ServiceRule* Deployment::stream_rule_named(const std::string& component) const {
  for (const auto& r : stream_rules)
    if (r.pattern == component) return &r;
  return nullptr;
}

Deployment parse_deployment(const json& document, const std::string& base_dir,
                            const std::string& file) {
  ConfigErrors errors;
  Deployment d = parse_deployment(document, base_dir, file, errors);
  errors.throw_if_any();
  return d;
}

Deployment parse_deployment(const json& document, const std::string& base_dir,
                            const std::string& file, ConfigErrors& errors) {
  Deployment d;
  d.file = file;
  d.base_dir = base_dir;
  d.document = document;
  // every independent part is checked even when another failed: all of a file's errors
  // are reported at once
  const std::size_t errors_before = errors.errors().size();
  std::optional<ConfigObject> root_object;
  if (!errors.check([&] { root_object.emplace(document, ""); })) return d;
  ConfigObject& root = *root_object;
  errors.check([&] { root.get_string("description", ""); });  // free text, ignored

  // ---- log level ----
  errors.check([&] {
    if (root.has("log_level"))
      d.log_level = root.get_choice("log_level", "info",
                                    {"trace", "debug", "info", "warning", "error", "off"});
  });

  // ---- requests: limits every transport applies ----
  errors.check([&] {
    auto requests = root.get_object("requests");
    if (!requests) return;
    d.max_wait = std::chrono::milliseconds(requests->get_int("max_wait_ms", 0, 0, 2'147'483'647));
    requests->finish();
  });

  // ---- scene, and how many worlds run it ----
  errors.check([&] { parse_scene(root, base_dir, d); });
  errors.check([&] { parse_worlds(root, base_dir, d); });

  // ---- run-time entities ----
  errors.check([&] { parse_spawn(root, base_dir, d); });

  // ---- component libraries (loaded by the gateway, which knows where to look) ----
  errors.check([&] {
    if (auto libraries = root.get_json("component_libraries"))
      d.component_libraries = string_list(*libraries, "component_libraries");
  });

  // ---- transports ----
  std::vector<std::string> transport_names;
  errors.check([&] {
    auto transports = root.get_object("transports");
    if (!transports)
      root.fail("transports", "an object {\"<name>\": {\"plugin\": ..., \"options\": {...}}}");
    for (auto it = transports->raw().begin(); it != transports->raw().end(); ++it) {
      transport_names.push_back(it.key());
      errors.check([&] {
        d.transports.push_back(
            parse_transport(it.key(), it.value(), transports->path_of(it.key())));
      });
    }
    if (transport_names.empty()) root.fail("transports", "at least one transport");
  });

  // ---- robots ----
  std::set<std::string> names(k_pseudo_components.begin(), k_pseudo_components.end());
  names.insert(k_stream_only_components.begin(), k_stream_only_components.end());
  const std::size_t errors_before_robots = errors.errors().size();
  errors.check([&] {
    auto robots = root.get_json("robots");
    if (!robots) return;
    if (!robots->is_array()) root.fail("robots", "an array of robots");
    for (std::size_t i = 0; i < robots->size(); ++i)
      if (auto robot =
              parse_robot((*robots)[i], "robots[" + std::to_string(i) + "]", names, errors))
        d.robots.push_back(std::move(*robot));
  });
  const bool robots_ok = errors.errors().size() == errors_before_robots;

  // ---- services (the mapping) and streams: component name or glob -> transports ----
  std::vector<std::string> all = d.component_names();
  // a robot of type mjcf gets its generic components once the scene is loaded (gateway)
  for (const auto& r : d.robots)
    if (r.robot.type == "mjcf")
      for (const char* type : {"armature", "armature_pose", "actuators", "sensors"})
        all.push_back(r.robot.name + "." + type);
  // what a "streams" rule may name besides: the components that only stream
  std::vector<std::string> streamed = all;
  streamed.insert(streamed.end(), k_stream_only_components.begin(), k_stream_only_components.end());
  // `frequency`: the section is "streams", whose rules may be {"transports": [...],
  // "frequency": Hz} as well as a list; the default rule's frequency goes there
  auto parse_rules = [&](const char* key, std::vector<ServiceRule>& rules,
                         std::optional<std::vector<std::string>>& fallback,
                         std::optional<double>* frequency) {
    auto section = root.get_object(key);
    if (!section) return false;
    for (auto it = section->raw().begin(); it != section->raw().end(); ++it) {
      errors.check([&] {
        const std::string path = section->path_of(it.key());
        std::optional<double> rate;
        std::vector<std::string> list;
        std::string list_path = path;  // where a transport's error points
        if (frequency && it.value().is_object()) {
          list = stream_rule(it.value(), path, rate);
          list_path += ".transports";
        } else if (frequency && !it.value().is_array()) {
          throw ConfigError(
              path +
              ": expected an array of transport names or an object {\"transports\": [...], " +
              "\"frequency\": Hz}, found " + describe_json(it.value()));
        } else {
          list = string_list(it.value(), path);
        }
        check_transports(list, transport_names, list_path);
        if (it.key() == "default") {
          fallback = std::move(list);
          if (frequency) *frequency = rate;
          return;
        }
        // a rule should match something: a typo must not silently disconnect a component
        // (not checked when a robot was invalid: its components are unknown). One close to a
        // name of the file is taken for a typo; another may map robots spawned at run time
        // (simulation spawn_entity's robot), and is only warned about.
        const std::vector<std::string>& names = frequency ? streamed : all;
        bool matched = std::any_of(names.begin(), names.end(), [&](const std::string& n) {
          return is_glob(it.key()) ? glob_matches(it.key(), n) : it.key() == n;
        });
        if (!matched && robots_ok) {
          const std::string suggestion = did_you_mean(it.key(), names);
          if (!suggestion.empty())
            throw ConfigError(path + ": expected a component name or a glob matching one (" +
                              join(names) + "), found '" + it.key() + "', which matches none" +
                              suggestion);
          d.warnings.push_back(path + ": '" + it.key() + "' matches no component of this file (" +
                               join(names) +
                               "): it maps only robots spawned at run time under such names");
        }
        rules.push_back(ServiceRule{it.key(), std::move(list), path, rate});
      });
    }
    return true;
  };
  errors.check(
      [&] { d.has_services = parse_rules("services", d.rules, d.default_transports, nullptr); });
  errors.check([&] {
    parse_rules("streams", d.stream_rules, d.default_stream_transports,
                &d.default_stream_frequency);
  });

  errors.check([&] { root.finish(); });
  if (errors.errors().size() != errors_before) return d;

  // transports nobody uses are probably a mistake, but harmless
  for (const auto& t : d.transports) {
    bool used = false;
    for (const auto& n : d.component_names()) {
      auto list = d.transports_for(n);
      if (std::find(list.begin(), list.end(), t.name) != list.end()) used = true;
    }
    if (!used)
      d.warnings.push_back(t.path + ": no component is mapped to transport '" + t.name + "'");
  }
  return d;
}

json load_config_document(const std::string& file) {
  std::ifstream in(file);
  if (!in) throw ConfigError({"cannot be read (no such file or no permission)"}, file);
  std::stringstream text;
  text << in.rdbuf();
  try {
    // syntax, numbers beyond a double and nesting deeper than k_max_config_depth are refused
    // with their JSON path before anything recursive touches the document
    return parse_config_text(text.str());
  } catch (const ConfigTextError& e) {
    // "demo.json:3:17: scene: invalid JSON: ...", where editors jump from
    throw ConfigError(e.located(file));
  }
}

Deployment load_deployment(const std::string& file) {
  ConfigErrors errors;
  Deployment d = load_deployment(file, errors);
  if (!errors.empty()) throw ConfigError(errors.errors(), file);
  return d;
}

Deployment load_deployment(const std::string& file, ConfigErrors& errors) {
  json document = load_config_document(file);
  fs::path base = fs::absolute(fs::path(file)).parent_path();
  return parse_deployment(document, base.string(), file, errors);
}

}  // namespace simgate::gateway
