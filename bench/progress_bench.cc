// progress_bench.cc — issue #20's progress target for simgate_bench_sim --mode progress:
// progress reports at 1 kHz to 100 concurrent calls keep the simulation's real-time factor
// at 0.99 or more.
//
// A Gateway built as `simgate run` builds it, from an in-memory deployment: the scene --mjcf
// (the demo's) at real-time pacing with a 0.25 ms step, a JSON-RPC transport on an
// ephemeral loopback port with progress_interval_ms 1, and a robot `bench` with one
// component `bench.worker` of this file's type, whose concurrent async service
// `run(steps)` reports {"step": n} at every step while its call runs (when progress_due():
// at most once per millisecond per call: up to 1 kHz) and completes after `steps` steps.
//
// Rounds alternate for --duration seconds (at least one of each): `--calls` calls (100), one
// per TCP connection, all asking for progress (`_meta: {"progress": true}`) or none of them,
// each running --round seconds of simulated time. A round's real-time factor is the
// simulated time the loop advanced between sending the calls and the last response, over
// the wall time it took. Prints the medians of both kinds of round, their ratio, the target
// (the progress rounds' factor >= 0.99) and the notifications received per call per second.
//
// Threads: the gateway's loop runs on the calling thread (Gateway::run); the client runs on
// a thread of its own, with blocking sockets and poll(); bench.worker is touched only by the
// simulation thread (its service and default_action run under the simulation lock).
#include "progress_bench.h"

#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "simgate/core/component.h"
#include "simgate/core/log.h"
#include "simgate/gateway/deployment.h"
#include "simgate/gateway/gateway.h"
#include "simgate/sim/registry.h"
#include "simgate/sim/sim_component.h"
#include "simgate/sim/simulation.h"

namespace simgate::bench {
namespace {

// bench.worker: run(steps) reports each step while it runs (simulation thread only).
class ProgressWorker : public sim::SimComponent {
 public:
  explicit ProgressWorker(sim::ComponentContext& c) : SimComponent(c.name(), c.sim()) {
    add_async_service(
        "run",
        [this](Completion call, int steps) { calls_.push_back({std::move(call), steps, 0}); },
        {"steps"})
        .concurrent()
        .doc(
            "reports {step} every step (at most once per progress interval), ends after `steps` "
            "steps");
  }
  void default_action() override {
    std::erase_if(calls_, [](Running& r) {
      if (r.call.done()) return true;  // cancelled, or ended at shutdown
      if (++r.done >= r.steps) {
        r.call(Status::success, r.done);
        return true;
      }
      // nothing built for a call that did not ask, or before its interval has passed
      if (r.call.progress_due()) r.call.progress(json{{"step", r.done}});
      return false;
    });
  }

