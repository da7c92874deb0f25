// stepping_bench.cc — simgate_bench_sim's stepping modes: the gateway's step loop against a
// bare mj_step loop (the demo scene, Debian's humanoid with the generic components), and the
// machine's timer baseline for the loop's jitter.
//
// Modes (--mode):
//   bare     mj_loadXML(--mjcf) and mj_step in a tight loop for --duration seconds: the
//            physics alone, the ceiling of any loop on this scene. With --copies N
//            --threads T: N worlds of it (mjData each) stepped by T threads, world i by thread
//            i % T, one step each in turn (the `farm` section's baseline for step_many).
//   gateway  a Gateway built from --config (deployment file) exactly as `simgate run`
//            builds it (builtin components, transports, mapping), plus one probe component
//            whose default_action() stamps the time of every step. Runs at
//            --realtime-factor (0 = as fast as possible) for --duration seconds, or until
//            its standard input closes with --until-stdin-closes (the harness drives
//            clients meanwhile). Prints {"endpoints": ...} when serving, then the results:
//            steps per second, real-time factor, overruns, and the jitter of the step
//            period (|interval - timestep/factor|, µs percentiles). With --record-dir DIR,
//            clients may record into DIR (`simulation start_recording NAME`, as `simgate run
//            --record-dir` allows): issue #39's section alternates rounds with and without.
//   sleep    the machine's timer baseline for that jitter: a loop with no work that sleeps
//            until the next period (the MJCF's timestep, real time) for --duration seconds,
//            scheduling as the gateway's loop does; the same figures as `gateway`.
//   humanoid issue #18's stepping target: Debian's humanoid (--mjcf, default
//            /usr/share/mujoco/model/humanoid/humanoid.xml) with a robot on its torso and
//            the generic components, built from an in-memory deployment by the Gateway as
//            `simgate run` builds it (registry, an idle socket transport on an ephemeral
//            loopback port), run as fast as possible for exactly N steps, against N bare
//            mj_step calls on the same model, from the same initial state (the same physics,
//            step for step: no component acts unless asked), in alternating rounds for
//            --duration seconds. Two variants: the model as shipped (armature,
//            armature_pose, actuators, and pose and odometry for its free root: it has no
//            <sensor>) and a copy with 40 sensor values
//            added (every joint's jointpos, the torso's frame and subtree), which adds the
//            `sensors` component; the bare loop steps the same copy. Prints steps/s (medians)
//            and gateway / bare (median of the rounds' ratios) per variant.
//
// The probe costs one clock read per step; the gateway's loop and the bare loop (its thread 0)
// run on the main thread, unpinned.
#include "stepping_bench.h"

#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <mujoco/mujoco.h>

#include "simgate/core/component.h"
#include "simgate/core/log.h"
#include "simgate/gateway/deployment.h"
#include "simgate/gateway/gateway.h"
#include "simgate/sim/registry.h"
#include "simgate/sim/simulation.h"

