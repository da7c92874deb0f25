// sim_bench.cc — simulation speed: the gateway's step loop against a bare mj_step loop (the
// demo scene, Debian's humanoid with the generic components), and the laser_scanner's update
// against bare mj_ray calls.
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
//   laser    issue #18's laser_scanner target: a 360-ray scan (scan_window 360, resolution
//            1) from a robot in a furnished room (a scene built in), timed as the
//            component's update (LaserScanner::scan) against a bare loop of the same mj_ray
//            calls (same origin, directions, geom groups and excluded body), in alternating
//            batches for --duration seconds; also the whole get_local_data with its JSON.
//            Prints µs per scan (medians of the batches) and update speed / bare speed.
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
//   snapshot issue #19's snapshots: `simulation save_state` and `restore_state` on --mjcf
//            (run as a transport runs them: RequestManager::on_incoming_request, arguments
//            bound from JSON), against mj_copyData of the same model, in alternating batches
//            for --duration seconds. Prints µs per call (medians of the batches).
//   spawn    issue #19's spawn target: `simulation spawn_entity` of one free body on the
//            scene --mjcf (the demo's), from the request to its SUCCESS (validation, the
//            recompilation on the worker, the swap at the next step: the simulation steps as
//            fast as possible meanwhile), then `delete_entity` of it, in rounds for
//            --duration seconds (at least 20), each beside the edit alone
//            (with_entity, the worker's share, on the main thread) and a bare mj_loadXML
//            of the same scene. Prints ms p50 and p99 of the four.
//   progress issue #20's progress target: 100 concurrent JSON-RPC calls getting progress
//            reports at 1 kHz each, the real-time factor against the same calls without
//            progress, in alternating rounds for --duration seconds (progress_bench.cc).
//   streams  issue #21's stream targets: --calls components (50) streaming at 100 Hz on the
//            socket, JSON-RPC and (--dds) DDS transports at once, every stream read by a
//            client: the real-time factor and CPU against the same gateway without streams,
//            the latency from a step's end to a socket subscriber's read and the sync round
//            trip of the same run (stream_bench.cc).
//   camera_fps  issue #22's frame-rate target: frames/s of simgate's camera path (scene copy,
//            the Renderer's render thread, pixels read back; with and without the PNG record)
//            against a bare mjv_updateScene + mjr_render + mjr_readPixels loop on the same
//            kind of EGL context, 320x240 and 640x480, RGB and depth, on --mjcf seen from
//            --site (camera_bench.cc).
//   camera_rtf  issue #22's real-time-factor target: --config (config/rover.json) at real
//            time, --duration seconds without and then with a JSON-RPC subscriber to
//            --camera's image stream (camera_bench.cc).
//   web_poses  issue #23's browser target: --config (config/demo.json, the web app's) at
//            real time, --duration seconds without and then with --calls WebSocket clients
//            (20 browser pages) receiving the body poses at --frequency (60 Hz) (web_bench.cc).
//   foxglove_rtf  issue #38's Foxglove target: --mjcf (bench/pendulums50.xml) on the foxglove
//            transport at real time, --duration seconds without and then with --calls Foxglove
//            clients (4) receiving /tf at --frequency (60 Hz) and a 640x480 camera at 10 Hz
//            (foxglove_bench.cc).
//
// The probe costs one clock read per step; both modes run on the main thread, unpinned.
#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <mujoco/mujoco.h>

#include "bench_util.h"
#include "camera_bench.h"
#include "foxglove_bench.h"
#include "web_bench.h"
#include "progress_bench.h"
#include "stream_bench.h"
#include "simgate/core/component.h"
#include "simgate/core/log.h"
#include "simgate/gateway/deployment.h"
#include "simgate/gateway/gateway.h"
#include "simgate/sim/model_edit.h"
#include "simgate/sim/simulation.h"
#include "simgate/sim/native_sensors.h"
#include "simgate/sim/registry.h"
#include "simgate/sim/simulation.h"
#include "simgate/sim/supervision.h"

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

// Runs services in the calling thread (snapshot mode); outcomes are only counted.
class DirectManager : public simgate::RequestManager {
 public:
  DirectManager() : RequestManager("Bench service manager") {}
  // One sync call; throws unless it succeeded.
  simgate::json call(const std::string& service, simgate::json params = simgate::json::array()) {
    auto outcome =
        on_incoming_request(new_request_id(), {"simulation", service, std::move(params)});
    if (!outcome || outcome->status != simgate::Status::success)
      throw std::runtime_error("simulation " + service +
                               " failed: " + (outcome ? outcome->message : "async"));
    return outcome->value.value_or(simgate::json());
  }

