#include "simgate/client/socket_client.h"

#include <algorithm>
#include <memory>

namespace simgate::client {

namespace {

using Clock = std::chrono::steady_clock;

std::chrono::milliseconds remaining(Clock::time_point deadline) {
  return std::max(std::chrono::milliseconds(0),
                  std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()));
}

// The socket transport's reply to a request before `auth <token>` (socket_request_manager.cc).
constexpr std::string_view k_authentication_required = "Authentication required";

}  // namespace

SocketClient::SocketClient(const std::string& host, std::uint16_t port,
                           std::chrono::milliseconds timeout)
    : connection_("socket client", host, port, timeout), host_(host) {}

SocketClient::~SocketClient() = default;

void SocketClient::close() { connection_.close(); }

void SocketClient::shutdown_send() { connection_.shutdown_send(); }

void SocketClient::send_raw(std::string_view bytes) { connection_.send_raw(bytes); }

void SocketClient::send_line(std::string_view line) { connection_.send_line(line); }

std::optional<std::string> SocketClient::read_line(std::chrono::milliseconds timeout) {
  return connection_.read_line(timeout);
}

SocketReply SocketClient::parse_reply(std::string_view line) {
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  SocketReply reply;
  std::size_t sp1 = line.find(' ');
  if (sp1 == std::string_view::npos)
    throw ClientError("socket client: malformed reply (no status): '" + std::string(line) + "'");
  reply.id = std::string(line.substr(0, sp1));
  std::string_view rest = line.substr(sp1 + 1);
  std::size_t sp2 = rest.find(' ');
  reply.status = std::string(rest.substr(0, sp2));
  if (sp2 != std::string_view::npos) {
    std::string_view payload = rest.substr(sp2 + 1);
    try {
      reply.value = json::parse(payload);
    } catch (const json::exception&) {
      // NaN/Infinity (Python's json) or text from a non-JSON server: keep it as a string
      reply.value = std::string(payload);
    }
  }
  return reply;
}

Outcome SocketClient::to_outcome(const SocketReply& reply) {
  if (reply.status == "SUCCESS" || reply.status == "OK") return Outcome::success(reply.value);
  std::string message;
  if (reply.value)
    message = reply.value->is_string() ? reply.value->get<std::string>() : reply.value->dump();
  if (reply.status == "PREEMPTED") {
    Outcome o = Outcome::failed(Failure::preempted, message.empty() ? "preempted" : message);
    o.value = reply.value;
    return o;
  }
  if (reply.status != "FAILED")
    throw ClientError("socket client: unknown status '" + reply.status + "' in reply to " +
                      reply.id);
  // the transport's messages keep MORSE's phrases: classify by them
  Failure failure = Failure::service_error;
  if (message.find("has not been registered") != std::string::npos)
    failure = Failure::unknown_service;
  else if (message.find("wrong # of parameters") != std::string::npos ||
           message.find("wrong parameter") != std::string::npos ||
           message.find("Invalid request syntax") != std::string::npos)
    failure = Failure::bad_arguments;
  else if (message.find("already running") != std::string::npos)
    failure = Failure::busy;
  Outcome o = Outcome::failed(failure, message);
  o.value = reply.value;
  return o;
}

std::string SocketClient::send_request(const std::string& component, const std::string& service,
                                       const json& params) {
  std::string id = std::to_string(next_id_++);
  std::string line = id + " " + component + " " + service;
  if (!params.is_null()) line += " " + params.dump(-1, ' ', false, json::error_handler_t::replace);
  send_line(line);
  return id;
}

void SocketClient::cancel(const std::string& id) { send_line(id + " cancel"); }

SocketReply SocketClient::wait_reply(const std::string& id, std::chrono::milliseconds timeout) {
  if (auto it = early_.find(id); it != early_.end()) {
    SocketReply r = std::move(it->second);
    early_.erase(it);
    return r;
  }
  const auto deadline = Clock::now() + timeout;
  for (;;) {
    auto line = read_line(remaining(deadline));
    if (!line)
      throw ClientError("socket client: no reply to request " + id + " from " + connection_.peer() +
                        " in time");
    SocketReply r = parse_reply(*line);
    // a request the server did not run: this connection has not presented its token
    if (r.status == "FAILED" && r.value && r.value->is_string() &&
        r.value->get_ref<const std::string&>().starts_with(k_authentication_required))
      throw AuthError("socket client: " + connection_.peer() + ": " + r.value->get<std::string>());
    if (r.id == id) return r;
    early_[r.id] = std::move(r);
  }
}

void SocketClient::login(const std::string& token, std::chrono::milliseconds timeout) {
  send_line("auth " + token);
  const SocketReply reply = wait_reply("auth", timeout);
  if (reply.status == "SUCCESS" || reply.status == "OK") {
    token_ = token;  // the stream ports ask for it too
    return;
  }
  const std::string message =
      reply.value && reply.value->is_string() ? reply.value->get<std::string>() : "";
  if (message.starts_with("wrong token"))
    throw AuthError("socket client: " + connection_.peer() +
                    ": the server refused the token: " + message);
  // any other reply: the line was read as a request, the server asks no token of this connection
}

std::unique_ptr<LineConnection> SocketClient::open_stream_port(const std::string& owner,
                                                               std::uint16_t port,
                                                               std::chrono::milliseconds timeout) {
  auto stream = std::make_unique<LineConnection>(owner, host_, port, timeout);
  // nothing is answered on a stream port: a wrong token closes it (the service port has
  // accepted this one)
  if (!token_.empty()) stream->send_line("auth " + token_);
  return stream;
}

Outcome SocketClient::call(const std::string& component, const std::string& service,
                           const json& params, std::chrono::milliseconds timeout) {
  std::string id = send_request(component, service, params);
  return to_outcome(wait_reply(id, timeout));
}

json SocketClient::list_services(std::chrono::milliseconds timeout) {
  Outcome o = call("simulation", "list_services", json::array(), timeout);
  if (o.status != Status::success)
    throw ClientError("socket client: simulation list_services failed: " + o.message);
  return o.value ? *o.value : json::array();
}

std::unique_ptr<Client> make_socket_client(const json& options) {
  std::string host = "127.0.0.1";
  int port = 4000;
  if (options.is_object()) {
    if (auto it = options.find("host"); it != options.end() && it->is_string())
      host = it->get<std::string>();
    if (auto it = options.find("port"); it != options.end()) {
      if (!it->is_number_integer() || it->get<long long>() < 1 || it->get<long long>() > 65535)
        throw ClientError("socket client: option 'port' must be an integer from 1 to 65535");
      port = it->get<int>();
    }
  }
  return std::make_unique<SocketClient>(host, static_cast<std::uint16_t>(port));
}

}  // namespace simgate::client
