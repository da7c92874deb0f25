// sim_bench.cc — simulation speed: the gateway's step loop against a bare mj_step loop.
//
// Modes (--mode):
//   bare     mj_loadXML(--mjcf) and mj_step in a tight loop for --duration seconds: the
//            physics alone, the ceiling of any loop on this scene.
//   gateway  a Gateway built from --config (deployment file) exactly as `simgate run`
//            builds it (builtin components, transports, mapping), plus one probe component
//            whose default_action() stamps the time of every step. Runs at
//            --realtime-factor (0 = as fast as possible) for --duration seconds, or until
//            its standard input closes with --until-stdin-closes (the harness drives
//            clients meanwhile). Prints {"endpoints": ...} when serving, then the results:
//            steps per second, real-time factor, overruns, and the jitter of the step
//            period (|interval - timestep/factor|, µs percentiles).
//   sleep    the machine's timer baseline for that jitter: a loop with no work that sleeps
//            until the next period (the MJCF's timestep, real time) for --duration seconds,
//            scheduling as the gateway's loop does; the same figures as `gateway`.
//
// The probe costs one clock read per step; both modes run on the main thread, unpinned.
#include <poll.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <iostream>
#include <string>
#include <thread>
#include <vector>

#include <mujoco/mujoco.h>

#include "bench_util.h"
#include "simgate/core/component.h"
#include "simgate/gateway/deployment.h"
#include "simgate/gateway/gateway.h"
#include "simgate/sim/registry.h"
#include "simgate/sim/simulation.h"

namespace {

using simgate::bench::Clock;
using simgate::bench::json;

// Stamps the wall time of every simulation step (simulation thread only).
class StepProbe : public simgate::Component {
 public:
  StepProbe() : Component("bench_probe") { stamps_.reserve(1 << 20); }
  void default_action() override {
    if (stamps_.size() < stamps_.capacity()) stamps_.push_back(Clock::now());
  }
  const std::vector<Clock::time_point>& stamps() const { return stamps_; }

