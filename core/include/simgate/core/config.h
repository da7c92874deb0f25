// simgate/core/config.h — reading a JSON configuration object with precise errors.
//
// A ConfigObject wraps one JSON object and the path that leads to it
// ("transports.socket"). Typed getters throw ConfigError naming the full path, what was
// expected and what was found; finish() throws for every key nobody asked for, so typos
// never pass silently. Used by the gateway for the deployment file and by each transport
// for its options.
#ifndef SIMGATE_CORE_CONFIG_H_
#define SIMGATE_CORE_CONFIG_H_

#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <cstddef>
#include <vector>

#include "simgate/core/errors.h"
#include "simgate/core/status.h"

namespace simgate {

// A short description of a JSON value for error messages: `string "abc"`, `number 3`,
// `array [1,2]`. Bounded whatever the value (see json_preview).
std::string describe_json(const json& value);

// The first 60 characters of value.dump() (compact, invalid UTF-8 replaced), cut to 57 and
// "..." when longer. Writes only what it shows: O(60) time and stack for a value of any
// depth or size. Use it (or describe_json) for any client-supplied value in a message.
std::string json_preview(const json& value);

// True if `[`/`{` nest deeper than `max_depth` anywhere in `text` (brackets inside strings
// skipped). One linear pass, no recursion: check it before json::parse on untrusted text
// (nlohmann's dump, comparisons and copies recurse once per level). The JSON-RPC and DDS
// transports check every message (params text) with it.
bool json_nests_deeper_than(std::string_view text, std::size_t max_depth) noexcept;

// The deepest `[`/`{` nesting a configuration document may have. Deployment files nest
// about six levels (transports.<name>.options.<key>); the limit keeps every recursive
// operation on a document (copies, comparisons, dumps) shallow.
inline constexpr std::size_t k_max_config_depth = 64;

// Parses the text of a configuration document. Throws one ConfigTextError (errors.h) naming
// the JSON path of the offending value ("scene.timestep", "robots[1].options";
// "configuration" for the document itself), its line and column when the text is not JSON
// (the start of the offending token), holds a number beyond a double (1e400: nlohmann's
// out_of_range), nests `[`/`{` deeper than `max_depth`, or holds a NUL byte.
// Nothing recursive runs before the depth is known: one streaming pass (nlohmann's SAX
// parser, iterative), then the document is built.
json parse_config_text(std::string_view text, std::size_t max_depth = k_max_config_depth);

class ConfigObject {
 public:
  // Throws ConfigError if value is not an object.
  ConfigObject(const json& value, std::string path);

  const std::string& path() const { return path_; }
  const json& raw() const { return value_; }
  bool has(const std::string& key) const;
  // "<path>.<key>" (or just key at the root).
  std::string path_of(const std::string& key) const;

  // Typed access. `required` throws if missing; `optional`/`get` return the default.
  std::string get_string(const std::string& key, const std::string& fallback);
  std::string required_string(const std::string& key);
  long long get_int(const std::string& key, long long fallback, long long min, long long max);
  double get_number(const std::string& key, double fallback, double min, double max);
  bool get_bool(const std::string& key, bool fallback);
  // One of `choices`.
  std::string get_choice(const std::string& key, const std::string& fallback,
                         const std::vector<std::string>& choices);
  // Any JSON value (marks the key as used); nullopt if absent.
  std::optional<json> get_json(const std::string& key);
  // A nested object; nullopt if absent.
  std::optional<ConfigObject> get_object(const std::string& key);

  // Throws ConfigError listing every key that no getter asked for, with the known keys.
  void finish() const;
  // The keys a getter asked for so far (present or not).
  const std::set<std::string>& asked() const { return used_; }
  // Throws if a key of the object is not in `allowed` (no getters needed).
  void allow_only(const std::vector<std::string>& allowed) const;

  [[noreturn]] void fail(const std::string& key, const std::string& expected) const;

 private:
  const json* find(const std::string& key);

  json value_;                  // the object itself (copied: configs are small)
  std::string path_;            // JSON path of this object, "" at the root
  std::set<std::string> used_;  // keys a getter asked for
};

}  // namespace simgate

#endif  // SIMGATE_CORE_CONFIG_H_
