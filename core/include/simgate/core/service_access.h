// simgate/core/service_access.h — which services a transport lets its clients call: its
// allow and deny lists.
//
// The configuration's mapping decides which components a transport serves; a ServiceAccess
// narrows that down to services. A service is callable through a transport when
//   - the transport serves its component (it is registered with the RequestManager),
//   - it matches a pattern of `allow`, when there is an allow list, and
//   - it matches no pattern of `deny` (deny wins over allow).
// The default ServiceAccess allows everything.
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

namespace simgate {

class ServiceAccess {
 public:
  // Allows everything.
  ServiceAccess() = default;
  // `allow`: nullopt for no allow list (everything not denied), else the patterns a service
  // must match one of (an empty list allows nothing). Throws std::invalid_argument naming
  // the first malformed pattern and why (pattern_error).
  ServiceAccess(std::optional<std::vector<std::string>> allow, std::vector<std::string> deny);

  // Why `pattern` is not a valid service pattern ("has no '.' between a component and a
  // service"), or "" when it is.
  static std::string pattern_error(std::string_view pattern);
  // Whether `pattern` matches the service `component`.`service` ('*': any characters).
  static bool matches(std::string_view pattern, std::string_view component, std::string_view service) noexcept;

  // Whether the lists let a client call `component`.`service` (served or not: the mapping
  // is the RequestManager's part).
  bool allows(std::string_view component, std::string_view service) const noexcept;
  // No allow list and no deny list: nothing is filtered.
  bool allows_everything() const noexcept { return !allow_ && deny_.empty(); }

  const std::optional<std::vector<std::string>>& allow() const noexcept { return allow_; }
  const std::vector<std::string>& deny() const noexcept { return deny_; }
  // "allow simulation.*, robot.*; deny simulation.quit" ("" when it allows everything), for
  // banners and logs.
  std::string describe() const;

 private:
  std::optional<std::vector<std::string>> allow_;  // patterns one of which a service must match
  std::vector<std::string> deny_;                  // patterns no service may match
};

}  // namespace simgate

#endif  // SIMGATE_CORE_SERVICE_ACCESS_H_
