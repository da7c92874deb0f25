// simgate/core/text.h — the small text helpers every layer shares (messages, logs, wire
// formats): join, a client's text quoted for a log line, hex digits. Pure functions; any
// thread.
#ifndef SIMGATE_CORE_TEXT_H_
#define SIMGATE_CORE_TEXT_H_

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace simgate {

// The items with `separator` between them: join({"a", "b", "c"}) is "a, b, c".
inline std::string join(const std::vector<std::string>& items,
                        const std::string& separator = ", ") {
  std::string out;
  for (const auto& item : items) {
    if (!out.empty()) out += separator;
    out += item;
  }
  return out;
}

// `text` as a client sent it, for a log line or an error message: its first `max_bytes`
// (then "..."), control characters shown as '?' (the log is read on terminals), in quotes.
inline std::string quoted_prefix(std::string_view text, std::size_t max_bytes = 80) {
  std::string out(text.substr(0, max_bytes));
  for (char& c : out)
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '?';
  return "'" + out + (text.size() > max_bytes ? "...'" : "'");
}

// The lower-case hex digit of `nibble` (0 to 15).
inline char hex_digit(unsigned nibble) { return "0123456789abcdef"[nibble & 15]; }
// Appends the two hex digits of each byte of `bytes`: append_hex(out, {0x1f}) appends "1f".
inline void append_hex(std::string& out, const std::uint8_t* bytes, std::size_t size) {
  for (std::size_t i = 0; i < size; ++i) {
    out.push_back(hex_digit(bytes[i] >> 4));
    out.push_back(hex_digit(bytes[i]));
  }
}

}  // namespace simgate

#endif  // SIMGATE_CORE_TEXT_H_
