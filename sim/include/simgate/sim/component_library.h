// simgate/sim/component_library.h — component types as plugins: the component library ABI.
//
// A component library is a shared library (libsimgate_components_<name>.so) exporting one
// extern "C" function, simgate_components_<name>_entry, that returns a static descriptor:
// the ABI version and the descriptor's size first (so an incompatible library is refused
// before anything else is read), then its name, version, build tag and one function that
// adds its types to a ComponentRegistry. A config names the libraries it needs:
//
//   "component_libraries": ["odometer", "/opt/lab/lib/libsimgate_components_grippers.so"]
//
// and they are found the way transport plugins are (core/plugin_loader.h: an explicit path,
// $SIMGATE_PLUGIN_PATH, --plugin-path, the config's directory, the plugins that came with
// simgate), opened with dlopen, and checked: ABI version, descriptor size, build tag (the
// C++ library ABI, nlohmann::json, MuJoCo's and Eigen's versions: a component touches
// mjModel/mjData and Eigen types across the boundary), the name, and the types it adds,
// which must be new (a library may not replace a built-in type or another library's).
// Every refusal is a PluginError naming the library, its path and why (and the paths
// tried when it is not found).
//
// The built-in types (registry.h) are registered through the same descriptor and the same
// checks (builtin_component_library()), so a built-in is nothing but a library linked in.
//
// Options: a component type reads its options in its factory through the ConfigObject,
// and the registry refuses the keys it did not read (with the valid ones): creating the
// components is part of `simgate check`, so a library's option checks run there without
// any declaration.
//
// Write a library with one line, around a function that registers its types:
//
//   void register_types(simgate::sim::ComponentRegistry& r) { r.add<Odometer>("odometer", ...); }
//   SIMGATE_COMPONENT_LIBRARY(odometer, "1.0.0", register_types)
//
// and build it with simgate_add_component_library(odometer odometer.cc) from simgate's CMake
// package (docs/writing-a-component.md). No exception crosses the boundary: the entry's
// register function catches everything and writes the message. A loaded library stays
// loaded as long as a registry holds one of its types (ComponentType::library), and the
// registry must outlive the components it created.
//
// Threads: loading happens while the simulation is built, on that thread.
#ifndef SIMGATE_SIM_COMPONENT_LIBRARY_H_
#define SIMGATE_SIM_COMPONENT_LIBRARY_H_

#include <mujoco/mujoco.h>

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "simgate/core/plugin.h"
#include "simgate/sim/registry.h"

#define SIMGATE_COMPONENT_ABI_VERSION 1u

// What must match for components to cross: the transports' tag (C++ ABI, JSON), plus the
// component ABI, MuJoCo's header version and Eigen's.
#define SIMGATE_COMPONENT_BUILD_TAG \
  SIMGATE_BUILD_TAG ";components=" SIMGATE_STRINGIFY(SIMGATE_COMPONENT_ABI_VERSION) ";mujoco=" \
      SIMGATE_STRINGIFY(mjVERSION_HEADER) ";eigen=" SIMGATE_STRINGIFY(EIGEN_WORLD_VERSION) "."   \
      SIMGATE_STRINGIFY(EIGEN_MAJOR_VERSION)

extern "C" {

// Adds the library's types to `registry` (a simgate::sim::ComponentRegistry*); 1, or 0
// with a message in `error`.
typedef int (*simgate_register_components_fn)(void* registry, char* error, size_t error_size);

struct simgate_component_library_descriptor {
  uint32_t abi_version;      // SIMGATE_COMPONENT_ABI_VERSION of its build
  uint32_t descriptor_size;  // sizeof(simgate_component_library_descriptor) of its build
  const char* name;          // "odometer": must match the file and entry names
  const char* version;       // the library's own version
  const char* build_tag;     // SIMGATE_COMPONENT_BUILD_TAG of its build
  simgate_register_components_fn register_types;  // required
};

typedef const struct simgate_component_library_descriptor* (*simgate_component_library_entry_fn)(
    void);
}

namespace simgate::sim {

namespace detail {
// The body of every library's register function: calls `add`, catches everything.
template <class Add>
int register_components(void* registry, char* error, size_t error_size, Add add) noexcept {
  try {
    add(*static_cast<ComponentRegistry*>(registry));
    return 1;
  } catch (const std::exception& e) {
    simgate::detail::copy_error(error, error_size, e.what());
  } catch (...) {
    simgate::detail::copy_error(error, error_size,
                                "unknown exception while registering component types");
  }
  return 0;
}
}  // namespace detail

// Adds the types of the library `d` describes (found at `path`, "built in" for the
// built-ins) to `registry` after the checks above; each type keeps `library` (the loaded
// library, null for built-ins) loaded. Returns the names of the types added. Throws
// PluginError.
std::vector<std::string> add_component_library(ComponentRegistry& registry,
                                               const simgate_component_library_descriptor* d,
                                               const std::string& what, const std::string& path,
                                               const std::shared_ptr<void>& library = nullptr);

// Finds, opens and checks a component library and adds its types to `registry`: the
// library stays loaded while one of them is in a registry. Returns the names of the types
// added. Throws PluginError.
std::vector<std::string> load_component_library(ComponentRegistry& registry,
                                                const std::string& name_or_path,
                                                const std::vector<std::string>& extra_dirs = {});

// The built-in types' descriptor (named "builtin").
const simgate_component_library_descriptor* builtin_component_library();

}  // namespace simgate::sim

#define SIMGATE_COMPONENT_LIBRARY(NAME, VERSION, REGISTER)                              \
  extern "C" __attribute__((visibility("default")))                                     \
  const simgate_component_library_descriptor* simgate_components_##NAME##_entry(void) { \
    static const simgate_component_library_descriptor descriptor = {                    \
        SIMGATE_COMPONENT_ABI_VERSION,                                                  \
        sizeof(simgate_component_library_descriptor),                                   \
        #NAME,                                                                          \
        VERSION,                                                                        \
        SIMGATE_COMPONENT_BUILD_TAG,                                                    \
        [](void* registry, char* error, size_t error_size) -> int {                     \
          return ::simgate::sim::detail::register_components(                           \
              registry, error, error_size,                                              \
              [](::simgate::sim::ComponentRegistry& r) { REGISTER(r); });               \
        }};                                                                             \
    return &descriptor;                                                                 \
  }

#endif  // SIMGATE_SIM_COMPONENT_LIBRARY_H_
