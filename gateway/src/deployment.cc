#include "simgate/gateway/deployment.h"

#include <fnmatch.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "simgate/core/log.h"

namespace simgate::gateway {

namespace fs = std::filesystem;

namespace {

const std::vector<std::string> k_pseudo_components = {"simulation", "time"};

std::string join(const std::vector<std::string>& items, const std::string& sep = ", ") {
  std::string out;
  for (const auto& i : items) out += (out.empty() ? "" : sep) + i;
  return out;
}

bool is_glob(const std::string& pattern) { return pattern.find_first_of("*?[") != std::string::npos; }

std::size_t literal_chars(const std::string& pattern) {
  return static_cast<std::size_t>(std::count_if(pattern.begin(), pattern.end(),
                                                [](char c) { return c != '*' && c != '?' && c != '[' && c != ']'; }));
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
  if (!value.is_array()) throw ConfigError(path + ": expected an array of transport names, found " + describe_json(value));
  std::vector<std::string> out;
  for (std::size_t i = 0; i < value.size(); ++i) {
    if (!value[i].is_string())
      throw ConfigError(path + "[" + std::to_string(i) + "]: expected a transport name, found " + describe_json(value[i]));
    out.push_back(value[i].get<std::string>());
  }
  return out;
}

ComponentConfig parse_component(ConfigObject& o, const std::string& full_prefix, const std::string& default_body,
                                const std::string& default_type) {
  ComponentConfig c;
  c.path = o.path();
  std::string name = o.required_string("name");
  check_name(name, o.path_of("name"));
  c.name = full_prefix + name;
  c.type = default_type.empty() ? o.required_string("type") : o.get_string("type", default_type);
  c.body = o.get_string("body", default_body.empty() ? name : default_body);
  auto options = o.get_object("options");
  c.options = options ? options->raw() : json::object();
  return c;
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

std::vector<std::string> Deployment::transports_for(const std::string& component) const {
  if (!has_services) {
    std::vector<std::string> all;
    for (const auto& t : transports) all.push_back(t.name);
    return all;
  }
  // exact name first
  for (const auto& r : rules)
    if (!is_glob(r.pattern) && r.pattern == component) return r.transports;
  // then the most specific glob (most literal characters; ties: first in key order)
  const ServiceRule* best = nullptr;
  for (const auto& r : rules)
    if (is_glob(r.pattern) && glob_matches(r.pattern, component) &&
        (!best || literal_chars(r.pattern) > literal_chars(best->pattern)))
      best = &r;
  if (best) return best->transports;
  return default_transports.value_or(std::vector<std::string>{});
}

Deployment parse_deployment(const json& document, const std::string& base_dir, const std::string& file) {
  Deployment d;
  d.file = file;
  d.base_dir = base_dir;
  ConfigObject root(document, "");
  root.get_string("description", "");  // free text, ignored

  // ---- log level ----
  if (root.has("log_level")) {
    std::string level = root.get_choice("log_level", "info", {"trace", "debug", "info", "warning", "error", "off"});
    d.log_level = level;
  }

  // ---- scene ----
  auto scene_object = root.get_object("scene");
  if (!scene_object) root.fail("scene", "an object {\"mjcf\": \"path/to/scene.xml\", ...}");
  ConfigObject& scene = *scene_object;
  std::string mjcf = scene.required_string("mjcf");
  fs::path mjcf_path = fs::path(mjcf).is_absolute() ? fs::path(mjcf) : fs::path(base_dir) / mjcf;
  std::error_code ec;
  if (!fs::is_regular_file(mjcf_path, ec))
    throw ConfigError(scene.path_of("mjcf") + ": expected an MJCF file, found '" + mjcf_path.string() +
                      "' (no such file)");
  d.mjcf = mjcf_path.lexically_normal().string();
  if (scene.has("timestep")) d.timestep = scene.get_number("timestep", 0.002, 1e-6, 1.0);
  if (auto factor = scene.get_json("realtime_factor")) {
    if (factor->is_string() && factor->get<std::string>() == "max") {
      d.realtime_factor = 0;
    } else if (factor->is_number() && factor->get<double>() >= 0 && factor->get<double>() <= 1e6) {
      d.realtime_factor = factor->get<double>();
    } else {
      throw ConfigError(scene.path_of("realtime_factor") +
                        ": expected a number >= 0 (0 = as fast as possible) or \"max\", found " +
                        describe_json(*factor));
    }
  }
  scene.finish();

  // ---- transports ----
  auto transports = root.get_object("transports");
  if (!transports) root.fail("transports", "an object {\"<name>\": {\"plugin\": ..., \"options\": {...}}}");
  for (auto it = transports->raw().begin(); it != transports->raw().end(); ++it) {
    std::string path = transports->path_of(it.key());
    check_name(it.key(), path);
    ConfigObject t(it.value(), path);
    TransportConfig tc;
    tc.name = it.key();
    tc.path = path;
    tc.plugin = t.get_string("plugin", it.key());
    auto options = t.get_object("options");
    tc.options = options ? options->raw() : json::object();
    t.finish();
    d.transports.push_back(std::move(tc));
  }
  transports->allow_only([&] {
    std::vector<std::string> keys;
    for (auto it = transports->raw().begin(); it != transports->raw().end(); ++it) keys.push_back(it.key());
    return keys;
  }());
  if (d.transports.empty()) root.fail("transports", "at least one transport");

  // ---- robots ----
  std::set<std::string> names(k_pseudo_components.begin(), k_pseudo_components.end());
  if (auto robots = root.get_json("robots")) {
    if (!robots->is_array()) root.fail("robots", "an array of robots");
    for (std::size_t i = 0; i < robots->size(); ++i) {
      std::string path = "robots[" + std::to_string(i) + "]";
      ConfigObject r((*robots)[i], path);
      RobotConfig rc;
      rc.robot = parse_component(r, "", "", "robot");
      if (!names.insert(rc.robot.name).second)
        throw ConfigError(r.path_of("name") + ": expected a unique name, found '" + rc.robot.name +
                          "' a second time" +
                          (rc.robot.name == "simulation" || rc.robot.name == "time" ? " (reserved)" : ""));
      if (auto components = r.get_json("components")) {
        if (!components->is_array()) r.fail("components", "an array of components");
        for (std::size_t j = 0; j < components->size(); ++j) {
          ConfigObject c((*components)[j], path + ".components[" + std::to_string(j) + "]");
          ComponentConfig cc = parse_component(c, rc.robot.name + ".", rc.robot.body, "");
          c.finish();
          if (!names.insert(cc.name).second)
            throw ConfigError(c.path_of("name") + ": expected a unique name, found '" + cc.name + "' a second time");
          rc.components.push_back(std::move(cc));
        }
      }
      r.finish();
      d.robots.push_back(std::move(rc));
    }
  }

  // ---- services (the mapping) ----
  std::vector<std::string> transport_names;
  for (const auto& t : d.transports) transport_names.push_back(t.name);
  auto check_transports = [&](const std::vector<std::string>& list, const std::string& path) {
    for (std::size_t i = 0; i < list.size(); ++i)
      if (std::find(transport_names.begin(), transport_names.end(), list[i]) == transport_names.end())
        throw ConfigError(path + "[" + std::to_string(i) + "]: expected a transport declared in \"transports\" (" +
                          join(transport_names) + "), found '" + list[i] + "'");
  };
  if (auto services = root.get_object("services")) {
    d.has_services = true;
    std::vector<std::string> all = d.component_names();
    std::vector<std::string> keys;
    for (auto it = services->raw().begin(); it != services->raw().end(); ++it) {
      keys.push_back(it.key());
      std::string path = services->path_of(it.key());
      auto list = string_list(it.value(), path);
      check_transports(list, path);
      if (it.key() == "default") {
        d.default_transports = std::move(list);
        continue;
      }
      // every rule must match something: a typo must not silently disconnect a component
      bool matched = std::any_of(all.begin(), all.end(), [&](const std::string& n) {
        return is_glob(it.key()) ? glob_matches(it.key(), n) : it.key() == n;
      });
      if (!matched)
        throw ConfigError(path + ": expected a component name or a glob matching one (" + join(all) +
                          "), found '" + it.key() + "', which matches none");
      d.rules.push_back(ServiceRule{it.key(), std::move(list), path});
    }
    services->allow_only(keys);
  }

  root.finish();

  // transports nobody uses are probably a mistake, but harmless
  for (const auto& t : d.transports) {
    bool used = false;
    for (const auto& n : d.component_names()) {
      auto list = d.transports_for(n);
      if (std::find(list.begin(), list.end(), t.name) != list.end()) used = true;
    }
    if (!used) log::warning(t.path, ": no component is mapped to transport '", t.name, "'");
  }
  return d;
}

Deployment load_deployment(const std::string& file) {
  std::ifstream in(file);
  if (!in) throw ConfigError("config '" + file + "': cannot be read (no such file or no permission)");
  std::stringstream text;
  text << in.rdbuf();
  json document;
  try {
    document = json::parse(text.str());
  } catch (const json::parse_error& e) {
    throw ConfigError("config '" + file + "': invalid JSON: " + e.what());
  }
  fs::path base = fs::absolute(fs::path(file)).parent_path();
  try {
    return parse_deployment(document, base.string(), file);
  } catch (const ConfigError& e) {
    throw ConfigError("config '" + file + "': " + e.what());
  }
}

}  // namespace simgate::gateway
