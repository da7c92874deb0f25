#include "simgate/jsonrpc/protocol.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include "simgate/core/config.h"

namespace simgate::jsonrpc {

std::string_view code_message(int error_code) noexcept {
  switch (error_code) {
    case code::parse_error: return "Parse error";
    case code::invalid_request: return "Invalid Request";
    case code::method_not_found: return "Method not found";
    case code::invalid_params: return "Invalid params";
    case code::internal_error: return "Internal error";
    case code::service_failed: return "Service failed";
    case code::preempted: return "Preempted";
    case code::cancelled: return "Cancelled";
    case code::timeout: return "Timeout";
    case code::busy: return "Busy";
    case code::unauthorized: return "Not authorized";
    case code::overloaded: return "Overloaded";
    case code::shutting_down: return "Shutting down";
  }
  return "Server error";
}

int code_for(const Outcome& outcome) noexcept {
  switch (outcome.failure) {
    case Failure::unknown_service: return code::method_not_found;
    case Failure::bad_arguments: return code::invalid_params;
    case Failure::busy: return code::busy;
    case Failure::service_error: return code::service_failed;
    case Failure::internal: return code::internal_error;
    case Failure::preempted: return code::preempted;
    case Failure::cancelled: return code::cancelled;
    case Failure::shutdown: return code::shutting_down;
    case Failure::timeout: return code::timeout;
    case Failure::none: break;
  }
  // a component finished its request with a bare status
  return outcome.status == Status::preempted ? code::preempted : code::service_failed;
}

std::string dump(const json& value) {
  return value.dump(-1, ' ', false, json::error_handler_t::replace);
}

namespace {

// Appends dump(value) to `out`, without the serializer for the common scalars.
void append_json(std::string& out, const json& value) {
  char digits[24];
  switch (value.type()) {
    case json::value_t::number_unsigned: {
      auto r = std::to_chars(digits, digits + sizeof digits,
                             value.get_ref<const json::number_unsigned_t&>());
      out.append(digits, r.ptr);
      return;
    }
    case json::value_t::number_integer: {
      auto r = std::to_chars(digits, digits + sizeof digits,
                             value.get_ref<const json::number_integer_t&>());
      out.append(digits, r.ptr);
      return;
    }
    case json::value_t::boolean: out += value.get<bool>() ? "true" : "false"; return;
    case json::value_t::null: out += "null"; return;
    default: out += dump(value); return;
  }
}

}  // namespace

void append_result_line(std::string& out, std::string_view id_text, const json& result) {
  using namespace std::string_view_literals;  // sizes known: no strlen
  out += R"({"jsonrpc":"2.0","id":)"sv;
  out += id_text;
  out += R"(,"result":)"sv;
  append_json(out, result);
  out += '}';
}

CallOptions read_meta(const json& meta, std::string& why) {
  CallOptions options;
  if (!meta.is_object()) {
    why =
        "expected an object of call options ({\"progress\": true, \"timeout_ms\": 5000}), found " +
        dump(meta);
    return options;
  }
  for (const auto& [key, value] : meta.items()) {
    if (key == "progress") {
      if (!value.is_boolean()) {
        why = "progress: expected true or false, found " + dump(value);
        return options;
      }
      options.progress = value.get<bool>();
    } else if (key == "timeout_ms") {
      // an integer number of ms (5000, or 5000.0 from clients whose numbers are all doubles)
      const bool integral = value.is_number_integer() ||
                            (value.is_number_float() && std::isfinite(value.get<double>()) &&
                             std::trunc(value.get<double>()) == value.get<double>());
      if (!integral) {
        why = "timeout_ms: expected an integer number of milliseconds (0 = no timeout), found " +
              dump(value);
        return options;
      }
      const double ms = value.is_number_float() ? value.get<double>()
                        : value.is_number_unsigned()
                            ? static_cast<double>(value.get<std::uint64_t>())
                            : static_cast<double>(value.get<std::int64_t>());
      if (ms < 0 || ms > static_cast<double>(k_max_timeout_ms)) {
        why = "timeout_ms: expected 0 (no timeout) to " + std::to_string(k_max_timeout_ms) +
              " ms, found " + dump(value);
        return options;
      }
      options.timeout = std::chrono::milliseconds(static_cast<long long>(ms));
    } else {
      why = "unknown call option '" + key + "' (known: progress, timeout_ms)";
      return options;
    }
  }
  return options;
}

json result_response(const json& id, json result) {
  return {{"jsonrpc", "2.0"}, {"id", id}, {"result", std::move(result)}};
}

json error_response(const json& id, int error_code, std::string message, json data) {
  json error = {{"code", error_code}, {"message", std::move(message)}};
  if (!data.is_null()) error["data"] = std::move(data);
  return {{"jsonrpc", "2.0"}, {"id", id}, {"error", std::move(error)}};
}

json outcome_response(const json& id, const Outcome& outcome, const std::string& method) {
  // data: the core's structured detail, then what every error carries
  json data = outcome.data.is_object() ? outcome.data : json::object();
  data["method"] = method;
  data["status"] = std::string(to_string(outcome.status));
  data["failure"] = std::string(to_string(outcome.failure));
  if (!outcome.message.empty()) data["message"] = outcome.message;
  // a value the component passed to completed(FAILED/PREEMPTED, value)
  if (outcome.value && !(outcome.value->is_string() && *outcome.value == outcome.message))
    data["value"] = *outcome.value;
  const int error_code = code_for(outcome);
  std::string message =
      outcome.message.empty() ? std::string(code_message(error_code)) : outcome.message;
  return error_response(id, error_code, std::move(message), std::move(data));
}

std::optional<json> parse_request(json& message, Request& out) {
  auto invalid = [](const json& id, const std::string& why) {
    return error_response(id, code::invalid_request, "Invalid Request: " + why,
                          json{{"reason", why}});
  };
  if (!message.is_object())
    return invalid(nullptr, "a request must be a JSON object, not " + describe_json(message));

  // the id first: every later error is reported with it
  out.has_id = false;
  out.id = nullptr;
  if (auto it = message.find("id"); it != message.end()) {
    if (!it->is_string() && !it->is_number() && !it->is_null())
      return invalid(nullptr, "'id' must be a string, a number or null, not " + describe_json(*it));
    out.has_id = true;
    out.id = *it;
  }
  auto version = message.find("jsonrpc");
  if (version == message.end() || *version != "2.0")
    return invalid(out.id, version == message.end()
                               ? std::string("member 'jsonrpc' is missing (must be \"2.0\")")
                               : "'jsonrpc' must be \"2.0\", not " + describe_json(*version));
  auto method = message.find("method");
  if (method == message.end()) return invalid(out.id, "member 'method' is missing");
  if (!method->is_string())
    return invalid(out.id, "'method' must be a string, not " + describe_json(*method));
  out.method = method->get<std::string>();
  out.params = nullptr;
  if (auto params = message.find("params"); params != message.end()) {
    if (!params->is_array() && !params->is_object())
      return invalid(out.id,
                     "'params' must be an array or an object, not " + describe_json(*params));
    out.params = std::move(*params);
  }
  return std::nullopt;
}

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

void append_id_text(std::string& out, const json& id) {
  if (id.is_string()) {
    out += '"';
    out += id.get_ref<const std::string&>();
    out += '"';
  } else {
    append_json(out, id);
  }
}

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
      out.method.assign(method);
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
      if (text == "-0")
        append_id_text(out.id_text, out.id);
      else
        out.id_text.assign(text);
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

std::string response_with_id_text(const json& response, std::string_view id_text) {
  std::string out = R"({"jsonrpc":"2.0","id":)";
  out += id_text;
  for (const char* member : {"error", "result"})
    if (auto it = response.find(member); it != response.end()) {
      out += ",\"";
      out += member;
      out += "\":";
      out += dump(*it);
    }
  out += '}';
  return out;
}

namespace {

// Reads the raw text of the "id" numbers of a request object or of a batch's entries.
class FloatIdScanner final : public nlohmann::json_sax<json> {
 public:
  std::vector<std::pair<std::size_t, std::string>> found;

