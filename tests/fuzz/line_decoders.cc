// Fuzz target line_decoders: the decoders issue #35 added in front of the line transports
// and the streams. The input is a connection's stream, split at '\n':
//   - every line goes through kit::is_http_request_line (a web page's POST to a line port
//     closes the connection: simgate/kit/http_line.h), compared with a regular expression of
//     the same grammar written independently;
//   - a line that is a JSON object is a stream command, checked by StreamHub::unknown_key
//     against a stream of fields "v" and "w" (a motion's).
//
// Properties: the detector and the grammar agree on every line; a command is refused exactly
// when one of its keys is neither a field nor "timestamp", and the refusal names that key.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <regex>
#include <string>
#include <string_view>

#include "fuzz_support.h"
#include "simgate/core/streams.h"
#include "simgate/kit/http_line.h"

namespace simgate::fuzz {
namespace {

// The grammar, as a regular expression: METHOD SP target SP HTTP/d.d [CR]
bool by_the_grammar(std::string_view line) {
  static const std::regex request_line("[A-Z]{1,16} [^ ]+ HTTP/[0-9]\\.[0-9]\r?",
                                       std::regex::ECMAScript);
  return std::regex_match(line.begin(), line.end(), request_line);
}

const StreamInfo& motion_stream() {
  static const StreamInfo info = [] {
    StreamInfo s;
    s.component = "robot.motion";
    s.direction = StreamDirection::in;
    s.kind = "velocity";
    s.fields = {"v", "w"};
    return s;
  }();
  return info;
}

void one_line(std::string_view line) {
  const bool http = kit::is_http_request_line(line);
  FUZZ_CHECK(http == by_the_grammar(line),
             "is_http_request_line agrees with the request-line grammar");
  if (line.empty() || line.front() != '{') return;
  const json command = json::parse(line, nullptr, false);
  if (!command.is_object()) return;
  std::optional<std::string> stranger;  // the first key that is no field ("" is a key too)
  for (auto it = command.begin(); it != command.end() && !stranger; ++it)
    if (it.key() != "v" && it.key() != "w" && it.key() != "timestamp") stranger = it.key();
  const std::string refusal = StreamHub::unknown_key(motion_stream(), command);
  FUZZ_CHECK(refusal.empty() == !stranger,
             "a command is refused exactly when it has an unknown key");
  if (stranger)
    FUZZ_CHECK(refusal.find("unknown key '" + *stranger + "'") != std::string::npos,
               "the refusal names the key");
}

}  // namespace
}  // namespace simgate::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  std::size_t start = 0;
  for (int lines = 0; start <= input.size() && lines < 64; ++lines) {
    const std::size_t end = std::min(input.find('\n', start), input.size());
    simgate::fuzz::one_line(input.substr(start, end - start));
    start = end + 1;
  }
  return 0;
}
