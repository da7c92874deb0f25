#include "simgate/client/client.h"

#include <optional>

namespace simgate::client {

namespace {

std::unique_ptr<Client> make_transport_client(const std::string& transport, const json& options) {
#if SIMGATE_CLIENT_SOCKET
  if (transport == "socket") return make_socket_client(options);
#endif
#if SIMGATE_CLIENT_JSONRPC
  if (transport == "jsonrpc") return make_jsonrpc_client(options);
#endif
#if SIMGATE_CLIENT_WEBSOCKET
  if (transport == "websocket") return make_websocket_client(options);
#endif
#if SIMGATE_CLIENT_DDS
  if (transport == "dds") return make_dds_client(options);
#endif
  (void)options;
  throw ClientError("no client for transport '" + transport +
                    "' in this build (known: socket, jsonrpc, websocket, dds)");
}

}  // namespace

std::unique_ptr<Client> make_client(const std::string& transport, const json& options) {
  // the login's keys are this function's: the transport's factory gets the others
  json transport_options = options;
  std::optional<std::string> token;
  std::chrono::milliseconds timeout{5000};
  if (transport_options.is_object()) {
    if (auto it = transport_options.find("token"); it != transport_options.end()) {
      if (!it->is_string())
        throw ClientError("client option 'token': expected a string, found " + it->dump());
      token = it->get<std::string>();
      transport_options.erase(it);
    }
    if (auto it = transport_options.find("timeout_ms"); it != transport_options.end()) {
      if (!it->is_number_integer() || it->get<long long>() < 1)
        throw ClientError("client option 'timeout_ms': expected a positive integer, found " +
                          it->dump());
      timeout = std::chrono::milliseconds(it->get<long long>());
      transport_options.erase(it);
    }
  }
  std::unique_ptr<Client> client = make_transport_client(transport, transport_options);
  if (token) client->login(*token, timeout);
  return client;
}

}  // namespace simgate::client
