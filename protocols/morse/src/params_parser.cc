#include "simgate/morse/params_parser.h"

#include "simgate/core/text.h"
#include "simgate/morse/wire.h"

#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>

namespace simgate::socket {
namespace {

// Thrown inside the parser only; parse_params() turns it into a ParamsParse.
struct SyntaxError {
  std::string message;  // what was wrong
  std::size_t offset;   // byte offset into the text
};

// The blanks between values: ' ', '\t', '\r', '\n', '\f', '\v' (a table: one load per byte).
constexpr std::array<bool, 256> k_blank = [] {
  std::array<bool, 256> t{};
  for (unsigned char c : {' ', '\t', '\r', '\n', '\f', '\v'}) t[c] = true;
  return t;
}();

bool is_blank(char c) { return k_blank[static_cast<unsigned char>(c)]; }
bool is_digit(char c) { return c >= '0' && c <= '9'; }
bool is_ident(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || is_digit(c) || c == '_';
}

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

void append_utf8(std::string& out, std::uint32_t cp) {
  if (cp < 0x80) {
    out += char(cp);
  } else if (cp < 0x800) {
    out += char(0xC0 | (cp >> 6));
    out += char(0x80 | (cp & 0x3F));
  } else if (cp < 0x10000) {
    out += char(0xE0 | (cp >> 12));
    out += char(0x80 | ((cp >> 6) & 0x3F));
    out += char(0x80 | (cp & 0x3F));
  } else {
    out += char(0xF0 | (cp >> 18));
    out += char(0x80 | ((cp >> 12) & 0x3F));
    out += char(0x80 | ((cp >> 6) & 0x3F));
    out += char(0x80 | (cp & 0x3F));
  }
}

class Parser {
 public:
  explicit Parser(std::string_view text) : text_(text) {}

  // The whole text into `out`; a top-level list or tuple reuses the array `out` holds.
  void parse_all(json& out) {
    skip_blanks();
    if (pos_ == text_.size()) {
      out = nullptr;
      return;
    }
    if (text_[pos_] == '[' || text_[pos_] == '(')
      parse_sequence(0, text_[pos_] == '[' ? ']' : ')', out);
    else
      parse_value(0, out);
    skip_blanks();
    if (pos_ != text_.size())
      fail("unexpected " + describe_here() + " after the end of the parameters");
  }

  // The whole text as values separated by blanks or commas (`0.5 0.2`, `0.5, 0.2`): true,
  // with `out` the array of them, when there are at least two and nothing else.
  bool parse_bare_sequence(json& out) {
    pos_ = 0;
    out = json::array();
    try {
      for (;;) {
        skip_blanks();
        if (pos_ == text_.size()) break;
        parse_value(0, out.emplace_back());
        skip_blanks();
        if (pos_ < text_.size() && text_[pos_] == ',') ++pos_;
      }
    } catch (const SyntaxError&) {
      return false;
    }
    return out.size() >= 2;
  }

 private:
  [[noreturn]] void fail(std::string message) { throw SyntaxError{std::move(message), pos_}; }
  [[noreturn]] void fail_at(std::size_t offset, std::string message) {
    throw SyntaxError{std::move(message), offset};
  }

  // "'x'", "byte 0xff" or "the end of the parameters", for messages.
  std::string describe_here() const {
    if (pos_ >= text_.size()) return "the end of the parameters";
    unsigned char c = static_cast<unsigned char>(text_[pos_]);
    if (c >= 0x20 && c < 0x7F) return std::string("'") + char(c) + "'";
    return std::string("byte 0x") + hex_digit(c >> 4) + hex_digit(c);
  }

  void skip_blanks() {
    while (pos_ < text_.size() && is_blank(text_[pos_])) ++pos_;
  }

