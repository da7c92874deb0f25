// simgate/core/plugin.h — the transport plugin ABI.
//
// A transport plugin is a shared library (libsimgate_transport_<name>.so) exporting one
// extern "C" function, simgate_transport_<name>_entry, that returns a static descriptor.
// The descriptor begins with the ABI version and its own size, so the host can refuse an
// incompatible library before touching anything else; then the plugin's name, version,
// build tag (C++ library ABI and JSON library version, which must match the host's), the
// option keys it accepts (the host rejects other keys before create), and three functions:
//
//   create(options_json, error, error_size) -> RequestManager* (nullptr + message on error)
//   destroy(RequestManager*)
//   validate(options_json, error, error_size, warnings, warnings_size) -> 1, or 0 + message:
//       every check create() makes of the options, short of opening anything (`simgate
//       check` calls it, and `run` before it creates anything); on success `warnings` holds
//       what the options deserve a warning for (a deprecated key, a token file others may
//       read), one per line, "" for none, so that `check` says what `run` would
//
// No exception crosses this boundary: create catches everything and writes the message.
// Write a plugin with one line:
//
//   SIMGATE_TRANSPORT_PLUGIN(socket, simgate::socket::SocketRequestManager, "0.1.0",
//                            "host", "port", "max_line")
//
// where the class has a constructor taking (const simgate::json& options) and, optionally,
// a static `validate_options(const simgate::json& options)` that throws what the
// constructor would throw for bad options without binding or starting anything, and
// returns its warnings (std::vector<std::string>) or nothing (void) (without it, validate
// checks nothing beyond the option keys). Bump
// SIMGATE_PLUGIN_ABI_VERSION on any change to this struct or to RequestManager.
#ifndef SIMGATE_CORE_PLUGIN_H_
#define SIMGATE_CORE_PLUGIN_H_

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <exception>
#include <string>
#include <type_traits>

#include "simgate/core/request_manager.h"

#define SIMGATE_PLUGIN_ABI_VERSION 8u

#define SIMGATE_STRINGIFY_(x) #x
#define SIMGATE_STRINGIFY(x) SIMGATE_STRINGIFY_(x)

// What must match between host and plugin for C++ objects to cross: the standard
// library's ABI and nlohmann::json's layout.
#define SIMGATE_BUILD_TAG \
  "abi" SIMGATE_STRINGIFY(SIMGATE_PLUGIN_ABI_VERSION) ";cxx11abi=" SIMGATE_STRINGIFY( \
      _GLIBCXX_USE_CXX11_ABI) ";json=" SIMGATE_STRINGIFY(NLOHMANN_JSON_VERSION_MAJOR) "." \
      SIMGATE_STRINGIFY(NLOHMANN_JSON_VERSION_MINOR)

extern "C" {

typedef simgate::RequestManager* (*simgate_create_fn)(const char* options_json, char* error,
                                                      size_t error_size);
typedef void (*simgate_destroy_fn)(simgate::RequestManager* manager);
typedef int (*simgate_validate_fn)(const char* options_json, char* error, size_t error_size,
                                   char* warnings, size_t warnings_size);

struct simgate_transport_descriptor {
  uint32_t abi_version;            // SIMGATE_PLUGIN_ABI_VERSION of the plugin's build
  uint32_t descriptor_size;        // sizeof(simgate_transport_descriptor) of the plugin's build
  const char* name;                // "socket": must match the file and entry names
  const char* version;             // the plugin's own version
  const char* build_tag;           // SIMGATE_BUILD_TAG of the plugin's build
  const char* const* option_keys;  // accepted option keys, nullptr-terminated
  simgate_create_fn create;        // required
  simgate_destroy_fn destroy;      // required
  simgate_validate_fn validate;    // required
};

typedef const struct simgate_transport_descriptor* (*simgate_transport_entry_fn)(void);
}

namespace simgate::detail {

inline void copy_error(char* error, size_t size, const char* text) {
  if (!error || size == 0) return;
  std::strncpy(error, text, size - 1);
  error[size - 1] = '\0';
}

// Shared body of every plugin's create(): parse options, construct, catch everything.
template <class Manager>
RequestManager* create_manager(const char* options_json, char* error, size_t error_size) noexcept {
  try {
    json options = options_json && *options_json ? json::parse(options_json) : json::object();
    return new Manager(options);
  } catch (const std::exception& e) {
    copy_error(error, error_size, e.what());
  } catch (...) {
    copy_error(error, error_size, "unknown exception in create()");
  }
  return nullptr;
}

// Shared body of every plugin's validate(): the class's validate_options() if it has one,
// its warnings (if it returns some) one per line.
template <class Manager>
int validate_options(const char* options_json, char* error, size_t error_size, char* warnings,
                     size_t warnings_size) noexcept {
  try {
    copy_error(warnings, warnings_size, "");
    json options = options_json && *options_json ? json::parse(options_json) : json::object();
    if constexpr (requires { Manager::validate_options(options); }) {
      if constexpr (std::is_void_v<decltype(Manager::validate_options(options))>) {
        Manager::validate_options(options);
      } else {
        std::string lines;
        for (const std::string& w : Manager::validate_options(options)) lines += w + "\n";
        copy_error(warnings, warnings_size, lines.c_str());
      }
    }
    return 1;
  } catch (const std::exception& e) {
    copy_error(error, error_size, e.what());
  } catch (...) {
    copy_error(error, error_size, "unknown exception in validate()");
  }
  return 0;
}

inline void destroy_manager(RequestManager* manager) noexcept {
  try {
    if (manager) manager->stop();
    delete manager;
  } catch (...) {}
}

}  // namespace simgate::detail

#define SIMGATE_TRANSPORT_PLUGIN(NAME, CLASS, VERSION, ...)                    \
  extern "C" __attribute__((visibility("default")))                            \
  const simgate_transport_descriptor* simgate_transport_##NAME##_entry(void) { \
    static const char* const keys[] = {__VA_ARGS__ __VA_OPT__(, ) nullptr};    \
    static const simgate_transport_descriptor descriptor = {                   \
        SIMGATE_PLUGIN_ABI_VERSION,                                            \
        sizeof(simgate_transport_descriptor),                                  \
        #NAME,                                                                 \
        VERSION,                                                               \
        SIMGATE_BUILD_TAG,                                                     \
        keys,                                                                  \
        &simgate::detail::create_manager<CLASS>,                               \
        &simgate::detail::destroy_manager,                                     \
        &simgate::detail::validate_options<CLASS>};                            \
    return &descriptor;                                                        \
  }

#endif  // SIMGATE_CORE_PLUGIN_H_