 private:
  struct Running {
    Completion call;
    int steps = 0;  // to take
    int done = 0;   // taken
  };
  std::vector<Running> calls_;
};

struct RoundResult {
  double realtime_factor = 0;
  std::uint64_t notifications = 0;  // rpc.progress received, all calls together
  std::uint64_t responses = 0;      // final responses received
  double wall_s = 0;
};

// One round: every connection sends one call, then everything is read until each has its
// response (bounded by `timeout`).
RoundResult run_round(sim::Simulation& simulation, const std::vector<int>& fds, bool progress,
                      int steps, double timestep, Clock::duration timeout) {
  RoundResult result;
  const std::uint64_t steps0 = simulation.steps();
  const auto start = Clock::now();
  for (std::size_t i = 0; i < fds.size(); ++i) {
    std::string line = R"({"jsonrpc":"2.0","method":"bench.worker.run","params":{"steps":)" +
                       std::to_string(steps) + (progress ? R"(,"_meta":{"progress":true}})" : "}") +
                       R"(,"id":)" + std::to_string(i) + "}\n";
    if (::send(fds[i], line.data(), line.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(line.size()))
      throw std::runtime_error("send failed");
  }
  std::vector<pollfd> polls;
  for (int fd : fds) polls.push_back({fd, POLLIN, 0});
  std::vector<std::string> pending(fds.size());
  std::vector<char> buffer(1 << 16);
  const auto deadline = start + timeout;
  while (result.responses < fds.size() && Clock::now() < deadline) {
    if (::poll(polls.data(), polls.size(), 100) <= 0) continue;
    for (std::size_t i = 0; i < polls.size(); ++i) {
      if (!(polls[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
      const ssize_t n = ::recv(fds[i], buffer.data(), buffer.size(), 0);
      if (n <= 0) throw std::runtime_error("a connection closed during the round");
      std::string& text = pending[i];
      text.append(buffer.data(), static_cast<std::size_t>(n));
      std::size_t begin = 0;
      for (std::size_t nl; (nl = text.find('\n', begin)) != std::string::npos; begin = nl + 1) {
        const std::string_view line(text.data() + begin, nl - begin);
        if (line.find("\"rpc.progress\"") != std::string_view::npos)
          ++result.notifications;
        else if (line.find("\"result\"") != std::string_view::npos)
          ++result.responses;
        else
          throw std::runtime_error("unexpected reply: " + std::string(line.substr(0, 200)));
      }
      text.erase(0, begin);
    }
  }
  const auto end = Clock::now();
  if (result.responses < fds.size())
    throw std::runtime_error("only " + std::to_string(result.responses) + " of " +
                             std::to_string(fds.size()) + " responses before the deadline");
  result.wall_s = std::chrono::duration<double>(end - start).count();
  result.realtime_factor =
      static_cast<double>(simulation.steps() - steps0) * timestep / result.wall_s;
  return result;
}

}  // namespace

json run_progress(const std::string& mjcf, double duration_s, double round_s, int calls) {
  namespace gw = simgate::gateway;
  log::set_level(log::Level::warning);
  // 4 kHz steps: a report passes at the first step 1 ms or more after the last one passed
  // (every 4th or 5th step when the loop keeps its pace; fewer when a busy host makes it
  // take its steps in bursts after a late wake-up, since the interval is wall time)
  constexpr double k_timestep = 0.00025;
  const json document = {
      {"scene", {{"mjcf", mjcf}, {"timestep", k_timestep}, {"realtime_factor", 1.0}}},
      {"transports",
       {{"jsonrpc",
         {{"plugin", "jsonrpc"},
          {"options", {{"host", "127.0.0.1"}, {"port", 0}, {"progress_interval_ms", 1}}}}}}},
      {"robots",
       json::array(
           {{{"name", "bench"},
             {"type", "robot"},
             {"body", "robot"},  // the demo's robot body: any body will do
             {"components", json::array({{{"name", "worker"}, {"type", "bench_progress"}}})}}})},
      {"services", {{"default", {"jsonrpc"}}}},
      {"log_level", "warning"}};
  const gw::Deployment deployment = gw::parse_deployment(document, ".");
  auto registry = sim::builtin_registry();
  registry.add<ProgressWorker>("bench_progress", sim::Kind::component,
                               "issue #20's progress benchmark");
  gw::Gateway gateway(deployment, registry, {});
  gateway.start();
  const std::uint16_t port = endpoint_port(gateway.endpoints().at("jsonrpc").at(0));

  const int steps = std::max(1, static_cast<int>(round_s / k_timestep));
  std::vector<double> plain, with_progress;
  std::uint64_t notifications = 0;
  double progress_wall = 0;
  std::string error;
  std::thread client([&] {
    std::vector<int> fds;
    try {
      for (int i = 0; i < calls; ++i) fds.push_back(connect_loopback(port));
      const auto timeout = std::chrono::duration_cast<Clock::duration>(
          std::chrono::duration<double>(round_s * 3 + 10));
      const auto end = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                          std::chrono::duration<double>(duration_s));
      // alternating, at least one round of each, at most 1000 in all
      for (int round = 0; round < 1000 && (round < 2 || Clock::now() < end); ++round) {
        const bool progress = round % 2 == 1;
        RoundResult r = run_round(gateway.simulation(), fds, progress, steps, k_timestep, timeout);
        (progress ? with_progress : plain).push_back(r.realtime_factor);
        if (progress) {
          notifications += r.notifications;
          progress_wall += r.wall_s;
        } else if (r.notifications) {
          throw std::runtime_error("calls that did not ask got progress notifications");
        }
      }
    } catch (const std::exception& e) {
      error = e.what();
    }
    for (int fd : fds) ::close(fd);
    gateway.stop();
  });
  gateway.run();
  client.join();
  gateway.shutdown();
  if (!error.empty()) throw std::runtime_error(error);

  const double plain_rtf = median(plain), progress_rtf = median(with_progress);
  return json{
      {"mode", "progress"},
      {"model", mjcf},
      {"timestep", k_timestep},
      {"calls", calls},
      {"round_s", round_s},
      {"rounds", {{"plain", plain.size()}, {"progress", with_progress.size()}}},
      {"realtime_factor", {{"plain", plain_rtf}, {"progress", progress_rtf}}},
      {"ratio", plain_rtf > 0 ? progress_rtf / plain_rtf : 0.0},
      {"progress_hz_per_call", progress_wall > 0 ? notifications / progress_wall / calls : 0.0},
      {"target", {{"realtime_factor_min", 0.99}, {"met", progress_rtf >= 0.99}}}};
}

}  // namespace simgate::bench
