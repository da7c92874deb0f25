// simgate/client/websocket_client.h — a client of the websocket transport: JSON-RPC 2.0, one
// message per WebSocket text message (Boost.Beast, blocking; the protocol is the jsonrpc
// transport's, so responses are read with JsonRpcClient::to_outcome and services_of).
//
// call() / list_services() (the Client interface), request() for any method, and receive()
// for what the server sends on its own (rpc.sample notifications of a subscription): a
// message that arrives while request() waits for its response is kept for receive().
//
// Deadlines: the socket's receive timeout (SO_RCVTIMEO) bounds each read; a read that times
// out leaves the WebSocket unusable (Beast fails the stream), so the client closes then:
// request() throws ClientError, receive() returns nullopt and closed() is true.
// Threads: not thread-safe; one client per thread.
#ifndef SIMGATE_CLIENT_WEBSOCKET_CLIENT_H_
#define SIMGATE_CLIENT_WEBSOCKET_CLIENT_H_

#include <chrono>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>

#include "simgate/client/client.h"

namespace simgate::client {

class WebSocketClient : public Client {
 public:
  // Connects to host:port and does the WebSocket handshake on "/". Throws ClientError.
  WebSocketClient(const std::string& host, std::uint16_t port,
                  std::chrono::milliseconds timeout = std::chrono::seconds(5));
  ~WebSocketClient() override;
  WebSocketClient(const WebSocketClient&) = delete;
  WebSocketClient& operator=(const WebSocketClient&) = delete;

  Outcome call(const std::string& component, const std::string& service, const json& params,
               std::chrono::milliseconds timeout) override;
  // rpc.discover, converted to ServiceDescriptor::to_json() objects.
  json list_services(std::chrono::milliseconds timeout) override;
  // rpc.login {"token"}, as JsonRpcClient::login.
  void login(const std::string& token, std::chrono::milliseconds timeout) override;

  // Sends a call (params: array, object or null, omitted) and returns its whole response
  // object; other messages received meanwhile are kept for receive(). The "auth" option's
  // refusal (-32005) throws AuthError, as JsonRpcClient's.
  json request(const std::string& method, const json& params, std::chrono::milliseconds timeout);
  // The next message the server sent (kept ones first), or nullopt when `timeout` passes
  // first (the client is then closed). std::chrono::milliseconds::max(): no deadline.
  std::optional<json> receive(std::chrono::milliseconds timeout);
  // The connection failed, timed out or was closed.
  bool closed() const;
  // The TCP socket's descriptor (-1 once closed): shutting it down (::shutdown, which a
  // signal handler may call) makes a blocked receive() return, for Ctrl-C.
  int native_handle();

 private:
  // The next message from the connection (not the kept ones); nullopt on timeout.
  std::optional<json> read(std::chrono::milliseconds timeout);

  struct Connection;                        // Beast's stream and its io_context
  std::unique_ptr<Connection> connection_;  // the WebSocket
  std::string peer_;                        // "host:port", for messages
  std::deque<json> early_;                  // messages that arrived before they were asked for
  std::int64_t next_id_ = 0;                // last id used
};

}  // namespace simgate::client

#endif  // SIMGATE_CLIENT_WEBSOCKET_CLIENT_H_
