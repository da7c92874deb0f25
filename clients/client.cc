#include "simgate/client/client.h"

namespace simgate::client {

std::unique_ptr<Client> make_client(const std::string& transport, const json& options) {
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

}  // namespace simgate::client
