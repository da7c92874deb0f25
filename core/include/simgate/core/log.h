// simgate/core/log.h — one process-wide logger shared by the gateway and every plugin.
//
// libsimgate_core is a shared library, so plugins loaded with dlopen log through the same
// sink and level as the host. Thread-safe; a sink must not block for long.
#ifndef SIMGATE_CORE_LOG_H_
#define SIMGATE_CORE_LOG_H_

#include <cstddef>
#include <cstdint>
#include <functional>
#include <sstream>
#include <string>
#include <string_view>

#include "simgate/core/text.h"

namespace simgate::log {

enum class Level { trace, debug, info, warning, error, off };

// Parses "trace", "debug", "info", "warning" (or "warn"), "error", "off"; false otherwise.
bool parse_level(std::string_view text, Level& out);
std::string_view to_string(Level level);

void set_level(Level level);
Level level();
inline bool enabled(Level l) { return l >= level() && l != Level::off; }

// `text` as a client sent it, quoted for a log line (simgate/core/text.h).
using simgate::quoted_prefix;

// Replaces the sink (default: one line per message on stderr). Empty restores the default.
void set_sink(std::function<void(Level, std::string_view)> sink);

// Observers see every line the sink gets, after it (a transport's log channel: Foxglove's
// /log). Each is called on the thread that logs, under the logger's lock: it must be quick,
// must not block and must not log. add_observer returns the handle remove_observer takes;
// once remove_observer returns, that observer is never called again.
std::uint64_t add_observer(std::function<void(Level, std::string_view)> observer);
void remove_observer(std::uint64_t handle);

// Lines at info level and above pass at most `burst` at once and `per_second` on average
// (a token bucket; defaults 200 and 50): a flood (20 000 refused connections, a client
// sending garbage as fast as it can) cannot fill a disk. What is dropped is counted and
// said, as a warning, before the next line that passes: "log: 1234 lines suppressed (more
// than 50 a second)". Debug and trace lines, asked for, are never dropped. burst 0: no limit.
void set_rate_limit(std::size_t burst, double per_second);

void write(Level level, std::string_view message);

// log::info("socket: listening on ", host, ":", port)
template <class... Args>
void at(Level l, const Args&... args) {
  if (!enabled(l)) return;
  std::ostringstream out;
  (out << ... << args);
  write(l, out.str());
}
template <class... Args>
void trace(const Args&... a) {
  at(Level::trace, a...);
}
template <class... Args>
void debug(const Args&... a) {
  at(Level::debug, a...);
}
template <class... Args>
void info(const Args&... a) {
  at(Level::info, a...);
}
template <class... Args>
void warning(const Args&... a) {
  at(Level::warning, a...);
}
template <class... Args>
void error(const Args&... a) {
  at(Level::error, a...);
}

}  // namespace simgate::log

#endif  // SIMGATE_CORE_LOG_H_