 private:
  std::vector<Clock::time_point> stamps_;  // one per step, up to the reserved capacity
};

Clock::duration seconds(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
}

json run_bare(const std::string& mjcf, double duration_s) {
  char error[1000] = "";
  mjModel* m = mj_loadXML(mjcf.c_str(), nullptr, error, sizeof error);
  if (!m) throw std::runtime_error("MJCF '" + mjcf + "': " + error);
  mjData* d = mj_makeData(m);
  std::uint64_t steps = 0;
  auto start = Clock::now(), end = start + seconds(duration_s);
  Clock::time_point now = start;
  while (now < end) {
    for (int i = 0; i < 64; ++i) mj_step(m, d);
    steps += 64;
    now = Clock::now();
  }
  double wall = std::chrono::duration<double>(now - start).count();
  json out{{"mode", "bare"},
           {"steps", steps},
           {"wall_s", wall},
           {"steps_per_s", static_cast<double>(steps) / wall},
           {"timestep", m->opt.timestep},
           {"realtime_factor", static_cast<double>(steps) * m->opt.timestep / wall}};
  mj_deleteData(d);
  mj_deleteModel(m);
  return out;
}

// |interval - period| of consecutive stamps, in µs percentiles.
json period_jitter(const std::vector<Clock::time_point>& stamps, double period_ns) {
  std::vector<std::int64_t> deviation;
  for (std::size_t i = 1; i < stamps.size(); ++i) {
    double interval = static_cast<double>(simgate::bench::ns_between(stamps[i - 1], stamps[i]));
    deviation.push_back(static_cast<std::int64_t>(std::fabs(interval - period_ns)));
  }
  return simgate::bench::summarize_us(std::move(deviation));
}

json run_sleep(const std::string& mjcf, double duration_s) {
  char error[1000] = "";
  mjModel* m = mj_loadXML(mjcf.c_str(), nullptr, error, sizeof error);
  if (!m) throw std::runtime_error("MJCF '" + mjcf + "': " + error);
  const double timestep = m->opt.timestep;
  mj_deleteModel(m);
  // the gateway's pacing: a fixed schedule, resynchronised when k_max_lag behind
  const auto period = seconds(timestep);
  std::vector<Clock::time_point> stamps;
  std::uint64_t periods = 0, overruns = 0;
  auto start = Clock::now(), end = start + seconds(duration_s), next = start;
  for (auto now = start; now < end; now = Clock::now()) {
    if (now < next) {
      std::this_thread::sleep_until(next);
      continue;
    }
    stamps.push_back(now);
    ++periods;
    next += period;
    if (now - next > simgate::sim::Simulation::k_max_lag) {
      next = now;
      ++overruns;
    }
  }
  double wall = std::chrono::duration<double>(Clock::now() - start).count();
  return json{{"mode", "sleep"},
              {"periods", periods},
              {"wall_s", wall},
              {"timestep", timestep},
              {"realtime_factor", static_cast<double>(periods) * timestep / wall},
              {"overruns", overruns},
              {"jitter", period_jitter(stamps, timestep * 1e9)}};
}

json run_gateway(const std::string& config, double factor, double duration_s, bool until_stdin) {
  namespace gw = simgate::gateway;
  gw::Deployment deployment = gw::load_deployment(config);
  auto registry = simgate::sim::builtin_registry();
  gw::GatewayOptions options;
  options.realtime_factor = factor;
  gw::Gateway gateway(deployment, registry, options);
  auto probe_owned = std::make_unique<StepProbe>();
  StepProbe* probe = probe_owned.get();
  gateway.simulation().add_component(std::move(probe_owned), "bench_probe");
  gateway.start();
  std::cout << json{{"endpoints", gateway.endpoints()}}.dump() << std::endl;

  // stop after the duration, or when the harness closes our standard input
  std::atomic<bool> done{false};
  std::thread stopper([&] {
    auto deadline = Clock::now() + seconds(duration_s);
    char byte;
    while (!done.load() && Clock::now() < deadline) {
      if (!until_stdin) {
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
        continue;
      }
      pollfd p{0, POLLIN, 0};
      if (::poll(&p, 1, 20) > 0 && ::read(0, &byte, 1) <= 0) break;
    }
    gateway.stop();
  });
  gateway.run();
  done = true;
  stopper.join();
  auto stats = gateway.simulation().statistics();

  // jitter of the step period against the paced period
  const double period_ns = factor > 0 ? stats.timestep / factor * 1e9 : 0;
  json jitter = period_jitter(probe->stamps(), period_ns);
  json out{{"mode", "gateway"},
           {"steps", stats.steps},
           {"wall_s", stats.wall_time},
           {"steps_per_s", stats.wall_time > 0 ? static_cast<double>(stats.steps) / stats.wall_time : 0.0},
           {"timestep", stats.timestep},
           {"target_factor", factor},
           {"realtime_factor", stats.realtime_factor},
           {"overruns", stats.overruns},
           {"jitter", std::move(jitter)}};
  gateway.shutdown();
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Simulation speed: the gateway's step loop against a bare mj_step loop.", "simgate_bench_sim"};
  std::string mode, mjcf, config;
  double factor = 0, duration = 2;
  bool until_stdin = false;
  app.add_option("--mode", mode, "bare, sleep or gateway (see the source's header)")
      ->required()
      ->check(CLI::IsMember({"bare", "sleep", "gateway"}));
  app.add_option("--mjcf", mjcf, "bare, sleep: the MJCF scene");
  app.add_option("--config", config, "gateway: the deployment file");
  app.add_option("--realtime-factor", factor, "gateway: pacing (0 = as fast as possible)")->capture_default_str();
  app.add_option("--duration", duration, "seconds to run")->capture_default_str();
  app.add_flag("--until-stdin-closes", until_stdin, "gateway: run until standard input closes instead");
  if (auto code = simgate::bench::parse_command_line(app, argc, argv)) return *code;
  if ((mode == "bare" || mode == "sleep") && mjcf.empty()) {
    std::cerr << "simgate_bench_sim: --mode " << mode << " needs --mjcf PATH\n";
    return 2;
  }
  if (mode == "gateway" && config.empty()) {
    std::cerr << "simgate_bench_sim: --mode gateway needs --config PATH\n";
    return 2;
  }
  try {
    json out;
    if (mode == "bare") {
      out = run_bare(mjcf, duration);
    } else if (mode == "sleep") {
      out = run_sleep(mjcf, duration);
    } else {
      out = run_gateway(config, factor, duration, until_stdin);
    }
    std::cout << out.dump() << std::endl;
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "simgate_bench_sim: " << e.what() << "\n";
    return 1;
  }
}
