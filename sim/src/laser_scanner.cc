// laser_scanner: MORSE's SICK / Hokuyo laser range sensor, as a fan of mj_ray rays.
//
// Rays lie in the x-y plane of the sensor frame, from -scan_window/2 to +scan_window/2
// every `resolution` degrees (MORSE's arc: both ends included; a full 360° window keeps
// one ray where the two ends meet). Their directions in the sensor frame are computed
// once per configuration; a scan turns them into the world and casts them.
//
// Not seeing the robot itself: mj_ray leaves out the geoms of one body only, and a robot
// has several (chassis, wheels, mast). Each ray is cast leaving out the sensor's body; when
// it still meets a geom of the robot (any body of the robot's subtree), it is cast again
// from just past that surface, leaving out that geom's body, and the distances add up. A
// ray that meets nothing of the robot, the usual case, costs exactly one mj_ray.
#include <algorithm>
#include <cmath>

#include "simgate/core/errors.h"
#include "simgate/sim/bounds.h"
#include "simgate/sim/native_sensors.h"

namespace simgate::sim {

namespace {
// Bounds of the properties (and options): a laser sees from a millimetre to 10 km; the
// finest resolution keeps a full turn within 36 001 rays.
constexpr double k_min_range = 1e-3, k_max_range = 1e4;            // m
constexpr double k_max_window = 360;                               // degrees
constexpr double k_min_resolution = 1e-2, k_max_resolution = 360;  // degrees
// How far past a surface of the robot a re-cast starts: a step that always progresses,
// far below any distance a scan resolves.
constexpr double k_skip = 1e-9;  // m
}  // namespace

LaserScanner::LaserScanner(ComponentContext& c)
    : SimComponent(c.name(), c.sim()), frame_(SensorFrame::from(c)) {
  // MORSE's defaults (its generic LaserScanner and the Sick preset)
  laser_range_ = c.options().get_number("laser_range", 30, k_min_range, k_max_range);
  scan_window_ = c.options().get_number("scan_window", 180, 0, k_max_window);
  resolution_ = c.options().get_number("resolution", 1, k_min_resolution, k_max_resolution);
  geom_groups_.fill(1);
  if (auto groups = c.options().get_json("geom_groups")) {
    const std::string expected =
        "a list of geom groups, integers from 0 to " + std::to_string(mjNGROUP - 1);
    if (!groups->is_array()) c.options().fail("geom_groups", expected);
    geom_groups_.fill(0);
    for (const json& g : *groups) {
      if (!g.is_number_integer() || g.get<long long>() < 0 || g.get<long long>() >= mjNGROUP)
        c.options().fail("geom_groups", expected + "; found " + g.dump());
      geom_groups_[g.get<std::size_t>()] = 1;
    }
  }
  // the robot's own geoms: those of every body of its subtree
  const mjModel* m = c.sim().m();
  const int robot_body = c.robot().body();
  own_geom_.assign(m->ngeom, 0);
  for (int g = 0; g < m->ngeom; ++g)
    if (in_subtree(m, m->geom_bodyid[g], robot_body)) {
      own_geom_[g] = 1;
      ++own_geom_count_;
    }
  build_rays();

  add_service("get_local_data", &LaserScanner::get_local_data)
      .doc(
          "range_list (m, laser_range when nothing is hit) and point_list ([x, y, z] in the sensor "
          "frame, "
          "[0, 0, 0] when nothing is hit), one per ray");
  declare_output_stream("laser_scan", [this] { return get_local_data(); });
  // a settable number, checked as add_number_property does, then the rays rebuilt
  auto number = [this](const std::string& name, double& value, double low, double high,
                       const std::string& unit) {
    add_property(
        name, [&value] { return json(value); },
        [this, &value, name, low, high, unit](const json& v) {
          if (!v.is_number())
            throw ServiceError("property '" + name + "' is a number, found " + describe_json(v),
                               Failure::bad_arguments, {{"parameter", "prop_val"}});
          const double d = v.get<double>();
          bounds::require_between(name, d, low, high, unit);
          value = d;
          build_rays();
        });
  };
  number("laser_range", laser_range_, k_min_range, k_max_range, "m");
  number("scan_window", scan_window_, 0, k_max_window, "degrees");
  number("resolution", resolution_, k_min_resolution, k_max_resolution, "degrees");
  add_property("ray_count", [this] { return json(ray_count()); });
}

void LaserScanner::build_rays() {
  // MORSE's arc: from -window/2, every `resolution`, while not past +window/2
  std::size_t n = static_cast<std::size_t>(std::floor(scan_window_ / resolution_ + 1e-9)) + 1;
  // a full turn would cast its first ray twice
  if (n > 1 && (n - 1) * resolution_ >= 360 - 1e-9) --n;
  directions_.resize(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const double angle = (-scan_window_ / 2 + static_cast<double>(i) * resolution_) * M_PI / 180;
    directions_[3 * i] = std::cos(angle);
    directions_[3 * i + 1] = std::sin(angle);
    directions_[3 * i + 2] = 0;
  }
  ranges_.assign(n, laser_range_);
  points_.assign(3 * n, 0.0);
}

double LaserScanner::cast(const mjtNum* origin, const mjtNum* direction) const {
  const mjModel* m = model();
  const mjData* d = data();
  mjtNum start[3] = {origin[0], origin[1], origin[2]};
  double travelled = 0;
  int exclude = frame_.body();
  // each pass gets past one surface of the robot: at most two per geom (in and out)
  for (int pass = 0; pass <= 2 * own_geom_count_ + 1; ++pass) {
    int geom = -1;
    const mjtNum t =
        mj_ray(m, d, start, direction, geom_groups_.data(), 1, exclude, &geom, nullptr);
    if (t < 0 || geom < 0) return -1;
    const double distance = travelled + t;
    if (distance > laser_range_) return -1;
    if (!own_geom_[geom]) return distance;
    // a part of the robot: on from just past it, its body left out
    travelled = distance + k_skip;
    exclude = m->geom_bodyid[geom];
    for (int k = 0; k < 3; ++k) start[k] = origin[k] + travelled * direction[k];
  }
  return -1;
}

void LaserScanner::scan() {
  const mjData* d = data();
  const mjtNum* origin = frame_.position(d);
  const mjtNum* r = frame_.rotation(d);  // row-major, world from sensor
  const std::size_t n = ray_count();
  for (std::size_t i = 0; i < n; ++i) {
    const double* local = &directions_[3 * i];
    // local z is 0: the rays lie in the sensor's x-y plane
    const mjtNum world[3] = {r[0] * local[0] + r[1] * local[1], r[3] * local[0] + r[4] * local[1],
                             r[6] * local[0] + r[7] * local[1]};
    const double t = cast(origin, world);
    double* point = &points_[3 * i];
    if (t < 0) {
      // MORSE: nothing hit reads the full range, and the point (0, 0, 0)
      ranges_[i] = laser_range_;
      point[0] = point[1] = point[2] = 0;
    } else {
      ranges_[i] = t;
      for (int k = 0; k < 3; ++k) point[k] = t * local[k];
    }
  }
}

void LaserScanner::on_model_changed(const ModelRemap& remap) {
  frame_.remap(remap);
  // the robot's geoms where they are now; geoms spawned since are not the robot's
  std::vector<char> own(static_cast<std::size_t>(model()->ngeom), 0);
  for (int g = 0; g < static_cast<int>(own_geom_.size()); ++g)
    if (const int now = remap.geom_of(g); now >= 0)
      own[static_cast<std::size_t>(now)] = own_geom_[static_cast<std::size_t>(g)];
  own_geom_ = std::move(own);
  own_geom_count_ = static_cast<int>(std::count(own_geom_.begin(), own_geom_.end(), 1));
}

json LaserScanner::get_local_data() {
  scan();
  const std::size_t n = ray_count();
  json points = json::array();
  points.get_ref<json::array_t&>().reserve(n);
  for (std::size_t i = 0; i < n; ++i)
    points.push_back({points_[3 * i], points_[3 * i + 1], points_[3 * i + 2]});
  return {{"range_list", ranges_},
          {"point_list", std::move(points)},
          {"timestamp", sim().state_time()}};
}

SIMGATE_BUILTIN_TYPE(
    laser_scanner,
    builtin_type<LaserScanner>(
        "laser_scanner", Kind::component,
        "fan of mj_ray rays: get_local_data (range_list, point_list)",
        "docs/components/native-sensors.md",
        {{"site",
          {{"type", "string"}},
          "a MuJoCo site on the robot: the sensor's frame (default: the body's frame)"},
         {"laser_range",
          {{"type", "number"}, {"minimum", 1e-3}, {"maximum", 1e4}, {"default", 30}},
          "metres"},
         {"scan_window",
          {{"type", "number"}, {"minimum", 0}, {"maximum", 360}, {"default", 180}},
          "degrees"},
         {"resolution",
          {{"type", "number"}, {"minimum", 1e-2}, {"maximum", 360}, {"default", 1}},
          "degrees between rays"},
         {"geom_groups",
          {{"type", "array"}, {"items", {{"type", "integer"}, {"minimum", 0}, {"maximum", 5}}}},
          "the MuJoCo geom groups the laser sees (default all)"}}));

}  // namespace simgate::sim