  // One value into `out` (built in place: no temporary to move and destroy).
  void parse_value(std::size_t depth, json& out) {
    skip_blanks();
    if (pos_ >= text_.size()) fail("expected a value but found the end of the parameters");
    char c = text_[pos_];
    switch (c) {
      case '[': return parse_sequence(depth, ']', out);
      case '(': return parse_sequence(depth, ')', out);
      case '{': return parse_dict(depth, out);
      case '"':
      case '\'': out = parse_string(); return;
      default: break;
    }
    if (is_digit(c) || c == '-' || c == '+' || c == '.') {
      if (!parse_plain_integer(out)) out = parse_number();
      return;
    }
    if (is_ident(c)) {
      out = parse_word();
      return;
    }
    fail("expected a value but found " + describe_here());
  }
  // into `out`, reusing the array it holds: its elements are overwritten in place
  void parse_sequence(std::size_t depth, char close, json& out) {
    if (depth + 1 > k_max_depth)
      fail("nesting deeper than " + std::to_string(k_max_depth) + " levels");
    const char* kind = close == ']' ? "list" : "tuple";
    ++pos_;  // the opening bracket
    if (!out.is_array()) {
      out = json::array();
      out.get_ref<json::array_t&>().reserve(4);  // most calls have a few arguments: one allocation
    }
    // the elements an array already holds are overwritten in place, the rest dropped at the end
    std::size_t count = 0;
    auto finish = [&] {
      ++pos_;
      auto& elements = out.get_ref<json::array_t&>();
      if (elements.size() > count)
        elements.erase(elements.begin() + std::ptrdiff_t(count), elements.end());
    };
    for (;;) {
      skip_blanks();
      if (pos_ < text_.size() && text_[pos_] == close) return finish();
      auto& elements = out.get_ref<json::array_t&>();
      parse_value(depth + 1, count < elements.size() ? elements[count] : elements.emplace_back());
      ++count;
      skip_blanks();
      if (pos_ < text_.size() && text_[pos_] == ',') {
        ++pos_;
        continue;
      }
      if (pos_ < text_.size() && text_[pos_] == close) return finish();
      fail(std::string("expected ',' or '") + close + "' in " + kind + " but found " +
           describe_here());
    }
  }

  void parse_dict(std::size_t depth, json& out) {
    if (depth + 1 > k_max_depth)
      fail("nesting deeper than " + std::to_string(k_max_depth) + " levels");
    ++pos_;  // '{'
    out = json::object();
    for (;;) {
      skip_blanks();
      if (pos_ < text_.size() && text_[pos_] == '}') {
        ++pos_;
        return;
      }
      // key: a string only (JSON objects have string keys)
      if (pos_ >= text_.size() || (text_[pos_] != '"' && text_[pos_] != '\''))
        fail("expected a string key in dict but found " + describe_here());
      std::string key = parse_string();
      skip_blanks();
      if (pos_ >= text_.size() || text_[pos_] != ':')
        fail("expected ':' after dict key but found " + describe_here());
      ++pos_;
      parse_value(depth + 1, out[key]);  // a repeated key: the last value wins
      skip_blanks();
      if (pos_ < text_.size() && text_[pos_] == ',') {
        ++pos_;
        continue;
      }
      if (pos_ < text_.size() && text_[pos_] == '}') {
        ++pos_;
        return;
      }
      fail("expected ',' or '}' in dict but found " + describe_here());
    }
  }

  // \uHHHH (and a following low surrogate) or \UHHHHHHHH or \xHH; pos_ is on the letter.
  std::uint32_t parse_hex_escape(std::size_t digits, std::size_t escape_start) {
    ++pos_;
    if (pos_ + digits > text_.size()) fail_at(escape_start, "truncated escape sequence");
    std::uint32_t cp = 0;
    for (std::size_t k = 0; k < digits; ++k) {
      int h = hex_value(text_[pos_ + k]);
      if (h < 0) fail_at(escape_start, "invalid hexadecimal digit in escape sequence");
      cp = (cp << 4) | std::uint32_t(h);
    }
    pos_ += digits;
    return cp;
  }