  bool null() override { return value(); }
  bool boolean(bool) override { return value(); }
  bool number_integer(number_integer_t) override { return value(); }
  bool number_unsigned(number_unsigned_t) override { return value(); }
  bool number_float(number_float_t, const string_t& text) override {
    // a request's own member: depth 1 (a lone request) or 2 (an entry of the batch)
    const bool request_level = (open_.size() == 1 && !open_[0].array) ||
                               (open_.size() == 2 && open_[0].array && !open_[1].array);
    if (request_level && open_.back().key == "id")
      found.emplace_back(open_.size() == 1 ? 0 : open_[0].index, text);
    return value();
  }
  bool string(string_t&) override { return value(); }
  bool binary(binary_t&) override { return value(); }
  bool start_object(std::size_t) override {
    open_.push_back({false, 0, {}});
    return true;
  }
  bool key(string_t& key) override {
    open_.back().key = key;
    return true;
  }
  bool end_object() override { return close(); }
  bool start_array(std::size_t) override {
    open_.push_back({true, 0, {}});
    return true;
  }
  bool end_array() override { return close(); }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) override {
    return false;
  }

 private:
  struct Open {
    bool array;         // else an object
    std::size_t index;  // arrays: the element being read
    std::string key;    // objects: the member being read
  };
  bool value() {
    if (!open_.empty() && open_.back().array) ++open_.back().index;
    return true;
  }
  bool close() {
    open_.pop_back();
    return value();
  }
  std::vector<Open> open_;  // the containers around the value being read
};

}  // namespace

