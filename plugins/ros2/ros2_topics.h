// simgate/ros2 topics — the simulation's data streams as ROS 2 topics (issue #41): the
// `simulation` component's body_poses as /tf (and the components' sensing frames as
// /tf_static), each robot's odometry (or pose) as /<robot>/odom, its armature_pose as
// /<robot>/joint_states, its imu as /<robot>/imu, each camera's images as
// /<robot>/<camera>/image_raw with /<robot>/<camera>/camera_info, each laser_scanner's scans as
// /<robot>/<laser>/scan; /<robot>/cmd_vel read into its motion_vw stream and
// /<robot>/joint_command into its armature's joint_positions. Another world's streams
// ("w1/robot.pose", "w1/simulation": docs/worlds.md) the same in the world's namespace:
// /w1/tf, /w1/tf_static, /w1/robot/odom, /w1/robot/cmd_vel, ...
//
// Terms:
//  - world namespace: "" for world 0's streams, "/w<k>" for world k's (the stream's name
//    "w<k>/<component>", RequestManager::world_address).
//  - robot: the part of a component's name (in its world) before its first '.'; its ROS
//    namespace is "<world namespace>/<robot as a ROS token>" (ros2_mapping.h). A robot with an
//    "odometry" stream (level integrated) has its /odom from it; one with only a "pose"
//    stream, from that. Frame ids are the same in every world (each world's /tf is a tree of
//    its own, as ROS runs simulations side by side: a namespace each).
//  - frame tree: a world's bodies, read once per model generation from its
//    `<world>simulation get_scene_geometry` (the transport asks: take_geometry_wanted()),
//    then set_geometry(); until it comes (and after a spawn or a delete, until the new one
//    comes) its body_poses samples are not written.
//  - output: one StreamSubscription (a few samples deep, latest kept) and one writer per
//    topic (a camera: two, its image and its camera_info), reliable, volatile, keep-last (ROS
//    2's defaults: 10; /tf 100, as tf2's broadcaster). /tf_static: reliable, transient-local,
//    keep-last 1, one message holding every fixed frame (what tf2's static broadcaster does).
//    A pushed stream (a camera's: rendering costs the simulation) is subscribed to only while
//    one of its writers has a matched reader (matches_changed()).
//  - input: /<robot>/cmd_vel, geometry_msgs/Twist, and /<robot>/joint_command,
//    sensor_msgs/JointState, reliable, volatile, keep-last 10: each Twist goes to
//    StreamHub::publish as {v: linear.x, w: angular.z}, each JointState as {name: position}
//    for the armature's joints (other names logged once, left out), the JointStates of one
//    take merged (applied at once when the simulation lock is free, else the latest waits for
//    the next turn; refusals counted by the hub).
//
// Life cycle: made by the transport in start() (host thread); sync() on the DDS thread makes
// the endpoints of the streams the hub lists (and later of those that come, and deletes those
// of streams that went); destroyed after the DDS thread is joined (unsubscribes; its entities
// go with the participant).
//
// Threads: everything on the DDS thread, except the subscriptions' wake (the simulation
// thread, under its lock), which only raises the transport's guard condition.
#ifndef SIMGATE_PLUGINS_ROS2_ROS2_TOPICS_H_
#define SIMGATE_PLUGINS_ROS2_ROS2_TOPICS_H_

#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include <dds/dds.h>

#include "ros2_mapping.h"
#include "simgate/core/streams.h"

namespace simgate::ros2 {

class Ros2Topics {
 public:
  // Waitset token of the input readers' read conditions.
  static constexpr dds_attach_t k_token_commands = -3;
  // Waitset token of the pushed streams' writers (their publication-matched status).
  static constexpr dds_attach_t k_token_matched = -6;

  struct Settings {
    std::string transport;    // our name in the configuration
    std::string world_frame;  // the world body's frame, parent of the root bodies
    bool tf = true;           // body_poses as /tf
    bool all_robots = true;   // every robot, or only `robots`
    std::set<std::string> robots;
  };

