#include "simgate/morse/wire.h"

#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "simgate/core/text.h"

namespace simgate::socket {
namespace {

// The bytes that separate tokens: ' ', '\t', '\r', '\f', '\v' (a table: one load per byte).
constexpr std::array<bool, 256> k_blank_in_line = [] {
  std::array<bool, 256> t{};
  for (unsigned char c : {' ', '\t', '\r', '\f', '\v'}) t[c] = true;
  return t;
}();

bool is_blank_in_line(char c) { return k_blank_in_line[static_cast<unsigned char>(c)]; }

std::size_t skip_blanks(std::string_view line, std::size_t pos) {
  while (pos < line.size() && is_blank_in_line(line[pos])) ++pos;
  return pos;
}

constexpr std::uint64_t k_ones = 0x0101010101010101ull, k_highs = 0x8080808080808080ull;

// The high bit of each byte of `w` below 0x21 (a blank, a control character or a space),
// exact up to the first such byte in memory order (little-endian), which is all we use.
inline std::uint64_t low_bytes(std::uint64_t w) { return (w - k_ones * 0x21) & ~w & k_highs; }

// The end of the token starting at `pos`; ORs its bytes into `bytes` (bit 7 set: not ASCII).
// Eight bytes at a time while a whole word fits: a word whose bytes are all above ' ' holds
// no blank; else the bytes before its first one at or below ' ' (found from the word, with
// no loop) are the token's, and the rest goes byte by byte (that byte is a blank, mostly).
inline std::size_t token_end(std::string_view line, std::size_t pos, unsigned& bytes) {
  if constexpr (std::endian::native == std::endian::little) {
    std::uint64_t seen = 0;  // the token's words, ORed
    while (line.size() - pos >= 8) {
      std::uint64_t w;
      std::memcpy(&w, line.data() + pos, 8);
      const std::uint64_t low = low_bytes(w);
      if (low == 0) {
        seen |= w;
        pos += 8;
        continue;
      }
      const int before = std::countr_zero(low) / 8;  // the token's bytes in this word
      seen |= w & ((std::uint64_t{1} << (8 * before)) - 1);
      pos += static_cast<std::size_t>(before);
      break;
    }
    bytes |= (seen & k_highs) != 0 ? 0x80u : 0u;
  }
  while (pos < line.size() && !is_blank_in_line(line[pos]))
    bytes |= static_cast<unsigned char>(line[pos++]);
  return pos;
}

// token_end for a request's id: `controls` set if the id holds a control character (below
// 0x20, or 0x7f: echoable_id's test, in the same pass). A word's bytes above ' ' can only
// hold 0x7f; the bytes below 0x21 that are no blank are left to the byte loop.
inline std::size_t id_end(std::string_view line, std::size_t pos, bool& controls) {
  const auto has_zero_byte = [](std::uint64_t v) { return (v - k_ones) & ~v & k_highs; };
  if constexpr (std::endian::native == std::endian::little) {
    std::uint64_t dels = 0;  // nonzero once a 0x7f byte was seen
    while (line.size() - pos >= 8) {
      std::uint64_t w;
      std::memcpy(&w, line.data() + pos, 8);
      const std::uint64_t low = low_bytes(w);
      if (low == 0) {
        dels |= has_zero_byte(w ^ (k_ones * 0x7f));
        pos += 8;
        continue;
      }
      const int before = std::countr_zero(low) / 8;
      // the bytes past the token made 0xff, never 0x7f
      dels |= has_zero_byte((w | (~std::uint64_t{0} << (8 * before))) ^ (k_ones * 0x7f));
      pos += static_cast<std::size_t>(before);
      break;
    }
    controls = controls || dels != 0;
  }
  for (; pos < line.size() && !is_blank_in_line(line[pos]); ++pos) {
    const auto c = static_cast<unsigned char>(line[pos]);
    if (c < 0x20 || c == 0x7f) controls = true;
  }
  return pos;
}

void append_u_escape(std::string& out, std::uint32_t unit) {
  char buf[6] = {
      '\\',           'u', hex_digit(unit >> 12), hex_digit(unit >> 8), hex_digit(unit >> 4),
      hex_digit(unit)};
  out.append(buf, 6);
}

// A JSON string with ensure_ascii, like Python's json.dumps.
void append_string(std::string& out, std::string_view s) {
  out += '"';
  std::size_t i = 0;
  while (i < s.size()) {
    // runs of plain printable ASCII are copied in one go
    std::size_t run = i;
    while (run < s.size()) {
      unsigned char c = static_cast<unsigned char>(s[run]);
      if (c < 0x20 || c >= 0x7F || c == '"' || c == '\\') break;
      ++run;
    }
    out.append(s.substr(i, run - i));
    i = run;
    if (i >= s.size()) break;
    unsigned char c = static_cast<unsigned char>(s[i]);
    switch (c) {
      case '"':
        out += "\\\"";
        ++i;
        continue;
      case '\\':
        out += "\\\\";
        ++i;
        continue;
      case '\n':
        out += "\\n";
        ++i;
        continue;
      case '\r':
        out += "\\r";
        ++i;
        continue;
      case '\t':
        out += "\\t";
        ++i;
        continue;
      case '\b':
        out += "\\b";
        ++i;
        continue;
      case '\f':
        out += "\\f";
        ++i;
        continue;
      default: break;
    }
    if (c < 0x20 || c == 0x7F) {
      append_u_escape(out, c);  // control characters and DEL, as Python does
      ++i;
      continue;
    }
    std::uint32_t cp = 0;
    std::size_t n = decode_utf8(s, i, cp);
    if (n == 0) {
      append_u_escape(out, 0xFFFD);  // invalid byte: replacement character
      ++i;
      continue;
    }
    if (cp >= 0x10000) {
      cp -= 0x10000;
      append_u_escape(out, 0xD800 + (cp >> 10));
      append_u_escape(out, 0xDC00 + (cp & 0x3FF));
    } else {
      append_u_escape(out, cp);
    }
    i += n;
  }
  out += '"';
}

// Writes an integer value (number_integer or number_unsigned) at `p`, which has room for
// 20 characters; returns the end.
char* write_integer(char* p, char* end, const json& value) {
  return value.is_number_unsigned() ? std::to_chars(p, end, value.get<std::uint64_t>()).ptr
                                    : std::to_chars(p, end, value.get<std::int64_t>()).ptr;
}

// Writes finite `d` at `p` as Python's repr(float) does, and returns the end: the shortest
// digits that read back as `d` (std::to_chars), laid out in fixed notation when
// 1e-4 <= |d| < 1e16 ("0.0001", "12.5", "1.0") and in scientific notation otherwise
// ("1e-05", "1.5e+16"), with at least two exponent digits. `p` has room for 32 characters.
char* write_repr_double(char* p, double d) {
  char sci[32];  // [-]D[.DDD]e±XX[X]: shortest, the exponent with two digits at least
  const char* const sci_end =
      std::to_chars(sci, sci + sizeof sci, d, std::chars_format::scientific).ptr;
  const char* s = sci;
  if (*s == '-') *p++ = *s++;
  const char* e = sci_end - 4;  // the exponent has two or three digits
  if (*e != 'e') --e;
  int exponent = 0;
  for (const char* q = e + 2; q < sci_end; ++q) exponent = exponent * 10 + (*q - '0');
  if (e[1] == '-') exponent = -exponent;
  if (exponent < -4 || exponent >= 16) {  // Python's scientific layout is to_chars'
    std::memcpy(p, s, static_cast<std::size_t>(sci_end - s));
    return p + (sci_end - s);
  }
  // the significant digits: s[0], then what follows the point
  char digits[20];
  std::size_t n = 0;
  digits[n++] = s[0];
  for (const char* q = s + 2; q < e; ++q) digits[n++] = *q;
  if (exponent < 0) {  // 0.000ddd
    *p++ = '0';
    *p++ = '.';
    for (int k = -1; k > exponent; --k) *p++ = '0';
    std::memcpy(p, digits, n);
    return p + n;
  }
  const std::size_t integer_digits = static_cast<std::size_t>(exponent) + 1;
  if (n <= integer_digits) {  // ddd000.0
    std::memcpy(p, digits, n);
    p += n;
    for (std::size_t k = n; k < integer_digits; ++k) *p++ = '0';
    *p++ = '.';
    *p++ = '0';
    return p;
  }
  std::memcpy(p, digits, integer_digits);  // ddd.ddd
  p += integer_digits;
  *p++ = '.';
  std::memcpy(p, digits + integer_digits, n - integer_digits);
  return p + (n - integer_digits);
}

void append_number(std::string& out, const json& value) {
  if (value.is_number_integer()) {
    char buf[24];
    out.append(buf, write_integer(buf, buf + sizeof buf, value));
  } else {
    double d = value.get<double>();
    if (std::isnan(d))
      out += "NaN";
    else if (std::isinf(d))
      out += d > 0 ? "Infinity" : "-Infinity";
    else {
      char buf[32];
      out.append(buf, write_repr_double(buf, d));
    }
  }
}

}  // namespace

std::size_t decode_utf8(std::string_view s, std::size_t i, std::uint32_t& cp) {
  auto b = [&](std::size_t k) { return static_cast<unsigned char>(s[k]); };
  unsigned char c = b(i);
  std::size_t n;
  if (c < 0x80) {
    cp = c;
    return 1;
  }
  if (c >= 0xC2 && c <= 0xDF) {
    n = 2;
    cp = c & 0x1F;
  } else if (c >= 0xE0 && c <= 0xEF) {
    n = 3;
    cp = c & 0x0F;
  } else if (c >= 0xF0 && c <= 0xF4) {
    n = 4;
    cp = c & 0x07;
  } else
    return 0;
  if (i + n > s.size()) return 0;
  for (std::size_t k = 1; k < n; ++k) {
    if ((b(i + k) & 0xC0) != 0x80) return 0;
    cp = (cp << 6) | (b(i + k) & 0x3F);
  }
  if ((n == 3 && cp < 0x800) || (n == 4 && cp < 0x10000) || cp > 0x10FFFF ||
      (cp >= 0xD800 && cp <= 0xDFFF))
    return 0;
  return n;
}

bool valid_utf8(std::string_view s, std::size_t& bad_offset) {
  std::uint32_t cp;
  for (std::size_t i = 0; i < s.size();) {
    if (static_cast<unsigned char>(s[i]) < 0x80) {
      ++i;
      continue;
    }
    std::size_t n = decode_utf8(s, i, cp);
    if (n == 0) {
      bad_offset = i;
      return false;
    }
    i += n;
  }
  return true;
}

bool echoable_id(std::string_view id) {
  for (char c : id)
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) return false;
  return true;
}

