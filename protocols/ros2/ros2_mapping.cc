// simgate's data in ROS 2's terms: names, time, frames, transforms, samples. See ros2_mapping.h.
#include "ros2_mapping.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace simgate::ros2 {

namespace {

bool token_char(char c, bool first) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_' ||
         (!first && c >= '0' && c <= '9');
}

using Quat = std::array<double, 4>;  // w, x, y, z

Quat multiply(const Quat& a, const Quat& b) {
  return {a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
          a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
          a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
          a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]};
}

Quat conjugate(const Quat& q) { return {q[0], -q[1], -q[2], -q[3]}; }

Quat normalized(const Quat& q) {
  const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  if (!(n > 0) || !std::isfinite(n)) return {1, 0, 0, 0};
  return {q[0] / n, q[1] / n, q[2] / n, q[3] / n};
}

// v rotated by q
std::array<double, 3> rotate(const Quat& q, const std::array<double, 3>& v) {
  const Quat p = multiply(multiply(q, {0, v[0], v[1], v[2]}), conjugate(q));
  return {p[1], p[2], p[3]};
}

double number_at(const json& array, std::size_t i, const char* what) {
  const json& value = array.at(i);
  if (!value.is_number()) throw std::invalid_argument(std::string(what) + " is not a number");
  return value.get<double>();
}

Pose pose_from(const json& pos, const json& quat, const char* what) {
  if (!pos.is_array() || pos.size() != 3 || !quat.is_array() || quat.size() != 4)
    throw std::invalid_argument(std::string(what) + ": expected pos [x, y, z], quat [w, x, y, z]");
  Pose out;
  for (std::size_t i = 0; i < 3; ++i) out.position[i] = number_at(pos, i, what);
  for (std::size_t i = 0; i < 4; ++i) out.rotation[i] = number_at(quat, i, what);
  out.rotation = normalized(out.rotation);
  return out;
}

}  // namespace

bool is_ros_token(std::string_view name) {
  if (name.empty()) return false;
  for (std::size_t i = 0; i < name.size(); ++i)
    if (!token_char(name[i], i == 0)) return false;
  return true;
}

std::string to_ros_token(std::string_view name) {
  std::string out;
  if (name.empty() || (name[0] >= '0' && name[0] <= '9')) out += '_';
  for (char c : name) out += token_char(c, false) ? c : '_';
  return out;
}

std::string dds_topic_name(std::string_view topic) {
  if (!topic.empty() && topic.front() == '/') topic.remove_prefix(1);
  return "rt/" + std::string(topic);
}

std::string robot_of(std::string_view component) {
  const std::size_t dot = component.find('.');
  return dot == std::string_view::npos ? std::string() : std::string(component.substr(0, dot));
}

std::string component_frame(std::string_view component) {
  std::string out;
  while (true) {
    const std::size_t dot = component.find('.');
    out += to_ros_token(component.substr(0, dot));
    if (dot == std::string_view::npos) return out;
    out += '/';
    component.remove_prefix(dot + 1);
  }
}

RosTime to_ros_time(double seconds) {
  if (!std::isfinite(seconds) || seconds <= 0) return {};
  if (seconds >= static_cast<double>(std::numeric_limits<std::int32_t>::max()))
    return {std::numeric_limits<std::int32_t>::max(), 999'999'999u};
  double whole = std::floor(seconds);
  auto nanoseconds = static_cast<std::int64_t>(std::llround((seconds - whole) * 1e9));
  if (nanoseconds >= 1'000'000'000) {  // rounded up to the next second
    whole += 1;
    nanoseconds -= 1'000'000'000;
  }
  return {static_cast<std::int32_t>(whole), static_cast<std::uint32_t>(nanoseconds)};
}

std::array<double, 4> quaternion_from_rpy(double roll, double pitch, double yaw) {
  const double cr = std::cos(roll / 2), sr = std::sin(roll / 2);
  const double cp = std::cos(pitch / 2), sp = std::sin(pitch / 2);
  const double cy = std::cos(yaw / 2), sy = std::sin(yaw / 2);
  return {cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
          cr * cp * sy - sr * sp * cy};
}

Pose relative_pose(const Pose& parent, const Pose& child) {
  const Quat inverse = conjugate(parent.rotation);
  const std::array<double, 3> offset{child.position[0] - parent.position[0],
                                     child.position[1] - parent.position[1],
                                     child.position[2] - parent.position[2]};
  Pose out;
  out.position = rotate(inverse, offset);
  out.rotation = normalized(multiply(inverse, child.rotation));
  return out;
}

