#include "simgate/core/service_access.h"

#include <stdexcept>

namespace simgate {

namespace {

bool pattern_char(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
         c == '-' || c == '.' || c == '*';
}

// The character at `i` of "<component>.<service>", without building the string.
char qualified_at(std::string_view component, std::string_view service, std::size_t i) noexcept {
  if (i < component.size()) return component[i];
  if (i == component.size()) return '.';
  return service[i - component.size() - 1];
}

}  // namespace

ServiceAccess::ServiceAccess(std::optional<std::vector<std::string>> allow,
                             std::vector<std::string> deny, bool console)
    : allow_(std::move(allow)), deny_(std::move(deny)), console_(console) {
  auto check = [](const std::vector<std::string>& patterns, const char* list) {
    for (const auto& p : patterns)
      if (std::string why = pattern_error(p); !why.empty())
        throw std::invalid_argument(std::string(list) + " pattern '" + p + "' " + why);
  };
  if (allow_) check(*allow_, "allow");
  check(deny_, "deny");
}

std::string ServiceAccess::pattern_error(std::string_view pattern) {
  if (pattern.empty()) return "is empty";
  for (char c : pattern)
    if (!pattern_char(c))
      return "has a character other than letters, digits, '_', '-', '.' and '*'";
  if (pattern == "*") return "";
  if (pattern.find('.') == std::string_view::npos)
    return "has no '.' between a component and a service (\"" + std::string(pattern) +
           ".*\": every service of a component '" + std::string(pattern) + "'; \"*." +
           std::string(pattern) + "\": a service '" + std::string(pattern) + "' of any component)";
  if (pattern.front() == '.' || pattern.back() == '.' ||
      pattern.find("..") != std::string_view::npos)
    return "has an empty name between dots";
  return "";
}

bool ServiceAccess::matches(std::string_view pattern, std::string_view component,
                            std::string_view service) noexcept {
  // '*' only: the classic linear match that backtracks to the last star (no recursion, no
  // allocation; O(pattern x name) at worst)
  const std::size_t n = component.size() + 1 + service.size();
  std::size_t p = 0, s = 0;
  std::size_t star = std::string_view::npos, star_s = 0;
  while (s < n) {
    if (p < pattern.size() && pattern[p] == '*') {
      star = p++;
      star_s = s;
    } else if (p < pattern.size() && pattern[p] == qualified_at(component, service, s)) {
      ++p;
      ++s;
    } else if (star != std::string_view::npos) {
      p = star + 1;
      s = ++star_s;
    } else {
      return false;
    }
  }
  while (p < pattern.size() && pattern[p] == '*') ++p;
  return p == pattern.size();
}

bool ServiceAccess::allows(std::string_view component, std::string_view service) const noexcept {
  for (const auto& p : deny_)
    if (matches(p, component, service)) return false;
  if (!allow_) return true;
  for (const auto& p : *allow_)
    if (matches(p, component, service)) return true;
  return false;
}

std::string ServiceAccess::describe() const {
  auto list = [](const std::vector<std::string>& patterns) {
    std::string out;
    for (const auto& p : patterns) out += (out.empty() ? "" : ", ") + p;
    return out.empty() ? std::string("nothing") : out;
  };
  std::string out;
  if (allow_) out = "allow " + list(*allow_);
  if (!deny_.empty()) out += (out.empty() ? "" : "; ") + std::string("deny ") + list(deny_);
  if (!console_) out += (out.empty() ? "" : "; ") + std::string("no process-wide services");
  return out;
}

}  // namespace simgate
