#include "simgate/core/log.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

namespace simgate::log {
namespace {

std::atomic<Level> g_level{Level::info};
std::mutex g_mutex;                                   // guards what follows, and stderr lines
std::function<void(Level, std::string_view)> g_sink;  // empty: stderr
// add_observer's, by handle
std::vector<std::pair<std::uint64_t, std::function<void(Level, std::string_view)>>> g_observers;
std::uint64_t g_next_observer = 1;

// The token bucket of set_rate_limit (under g_mutex).
struct RateLimit {
  using Clock = std::chrono::steady_clock;
  std::size_t burst = 200;  // 0: no limit
  double per_second = 50;   // refill
  double tokens = 200;      // lines that may pass now
  Clock::time_point refilled = Clock::now();
  std::size_t suppressed = 0;  // dropped since the last line that passed

  // Whether a line may pass now (takes its token).
  bool take() {
    if (burst == 0) return true;
    const auto now = Clock::now();
    tokens = std::min(static_cast<double>(burst),
                      tokens + std::chrono::duration<double>(now - refilled).count() * per_second);
    refilled = now;
    if (tokens < 1) return false;
    tokens -= 1;
    return true;
  }
};
RateLimit g_rate;

void emit_to_sink(Level level, std::string_view message) {
  if (g_sink) {
    g_sink(level, message);
    return;
  }
  // "12:00:01.234 warning socket: client 3 vanished"
  auto now = std::chrono::system_clock::now();
  std::time_t t = std::chrono::system_clock::to_time_t(now);
  auto ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000;
  std::tm tm{};
  localtime_r(&t, &tm);
  std::fprintf(stderr, "%02d:%02d:%02d.%03d %-7s %.*s\n", tm.tm_hour, tm.tm_min, tm.tm_sec,
               static_cast<int>(ms), to_string(level).data(), static_cast<int>(message.size()),
               message.data());
}

void emit(Level level, std::string_view message) {
  emit_to_sink(level, message);
  for (const auto& [handle, observer] : g_observers) observer(level, message);
}

}  // namespace

bool parse_level(std::string_view text, Level& out) {
  static constexpr std::pair<std::string_view, Level> names[] = {
      {"trace", Level::trace},     {"debug", Level::debug},  {"info", Level::info},
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

std::uint64_t add_observer(std::function<void(Level, std::string_view)> observer) {
  std::lock_guard lock(g_mutex);
  g_observers.emplace_back(g_next_observer, std::move(observer));
  return g_next_observer++;
}

void remove_observer(std::uint64_t handle) {
  std::lock_guard lock(g_mutex);
  std::erase_if(g_observers, [handle](const auto& o) { return o.first == handle; });
}

void set_rate_limit(std::size_t burst, double per_second) {
  std::lock_guard lock(g_mutex);
  g_rate.burst = burst;
  g_rate.per_second = per_second;
  g_rate.tokens = static_cast<double>(burst);
  g_rate.refilled = RateLimit::Clock::now();
}

void write(Level level, std::string_view message) {
  std::lock_guard lock(g_mutex);
  if (level >= Level::info) {
    if (!g_rate.take()) {
      ++g_rate.suppressed;
      return;
    }
    if (g_rate.suppressed > 0) {
      char per_second[32];
      std::snprintf(per_second, sizeof per_second, "%g", g_rate.per_second);
      emit(Level::warning, "log: " + std::to_string(g_rate.suppressed) +
                               " lines suppressed (more than " + per_second + " a second)");
      g_rate.suppressed = 0;
    }
  }
  emit(level, message);
}

}  // namespace simgate::log