std::optional<std::string_view> parse_auth_line(std::string_view line) {
  constexpr std::string_view k_auth = "auth";
  const std::size_t start = skip_blanks(line, 0);
  std::string_view rest = line.substr(start);
  if (rest.substr(0, k_auth.size()) != k_auth || rest.size() <= k_auth.size() ||
      !is_blank_in_line(rest[k_auth.size()]))
    return std::nullopt;
  std::string_view token = rest.substr(skip_blanks(rest, k_auth.size()));
  while (!token.empty() && is_blank_in_line(token.back())) token.remove_suffix(1);
  return token;
}

RequestLine parse_request_line(std::string_view line) {
  RequestLine r;
  bool id_controls = false;  // ids are echoed verbatim: only control characters are refused
  unsigned name_bytes = 0;   // the names' bytes ORed: non-ASCII names need a UTF-8 check
  const std::size_t id_begin = skip_blanks(line, 0);
  const std::size_t id_stop = id_end(line, id_begin, id_controls);
  if (id_begin == id_stop) return r;  // blank
  r.id = line.substr(id_begin, id_stop - id_begin);
  if (id_controls) [[unlikely]] {
    std::size_t at = 0;  // the first control character
    while (echoable_id(r.id.substr(at, 1))) ++at;
    r.kind = RequestLine::Kind::malformed;
    r.error = "Malformed request! the id contains a control character (byte " +
              std::to_string(static_cast<unsigned char>(r.id[at])) + " at column " +
              std::to_string(id_begin + at + 1) +
              "); ids are echoed in replies, use printable ones";
    r.id = "-";
    return r;
  }

  const std::size_t c_begin = skip_blanks(line, id_stop);
  const std::size_t c_end = token_end(line, c_begin, name_bytes);
  if (c_begin == c_end) {
    r.kind = RequestLine::Kind::malformed;
    r.error =
        "Malformed request! expected '<id> <component> <service> [params]' or '<id> cancel', "
        "got only an id";
    return r;
  }
  r.component = line.substr(c_begin, c_end - c_begin);

  const std::size_t s_begin = skip_blanks(line, c_end);
  const std::size_t s_end = token_end(line, s_begin, name_bytes);
  if (s_begin == s_end) {
    if (r.component == "cancel") {
      r.kind = RequestLine::Kind::cancel;
      return r;
    }
    r.kind = RequestLine::Kind::malformed;
    r.error = "Malformed request! missing the service name after the component at column " +
              std::to_string(c_end + 1) + " (expected '<id> <component> <service> [params]')";
    return r;
  }
  r.service = line.substr(s_begin, s_end - s_begin);

  // the parameters: the rest of the line without surrounding blanks
  const std::size_t p_begin = skip_blanks(line, s_end);
  std::size_t p_end = line.size();
  while (p_end > p_begin && is_blank_in_line(line[p_end - 1])) --p_end;
  r.params = line.substr(p_begin, p_end - p_begin);
  r.params_column = p_begin + 1;
  r.kind = RequestLine::Kind::call;

  // names must be text: say where they are not
  std::size_t bad = 0;
  if (!(name_bytes & 0x80)) return r;
  if (!valid_utf8(r.component, bad)) {
    r.kind = RequestLine::Kind::malformed;
    r.error = "Invalid request syntax: the component name is not valid UTF-8 (column " +
              std::to_string(c_begin + bad + 1) + ")";
  } else if (!valid_utf8(r.service, bad)) {
    r.kind = RequestLine::Kind::malformed;
    r.error = "Invalid request syntax: the service name is not valid UTF-8 (column " +
              std::to_string(s_begin + bad + 1) + ")";
  }
  return r;
}

