// fast_path.cc — parse_request_fast (protocol.h): the common shape of a JSON-RPC request
// read in one pass, in place, without a DOM for the envelope.
#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include "simgate/core/text.h"
#include "simgate/jsonrpc/protocol.h"

namespace simgate::jsonrpc {

namespace {

// Bytes a plain string may hold: printable ASCII except the quote and the backslash.
constexpr std::array<bool, 256> k_plain = [] {
  std::array<bool, 256> table{};
  for (int c = 0x20; c <= 0x7e; ++c) table[static_cast<std::size_t>(c)] = c != '"' && c != '\\';
  return table;
}();

// One past the last byte of the plain run that starts at `p` (k_plain), at most `end`: eight
// bytes at a time while a whole word fits (a word holding no quote, backslash, control or
// non-ASCII byte is all plain), then byte by byte.
const char* skip_plain(const char* p, const char* end) {
  constexpr std::uint64_t ones = 0x0101010101010101ull, highs = 0x8080808080808080ull;
  const auto has_zero_byte = [](std::uint64_t v) { return (v - ones) & ~v & highs; };
  while (end - p >= 8) {
    std::uint64_t w;
    std::memcpy(&w, p, 8);
    const std::uint64_t special =
        has_zero_byte(w ^ (ones * '"')) | has_zero_byte(w ^ (ones * '\\')) |
        has_zero_byte(w ^ (ones * 0x7f)) | ((w - ones * 0x20) & ~w & highs) |  // a byte < 0x20
        (w & highs);                                                           // a byte >= 0x80
    if (special) break;
    p += 8;
  }
  while (p < end && k_plain[static_cast<unsigned char>(*p)]) ++p;
  return p;
}

// A one-pass reader of the request shapes parse_request_fast accepts. Every function
// returns false as soon as the input leaves that shape (the caller then gives up).
class FastReader {
 public:
  explicit FastReader(std::string_view text) : p_(text.data()), end_(text.data() + text.size()) {}

  void skip_ws() {
    // compact JSON (what clients send) has none: one comparison in the common case
    if (p_ < end_ && static_cast<unsigned char>(*p_) > ' ') return;
    while (p_ < end_ && (*p_ == ' ' || *p_ == '\t' || *p_ == '\n' || *p_ == '\r')) ++p_;
  }
  bool at_end() const { return p_ == end_; }
  const char* position() const { return p_; }
  // The next character after white space, consumed if it is `c`.
  bool eat(char c) {
    skip_ws();
    if (p_ < end_ && *p_ == c) {
      ++p_;
      return true;
    }
    return false;
  }
  char peek() {
    skip_ws();
    return p_ < end_ ? *p_ : '\0';
  }

  // A string of printable ASCII without escapes: its content is the text between the
  // quotes, exactly as json::parse reads it and dump() writes it back.
  bool plain_string(std::string_view& s) {
    skip_ws();
    if (p_ >= end_ || *p_ != '"') return false;
    const char* begin = ++p_;
    p_ = skip_plain(p_, end_);
    if (p_ >= end_ || *p_ != '"') return false;
    s = std::string_view(begin, static_cast<std::size_t>(p_ - begin));
    ++p_;
    return true;
  }

