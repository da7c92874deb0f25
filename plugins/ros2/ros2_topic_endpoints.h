// ros2_topic_endpoints.h — what Ros2Topics keeps of each topic: an output stream's writers
// and subscription, an input stream's reader (private to plugins/ros2: ros2_topics.cc,
// ros2_topic_messages.cc, ros2_topic_commands.cc).
#ifndef SIMGATE_PLUGINS_ROS2_ROS2_TOPIC_ENDPOINTS_H_
#define SIMGATE_PLUGINS_ROS2_ROS2_TOPIC_ENDPOINTS_H_

#include <cstdint>
#include <memory>
#include <set>
#include <string>

#include <dds/dds.h>

#include "ros2_topics.h"

namespace simgate::ros2 {

struct Ros2Topics::Output {
  StreamInfo info;
  Role role = Role::tf;
  std::string topic;           // the ROS topic name: "/robot/odom"
  std::string frame_id;        // the header's frame (odometry, imu, image, scan)
  std::string child_frame_id;  // odometry: the child frame
  dds_entity_t writer = 0;
  dds_entity_t info_writer = 0;                      // a camera's: its camera_info
  std::shared_ptr<StreamSubscription> subscription;  // to the hub (a pushed stream: while read)
  bool shape_logged = false;  // a sample not of the message's shape was logged
  LaserReading laser;         // a laser's arc and reach, read from its scans
  // Role::tf: its world's frame tree (not known(): none yet), asked for with
  // `<world>simulation get_scene_geometry`, and its world's /tf_static
  FrameTree frames;
  bool geometry_wanted = true;    // a frame tree is to be asked for
  bool geometry_refused = false;  // its world refused it: not asked again
  dds_entity_t static_writer = 0;
  std::uint64_t static_written = ~std::uint64_t{0};  // the generation /tf_static holds
};

struct Ros2Topics::Input {
  StreamInfo info;
  Command command = Command::velocity;
  std::string topic;  // "/robot/cmd_vel", "/robot/joint_command"
  dds_entity_t reader = 0;
  dds_entity_t condition = 0;            // its read condition, in the waitset
  std::set<std::string> unknown_logged;  // joint names logged as not the armature's
  bool bad_logged = false;               // a malformed JointState was logged
};

}  // namespace simgate::ros2

#endif  // SIMGATE_PLUGINS_ROS2_ROS2_TOPIC_ENDPOINTS_H_
