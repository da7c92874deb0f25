#include "simgate/jsonrpc/protocol.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>

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
