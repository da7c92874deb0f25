// The data streams as ROS 2 topics: which stream becomes which topic, the messages filled from
// the samples, the cmd_vel commands. Design: ros2_topics.h, docs/transports/ros2.md.
#include "ros2_topics.h"

#include <algorithm>
#include <stdexcept>
#include <string_view>
#include <utility>

#include "dds_support.h"
#include "ros2_msgs.h"
#include "ros2_types.h"
#include "simgate/core/log.h"
#include "simgate/core/request_manager.h"
#include "simgate/core/text.h"

namespace simgate::ros2 {

namespace {

// Samples a subscription keeps: the DDS thread writes them as soon as it wakes, so a few
// cover its scheduling hiccups; older ones are dropped (counted by the hub).
constexpr std::size_t k_subscription_capacity = 8;
// Commands (Twists, JointStates) one dds_take returns at most.
constexpr int k_command_take_batch = 16;
// History depths: ROS 2's default profile (keep-last 10); tf2's broadcaster's for /tf.
constexpr int32_t k_default_depth = 10;
constexpr int32_t k_tf_depth = 100;

using dds::check_created;
using dds::make_qos;
using dds::QosPtr;

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

// A component's world: its ROS namespace ("/w1"; "" for world 0) and the component's name
// there ("w1/robot.pose": "/w1", "robot.pose").
struct WorldName {
  std::string ns;
  std::string_view name;
};
WorldName world_name(std::string_view component) {
  const auto address = RequestManager::world_address(component);
  if (!address) return {"", component};
  const std::string_view name = component.substr(address->second);
  if (address->first == 0) return {"", name};
  return {"/" + std::string(component.substr(0, address->second - 1)), name};
}

// A ROS sequence over `data`'s elements (not copied, not released by the writer).
template <typename Sequence, typename T>
void borrow(Sequence& sequence, T* data, std::size_t count) {
  sequence._maximum = sequence._length = static_cast<uint32_t>(count);
  sequence._buffer = data;
  sequence._release = false;
}

}  // namespace

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

Ros2Topics::Ros2Topics(std::shared_ptr<StreamDirectory> hub, Settings settings,
                       dds_entity_t participant, dds_entity_t waitset, dds_entity_t guard)
    : hub_(std::move(hub)),
      settings_(std::move(settings)),
      participant_(participant),
      waitset_(waitset),
      guard_(guard) {}

Ros2Topics::~Ros2Topics() {
  for (auto& [component, output] : outputs_)
    if (output->subscription) hub_->unsubscribe(output->subscription);
}

dds_entity_t Ros2Topics::topic(const std::string& name, const dds_topic_descriptor_t* descriptor) {
  // announced by name only, as ROS 2's types are (ros2_types.h)
  return dds::cached_topic(topics_, participant_, name, name_only(*descriptor));
}

std::string Ros2Topics::robot_namespace(const std::string& world, const std::string& robot) {
  const std::string ns = world + "/" + to_ros_token(robot);
  auto [it, added] = namespaces_.emplace(ns, robot);
  if (!added && it->second != robot)
    throw std::runtime_error("robot '" + robot + "' would have namespace " + ns +
                             ", which robot '" + it->second + "' has");
  return ns;
}

void Ros2Topics::plan(const std::vector<StreamInfo>& listed, std::map<std::string, Role>& outputs,
                      std::map<std::string, Command>& inputs) {
  // per robot (of each world: by "w1/robot"): the odometry source (an integrated odometry
  // before a pose), the first joint stream, the first velocity input, the first joint input;
  // every camera and laser (each has topics of its own); each world's /tf
  std::map<std::string, std::string> odometry, pose, joints, imu, velocity, joint_commands;
  for (const StreamInfo& info : listed) {
    const std::string_view name = world_name(info.component).name;
    if (name == "simulation" && info.kind == "body_poses") {
      if (settings_.tf) outputs.emplace(info.component, Role::tf);
      continue;
    }
    const std::string robot = robot_of(name);
    if (robot.empty() || (!settings_.all_robots && !settings_.robots.count(robot))) continue;
    if (info.direction == StreamDirection::out &&
        (info.kind == "image" || info.kind == "depth_image" || info.kind == "laser_scan")) {
      outputs.emplace(info.component, info.kind == "laser_scan" ? Role::laser_scan : Role::image);
      continue;
    }
    std::map<std::string, std::string>* slot =
        info.direction == StreamDirection::in ? (info.kind == "velocity"          ? &velocity
                                                 : info.kind == "joint_positions" ? &joint_commands
                                                                                  : nullptr)
                                              : (info.kind == "odometry"      ? &odometry
                                                 : info.kind == "pose"        ? &pose
                                                 : info.kind == "joint_state" ? &joints
                                                 : info.kind == "imu"         ? &imu
                                                                              : nullptr);
    if (slot && slot->emplace(robot_of(info.component), info.component).second) continue;
    if (skipped_logged_.insert(info.component).second)
      log::info("ros2 transport: the ", info.kind, " stream of ", info.component,
                " has no ROS 2 topic ",
                slot ? "(its robot has another stream of that kind already)"
                     : "in this version (docs/transports/ros2.md, Topics)");
  }
  for (const auto& [robot, component] : odometry) outputs.emplace(component, Role::odometry);
  for (const auto& [robot, component] : pose)
    if (!odometry.count(robot)) outputs.emplace(component, Role::pose_odometry);
  for (const auto& [robot, component] : joints) outputs.emplace(component, Role::joint_states);
  for (const auto& [robot, component] : imu) outputs.emplace(component, Role::imu);
  for (const auto& [robot, component] : velocity) inputs.emplace(component, Command::velocity);
  for (const auto& [robot, component] : joint_commands) inputs.emplace(component, Command::joints);
}

bool Ros2Topics::sync() {
  const std::vector<StreamInfo> listed = hub_->streams(settings_.transport);
  std::map<std::string, Role> wanted_outputs;
  std::map<std::string, Command> wanted_inputs;
  plan(listed, wanted_outputs, wanted_inputs);
  if (!robots_checked_) {
    // a robot named in the "robots" option with no stream here is most likely a typo
    robots_checked_ = true;
    std::set<std::string> streaming;
    for (const StreamInfo& info : listed)
      streaming.insert(robot_of(world_name(info.component).name));
    streaming.erase("");
    for (const std::string& robot : settings_.robots)
      if (!streaming.count(robot)) {
        std::string known;
        for (const std::string& name : streaming) known += (known.empty() ? "" : ", ") + name;
        log::warning("ros2 transport: robot '", robot,
                     "' (option \"robots\") has no stream carried by this transport (robots "
                     "with streams here: ",
                     known.empty() ? "none" : known, "; map their streams to it in \"streams\")");
      }
  }
  bool changed = false;
  // those that went (or now have another role), or whose stream closed
  for (auto it = outputs_.begin(); it != outputs_.end();) {
    auto wanted = wanted_outputs.find(it->first);
    const bool closed = it->second->subscription && it->second->subscription->closed();
    if (wanted != wanted_outputs.end() && wanted->second == it->second->role && !closed) {
      ++it;
      continue;
    }
    remove_output(*it->second);
    it = outputs_.erase(it);
    changed = true;
  }
  for (auto it = inputs_.begin(); it != inputs_.end();) {
    auto wanted = wanted_inputs.find(it->first);
    if (wanted != wanted_inputs.end() && wanted->second == it->second->command) {
      ++it;
      continue;
    }
    remove_input(*it->second);
    it = inputs_.erase(it);
    changed = true;
  }
  // those that came
  for (const StreamInfo& info : listed) {
    try {
      if (auto role = wanted_outputs.find(info.component);
          role != wanted_outputs.end() && !outputs_.count(info.component)) {
        add_output(info, role->second);
        changed = true;
      } else if (auto command = wanted_inputs.find(info.component);
                 command != wanted_inputs.end() && !inputs_.count(info.component)) {
        add_input(info, command->second);
        changed = true;
      }
    } catch (const std::exception& e) {
      log::error("ros2 transport: the stream of '", info.component, "' is not carried: ", e.what());
    }
  }
  return changed;
}

void Ros2Topics::add_output(const StreamInfo& info, Role role) {
  auto output = std::make_unique<Output>();
  output->info = info;
  output->role = role;
  const dds_topic_descriptor_t* descriptor = nullptr;
  int32_t depth = k_default_depth;
  // a world's topics in its namespace ("/w1/tf", "/w1/robot/odom"), its frames named as
  // world 0's (each world's /tf a tree of its own)
  const WorldName world = world_name(info.component);
  if (role == Role::tf) {
    output->topic = world.ns + "/tf";
    descriptor = &tf2_msgs_msg_dds__TFMessage__desc;
    depth = k_tf_depth;
    // the sensing frames: every one in one message, kept for late joiners
    const std::string static_topic = world.ns + "/tf_static";
    QosPtr qos = make_qos(true, 1, 0);
    output->static_writer = check_created(
        dds_create_writer(participant_, topic(dds_topic_name(static_topic), descriptor), qos.get(),
                          nullptr),
        "writer " + static_topic);
  } else {
    const std::string robot = robot_of(world.name);
    const std::string ns = robot_namespace(world.ns, robot);
    const std::string frame_root = to_ros_token(robot);
    // a sensor's own topics under its robot's namespace: "/robot/camera/..."
    const std::string frame = component_frame(world.name);
    const std::string sensor = ns + frame.substr(std::min(frame.find('/'), frame.size()));
    if (role == Role::image) {
      output->topic = sensor + "/image_raw";
      descriptor = &sensor_msgs_msg_dds__Image__desc;
      // the camera's optical frame (x right, y down, z forward), on /tf_static under its body
      output->frame_id = frame;
    } else if (role == Role::laser_scan) {
      output->topic = sensor + "/scan";
      descriptor = &sensor_msgs_msg_dds__LaserScan__desc;
      output->frame_id = frame;
    } else if (role == Role::joint_states) {
      output->topic = ns + "/joint_states";
      descriptor = &sensor_msgs_msg_dds__JointState__desc;
    } else if (role == Role::imu) {
      output->topic = ns + "/imu";
      descriptor = &sensor_msgs_msg_dds__Imu__desc;
      // its values are in the sensor's frame, on /tf_static under its body
      output->frame_id = frame;
    } else {
      output->topic = ns + "/odom";
      descriptor = &nav_msgs_msg_dds__Odometry__desc;
      // integrated odometry: from where its sensor started, of its sensing frame; a pose: in
      // the world, of the robot (its frame named as the robot)
      output->frame_id = role == Role::odometry ? frame_root + "/odom" : settings_.world_frame;
      output->child_frame_id = role == Role::odometry ? frame : frame_root;
    }
  }
  QosPtr qos = make_qos(false, depth, 0);
  output->writer = check_created(
      dds_create_writer(participant_, topic(dds_topic_name(output->topic), descriptor), qos.get(),
                        nullptr),
      "writer " + output->topic);
  std::string info_topic;
  if (role == Role::image) {
    info_topic = output->topic.substr(0, output->topic.rfind('/')) + "/camera_info";
    output->info_writer = check_created(
        dds_create_writer(participant_,
                          topic(dds_topic_name(info_topic), &sensor_msgs_msg_dds__CameraInfo__desc),
                          qos.get(), nullptr),
        "writer " + info_topic);
  }
  if (info.pushed) {
    // its component works for it while subscribed (a camera renders): subscribed to only
    // while a writer has a reader (matches_changed)
    for (dds_entity_t writer : {output->writer, output->info_writer}) {
      if (writer == 0) continue;
      check_created(dds_set_status_mask(writer, DDS_PUBLICATION_MATCHED_STATUS),
                    "status mask " + output->topic);
      check_created(dds_waitset_attach(waitset_, writer, k_token_matched),
                    "waitset attachment " + output->topic);
    }
  } else {
    subscribe(*output);
    if (!output->subscription) {
      for (dds_entity_t writer : {output->writer, output->info_writer, output->static_writer})
        if (writer) dds_delete(writer);
      return;  // gone meanwhile
    }
  }
  log::info("ros2 transport: ", info.component, " on ", output->topic, " (", descriptor->m_typename,
            ")", info_topic.empty() ? "" : " and " + info_topic,
            info.pushed ? " (made while read)" : "");
  const bool pushed = info.pushed;
  outputs_.emplace(info.component, std::move(output));
  if (pushed) matches_changed();  // a reader that matched already
}

void Ros2Topics::subscribe(Output& output) {
  SubscriberOptions options{k_subscription_capacity, "ros2 topic " + output.topic, {}, {}};
  const dds_entity_t guard = guard_;
  options.wake = [guard] { dds_set_guardcondition(guard, true); };
  output.subscription =
      hub_->subscribe(output.info.component, settings_.transport, std::move(options));
}

void Ros2Topics::matches_changed() {
  for (auto& [component, output] : outputs_) {
    if (!output->info.pushed) continue;
    // read every writer's status (each read resets its trigger)
    bool read = false;
    for (dds_entity_t writer : {output->writer, output->info_writer}) {
      dds_publication_matched_status_t status;
      if (writer != 0 && dds_get_publication_matched_status(writer, &status) == 0)
        read = read || status.current_count > 0;
    }
    if (read && !output->subscription) {
      subscribe(*output);
    } else if (!read && output->subscription) {
      hub_->unsubscribe(output->subscription);
      output->subscription.reset();
    }
  }
}

void Ros2Topics::add_input(const StreamInfo& info, Command command) {
  const WorldName world = world_name(info.component);
  const std::string ns = robot_namespace(world.ns, robot_of(world.name));
  auto input = std::make_unique<Input>();
  input->info = info;
  input->command = command;
  const bool joints = command == Command::joints;
  input->topic = ns + (joints ? "/joint_command" : "/cmd_vel");
  const dds_topic_descriptor_t* descriptor =
      joints ? &sensor_msgs_msg_dds__JointState__desc : &geometry_msgs_msg_dds__Twist__desc;
  QosPtr qos = make_qos(false, k_default_depth, 0);
  input->reader =
      check_created(dds_create_reader(participant_, topic(dds_topic_name(input->topic), descriptor),
                                      qos.get(), nullptr),
                    "reader " + input->topic);
  input->condition = check_created(dds_create_readcondition(input->reader, DDS_ANY_STATE),
                                   "read condition " + input->topic);
  check_created(dds_waitset_attach(waitset_, input->condition, k_token_commands),
                "waitset attachment " + input->topic);
  log::info("ros2 transport: ", input->topic, " (",
            joints ? "sensor_msgs/msg/JointState" : "geometry_msgs/msg/Twist", ") into ",
            info.component);
  inputs_.emplace(info.component, std::move(input));
}

void Ros2Topics::remove_output(Output& output) {
  if (output.subscription) hub_->unsubscribe(output.subscription);
  dds_delete(output.writer);  // (detached from the waitset with it)
  if (output.info_writer) dds_delete(output.info_writer);
  if (output.static_writer) dds_delete(output.static_writer);
  log::info("ros2 transport: ", output.topic, " ended (", output.info.component, " is gone)");
}

void Ros2Topics::remove_input(Input& input) {
  dds_waitset_detach(waitset_, input.condition);
  dds_delete(input.reader);  // its read condition goes with it
  log::info("ros2 transport: ", input.topic, " ended (", input.info.component, " is gone)");
}

void Ros2Topics::endpoints(std::vector<dds_entity_t>& writers,
                           std::vector<dds_entity_t>& readers) const {
  for (const auto& [component, output] : outputs_) {
    writers.push_back(output->writer);
    if (output->info_writer) writers.push_back(output->info_writer);
    if (output->static_writer) writers.push_back(output->static_writer);
  }
  for (const auto& [component, input] : inputs_) readers.push_back(input->reader);
}

std::vector<std::string> Ros2Topics::take_geometry_wanted() {
  std::vector<std::string> wanted;
  for (auto& [component, output] : outputs_)
    if (output->role == Role::tf && std::exchange(output->geometry_wanted, false) &&
        !output->geometry_refused)
      wanted.push_back(component);
  return wanted;
}

void Ros2Topics::set_geometry(const std::string& component, const json& geometry) {
  const auto it = outputs_.find(component);
  if (it == outputs_.end() || it->second->role != Role::tf) return;  // gone meanwhile
  it->second->frames = FrameTree::from_geometry(geometry, settings_.world_frame);
  write_static(*it->second);
}

void Ros2Topics::refuse_geometry(const std::string& component) {
  if (const auto it = outputs_.find(component); it != outputs_.end())
    it->second->geometry_refused = true;
}

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

void Ros2Topics::take_commands() {
  for (auto& [component, input] : inputs_) {
    if (input->command == Command::joints)
      take_joint_states(*input);
    else
      take_twists(*input);
  }
}

void Ros2Topics::take_twists(Input& input) {
  void* samples[k_command_take_batch] = {};
  dds_sample_info_t infos[k_command_take_batch];
  const dds_return_t n =
      dds_take(input.reader, samples, infos, k_command_take_batch, k_command_take_batch);
  // the latest Twist of the batch is what counts (the hub keeps only the latest anyway)
  const geometry_msgs_msg_dds__Twist_* latest = nullptr;
  for (dds_return_t i = 0; i < n; ++i)
    if (infos[i].valid_data) latest = static_cast<const geometry_msgs_msg_dds__Twist_*>(samples[i]);
  if (latest)
    hub_->publish(input.info.component, settings_.transport,
                  velocity_command(latest->linear.x, latest->angular.z));
  if (n > 0) dds_return_loan(input.reader, samples, n);
}

void Ros2Topics::take_joint_states(Input& input) {
  void* samples[k_command_take_batch] = {};
  dds_sample_info_t infos[k_command_take_batch];
  const dds_return_t n =
      dds_take(input.reader, samples, infos, k_command_take_batch, k_command_take_batch);
  // the batch's JointStates merged, in order: a later position of a joint replaces an
  // earlier one, and joints named only earlier keep theirs
  json merged = json::object();
  std::vector<std::string> names;
  std::vector<double> positions;
  for (dds_return_t i = 0; i < n; ++i) {
    if (!infos[i].valid_data) continue;
    const auto* message = static_cast<const sensor_msgs_msg_dds__JointState_*>(samples[i]);
    names.assign(message->name._buffer, message->name._buffer + message->name._length);
    positions.assign(message->position._buffer,
                     message->position._buffer + message->position._length);
    try {
      JointCommand command = joint_command(names, positions, input.info.fields);
      for (const std::string& name : command.unknown)
        if (input.unknown_logged.insert(name).second)
          log::warning("ros2 transport: ", input.topic, ": joint '", name, "' is not one of ",
                       input.info.component, "'s (", join(input.info.fields),
                       "); its position is ignored (logged once)");
      merged.update(command.positions);
    } catch (const std::invalid_argument& e) {
      if (!input.bad_logged)
        log::warning("ros2 transport: ", input.topic, ": a JointState is ignored: ", e.what(),
                     " (logged once)");
      input.bad_logged = true;
    }
  }
  if (n > 0) dds_return_loan(input.reader, samples, n);
  if (!merged.empty()) hub_->publish(input.info.component, settings_.transport, merged);
}

}  // namespace simgate::ros2
