// simgate/client/socket_client.h — a client of the socket transport (MORSE's text protocol).
//
// One TCP connection to a `socket` transport. Three levels of use:
//   - call(): blocking, one request at a time, with a deadline (the Client interface);
//   - send_request() / cancel() / wait_reply(): several requests in flight, matched by id
//     (replies for other ids that arrive meanwhile are kept until asked for);
//   - send_line() / send_raw() / read_line(): raw protocol access for tests and pipelined
//     benchmarks.
// Replies are parsed like pymorse does: "<id> <STATUS>[ <json>]"; "OK" is read as SUCCESS.
// A transport with "auth" reads a first line `auth <token>` (login()), on the service port
// and on each stream port (open_stream_port()); a request refused for want of it throws
// AuthError.
//
// Threads: not thread-safe; use one SocketClient per thread. Every wait has a deadline;
// connection loss, timeouts and unparsable replies throw ClientError.
#ifndef SIMGATE_CLIENT_SOCKET_CLIENT_H_
#define SIMGATE_CLIENT_SOCKET_CLIENT_H_

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "simgate/client/client.h"
#include "simgate/client/line_connection.h"

namespace simgate::client {

// One reply line, split.
struct SocketReply {
  std::string id;             // the request id it answers
  std::string status;         // "SUCCESS", "OK", "FAILED", "PREEMPTED"
  std::optional<json> value;  // the payload, absent on a bare status
};

class SocketClient : public Client {
 public:
  // Connects to host:port (TCP_NODELAY). Throws ClientError if it cannot.
  SocketClient(const std::string& host, std::uint16_t port,
               std::chrono::milliseconds timeout = std::chrono::seconds(5));
  ~SocketClient() override;
  SocketClient(const SocketClient&) = delete;
  SocketClient& operator=(const SocketClient&) = delete;

  Outcome call(const std::string& component, const std::string& service, const json& params,
               std::chrono::milliseconds timeout) override;
  // `simulation list_services`; throws ClientError if the server has no such service.
  json list_services(std::chrono::milliseconds timeout) override;
  // Sends `auth <token>` and reads its reply: `auth SUCCESS` (or OK) logs in; `auth FAILED
  // "wrong token..."` throws AuthError (the server closes the connection). Any other reply
  // is a server that asks no token of this connection (no "auth", or a loopback client it
  // trusts), which took the line for a request: the token is then not needed.
  void login(const std::string& token, std::chrono::milliseconds timeout) override;
  // A connection to one of the server's stream ports (`simulation get_stream_port`), on
  // the service port's host, presenting the token as its first line when the service port
  // asked for it. `owner` names it in messages ("simgate watch").
  std::unique_ptr<LineConnection> open_stream_port(const std::string& owner, std::uint16_t port,
                                                   std::chrono::milliseconds timeout);

  // Sends "<id> <component> <service> <params as JSON>" with a fresh id; returns the id.
  std::string send_request(const std::string& component, const std::string& service,
                           const json& params);
  // Sends "<id> cancel" (no reply of its own: the request ends PREEMPTED).
  void cancel(const std::string& id);
  // Waits for the reply to `id`, keeping others for later.
  SocketReply wait_reply(const std::string& id, std::chrono::milliseconds timeout);

  // Sends `line` + "\n" / exactly `bytes`.
  void send_line(std::string_view line);
  void send_raw(std::string_view bytes);
  // The next line (without '\n'), or nullopt when `timeout` passes first. Throws
  // ClientError when the server closed the connection (closed() then returns true).
  std::optional<std::string> read_line(std::chrono::milliseconds timeout);
  bool closed() const { return connection_.closed(); }
  // Half-closes: the server sees the end of input (replies still arrive).
  void shutdown_send();
  // Closes the connection.
  void close();

  static SocketReply parse_reply(std::string_view line);
  static Outcome to_outcome(const SocketReply& reply);

 private:
  LineConnection connection_;                 // the TCP connection and its line buffer
  std::string host_;                          // the server's address, its stream ports' too
  std::map<std::string, SocketReply> early_;  // replies that arrived before they were awaited
  std::uint64_t next_id_ = 0;                 // ids are decimal counters, as pymorse's
  std::string token_;  // the token the server accepted ("" before, or if none was needed)
};

}  // namespace simgate::client

#endif  // SIMGATE_CLIENT_SOCKET_CLIENT_H_
