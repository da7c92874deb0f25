// simgate/kit/connection_rules.h — the rules on a TCP transport's connections that do not
// depend on how it frames its messages (ConnectionServer, connection.h, applies them to
// every TCP transport's connections):
//
//   PeerCounts  open connections by non-loopback address, against max_connections_per_peer
//               (loopback peers are the machine's own programs, all one address: not counted).
//   make_room   at max_connections, closes the connection idle longest once idle for
//               idle_evict_s; failing one, the one silent longest while it waits for replies
//               (a client holding every slot with calls that never end must not lock
//               everyone out: issue #17).
//   sweep_ticks a duration in sweeps of the connections (a timeout is that precise).
//
// Connections are counted in sweeps ("ticks"): each transport sweeps its connections every
// k_sweep and a connection remembers the tick of its last activity. Everything here runs on
// the transport's I/O thread.
#ifndef SIMGATE_KIT_CONNECTION_RULES_H_
#define SIMGATE_KIT_CONNECTION_RULES_H_

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <utility>  // before Asio: Boost 1.74 needs std::exchange in C++20 mode

#include <boost/asio/ip/address.hpp>

#include "simgate/core/log.h"
#include "simgate/kit/auth.h"

namespace simgate::kit {

// How often a transport sweeps its connections: timeouts are this precise.
inline constexpr std::chrono::milliseconds k_connection_sweep{250};

// `duration` in sweeps, at least one (a timeout shorter than a sweep waits for the next).
inline std::uint32_t sweep_ticks(std::chrono::milliseconds duration) {
  return static_cast<std::uint32_t>(std::max<std::int64_t>(
      1, (duration + k_connection_sweep - std::chrono::milliseconds(1)) / k_connection_sweep));
}

// Why the server ends a connection (Connection::end), for framings that tell the client (a
// WebSocket close code).
enum class Ending {
  refused,  // it broke a rule or made room for another (a wrong token, idle_evict_s): 1008
  timeout,  // it held the connection without use (idle_timeout_s, line_timeout_s): 1001
};

// Open connections by non-loopback address (max_connections_per_peer; 0: no limit).
class PeerCounts {
 public:
  explicit PeerCounts(std::size_t max_per_peer = 0) : max_(max_per_peer) {}
  // A connection from `peer` opened (counted when it is not loopback and there is a limit).
  void add(const boost::asio::ip::address& peer) {
    if (max_ > 0 && !TokenAuth::is_loopback(peer)) ++counts_[peer];
  }
  // A connection from `peer` (added before) closed.
  void remove(const boost::asio::ip::address& peer) {
    auto it = counts_.find(peer);
    if (it != counts_.end() && --it->second == 0) counts_.erase(it);
  }
  void clear() { counts_.clear(); }
  // Why one more connection from `peer` is refused, or "":
  // "too many connections from 192.0.2.7 (max_connections_per_peer 64)".
  std::string refusal_reason(const boost::asio::ip::address& peer) const {
    if (max_ == 0 || TokenAuth::is_loopback(peer)) return "";
    auto it = counts_.find(peer);
    if (it == counts_.end() || it->second < max_) return "";
    return "too many connections from " + peer.to_string() + " (max_connections_per_peer " +
           std::to_string(max_) + ")";
  }
  std::size_t count(const boost::asio::ip::address& peer) const {
    auto it = counts_.find(peer);
    return it == counts_.end() ? 0 : it->second;
  }

 private:
  std::size_t max_;                                         // 0: no limit
  std::map<boost::asio::ip::address, std::size_t> counts_;  // open connections by address
};

// At max_connections (the caller checked), makes room by closing one connection of
// `connections` (a range of shared_ptr<Connection>) idle for at least `limit` ticks
// (sweep_ticks(idle_evict_s)): the one idle longest, else the one silent longest while it
// waits for replies. `Connection` has idle_ticks(), silent_ticks(), unanswered(), label()
// and end(std::string_view reason, Ending). `who` names the transport in the warning logged.
// True when one was closed.
template <class Connections>
bool make_room(const Connections& connections, std::uint32_t limit, const std::string& who,
               std::size_t max_connections) {
  using Pointer = typename Connections::value_type;
  Pointer idlest, silentest;
  for (const auto& c : connections) {
    if (!idlest || c->idle_ticks() > idlest->idle_ticks()) idlest = c;
    if (!silentest || c->silent_ticks() > silentest->silent_ticks()) silentest = c;
  }
  const double sweep_s = k_connection_sweep.count() / 1000.0;
  if (idlest && idlest->idle_ticks() >= limit) {
    log::warning(who, ": ", idlest->label(), " closed to make room for a new connection: idle for ",
                 idlest->idle_ticks() * sweep_s, " s while ", max_connections,
                 " connections were open (idle_evict_s)");
    idlest->end("idle while the server was full", Ending::refused);
    return true;
  }
  if (silentest && silentest->silent_ticks() >= limit) {
    log::warning(who, ": ", silentest->label(),
                 " closed to make room for a new connection: silent for ",
                 silentest->silent_ticks() * sweep_s, " s with ", silentest->unanswered(),
                 " replies owed while ", max_connections, " connections were open (idle_evict_s)");
    silentest->end("silent while the server was full", Ending::refused);
    return true;
  }
  return false;
}

}  // namespace simgate::kit

#endif  // SIMGATE_KIT_CONNECTION_RULES_H_
