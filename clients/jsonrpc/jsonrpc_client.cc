#include "simgate/client/jsonrpc_client.h"

namespace simgate::client {

namespace {
using Clock = std::chrono::steady_clock;
}  // namespace

JsonRpcClient::JsonRpcClient(const std::string& host, std::uint16_t port,
                             std::chrono::milliseconds timeout)
    : connection_("jsonrpc client", host, port, timeout), peer_(connection_.peer()) {}

JsonRpcClient::~JsonRpcClient() = default;

void JsonRpcClient::close() { connection_.close(); }

void JsonRpcClient::shutdown_write() { connection_.shutdown_send(); }

// ---- raw

void JsonRpcClient::send_raw(std::string_view bytes) { connection_.send_raw(bytes); }

void JsonRpcClient::send_line(std::string_view line) { connection_.send_line(line); }

std::optional<std::string> JsonRpcClient::read_line(std::chrono::milliseconds timeout) {
  auto line = connection_.read_line(timeout);
  if (line && !line->empty() && line->back() == '\r') line->pop_back();
  return line;
}

bool JsonRpcClient::wait_closed(std::chrono::milliseconds timeout) {
  return connection_.wait_closed(timeout);
}

// ---- pipelined

json JsonRpcClient::send_request(const std::string& method, const json& params) {
  json id = ++next_id_;
  json message = {{"jsonrpc", "2.0"}, {"id", id}, {"method", method}};
  if (!params.is_null()) message["params"] = params;
  send_line(message.dump(-1, ' ', false, json::error_handler_t::replace));
  return id;
}

void JsonRpcClient::send_notification(const std::string& method, const json& params) {
  json message = {{"jsonrpc", "2.0"}, {"method", method}};
  if (!params.is_null()) message["params"] = params;
  send_line(message.dump(-1, ' ', false, json::error_handler_t::replace));
}

std::optional<json> JsonRpcClient::receive(std::chrono::milliseconds timeout) {
  if (!early_.empty()) {
    json message = std::move(early_.front());
    early_.pop_front();
    return message;
  }
  const auto deadline = Clock::now() + timeout;
  for (;;) {
    auto line =
        read_line(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()));
    if (!line) return std::nullopt;
    if (line->empty()) continue;
    try {
      return json::parse(*line);
    } catch (const json::parse_error& e) {
      throw ClientError("jsonrpc client: " + peer_ + ": unparsable response '" +
                        line->substr(0, 200) + "': " + e.what());
    }
  }
}

json JsonRpcClient::wait_for(const json& id, std::chrono::milliseconds timeout) {
  // kept messages first
  for (auto it = early_.begin(); it != early_.end(); ++it) {
    if (it->is_object() && it->value("id", json()) == id) {
      json message = std::move(*it);
      early_.erase(it);
      throw_if_unauthorized(message, "jsonrpc client: " + peer_);
      return message;
    }
  }
  const auto deadline = Clock::now() + timeout;
  for (;;) {
    auto line =
        read_line(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()));
    if (!line)
      throw ClientError("jsonrpc client: " + peer_ + ": no response to id " + id.dump() +
                        " within " + std::to_string(timeout.count()) + " ms");
    if (line->empty()) continue;
    json message;
    try {
      message = json::parse(*line);
    } catch (const json::parse_error& e) {
      throw ClientError("jsonrpc client: " + peer_ + ": unparsable response: " + e.what());
    }
    if (message.is_object() && message.value("id", json()) == id) {
      throw_if_unauthorized(message, "jsonrpc client: " + peer_);
      return message;
    }
    early_.push_back(std::move(message));
  }
}

// ---- blocking

json JsonRpcClient::request(const std::string& method, const json& params,
                            std::chrono::milliseconds timeout) {
  return wait_for(send_request(method, params), timeout);
}

Outcome JsonRpcClient::call(const std::string& component, const std::string& service,
                            const json& params, std::chrono::milliseconds timeout) {
  return to_outcome(request(component + "." + service, params, timeout));
}

void JsonRpcClient::login(const std::string& token, std::chrono::milliseconds timeout) {
  const json response =
      request("rpc.login", json{{"token", token}}, timeout);  // refused: AuthError
  if (response.value("result", json()) != true)
    throw ClientError("jsonrpc client: " + peer_ + ": rpc.login failed: " + response.dump());
}