  // A number as json::parse stores it: non-negative integers unsigned, negative ones
  // signed (up to 18 digits: no overflow), others double (finite, correctly rounded).
  bool number(json& value) {
    skip_ws();
    const char* begin = p_;
    bool negative = false;
    if (p_ < end_ && *p_ == '-') {
      negative = true;
      ++p_;
    }
    // int part: 0 | [1-9][0-9]*, its value read on the way (used if it is all)
    const char* digits = p_;
    std::uint64_t magnitude = 0;
    if (p_ >= end_ || !is_digit(*p_)) return false;
    if (*p_ == '0')
      ++p_;
    else
      for (; p_ < end_ && is_digit(*p_); ++p_)
        magnitude = magnitude * 10 + static_cast<std::uint64_t>(*p_ - '0');  // wraps past 19
    const std::size_t int_digits = static_cast<std::size_t>(p_ - digits);
    bool integer = true;
    if (p_ < end_ && *p_ == '.') {
      integer = false;
      ++p_;
      if (p_ >= end_ || !is_digit(*p_)) return false;
      while (p_ < end_ && is_digit(*p_)) ++p_;
    }
    if (p_ < end_ && (*p_ == 'e' || *p_ == 'E')) {
      integer = false;
      ++p_;
      if (p_ < end_ && (*p_ == '+' || *p_ == '-')) ++p_;
      if (p_ >= end_ || !is_digit(*p_)) return false;
      while (p_ < end_ && is_digit(*p_)) ++p_;
    }
    if (integer) {
      if (int_digits > 18) return false;
      if (negative)
        set(value, static_cast<json::number_integer_t>(-static_cast<std::int64_t>(magnitude)));
      else
        set(value, static_cast<json::number_unsigned_t>(magnitude));
      return true;
    }
    double d = 0;
    auto r = std::from_chars(begin, p_, d);
    if (r.ec != std::errc() || r.ptr != p_ || !std::isfinite(d)) return false;
    set(value, static_cast<json::number_float_t>(d));
    return true;
  }

  // A literal (true, false, null) or a number or a plain string.
  // `value` is overwritten in place: a value of the same type (an element of an array kept
  // from an earlier request) keeps its storage, nothing is built and destroyed.
  bool scalar(json& value) {
    const char c = peek();
    if (c == '"') {
      std::string_view s;
      if (!plain_string(s)) return false;
      if (value.is_string())
        value.get_ref<json::string_t&>().assign(s);
      else
        value = std::string(s);
      return true;
    }
    if (c == 't' || c == 'f') {
      const bool b = c == 't';
      if (!consume(b ? "true" : "false")) return false;
      set(value, static_cast<json::boolean_t>(b));
      return true;
    }
    if (c == 'n') {
      if (!consume("null")) return false;
      if (!value.is_null()) value = nullptr;
      return true;
    }
    return number(value);
  }

  // Consumes `text` if the input continues with exactly it.
  bool consume(std::string_view text) {
    if (static_cast<std::size_t>(end_ - p_) < text.size() ||
        std::memcmp(p_, text.data(), text.size()) != 0)
      return false;
    p_ += text.size();
    return true;
  }

  // params: an array or an object of scalars, or any array/object that json::parse accepts
  // (parsed from its own text) when nested no deeper than `max_depth` - 1.
  bool params(json& value, std::size_t max_depth) {
    const char* begin = (skip_ws(), p_);
    if (flat_container(value)) return true;
    p_ = begin;
    const char* end = container_end(max_depth);
    if (!end) return false;
    try {
      value = json::parse(begin, end);
    } catch (const json::exception&) {
      return false;
    }
    p_ = end;
    return true;
  }

 private:
  static bool is_digit(char c) { return c >= '0' && c <= '9'; }

  // value = v, in place when value already holds a T (by its type: get_ptr<number_integer_t*>
  // also answers for an unsigned value)
  template <class T>
  static void set(json& value, T v) {
    constexpr json::value_t type =
        std::is_same_v<T, json::boolean_t>           ? json::value_t::boolean
        : std::is_same_v<T, json::number_unsigned_t> ? json::value_t::number_unsigned
        : std::is_same_v<T, json::number_integer_t>  ? json::value_t::number_integer
                                                     : json::value_t::number_float;
    if (value.type() == type)
      *value.get_ptr<T*>() = v;
    else
      value = v;
  }

