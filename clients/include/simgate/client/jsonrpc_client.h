// simgate/client/jsonrpc_client.h — a client of the jsonrpc transport (JSON-RPC 2.0, NDJSON).
//
// One TCP connection to a `jsonrpc` transport; one JSON message per '\n'-terminated line.
// Three levels of use:
//   - call() / request() / discover() / cancel(): blocking, with a deadline;
//   - send_request() / send_notification() / wait_for() / receive(): pipelining, many
//     calls in flight, responses matched by id (responses for other ids that arrive while
//     waiting are kept for later);
//   - send_line() / send_raw() / read_line(): raw protocol access for tests and benchmarks.
// Ids chosen by this class are integers counting up from 1.
//
// Threads: not thread-safe; use one JsonRpcClient per thread. Every wait has a deadline;
// connection loss, timeouts and unparsable responses throw ClientError. Error responses
// are not exceptions: request() returns the response object, call() an Outcome; but for
// k_unauthorized (the transport's "auth" wants rpc.login first, or refused its token), which
// throws AuthError: no call ran.
#ifndef SIMGATE_CLIENT_JSONRPC_CLIENT_H_
#define SIMGATE_CLIENT_JSONRPC_CLIENT_H_

#include <chrono>
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <string_view>

#include "simgate/client/client.h"
#include "simgate/client/line_connection.h"

namespace simgate::client {

class JsonRpcClient : public Client {
 public:
  // The server's error codes (docs/transports/jsonrpc.md).
  static constexpr int k_parse_error = -32700;
  static constexpr int k_invalid_request = -32600;
  static constexpr int k_method_not_found = -32601;
  static constexpr int k_invalid_params = -32602;
  static constexpr int k_internal_error = -32603;
  static constexpr int k_service_failed = -32000;
  static constexpr int k_preempted = -32001;
  static constexpr int k_cancelled = -32002;
  static constexpr int k_timeout = -32003;
  static constexpr int k_busy = -32004;
  static constexpr int k_unauthorized = -32005;
  static constexpr int k_overloaded = -32006;
  static constexpr int k_shutting_down = -32007;

  // Connects to host:port (TCP_NODELAY). Throws ClientError if it cannot.
  JsonRpcClient(const std::string& host, std::uint16_t port,
                std::chrono::milliseconds timeout = std::chrono::seconds(5));
  ~JsonRpcClient() override;
  JsonRpcClient(const JsonRpcClient&) = delete;
  JsonRpcClient& operator=(const JsonRpcClient&) = delete;

  // ---- blocking ----

  // Calls "component.service" and converts the response (Client interface).
  Outcome call(const std::string& component, const std::string& service, const json& params,
               std::chrono::milliseconds timeout) override;
  // rpc.discover, converted to ServiceDescriptor::to_json() objects.
  json list_services(std::chrono::milliseconds timeout) override;
  // rpc.login {"token"}: AuthError when the server refuses it (and closes the connection).
  // A server without "auth" accepts any token.
  void login(const std::string& token, std::chrono::milliseconds timeout) override;
  // The raw OpenRPC document.
  json discover(std::chrono::milliseconds timeout);
  // Sends a call and returns its whole response object (result or error).
  json request(const std::string& method, const json& params, std::chrono::milliseconds timeout);
  // rpc.cancel {"id": id}: true if the server found the pending call.
  bool cancel(const json& id, std::chrono::milliseconds timeout);

  // ---- pipelined ----

  // Sends a call with a fresh id; returns the id. params: array, object or null (omitted).
  json send_request(const std::string& method, const json& params);
  // Sends a notification (no id, no response).
  void send_notification(const std::string& method, const json& params);
  // The response whose id equals `id`; others received meanwhile are kept.
  json wait_for(const json& id, std::chrono::milliseconds timeout);
  // The next message (kept ones first): a response object or a batch array; nullopt when
  // `timeout` passes first.
  std::optional<json> receive(std::chrono::milliseconds timeout);

  // ---- raw ----

  void send_line(std::string_view line);  // line + "\n"
  void send_raw(std::string_view bytes);  // exactly these bytes
  // The next line without its '\n', or nullopt on timeout. Throws ClientError when the
  // server closed the connection (closed() then returns true).
  std::optional<std::string> read_line(std::chrono::milliseconds timeout);
  // Reads and discards until the server closes; true if it did before `timeout`.
  bool wait_closed(std::chrono::milliseconds timeout);
  // Half-closes (shutdown SHUT_WR): the server sees end of input.
  void shutdown_write();
  bool closed() const { return connection_.closed(); }
  void close();

  // An Outcome from a response object (result -> success; error code -> Failure).
  static Outcome to_outcome(const json& response);
  // The services of an rpc.discover result (OpenRPC) as ServiceDescriptor::to_json()
  // objects (also the websocket client's: the same protocol).
  static json services_of(const json& openrpc);
  // Throws AuthError, prefixed with `who` ("jsonrpc client: 127.0.0.1:4001"), when
  // `response` is the k_unauthorized error (also the websocket client's).
  static void throw_if_unauthorized(const json& response, const std::string& who);

 private:
  LineConnection connection_;  // the TCP connection and its line buffer
  std::string peer_;           // "host:port", for messages
  std::deque<json> early_;     // messages that arrived before they were asked for
  std::int64_t next_id_ = 0;   // last id used
};

}  // namespace simgate::client

#endif  // SIMGATE_CLIENT_JSONRPC_CLIENT_H_
