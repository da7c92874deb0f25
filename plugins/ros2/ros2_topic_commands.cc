// The commands ROS 2 nodes write, into the input streams (Ros2Topics::take_commands, on the
// DDS thread): /<robot>/cmd_vel's Twists as the motion's velocity (the latest of a take), and
// /<robot>/joint_command's JointStates as an armature's joint positions (a take's merged).
// Which stream becomes which topic: ros2_topics.cc.
#include <string>
#include <vector>

#include "ros2_msgs.h"
#include "ros2_topic_endpoints.h"
#include "ros2_topics.h"
#include "simgate/core/log.h"
#include "simgate/core/text.h"

namespace simgate::ros2 {

namespace {

// Commands (Twists, JointStates) one dds_take returns at most.
constexpr int k_command_take_batch = 16;

}  // namespace

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
