// simgate/core/plugin_loader.h — finding, checking and instantiating transport plugins (and
// finding and opening any kind of simgate plugin library).
//
// load_transport("socket") searches, in order:
//   1. an explicit path (a name containing '/' or ending in ".so"),
//   2. each directory of $SIMGATE_PLUGIN_PATH (colon-separated),
//   3. extra directories given by the caller (the gateway: --plugin-path, then the config
//      file's directory),
//   4. the plugins that came with this libsimgate_core, found from where the library runs
//      (dladdr): the build tree's plugin directory when it is the build tree's library,
//      otherwise <the library's directory>/simgate/plugins, i.e. the install prefix's
//      <libdir>/simgate/plugins, wherever the prefix was installed or moved to (an installed
//      binary never searches the build tree),
// for libsimgate_transport_<name>.so, opens it with dlopen(RTLD_NOW | RTLD_LOCAL), finds
// simgate_transport_<name>_entry, and checks the ABI version, descriptor size, build tag,
// name and required functions. Every refusal throws PluginError naming the plugin, the
// path, the reason and every path tried.
//
// A TransportHandle keeps the library loaded for as long as the manager it created lives.
#ifndef SIMGATE_CORE_PLUGIN_LOADER_H_
#define SIMGATE_CORE_PLUGIN_LOADER_H_

#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "simgate/core/plugin.h"
#include "simgate/core/request_manager.h"

namespace simgate {

class PluginError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A transport whose options passed validate() failed to start: a port in use, no DDS
// domain. A runtime failure of the machine, not of the configuration.
class TransportError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A loaded, checked plugin library.
class TransportPlugin {
 public:
  const simgate_transport_descriptor& descriptor() const { return *descriptor_; }
  const std::string& path() const { return path_; }
  const std::string& name() const { return name_; }
  std::vector<std::string> option_keys() const;

  // Creates a manager from the plugin: validate() first (ConfigError; its warnings logged),
  // then create_validated().
  std::shared_ptr<RequestManager> create(const json& options, const std::string& config_path) const;
  // The plugin's create() on options validate() accepted (the host reported its warnings),
  // whose failure is a TransportError prefixed with `config_path`. The returned manager
  // keeps the library loaded.
  std::shared_ptr<RequestManager> create_validated(const json& options,
                                                   const std::string& config_path) const;
  // Every check create() makes of `options`, opening nothing (no socket bound, no DDS
  // participant). Throws ConfigError prefixed with `config_path`; returns the warnings the
  // options deserve (a deprecated key, a token file others may read), as `run` gives them.
  std::vector<std::string> validate(const json& options, const std::string& config_path) const;

 private:
  friend std::shared_ptr<TransportPlugin> load_transport_plugin(const std::string&,
                                                                const std::vector<std::string>&);
  std::shared_ptr<void> library_;                             // dlclose on last reference
  const simgate_transport_descriptor* descriptor_ = nullptr;  // inside library_
  std::string path_;                                          // where it was found
  std::string name_;                                          // requested name
};

// A plugin library found, opened and its entry function resolved, not yet checked: what
// every kind of plugin (transports here, component libraries in sim/component_library.h)
// does alike.
struct PluginLibrary {
  std::shared_ptr<void> library;  // dlclose on last reference
  std::string path;               // where it was found
  std::string name;               // "socket"
  std::string what;               // "transport plugin 'socket'", for messages
  std::string entry_name;         // "simgate_transport_socket_entry"
  void* entry = nullptr;          // that function
};

// Searches (as above) for libsimgate_<kind>_<name>.so, opens it and resolves
// simgate_<kind>_<name>_entry. `what_kind` names the kind in messages ("transport
// plugin"). Throws PluginError naming the paths tried.
PluginLibrary open_plugin_library(std::string_view kind, std::string_view what_kind,
                                  const std::string& name_or_path,
                                  const std::vector<std::string>& extra_dirs = {});

// The directories searched for `name` (after an explicit path), in order.
std::vector<std::string> plugin_search_path(const std::vector<std::string>& extra_dirs = {});

// Finds, opens and checks a plugin. Throws PluginError.
std::shared_ptr<TransportPlugin> load_transport_plugin(
    const std::string& name_or_path, const std::vector<std::string>& extra_dirs = {});

// load_transport_plugin + create, for standalone programs:
//   auto rm = simgate::load_transport("socket", {{"port", 4000}});
std::shared_ptr<RequestManager> load_transport(const std::string& name_or_path,
                                               const json& options = json::object());

}  // namespace simgate

#endif  // SIMGATE_CORE_PLUGIN_LOADER_H_
