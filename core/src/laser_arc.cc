// A laser's arc read from its hits (simgate/core/laser_arc.h).
#include "simgate/core/laser_arc.h"

#include <cmath>

namespace simgate {

namespace {

// MORSE's default resolution: 1°.
constexpr double k_default_step = M_PI / 180;

double coordinate(const json& point, std::size_t i) {
  return point.is_array() && i < point.size() && point[i].is_number() ? point[i].get<double>()
                                                                      : 0.0;
}

}  // namespace

bool LaserArc::read(const json& point_list, std::size_t rays) {
  if (!point_list.is_array() || point_list.size() != rays) return false;
  // the first and the last hit: the widest baseline
  std::size_t first = rays, last = rays;
  double first_angle = 0, last_angle = 0;
  for (std::size_t i = 0; i < rays; ++i) {
    const json& p = point_list[i];
    const double x = coordinate(p, 0), y = coordinate(p, 1);
    if (x == 0 && y == 0) continue;  // a miss
    const double angle = std::atan2(y, x);
    if (first == rays) {
      first = i;
      first_angle = angle;
    }
    last = i;
    last_angle = angle;
  }
  if (first == rays || last == first) return false;
  // the rays turn counterclockwise: the bearing grows from the first hit to the last
  double turn = last_angle - first_angle;
  if (turn <= 0) turn += 2 * M_PI;
  const double spacing = turn / static_cast<double>(last - first);
  if (!std::isfinite(spacing) || spacing <= 0) return false;
  step = spacing;
  start = std::remainder(first_angle - static_cast<double>(first) * spacing, 2 * M_PI);
  return true;
}

LaserArc::Angles LaserArc::angles(std::size_t rays) const {
  if (step > 0) return {start, step};
  const double n = static_cast<double>(rays);
  return {rays > 0 ? -(n - 1) / 2 * k_default_step : 0.0, k_default_step};
}

}  // namespace simgate
