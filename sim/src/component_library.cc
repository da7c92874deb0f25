#include "simgate/sim/component_library.h"

#include "simgate/core/log.h"
#include "simgate/core/plugin_loader.h"

namespace simgate::sim {

std::vector<std::string> add_component_library(ComponentRegistry& registry,
                                               const simgate_component_library_descriptor* d,
                                               const std::string& what, const std::string& path,
                                               const std::shared_ptr<void>& library) {
  // check before trusting anything beyond the first two fields
  auto refuse = [&](const std::string& why) {
    throw PluginError(what + " (" + path + "): " + why);
  };
  if (!d) refuse("its entry function returned no descriptor");
  if (d->abi_version != SIMGATE_COMPONENT_ABI_VERSION)
    refuse("component ABI version " + std::to_string(d->abi_version) + ", expected " +
           std::to_string(SIMGATE_COMPONENT_ABI_VERSION) +
           " (rebuild the library against this simgate)");
  if (d->descriptor_size < sizeof(simgate_component_library_descriptor))
    refuse("descriptor of " + std::to_string(d->descriptor_size) + " bytes, expected at least " +
           std::to_string(sizeof(simgate_component_library_descriptor)));
  if (!d->build_tag || std::string(d->build_tag) != SIMGATE_COMPONENT_BUILD_TAG)
    refuse(std::string("built with '") + (d->build_tag ? d->build_tag : "(none)") +
           "', expected '" + SIMGATE_COMPONENT_BUILD_TAG +
           "' (C++ library ABI, JSON, MuJoCo and Eigen must match)");
  if (!d->name || !*d->name) refuse("the descriptor has no name");
  if (!d->register_types) refuse("required function register_types is missing");

  // its types go into a registry of their own first: nothing is added unless all may be
  ComponentRegistry added;
  char error[1024] = {0};
  if (!d->register_types(&added, error, sizeof(error)))
    refuse(std::string("registering its types failed: ") + (error[0] ? error : "no reason given"));
  if (added.types().empty()) refuse("it registers no component type");
  const std::string origin = path == "built in" ? path : what + " (" + path + ")";
  std::vector<std::string> names;
  for (const auto& [name, type] : added.types()) {
    if (const ComponentType* existing = registry.find(name))
      refuse("it registers type '" + name + "', which " + existing->origin + " already provides (" +
             "a library may not replace a type: give yours another name)");
    if (!type.factory) refuse("type '" + name + "' has no factory");
    names.push_back(name);
  }
  for (auto [name, type] : added.types()) {
    type.origin = origin;
    type.library = library;
    registry.add(std::move(type));
  }
  return names;
}

std::vector<std::string> load_component_library(ComponentRegistry& registry,
                                                const std::string& name_or_path,
                                                const std::vector<std::string>& extra_dirs) {
  PluginLibrary found =
      open_plugin_library("components", "component library", name_or_path, extra_dirs);
  const auto* d = reinterpret_cast<simgate_component_library_entry_fn>(found.entry)();
  if (d && d->abi_version == SIMGATE_COMPONENT_ABI_VERSION &&
      d->descriptor_size >= sizeof(simgate_component_library_descriptor) && d->name &&
      found.name != d->name)
    throw PluginError(found.what + " (" + found.path + "): calls itself '" + d->name +
                      "', expected '" + found.name + "'");
  std::vector<std::string> names =
      add_component_library(registry, d, found.what, found.path, found.library);
  log::debug("loaded ", found.what, " version ", d->version ? d->version : "?", " from ",
             found.path, ": ", names.size(), " type(s)");
  return names;
}

namespace {
void register_builtins(ComponentRegistry& registry) { register_builtin_components(registry); }
}  // namespace

const simgate_component_library_descriptor* builtin_component_library() {
  static const simgate_component_library_descriptor descriptor = {
      SIMGATE_COMPONENT_ABI_VERSION,
      sizeof(simgate_component_library_descriptor),
      "builtin",
      SIMGATE_VERSION,
      SIMGATE_COMPONENT_BUILD_TAG,
      [](void* registry, char* error, size_t error_size) -> int {
        return detail::register_components(registry, error, error_size, register_builtins);
      }};
  return &descriptor;
}

ComponentRegistry builtin_registry() {
  ComponentRegistry registry;
  add_component_library(registry, builtin_component_library(), "the built-in component types",
                        "built in");
  return registry;
}

}  // namespace simgate::sim
