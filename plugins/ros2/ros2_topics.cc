// The data streams as ROS 2 topics: which stream becomes which topic (plan, sync), their
// writers and readers made and deleted, a pushed stream subscribed to while read, each world's
// frame tree asked for. The messages filled from the samples: ros2_topic_messages.cc; the
// commands read into input streams: ros2_topic_commands.cc. Design: ros2_topics.h,
// docs/transports/ros2.md.
#include "ros2_topics.h"

#include <algorithm>
#include <stdexcept>
#include <string_view>
#include <utility>

#include "dds_support.h"
#include "ros2_msgs.h"
#include "ros2_topic_endpoints.h"
#include "ros2_types.h"
#include "simgate/core/log.h"
#include "simgate/core/request_manager.h"

namespace simgate::ros2 {

namespace {

// Samples a subscription keeps: the DDS thread writes them as soon as it wakes, so a few
// cover its scheduling hiccups; older ones are dropped (counted by the hub).
constexpr std::size_t k_subscription_capacity = 8;
// History depths: ROS 2's default profile (keep-last 10); tf2's broadcaster's for /tf.
constexpr int32_t k_default_depth = 10;
constexpr int32_t k_tf_depth = 100;

using dds::check_created;
using dds::make_qos;
using dds::QosPtr;

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

}  // namespace

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

}  // namespace simgate::ros2
