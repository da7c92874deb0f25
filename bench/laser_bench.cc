// laser_bench.cc — simgate_bench_sim's laser mode: the laser_scanner's update against bare
// mj_ray calls.
//
// Mode (--mode):
//   laser    issue #18's laser_scanner target: a 360-ray scan (scan_window 360, resolution
//            1) from a robot in a furnished room (a scene built in), timed as the
//            component's update (LaserScanner::scan) against a bare loop of the same mj_ray
//            calls (same origin, directions, geom groups and excluded body), in alternating
//            batches for --duration seconds; also the whole get_local_data with its JSON.
//            Prints µs per scan (medians of the batches) and update speed / bare speed.
#include "laser_bench.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include <mujoco/mujoco.h>

#include "simgate/sim/native_sensors.h"
#include "simgate/sim/registry.h"
#include "simgate/sim/simulation.h"

namespace simgate::bench {
namespace {

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

}  // namespace

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

}  // namespace simgate::bench
