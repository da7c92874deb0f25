// Paths of an armature's motions: sampling them, building one from a MORSE trajectory, and
// the checks every target passes before it may reach MuJoCo.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "simgate/core/errors.h"
#include "simgate/sim/armature.h"
#include "simgate/sim/bounds.h"
#include "helpers.h"

namespace simgate::sim {

namespace {

// Longest trajectory, and farthest start ahead of now: simulated seconds (11.6 days).
constexpr double k_max_duration = 1e6;

[[noreturn]] void refuse(const std::string& where, const std::string& message) {
  throw ServiceError(where + ": " + message, Failure::bad_arguments,
                     {{"parameter", "trajectory"}, {"where", where}});
}

// The array at `key` of `object` (points[i].positions...): `expected_size` finite numbers;
// nullopt when absent.
std::optional<std::vector<double>> numbers_at(const json& object, const std::string& key,
                                              const std::string& where, std::size_t expected_size,
                                              const std::string& expected_what) {
  auto it = object.find(key);
  if (it == object.end()) return std::nullopt;
  const std::string here = where + "." + key;
  if (!it->is_array()) refuse(here, "expected an array of numbers, found " + describe_json(*it));
  if (it->size() != expected_size)
    refuse(here, "has " + std::to_string(it->size()) + " values; expected " +
                     std::to_string(expected_size) + " (" + expected_what + ")");
  std::vector<double> out;
  out.reserve(it->size());
  for (std::size_t k = 0; k < it->size(); ++k) {
    const json& v = (*it)[k];
    if (!v.is_number())
      refuse(here + "[" + std::to_string(k) + "]", "expected a number, found " + describe_json(v));
    // even the values nobody uses: a NaN is a client's mistake to report, not to carry
    const double x = v.get<double>();
    if (!std::isfinite(x))
      refuse(here + "[" + std::to_string(k) + "]", number(x) + " is not a finite number");
    out.push_back(x);
  }
  return out;
}

// The armature joints a trajectory names, in its order (default: all of them).
std::vector<std::size_t> trajectory_joints(const json& trajectory, const JointSet& joints) {
  std::vector<std::size_t> out;
  auto it = trajectory.find("joint_names");
  if (it == trajectory.end()) {
    for (std::size_t i = 0; i < joints.size(); ++i) out.push_back(i);
    return out;
  }
  if (!it->is_array() || it->empty())
    refuse("joint_names", "expected a non-empty array of joint names, found " + describe_json(*it));
  std::set<std::size_t> seen;
  for (std::size_t k = 0; k < it->size(); ++k) {
    const std::string where = "joint_names[" + std::to_string(k) + "]";
    const json& name = (*it)[k];
    if (!name.is_string()) refuse(where, "expected a joint name, found " + describe_json(name));
    std::size_t j;
    try {
      j = joints.index_of(name.get<std::string>(), where);
    } catch (const ServiceError& e) {
      refuse(where, e.message());
    }
    if (!seen.insert(j).second) refuse(where, "joint '" + joints[j].name + "' is named twice");
    out.push_back(j);
  }
  return out;
}

}  // namespace

// ---- paths ---------------------------------------------------------------------------------

PathSample sample(const JointPath& path, bool hermite, double t) {
  const auto& k = path.knots;
  // the first knot after t; knots at t are behind it, so a jump at t has happened
  auto next = std::upper_bound(k.begin(), k.end(), t,
                               [](double time, const Knot& knot) { return time < knot.time; });
  if (next == k.begin()) return {k.front().position, 0};
  if (next == k.end()) return {k.back().position, 0};
  const Knot& a = *(next - 1);
  const Knot& b = *next;
  const double h = b.time - a.time;  // > 0: b.time > t >= a.time
  const double s = (t - a.time) / h;
  if (!hermite) return {a.position + s * (b.position - a.position), (b.position - a.position) / h};
  // cubic Hermite basis on [0, 1] and its derivative (divided by h for d/dt)
  const double s2 = s * s, s3 = s2 * s;
  const double h00 = 2 * s3 - 3 * s2 + 1, h10 = s3 - 2 * s2 + s, h01 = -2 * s3 + 3 * s2,
               h11 = s3 - s2;
  const double d00 = 6 * s2 - 6 * s, d10 = 3 * s2 - 4 * s + 1, d01 = -6 * s2 + 6 * s,
               d11 = 3 * s2 - 2 * s;
  return {h00 * a.position + h10 * h * a.velocity + h01 * b.position + h11 * h * b.velocity,
          (d00 * a.position + d01 * b.position) / h + d10 * a.velocity + d11 * b.velocity};
}

double Motion::end_time() const {
  double end = -std::numeric_limits<double>::infinity();
  for (const auto& p : paths) end = std::max(end, p.knots.back().time);
  return end;
}

// ---- targets -------------------------------------------------------------------------------

void require_reachable(const ArmatureJoint& joint, double target, const std::string& parameter) {
  const bool prismatic = joint.kind == JointKind::prismatic;
  bounds::require_within(parameter, target, prismatic ? bounds::position : bounds::angle,
                         unit_of(joint.kind));
  const std::string unit(unit_of(joint.kind));
  if (joint.limited && (target < joint.low || target > joint.high))
    throw ServiceError(
        parameter + " = " + number(target) + " is outside the range of joint '" + joint.name +
            "': [" + number(joint.low) + ", " + number(joint.high) + "] " + unit,
        Failure::bad_arguments,
        {{"parameter", parameter},
         {"expected",
          "a position within [" + number(joint.low) + ", " + number(joint.high) + "] " + unit}});
  const double ctrl = joint.gear * target;
  if (joint.servo >= 0 && joint.ctrl_limited && (ctrl < joint.ctrl_low || ctrl > joint.ctrl_high)) {
    // the servo's reach, in the joint's own unit
    double a = joint.ctrl_low / joint.gear, b = joint.ctrl_high / joint.gear;
    if (a > b) std::swap(a, b);
    throw ServiceError(
        parameter + " = " + number(target) + " is beyond what the position servo of joint '" +
            joint.name + "' can reach: [" + number(a) + ", " + number(b) + "] " + unit +
            " (its ctrlrange)",
        Failure::bad_arguments,
        {{"parameter", parameter},
         {"expected", "a position within [" + number(a) + ", " + number(b) + "] " + unit}});
  }
}

// ---- trajectories --------------------------------------------------------------------------

Motion parse_trajectory(const json& trajectory, const JointSet& joints, double now,
                        double clock_offset, const std::vector<double>& from) {
  if (!trajectory.is_object())
    throw ServiceError(
        "trajectory: expected an object {\"starttime\"?, \"points\": [...]}, found " +
            describe_json(trajectory),
        Failure::bad_arguments, {{"parameter", "trajectory"}});
  for (auto it = trajectory.begin(); it != trajectory.end(); ++it)
    if (it.key() != "starttime" && it.key() != "points" && it.key() != "joint_names")
      refuse(it.key(), "unknown field (a trajectory has starttime, joint_names and points)");

  // start: on `time now`'s scale; a past start (or none) is now, as in MORSE
  double start = now;
  if (auto it = trajectory.find("starttime"); it != trajectory.end() && !it->is_null()) {
    if (!it->is_number())
      refuse("starttime", "expected a number of seconds, found " + describe_json(*it));
    const double asked = it->get<double>();
    const double asked_sim = asked - clock_offset;
    if (!std::isfinite(asked) || !std::isfinite(asked_sim))
      refuse("starttime", "starttime = " + number(asked) + " is not a finite number of seconds");
    if (asked_sim - now > k_max_duration)
      refuse("starttime", "starttime = " + number(asked) + " is " + number(asked_sim - now) +
                              " s from now (time now: " + number(now + clock_offset) +
                              "); expected at most " + number(k_max_duration) + " s ahead");
    start = std::max(now, asked_sim);
  }

  const std::vector<std::size_t> order = trajectory_joints(trajectory, joints);
  std::vector<std::string> order_names;
  for (std::size_t j : order) order_names.push_back(joints[j].name);
  const std::string one_per_joint = "one per joint: " + join(order_names);

  auto points = trajectory.find("points");
  if (points == trajectory.end())
    refuse("points", "missing: a trajectory needs at least one point");
  if (!points->is_array())
    refuse("points", "expected an array of points, found " + describe_json(*points));
  if (points->empty()) refuse("points", "empty: a trajectory needs at least one point");

  Motion motion;
  for (std::size_t k = 0; k < order.size(); ++k)
    motion.paths.push_back({order[k], {{start, from[order[k]], 0}}});
  bool with_velocities = false;
  double previous_time = 0;
  for (std::size_t i = 0; i < points->size(); ++i) {
    const json& point = (*points)[i];
    const std::string where = "points[" + std::to_string(i) + "]";
    if (!point.is_object())
      refuse(where, "expected an object {\"positions\", \"time_from_start\"}, found " +
                        describe_json(point));
    for (auto it = point.begin(); it != point.end(); ++it)
      if (it.key() != "positions" && it.key() != "velocities" && it.key() != "accelerations" &&
          it.key() != "effort" && it.key() != "time_from_start")
        refuse(where + "." + it.key(),
               "unknown field (a point has positions, velocities, accelerations, effort and "
               "time_from_start)");

    // time: after the previous point's, within the longest trajectory
    auto t = point.find("time_from_start");
    if (t == point.end()) refuse(where + ".time_from_start", "missing: seconds from starttime");
    if (!t->is_number())
      refuse(where + ".time_from_start",
             "expected a number of seconds, found " + describe_json(*t));
    const double time = t->get<double>();
    bounds::require_between(where + ".time_from_start", time, 0, k_max_duration, "s");
    if (i > 0 && time <= previous_time)
      refuse(where + ".time_from_start", number(time) + " is not after points[" +
                                             std::to_string(i - 1) + "].time_from_start (" +
                                             number(previous_time) + "): times must increase");
    previous_time = time;

    // positions: one per joint, each reachable
    auto positions = numbers_at(point, "positions", where, order.size(), one_per_joint);
    if (!positions) refuse(where + ".positions", "missing: " + one_per_joint);
    for (std::size_t k = 0; k < order.size(); ++k)
      require_reachable(joints[order[k]], (*positions)[k],
                        where + ".positions[" + std::to_string(k) + "]");

    // velocities: for every point or for none (Hermite needs both ends of each segment)
    auto velocities = numbers_at(point, "velocities", where, order.size(), one_per_joint);
    if (i == 0) with_velocities = velocities.has_value();
    if (velocities.has_value() != with_velocities)
      refuse(where + ".velocities", std::string(velocities ? "given" : "missing") +
                                        " while points[0] has " +
                                        (with_velocities ? "them" : "none") +
                                        ": give velocities for every point or for none");
    for (std::size_t k = 0; velocities && k < order.size(); ++k) {
      const bool prismatic = joints[order[k]].kind == JointKind::prismatic;
      bounds::require_within(where + ".velocities[" + std::to_string(k) + "]", (*velocities)[k],
                             prismatic ? bounds::linear_speed : bounds::angular_speed,
                             prismatic ? "m/s" : "rad/s");
    }
    // accelerations and effort: MORSE ignores them, so do we; they must still be numbers
    numbers_at(point, "accelerations", where, order.size(), one_per_joint);
    numbers_at(point, "effort", where, order.size(), one_per_joint);

    for (std::size_t k = 0; k < order.size(); ++k)
      motion.paths[k].knots.push_back(
          {start + time, (*positions)[k], velocities ? (*velocities)[k] : 0.0});
  }
  motion.hermite = with_velocities;
  return motion;
}

}  // namespace simgate::sim
