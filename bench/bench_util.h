// bench_util.h — small helpers shared by the benchmark programs of bench/.
//
// Terms: a *sample* is one measured duration in nanoseconds; Summary reduces a set of
// samples to the figures the harness reports (count, mean, p50, p90, p99, max, in µs).
// parse_command_line() runs a program's CLI11 parser the same way for every program of
// bench/: each prints one JSON object on stdout (its results) and diagnostics on stderr, so
// the harness (bench/harness.py) can read them without scraping text.
//
// Threads: nothing here is shared between threads.
#ifndef SIMGATE_BENCH_BENCH_UTIL_H_
#define SIMGATE_BENCH_BENCH_UTIL_H_

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <cstdint>
#include <iostream>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

namespace simgate::bench {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

// Nanoseconds between two time points.
inline std::int64_t ns_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(b - a).count();
}

// `s` seconds as a Clock duration (deadlines: Clock::now() + seconds(duration_s)).
inline Clock::duration seconds(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
}

// The q-quantile (0..1) of sorted samples, nearest rank.
inline double quantile(const std::vector<std::int64_t>& sorted, double q) {
  if (sorted.empty()) return 0;
  auto rank = static_cast<std::size_t>(q * static_cast<double>(sorted.size() - 1) + 0.5);
  return static_cast<double>(sorted[std::min(rank, sorted.size() - 1)]);
}

// The median of v (the mean of the middle two for an even count), 0 when v is empty.
inline double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty()      ? 0
         : v.size() % 2 ? v[v.size() / 2]
                        : (v[v.size() / 2 - 1] + v[v.size() / 2]) / 2;
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

// CPU seconds this process has used (user + system), and the calling thread alone.
inline double process_cpu_s() {
  rusage usage{};
  ::getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
         static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec) / 1e6;
}
inline double thread_cpu_s() {
  timespec t{};
  ::clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + static_cast<double>(t.tv_nsec) / 1e9;
}

// One phase of a simulation running at real time beside a benchmark's client thread (the
// camera and web benches' "without" and "with"): `during(end)` runs on the client thread
// until `end` (`seconds` from now); `steps()` reads the simulation's step count. The
// real-time factor is the simulated time its steps covered over the wall time; the CPU is
// the process's minus the client thread's (what the simulation and its transports used).
struct RealtimePhase {
  double wall_s = 0;
  double realtime_factor = 0;
  double cpu_s = 0;
};
template <class Steps, class During>
void measure_realtime_phase(RealtimePhase& phase, double seconds, double timestep, Steps&& steps,
                            During&& during) {
  const auto start = Clock::now();
  const std::uint64_t steps0 = steps();
  const double cpu0 = process_cpu_s(), client0 = thread_cpu_s();
  during(start +
         std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds)));
  const std::uint64_t steps1 = steps();
  phase.wall_s = std::chrono::duration<double>(Clock::now() - start).count();
  phase.cpu_s = process_cpu_s() - cpu0 - (thread_cpu_s() - client0);
  phase.realtime_factor = static_cast<double>(steps1 - steps0) * timestep / phase.wall_s;
}

// The port of an endpoint as the transports print them: "tcp://127.0.0.1:4000" -> 4000.
inline std::uint16_t endpoint_port(const std::string& endpoint) {
  return static_cast<std::uint16_t>(std::stoi(endpoint.substr(endpoint.rfind(':') + 1)));
}

// A TCP connection to 127.0.0.1:`port`, TCP_NODELAY (its descriptor). Throws on failure.
inline int connect_loopback(std::uint16_t port) {
  int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) throw std::runtime_error("socket() failed");
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    ::close(fd);
    throw std::runtime_error("cannot connect to 127.0.0.1:" + std::to_string(port));
  }
  int one = 1;
  ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  return fd;
}

// Parses argv into `app`'s options. Returns nullopt to go on, or the exit code to return:
// 0 after --help, 2 after a usage error (printed on stderr; unknown options are errors, so
// a typo never passes silently).
inline std::optional<int> parse_command_line(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
    return std::nullopt;
  } catch (const CLI::Success& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << app.get_name() << ": " << e.what() << " (" << app.get_name()
              << " --help shows the options)\n";
    return 2;
  }
}

}  // namespace simgate::bench

#endif  // SIMGATE_BENCH_BENCH_UTIL_H_
