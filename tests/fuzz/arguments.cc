// Fuzz target arguments: the core's argument binding (core/include/simgate/core/
// arguments.h, service.h: bind_arguments and ArgTraits) and request life cycle, reached
// the way every transport reaches them: RequestManager::on_incoming_request under the
// simulation lock. ServiceHost serves services of many signatures (numbers of every width,
// strings, optionals, arrays, maps, nested vectors, Eigen vectors, any JSON, defaults;
// sync, async under each policy, concurrent, a component that completes with the client's
// value).
//
// The input is a script, one command per line:
//   <component> <service> [<JSON params>]   a call (params: array, object, anything)
//   ~                                       a simulation step (async calls finish)
//   ^<anything>                             cancels an async call started earlier
//   !preempt | !reject                      the global policy
// Properties (ServiceHost): outcomes are consistent (a failure says why) and print; every
// async call ends exactly once, at the end of the input at the latest.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "fuzz_support.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  simgate::fuzz::quiet_logs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace simgate;
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  fuzz::ServiceHost& host = fuzz::ServiceHost::instance();
  std::size_t begin = 0;
  while (begin < input.size()) {
    std::size_t end = input.find('\n', begin);
    if (end == std::string_view::npos) end = input.size();
    const std::string_view line = input.substr(begin, end - begin);
    begin = end + 1;

    if (line.empty()) continue;
    if (line == "~") {
      host.tick();
      continue;
    }
    if (line.front() == '^') {
      host.cancel_started(line.size());
      continue;
    }
    if (line == "!preempt" || line == "!reject") {
      host.set_global_policy(line == "!preempt" ? GlobalPolicy::preempt : GlobalPolicy::reject);
      continue;
    }
    // <component> <service> [params]
    const std::size_t s1 = line.find(' ');
    const std::string component(line.substr(0, s1));
    std::string service;
    std::string_view params_text;
    if (s1 != std::string_view::npos) {
      const std::size_t s2 = line.find(' ', s1 + 1);
      service =
          line.substr(s1 + 1, s2 == std::string_view::npos ? std::string_view::npos : s2 - s1 - 1);
      if (s2 != std::string_view::npos) params_text = line.substr(s2 + 1);
    }
    json params;
    if (!params_text.empty()) {
      // as the transports: the depth pre-scan, then the parser
      if (json_nests_deeper_than(params_text, 128)) continue;
      params = json::parse(params_text, nullptr, /*allow_exceptions=*/false);
      if (params.is_discarded()) continue;
    }
    host.call(component, service, params);
  }
  host.end_input();
  return 0;
}
