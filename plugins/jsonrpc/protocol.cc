#include "protocol.h"

#include <algorithm>

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
    case Failure::none: break;
  }
  // a component finished its request with a bare status
  return outcome.status == Status::preempted ? code::preempted : code::service_failed;
}

std::string dump(const json& value) {
  return value.dump(-1, ' ', false, json::error_handler_t::replace);
}

std::string result_line(const json& id, const json& result) {
  std::string line;
  line.reserve(48);
  line += R"({"jsonrpc":"2.0","id":)";
  line += dump(id);
  line += R"(,"result":)";
  line += dump(result);
  line += '}';
  return line;
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
  std::string message = outcome.message.empty() ? std::string(code_message(error_code)) : outcome.message;
  return error_response(id, error_code, std::move(message), std::move(data));
}

std::optional<json> parse_request(json& message, Request& out) {
  auto invalid = [](const json& id, const std::string& why) {
    return error_response(id, code::invalid_request, "Invalid Request: " + why, json{{"reason", why}});
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
  if (!method->is_string()) return invalid(out.id, "'method' must be a string, not " + describe_json(*method));
  out.method = method->get<std::string>();
  out.params = nullptr;
  if (auto params = message.find("params"); params != message.end()) {
    if (!params->is_array() && !params->is_object())
      return invalid(out.id, "'params' must be an array or an object, not " + describe_json(*params));
    out.params = std::move(*params);
  }
  return std::nullopt;
}

bool split_method(const std::string& method, std::string& component, std::string& service) {
  const auto dot = method.rfind('.');
  if (dot == std::string::npos || dot == 0 || dot + 1 == method.size()) return false;
  component = method.substr(0, dot);
  service = method.substr(dot + 1);
  return true;
}

bool nests_deeper_than(std::string_view text, std::size_t max_depth) noexcept {
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

json openrpc_document(const std::vector<ServiceDescriptor>& services, std::string_view version,
                      std::string_view global_policy) {
  json methods = json::array();
  for (const auto& d : services) {
    // parameters: JSON schema from the C++ type, the default inside the schema
    json params = json::array();
    for (const auto& p : d.params) {
      json schema = p.schema.is_object() ? p.schema : json::object();
      if (p.default_value) schema["default"] = *p.default_value;
      json param = {{"name", p.name}, {"required", !p.default_value.has_value()}, {"schema", std::move(schema)}};
      if (!p.type.empty()) param["description"] = p.type;
      params.push_back(std::move(param));
    }
    json method = {
        {"name", d.qualified_name()},
        {"params", std::move(params)},
        {"paramStructure", "either"},
        {"result", {{"name", "result"}, {"schema", d.result_schema.is_object() ? d.result_schema : json::object()}}},
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
      method["x-interruptible"] = d.policy == Policy::interruptible ||
                                  (d.policy == Policy::unspecified && global_policy == "preempt");
    }
    methods.push_back(std::move(method));
  }
  std::sort(methods.begin(), methods.end(),
            [](const json& a, const json& b) { return a["name"].get_ref<const std::string&>() < b["name"].get_ref<const std::string&>(); });

  // the server error codes, so generated clients can name them
  json errors = json::object();
  for (int c : {code::service_failed, code::preempted, code::cancelled, code::busy, code::overloaded,
                code::shutting_down}) {
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
         "callable: rpc.discover (this document) and rpc.cancel {\"id\": <id of your pending call>}."}}},
      {"methods", std::move(methods)},
      {"components", {{"errors", std::move(errors)}}},
  };
}

}  // namespace simgate::jsonrpc
