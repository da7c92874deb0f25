// simgate/kit/origin_policy.h — which web pages may open a WebSocket to the transport (the
// `allowed_origins` option), against cross-site WebSocket hijacking: a browser lets any page
// open a WebSocket to any address, and tells the server which site the page came from in the
// upgrade's `Origin` header; the server must refuse the sites it does not trust.
//
// The rule:
//   - an upgrade without `Origin` is allowed: browsers always send it, so it comes from a
//     program (a WebSocket library, curl), which no page drives;
//   - with `allowed_origins` absent, the transport's own origins are allowed: `http://H:P`
//     with P the bound port and H the bound host, `localhost`, `127.0.0.1` or `[::1]` (the
//     web app served on this port is one of them); bound to every interface (`0.0.0.0`,
//     `::`), also any IP literal on port P (a page this transport served to another
//     machine; a literal cannot be re-pointed by DNS at this machine, a name could);
//   - `allowed_origins` given (an array of `"scheme://host[:port]"`, `"null"`, or `"*"`:
//     any) replaces that list: matched case-insensitively, the default port of the scheme
//     implied (`http://a` is `http://a:80`).
//
// Life cycle: parsed from the options once (take()), completed with the bound port
// (bind()), then consulted by the I/O thread for each upgrade (allows()); immutable after.
#ifndef SIMGATE_KIT_ORIGIN_POLICY_H_
#define SIMGATE_KIT_ORIGIN_POLICY_H_

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "simgate/core/config.h"

namespace simgate::kit {

class OriginPolicy {
 public:
  // Takes "allowed_origins" out of `options` (so that the JSON-RPC parser does not see it)
  // and checks it. Throws ConfigError naming the key and the entry.
  static OriginPolicy take(json& options);

  // The transport listens on `host` (as configured) and `port` (bound): the default list.
  void bind(const std::string& host, std::uint16_t port);

  // Whether an upgrade whose Origin header is `origin` (nullopt: no header) is allowed.
  bool allows(std::optional<std::string_view> origin) const;

  // "the transport's own origins" or the configured list, for messages.
  std::string describe() const;

  // "scheme://host:port" lower-cased with the scheme's default port made explicit, or "" if
  // `origin` is not of that shape ("null" and "*" are returned as they are).
  static std::string normalize(std::string_view origin);

 private:
  bool configured_ = false;        // allowed_origins was given
  bool any_ = false;               // "*" among them
  std::vector<std::string> list_;  // normalized origins allowed
  std::uint16_t port_ = 0;         // the bound port (default list)
  bool every_interface_ = false;   // bound to 0.0.0.0 or :: (default list)
};

}  // namespace simgate::kit

#endif  // SIMGATE_KIT_ORIGIN_POLICY_H_
