// Fuzz target config: the deployment loader (gateway/include/simgate/gateway/deployment.h)
// as `simgate check` and `simgate run` use it before anything starts: the file's text
// parsed as load_deployment() parses it (core's parse_config_text: syntax, numbers beyond a
// double and nesting refused with a ConfigError), then parse_deployment() (structure, names, the
// services mapping against the transports and components), then the mapping queried for
// every component; each transport's options read through core's ConfigObject as a plugin
// reads them (config.h). Relative scene paths resolve in the repository's config/ (the
// scene file is only stat()ed).
//
// Properties: errors are ConfigErrors (nothing else escapes) with a non-empty message;
// parse_config_text refuses no JSON text that json::parse reads within the depth limit
// (a NUL byte aside: refused, where json::parse ends the text), and
// what it accepts is within it; an accepted deployment has unique component names, and its
// mapping names declared transports only.
#include <cstddef>
#include <cstdint>
#include <set>
#include <string>
#include <string_view>

#include "fuzz_support.h"
#include "simgate/gateway/deployment.h"

namespace simgate::fuzz {
namespace {

// A plugin's options as the socket and JSON-RPC transports read theirs.
void read_options(const gateway::TransportConfig& t) {
  try {
    ConfigObject o(t.options, t.path + ".options");
    (void)o.get_string("host", "127.0.0.1");
    (void)o.get_int("port", 4000, 0, 65535);
    (void)o.get_int("max_connections", 256, 1, 1 << 20);
    (void)o.get_number("io_spin_us", 50, 0, 1e6);
    (void)o.get_bool("tcp_nodelay", true);
    (void)o.get_choice("global_policy", "reject", {"reject", "preempt"});
    (void)o.get_json("extra");
    if (auto nested = o.get_object("limits")) {
      (void)nested->get_int("max_depth", 128, 2, 10000);
      nested->finish();
    }
    o.finish();
  } catch (const ConfigError& e) {
    FUZZ_CHECK(!std::string(e.what()).empty(), "a ConfigError says what");
  }
}

}  // namespace
}  // namespace simgate::fuzz

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  simgate::fuzz::quiet_logs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace simgate;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  json document;
  try {
    document = parse_config_text(text);  // as load_deployment
  } catch (const ConfigError& e) {
    FUZZ_CHECK(!e.errors().empty() && !e.errors()[0].empty(), "a refused text says why");
    // refused: not JSON, a number beyond a double, too deep, or a NUL byte (where nlohmann
    // ends the text); never JSON that nlohmann reads, no deeper than the limit
    if (text.find('\0') != std::string_view::npos) {
      FUZZ_CHECK(e.errors()[0].find("found a NUL byte (line ") != std::string::npos,
                 "a NUL byte is named");
    } else if (!json_nests_deeper_than(text, k_max_config_depth)) {
      const json reference = json::parse(text, nullptr, /*allow_exceptions=*/false);
      FUZZ_CHECK(reference.is_discarded(),
                 "parse_config_text refuses only what json::parse refuses: " + e.errors()[0]);
    }
    return 0;
  }
  FUZZ_CHECK(fuzz::depth_of(document) <= k_max_config_depth, "parse_config_text bounds the depth");

  gateway::Deployment d;
  try {
    d = gateway::parse_deployment(document, SIMGATE_FUZZ_CONFIG_DIR, "fuzz.json");
  } catch (const ConfigError& e) {
    FUZZ_CHECK(!e.errors().empty(), "a ConfigError lists its errors");
    for (const auto& message : e.errors()) FUZZ_CHECK(!message.empty(), "every error says what");
    return 0;
  }
  std::set<std::string> transports;
  for (const auto& t : d.transports) {
    transports.insert(t.name);
    fuzz::read_options(t);
  }
  const std::vector<std::string> names = d.component_names();
  FUZZ_CHECK(std::set<std::string>(names.begin(), names.end()).size() == names.size(),
             "component names are unique");
  for (const auto& name : names)
    for (const auto& t : d.transports_for(name))
      FUZZ_CHECK(transports.count(t), "the mapping names declared transports only: " + t);
  return 0;
}