  std::string parse_string() {
    const char quote = text_[pos_];
    const std::size_t start = pos_;
    ++pos_;
    std::string out;
    for (;;) {
      if (pos_ >= text_.size()) fail_at(start, "unterminated string");
      char c = text_[pos_];
      if (c == quote) {
        ++pos_;
        return out;
      }
      if (c == '\\') {
        const std::size_t escape_start = pos_;
        ++pos_;
        if (pos_ >= text_.size()) fail_at(start, "unterminated string");
        char e = text_[pos_];
        switch (e) {
          case 'n':
            out += '\n';
            ++pos_;
            break;
          case 't':
            out += '\t';
            ++pos_;
            break;
          case 'r':
            out += '\r';
            ++pos_;
            break;
          case 'b':
            out += '\b';
            ++pos_;
            break;
          case 'f':
            out += '\f';
            ++pos_;
            break;
          case 'v':
            out += '\v';
            ++pos_;
            break;
          case 'a':
            out += '\a';
            ++pos_;
            break;
          case '0':
            out += '\0';
            ++pos_;
            break;
          case '\\':
            out += '\\';
            ++pos_;
            break;
          case '\'':
            out += '\'';
            ++pos_;
            break;
          case '"':
            out += '"';
            ++pos_;
            break;
          case '/':
            out += '/';
            ++pos_;
            break;
          case 'x': append_utf8(out, parse_hex_escape(2, escape_start)); break;
          case 'U': {
            std::uint32_t cp = parse_hex_escape(8, escape_start);
            if (cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF))
              fail_at(escape_start, "escape sequence is not a valid code point");
            append_utf8(out, cp);
            break;
          }
          case 'u': {
            std::uint32_t cp = parse_hex_escape(4, escape_start);
            if (cp >= 0xD800 && cp <= 0xDBFF) {
              // a high surrogate must be followed by \u and a low surrogate
              if (pos_ + 1 < text_.size() && text_[pos_] == '\\' && text_[pos_ + 1] == 'u') {
                ++pos_;
                std::uint32_t low = parse_hex_escape(4, escape_start);
                if (low < 0xDC00 || low > 0xDFFF)
                  fail_at(escape_start, "high surrogate not followed by a low surrogate");
                cp = 0x10000 + ((cp - 0xD800) << 10) + (low - 0xDC00);
              } else {
                fail_at(escape_start, "high surrogate not followed by a low surrogate");
              }
            } else if (cp >= 0xDC00 && cp <= 0xDFFF) {
              fail_at(escape_start, "lone low surrogate in escape sequence");
            }
            append_utf8(out, cp);
            break;
          }
          default:
            fail_at(escape_start, std::string("unknown escape sequence '\\") +
                                      ((e >= 0x20 && e < 0x7F) ? std::string(1, e) : "?") + "'");
        }
        continue;
      }
      if (static_cast<unsigned char>(c) < 0x20) fail("control character in string");
      std::uint32_t cp = 0;
      std::size_t n = decode_utf8(text_, pos_, cp);
      if (n == 0) fail("invalid UTF-8 in string");
      out.append(text_.substr(pos_, n));
      pos_ += n;
    }
  }

  // The usual argument, a plain decimal integer that fits easily ("42", "-7": up to 18
  // digits, no leading zero, followed by a delimiter), into `out` without the general
  // number parser. False, with nothing consumed, for anything else (parse_number() decides).
  bool parse_plain_integer(json& out) {
    const bool negative = text_[pos_] == '-';
    const std::size_t first = pos_ + (negative ? 1 : 0);
    std::size_t end = first;
    std::int64_t magnitude = 0;
    while (end < text_.size() && end - first < 18 && is_digit(text_[end]))
      magnitude = magnitude * 10 + (text_[end++] - '0');
    const std::size_t digits = end - first;
    if (digits == 0 || digits == 18 || (digits > 1 && text_[first] == '0')) return false;
    if (end < text_.size()) {
      const char next = text_[end];
      if (!is_blank(next) && next != ',' && next != ']' && next != ')' && next != '}') return false;
    }
    pos_ = end;
    const std::int64_t value = negative ? -magnitude : magnitude;
    // an element a refilled call kept from its previous request is overwritten in place
    if (out.is_number_integer() && !out.is_number_unsigned())
      out.get_ref<json::number_integer_t&>() = value;
    else
      out = value;
    return true;
  }