void append_json(std::string& out, const json& value) {
  switch (value.type()) {
    case json::value_t::null: out += "null"; return;
    case json::value_t::boolean: out += value.get<bool>() ? "true" : "false"; return;
    case json::value_t::string: append_string(out, value.get_ref<const std::string&>()); return;
    case json::value_t::number_integer:
    case json::value_t::number_unsigned:
    case json::value_t::number_float: append_number(out, value); return;
    case json::value_t::array: {  // (the containers themselves: json's iterators cost more)
      out += '[';
      bool first = true;
      for (const json& e : value.get_ref<const json::array_t&>()) {
        if (!first) out += ", ";
        first = false;
        append_json(out, e);
      }
      out += ']';
      return;
    }
    case json::value_t::object: {
      out += '{';
      bool first = true;
      for (const auto& [key, member] : value.get_ref<const json::object_t&>()) {
        if (!first) out += ", ";
        first = false;
        append_string(out, key);
        out += ": ";
        append_json(out, member);
      }
      out += '}';
      return;
    }
    case json::value_t::binary:
    case json::value_t::discarded: out += "null"; return;
  }
}

void append_reply(std::string& out, std::string_view id, std::string_view status,
                  const json* value) {
  // the usual reply (a short id, then no value or an integer) is composed on the stack and
  // appended in one piece
  char line[96];
  const bool integer = value && value->is_number_integer();
  if ((!value || integer) && id.size() + status.size() <= sizeof line - 24) {
    char* p = line;
    std::memcpy(p, id.data(), id.size());
    p += id.size();
    *p++ = ' ';
    std::memcpy(p, status.data(), status.size());
    p += status.size();
    if (integer) {
      *p++ = ' ';
      p = write_integer(p, line + sizeof line, *value);
    }
    *p++ = '\n';
    out.append(line, static_cast<std::size_t>(p - line));
    return;
  }
  out.append(id);
  out += ' ';
  out.append(status);
  if (value) {
    out += ' ';
    append_json(out, *value);
  }
  out += '\n';
}

}  // namespace simgate::socket
