#include "simgate/core/config.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <utility>

#include "simgate/core/suggest.h"

namespace simgate {

namespace {

// The preview's size: at most this many characters of the value's text.
constexpr std::size_t k_preview_chars = 60;

// Shortens `text` to `size` bytes without splitting a UTF-8 sequence.
void cut_utf8(std::string& text, std::size_t size) {
  if (text.size() <= size) return;
  while (size > 0 && (static_cast<unsigned char>(text[size]) & 0xC0) == 0x80) --size;
  text.resize(size);
}

// Appends `s` as a JSON string, escaped as dump() does; a long one only in part: its first
// `limit` bytes or more (enough to fill the preview; the rest could never be shown).
void append_string_preview(const std::string& s, std::string& out, std::size_t limit) {
  if (s.size() <= limit + 4) {
    out += json(s).dump(-1, ' ', false, json::error_handler_t::replace);
    return;
  }
  std::string head = s.substr(0, limit + 5);
  cut_utf8(head, limit + 4);  // backs off at most 3 bytes: head keeps more than `limit`
  std::string quoted = json(head).dump(-1, ' ', false, json::error_handler_t::replace);
  quoted.pop_back();  // the string goes on: no closing quote (the preview is cut before it)
  out += quoted;
}

// Appends value's compact dump() to `out` until `out` holds more than `limit` characters,
// then stops (returns false). Every call writes at least one character before it recurses,
// so recursion is at most limit + 1 deep and the work is O(limit) whatever the value.
bool append_preview(const json& value, std::string& out, std::size_t limit) {
  if (out.size() > limit) return false;
  switch (value.type()) {
    case json::value_t::array: {
      out += '[';
      bool first = true;
      for (const auto& element : value) {
        if (!first) out += ',';
        first = false;
        if (!append_preview(element, out, limit)) return false;
      }
      out += ']';
      break;
    }
    case json::value_t::object: {
      out += '{';
      bool first = true;
      for (auto it = value.begin(); it != value.end(); ++it) {
        if (!first) out += ',';
        first = false;
        append_string_preview(it.key(), out, limit);
        out += ':';
        if (!append_preview(it.value(), out, limit)) return false;
      }
      out += '}';
      break;
    }
    case json::value_t::string:
      append_string_preview(value.get_ref<const std::string&>(), out, limit);
      break;
    default:  // a scalar: its text is short
      out += value.dump(-1, ' ', false, json::error_handler_t::replace);
      break;
  }
  return out.size() <= limit;
}

}  // namespace

std::string json_preview(const json& value) {
  std::string text;
  text.reserve(k_preview_chars + 8);
  append_preview(value, text, k_preview_chars);
  if (text.size() > k_preview_chars) {
    cut_utf8(text, k_preview_chars - 3);
    text += "...";
  }
  return text;
}

std::string describe_json(const json& value) {
  std::string text;
  switch (value.type()) {
    case json::value_t::null: return "null";
    case json::value_t::boolean:
      return std::string("boolean ") + (value.get<bool>() ? "true" : "false");
    case json::value_t::string: text = "string "; break;
    case json::value_t::number_integer:
    case json::value_t::number_unsigned:
    case json::value_t::number_float: text = "number "; break;
    case json::value_t::array: text = "array "; break;
    case json::value_t::object: text = "object "; break;
    default: return "invalid value";
  }
  return text + json_preview(value);
}

bool json_nests_deeper_than(std::string_view text, std::size_t max_depth) noexcept {
  std::size_t depth = 0;
  bool in_string = false;
  bool escaped = false;
  for (char c : text) {
    if (in_string) {
      // inside a string only the closing quote matters
      if (escaped)
        escaped = false;
      else if (c == '\\')
        escaped = true;
      else if (c == '"')
        in_string = false;
      continue;
    }
    switch (c) {
      case '"': in_string = true; break;
      case '[':
      case '{':
        if (++depth > max_depth) return true;
        break;
      case ']':
      case '}':
        if (depth > 0) --depth;
        break;
      default: break;
    }
  }
  return false;
}

namespace {

// Streams a document through nlohmann's (iterative) SAX parser, keeping the JSON path of the
// value being read, and stops at the first problem: nesting deeper than max_depth, a number
// beyond a double, a syntax error. Builds nothing.
class ConfigScanner final : public nlohmann::json_sax<json> {
 public:
  ConfigScanner(std::string_view text, std::size_t max_depth)
      : text_(text), max_depth_(max_depth) {}