FrameTree FrameTree::from_geometry(const json& geometry, const std::string& world_frame) {
  if (!geometry.is_object()) throw std::invalid_argument("the scene geometry is not an object");
  FrameTree tree;
  tree.generation = geometry.value("generation", std::uint64_t{0});
  const json& bodies = geometry.at("bodies");
  if (!bodies.is_array() || bodies.empty())
    throw std::invalid_argument("the scene geometry has no bodies");
  const int count = static_cast<int>(bodies.size());
  for (int b = 0; b < count; ++b) {
    const json& body = bodies[static_cast<std::size_t>(b)];
    const int parent = body.at("parent").get<int>();
    if (parent < 0 || parent >= count || (b > 0 && parent >= b))
      throw std::invalid_argument("body " + std::to_string(b) + " has parent " +
                                  std::to_string(parent) + ", not an earlier body");
    tree.names.push_back(b == 0 ? world_frame : body.at("name").get<std::string>());
    tree.parents.push_back(parent);
  }
  if (geometry.contains("frames")) {
    for (const json& frame : geometry.at("frames")) {
      Fixed fixed;
      fixed.name = component_frame(frame.at("name").get<std::string>());
      fixed.body = frame.at("body").get<int>();
      if (fixed.body < 0 || fixed.body >= count)
        throw std::invalid_argument("frame '" + fixed.name + "' is on no body");
      fixed.pose = pose_from(frame.at("pos"), frame.at("quat"), "a component's frame");
      tree.fixed.push_back(std::move(fixed));
    }
  }
  return tree;
}

bool body_transforms(const json& sample, const FrameTree& tree, std::vector<FrameTransform>& out) {
  out.clear();
  if (!tree.known() || !sample.is_object()) return false;
  if (sample.value("generation", std::uint64_t{0}) != tree.generation) return false;
  const auto poses_it = sample.find("poses");
  if (poses_it == sample.end() || !poses_it->is_array() || poses_it->size() != tree.names.size())
    return false;
  const json& poses = *poses_it;
  std::vector<Pose> world(poses.size());
  try {
    for (std::size_t b = 0; b < poses.size(); ++b) {
      const json& p = poses[b];
      if (!p.is_array() || p.size() != 7) return false;
      for (std::size_t i = 0; i < 3; ++i) world[b].position[i] = number_at(p, i, "a pose");
      for (std::size_t i = 0; i < 4; ++i) world[b].rotation[i] = number_at(p, 3 + i, "a pose");
    }
  } catch (const std::exception&) {
    return false;
  }
  out.reserve(poses.size() - 1);
  for (std::size_t b = 1; b < poses.size(); ++b) {
    const auto parent = static_cast<std::size_t>(tree.parents[b]);
    out.push_back({&tree.names[parent], &tree.names[b], relative_pose(world[parent], world[b])});
  }
  return true;
}

std::vector<FrameTransform> fixed_transforms(const FrameTree& tree) {
  std::vector<FrameTransform> out;
  for (const FrameTree::Fixed& fixed : tree.fixed)
    out.push_back({&tree.names[static_cast<std::size_t>(fixed.body)], &fixed.name, fixed.pose});
  return out;
}

JointPositions joint_positions(const json& sample) {
  if (!sample.is_object()) throw std::invalid_argument("the joint sample is not an object");
  JointPositions out;
  for (const auto& [name, value] : sample.items()) {
    if (name == "timestamp") continue;
    if (!value.is_number())
      throw std::invalid_argument("joint '" + name + "' has no number for its position");
    out.names.push_back(name);
    out.positions.push_back(value.get<double>());
  }
  return out;
}

OdometryValues odometry_from_integrated(const std::array<double, 12>& v) {
  OdometryValues out;
  out.pose.position = {v[0], v[1], v[2]};
  out.pose.rotation = quaternion_from_rpy(v[3], v[4], v[5]);
  out.linear = {v[6], v[7], v[8]};
  out.angular = {v[9], v[10], v[11]};
  out.twist_known = true;
  return out;
}

OdometryValues odometry_from_pose(const std::array<double, 6>& v) {
  OdometryValues out;
  out.pose.position = {v[0], v[1], v[2]};
  out.pose.rotation = quaternion_from_rpy(v[3], v[4], v[5]);
  return out;
}

json velocity_command(double linear_x, double angular_z) {
  return {{"v", linear_x}, {"w", angular_z}};
}

