#include "simgate/core/plugin_loader.h"

#include <dlfcn.h>
#include <sys/stat.h>

#include <algorithm>
#include <cstdlib>
#include <sstream>
#include <string_view>

#include "simgate/core/config.h"
#include "simgate/core/log.h"

namespace simgate {
namespace {

bool is_regular_file(const std::string& path) {
  struct stat st{};
  return ::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

std::string file_name_for(std::string_view kind, const std::string& name) {
  return "libsimgate_" + std::string(kind) + "_" + name + ".so";
}

// "plugins/libsimgate_<kind>_x.so" -> "x"
std::string name_from_path(std::string_view kind, const std::string& path) {
  std::string file = path.substr(path.find_last_of('/') + 1);
  const std::string prefix = "libsimgate_" + std::string(kind) + "_", suffix = ".so";
  if (file.rfind(prefix, 0) == 0) file = file.substr(prefix.size());
  if (file.size() > suffix.size() &&
      file.compare(file.size() - suffix.size(), suffix.size(), suffix) == 0)
    file.resize(file.size() - suffix.size());
  return file;
}

std::string list(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& i : items) out += "\n  " + i;
  return out;
}

}  // namespace

std::vector<std::string> plugin_search_path(const std::vector<std::string>& extra_dirs) {
  std::vector<std::string> dirs;
  if (const char* env = std::getenv("SIMGATE_PLUGIN_PATH")) {
    std::stringstream in(env);
    for (std::string dir; std::getline(in, dir, ':');)
      if (!dir.empty()) dirs.push_back(dir);
  }
  dirs.insert(dirs.end(), extra_dirs.begin(), extra_dirs.end());
  // Then the plugins that came with this libsimgate_core, found from where it runs: the
  // build tree's plugin directory when it is the build tree's library, else
  // <its directory>/simgate/plugins, an installed prefix's own (still right after the prefix
  // moved). An installed binary never looks in the build tree.
  auto resolved = [](const char* path) {
    std::string out;
    if (char* real = ::realpath(path, nullptr)) {
      out = real;
      std::free(real);
    }
    return out;
  };
  static const char anchor = 0;  // an object inside this library
  Dl_info info{};
  const std::string library =
      ::dladdr(&anchor, &info) && info.dli_fname ? resolved(info.dli_fname) : std::string();
  const std::string::size_type slash = library.find_last_of('/');
  if (slash == std::string::npos) {
    dirs.push_back(
        SIMGATE_INSTALL_PLUGIN_DIR);  // where it runs from is unknown: the configured prefix
  } else {
    const std::string library_dir = library.substr(0, slash);
    const bool build_tree = library_dir == resolved(SIMGATE_BUILD_LIB_DIR);
    dirs.push_back(build_tree ? std::string(SIMGATE_BUILD_PLUGIN_DIR)
                              : library_dir + "/" + SIMGATE_PLUGIN_DIR_FROM_LIBDIR);
  }
  return dirs;
}

PluginLibrary open_plugin_library(std::string_view kind, std::string_view what_kind,
                                  const std::string& name_or_path,
                                  const std::vector<std::string>& extra_dirs) {
  // candidates: an explicit path, or <dir>/libsimgate_<kind>_<name>.so for each dir
  const bool explicit_path = name_or_path.find('/') != std::string::npos ||
                             (name_or_path.size() > 3 && name_or_path.ends_with(".so"));
  std::vector<std::string> candidates;
  if (explicit_path) {
    candidates.push_back(name_or_path);
  } else {
    for (const auto& dir : plugin_search_path(extra_dirs))
      candidates.push_back(dir + "/" + file_name_for(kind, name_or_path));
  }
  PluginLibrary found;
  found.name = explicit_path ? name_from_path(kind, name_or_path) : name_or_path;
  found.what = std::string(what_kind) + " '" + found.name + "'";

  for (const auto& c : candidates)
    if (is_regular_file(c)) {
      found.path = c;
      break;
    }
  if (found.path.empty())
    throw PluginError(found.what + ": no " +
                      (explicit_path ? "file " + name_or_path : file_name_for(kind, found.name)) +
                      " found; paths tried:" + list(candidates) +
                      "\n(set SIMGATE_PLUGIN_PATH or give the library's path)");

  // open it: RTLD_LOCAL keeps each plugin's symbols to itself
  void* handle = ::dlopen(found.path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!handle) {
    const char* err = ::dlerror();
    throw PluginError(found.what + " (" + found.path + "): dlopen failed: " +
                      (err ? err : "unknown error") + "\npaths tried:" + list(candidates));
  }
  found.library = std::shared_ptr<void>(handle, [](void* h) { ::dlclose(h); });

  found.entry_name = "simgate_" + std::string(kind) + "_" + found.name + "_entry";
  ::dlerror();
  found.entry = ::dlsym(handle, found.entry_name.c_str());
  if (!found.entry)
    throw PluginError(
        found.what + " (" + found.path + "): entry function " + found.entry_name +
        " not found; is it built with " +
        (kind == "transport" ? "SIMGATE_TRANSPORT_PLUGIN(" : "SIMGATE_COMPONENT_LIBRARY(") +
        found.name + ", ...)?");
  return found;
}

std::shared_ptr<TransportPlugin> load_transport_plugin(const std::string& name_or_path,
                                                       const std::vector<std::string>& extra_dirs) {
  PluginLibrary found =
      open_plugin_library("transport", "transport plugin", name_or_path, extra_dirs);
  const std::string& name = found.name;
  const std::string& what = found.what;
  const std::string& path = found.path;
  const simgate_transport_descriptor* d =
      reinterpret_cast<simgate_transport_entry_fn>(found.entry)();

  // check before trusting anything beyond the first two fields
  auto refuse = [&](const std::string& why) {
    throw PluginError(what + " (" + path + "): " + why);
  };
  if (!d) refuse(found.entry_name + "() returned no descriptor");
  if (d->abi_version != SIMGATE_PLUGIN_ABI_VERSION)
    refuse("ABI version " + std::to_string(d->abi_version) + ", expected " +
           std::to_string(SIMGATE_PLUGIN_ABI_VERSION) +
           " (rebuild the plugin against this simgate)");
  if (d->descriptor_size < sizeof(simgate_transport_descriptor))
    refuse("descriptor of " + std::to_string(d->descriptor_size) + " bytes, expected at least " +
           std::to_string(sizeof(simgate_transport_descriptor)));
  if (!d->build_tag || std::string(d->build_tag) != SIMGATE_BUILD_TAG)
    refuse(std::string("built with '") + (d->build_tag ? d->build_tag : "(none)") +
           "', expected '" + SIMGATE_BUILD_TAG + "' (C++ library ABI and JSON library must match)");
  if (!d->name || name != d->name)
    refuse(std::string("calls itself '") + (d->name ? d->name : "(null)") + "', expected '" + name +
           "'");
  if (!d->create) refuse("required function create is missing");
  if (!d->destroy) refuse("required function destroy is missing");
  if (!d->validate) refuse("required function validate is missing");

  auto plugin = std::make_shared<TransportPlugin>();
  plugin->library_ = std::move(found.library);
  plugin->descriptor_ = d;
  plugin->path_ = path;
  plugin->name_ = name;
  log::debug("loaded ", what, " version ", d->version ? d->version : "?", " from ", path);
  return plugin;
}

std::vector<std::string> TransportPlugin::option_keys() const {
  std::vector<std::string> keys;
  for (const char* const* k = descriptor_->option_keys; k && *k; ++k) keys.emplace_back(*k);
  return keys;
}

std::vector<std::string> TransportPlugin::validate(const json& options,
                                                   const std::string& config_path) const {
  std::vector<std::string> keys = option_keys();
  ConfigObject(options, config_path).allow_only(keys);
  char error[1024] = {0};
  char warnings[4096] = {0};
  if (descriptor_->validate(options.dump().c_str(), error, sizeof(error), warnings,
                            sizeof(warnings))) {
    std::vector<std::string> out;
    std::string_view rest(warnings);
    for (std::size_t end; (end = rest.find('\n')) != std::string_view::npos;
         rest.remove_prefix(end + 1))
      if (end > 0) out.emplace_back(rest.substr(0, end));
    if (!rest.empty()) out.emplace_back(rest);
    return out;
  }
  // a plugin reads its options with a ConfigObject at the root: "port: expected ..." is
  // about one of its keys, and becomes "<config_path>.port: expected ..."
  const std::string message = error[0] ? error : "no reason given";
  const std::size_t end = message.find_first_of(".[:");
  if (end != std::string::npos &&
      std::find(keys.begin(), keys.end(), message.substr(0, end)) != keys.end())
    throw ConfigError(config_path + "." + message);
  throw ConfigError(config_path + ": transport '" + name_ + "' refused its options: " + message);
}

std::shared_ptr<RequestManager> TransportPlugin::create(const json& options,
                                                        const std::string& config_path) const {
  for (const std::string& warning : validate(options, config_path)) log::warning(warning);
  return create_validated(options, config_path);
}

std::shared_ptr<RequestManager> TransportPlugin::create_validated(
    const json& options, const std::string& config_path) const {
  char error[1024] = {0};
  RequestManager* manager = descriptor_->create(options.dump().c_str(), error, sizeof(error));
  if (!manager)
    throw TransportError(config_path + ": transport '" + name_ +
                         "' could not start: " + (error[0] ? error : "no reason given"));
  // the deleter keeps the library loaded until the manager is gone
  auto library = library_;
  auto destroy = descriptor_->destroy;
  return std::shared_ptr<RequestManager>(manager,
                                         [library, destroy](RequestManager* m) { destroy(m); });
}

std::shared_ptr<RequestManager> load_transport(const std::string& name_or_path,
                                               const json& options) {
  return load_transport_plugin(name_or_path)->create(options, "transport '" + name_or_path + "'");
}

}  // namespace simgate
