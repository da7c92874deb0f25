// Fuzz target dds_params: what the DDS transport does with a decoded simgate_Request's
// strings (plugins/dds/dds_requests.cc, handle_request, OP_CALL), without a DDS
// participant: handle_request itself starts by asking Cyclone about the sample's writer
// (dds_get_matched_publication_data), so it cannot run without a live reader; this target
// follows its steps on the same core functions instead (docs/fuzzing.md says what a full
// handler fuzz would need):
//   params larger than max_params -> refused; json_nests_deeper_than(params, max_depth) ->
//   refused; json::parse without exceptions; anything but an array, an object or "" ->
//   refused with the text's first 60 bytes; the call bound and run (ServiceHost, under the
//   simulation lock); the reply's result, data and message serialised as dump() does.
// It also checks the core helpers a reply's message uses on the parsed value: json_preview
// is dump() cut to 60 characters, whatever the value; describe_json is bounded.
//
// The input: the component, '\n', the service, '\n', the params text (the rest, newlines
// included), as the sample's three strings.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "fuzz_support.h"

namespace simgate::fuzz {
namespace {

constexpr std::size_t k_max_params = 1 << 20;  // the transport's defaults
constexpr std::size_t k_max_depth = 128;

// json_preview's contract (config.h): dump(), cut to 57 and "..." when longer than 60,
// never in the middle of a UTF-8 sequence.
void check_preview(const json& value) {
  const std::string preview = json_preview(value);
  const std::string text = dump(value);
  if (text.size() <= 60) {
    FUZZ_CHECK(preview == text, "a short value's preview is its dump: " + preview + " vs " + text);
  } else {
    FUZZ_CHECK(
        preview.size() <= 60 && preview.size() >= 3 && preview.substr(preview.size() - 3) == "...",
        "a long value's preview is cut with '...': " + preview);
    const std::string shown = preview.substr(0, preview.size() - 3);
    FUZZ_CHECK(text.compare(0, shown.size(), shown) == 0,
               "a preview is the start of the dump: " + preview);
    FUZZ_CHECK(shown.size() + 3 >= 57, "a preview backs off at most 3 bytes for UTF-8: " + preview);
  }
  const std::string described = describe_json(value);
  FUZZ_CHECK(described.size() <= 80, "describe_json is bounded: " + described);
}

void request(std::string_view component, std::string_view service, std::string_view params_text,
             ServiceHost& host) {
  const std::string name = std::string(component) + "." + std::string(service);
  if (params_text.size() > k_max_params) return;                 // FL_BAD_ARGUMENTS: too large
  if (json_nests_deeper_than(params_text, k_max_depth)) return;  // FL_BAD_ARGUMENTS: too deep
  json params;
  if (!params_text.empty()) {
    params = json::parse(params_text, nullptr, false);
    if (params.is_discarded() || !(params.is_array() || params.is_object() || params.is_null())) {
      // the reply quotes the text's first 60 bytes (a cut UTF-8 sequence included)
      const std::string message = name + ": params must be a JSON array, object or \"\", not '" +
                                  std::string(params_text.substr(0, 60)) + "'";
      (void)dump(json(message));
      if (!params.is_discarded()) check_preview(params);
      return;
    }
    check_preview(params);
    const std::size_t depth = depth_of(params);
    FUZZ_CHECK(depth <= k_max_depth, "the pre-scan keeps deeper params out");
    FUZZ_CHECK(depth == 0 || json_nests_deeper_than(params_text, depth - 1),
               "the pre-scan sees the value's depth");
  }
  const std::optional<Outcome> outcome =
      host.call(std::string(component), std::string(service), params);
  if (!outcome) return;  // async: acknowledged, ends in a later step
  // the reply (send_outcome): result, data and message as text
  if (outcome->value) (void)dump(*outcome->value);
  if (!outcome->data.is_null() && !outcome->data.empty()) (void)dump(outcome->data);
  (void)dump(json(outcome->message));
}

}  // namespace
}  // namespace simgate::fuzz

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  simgate::fuzz::quiet_logs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace simgate;
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  const std::size_t c_end = input.find('\n');
  const std::string_view component = input.substr(0, c_end);
  std::string_view service, params;
  if (c_end != std::string_view::npos) {
    const std::size_t s_end = input.find('\n', c_end + 1);
    service = input.substr(
        c_end + 1, s_end == std::string_view::npos ? std::string_view::npos : s_end - c_end - 1);
    if (s_end != std::string_view::npos) params = input.substr(s_end + 1);
  }
  // a DDS string ends at its first NUL
  auto c_string = [](std::string_view s) { return s.substr(0, s.find('\0')); };
  fuzz::ServiceHost& host = fuzz::ServiceHost::instance();
  fuzz::request(c_string(component), c_string(service), c_string(params), host);
  host.tick();
  host.end_input();
  return 0;
}
