// Deliberately broken plugins: each is compiled with one BROKEN_* macro defined and must be
// refused by the loader with a clear message.
#include <stdexcept>

#include "simgate/core/plugin.h"

namespace {

class Throwing : public simgate::RequestManager {
 public:
  explicit Throwing(const simgate::json&) : RequestManager("Throwing") {
    throw std::runtime_error("cannot open /dev/imaginary: no such device");
  }
  void on_service_completion(simgate::RequestId, simgate::Outcome&&) override {}
};

const char* const no_keys[] = {nullptr};

[[maybe_unused]] simgate::RequestManager* create_none(const char*, char*, size_t) {
  return nullptr;
}
[[maybe_unused]] void destroy_none(simgate::RequestManager*) {}
[[maybe_unused]] int validate_none(const char*, char*, size_t, char*, size_t) { return 1; }

}  // namespace

#define EXPORT extern "C" __attribute__((visibility("default")))

#if defined(BROKEN_THROWS)
SIMGATE_TRANSPORT_PLUGIN(throws, Throwing, "0.0.1")
#elif defined(BROKEN_ABI)
EXPORT const simgate_transport_descriptor* simgate_transport_badabi_entry(void) {
  static const simgate_transport_descriptor d = {999,
                                                 sizeof(simgate_transport_descriptor),
                                                 "badabi",
                                                 "0",
                                                 SIMGATE_BUILD_TAG,
                                                 no_keys,
                                                 create_none,
                                                 destroy_none,
                                                 validate_none};
  return &d;
}
#elif defined(BROKEN_TAG)
EXPORT const simgate_transport_descriptor* simgate_transport_badtag_entry(void) {
  static const simgate_transport_descriptor d = {SIMGATE_PLUGIN_ABI_VERSION,
                                                 sizeof(simgate_transport_descriptor),
                                                 "badtag",
                                                 "0",
                                                 "abi1;cxx11abi=0;json=2.0",
                                                 no_keys,
                                                 create_none,
                                                 destroy_none,
                                                 validate_none};
  return &d;
}
#elif defined(BROKEN_NOCREATE)
EXPORT const simgate_transport_descriptor* simgate_transport_nocreate_entry(void) {
  static const simgate_transport_descriptor d = {SIMGATE_PLUGIN_ABI_VERSION,
                                                 sizeof(simgate_transport_descriptor),
                                                 "nocreate",
                                                 "0",
                                                 SIMGATE_BUILD_TAG,
                                                 no_keys,
                                                 nullptr,
                                                 destroy_none,
                                                 validate_none};
  return &d;
}
#elif defined(BROKEN_NOSYMBOL)
// exports a function, but not the entry the loader looks for
EXPORT int simgate_transport_something_else(void) { return 42; }
#elif defined(BROKEN_MISNAMED)
EXPORT const simgate_transport_descriptor* simgate_transport_misnamed_entry(void) {
  static const simgate_transport_descriptor d = {SIMGATE_PLUGIN_ABI_VERSION,
                                                 sizeof(simgate_transport_descriptor),
                                                 "other",
                                                 "0",
                                                 SIMGATE_BUILD_TAG,
                                                 no_keys,
                                                 create_none,
                                                 destroy_none,
                                                 validate_none};
  return &d;
}
#elif defined(BROKEN_UNDEFINED)
// needs a function no library provides: dlopen(RTLD_NOW) refuses it
extern "C" int simgate_function_nobody_defines(int);
EXPORT int simgate_transport_undefined_entry(void) { return simgate_function_nobody_defines(1); }
#endif