  bool flat_container(json& value) {
    if (eat('[')) {
      if (!value.is_array()) {
        value = json::array();
        value.get_ref<json::array_t&>().reserve(4);  // no regrowth for the usual few arguments
      }
      // an array kept from an earlier request (release_params) is overwritten element by
      // element, in place: no value built or destroyed for an argument of the same type
      auto& elements = value.get_ref<json::array_t&>();
      std::size_t n = 0;
      if (!eat(']')) {
        do {
          if (n == elements.size()) elements.emplace_back();
          if (!scalar(elements[n++])) return false;
        } while (eat(','));
        if (!eat(']')) return false;
      }
      elements.erase(elements.begin() + static_cast<std::ptrdiff_t>(n), elements.end());
      return true;
    }
    if (eat('{')) {
      value = json::object();
      if (eat('}')) return true;
      do {
        std::string_view key;
        json element;
        if (!plain_string(key) || !eat(':') || !scalar(element)) return false;
        // a repeated key: the last wins, as in json::parse
        value[std::string(key)] = std::move(element);
      } while (eat(','));
      return eat('}');
    }
    return false;
  }

  // Where the array or object at p_ ends (one past its closing bracket), or null when it
  // does not close or nests deeper than max_depth - 1 (the envelope is one more level).
  const char* container_end(std::size_t max_depth) const {
    if (p_ >= end_ || (*p_ != '[' && *p_ != '{')) return nullptr;
    std::size_t depth = 0;
    bool in_string = false;
    bool escaped = false;
    for (const char* q = p_; q < end_; ++q) {
      const char c = *q;
      if (in_string) {
        if (escaped)
          escaped = false;
        else if (c == '\\')
          escaped = true;
        else if (c == '"')
          in_string = false;
        continue;
      }
      if (c == '"') {
        in_string = true;
      } else if (c == '[' || c == '{') {
        if (++depth + 1 > max_depth) return nullptr;
      } else if (c == ']' || c == '}') {
        if (--depth == 0) return q + 1;
      }
    }
    return nullptr;
  }

  const char* p_;    // next character
  const char* end_;  // end of the text
};

}  // namespace

bool parse_request_fast(std::string_view line, std::size_t max_depth, Request& out) {
  FastReader in(line);
  if (!in.eat('{')) return false;
  bool has_version = false, has_method = false, has_params = false;
  out.has_id = false;
  out.id_text.clear();
  // out.id and out.params are refilled in place (params' array reused), nulled at the end
  // when absent; the members, each once, are named in plain text (anything else, an
  // escaped name included, goes to the full parser)
  enum class Member { version, method, id, params };
  do {
    in.skip_ws();
    Member key;
    if (in.consume(R"("jsonrpc")"))
      key = Member::version;
    else if (in.consume(R"("method")"))
      key = Member::method;
    else if (in.consume(R"("id")"))
      key = Member::id;
    else if (in.consume(R"("params")"))
      key = Member::params;
    else
      return false;
    if (!in.eat(':')) return false;
    if (key == Member::version) {
      if (has_version || (in.skip_ws(), !in.consume(R"("2.0")"))) return false;
      has_version = true;
    } else if (key == Member::method) {
      std::string_view method;
      if (has_method || !in.plain_string(method)) return false;
      assign_text(out.method, method);
      has_method = true;
    } else if (key == Member::id) {
      if (out.has_id) return false;
      const char c = in.peek();
      const char* begin = in.position();
      if (c == '"') {
        if (!in.scalar(out.id)) return false;
      } else if (c == 'n' || c == '-' || (c >= '0' && c <= '9')) {
        if (!in.scalar(out.id) || !(out.id.is_null() || out.id.is_number_integer())) return false;
      } else {
        return false;
      }
      // its text as sent is dump(id): a plain string, an integer without leading zeros, null
      // (but for "-0", which dump() writes "0")
      const std::string_view text(begin, static_cast<std::size_t>(in.position() - begin));
      assign_text(out.id_text, text == "-0" ? std::string_view("0") : text);
      out.has_id = true;
    } else {
      const char c = in.peek();
      if (has_params || (c != '[' && c != '{') || !in.params(out.params, max_depth)) return false;
      has_params = true;
    }
  } while (in.eat(','));
  if (!in.eat('}')) return false;
  in.skip_ws();
  if (!in.at_end() || !has_version || !has_method) return false;
  if (!has_params) out.params = nullptr;
  if (!out.has_id && !out.id.is_null()) out.id = nullptr;
  return true;
}

}  // namespace simgate::jsonrpc