  // The problem found (empty when the text is a valid document), and the byte offset it
  // points at.
  const std::string& error() const { return error_; }
  std::size_t error_offset() const { return error_offset_; }

  bool null() override { return value(); }
  bool boolean(bool) override { return value(); }
  bool number_integer(number_integer_t) override { return value(); }
  bool number_unsigned(number_unsigned_t) override { return value(); }
  bool number_float(number_float_t, const string_t&) override { return value(); }
  bool string(string_t&) override { return value(); }
  bool binary(binary_t&) override { return value(); }
  bool start_object(std::size_t) override { return open(false); }
  bool key(string_t& key) override {
    frames_.back().key = key;
    return true;
  }
  bool end_object() override { return close(); }
  bool start_array(std::size_t) override { return open(true); }
  bool end_array() override { return close(); }

  bool parse_error(std::size_t position, const std::string& last_token,
                   const nlohmann::detail::exception& ex) override {
    // `position` counts the bytes read, the offending one included (one past the end at the
    // end of the text)
    if (ex.id == 406) {  // out_of_range: a number beyond a double, pointed at from its start
      error_offset_ = position >= last_token.size() ? position - last_token.size() : 0;
      error_ =
          path() +
          ": expected a number a double can hold (at most about 1.8e308 in magnitude), found " +
          last_token;
    } else {
      // the byte that made it fail (nlohmann's token string is not the token's text: it
      // keeps what came before an invalid literal and writes control characters as <U+000A>)
      error_offset_ = position > 0 ? position - 1 : 0;
      error_ = path() + ": invalid JSON: " + syntax_error(ex.what());
    }
    return false;
  }

 private:
  struct Frame {
    bool array = false;              // else an object
    std::size_t index = 0;           // arrays: the element being read
    std::optional<std::string> key;  // objects: the member being read (none between members)
  };

  // A value was read: the path goes back to its container until the next key or element.
  bool value() {
    if (frames_.empty()) return true;
    if (frames_.back().array) {
      ++frames_.back().index;
    } else {
      frames_.back().key.reset();
    }
    return true;
  }
  bool open(bool array) {
    if (frames_.size() >= max_depth_) {
      // the bracket just read: the scanner has consumed it
      error_ = path(4) + ": expected at most " + std::to_string(max_depth_) +
               " levels of nested arrays and objects, found deeper nesting";
      error_offset_ = too_deep_bracket();
      return false;
    }
    frames_.push_back(Frame{array, 0, std::nullopt});
    return true;
  }
  bool close() {
    frames_.pop_back();
    return value();
  }

  // "scene.timestep", "robots[0].components[1]", "configuration" for the document; after
  // `max_segments` keys and indices, "..." (the path of a too-deep value is as long as it is deep).
  std::string path(std::size_t max_segments = SIZE_MAX) const {
    std::string out;
    for (std::size_t i = 0; i < frames_.size(); ++i) {
      const Frame& f = frames_[i];
      if (i == max_segments) {
        out += "...";
        break;
      }
      if (f.array) {
        out += "[" + std::to_string(f.index) + "]";
      } else if (f.key) {
        out += (out.empty() ? "" : ".") + *f.key;
      }
    }
    if (out.empty() || out.front() == '[') out = "configuration" + out;
    return out;
  }

