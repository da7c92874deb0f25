// The samples of the streams as ROS 2 messages (Ros2Topics::write_samples, on the DDS thread):
// /tf from body_poses through the world's frame tree and its /tf_static, odometry (or a pose)
// as nav_msgs/Odometry, joint_states, imu, a camera's image_raw with its camera_info and a
// laser's scan, each filled member by member from the sample and written. Which stream becomes
// which topic: ros2_topics.cc.
#include <algorithm>
#include <array>
#include <stdexcept>
#include <string_view>
#include <vector>

#include "dds_support.h"
#include "ros2_msgs.h"
#include "ros2_topic_endpoints.h"
#include "ros2_topics.h"
#include "simgate/core/log.h"

namespace simgate::ros2 {

namespace {

char* c_str(const std::string& s) { return const_cast<char*>(s.c_str()); }

// The message structs are filled member by member, by name: never by position, so that the
// code does not depend on the order of the IDL's fields (which is the wire's).
builtin_interfaces_msg_dds__Time_ stamp(double seconds) {
  const RosTime t = to_ros_time(seconds);
  builtin_interfaces_msg_dds__Time_ out{};
  out.sec = t.sec;
  out.nanosec = t.nanosec;
  return out;
}

geometry_msgs_msg_dds__Vector3_ vector3(const std::array<double, 3>& v) {
  geometry_msgs_msg_dds__Vector3_ out{};
  out.x = v[0];
  out.y = v[1];
  out.z = v[2];
  return out;
}

geometry_msgs_msg_dds__Point_ point(const std::array<double, 3>& v) {
  geometry_msgs_msg_dds__Point_ out{};
  out.x = v[0];
  out.y = v[1];
  out.z = v[2];
  return out;
}

// (w, x, y, z) as ROS's Quaternion
geometry_msgs_msg_dds__Quaternion_ quaternion(const std::array<double, 4>& q) {
  geometry_msgs_msg_dds__Quaternion_ out{};
  out.w = q[0];
  out.x = q[1];
  out.y = q[2];
  out.z = q[3];
  return out;
}

void fill(geometry_msgs_msg_dds__TransformStamped_& out, const FrameTransform& in, double time) {
  out.header.stamp = stamp(time);
  out.header.frame_id = c_str(*in.parent);
  out.child_frame_id = c_str(*in.child);
  out.transform.translation = vector3(in.pose.position);
  out.transform.rotation = quaternion(in.pose.rotation);
}

dds_return_t write_transforms(dds_entity_t writer, const std::vector<FrameTransform>& transforms,
                              double time) {
  std::vector<geometry_msgs_msg_dds__TransformStamped_> items(transforms.size());
  for (std::size_t i = 0; i < transforms.size(); ++i) fill(items[i], transforms[i], time);
  tf2_msgs_msg_dds__TFMessage_ message{};
  message.transforms._maximum = message.transforms._length = static_cast<uint32_t>(items.size());
  message.transforms._buffer = items.data();
  message.transforms._release = false;
  return dds_write(writer, &message);
}

const char* role_name(int role) {
  static const char* const k_names[] = {"/tf", "odom",      "odom", "joint_states",
                                        "imu", "image_raw", "scan"};
  return k_names[role];
}

// A ROS sequence over `data`'s elements (not copied, not released by the writer).
template <typename Sequence, typename T>
void borrow(Sequence& sequence, T* data, std::size_t count) {
  sequence._maximum = sequence._length = static_cast<uint32_t>(count);
  sequence._buffer = data;
  sequence._release = false;
}

}  // namespace

void Ros2Topics::write_static(Output& output) {
  if (!output.frames.known() || output.static_written == output.frames.generation) return;
  const std::vector<FrameTransform> fixed = fixed_transforms(output.frames);
  const dds_return_t rc = write_transforms(output.static_writer, fixed, hub_->time());
  if (rc < 0) {
    log::error("ros2 transport: ", output.topic, "_static not written: ", dds::retcode_text(rc));
    return;
  }
  output.static_written = output.frames.generation;
}

void Ros2Topics::write_samples() {
  for (auto& [component, output] : outputs_) {
    if (!output->subscription) continue;  // a pushed stream nobody reads
    taken_.clear();
    output->subscription->take(taken_);
    for (const SamplePtr& sample : taken_) {
      dds_return_t rc = 0;
      try {
        switch (output->role) {
          case Role::tf: rc = write_tf(*output, *sample); break;
          case Role::odometry:
          case Role::pose_odometry: rc = write_odometry(*output, *sample); break;
          case Role::joint_states: rc = write_joint_states(*output, *sample); break;
          case Role::imu: rc = write_imu(*output, *sample); break;
          case Role::image: rc = write_image(*output, *sample); break;
          case Role::laser_scan: rc = write_scan(*output, *sample); break;
        }
      } catch (const std::exception& e) {
        // a component whose samples do not have its kind's shape (a component library's)
        if (!output->shape_logged)
          log::warning("ros2 transport: a sample of ", component, " does not fit ",
                       role_name(static_cast<int>(output->role)), " (", e.what(),
                       "); such samples are dropped (logged once)");
        output->shape_logged = true;
        output->subscription->note_dropped(1);
        continue;
      }
      if (rc < 0) output->subscription->note_dropped(1);
    }
  }
  taken_.clear();
}

dds_return_t Ros2Topics::write_tf(Output& output, const StreamSample& sample) {
  if (!body_transforms(sample.data(), output.frames, transforms_)) {
    // another model (a spawn, a delete), or none known yet: its frames first (the sample is
    // skipped: no reader was slow)
    output.geometry_wanted = true;
    return 0;
  }
  return write_transforms(output.writer, transforms_, sample.time());
}

dds_return_t Ros2Topics::write_odometry(Output& output, const StreamSample& sample) {
  OdometryValues values;
  if (output.role == Role::odometry) {
    static constexpr std::string_view k_keys[] = {"x",  "y",  "z",  "roll", "pitch", "yaw",
                                                  "vx", "vy", "vz", "wx",   "wy",    "wz"};
    std::array<double, 12> numbers;
    sample.numbers(k_keys, numbers);
    values = odometry_from_integrated(numbers);
  } else {
    static constexpr std::string_view k_keys[] = {"x", "y", "z", "roll", "pitch", "yaw"};
    std::array<double, 6> numbers;
    sample.numbers(k_keys, numbers);
    values = odometry_from_pose(numbers);
  }
  nav_msgs_msg_dds__Odometry_ message{};
  message.header.stamp = stamp(sample.time());
  message.header.frame_id = c_str(output.frame_id);
  message.child_frame_id = c_str(output.child_frame_id);
  const Pose& pose = values.pose;
  message.pose.pose.position = point(pose.position);
  message.pose.pose.orientation = quaternion(pose.rotation);
  message.twist.twist.linear = vector3(values.linear);
  message.twist.twist.angular = vector3(values.angular);
  // a pose sample has no velocity: its twist is unknown (-1 first, as sensor_msgs marks an
  // unknown estimate)
  if (!values.twist_known) message.twist.covariance[0] = -1;
  return dds_write(output.writer, &message);
}

dds_return_t Ros2Topics::write_joint_states(Output& output, const StreamSample& sample) {
  const JointPositions joints = joint_positions(sample.data());
  std::vector<char*> names;
  names.reserve(joints.names.size());
  for (const std::string& name : joints.names) names.push_back(c_str(name));
  sensor_msgs_msg_dds__JointState_ message{};
  message.header.stamp = stamp(sample.time());
  message.header.frame_id = const_cast<char*>("");
  const auto count = static_cast<uint32_t>(names.size());
  message.name._maximum = message.name._length = count;
  message.name._buffer = names.data();
  message.position._maximum = message.position._length = count;
  message.position._buffer = const_cast<double*>(joints.positions.data());
  // velocity and effort: empty (the stream has positions; JointState allows empty arrays)
  return dds_write(output.writer, &message);
}

dds_return_t Ros2Topics::write_imu(Output& output, const StreamSample& sample) {
  const json& data = sample.data();
  auto vector = [&data](const char* key) {
    const json& v = data.at(key);
    if (!v.is_array() || v.size() != 3)
      throw std::invalid_argument(std::string(key) + ": not [x, y, z]");
    return geometry_msgs_msg_dds__Vector3_{v[0].get<double>(), v[1].get<double>(),
                                           v[2].get<double>()};
  };
  sensor_msgs_msg_dds__Imu_ message{};
  message.header.stamp = stamp(sample.time());
  message.header.frame_id = c_str(output.frame_id);
  message.angular_velocity = vector("angular_velocity");
  message.linear_acceleration = vector("linear_acceleration");
  // no orientation estimate (-1 first, as sensor_msgs/Imu says); the other covariances all
  // zero: unknown
  message.orientation.w = 1;
  message.orientation_covariance[0] = -1;
  return dds_write(output.writer, &message);
}

dds_return_t Ros2Topics::write_image(Output& output, const StreamSample& sample) {
  // the pixels as the camera gave them (rgb8, or 32FC1 metres): no decoding, no copy
  const StreamPayload* payload = sample.payload();
  if (!payload) throw std::invalid_argument("the sample carries no pixels");
  const ImageShape shape = image_shape(*payload);
  const CameraInfoValues values = camera_info_values(payload->description);
  const builtin_interfaces_msg_dds__Time_ time = stamp(sample.time());
  sensor_msgs_msg_dds__Image_ image{};
  image.header.stamp = time;
  image.header.frame_id = c_str(output.frame_id);
  image.height = shape.height;
  image.width = shape.width;
  image.encoding = c_str(shape.encoding);
  image.is_bigendian = shape.is_bigendian ? 1 : 0;
  image.step = shape.step;
  borrow(image.data, const_cast<std::uint8_t*>(payload->bytes.data()), payload->bytes.size());
  const dds_return_t rc = dds_write(output.writer, &image);
  // its camera_info: the same stamp and frame
  sensor_msgs_msg_dds__CameraInfo_ info{};
  info.header = image.header;
  info.height = values.height;
  info.width = values.width;
  info.distortion_model = const_cast<char*>(k_distortion_model);
  std::array<double, 5> d = values.d;
  borrow(info.d, d.data(), d.size());
  std::copy(values.k.begin(), values.k.end(), info.k);
  std::copy(values.r.begin(), values.r.end(), info.r);
  std::copy(values.p.begin(), values.p.end(), info.p);
  const dds_return_t info_rc = dds_write(output.info_writer, &info);
  return rc < 0 ? rc : info_rc;
}

dds_return_t Ros2Topics::write_scan(Output& output, const StreamSample& sample) {
  LaserScanValues values = laser_scan_values(sample.data(), output.info.frequency, output.laser);
  sensor_msgs_msg_dds__LaserScan_ message{};
  message.header.stamp = stamp(sample.time());
  message.header.frame_id = c_str(output.frame_id);
  message.angle_min = values.angle_min;
  message.angle_max = values.angle_max;
  message.angle_increment = values.angle_increment;
  message.time_increment = 0;
  message.scan_time = values.scan_time;
  message.range_min = values.range_min;
  message.range_max = values.range_max;
  borrow(message.ranges, values.ranges.data(), values.ranges.size());
  // intensities: empty (the scanner measures none)
  return dds_write(output.writer, &message);
}

}  // namespace simgate::ros2