 protected:
  void on_service_completion(simgate::RequestId, simgate::Outcome&&) override {}
};

json run_snapshot(const std::string& mjcf, double duration_s) {
  simgate::sim::Simulation sim(simgate::sim::Model::load_file(mjcf), {std::nullopt, 0.0});
  add_world_components(sim);
  auto rm = std::make_shared<DirectManager>();
  rm->register_component(*sim.find("simulation")->component);
  sim.add_request_manager(rm, "bench");
  std::lock_guard lock(*sim.gate());
  // a state worth saving: a second of motion
  for (int i = 0; i < 500; ++i) sim.step();
  mjData* copy = mj_makeData(sim.m());
  const std::int64_t handle = rm->call("save_state").get<std::int64_t>();

  constexpr int batch = 50;  // saves per batch: below the 64 states kept at once
  std::vector<double> save_us, restore_us, copy_us;
  auto per_call = [](Clock::time_point t0, Clock::time_point t1) {
    return std::chrono::duration<double, std::micro>(t1 - t0).count() / batch;
  };
  const auto end = Clock::now() + seconds(duration_s);
  while (Clock::now() < end || save_us.empty()) {
    std::vector<std::int64_t> handles;
    auto t0 = Clock::now();
    for (int i = 0; i < batch; ++i) handles.push_back(rm->call("save_state").get<std::int64_t>());
    auto t1 = Clock::now();
    save_us.push_back(per_call(t0, t1));
    for (auto h : handles) rm->call("drop_state", {h});

    t0 = Clock::now();
    for (int i = 0; i < batch; ++i) rm->call("restore_state", {handle});
    t1 = Clock::now();
    restore_us.push_back(per_call(t0, t1));

    t0 = Clock::now();
    for (int i = 0; i < batch; ++i) mj_copyData(copy, sim.m(), sim.d());
    t1 = Clock::now();
    copy_us.push_back(per_call(t0, t1));
  }
  mj_deleteData(copy);
  auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  return {{"mode", "snapshot"},
          {"batches", save_us.size()},
          {"save_state_us", median(save_us)},
          {"restore_state_us", median(restore_us)},
          {"mj_copyData_us", median(copy_us)},
          {"nq", sim.m()->nq},
          {"nv", sim.m()->nv}};
}

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

// A 6 x 4 m room with furniture, and a wheeled robot whose laser sits on a mast above its
// wheels (the usual mounting: no ray meets the robot, as in the bare loop).
constexpr const char* k_laser_room = R"(
<mujoco model="laser-bench-room">
  <worldbody>
    <geom type="plane" size="0 0 0.1"/>
    <geom type="box" pos="3.1 0 0.5" size="0.1 2.2 0.5"/>
    <geom type="box" pos="-3.1 0 0.5" size="0.1 2.2 0.5"/>
    <geom type="box" pos="0 2.1 0.5" size="3.2 0.1 0.5"/>
    <geom type="box" pos="0 -2.1 0.5" size="3.2 0.1 0.5"/>
    <geom type="box" pos="1.5 1.2 0.4" size="0.4 0.3 0.4"/>
    <geom type="cylinder" pos="-1.2 -0.8 0.5" size="0.2 0.5"/>
    <geom type="cylinder" pos="-2 1.4 0.5" size="0.15 0.5"/>
    <geom type="sphere" pos="2 -1.2 0.3" size="0.3"/>
    <geom type="capsule" fromto="-0.5 1.5 0.3 0.5 1.5 0.3" size="0.1"/>
    <body name="robot" pos="0 0 0.1">
      <freejoint/>
      <geom type="box" size="0.25 0.17 0.05" pos="0 0 0.06" mass="6"/>
      <geom type="sphere" size="0.05" pos="-0.2 0 -0.05" mass="0.2"/>
      <geom type="cylinder" size="0.03 0.1" pos="0.1 0 0.2" mass="0.1"/>
      <site name="laser" pos="0.1 0 0.3"/>
      <body name="left_wheel" pos="0.1 0.21 0">
        <joint type="hinge" axis="0 1 0"/>
        <geom type="cylinder" size="0.1 0.02" zaxis="0 1 0" mass="0.5"/>
      </body>
      <body name="right_wheel" pos="0.1 -0.21 0">
        <joint type="hinge" axis="0 1 0"/>
        <geom type="cylinder" size="0.1 0.02" zaxis="0 1 0" mass="0.5"/>
      </body>
    </body>
  </worldbody>
