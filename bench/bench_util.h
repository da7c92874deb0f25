// bench_util.h — small helpers shared by the benchmark programs of bench/.
//
// Terms: a *sample* is one measured duration in nanoseconds; Summary reduces a set of
// samples to the figures the harness reports (count, mean, p50, p90, p99, max, in µs).
// Args is a minimal "--name value" parser: every program of bench/ prints one JSON object
// on stdout (its results) and diagnostics on stderr, so the harness (bench/harness.py) can
// read them without scraping text.
//
// Threads: nothing here is shared between threads.
#ifndef SIMGATE_BENCH_BENCH_UTIL_H_
#define SIMGATE_BENCH_BENCH_UTIL_H_

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace simgate::bench {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

// Nanoseconds between two time points.
inline std::int64_t ns_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(b - a).count();
}

// The q-quantile (0..1) of sorted samples, nearest rank.
inline double quantile(const std::vector<std::int64_t>& sorted, double q) {
  if (sorted.empty()) return 0;
  auto rank = static_cast<std::size_t>(q * static_cast<double>(sorted.size() - 1) + 0.5);
  return static_cast<double>(sorted[std::min(rank, sorted.size() - 1)]);
}

// Count, mean and percentiles of nanosecond samples, reported in microseconds.
inline json summarize_us(std::vector<std::int64_t> samples) {
  std::sort(samples.begin(), samples.end());
  double sum = 0;
  for (auto s : samples) sum += static_cast<double>(s);
  const double n = static_cast<double>(samples.size());
  return {{"n", samples.size()},
          {"mean_us", samples.empty() ? 0.0 : sum / n / 1e3},
          {"p50_us", quantile(samples, 0.50) / 1e3},
          {"p90_us", quantile(samples, 0.90) / 1e3},
          {"p99_us", quantile(samples, 0.99) / 1e3},
          {"max_us", samples.empty() ? 0.0 : static_cast<double>(samples.back()) / 1e3}};
}

// "--name value" options and bare flags; unknown names are reported by finish().
class Args {
 public:
  Args(int argc, char** argv) {
    for (int i = 1; i < argc; ++i) {
      std::string a = argv[i];
      if (a.rfind("--", 0) != 0) throw std::invalid_argument("unexpected argument '" + a + "'");
      if (i + 1 < argc && std::string(argv[i + 1]).rfind("--", 0) != 0)
        values_[a.substr(2)] = argv[++i];
      else
        values_[a.substr(2)] = "";
    }
  }
  std::string get(const std::string& name, const std::string& fallback) {
    used_.push_back(name);
    auto it = values_.find(name);
    return it == values_.end() ? fallback : it->second;
  }
  double number(const std::string& name, double fallback) {
    std::string text = get(name, "");
    if (text.empty()) return fallback;
    char* end = nullptr;
    double v = std::strtod(text.c_str(), &end);
    if (!end || *end) throw std::invalid_argument("--" + name + ": expected a number, found '" + text + "'");
    return v;
  }
  bool flag(const std::string& name) {
    used_.push_back(name);
    return values_.count(name) != 0;
  }
  // Throws for options no getter asked for (typos never pass silently).
  void finish() const {
    for (const auto& [k, v] : values_)
      if (std::find(used_.begin(), used_.end(), k) == used_.end())
        throw std::invalid_argument("unknown option --" + k);
  }

 private:
  std::map<std::string, std::string> values_;  // name (without dashes) -> value ("" for flags)
  std::vector<std::string> used_;              // names asked for
};

}  // namespace simgate::bench

#endif  // SIMGATE_BENCH_BENCH_UTIL_H_
