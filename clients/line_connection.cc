#include "simgate/client/line_connection.h"

#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <memory>

#include "simgate/client/client.h"

namespace simgate::client {

namespace {

using Clock = LineConnection::Clock;

// How long a blocked send may wait for the server to read.
constexpr auto k_send_timeout = std::chrono::seconds(30);

// Milliseconds left until `deadline`, for poll() (0 once passed).
int remaining_ms(Clock::time_point deadline) {
  auto left =
      std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
  return left <= 0 ? 0 : static_cast<int>(std::min<long long>(left, 1 << 30));
}

}  // namespace

LineConnection::LineConnection(std::string owner, const std::string& host, std::uint16_t port,
                               std::chrono::milliseconds timeout)
    : owner_(std::move(owner)), peer_(host + ":" + std::to_string(port)) {
  // resolve (numeric hosts and names such as localhost)
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  if (int rc = ::getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &found); rc != 0)
    throw ClientError(owner_ + ": cannot resolve '" + host + "': " + gai_strerror(rc));
  std::unique_ptr<addrinfo, decltype(&::freeaddrinfo)> list(found, &::freeaddrinfo);

  // try every address until one connects, all within the deadline
  const auto deadline = Clock::now() + timeout;
  std::string last_error = "no address";
  for (addrinfo* a = found; a; a = a->ai_next) {
    int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a->ai_protocol);
    if (fd < 0) {
      last_error = std::strerror(errno);
      continue;
    }
    int err = 0;
    if (::connect(fd, a->ai_addr, a->ai_addrlen) != 0) {
      err = errno;
      if (err == EINPROGRESS) {
        pollfd p{fd, POLLOUT, 0};
        int ready = ::poll(&p, 1, remaining_ms(deadline));
        socklen_t len = sizeof err;
        if (ready == 1)
          ::getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &len);
        else
          err = ready == 0 ? ETIMEDOUT : errno;
      }
    }
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
  throw ClientError(owner_ + ": cannot connect to " + peer_ + ": " + last_error);
}

LineConnection::~LineConnection() { close(); }

void LineConnection::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

void LineConnection::shutdown_send() {
  if (fd_ >= 0) ::shutdown(fd_, SHUT_WR);
}

void LineConnection::fail(const std::string& what) {
  throw ClientError(owner_ + ": " + peer_ + ": " + what);
}

void LineConnection::send_raw(std::string_view bytes) {
  if (fd_ < 0) fail("the connection is closed");
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
        fail("send timed out (the server does not read)");
      continue;
    }
    closed_ = true;
    fail(std::string("send failed: ") + std::strerror(errno));
  }
}

void LineConnection::send_line(std::string_view line) {
  std::string bytes;
  bytes.reserve(line.size() + 1);
  bytes.append(line);
  bytes.push_back('\n');
  send_raw(bytes);
}

bool LineConnection::fill(Clock::time_point deadline) {
  if (fd_ < 0 || closed_) fail("the server closed the connection");
  for (;;) {
    char chunk[65536];
    ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
    if (n > 0) {
      buffer_.append(chunk, static_cast<std::size_t>(n));
      return true;
    }
    if (n == 0) {
      closed_ = true;
      fail("the server closed the connection");
    }
    if (errno == EINTR) continue;
    if (errno != EAGAIN && errno != EWOULDBLOCK) {
      closed_ = true;
      fail(std::string("receive failed: ") + std::strerror(errno));
    }
    // nothing yet: wait for data until the deadline
    pollfd p{fd_, POLLIN, 0};
    const int timeout = remaining_ms(deadline);
    if (timeout == 0) return false;
    int ready = ::poll(&p, 1, timeout);
    if (ready == 0) return false;
    if (ready < 0 && errno != EINTR) fail(std::string("poll failed: ") + std::strerror(errno));
  }
}

std::optional<std::string> LineConnection::read_line(std::chrono::milliseconds timeout) {
  const auto deadline = Clock::now() + timeout;
  for (;;) {
    auto nl = buffer_.find('\n', scanned_);
    if (nl != std::string::npos) {
      std::string line = buffer_.substr(0, nl);
      buffer_.erase(0, nl + 1);
      scanned_ = 0;
      return line;
    }
    scanned_ = buffer_.size();
    if (!fill(deadline)) return std::nullopt;
  }
}

bool LineConnection::wait_closed(std::chrono::milliseconds timeout) {
  const auto deadline = Clock::now() + timeout;
  try {
    while (fill(deadline)) {
      buffer_.clear();
      scanned_ = 0;
    }
    return false;
  } catch (const ClientError&) {
    return true;
  }
}

}  // namespace simgate::client