</mujoco>)";

json run_laser(double duration_s) {
  namespace sim = simgate::sim;
  sim::Simulation simulation(sim::Model::load_string(k_laser_room, "laser-bench-room.xml"),
                             sim::SimulationOptions{std::nullopt, 0.0});
  auto registry = sim::builtin_registry();
  auto robot = registry.create(sim::Kind::robot, {"robot", "robot", "robot", "robots[0]"},
                               json::object(), simulation, nullptr);
  auto component = registry.create(
      sim::Kind::component, {"robot.laser", "laser_scanner", "robot", "robots[0].components[0]"},
      json{{"site", "laser"}, {"scan_window", 360}, {"resolution", 1}}, simulation,
      static_cast<sim::Robot*>(robot.get()));
  auto& laser = static_cast<sim::LaserScanner&>(*component);
  for (int i = 0; i < 100; ++i) simulation.step();  // settled on its wheels
  const mjModel* m = simulation.m();
  const mjData* d = simulation.d();

  // the bare loop: the same rays, one mj_ray each, results kept as the component keeps them
  const std::vector<double>& local = laser.directions();
  const std::size_t rays = laser.ray_count();
  std::vector<double> bare_ranges(rays);
  auto bare_scan = [&] {
    const mjtNum* origin = laser.frame().position(d);
    const mjtNum* r = laser.frame().rotation(d);
    for (std::size_t i = 0; i < rays; ++i) {
      const double* l = &local[3 * i];
      const mjtNum world[3] = {r[0] * l[0] + r[1] * l[1], r[3] * l[0] + r[4] * l[1],
                               r[6] * l[0] + r[7] * l[1]};
      int geom = -1;
      bare_ranges[i] =
          mj_ray(m, d, origin, world, laser.geom_groups(), 1, laser.frame().body(), &geom, nullptr);
    }
  };
  // the two must agree before they are compared
  bare_scan();
  laser.scan();
  for (std::size_t i = 0; i < rays; ++i)
    if (std::abs((bare_ranges[i] < 0 ? 30.0 : bare_ranges[i]) - laser.ranges()[i]) > 1e-12)
      throw std::runtime_error("laser bench: ray " + std::to_string(i) + " reads " +
                               std::to_string(laser.ranges()[i]) + " m, the bare loop " +
                               std::to_string(bare_ranges[i]) + " m");

  // alternating batches, so that both see the same machine; medians of ns per scan
  constexpr int k_batch = 100;
  std::vector<std::int64_t> bare_ns, update_ns, json_ns;
  std::size_t json_bytes = 0;
  auto time_batch = [&](auto&& scan, std::vector<std::int64_t>& out) {
    auto start = Clock::now();
    for (int i = 0; i < k_batch; ++i) scan();
    out.push_back(simgate::bench::ns_between(start, Clock::now()) / k_batch);
  };
  auto end = Clock::now() + seconds(duration_s);
  while (Clock::now() < end || bare_ns.size() < 5) {
    time_batch(bare_scan, bare_ns);
    time_batch([&] { laser.scan(); }, update_ns);
    time_batch([&] { json_bytes = laser.get_local_data().dump().size(); }, json_ns);
  }
  auto median_us = [](std::vector<std::int64_t> v) {
    std::sort(v.begin(), v.end());
    return static_cast<double>(v[v.size() / 2]) / 1e3;
  };
  const double bare_us = median_us(bare_ns), update_us = median_us(update_ns),
               json_us = median_us(json_ns);
  return json{{"mode", "laser"},
              {"rays", rays},
              {"geoms", m->ngeom},
              {"batches", bare_ns.size()},
              {"bare_us_per_scan", bare_us},
              {"update_us_per_scan", update_us},
              {"update_speed_ratio", bare_us / update_us},
              {"get_local_data_us_per_scan", json_us},
              {"get_local_data_bytes", json_bytes}};
}

// ---- humanoid ------------------------------------------------------------------------------

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

// ---- spawn ----------------------------------------------------------------------------------

