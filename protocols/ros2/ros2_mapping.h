// simgate/ros2 mapping — simgate's data in ROS 2's terms, for the ros2 transport
// (plugins/ros2, docs/transports/ros2.md): ROS names and topic names, ROS time, the scene's
// frames (tf's tree of bodies) and the transforms between them, the messages' field values
// from stream samples, the ROS graph's ids. The messages' types are ros2_msgs.idl's.
//
// Terms:
//  - ROS name token: [A-Za-z_][A-Za-z0-9_]*, what a ROS 2 node, namespace or topic name is
//    made of; simgate's names (robots, components) are turned into tokens (to_ros_token).
//  - DDS topic name: "rt/" + the ROS topic name without its leading '/' (rmw_cyclonedds);
//    the graph's own topic, ros_discovery_info, has no prefix.
//  - frame tree: each body of the MuJoCo model is a tf frame named after the body; a body's
//    parent frame is its parent body's, and the world body (0) is the `world_frame` option's
//    frame ("world"). Components that sense from a frame of their own (a sensor's site, a
//    camera's optical frame) are frames fixed to their body, named "<robot>/<component>".
//  - pose: position and unit quaternion (w, x, y, z), as body_poses samples give them.
//
// Threads: pure functions and values, any thread.
#ifndef SIMGATE_PROTOCOLS_ROS2_ROS2_MAPPING_H_
#define SIMGATE_PROTOCOLS_ROS2_ROS2_MAPPING_H_

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "simgate/core/laser_arc.h"
#include "simgate/core/status.h"
#include "simgate/core/streams.h"

