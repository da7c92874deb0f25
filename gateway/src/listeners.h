// The TCP addresses the built-in TCP transports (socket, jsonrpc) of a deployment will
// listen on, and the checks `simgate check` can make of them without listening: two
// transports on one port, and an address this machine does not have. A plugin validates
// its own options (a port out of range, a host that does not resolve); what needs the
// whole deployment, or the plugin cannot tell without binding, is checked here.
#ifndef SIMGATE_GATEWAY_SRC_LISTENERS_H_
#define SIMGATE_GATEWAY_SRC_LISTENERS_H_

#include <sys/socket.h>

#include <optional>
#include <string>
#include <vector>

#include "simgate/core/errors.h"
#include "simgate/gateway/deployment.h"

namespace simgate::gateway {

// Where one transport will listen, read from its (valid) options as the plugin reads them.
struct Listener {
  const TransportConfig* transport = nullptr;  // its entry in the deployment
  std::string host;                            // as configured, or the plugin's default
  int port = 0;                                // as configured, or the default; 0 = any free port
  bool port_configured = false;                // "port" is in the options
  sockaddr_storage address{};                  // `host` resolved as the plugin resolves it
  socklen_t address_size = 0;                  // of `address`
};

// The listener of transport `t` served by plugin `plugin_name` (the loaded plugin's own
// name), or nullopt when the plugin is not a built-in TCP transport or its host does not
// resolve (the plugin reports that).
std::optional<Listener> listener_of(const std::string& plugin_name, const TransportConfig& t);

// Records a ConfigError for every listener that would share a port with an earlier one on
// an overlapping address (equal, or a wildcard covering the other: 0.0.0.0 covers IPv4,
// "::" both families), port 0 excluded, and for every address that is none of this
// machine's (binds a throwaway socket to it on port 0, never listening).
void check_listeners(const std::vector<Listener>& listeners, ConfigErrors& errors);

}  // namespace simgate::gateway

#endif  // SIMGATE_GATEWAY_SRC_LISTENERS_H_
