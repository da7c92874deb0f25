// simgate/core/log.h — one process-wide logger shared by the gateway and every plugin.
//
// libsimgate_core is a shared library, so plugins loaded with dlopen log through the same
// sink and level as the host. Thread-safe; a sink must not block for long.
#ifndef SIMGATE_CORE_LOG_H_
#define SIMGATE_CORE_LOG_H_

#include <functional>
#include <sstream>
#include <string>
#include <string_view>

namespace simgate::log {

enum class Level { trace, debug, info, warning, error, off };

// Parses "trace", "debug", "info", "warning" (or "warn"), "error", "off"; false otherwise.
bool parse_level(std::string_view text, Level& out);
std::string_view to_string(Level level);

void set_level(Level level);
Level level();
inline bool enabled(Level l) { return l >= level() && l != Level::off; }

// Replaces the sink (default: one line per message on stderr). Empty restores the default.
void set_sink(std::function<void(Level, std::string_view)> sink);

void write(Level level, std::string_view message);

// log::info("socket: listening on ", host, ":", port)
template <class... Args>
void at(Level l, const Args&... args) {
  if (!enabled(l)) return;
  std::ostringstream out;
  (out << ... << args);
  write(l, out.str());
}
template <class... Args> void trace(const Args&... a) { at(Level::trace, a...); }
template <class... Args> void debug(const Args&... a) { at(Level::debug, a...); }
template <class... Args> void info(const Args&... a) { at(Level::info, a...); }
template <class... Args> void warning(const Args&... a) { at(Level::warning, a...); }
template <class... Args> void error(const Args&... a) { at(Level::error, a...); }

}  // namespace simgate::log

#endif  // SIMGATE_CORE_LOG_H_