namespace simgate::ros2 {

// ---- names ----

// Whether `name` is a ROS name token ([A-Za-z_][A-Za-z0-9_]*, not empty).
bool is_ros_token(std::string_view name);
// `name` made a token: every other character '_', '_' before a leading digit, "_" for "".
std::string to_ros_token(std::string_view name);
// "rt/" + the ROS topic name `topic` ("/robot/odom") without its leading '/'.
std::string dds_topic_name(std::string_view topic);
// The robot a component belongs to: its name up to the first '.' ("robot.pose" -> "robot");
// "" for a component of no robot ("simulation").
std::string robot_of(std::string_view component);
// The tf frame of a component's own sensing frame: "robot.odometry" -> "robot/odometry"
// (each part a ROS token).
std::string component_frame(std::string_view component);

// ---- time ----

// builtin_interfaces/Time of `seconds` of simulated time: sec, nanosec (0 .. 999999999),
// nanoseconds rounded; negative or not finite -> 0, beyond int32 -> the largest time.
struct RosTime {
  std::int32_t sec = 0;
  std::uint32_t nanosec = 0;
};
RosTime to_ros_time(double seconds);

// ---- poses and frames ----

struct Pose {
  std::array<double, 3> position{0, 0, 0};
  std::array<double, 4> rotation{1, 0, 0, 0};  // w, x, y, z
};

// The rotation roll about x, then pitch about y, then yaw about z (R = Rz(yaw) Ry(pitch)
// Rx(roll): simgate's and ROS's convention), as (w, x, y, z).
std::array<double, 4> quaternion_from_rpy(double roll, double pitch, double yaw);
// `child` in `parent`'s frame (parent⁻¹ · child), both given in a common frame.
Pose relative_pose(const Pose& parent, const Pose& child);

// The model's frames, read from a `simulation get_scene_geometry` answer (bodies, frames,
// generation).
struct FrameTree {
  std::uint64_t generation = 0;
  std::vector<std::string> names;  // by body id; the world body's is `world_frame`
  std::vector<int> parents;        // by body id (the world's: 0)
  // A component's sensing frame, fixed to a body.
  struct Fixed {
    std::string name;  // component_frame(component)
    int body = 0;
    Pose pose;  // in the body's frame
  };
  std::vector<Fixed> fixed;
  bool known() const { return !names.empty(); }
  // Throws std::invalid_argument naming what is malformed.
  static FrameTree from_geometry(const json& geometry, const std::string& world_frame);
};

// One transform of a tf message: `child` in `parent`, both frames of the tree.
struct FrameTransform {
  const std::string* parent = nullptr;
  const std::string* child = nullptr;
  Pose pose;
};
// The transforms of a body_poses sample ({generation, poses: [[x, y, z, qw, qx, qy, qz] per
// body]}): each body but the world in its parent body's frame. False, `out` empty, when the
// sample is of another generation than `tree` or malformed (not one pose per body).
bool body_transforms(const json& sample, const FrameTree& tree, std::vector<FrameTransform>& out);
// The fixed frames' transforms (for /tf_static): each in its body's frame.
std::vector<FrameTransform> fixed_transforms(const FrameTree& tree);

// ---- samples ----

// An armature_pose (kind joint_state) sample, {joint: position, ..., timestamp}: the joints'
// names and positions, in the sample's order. Throws std::invalid_argument when a value is no
// number.
struct JointPositions {
  std::vector<std::string> names;
  std::vector<double> positions;
};
JointPositions joint_positions(const json& sample);

// nav_msgs/Odometry's values: pose in the header's frame, twist in the child frame.
struct OdometryValues {
  Pose pose;
  std::array<double, 3> linear{0, 0, 0};
  std::array<double, 3> angular{0, 0, 0};
  bool twist_known = false;  // false: a pose sample has no velocities
};
// From the numbers of a kind "odometry" sample (x, y, z, roll, pitch, yaw relative to where
// the sensor started; vx, vy, vz, wx, wy, wz in the sensor frame): `values` in that order.
OdometryValues odometry_from_integrated(const std::array<double, 12>& values);
// From a kind "pose" sample's numbers (x, y, z, roll, pitch, yaw in the world frame).
OdometryValues odometry_from_pose(const std::array<double, 6>& values);

// The motion_vw command of a geometry_msgs/Twist: v = linear.x, w = angular.z.
json velocity_command(double linear_x, double angular_z);

// The joint_positions command (an armature's input) of a sensor_msgs/JointState: {name[i]:
// position[i]} for each name among `joints` (the stream's fields); the other names in
// `unknown`, left out. Velocities and efforts are not commands here. Throws
// std::invalid_argument when the message has positions but not one per name.
struct JointCommand {
  json positions = json::object();  // empty: nothing to command
  std::vector<std::string> unknown;
};
JointCommand joint_command(const std::vector<std::string>& names,
                           const std::vector<double>& positions,
                           const std::vector<std::string>& joints);

// ---- cameras ----

// sensor_msgs/Image's fields of a camera's sample (its payload: content "image", description
// {width, height, encoding, step, is_bigendian}, the pixels rows top first, as Image has
// them). Throws std::invalid_argument when the payload is no image or its size is not
// height * step.
struct ImageShape {
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::uint32_t step = 0;  // bytes per row
  std::string encoding;    // sensor_msgs/image_encodings: "rgb8", "32FC1"
  bool is_bigendian = false;
};
ImageShape image_shape(const StreamPayload& payload);

// sensor_msgs/CameraInfo's values of a camera's payload description (width, height,
// intrinsic_matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]): an ideal pinhole, "plumb_bob" with
// no distortion, R identity (a monocular camera), P = [K | 0]. Throws std::invalid_argument
// when the intrinsics are not a 3x3 matrix of numbers.
struct CameraInfoValues {
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::array<double, 5> d{};  // k1, k2, t1, t2, k3: all 0
  std::array<double, 9> k{};
  std::array<double, 9> r{};
  std::array<double, 12> p{};
};
inline constexpr const char* k_distortion_model = "plumb_bob";
CameraInfoValues camera_info_values(const json& description);

// ---- laser scans ----

// What the transport keeps of one laser_scanner's stream between scans: where its rays
// point (simgate/core/laser_arc.h) and how far it sees (laser_range: the range a miss reads;
// 0 until a miss came).
struct LaserReading {
  LaserArc arc;
  double reach = 0;
};
// sensor_msgs/LaserScan's values of a laser_scan sample ({range_list, point_list}): the
// angles of `reading`'s arc (read from this scan's hits first), each hit's range, +inf for a
// miss (a ray whose point is [0, 0, 0]: no return, REP 117), range_min 0, range_max the
// laser's reach (before a miss showed it: the farthest hit), scan_time 1 / `frequency` (0 for
// 0), time_increment 0 (every ray is cast at the same instant). Throws std::invalid_argument
// when the sample has no range_list of numbers.
struct LaserScanValues {
  float angle_min = 0;
  float angle_max = 0;
  float angle_increment = 0;
  float scan_time = 0;
  float range_min = 0;
  float range_max = 0;
  std::vector<float> ranges;
};
LaserScanValues laser_scan_values(const json& sample, double frequency, LaserReading& reading);

// ---- the ROS graph ----

using Gid = std::array<std::uint8_t, 16>;
// USER_DATA of the participant, as rmw_cyclonedds writes it: "enclave=/;".
inline constexpr std::string_view k_participant_user_data = "enclave=/;";
// The topic of the graph (rmw_dds_common::msg::ParticipantEntitiesInfo), unprefixed.
inline constexpr const char* k_discovery_topic = "ros_discovery_info";

}  // namespace simgate::ros2

#endif  // SIMGATE_PROTOCOLS_ROS2_ROS2_MAPPING_H_
