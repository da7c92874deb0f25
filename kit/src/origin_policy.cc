#include "simgate/kit/origin_policy.h"

#include <algorithm>
#include <cctype>
#include <utility>  // before Asio: Boost 1.74 needs std::exchange in C++20 mode

#include <boost/asio/ip/address.hpp>

#include "simgate/core/errors.h"

namespace simgate::kit {

namespace {

std::string lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

// The host part of a normalized origin ("http://[::1]:80" -> "[::1]").
std::string_view host_of(std::string_view normalized) {
  const auto start = normalized.find("://") + 3;
  const auto colon = normalized.rfind(':');
  return normalized.substr(start, colon - start);
}

bool is_ip_literal(std::string_view host) {
  if (host.size() > 2 && host.front() == '[' && host.back() == ']')
    host = host.substr(1, host.size() - 2);
  boost::system::error_code ec;
  (void)boost::asio::ip::make_address(std::string(host), ec);
  return !ec;
}

}  // namespace

std::string OriginPolicy::normalize(std::string_view origin) {
  if (origin == "null" || origin == "*") return std::string(origin);
  const std::string o = lower(origin);
  const auto sep = o.find("://");
  if (sep == std::string::npos || sep == 0) return "";
  const std::string scheme = o.substr(0, sep);
  if (!std::all_of(scheme.begin(), scheme.end(), [](char c) {
        return std::isalnum(static_cast<unsigned char>(c)) || c == '+' || c == '-' || c == '.';
      }))
    return "";
  std::string rest = o.substr(sep + 3);
  if (rest.empty() || rest.find_first_of("/?#@ \t") != std::string::npos)
    return "";  // no path, no user
  std::string host = rest, port;
  if (rest.front() == '[') {  // [v6]:port
    const auto close = rest.find(']');
    if (close == std::string::npos) return "";
    host = rest.substr(0, close + 1);
    const std::string after = rest.substr(close + 1);
    if (!after.empty()) {
      if (after.front() != ':') return "";
      port = after.substr(1);
    }
  } else if (const auto colon = rest.find(':'); colon != std::string::npos) {
    host = rest.substr(0, colon);
    port = rest.substr(colon + 1);
  }
  if (host.empty() || host == "[]") return "";
  if (port.empty()) {
    if (scheme == "http" || scheme == "ws")
      port = "80";
    else if (scheme == "https" || scheme == "wss")
      port = "443";
    else
      return "";
  }
  if (port.size() > 5 ||
      !std::all_of(port.begin(), port.end(), [](char c) { return c >= '0' && c <= '9'; }) ||
      std::stoul(port) > 65535)
    return "";
  return scheme + "://" + host + ":" + std::to_string(std::stoul(port));
}

OriginPolicy OriginPolicy::take(json& options) {
  OriginPolicy p;
  if (!options.is_object()) return p;  // the JSON-RPC options say what is wrong with it
  auto it = options.find("allowed_origins");
  if (it == options.end()) return p;
  const json value = std::move(*it);
  options.erase(it);
  const std::string expected =
      "an array of origins (\"http://host:port\", \"null\", or \"*\" for any page), as browsers "
      "send them";
  if (!value.is_array())
    throw ConfigError("allowed_origins: expected " + expected + ", found " + value.dump());
  p.configured_ = true;
  for (std::size_t i = 0; i < value.size(); ++i) {
    const json& entry = value[i];
    const std::string n = entry.is_string() ? normalize(entry.get<std::string>()) : "";
    if (n.empty())
      throw ConfigError("allowed_origins[" + std::to_string(i) +
                        "]: expected an origin (scheme://host[:port], no path: " +
                        "\"http://127.0.0.1:8090\"), \"null\" or \"*\", found " + entry.dump());
    if (n == "*") p.any_ = true;
    p.list_.push_back(n);
  }
  return p;
}

void OriginPolicy::bind(const std::string& host, std::uint16_t port) {
  port_ = port;
  if (configured_) return;
  const std::string h = lower(host);
  every_interface_ = h == "0.0.0.0" || h == "::" || h == "[::]";
  std::vector<std::string> hosts = {"localhost", "127.0.0.1", "[::1]"};
  if (!every_interface_) {
    std::string own = h;
    if (own.find(':') != std::string::npos && own.front() != '[')
      own = "[" + own + "]";  // a v6 literal
    hosts.push_back(own);
  }
  for (const auto& name : hosts) list_.push_back("http://" + name + ":" + std::to_string(port));
}

bool OriginPolicy::allows(std::optional<std::string_view> origin) const {
  if (!origin) return true;  // not a browser
  if (any_) return true;
  const std::string n = normalize(*origin);
  if (n.empty() || n == "*") return false;
  if (std::find(list_.begin(), list_.end(), n) != list_.end()) return true;
  // bound everywhere, by default: a page this transport served, addressed by IP
  if (!configured_ && every_interface_ && n.starts_with("http://") &&
      n.ends_with(":" + std::to_string(port_)))
    return is_ip_literal(host_of(n));
  return false;
}

std::string OriginPolicy::describe() const {
  if (!configured_)
    return "the transport's own origins (http://localhost:" + std::to_string(port_) +
           " and the like)";
  std::string s;
  for (const auto& o : list_) s += (s.empty() ? "" : ", ") + o;
  return s.empty() ? "none" : s;
}

}  // namespace simgate::kit
