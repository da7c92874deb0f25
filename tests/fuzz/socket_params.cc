// Fuzz target socket_params: the socket transport's parameter parser (plugins/socket/
// params_parser.h), JSON and Python literals, on its own. The input is the parameters text
// of one request line.
//
// Properties:
//  - errors point into the text, and move with first_column;
//  - a parsed value holds valid UTF-8 only, and what append_json writes of it (MORSE's
//    json.dumps layout) parses back to the same value, types included;
//  - any JSON text (nlohmann accepts it, no deeper than k_max_depth, no NUL byte) is accepted, with the
//    same value (integers compared by value: nlohmann reads 5 as unsigned, the parser as
//    signed); the refusals are numbers out of range (an integer beyond 64 bits, which
//    nlohmann turns into a double; a number beyond a double);
//  - the bare-values hint (`0.5 0.2` -> `[0.5, 0.2]`) is a list the parser reads;
//  - valid_utf8 agrees with nlohmann's UTF-8 check of the same bytes.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "fuzz_support.h"
#include "simgate/morse/params_parser.h"
#include "simgate/morse/wire.h"

namespace simgate::fuzz {
namespace {

bool all_utf8(const json& value) {
  std::size_t bad = 0;
  if (value.is_string()) return socket::valid_utf8(value.get_ref<const std::string&>(), bad);
  if (value.is_object()) {
    for (auto it = value.begin(); it != value.end(); ++it)
      if (!socket::valid_utf8(it.key(), bad) || !all_utf8(it.value())) return false;
    return true;
  }
  if (value.is_array()) {
    for (const auto& e : value)
      if (!all_utf8(e)) return false;
  }
  return true;
}

// identical(), but any two integers of the same value are the same
bool same_value(const json& a, const json& b) {
  const bool ai = a.is_number_integer(), bi = b.is_number_integer();  // signed or unsigned
  if (ai || bi) return ai && bi && a == b;
  if (a.type() != b.type()) return false;
  if (a.is_array()) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i)
      if (!same_value(a[i], b[i])) return false;
    return true;
  }
  if (a.is_object()) {
    if (a.size() != b.size()) return false;
    for (auto it = a.begin(), jt = b.begin(); it != a.end(); ++it, ++jt)
      if (it.key() != jt.key() || !same_value(it.value(), jt.value())) return false;
    return true;
  }
  return identical(a, b);
}

}  // namespace
}  // namespace simgate::fuzz

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  simgate::fuzz::quiet_logs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace simgate;
  using fuzz::dump;
  const std::string_view text(reinterpret_cast<const char*>(data), size);

  const socket::ParamsParse p = socket::parse_params(text, 1);
  const socket::ParamsParse shifted = socket::parse_params(text, 1000);
  FUZZ_CHECK(p.ok == shifted.ok, "first_column does not change the outcome");

  if (!p.ok) {
    FUZZ_CHECK(!p.error.empty(), "an error says what");
    FUZZ_CHECK(p.column >= 1 && p.column <= text.size() + 1, "the error's column is in the text");
    FUZZ_CHECK(shifted.column == p.column + 999 && shifted.error == p.error &&
                   shifted.example == p.example,
               "the error moves with first_column");
    if (!p.example.empty()) {
      // (wrapping bare values in a list adds a level: values k_max_depth deep make a hint
      // one level too deep)
      const socket::ParamsParse hint = socket::parse_params(p.example);
      const bool one_too_deep = !hint.ok && hint.error.rfind("nesting deeper than", 0) == 0;
      FUZZ_CHECK((hint.ok && hint.value.is_array() && hint.value.size() >= 2) || one_too_deep,
                 "the bare-values hint is a list of two values or more: " + p.example);
    }
  } else {
    FUZZ_CHECK(p.example.empty(), "no hint without an error");
    FUZZ_CHECK(fuzz::identical(p.value, shifted.value), "first_column does not change the value");
    FUZZ_CHECK(fuzz::all_utf8(p.value), "parsed strings are valid UTF-8");
    // MORSE's layout of the value reads back as the same value
    std::string written;
    socket::append_json(written, p.value);
    const socket::ParamsParse again = socket::parse_params(written);
    FUZZ_CHECK(again.ok, "append_json's text parses: " + written + " -> " + again.error);
    FUZZ_CHECK(fuzz::identical(p.value, again.value),
               "append_json round trip: " + written + " -> " + dump(again.value));
    std::string rewritten;
    socket::append_json(rewritten, again.value);
    FUZZ_CHECK(rewritten == written, "append_json is stable: " + written + " vs " + rewritten);
  }

  // JSON, what today's MORSE clients send, is always accepted, as nlohmann reads it
  // (nlohmann skips a byte order mark, and reads a NUL byte as the end of the text)
  const bool bom = text.substr(0, 3) == "\xEF\xBB\xBF";
  const bool nul = text.find('\0') != std::string_view::npos;
  if (!bom && !nul && !json_nests_deeper_than(text, socket::k_max_depth)) {
    const json reference = json::parse(text, nullptr, /*allow_exceptions=*/false);
    if (!reference.is_discarded()) {
      // refused on purpose: integers beyond 64 bits (nlohmann makes them doubles) and
      // numbers beyond a double (numbers too small for one read 0.0, as nlohmann reads them)
      const bool out_of_range =
          !p.ok && (p.error == "integer out of range" || p.error == "number out of range");
      FUZZ_CHECK(p.ok || out_of_range, "valid JSON is accepted: " + p.error);
      if (p.ok)
        FUZZ_CHECK(fuzz::same_value(p.value, reference),
                   "JSON reads as nlohmann reads it: " + dump(p.value) + " vs " + dump(reference));
    }
  }

  // the transport's UTF-8 check is nlohmann's
  std::size_t bad = 0;
  const bool valid = socket::valid_utf8(text, bad);
  bool nlohmann_valid = true;
  try {
    (void)json(std::string(text)).dump();
  } catch (const json::type_error&) {
    nlohmann_valid = false;
  }
  FUZZ_CHECK(valid == nlohmann_valid, "valid_utf8 agrees with nlohmann");
  if (!valid) {
    FUZZ_CHECK(bad < text.size(), "the first invalid byte is in the text");
    std::size_t before = 0;
    FUZZ_CHECK(socket::valid_utf8(text.substr(0, bad), before),
               "the text before the first invalid byte is valid");
  }
  return 0;
}