  // `guard`: raised by the subscriptions' wake (samples are waiting); `waitset`: the DDS
  // thread's (the input readers and the pushed streams' writers are attached to it).
  Ros2Topics(std::shared_ptr<StreamDirectory> hub, Settings settings, dds_entity_t participant,
             dds_entity_t waitset, dds_entity_t guard);
  ~Ros2Topics();
  Ros2Topics(const Ros2Topics&) = delete;
  Ros2Topics& operator=(const Ros2Topics&) = delete;

  // ---- DDS thread ----
  // Endpoints for the streams the hub lists now; those of streams it no longer lists go.
  // True when the endpoints changed (the graph must be published anew).
  bool sync();
  // Writes the samples every subscription queued.
  void write_samples();
  // Takes the commands of every input reader (Twists, JointStates) and publishes them to the
  // hub.
  void take_commands();
  // A pushed stream's writer matched or lost a reader (k_token_matched): each such stream
  // subscribed to while one of its writers has a reader, else not. Reads (and so resets)
  // every such writer's status.
  void matches_changed();
  // The body_poses streams ("simulation", "w1/simulation") whose world's frame tree is wanted
  // (a sample of a model not known yet came, or none is known); cleared by the call.
  std::vector<std::string> take_geometry_wanted();
  // The answer of `<world>simulation get_scene_geometry` for body_poses stream `component`:
  // the frames of its world's model; its /tf_static. Throws std::invalid_argument when the
  // answer is malformed; nothing when the stream is gone.
  void set_geometry(const std::string& component, const json& geometry);
  // `component`'s world refused get_scene_geometry: it is not asked again.
  void refuse_geometry(const std::string& component);
  // The GIDs (DDS GUIDs) of our writers and readers, for the ROS graph.
  void endpoints(std::vector<dds_entity_t>& writers, std::vector<dds_entity_t>& readers) const;

 private:
  enum class Role { tf, odometry, pose_odometry, joint_states, imu, image, laser_scan };
  enum class Command { velocity, joints };
  struct Output;
  struct Input;

  dds_entity_t topic(const std::string& name, const dds_topic_descriptor_t* descriptor);
  // What each listed stream of a carried robot becomes (component -> role); inputs apart.
  void plan(const std::vector<StreamInfo>& listed, std::map<std::string, Role>& outputs,
            std::map<std::string, Command>& inputs);
  void add_output(const StreamInfo& info, Role role);
  void add_input(const StreamInfo& info, Command command);
  void subscribe(Output& output);
  void remove_output(Output& output);
  void remove_input(Input& input);
  void write_static(Output& output);
  dds_return_t write_tf(Output& output, const StreamSample& sample);
  dds_return_t write_odometry(Output& output, const StreamSample& sample);
  dds_return_t write_joint_states(Output& output, const StreamSample& sample);
  dds_return_t write_imu(Output& output, const StreamSample& sample);
  dds_return_t write_image(Output& output, const StreamSample& sample);
  dds_return_t write_scan(Output& output, const StreamSample& sample);
  void take_twists(Input& input);
  void take_joint_states(Input& input);
  // The namespace of `robot` of the world whose namespace is `world` ("/robot", "/w1/robot");
  // throws std::runtime_error when another robot took its token already.
  std::string robot_namespace(const std::string& world, const std::string& robot);

  std::shared_ptr<StreamDirectory> hub_;
  const Settings settings_;
  const dds_entity_t participant_;
  const dds_entity_t waitset_;
  const dds_entity_t guard_;
  std::map<std::string, dds_entity_t> topics_;              // by DDS topic name: made once
  std::map<std::string, std::unique_ptr<Output>> outputs_;  // by component
  std::map<std::string, std::unique_ptr<Input>> inputs_;    // by component
  std::map<std::string, std::string> namespaces_;           // ROS namespace -> its robot
  std::set<std::string> skipped_logged_;                    // streams logged as not carried
  bool robots_checked_ = false;             // the "robots" option was checked against the streams
  std::vector<SamplePtr> taken_;            // write_samples' buffer
  std::vector<FrameTransform> transforms_;  // write_tf's buffer
};

}  // namespace simgate::ros2

#endif  // SIMGATE_PLUGINS_ROS2_ROS2_TOPICS_H_