void JsonRpcClient::throw_if_unauthorized(const json& response, const std::string& who) {
  if (!response.is_object()) return;
  const auto error = response.find("error");
  if (error == response.end() || !error->is_object() || error->value("code", 0) != k_unauthorized)
    return;
  throw AuthError(who + ": " + error->value("message", std::string("Unauthorized")));
}

json JsonRpcClient::discover(std::chrono::milliseconds timeout) {
  json response = request("rpc.discover", nullptr, timeout);
  if (!response.contains("result"))
    throw ClientError("jsonrpc client: " + peer_ + ": rpc.discover failed: " + response.dump());
  return response["result"];
}

json JsonRpcClient::list_services(std::chrono::milliseconds timeout) {
  return services_of(discover(timeout));
}

json JsonRpcClient::services_of(const json& openrpc) {
  // OpenRPC methods back to ServiceDescriptor::to_json() objects
  json out = json::array();
  for (const auto& m : openrpc.value("methods", json::array())) {
    json params = json::array();
    for (const auto& p : m.value("params", json::array())) {
      json schema = p.value("schema", json::object());
      json e = {{"name", p.value("name", "")},
                {"type", p.value("description", "")},
                {"required", p.value("required", true)}};
      if (schema.contains("default")) {
        e["default"] = schema["default"];
        schema.erase("default");
      }
      e["schema"] = std::move(schema);
      params.push_back(std::move(e));
    }
    json d = {{"component", m.value("x-component", "")},
              {"name", m.value("x-service", "")},
              {"async", m.value("x-async", false)},
              {"params", std::move(params)},
              {"doc", m.value("description", "")},
              {"result", m.contains("result") ? m["result"].value("schema", json::object())
                                              : json::object()}};
    if (d["async"].get<bool>()) d["policy"] = m.value("x-policy", "unspecified");
    out.push_back(std::move(d));
  }
  return out;
}

bool JsonRpcClient::cancel(const json& id, std::chrono::milliseconds timeout) {
  json response = request("rpc.cancel", json{{"id", id}}, timeout);
  if (!response.contains("result") || !response["result"].is_boolean())
    throw ClientError("jsonrpc client: " + peer_ + ": rpc.cancel failed: " + response.dump());
  return response["result"].get<bool>();
}

Outcome JsonRpcClient::to_outcome(const json& response) {
  if (!response.is_object())
    throw ClientError("jsonrpc client: not a response object: " + response.dump());
  if (auto result = response.find("result"); result != response.end())
    return Outcome::success(*result);
  auto error = response.find("error");
  if (error == response.end() || !error->is_object())
    throw ClientError("jsonrpc client: response has neither result nor error: " + response.dump());
  const int code = error->value("code", k_internal_error);
  json data = error->value("data", json::object());
  Failure failure = Failure::internal;
  switch (code) {
    case k_method_not_found: failure = Failure::unknown_service; break;
    case k_invalid_params: failure = Failure::bad_arguments; break;
    case k_service_failed: failure = Failure::service_error; break;
    case k_preempted: failure = Failure::preempted; break;
    case k_cancelled: failure = Failure::cancelled; break;
    case k_busy: failure = Failure::busy; break;
    case k_shutting_down: failure = Failure::shutdown; break;
    case k_timeout: failure = Failure::timeout; break;
    default: failure = Failure::internal; break;
  }
  std::string message = error->value("message", "");
  Outcome outcome =
      Outcome::failed(failure, message, data.is_object() ? data : json{{"data", data}});
  // the component's own value, when it gave one
  if (data.is_object() && data.contains("value")) outcome.value = data["value"];
  return outcome;
}

std::unique_ptr<Client> make_jsonrpc_client(const json& options) {
  const std::string host = options.value("host", "127.0.0.1");
  const auto port = options.value("port", 4001);
  if (port < 1 || port > 65535)
    throw ClientError("jsonrpc client: port " + std::to_string(port) + " out of range");
  return std::make_unique<JsonRpcClient>(host, static_cast<std::uint16_t>(port));
}

}  // namespace simgate::client