  // nlohmann's "[json.exception.parse_error.101] parse error at line 1, column 9: syntax
  // error while parsing object key - unexpected '}'; expected string literal" as "expected
  // string literal, found '}' (while parsing object key)"; its position is the caller's.
  static std::string syntax_error(std::string what) {
    const std::size_t syntax = what.find("syntax error ");
    if (syntax == std::string::npos) {
      const std::size_t bracket = what.find("] ");
      return bracket == std::string::npos ? what : what.substr(bracket + 2);
    }
    std::string rest = what.substr(syntax + 13);  // "[while parsing C ]- E[; expected X]"
    std::string context;
    if (rest.starts_with("while parsing ")) {
      const std::size_t dash = rest.find(" - ");
      context = rest.substr(14, dash == std::string::npos ? std::string::npos : dash - 14);
      rest = dash == std::string::npos ? "" : rest.substr(dash + 3);
    } else if (rest.starts_with("- ")) {
      rest = rest.substr(2);
    }
    std::string expected;
    if (const std::size_t at = rest.rfind("; expected "); at != std::string::npos) {
      expected = rest.substr(at + 11);
      rest = rest.substr(0, at);
    }
    // "unexpected <token>", or the lexer's "<what>; last read: '<text>'"
    std::string found = rest, details;
    if (rest.starts_with("unexpected ")) {
      found = rest.substr(11);
    } else if (const std::size_t read = rest.find("; last read: "); read != std::string::npos) {
      found = rest.substr(0, read);
      details = rest.substr(read + 2);
    }
    if (!context.empty())
      details += (details.empty() ? "" : "; ") + std::string("while parsing ") + context;
    return (expected.empty() ? "found " : "expected " + expected + ", found ") + found +
           (details.empty() ? "" : " (" + details + ")");
  }

  // The offset of the bracket that opens level max_depth + 1 (the SAX interface gives no
  // positions): counted as json_nests_deeper_than counts, once, on failure.
  std::size_t too_deep_bracket() const {
    std::size_t depth = 0;
    bool in_string = false, escaped = false;
    for (std::size_t i = 0; i < text_.size(); ++i) {
      char c = text_[i];
      if (in_string) {
        if (escaped)
          escaped = false;
        else if (c == '\\')
          escaped = true;
        else if (c == '"')
          in_string = false;
        continue;
      }
      if (c == '"')
        in_string = true;
      else if (c == '[' || c == '{') {
        if (++depth > max_depth_) return i;
      } else if ((c == ']' || c == '}') && depth > 0) {
        --depth;
      }
    }
    return text_.size();
  }

