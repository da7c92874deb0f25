// simgate/core/text.h — the small text helpers every layer shares (messages, logs, wire
// formats): join, a client's text quoted for a log line, hex digits, short texts compared
// and copied into kept strings on the hot path. Pure functions; any thread.
#ifndef SIMGATE_CORE_TEXT_H_
#define SIMGATE_CORE_TEXT_H_

#include <cstddef>
#include <cstdint>
#include <cstring>
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

// a == b, for the hot path's short names (a component, a service: compared with the kept
// ones on every request): up to 16 bytes in two overlapping word compares, inlined, where
// std::string's == calls memcmp (about 50 instructions a compare).
inline bool same_text(std::string_view a, std::string_view b) {
  const std::size_t n = a.size();
  if (n != b.size()) return false;
  const char* p = a.data();
  const char* q = b.data();
  if (n >= 8) {
    if (n > 16) return std::memcmp(p, q, n) == 0;
    std::uint64_t p1, p2, q1, q2;
    std::memcpy(&p1, p, 8);
    std::memcpy(&p2, p + n - 8, 8);
    std::memcpy(&q1, q, 8);
    std::memcpy(&q2, q + n - 8, 8);
    return ((p1 ^ q1) | (p2 ^ q2)) == 0;
  }
  if (n >= 4) {
    std::uint32_t p1, p2, q1, q2;
    std::memcpy(&p1, p, 4);
    std::memcpy(&p2, p + n - 4, 4);
    std::memcpy(&q1, q, 4);
    std::memcpy(&q2, q + n - 4, 4);
    return ((p1 ^ q1) | (p2 ^ q2)) == 0;
  }
  for (std::size_t i = 0; i < n; ++i)
    if (p[i] != q[i]) return false;
  return true;
}

// dest = text, for the hot path's kept strings (a request's method, its id, a table's key):
// they hold a text of about the same length from the last request, so this is a length
// change within the capacity and a copy inlined for up to 16 bytes, where std::string's
// assign() runs its general replace (about 70 instructions with its memcpy call).
// `text` must not point into `dest`.
inline void assign_text(std::string& dest, std::string_view text) {
  const std::size_t n = text.size();
  if (n > dest.capacity()) [[unlikely]] {
    dest.assign(text);
    return;
  }
  dest.resize(n);  // no allocation: within the capacity
  char* d = dest.data();
  const char* s = text.data();
  if (n >= 8 && n <= 16) {  // two 8-byte copies that overlap when n < 16
    std::uint64_t head, tail;
    std::memcpy(&head, s, 8);
    std::memcpy(&tail, s + n - 8, 8);
    std::memcpy(d, &head, 8);
    std::memcpy(d + n - 8, &tail, 8);
  } else if (n >= 4 && n < 8) {
    std::uint32_t head, tail;
    std::memcpy(&head, s, 4);
    std::memcpy(&tail, s + n - 4, 4);
    std::memcpy(d, &head, 4);
    std::memcpy(d + n - 4, &tail, 4);
  } else if (n > 16) {
    std::memcpy(d, s, n);
  } else {
    for (std::size_t i = 0; i < n; ++i) d[i] = s[i];
  }
}

}  // namespace simgate

#endif  // SIMGATE_CORE_TEXT_H_
