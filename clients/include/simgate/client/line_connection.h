// simgate/client/line_connection.h — one TCP connection that carries '\n'-terminated lines.
//
// The part the socket and JSON-RPC clients share: connecting with a deadline (every address
// of the name is tried, TCP_NODELAY), sending with a bounded wait (a server that stops
// reading makes send fail after 30 s instead of hanging), and reading lines with a
// deadline. The protocol on top (ids, replies, JSON) is the client's.
//
// Errors: ClientError, prefixed with the owner's name ("socket client: ...") and the peer.
// Threads: not thread-safe; one connection per thread.
#ifndef SIMGATE_CLIENT_LINE_CONNECTION_H_
#define SIMGATE_CLIENT_LINE_CONNECTION_H_

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace simgate::client {

class LineConnection {
 public:
  using Clock = std::chrono::steady_clock;

  // Connects to host:port within `timeout`. `owner` names the client in messages.
  LineConnection(std::string owner, const std::string& host, std::uint16_t port,
                 std::chrono::milliseconds timeout);
  ~LineConnection();
  LineConnection(const LineConnection&) = delete;
  LineConnection& operator=(const LineConnection&) = delete;

  // Sends exactly `bytes` / `line` + "\n".
  void send_raw(std::string_view bytes);
  void send_line(std::string_view line);
  // The next line without its '\n' (a '\r' before it is kept), or nullopt when `timeout`
  // passes first. Throws ClientError once the server closed the connection.
  std::optional<std::string> read_line(std::chrono::milliseconds timeout);
  // Reads and discards until the server closes: true if it did within `timeout`.
  bool wait_closed(std::chrono::milliseconds timeout);

  // Half-closes: the server sees the end of input (replies still arrive).
  void shutdown_send();
  void close();
  // The server closed the connection (or it failed).
  bool closed() const { return closed_; }
  const std::string& peer() const { return peer_; }

 private:
  // Appends what arrives before `deadline` to buffer_; false on timeout.
  bool fill(Clock::time_point deadline);
  // "socket client: 127.0.0.1:4000: <what>"
  [[noreturn]] void fail(const std::string& what);

  std::string owner_;        // "socket client", "jsonrpc client"
  std::string peer_;         // "host:port"
  int fd_ = -1;              // the connected socket (non-blocking)
  std::string buffer_;       // bytes received, not yet returned as lines
  std::size_t scanned_ = 0;  // buffer_ holds no '\n' before this offset
  bool closed_ = false;      // the peer closed the connection, or it failed
};

}  // namespace simgate::client

#endif  // SIMGATE_CLIENT_LINE_CONNECTION_H_