  std::string_view text_;         // the document
  std::size_t max_depth_;         // deepest nesting accepted
  std::vector<Frame> frames_;     // the containers open at the current value
  std::string error_;             // the problem found, if any
  std::size_t error_offset_ = 0;  // the byte it points at
};

// Line and column (both from 1, the column in bytes) of byte `offset` of `text`.
std::pair<std::size_t, std::size_t> line_and_column(std::string_view text, std::size_t offset) {
  const std::string_view before = text.substr(0, std::min(offset, text.size()));
  const std::size_t line =
      1 + static_cast<std::size_t>(std::count(before.begin(), before.end(), '\n'));
  const std::size_t line_start =
      before.rfind('\n') == std::string_view::npos ? 0 : before.rfind('\n') + 1;
  return {line, before.size() - line_start + 1};
}

}  // namespace

json parse_config_text(std::string_view text, std::size_t max_depth) {
  // nlohmann's parser ends the document at a NUL byte: what follows would be ignored
  // (issue #17, item 9). A text file has none.
  if (const std::size_t nul = text.find('\0'); nul != std::string_view::npos) {
    const auto [line, column] = line_and_column(text, nul);
    throw ConfigTextError("configuration: expected a text file, found a NUL byte", line, column);
  }
  ConfigScanner scanner(text, max_depth);
  if (!json::sax_parse(text.begin(), text.end(), &scanner) || !scanner.error().empty()) {
    const auto [line, column] = line_and_column(text, scanner.error_offset());
    throw ConfigTextError(
        scanner.error().empty() ? std::string("configuration: invalid JSON") : scanner.error(),
        line, column);
  }
  // known to be valid and shallow: building, copying and dumping it recurse little
  return json::parse(text.begin(), text.end());
}

ConfigObject::ConfigObject(const json& value, std::string path)
    : value_(value), path_(std::move(path)) {
  if (!value_.is_object())
    throw ConfigError((path_.empty() ? std::string("configuration") : path_) +
                      ": expected an object, found " + describe_json(value_));
}

bool ConfigObject::has(const std::string& key) const { return value_.contains(key); }

std::string ConfigObject::path_of(const std::string& key) const {
  return path_.empty() ? key : path_ + "." + key;
}

const json* ConfigObject::find(const std::string& key) {
  used_.insert(key);
  auto it = value_.find(key);
  return it == value_.end() ? nullptr : &*it;
}

void ConfigObject::fail(const std::string& key, const std::string& expected) const {
  auto it = value_.find(key);
  std::string found = it == value_.end() ? "nothing" : describe_json(*it);
  throw ConfigError(path_of(key) + ": expected " + expected + ", found " + found);
}

std::string ConfigObject::get_string(const std::string& key, const std::string& fallback) {
  const json* v = find(key);
  if (!v) return fallback;
  if (!v->is_string()) fail(key, "a string");
  return v->get<std::string>();
}

std::string ConfigObject::required_string(const std::string& key) {
  const json* v = find(key);
  if (!v || !v->is_string() || v->get<std::string>().empty()) fail(key, "a non-empty string");
  return v->get<std::string>();
}

long long ConfigObject::get_int(const std::string& key, long long fallback, long long min,
                                long long max) {
  const json* v = find(key);
  if (!v) return fallback;
  std::string expected = "an integer from " + std::to_string(min) + " to " + std::to_string(max);
  if (!v->is_number_integer()) fail(key, expected);
  long long n = v->is_number_unsigned() && v->get<unsigned long long>() > (unsigned long long)max
                    ? max + 1
                    : v->get<long long>();
  if (n < min || n > max) fail(key, expected);
  return n;
}

double ConfigObject::get_number(const std::string& key, double fallback, double min, double max) {
  const json* v = find(key);
  if (!v) return fallback;
  std::ostringstream expected;
  expected << "a number from " << min << " to " << max;
  if (!v->is_number()) fail(key, expected.str());
  double n = v->get<double>();
  if (!std::isfinite(n) || n < min || n > max) fail(key, expected.str());
  return n;
}

bool ConfigObject::get_bool(const std::string& key, bool fallback) {
  const json* v = find(key);
  if (!v) return fallback;
  if (!v->is_boolean()) fail(key, "true or false");
  return v->get<bool>();
}

std::string ConfigObject::get_choice(const std::string& key, const std::string& fallback,
                                     const std::vector<std::string>& choices) {
  std::string expected = "one of";
  for (std::size_t i = 0; i < choices.size(); ++i)
    expected += (i ? ", \"" : " \"") + choices[i] + "\"";
  const json* v = find(key);
  if (!v) return fallback;
  if (!v->is_string()) fail(key, expected);
  const std::string& text = v->get_ref<const std::string&>();
  if (std::find(choices.begin(), choices.end(), text) == choices.end())
    throw ConfigError(path_of(key) + ": expected " + expected + ", found " + describe_json(*v) +
                      did_you_mean(text, choices));
  return v->get<std::string>();
}

std::optional<json> ConfigObject::get_json(const std::string& key) {
  const json* v = find(key);
  if (!v) return std::nullopt;
  return *v;
}

std::optional<ConfigObject> ConfigObject::get_object(const std::string& key) {
  const json* v = find(key);
  if (!v) return std::nullopt;
  if (!v->is_object()) fail(key, "an object");
  return ConfigObject(*v, path_of(key));
}

void ConfigObject::finish() const {
  std::vector<std::string> known(used_.begin(), used_.end());
  allow_only(known);
}

void ConfigObject::allow_only(const std::vector<std::string>& allowed) const {
  std::vector<std::string> errors;
  for (auto it = value_.begin(); it != value_.end(); ++it) {
    if (std::find(allowed.begin(), allowed.end(), it.key()) != allowed.end()) continue;
    std::string known;
    for (const auto& k : allowed) known += (known.empty() ? "" : ", ") + k;
    auto suggestion = closest_match(it.key(), allowed);
    errors.push_back(path_of(it.key()) + ": unknown key (" +
                     (suggestion ? "did you mean '" + *suggestion + "'? " : std::string()) +
                     "known keys: " + (known.empty() ? "none" : known) + ")");
  }
  if (!errors.empty()) throw ConfigError(std::move(errors));
}

}  // namespace simgate
