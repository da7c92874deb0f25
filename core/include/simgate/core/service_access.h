// simgate/core/service_access.h — which services a transport lets its clients call: its
// allow and deny lists.
//
// The configuration's mapping decides which components a transport serves; a ServiceAccess
// narrows that down to services. A service is callable through a transport when
//   - the transport serves its component (it is registered with the RequestManager),
//   - it matches a pattern of `allow`, when there is an allow list, and
//   - it matches no pattern of `deny` (deny wins over allow).
//   - it is not process-wide (ServiceDescriptor::process_wide: `simulation quit`,
//     `terminate`, `set_log_level`, which end the process or change it for every client),
//     or the transport is a console (console()).
// The default ServiceAccess allows everything, and is a console.
//
// Consoles. Ending the process and blinding its log are the operator's, not any network
// client's: a deployment names the transports that may (a transport's "console" in the
// configuration; by default only the socket transport bound to a loopback address, the
// operator's telnet), and every other transport refuses process-wide services, with a
// reply that says why rather than "unknown service" (they are MORSE's, no secret).
//
// Patterns name services by their qualified name "component.service" ("simulation.quit",
// "robot.motion.set_speed"); '*' stands for any run of characters, dots included:
//   "simulation.*"  every service of `simulation`
//   "*.quit"        a service `quit` of any component
//   "robot.*"       every service of `robot` and of its components (robot.motion, ...)
//   "*"             every service
// A pattern is made of letters, digits, '_', '-', '.' and '*'; it has a '.' (a component
// and a service) unless it is "*", and no empty part between dots. Anything else is
// refused where the configuration is read, so a typo cannot pass for a rule.
//
// A RequestManager applies its ServiceAccess (RequestManager::set_access) wherever it looks
// services up: a call to a service it denies gets the answer an unknown service gets, and
// its descriptors (every transport's introspection) leave the service out.
//
// Threads: an immutable value once built; any thread may read it.
#ifndef SIMGATE_CORE_SERVICE_ACCESS_H_
#define SIMGATE_CORE_SERVICE_ACCESS_H_

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "simgate/core/service.h"

namespace simgate {

class ServiceAccess {
 public:
  // Allows everything.
  ServiceAccess() = default;
  // `allow`: nullopt for no allow list (everything not denied), else the patterns a service
  // must match one of (an empty list allows nothing). Throws std::invalid_argument naming
  // the first malformed pattern and why (pattern_error).
  // `console`: whether the transport serves process-wide services.
  ServiceAccess(std::optional<std::vector<std::string>> allow, std::vector<std::string> deny,
                bool console = true);

  // Why `pattern` is not a valid service pattern ("has no '.' between a component and a
  // service"), or "" when it is.
  static std::string pattern_error(std::string_view pattern);
  // Whether `pattern` matches the service `component`.`service` ('*': any characters).
  static bool matches(std::string_view pattern, std::string_view component,
                      std::string_view service) noexcept;

  // Whether the lists let a client call `component`.`service` (served or not: the mapping
  // is the RequestManager's part).
  bool allows(std::string_view component, std::string_view service) const noexcept;
  // Whether the lists and the console rule let a client call the service `d` describes.
  bool allows(const ServiceDescriptor& d) const noexcept {
    return (console_ || !d.process_wide) && allows(d.component, d.name);
  }
  // Whether `d` is refused only because it is process-wide and this is no console.
  bool refuses_as_no_console(const ServiceDescriptor& d) const noexcept {
    return !console_ && d.process_wide && allows(d.component, d.name);
  }
  // No allow list, no deny list, a console: nothing is filtered.
  bool allows_everything() const noexcept { return !allow_ && deny_.empty() && console_; }
  bool console() const noexcept { return console_; }

  const std::optional<std::vector<std::string>>& allow() const noexcept { return allow_; }
  const std::vector<std::string>& deny() const noexcept { return deny_; }
  // "allow simulation.*, robot.*; deny simulation.quit; no process-wide services" ("" when
  // it allows everything), for banners and logs.
  std::string describe() const;

 private:
  std::optional<std::vector<std::string>> allow_;  // patterns one of which a service must match
  std::vector<std::string> deny_;                  // patterns no service may match
  bool console_ = true;                            // serves process-wide services
};

}  // namespace simgate

#endif  // SIMGATE_CORE_SERVICE_ACCESS_H_
