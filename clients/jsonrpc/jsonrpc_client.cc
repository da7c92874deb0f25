#include "simgate/client/jsonrpc_client.h"

#include <cerrno>
#include <cstring>

#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

namespace simgate::client {

namespace {
using Clock = std::chrono::steady_clock;

// Milliseconds left until `deadline`, for poll() (0 when passed).
int remaining_ms(Clock::time_point deadline) {
  auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
  if (left <= 0) return 0;
  return left > 1000000 ? 1000000 : static_cast<int>(left);
}

std::string errno_text(int err) { return std::strerror(err); }

// How long a blocked send may wait for the server to read.
constexpr auto k_send_timeout = std::chrono::seconds(30);
}  // namespace

JsonRpcClient::JsonRpcClient(const std::string& host, std::uint16_t port, std::chrono::milliseconds timeout)
    : peer_(host + ":" + std::to_string(port)) {
  // resolve (numeric hosts and names such as localhost)
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  const std::string service = std::to_string(port);
  if (int rc = ::getaddrinfo(host.c_str(), service.c_str(), &hints, &found); rc != 0)
    throw ClientError("jsonrpc client: cannot resolve '" + host + "': " + gai_strerror(rc));
  const auto deadline = Clock::now() + timeout;
  std::string last_error = "no address";
  for (addrinfo* a = found; a && fd_ < 0; a = a->ai_next) {
    int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a->ai_protocol);
    if (fd < 0) {
      last_error = errno_text(errno);
      continue;
    }
    // non-blocking connect, bounded by the deadline
    int rc = ::connect(fd, a->ai_addr, a->ai_addrlen);
    if (rc != 0 && errno == EINPROGRESS) {
      pollfd p{fd, POLLOUT, 0};
      const int ready = ::poll(&p, 1, remaining_ms(deadline));
      if (ready == 1) {
        int err = 0;
        socklen_t len = sizeof err;
        ::getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &len);
        rc = err == 0 ? 0 : -1;
        errno = err;
      } else {
        rc = -1;
        if (ready == 0) errno = ETIMEDOUT;
      }
    }
    if (rc != 0) {
      last_error = errno_text(errno);
      ::close(fd);
      continue;
    }
    int one = 1;
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    fd_ = fd;
  }
  ::freeaddrinfo(found);
  if (fd_ < 0) throw ClientError("jsonrpc client: cannot connect to " + peer_ + ": " + last_error);
}

JsonRpcClient::~JsonRpcClient() { close(); }

void JsonRpcClient::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

void JsonRpcClient::shutdown_write() {
  if (fd_ >= 0) ::shutdown(fd_, SHUT_WR);
}

// ---- raw

void JsonRpcClient::send_raw(std::string_view bytes) {
  if (fd_ < 0) throw ClientError("jsonrpc client: " + peer_ + ": connection is closed");
  const auto deadline = Clock::now() + k_send_timeout;
  while (!bytes.empty()) {
    ssize_t n = ::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL);
    if (n > 0) {
      bytes.remove_prefix(static_cast<std::size_t>(n));
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      // the server is not reading: wait, but not forever
      pollfd p{fd_, POLLOUT, 0};
      if (::poll(&p, 1, remaining_ms(deadline)) == 0)
        throw ClientError("jsonrpc client: " + peer_ + ": send timed out (server not reading)");
      continue;
    }
    closed_ = true;
    throw ClientError("jsonrpc client: " + peer_ + ": send failed: " + errno_text(errno));
  }
}

void JsonRpcClient::send_line(std::string_view line) {
  std::string bytes;
  bytes.reserve(line.size() + 1);
  bytes.append(line);
  bytes.push_back('\n');
  send_raw(bytes);
}

bool JsonRpcClient::fill(Clock::time_point deadline) {
  if (fd_ < 0 || closed_) throw ClientError("jsonrpc client: " + peer_ + ": connection closed by the server");
  for (;;) {
    char chunk[65536];
    ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
    if (n > 0) {
      buffer_.append(chunk, static_cast<std::size_t>(n));
      return true;
    }
    if (n == 0) {
      closed_ = true;
      throw ClientError("jsonrpc client: " + peer_ + ": connection closed by the server");
    }
    if (errno == EINTR) continue;
    if (errno != EAGAIN && errno != EWOULDBLOCK) {
      closed_ = true;
      throw ClientError("jsonrpc client: " + peer_ + ": receive failed: " + errno_text(errno));
    }
    pollfd p{fd_, POLLIN, 0};
    const int timeout = remaining_ms(deadline);
    if (timeout == 0 || ::poll(&p, 1, timeout) == 0) return false;
  }
}

