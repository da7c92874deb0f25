#include "simgate/core/log.h"

#include <atomic>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <mutex>

namespace simgate::log {
namespace {

std::atomic<Level> g_level{Level::info};
std::mutex g_mutex;                                       // guards g_sink and stderr lines
std::function<void(Level, std::string_view)> g_sink;      // empty: stderr

}  // namespace

bool parse_level(std::string_view text, Level& out) {
  static constexpr std::pair<std::string_view, Level> names[] = {
      {"trace", Level::trace}, {"debug", Level::debug},     {"info", Level::info},
      {"warning", Level::warning}, {"warn", Level::warning}, {"error", Level::error},
      {"off", Level::off}};
  for (const auto& [name, level] : names)
    if (name == text) {
      out = level;
      return true;
    }
  return false;
}

std::string_view to_string(Level level) {
  switch (level) {
    case Level::trace: return "trace";
    case Level::debug: return "debug";
    case Level::info: return "info";
    case Level::warning: return "warning";
    case Level::error: return "error";
    case Level::off: return "off";
  }
  return "?";
}

void set_level(Level level) { g_level = level; }
Level level() { return g_level; }

void set_sink(std::function<void(Level, std::string_view)> sink) {
  std::lock_guard lock(g_mutex);
  g_sink = std::move(sink);
}

void write(Level level, std::string_view message) {
  std::lock_guard lock(g_mutex);
  if (g_sink) {
    g_sink(level, message);
    return;
  }
  // "12:00:01.234 warning socket: client 3 vanished"
  auto now = std::chrono::system_clock::now();
  std::time_t t = std::chrono::system_clock::to_time_t(now);
  auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000;
  std::tm tm{};
  localtime_r(&t, &tm);
  std::fprintf(stderr, "%02d:%02d:%02d.%03d %-7s %.*s\n", tm.tm_hour, tm.tm_min, tm.tm_sec,
               static_cast<int>(ms), to_string(level).data(), static_cast<int>(message.size()),
               message.data());
}

}  // namespace simgate::log