std::vector<std::pair<std::size_t, std::string>> float_id_texts(std::string_view line) {
  FloatIdScanner scanner;
  if (!json::sax_parse(line.begin(), line.end(), &scanner)) return {};
  return std::move(scanner.found);
}

bool split_method(std::string_view method, std::string_view& component, std::string_view& service) {
  const auto dot = method.rfind('.');
  if (dot == std::string_view::npos || dot == 0 || dot + 1 == method.size()) return false;
  component = method.substr(0, dot);
  service = method.substr(dot + 1);
  return true;
}

json openrpc_document(const std::vector<ServiceDescriptor>& services, std::string_view version,
                      std::string_view global_policy) {
  json methods = json::array();
  for (const auto& d : services) {
    // parameters: JSON schema from the C++ type, the default inside the schema
    json params = json::array();
    for (const auto& p : d.params) {
      json schema = p.schema.is_object() ? p.schema : json::object();
      if (p.default_value) schema["default"] = *p.default_value;
      json param = {{"name", p.name},
                    {"required", !p.default_value.has_value()},
                    {"schema", std::move(schema)}};
      if (!p.type.empty()) param["description"] = p.type;
      params.push_back(std::move(param));
    }
    json method = {
        {"name", d.qualified_name()},
        {"params", std::move(params)},
        {"paramStructure", "either"},
        {"result",
         {{"name", "result"},
          {"schema", d.result_schema.is_object() ? d.result_schema : json::object()}}},
        {"x-component", d.component},
        {"x-service", d.name},
        {"x-async", d.is_async},
        {"x-signature", d.signature()},
    };
    if (!d.doc.empty()) {
      method["summary"] = d.doc;
      method["description"] = d.doc;
    }
    if (d.is_async) {
      // the policy that applies: the service's own, else the transport's global one
      method["x-policy"] = std::string(to_string(d.policy));
      // concurrent: every call runs on its own, none preempts another
      method["x-concurrent"] = d.concurrent;
      method["x-interruptible"] =
          !d.concurrent && (d.policy == Policy::interruptible ||
                            (d.policy == Policy::unspecified && global_policy == "preempt"));
    }
    methods.push_back(std::move(method));
  }
  std::sort(methods.begin(), methods.end(), [](const json& a, const json& b) {
    return a["name"].get_ref<const std::string&>() < b["name"].get_ref<const std::string&>();
  });

  // the server error codes, so generated clients can name them
  json errors = json::object();
  for (int c : {code::service_failed, code::preempted, code::cancelled, code::busy,
                code::overloaded, code::shutting_down}) {
    std::string name(code_message(c));
    std::replace(name.begin(), name.end(), ' ', '_');
    errors[name] = {{"code", c}, {"message", code_message(c)}};
  }
  return {
      {"openrpc", "1.2.6"},
      {"info",
       {{"title", "simgate JSON-RPC transport"},
        {"version", version},
        {"description",
         "Services of the simgate components this transport serves. Method names are "
         "'component.service'; params are positional (array) or named (object). Also "
         "callable: rpc.discover (this document) and rpc.cancel {\"id\": <id of your pending "
         "call>}."}}},
      {"methods", std::move(methods)},
      {"components", {{"errors", std::move(errors)}}},
  };
}

}  // namespace simgate::jsonrpc
