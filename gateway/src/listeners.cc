#include "listeners.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "simgate/core/errors.h"
#include "simgate/kit/tcp_server.h"

namespace simgate::gateway {

namespace {

// The built-in TCP transports and their defaults (plugins/socket/README.md,
// plugins/jsonrpc/README.md, plugins/websocket/README.md, docs/transports/foxglove.md): all
// listen on 127.0.0.1 unless
// "host" says otherwise.
struct TcpPlugin {
  const char* name;  // the plugin's own name
  int default_port;  // without "port"
};
constexpr TcpPlugin k_tcp_plugins[] = {
    {"socket", 4000}, {"jsonrpc", 4001}, {"websocket", 8090}, {"foxglove", 8765}};
constexpr const char* k_default_host = "127.0.0.1";

// IPv4-mapped IPv6 addresses (::ffff:a.b.c.d) are the IPv4 address they map.
sockaddr_storage normalized(const sockaddr_storage& in) {
  if (in.ss_family != AF_INET6) return in;
  const auto& v6 = reinterpret_cast<const sockaddr_in6&>(in);
  if (!IN6_IS_ADDR_V4MAPPED(&v6.sin6_addr)) return in;
  sockaddr_storage out{};
  auto& v4 = reinterpret_cast<sockaddr_in&>(out);
  v4.sin_family = AF_INET;
  std::memcpy(&v4.sin_addr, &v6.sin6_addr.s6_addr[12], 4);
  return out;
}

bool is_wildcard(const sockaddr_storage& a) {
  if (a.ss_family == AF_INET)
    return reinterpret_cast<const sockaddr_in&>(a).sin_addr.s_addr == htonl(INADDR_ANY);
  if (a.ss_family == AF_INET6)
    return IN6_IS_ADDR_UNSPECIFIED(&reinterpret_cast<const sockaddr_in6&>(a).sin6_addr);
  return false;
}

bool same_address(const sockaddr_storage& a, const sockaddr_storage& b) {
  if (a.ss_family != b.ss_family) return false;
  if (a.ss_family == AF_INET)
    return reinterpret_cast<const sockaddr_in&>(a).sin_addr.s_addr ==
           reinterpret_cast<const sockaddr_in&>(b).sin_addr.s_addr;
  const auto& x = reinterpret_cast<const sockaddr_in6&>(a);
  const auto& y = reinterpret_cast<const sockaddr_in6&>(b);
  return std::memcmp(&x.sin6_addr, &y.sin6_addr, sizeof x.sin6_addr) == 0 &&
         x.sin6_scope_id == y.sin6_scope_id;
}

// Whether listening on both, on one port, fails on Linux (both transports set SO_REUSEADDR,
// which only forgives TIME_WAIT, and leave IPv6 sockets dual-stack): the same address, or a
// wildcard covering the other ("0.0.0.0" every IPv4 address, "::" every address).
bool overlap(const sockaddr_storage& a_in, const sockaddr_storage& b_in) {
  sockaddr_storage a = normalized(a_in), b = normalized(b_in);
  if (same_address(a, b)) return true;
  auto covers = [](const sockaddr_storage& wide, const sockaddr_storage& other) {
    if (!is_wildcard(wide)) return false;
    return wide.ss_family == AF_INET6 || other.ss_family == AF_INET;
  };
  return covers(a, b) || covers(b, a);
}

// "127.0.0.1", "::1".
std::string address_text(const sockaddr_storage& a) {
  char text[INET6_ADDRSTRLEN] = "?";
  if (a.ss_family == AF_INET) {
    inet_ntop(AF_INET, &reinterpret_cast<const sockaddr_in&>(a).sin_addr, text, sizeof text);
  } else {
    inet_ntop(AF_INET6, &reinterpret_cast<const sockaddr_in6&>(a).sin6_addr, text, sizeof text);
  }
  return text;
}

// "127.0.0.1:4000", "[::1]:4000".
std::string endpoint_text(const Listener& l) {
  std::string address = address_text(l.address);
  return (l.address.ss_family == AF_INET6 ? "[" + address + "]" : address) + ":" +
         std::to_string(l.port);
}

// Binds a throwaway TCP socket to `l`'s address on port 0 (never listening): the error the
// transport would get for the address itself, 0 if none.
int bind_error(const Listener& l) {
  int fd = ::socket(l.address.ss_family, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return errno;
  sockaddr_storage probe = l.address;
  if (probe.ss_family == AF_INET) {
    reinterpret_cast<sockaddr_in&>(probe).sin_port = 0;
  } else {
    reinterpret_cast<sockaddr_in6&>(probe).sin6_port = 0;
  }
  int error =
      ::bind(fd, reinterpret_cast<const sockaddr*>(&probe), l.address_size) == 0 ? 0 : errno;
  ::close(fd);
  return error;
}

}  // namespace

std::optional<Listener> listener_of(const std::string& plugin_name, const TransportConfig& t) {
  const TcpPlugin* plugin = nullptr;
  for (const auto& p : k_tcp_plugins)
    if (plugin_name == p.name) plugin = &p;
  if (!plugin || !t.options.is_object()) return std::nullopt;

  Listener l;
  l.transport = &t;
  l.host = k_default_host;
  l.port = plugin->default_port;
  if (auto it = t.options.find("host"); it != t.options.end() && it->is_string())
    l.host = it->get<std::string>();
  if (auto it = t.options.find("port"); it != t.options.end() && it->is_number_integer()) {
    l.port = it->get<int>();
    l.port_configured = true;
  }

  // resolved by the transports' own rule (the kit's), so that both see the same address; a
  // host that does not resolve is the plugin's own error, reported by its validate
  boost::asio::ip::tcp::endpoint endpoint;
  try {
    endpoint = kit::listen_endpoint(l.host, static_cast<std::uint16_t>(l.port));
  } catch (const ConfigError&) {
    return std::nullopt;
  }
  std::memcpy(&l.address, endpoint.data(), endpoint.size());
  l.address_size = static_cast<socklen_t>(endpoint.size());
  return l;
}

void check_listeners(const std::vector<Listener>& listeners, ConfigErrors& errors) {
  for (std::size_t i = 0; i < listeners.size(); ++i) {
    const Listener& l = listeners[i];
    const std::string& path = l.transport->path;
    // an address of this machine
    if (!is_wildcard(l.address)) {
      int error = bind_error(l);
      if (error == EADDRNOTAVAIL || error == EAFNOSUPPORT) {
        errors.add(path +
                   ".options.host: expected an address of this machine (127.0.0.1, ::1, one of its "
                   "interfaces', or 0.0.0.0 / :: for all), found '" +
                   l.host + "'" +
                   (l.host == address_text(l.address) ? "" : " (" + address_text(l.address) + ")") +
                   ": " + std::strerror(error));
        continue;
      }
    }
    // a port of its own
    if (l.port == 0) continue;
    for (std::size_t j = 0; j < i; ++j) {
      const Listener& other = listeners[j];
      if (other.port != l.port || !overlap(l.address, other.address)) continue;
      std::string mine = endpoint_text(l), theirs = endpoint_text(other);
      errors.add(path + ".options.port: expected a port no other transport listens on, found " +
                 std::to_string(l.port) + (l.port_configured ? "" : " (the default)") + ", which " +
                 other.transport->path + " listens on too (" +
                 (mine == theirs ? mine : theirs + " and " + mine + " overlap") +
                 "): choose another port, or 0 for any free one");
      break;
    }
  }
}

}  // namespace simgate::gateway
