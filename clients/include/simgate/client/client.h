// simgate/client/client.h — the common client interface of every transport.
//
// `simgate call` and `simgate list` use it, so do the tests. Each transport's client
// (clients/<name>/) offers a richer class of its own (pipelining, async calls, cancel);
// this is their common denominator: one blocking call at a time, with a deadline.
#ifndef SIMGATE_CLIENT_CLIENT_H_
#define SIMGATE_CLIENT_CLIENT_H_

#include <chrono>
#include <memory>
#include <stdexcept>
#include <string>

#include "simgate/core/status.h"

namespace simgate::client {

// Connection failures, timeouts and protocol violations (not service failures: those are
// Outcomes).
class ClientError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class Client {
 public:
  virtual ~Client() = default;
  // Calls component.service with params (array, object or null) and waits for the final
  // outcome. Throws ClientError on connection loss or when `timeout` passes.
  virtual Outcome call(const std::string& component, const std::string& service,
                       const json& params, std::chrono::milliseconds timeout) = 0;
  // Everything the server offers through this transport: a JSON array of
  // ServiceDescriptor::to_json() objects.
  virtual json list_services(std::chrono::milliseconds timeout) = 0;
};

// transport: "socket", "jsonrpc", "websocket" or "dds". options: {"host", "port"} for TCP transports,
// {"domain", "partition", "config"} for DDS. Throws ClientError for unknown transports.
std::unique_ptr<Client> make_client(const std::string& transport, const json& options);

// Implemented in clients/<name>/ (present when SIMGATE_CLIENT_<NAME> is defined).
std::unique_ptr<Client> make_socket_client(const json& options);
std::unique_ptr<Client> make_jsonrpc_client(const json& options);
std::unique_ptr<Client> make_websocket_client(const json& options);
std::unique_ptr<Client> make_dds_client(const json& options);

}  // namespace simgate::client

#endif  // SIMGATE_CLIENT_CLIENT_H_