  json parse_number() {
    const std::size_t start = pos_;
    bool negative = false;
    if (text_[pos_] == '+' || text_[pos_] == '-') {
      negative = text_[pos_] == '-';
      ++pos_;
      // -Infinity / +Infinity
      if (text_.substr(pos_, 8) == "Infinity" &&
          (pos_ + 8 == text_.size() || !is_ident(text_[pos_ + 8]))) {
        pos_ += 8;
        return negative ? -std::numeric_limits<double>::infinity()
                        : std::numeric_limits<double>::infinity();
      }
    }
    const std::size_t digits_start = pos_;
    std::size_t int_digits = 0, frac_digits = 0;
    bool is_float = false;
    while (pos_ < text_.size() && is_digit(text_[pos_])) ++pos_, ++int_digits;
    if (pos_ < text_.size() && text_[pos_] == '.') {
      is_float = true;
      ++pos_;
      while (pos_ < text_.size() && is_digit(text_[pos_])) ++pos_, ++frac_digits;
    }
    if (int_digits + frac_digits == 0) {
      pos_ = start;
      fail("malformed number");
    }
    if (int_digits > 1 && text_[digits_start] == '0' && !is_float &&
        (pos_ >= text_.size() || (text_[pos_] != 'e' && text_[pos_] != 'E'))) {
      pos_ = start;
      fail("malformed number: leading zeros are not allowed");
    }
    if (pos_ < text_.size() && (text_[pos_] == 'e' || text_[pos_] == 'E')) {
      is_float = true;
      ++pos_;
      if (pos_ < text_.size() && (text_[pos_] == '+' || text_[pos_] == '-')) ++pos_;
      std::size_t exp_digits = 0;
      while (pos_ < text_.size() && is_digit(text_[pos_])) ++pos_, ++exp_digits;
      if (exp_digits == 0) {
        pos_ = start;
        fail("malformed number: missing exponent digits");
      }
    }
    if (pos_ < text_.size() && is_ident(text_[pos_]))
      fail("malformed number: unexpected " + describe_here());
    std::string_view body = text_.substr(digits_start, pos_ - digits_start);

    if (!is_float) {
      std::uint64_t magnitude = 0;
      auto [end, ec] = std::from_chars(body.data(), body.data() + body.size(), magnitude);
      if (ec == std::errc() && end == body.data() + body.size()) {
        if (!negative) {
          if (magnitude <= std::uint64_t(std::numeric_limits<std::int64_t>::max()))
            return std::int64_t(magnitude);
          return magnitude;
        }
        if (magnitude <= std::uint64_t(std::numeric_limits<std::int64_t>::max()) + 1)
          return magnitude == 0 ? std::int64_t(0) : std::int64_t(0 - magnitude);
      }
      fail_at(start, "integer out of range");
    }
    double value = 0;
    auto [end, ec] = std::from_chars(body.data(), body.data() + body.size(), value);
    if (ec == std::errc::result_out_of_range && end == body.data() + body.size()) {
      // beyond a double: too large is an error; too small is 0.0 (or a subnormal), as
      // Python's float() and json.loads read it (`[1e-400]`). strtod tells them apart (the
      // body is well formed, and simgate keeps the C locale)
      value = std::strtod(std::string(body).c_str(), nullptr);
      if (std::isinf(value)) fail_at(start, "number out of range");
      return negative ? -value : value;
    }
    if (ec != std::errc() || end != body.data() + body.size()) fail_at(start, "malformed number");
    return negative ? -value : value;
  }

  json parse_word() {
    const std::size_t start = pos_;
    while (pos_ < text_.size() && is_ident(text_[pos_])) ++pos_;
    std::string_view word = text_.substr(start, pos_ - start);
    if (word == "True" || word == "true") return true;
    if (word == "False" || word == "false") return false;
    if (word == "None" || word == "null") return nullptr;
    if (word == "NaN") return std::numeric_limits<double>::quiet_NaN();
    if (word == "Infinity") return std::numeric_limits<double>::infinity();
    fail_at(start, "unknown name '" + std::string(word.substr(0, 40)) +
                       "' (expected a number, a quoted string, True, False or None)");
  }

  std::string_view text_;  // the parameters text
  std::size_t pos_ = 0;    // next byte to read
};

}  // namespace

bool parse_params_into(std::string_view text, std::size_t first_column, json& value,
                       ParamsParse& error) {
  Parser parser(text);
  try {
    parser.parse_all(value);
    return true;
  } catch (const SyntaxError& e) {
    error.ok = false;
    error.error = e.message;
    error.column = first_column + e.offset;
  }
  // bare values typed without brackets (telnet users): say which list they meant
  error.example.clear();
  json values;
  if (Parser(text).parse_bare_sequence(values)) append_json(error.example, values);
  return false;
}

ParamsParse parse_params(std::string_view text, std::size_t first_column) {
  ParamsParse result;
  result.ok = parse_params_into(text, first_column, result.value, result);
  return result;
}

}  // namespace simgate::socket
