#include "simgate/core/config.h"

#include <algorithm>
#include <cmath>
#include <sstream>

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
    case json::value_t::boolean: return std::string("boolean ") + (value.get<bool>() ? "true" : "false");
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
      if (escaped) escaped = false;
      else if (c == '\\') escaped = true;
      else if (c == '"') in_string = false;
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

ConfigObject::ConfigObject(const json& value, std::string path) : value_(value), path_(std::move(path)) {
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

long long ConfigObject::get_int(const std::string& key, long long fallback, long long min, long long max) {
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
  for (std::size_t i = 0; i < choices.size(); ++i) expected += (i ? ", \"" : " \"") + choices[i] + "\"";
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
