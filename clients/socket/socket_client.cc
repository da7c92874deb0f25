#include "simgate/client/socket_client.h"

#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <memory>

namespace simgate::client {

namespace {

using Clock = std::chrono::steady_clock;

int remaining_ms(Clock::time_point deadline) {
  auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
  return left < 0 ? 0 : static_cast<int>(std::min<long long>(left, 1 << 30));
}

}  // namespace

SocketClient::SocketClient(const std::string& host, std::uint16_t port, std::chrono::milliseconds timeout)
    : peer_(host + ":" + std::to_string(port)) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  int rc = ::getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &found);
  if (rc != 0) throw ClientError("socket client: cannot resolve " + peer_ + ": " + gai_strerror(rc));
  std::unique_ptr<addrinfo, decltype(&::freeaddrinfo)> list(found, &::freeaddrinfo);

  std::string last_error = "no address";
  const auto deadline = Clock::now() + timeout;
  for (addrinfo* a = found; a; a = a->ai_next) {
    int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a->ai_protocol);
    if (fd < 0) {
      last_error = std::strerror(errno);
      continue;
    }
    // non-blocking connect, so the deadline holds
    if (::connect(fd, a->ai_addr, a->ai_addrlen) != 0 && errno != EINPROGRESS) {
      last_error = std::strerror(errno);
      ::close(fd);
      continue;
    }
    pollfd p{fd, POLLOUT, 0};
    int ready = ::poll(&p, 1, remaining_ms(deadline));
    int err = 0;
    socklen_t len = sizeof err;
    if (ready <= 0) {
      last_error = ready == 0 ? "timed out" : std::strerror(errno);
      ::close(fd);
      continue;
    }
    ::getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &len);
    if (err != 0) {
      last_error = std::strerror(err);
      ::close(fd);
      continue;
    }
    int one = 1;
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    fd_ = fd;
    return;
  }
  throw ClientError("socket client: cannot connect to " + peer_ + ": " + last_error);
}

SocketClient::~SocketClient() { close(); }

void SocketClient::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

void SocketClient::shutdown_send() {
  if (fd_ >= 0) ::shutdown(fd_, SHUT_WR);
}

void SocketClient::send_raw(std::string_view bytes) {
  if (fd_ < 0) throw ClientError("socket client: not connected to " + peer_);
  while (!bytes.empty()) {
    ssize_t n = ::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL);
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN || errno == EWOULDBLOCK) {
        pollfd p{fd_, POLLOUT, 0};
        if (::poll(&p, 1, 10000) <= 0)
          throw ClientError("socket client: " + peer_ + " does not accept data (send timed out)");
        continue;
      }
      throw ClientError("socket client: send to " + peer_ + " failed: " + std::strerror(errno));
    }
    bytes.remove_prefix(static_cast<std::size_t>(n));
  }
}

void SocketClient::send_line(std::string_view line) {
  std::string data;
  data.reserve(line.size() + 1);
  data.append(line);
  data += '\n';
  send_raw(data);
}

std::optional<std::string> SocketClient::read_line(std::chrono::milliseconds timeout) {
  const auto deadline = Clock::now() + timeout;
  for (;;) {
    std::size_t nl = buffer_.find('\n');
    if (nl != std::string::npos) {
      std::string line = buffer_.substr(0, nl);
      buffer_.erase(0, nl + 1);
      return line;
    }
    if (closed_ || fd_ < 0) throw ClientError("socket client: " + peer_ + " closed the connection");
    pollfd p{fd_, POLLIN, 0};
    int ready = ::poll(&p, 1, remaining_ms(deadline));
    if (ready < 0) {
      if (errno == EINTR) continue;
      throw ClientError("socket client: poll failed: " + std::string(std::strerror(errno)));
    }
    if (ready == 0) return std::nullopt;
    char chunk[16384];
    ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
    if (n < 0) {
      if (errno == EINTR || errno == EAGAIN || errno == EWOULDBLOCK) continue;
      closed_ = true;
      throw ClientError("socket client: receive from " + peer_ + " failed: " + std::strerror(errno));
    }
    if (n == 0) {
      closed_ = true;
      throw ClientError("socket client: " + peer_ + " closed the connection");
    }
    buffer_.append(chunk, static_cast<std::size_t>(n));
  }
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
  if (reply.value) message = reply.value->is_string() ? reply.value->get<std::string>() : reply.value->dump();
  if (reply.status == "PREEMPTED") {
    Outcome o = Outcome::failed(Failure::preempted, message.empty() ? "preempted" : message);
    o.value = reply.value;
    return o;
  }
  if (reply.status != "FAILED")
    throw ClientError("socket client: unknown status '" + reply.status + "' in reply to " + reply.id);
  // the transport's messages keep MORSE's phrases: classify by them
  Failure failure = Failure::service_error;
  if (message.find("has not been registered") != std::string::npos) failure = Failure::unknown_service;
  else if (message.find("wrong # of parameters") != std::string::npos ||
           message.find("wrong parameter") != std::string::npos ||
           message.find("Invalid request syntax") != std::string::npos)
    failure = Failure::bad_arguments;
  else if (message.find("already running") != std::string::npos) failure = Failure::busy;
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
    auto line = read_line(std::chrono::milliseconds(remaining_ms(deadline)));
    if (!line) throw ClientError("socket client: no reply to request " + id + " from " + peer_ + " in time");
    SocketReply r = parse_reply(*line);
    if (r.id == id) return r;
    early_[r.id] = std::move(r);
  }
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
    if (auto it = options.find("host"); it != options.end() && it->is_string()) host = it->get<std::string>();
    if (auto it = options.find("port"); it != options.end()) {
      if (!it->is_number_integer() || it->get<long long>() < 1 || it->get<long long>() > 65535)
        throw ClientError("socket client: option 'port' must be an integer from 1 to 65535");
      port = it->get<int>();
    }
  }
  return std::make_unique<SocketClient>(host, static_cast<std::uint16_t>(port));
}

}  // namespace simgate::client