namespace simgate::bench {
namespace {

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

// |interval - period| of consecutive stamps, in µs percentiles.
json period_jitter(const std::vector<Clock::time_point>& stamps, double period_ns) {
  std::vector<std::int64_t> deviation;
  for (std::size_t i = 1; i < stamps.size(); ++i) {
    double interval = static_cast<double>(simgate::bench::ns_between(stamps[i - 1], stamps[i]));
    deviation.push_back(static_cast<std::int64_t>(std::fabs(interval - period_ns)));
  }
  return simgate::bench::summarize_us(std::move(deviation));
}

}  // namespace

json run_bare(const std::string& mjcf, double duration_s, int copies, int threads) {
  char error[1000] = "";
  mjModel* m = mj_loadXML(mjcf.c_str(), nullptr, error, sizeof error);
  if (!m) throw std::runtime_error("MJCF '" + mjcf + "': " + error);
  // `copies` worlds of the model, world i stepped by thread i % threads, each thread stepping
  // its worlds in turn until the time is up: the ceiling of any loop stepping them
  std::vector<mjData*> data;
  for (int i = 0; i < copies; ++i) data.push_back(mj_makeData(m));
  std::vector<std::uint64_t> steps(static_cast<std::size_t>(threads), 0);
  const auto start = Clock::now(), end = start + seconds(duration_s);
  std::vector<Clock::time_point> ended(static_cast<std::size_t>(threads), start);
  const int steps_per_visit = copies == 1 ? 64 : 1;  // between two looks at the clock: 64+
  auto work = [&](int t) {
    Clock::time_point now = start;
    std::uint64_t taken = 0;
    while (now < end) {
      for (int i = t; i < copies; i += threads)
        for (int k = 0; k < steps_per_visit; ++k) mj_step(m, data[static_cast<std::size_t>(i)]);
      taken += static_cast<std::uint64_t>(steps_per_visit) *
               static_cast<std::uint64_t>((copies - t + threads - 1) / threads);
      now = Clock::now();
    }
    steps[static_cast<std::size_t>(t)] = taken;
    ended[static_cast<std::size_t>(t)] = now;
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(work, t);
  work(0);
  for (auto& th : pool) th.join();
  std::uint64_t total = 0;
  for (auto n : steps) total += n;
  const double wall =
      std::chrono::duration<double>(*std::max_element(ended.begin(), ended.end()) - start).count();
  json out{{"mode", "bare"},
           {"copies", copies},
           {"threads", threads},
           {"steps", total},
           {"wall_s", wall},
           {"steps_per_s", static_cast<double>(total) / wall},
           {"timestep", m->opt.timestep},
           {"realtime_factor", static_cast<double>(total) * m->opt.timestep / wall}};
  for (mjData* d : data) mj_deleteData(d);
  mj_deleteModel(m);
  return out;
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

json run_gateway(const std::string& config, double factor, double duration_s, bool until_stdin,
                 const std::string& record_dir) {
  namespace gw = simgate::gateway;
  gw::Deployment deployment = gw::load_deployment(config);
  auto registry = simgate::sim::builtin_registry();
  gw::GatewayOptions options;
  options.realtime_factor = factor;
  if (!record_dir.empty()) options.record_dir = std::filesystem::absolute(record_dir).string();
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
           {"steps_per_s",
            stats.wall_time > 0 ? static_cast<double>(stats.steps) / stats.wall_time : 0.0},
           {"timestep", stats.timestep},
           {"target_factor", factor},
           {"realtime_factor", stats.realtime_factor},
           {"overruns", stats.overruns},
           {"jitter", std::move(jitter)}};
  gateway.shutdown();
  return out;
}

// ---- humanoid ------------------------------------------------------------------------------

namespace {

constexpr const char* k_debian_humanoid = "/usr/share/mujoco/model/humanoid/humanoid.xml";

// Ends the gateway's loop after exactly `limit` steps: the loop checks for a stop before
// each step, and the last step's default_action asks for it (simulation thread).
class StepLimit : public simgate::Component {
 public:
  StepLimit(simgate::gateway::Gateway& gateway, std::uint64_t limit)
      : Component("bench_step_limit"), gateway_(gateway), limit_(limit) {}
  void default_action() override {
    if (++steps_ == limit_) gateway_.stop();
  }
  std::uint64_t steps() const { return steps_; }

 private:
  simgate::gateway::Gateway& gateway_;
  std::uint64_t limit_;
  std::uint64_t steps_ = 0;
};

// A copy of `mjcf` (in `dir`) with 40 sensor values before </mujoco>: each hinge's jointpos
// (21 in the humanoid) and the torso's position, orientation, velocities, and its subtree's
// centre of mass and velocity.
std::string with_sensors(const std::string& mjcf, const std::filesystem::path& dir) {
  std::ifstream in(mjcf);
  if (!in) throw std::runtime_error("cannot read '" + mjcf + "'");
  std::stringstream text;
  text << in.rdbuf();
  std::string xml = text.str();
  char error[1000] = "";
  mjModel* m = mj_loadXML(mjcf.c_str(), nullptr, error, sizeof error);
  if (!m) throw std::runtime_error("MJCF '" + mjcf + "': " + error);
  std::string sensors = "  <sensor>\n";
  int values = 0;
  for (int j = 0; j < m->njnt; ++j) {
    const char* name = mj_id2name(m, mjOBJ_JOINT, j);
    if (m->jnt_type[j] != mjJNT_HINGE || !name) continue;
    sensors += std::string("    <jointpos joint=\"") + name + "\"/>\n";
    ++values;
  }
  mj_deleteModel(m);
  for (const char* s : {"framepos", "framequat", "framelinvel", "frameangvel"})
    sensors += std::string("    <") + s + " objtype=\"xbody\" objname=\"torso\"/>\n";
  sensors += "    <subtreecom body=\"torso\"/>\n    <subtreelinvel body=\"torso\"/>\n  </sensor>\n";
  values += 3 + 4 + 3 + 3 + 3 + 3;
  if (values != 40)
    std::cerr << "simgate_bench_sim: the sensor block has " << values << " values, not 40\n";
  const auto end = xml.rfind("</mujoco>");
  if (end == std::string::npos) throw std::runtime_error("'" + mjcf + "' has no </mujoco>");
  xml.insert(end, sensors);
  const std::filesystem::path out = dir / "humanoid-with-sensors.xml";
  std::ofstream(out) << xml;
  return out.string();
}

// Seconds for `steps` bare mj_step calls from the model's initial state.
double time_bare(const std::string& mjcf, std::uint64_t steps) {
  char error[1000] = "";
  mjModel* m = mj_loadXML(mjcf.c_str(), nullptr, error, sizeof error);
  if (!m) throw std::runtime_error("MJCF '" + mjcf + "': " + error);
  mjData* d = mj_makeData(m);
  mj_forward(m, d);  // as the simulation's Model does at load
  const auto start = Clock::now();
  for (std::uint64_t i = 0; i < steps; ++i) mj_step(m, d);
  const double wall = std::chrono::duration<double>(Clock::now() - start).count();
  mj_deleteData(d);
  mj_deleteModel(m);
  return wall;
}

// Seconds for the gateway's loop, as fast as possible, to take `steps` steps from the
// initial state: a robot on the torso with `components` and an idle socket transport.
double time_gateway(const std::string& mjcf, const std::vector<std::string>& components,
                    std::uint64_t steps) {
  namespace gw = simgate::gateway;
  json robot = {
      {"name", "humanoid"}, {"type", "robot"}, {"body", "torso"}, {"components", json::array()}};
  for (const auto& c : components) robot["components"].push_back({{"name", c}, {"type", c}});
  const json document = {
      {"scene", {{"mjcf", mjcf}, {"realtime_factor", 0}}},
      {"transports",
       {{"socket", {{"plugin", "socket"}, {"options", {{"host", "127.0.0.1"}, {"port", 0}}}}}}},
      {"robots", json::array({robot})},
      {"services", {{"default", {"socket"}}}},
      {"log_level", "warning"}};
  const gw::Deployment deployment = gw::parse_deployment(document, ".");
  const auto registry = simgate::sim::builtin_registry();
  gw::Gateway gateway(deployment, registry, {});
  auto limit_owned = std::make_unique<StepLimit>(gateway, steps);
  StepLimit* limit = limit_owned.get();
  gateway.simulation().add_component(std::move(limit_owned), "bench_step_limit");
  gateway.start();
  const auto start = Clock::now();
  gateway.run();
  const double wall = std::chrono::duration<double>(Clock::now() - start).count();
  if (limit->steps() != steps)
    throw std::runtime_error("the gateway took " + std::to_string(limit->steps()) + " steps, not " +
                             std::to_string(steps));
  gateway.shutdown();
  return wall;
}

}  // namespace

json run_humanoid(const std::string& mjcf_arg, double duration_s) {
  // each round's gateway says where it listens: not worth a line
  simgate::log::set_level(simgate::log::Level::warning);
  const std::string stock = mjcf_arg.empty() ? k_debian_humanoid : mjcf_arg;
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("simgate-bench-humanoid-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  struct Variant {
    std::string name, mjcf;
    std::vector<std::string> components;
  };
  std::vector<Variant> variants = {{"stock", stock, {"armature", "armature_pose", "actuators"}},
                                   {"with_sensors",
                                    with_sensors(stock, dir),
                                    {"armature", "armature_pose", "actuators", "sensors"}}};
  // steps per round: about a tenth of the budget per variant and side
  const double rate = 2000 / time_bare(stock, 2000);
  constexpr int k_rounds = 7;
  const auto steps =
      static_cast<std::uint64_t>(std::max(1000.0, rate * duration_s / (4.0 * k_rounds)));
  json out = {
      {"mode", "humanoid"}, {"model", stock}, {"steps_per_round", steps}, {"rounds", k_rounds}};
  auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  for (const Variant& v : variants) {
    std::vector<double> bare, gateway, ratios;
    for (int round = 0; round < k_rounds; ++round) {
      // alternate which goes first: neither always gets a warm cache or a quieter moment
      double b = 0, g = 0;
      if (round % 2 == 0) {
        b = time_bare(v.mjcf, steps);
        g = time_gateway(v.mjcf, v.components, steps);
      } else {
        g = time_gateway(v.mjcf, v.components, steps);
        b = time_bare(v.mjcf, steps);
      }
      bare.push_back(static_cast<double>(steps) / b);
      gateway.push_back(static_cast<double>(steps) / g);
      ratios.push_back(b / g);
    }
    out["variants"][v.name] = {{"components", v.components},
                               {"bare_steps_per_s", median(bare)},
                               {"gateway_steps_per_s", median(gateway)},
                               {"ratio", median(ratios)},
                               {"ratio_min", *std::min_element(ratios.begin(), ratios.end())},
                               {"ratio_max", *std::max_element(ratios.begin(), ratios.end())}};
  }
  std::filesystem::remove_all(dir);
  return out;
}

}  // namespace simgate::bench
