// simgate/kit/auth.h — a TCP transport's optional shared-token authentication (issue #17).
//
// Off unless the transport's options hold "auth": {"token_file": PATH} or {"token_env":
// NAME}. The token itself is never in the config (configs are shared, checked in, shown by
// `simgate check`): it is read from the file (its first line) or the environment variable
// when the options are parsed, so `simgate check` already says when it is missing. It must
// be 16 to 4096 printable ASCII characters without spaces (`openssl rand -hex 32` makes
// one). A token file others may read draws a warning.
//
// Who must present it: clients connecting from a non-loopback address. Loopback peers
// (127.0.0.0/8, ::1, and IPv4-mapped 127.x) are the machine's own programs, which the
// default deployment (bound to 127.0.0.1) trusts already; "loopback": true requires the
// token from them too. How a client presents it is the protocol's affair: the socket
// transport reads a first line `auth <token>`, JSON-RPC an `rpc.login` call (docs/transports).
// A wrong token closes the connection: one guess per connection.
//
// Threads: read() anywhere; the rest is const (any thread).
#ifndef SIMGATE_KIT_AUTH_H_
#define SIMGATE_KIT_AUTH_H_

#include <string>
#include <string_view>
#include <vector>

#include <boost/asio/ip/address.hpp>

#include "simgate/core/config.h"

namespace simgate::kit {

struct TokenAuth {
  bool enabled = false;   // "auth" was given
  bool loopback = false;  // ("loopback") loopback peers must authenticate too
  std::string token;      // the shared secret
  std::string source;     // where it came from, for messages: "file '/etc/simgate/token'"

  // Reads the "auth" object of `config` (absent: disabled); warnings (a token file others
  // may read) are appended to `warnings`. Throws ConfigError naming auth.token_file, ...
  static TokenAuth read(ConfigObject& config, std::vector<std::string>& warnings);

  // Whether a client connecting from `peer` must present the token.
  bool required_for(const boost::asio::ip::address& peer) const {
    return enabled && (loopback || !is_loopback(peer));
  }
  // Whether `presented` is the token; takes the same time whatever bytes differ.
  bool accepts(std::string_view presented) const;

  // 127.0.0.0/8, ::1, ::ffff:127.x.y.z.
  static bool is_loopback(const boost::asio::ip::address& address);
};

}  // namespace simgate::kit

#endif  // SIMGATE_KIT_AUTH_H_