std::optional<std::string> JsonRpcClient::read_line(std::chrono::milliseconds timeout) {
  const auto deadline = Clock::now() + timeout;
  std::size_t scanned = 0;
  for (;;) {
    auto nl = buffer_.find('\n', scanned);
    if (nl != std::string::npos) {
      std::string line = buffer_.substr(0, nl);
      buffer_.erase(0, nl + 1);
      if (!line.empty() && line.back() == '\r') line.pop_back();
      return line;
    }
    scanned = buffer_.size();
    if (!fill(deadline)) return std::nullopt;
  }
}

bool JsonRpcClient::wait_closed(std::chrono::milliseconds timeout) {
  const auto deadline = Clock::now() + timeout;
  try {
    while (fill(deadline)) buffer_.clear();
    return false;
  } catch (const ClientError&) {
    return true;
  }
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
    auto line = read_line(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()));
    if (!line) return std::nullopt;
    if (line->empty()) continue;
    try {
      return json::parse(*line);
    } catch (const json::parse_error& e) {
      throw ClientError("jsonrpc client: " + peer_ + ": unparsable response '" + line->substr(0, 200) +
                        "': " + e.what());
    }
  }
}

json JsonRpcClient::wait_for(const json& id, std::chrono::milliseconds timeout) {
  // kept messages first
  for (auto it = early_.begin(); it != early_.end(); ++it) {
    if (it->is_object() && it->value("id", json()) == id) {
      json message = std::move(*it);
      early_.erase(it);
      return message;
    }
  }
  const auto deadline = Clock::now() + timeout;
  for (;;) {
    auto line = read_line(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()));
    if (!line)
      throw ClientError("jsonrpc client: " + peer_ + ": no response to id " + id.dump() + " within " +
                        std::to_string(timeout.count()) + " ms");
    if (line->empty()) continue;
    json message;
    try {
      message = json::parse(*line);
    } catch (const json::parse_error& e) {
      throw ClientError("jsonrpc client: " + peer_ + ": unparsable response: " + e.what());
    }
    if (message.is_object() && message.value("id", json()) == id) return message;
    early_.push_back(std::move(message));
  }
}

// ---- blocking

json JsonRpcClient::request(const std::string& method, const json& params, std::chrono::milliseconds timeout) {
  return wait_for(send_request(method, params), timeout);
}

Outcome JsonRpcClient::call(const std::string& component, const std::string& service, const json& params,
                            std::chrono::milliseconds timeout) {
  return to_outcome(request(component + "." + service, params, timeout));
}

json JsonRpcClient::discover(std::chrono::milliseconds timeout) {
  json response = request("rpc.discover", nullptr, timeout);
  if (!response.contains("result"))
    throw ClientError("jsonrpc client: " + peer_ + ": rpc.discover failed: " + response.dump());
  return response["result"];
}

json JsonRpcClient::list_services(std::chrono::milliseconds timeout) {
  // OpenRPC methods back to ServiceDescriptor::to_json() objects
  json out = json::array();
  for (const auto& m : discover(timeout).value("methods", json::array())) {
    json params = json::array();
    for (const auto& p : m.value("params", json::array())) {
      json schema = p.value("schema", json::object());
      json e = {{"name", p.value("name", "")}, {"type", p.value("description", "")},
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
              {"result", m.contains("result") ? m["result"].value("schema", json::object()) : json::object()}};
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
  if (!response.is_object()) throw ClientError("jsonrpc client: not a response object: " + response.dump());
  if (auto result = response.find("result"); result != response.end()) return Outcome::success(*result);
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
    default: failure = Failure::internal; break;
  }
  std::string message = error->value("message", "");
  Outcome outcome = Outcome::failed(failure, message, data.is_object() ? data : json{{"data", data}});
  // the component's own value, when it gave one
  if (data.is_object() && data.contains("value")) outcome.value = data["value"];
  return outcome;
}

std::unique_ptr<Client> make_jsonrpc_client(const json& options) {
  const std::string host = options.value("host", "127.0.0.1");
  const auto port = options.value("port", 4001);
  if (port < 1 || port > 65535) throw ClientError("jsonrpc client: port " + std::to_string(port) + " out of range");
  return std::make_unique<JsonRpcClient>(host, static_cast<std::uint16_t>(port));
}

}  // namespace simgate::client