// Keeps the outcomes of the requests it submits (the simulation thread delivers them).
class SpawnBenchManager : public simgate::RequestManager {
 public:
  SpawnBenchManager() : RequestManager("spawn bench") {}
  ~SpawnBenchManager() override { stop(); }
  void stop() override { abandon_pending(); }
  simgate::RequestId call(const std::string& service, json params) {
    simgate::RequestId id = new_request_id();
    submit(id, simgate::Call{"simulation", service, std::move(params)});
    return id;
  }
  std::optional<simgate::Outcome> take(simgate::RequestId id) {
    auto it = outcomes_.find(id);
    if (it == outcomes_.end()) return std::nullopt;
    simgate::Outcome o = std::move(it->second);
    outcomes_.erase(it);
    return o;
  }

 protected:
  void on_service_completion(simgate::RequestId id, simgate::Outcome&& outcome) override {
    outcomes_[id] = std::move(outcome);
  }

 private:
  std::map<simgate::RequestId, simgate::Outcome> outcomes_;  // answered, not yet taken
};

json run_spawn(const std::string& mjcf, double duration) {
  using simgate::bench::ns_between;
  namespace sim = simgate::sim;
  sim::Simulation simulation(sim::Model::load_file(mjcf),
                             sim::SimulationOptions{std::nullopt, 0.0});
  add_world_components(simulation);
  auto manager = std::make_shared<SpawnBenchManager>();
  manager->register_component(*simulation.find("simulation")->component);
  simulation.add_request_manager(manager, "bench");
  // a request's nanoseconds from submission to its outcome, the loop stepping meanwhile
  auto timed = [&](const std::string& service, json params) {
    const auto start = Clock::now();
    const simgate::RequestId id = manager->call(service, std::move(params));
    for (;;) {
      simulation.process_requests();
      if (auto o = manager->take(id)) {
        if (o->status != simgate::Status::success)
          throw std::runtime_error(service + ": " + o->message);
        return ns_between(start, Clock::now());
      }
      simulation.step();
    }
  };
  const std::string ball = "<body><freejoint/><geom type='sphere' size='0.1' mass='1'/></body>";
  std::vector<std::int64_t> spawn, remove, compile, load;
  const auto end = Clock::now() + std::chrono::duration<double>(duration);
  while (Clock::now() < end || spawn.size() < 20) {
    spawn.push_back(timed("spawn_entity", json::array({"bench_ball", ball, {1.0, 1.0, 0.5}})));
    remove.push_back(timed("delete_entity", json::array({"bench_ball"})));
    // the worker's share alone: the same edit, on this thread
    auto start = Clock::now();
    sim::with_entity(sim::EditBase::of(simulation.model()), "bench_ball",
                     sim::entity_document(ball, "bench_ball", {}));
    compile.push_back(ns_between(start, Clock::now()));
    char error[1024] = "";
    start = Clock::now();
    mjModel* m = mj_loadXML(mjcf.c_str(), nullptr, error, sizeof error);
    load.push_back(ns_between(start, Clock::now()));
    if (!m) throw std::runtime_error(std::string("mj_loadXML: ") + error);
    mj_deleteModel(m);
  }
  auto ms = [](std::vector<std::int64_t> samples) {
    std::sort(samples.begin(), samples.end());
    return json{{"p50_ms", simgate::bench::quantile(samples, 0.5) / 1e6},
                {"p99_ms", simgate::bench::quantile(samples, 0.99) / 1e6}};
  };
  return json{{"mode", "spawn"},
              {"model", mjcf},
              {"rounds", spawn.size()},
              {"spawn_entity", ms(spawn)},
              {"delete_entity", ms(remove)},
              {"with_entity", ms(compile)},
              {"mj_loadXML", ms(load)},
              {"model_generation", simulation.model_generation()}};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Simulation speed: the gateway's step loop against a bare mj_step loop.",
               "simgate_bench_sim"};
  std::string mode, mjcf, config, record_dir;
  double factor = 0, duration = 2;
  bool until_stdin = false;
  double round_s = 1;
  int calls = 100;
  bool dds = false;
  simgate::bench::CameraFpsOptions camera_fps;
  std::string camera = "rover.camera";
  double frequency = 60;
  int copies = 1, threads = 1;
  app.add_option("--copies", copies, "bare: worlds of the model stepped")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  app.add_option("--threads", threads, "bare: threads stepping them")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  app.add_option("--mode", mode,
                 "bare, sleep, gateway, laser, humanoid, snapshot, spawn, progress, streams, "
                 "camera_fps, camera_rtf, web_poses or foxglove_rtf "
                 "(see the source's header)")
      ->required()
      ->check(CLI::IsMember({"bare", "sleep", "gateway", "laser", "humanoid", "snapshot", "spawn",
                             "progress", "streams", "camera_fps", "camera_rtf", "web_poses",
                             "foxglove_rtf"}));
  app.add_option("--site", camera_fps.site, "camera_fps: the site the view is from")
      ->capture_default_str();
  app.add_option("--frames", camera_fps.frames,
                 "camera_fps: frames per side, size and kind, at most")
      ->capture_default_str();
  app.add_option("--batch", camera_fps.batch, "camera_fps: frames of one side in a row")
      ->capture_default_str();
  app.add_option("--camera", camera, "camera_rtf: the camera component whose stream is subscribed")
      ->capture_default_str();
  app.add_option("--frequency", frequency,
                 "web_poses, foxglove_rtf: the body poses' samples per simulated second")
      ->capture_default_str();
  app.add_flag("--dds", dds, "streams: the DDS transport streams too");
  app.add_option("--round", round_s, "progress: simulated seconds each call runs")
      ->capture_default_str();
  app.add_option("--calls", calls,
                 "progress: concurrent calls, one connection each; streams: components; web_poses: "
                 "WebSocket clients; foxglove_rtf: Foxglove clients")
      ->capture_default_str();
  app.add_option(
      "--mjcf", mjcf,
      "bare, sleep, snapshot, spawn, progress, streams, camera_fps, foxglove_rtf: the MJCF "
      "scene; "
      "humanoid: another "
      "humanoid.xml");
  app.add_option("--config", config, "gateway, camera_rtf, web_poses: the deployment file");
  app.add_option("--realtime-factor", factor, "gateway: pacing (0 = as fast as possible)")
      ->capture_default_str();
  app.add_option("--duration", duration,
                 "seconds to run (camera_fps: per side, size and kind, at most)")
      ->capture_default_str();
  app.add_flag("--until-stdin-closes", until_stdin,
               "gateway: run until standard input closes instead");
  app.add_option("--record-dir", record_dir,
                 "gateway: let clients record into DIR (simulation start_recording NAME)");
  if (auto code = simgate::bench::parse_command_line(app, argc, argv)) return *code;
  if ((mode == "bare" || mode == "sleep" || mode == "snapshot" || mode == "spawn" ||
       mode == "progress" || mode == "streams" || mode == "camera_fps" || mode == "foxglove_rtf") &&
      mjcf.empty()) {
    std::cerr << "simgate_bench_sim: --mode " << mode << " needs --mjcf PATH\n";
    return 2;
  }
  if ((mode == "gateway" || mode == "camera_rtf" || mode == "web_poses") && config.empty()) {
    std::cerr << "simgate_bench_sim: --mode " << mode << " needs --config PATH\n";
    return 2;
  }
  try {
    json out;
    if (mode == "bare") {
      out = run_bare(mjcf, duration, copies, threads);
    } else if (mode == "sleep") {
      out = run_sleep(mjcf, duration);
    } else if (mode == "laser") {
      out = run_laser(duration);
    } else if (mode == "humanoid") {
      out = run_humanoid(mjcf, duration);
    } else if (mode == "snapshot") {
      out = run_snapshot(mjcf, duration);
    } else if (mode == "spawn") {
      out = run_spawn(mjcf, duration);
    } else if (mode == "progress") {
      out = simgate::bench::run_progress(mjcf, duration, round_s, calls);
    } else if (mode == "streams") {
      out = simgate::bench::run_streams(mjcf, duration, calls, 2000, dds);
    } else if (mode == "camera_fps") {
      camera_fps.mjcf = mjcf;
      camera_fps.seconds = duration;
      out = simgate::bench::run_camera_fps(camera_fps);
    } else if (mode == "camera_rtf") {
      out = simgate::bench::run_camera_rtf(config, camera, duration);
    } else if (mode == "web_poses") {
      out = simgate::bench::run_web_poses(config, calls, frequency, duration);
    } else if (mode == "foxglove_rtf") {
      out = simgate::bench::run_foxglove_rtf(mjcf, calls, frequency, duration);
    } else {
      out = run_gateway(config, factor, duration, until_stdin, record_dir);
    }
    std::cout << out.dump() << std::endl;
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "simgate_bench_sim: " << e.what() << "\n";
    return 1;
  }
}
