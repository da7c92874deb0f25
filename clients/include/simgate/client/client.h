// simgate/client/client.h — the common client interface of every transport.
//
// The `simgate` client commands (call, list, watch, publish, snapshot) use it, so do the
// tests. Each transport's client (clients/<name>/) offers a richer class of its own
// (pipelining, async calls, cancel); this is their common denominator: one blocking call at
// a time, with a deadline, and the login a transport's "auth" option asks for.
#ifndef SIMGATE_CLIENT_CLIENT_H_
#define SIMGATE_CLIENT_CLIENT_H_

#include <chrono>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>

#include "simgate/core/status.h"

namespace simgate::client {

// Connection failures, timeouts and protocol violations (not service failures: those are
// Outcomes).
class ClientError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The server refused the client: its transport's "auth" option requires a token that was
// not presented, or the one presented is wrong (the server then closes the connection).
class AuthError : public ClientError {
 public:
  using ClientError::ClientError;
};

// Why a token cannot be presented to the DDS transport (DdsClient::login's error, and the
// command line's).
inline constexpr std::string_view k_dds_has_no_token =
    "the dds transport has no token authentication: who may reach it is set with Cyclone's network "
    "settings "
    "or DDS Security (docs/transports/dds.md, \"Network exposure\")";

class Client {
 public:
  virtual ~Client() = default;
  // Calls component.service with params (array, object or null) and waits for the final
  // outcome. Throws ClientError on connection loss or when `timeout` passes.
  virtual Outcome call(const std::string& component, const std::string& service, const json& params,
                       std::chrono::milliseconds timeout) = 0;
  // Everything the server offers through this transport: a JSON array of
  // ServiceDescriptor::to_json() objects.
  virtual json list_services(std::chrono::milliseconds timeout) = 0;
  // Presents the shared token of the transport's "auth" option
  // (docs/configuration.md#authentication-auth-per-tcp-transport), as the transport expects
  // it, before any call. Throws AuthError when the server refuses it, ClientError when the
  // transport has no token authentication (DDS) or the server does not answer in time.
  virtual void login(const std::string& token, std::chrono::milliseconds timeout) = 0;
};

// transport: "socket", "jsonrpc", "websocket" or "dds". options: {"host", "port"} for TCP
// transports, {"domain", "partition", "config"} for DDS; and for any of them "token",
// presented at once (login()) within "timeout_ms" (default 5000). Throws ClientError for
// unknown transports, and what login() throws.
std::unique_ptr<Client> make_client(const std::string& transport, const json& options);

// Implemented in clients/<name>/ (present when SIMGATE_CLIENT_<NAME> is defined).
std::unique_ptr<Client> make_socket_client(const json& options);
std::unique_ptr<Client> make_jsonrpc_client(const json& options);
std::unique_ptr<Client> make_websocket_client(const json& options);
std::unique_ptr<Client> make_dds_client(const json& options);

}  // namespace simgate::client

#endif  // SIMGATE_CLIENT_CLIENT_H_