JointCommand joint_command(const std::vector<std::string>& names,
                           const std::vector<double>& positions,
                           const std::vector<std::string>& joints) {
  JointCommand out;
  if (positions.empty()) return out;  // velocities or efforts only: nothing here
  if (positions.size() != names.size())
    throw std::invalid_argument(std::to_string(names.size()) + " names and " +
                                std::to_string(positions.size()) +
                                " positions (JointState: one position per name)");
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (std::find(joints.begin(), joints.end(), names[i]) == joints.end()) {
      out.unknown.push_back(names[i]);
      continue;
    }
    out.positions[names[i]] = positions[i];
  }
  return out;
}

// ---- cameras ----

ImageShape image_shape(const StreamPayload& payload) {
  if (payload.content != "image" || !payload.description.is_object())
    throw std::invalid_argument("the sample carries no image");
  const json& d = payload.description;
  ImageShape out;
  try {
    out.width = d.at("width").get<std::uint32_t>();
    out.height = d.at("height").get<std::uint32_t>();
    out.step = d.at("step").get<std::uint32_t>();
    out.encoding = d.at("encoding").get<std::string>();
    out.is_bigendian = d.value("is_bigendian", false);
  } catch (const json::exception& e) {
    throw std::invalid_argument(std::string("the image's description: ") + e.what());
  }
  if (static_cast<std::uint64_t>(out.step) * out.height != payload.bytes.size())
    throw std::invalid_argument("the image has " + std::to_string(payload.bytes.size()) +
                                " bytes, not height " + std::to_string(out.height) + " x step " +
                                std::to_string(out.step));
  return out;
}

CameraInfoValues camera_info_values(const json& description) {
  if (!description.is_object()) throw std::invalid_argument("the image has no description");
  CameraInfoValues out;
  const json& k = description.value("intrinsic_matrix", json());
  if (!k.is_array() || k.size() != 3)
    throw std::invalid_argument("intrinsic_matrix: not a 3x3 matrix");
  for (std::size_t row = 0; row < 3; ++row) {
    if (!k[row].is_array() || k[row].size() != 3)
      throw std::invalid_argument("intrinsic_matrix: not a 3x3 matrix");
    for (std::size_t column = 0; column < 3; ++column) {
      const json& v = k[row][column];
      if (!v.is_number()) throw std::invalid_argument("intrinsic_matrix: not numbers");
      out.k[3 * row + column] = v.get<double>();
      out.p[4 * row + column] = v.get<double>();  // P = [K | 0]: no baseline
    }
  }
  out.r = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  out.width = description.value("width", 0u);
  out.height = description.value("height", 0u);
  return out;
}

// ---- laser scans ----

LaserScanValues laser_scan_values(const json& sample, double frequency, LaserReading& reading) {
  if (!sample.is_object()) throw std::invalid_argument("the scan is not an object");
  const auto ranges = sample.find("range_list");
  if (ranges == sample.end() || !ranges->is_array() || ranges->empty())
    throw std::invalid_argument("the scan has no range_list");
  const std::size_t n = ranges->size();
  const auto points = sample.find("point_list");
  const bool has_points = points != sample.end() && points->is_array() && points->size() == n;
  if (has_points) reading.arc.read(*points, n);
  LaserScanValues out;
  out.ranges.reserve(n);
  double farthest = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const json& r = (*ranges)[i];
    if (!r.is_number()) throw std::invalid_argument("range_list: not numbers");
    const double range = r.get<double>();
    const json& p = has_points ? (*points)[i] : json();
    const bool miss = has_points && p.is_array() && p.size() >= 2 && p[0] == 0 && p[1] == 0 &&
                      (p.size() < 3 || p[2] == 0);
    if (miss) {
      reading.reach = range;  // MORSE: a miss reads the laser's range
      out.ranges.push_back(std::numeric_limits<float>::infinity());
    } else {
      farthest = std::max(farthest, range);
      out.ranges.push_back(static_cast<float>(range));
    }
  }
  const LaserArc::Angles angles = reading.arc.angles(n);
  out.angle_min = static_cast<float>(angles.start);
  out.angle_increment = static_cast<float>(angles.step);
  out.angle_max = static_cast<float>(angles.start + static_cast<double>(n - 1) * angles.step);
  out.scan_time = frequency > 0 ? static_cast<float>(1 / frequency) : 0.0f;
  out.range_min = 0;
  out.range_max = static_cast<float>(reading.reach > 0 ? reading.reach : farthest);
  return out;
}

}  // namespace simgate::ros2
