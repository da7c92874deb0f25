// deployment.cc — the deployment file as a whole: read (load_deployment), every part checked
// and every error of the file reported at once (parse_deployment), the mapping's "services"
// and "streams" rules read and checked against the transports and components. Its sections
// (scene, worlds, spawn, transports, robots): deployment_sections.cc; which transports a
// component's rules give it: deployment_mapping.cc.
#include "simgate/gateway/deployment.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "deployment_parsing.h"
#include "simgate/core/streams.h"
#include "simgate/core/suggest.h"
#include "simgate/core/text.h"

namespace simgate::gateway {

namespace fs = std::filesystem;

const std::vector<std::string> k_pseudo_components = {"simulation", "time", "communication"};
const std::vector<std::string> k_stream_only_components = {"simulation.events"};

namespace {

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

std::vector<std::string> Deployment::component_names() const {
  std::vector<std::string> names;
  for (const auto& r : robots) {
    names.push_back(r.robot.name);
    for (const auto& c : r.components) names.push_back(c.name);
  }
  names.insert(names.end(), k_pseudo_components.begin(), k_pseudo_components.end());
  return names;
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
