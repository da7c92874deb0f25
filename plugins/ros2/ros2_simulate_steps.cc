// The ros2 transport's SimulateSteps action server, as rcl_action over rmw_cyclonedds offers an
// action. Design: ros2_simulate_steps.h, docs/transports/ros2.md.
#include "ros2_simulate_steps.h"

#include <algorithm>
#include <cstdint>
#include <exception>

#include "dds_support.h"
#include "ros2_actions.h"
#include "ros2_mapping.h"
#include "ros2_types.h"
#include "simgate/core/log.h"

namespace simgate::ros2 {

namespace {

using SendGoalRequest = simulation_interfaces_action_dds__SimulateSteps_SendGoal_Request_;
using SendGoalResponse = simulation_interfaces_action_dds__SimulateSteps_SendGoal_Response_;
using GetResultRequest = simulation_interfaces_action_dds__SimulateSteps_GetResult_Request_;
using GetResultResponse = simulation_interfaces_action_dds__SimulateSteps_GetResult_Response_;
using FeedbackMessage = simulation_interfaces_action_dds__SimulateSteps_FeedbackMessage_;
using CancelGoalRequest = action_msgs_srv_dds__CancelGoal_Request_;
using CancelGoalResponse = action_msgs_srv_dds__CancelGoal_Response_;
using GoalInfoMessage = action_msgs_msg_dds__GoalInfo_;
using GoalStatusMessage = action_msgs_msg_dds__GoalStatus_;
using UuidMessage = unique_identifier_msgs_msg_dds__UUID_;

GoalId goal_id_of(const UuidMessage& uuid) {
  GoalId id;
  std::copy(std::begin(uuid.uuid), std::end(uuid.uuid), id.begin());
  return id;
}

void set_goal_id(UuidMessage& out, const GoalId& id) {
  std::copy(id.begin(), id.end(), std::begin(out.uuid));
}

std::int64_t stamp_nanoseconds(std::int32_t sec, std::uint32_t nanosec) {
  return static_cast<std::int64_t>(sec) * 1'000'000'000 + nanosec;
}

// The goal id as rclcpp prints a UUID (hex), for logs.
std::string goal_id_text(const GoalId& id) {
  static constexpr char k_hex[] = "0123456789abcdef";
  std::string out;
  for (std::uint8_t byte : id) {
    out += k_hex[byte >> 4];
    out += k_hex[byte & 15];
  }
  return out;
}

}  // namespace

Ros2SimulateSteps::Ros2SimulateSteps(Settings settings, Ros2Services& services,
                                     dds_entity_t participant, Starter start, Canceller cancel,
                                     std::function<double()> sim_time)
    : settings_(std::move(settings)),
      services_(services),
      participant_(participant),
      start_(std::move(start)),
      cancel_(std::move(cancel)),
      sim_time_(std::move(sim_time)) {
  const std::string& action = settings_.action;
  services_.add(
      action_part_name(action, "send_goal"),
      simulation_interfaces_action_dds__SimulateSteps_SendGoal_Request__desc,
      simulation_interfaces_action_dds__SimulateSteps_SendGoal_Response__desc,
      [this](const void* request, const Ros2Services::ReplyTo& to) { send_goal(request, to); });
  services_.add(
      action_part_name(action, "cancel_goal"), action_msgs_srv_dds__CancelGoal_Request__desc,
      action_msgs_srv_dds__CancelGoal_Response__desc,
      [this](const void* request, const Ros2Services::ReplyTo& to) { cancel_goal(request, to); });
  services_.add(
      action_part_name(action, "get_result"),
      simulation_interfaces_action_dds__SimulateSteps_GetResult_Request__desc,
      simulation_interfaces_action_dds__SimulateSteps_GetResult_Response__desc,
      [this](const void* request, const Ros2Services::ReplyTo& to) { get_result(request, to); });
  // feedback: ROS 2's default profile (reliable, volatile, keep-last 10); status: rcl_action's
  // (reliable, transient-local, keep-last 1)
  const std::string feedback_topic =
      dds_topic_name(services_.full_name(action_part_name(action, "feedback")));
  const std::string status_topic =
      dds_topic_name(services_.full_name(action_part_name(action, "status")));
  dds::QosPtr feedback_qos = dds::make_qos(false, 10, 0);
  dds::QosPtr status_qos = dds::make_qos(true, 1, 0);
  feedback_writer_ = dds::check_created(
      dds_create_writer(
          participant_,
          dds::cached_topic(
              topics_, participant_, feedback_topic,
              name_only(simulation_interfaces_action_dds__SimulateSteps_FeedbackMessage__desc)),
          feedback_qos.get(), nullptr),
      "writer " + feedback_topic);
  status_writer_ = dds::check_created(
      dds_create_writer(participant_,
                        dds::cached_topic(topics_, participant_, status_topic,
                                          name_only(action_msgs_msg_dds__GoalStatusArray__desc)),
                        status_qos.get(), nullptr),
      "writer " + status_topic);
}

Ros2SimulateSteps::~Ros2SimulateSteps() = default;  // the entities go with the participant

void Ros2SimulateSteps::endpoints(std::vector<dds_entity_t>& writers,
                                  std::vector<dds_entity_t>&) const {
  writers.push_back(feedback_writer_);
  writers.push_back(status_writer_);
}

Ros2SimulateSteps::Goal* Ros2SimulateSteps::find(const GoalId& id) {
  for (Goal& goal : goals_)
    if (goal.id == id) return &goal;
  return nullptr;
}

bool Ros2SimulateSteps::move(Goal& goal, GoalEvent event) {
  const std::optional<GoalStatus> next = goal_transition(goal.status, event);
  if (!next) {
    log::debug("ros2 transport: ", settings_.action, ": goal ", goal_id_text(goal.id), ": event ",
               static_cast<int>(event), " refused in state ", static_cast<int>(goal.status));
    return false;
  }
  goal.status = *next;
  return true;
}

void Ros2SimulateSteps::send_goal(const void* request, const Ros2Services::ReplyTo& to) {
  const auto& rq = *static_cast<const SendGoalRequest*>(request);
  const GoalId id = goal_id_of(rq.goal_id);
  const std::uint64_t steps = rq.goal.steps;
  SendGoalResponse* response;
  Ros2Services::Sample reply = services_.new_reply(to, response);
  // one goal at a time (simgate's `simulation` takes one step call at a time), ids unique
  const bool running = std::any_of(goals_.begin(), goals_.end(),
                                   [](const Goal& goal) { return !is_terminal(goal.status); });
  if (running || find(id)) {
    response->accepted = false;  // stamp zero, as rclcpp_action answers a rejected goal
    services_.send(to, std::move(reply));
    log::debug("ros2 transport: ", settings_.action, ": goal ", goal_id_text(id),
               " rejected: ", running ? "another goal runs" : "its id is taken");
    return;
  }
  Goal goal;
  goal.id = id;
  const RosTime now = to_ros_time(sim_time_());
  goal.sec = now.sec;
  goal.nanosec = now.nanosec;
  goal.steps = steps;
  goals_.push_back(std::move(goal));
  trim();
  response->accepted = true;
  response->stamp.sec = now.sec;
  response->stamp.nanosec = now.nanosec;
  services_.send(to, std::move(reply));
  write_status();  // ACCEPTED
  move(goals_.back(), GoalEvent::execute);
  write_status();  // EXECUTING
  // simgate refuses a count beyond what it takes in one call, saying so (the goal aborts)
  Call call{
      "simulation", "step",
      json{{"n", steps > static_cast<std::uint64_t>(INT64_MAX) ? json(INT64_MAX) : json(steps)}}};
  call.progress = true;
  RequestId call_id = 0;
  try {
    call_id = start_(
        std::move(call), [this, id](json&& progress) { progressed(id, progress); },
        [this, id](Outcome&& outcome) { ended(id, std::move(outcome)); });
  } catch (const std::exception& e) {
    ended(id, Outcome::failed(Failure::internal, e.what()));
    return;
  }
  // the call may have ended already (a playing simulation refuses at once)
  if (Goal* started = find(id); started && !is_terminal(started->status)) started->call = call_id;
}

void Ros2SimulateSteps::cancel_goal(const void* request, const Ros2Services::ReplyTo& to) {
  const auto& rq = *static_cast<const CancelGoalRequest*>(request);
  std::vector<GoalRef> known;
  known.reserve(goals_.size());
  for (const Goal& goal : goals_)
    known.push_back({goal.id, stamp_nanoseconds(goal.sec, goal.nanosec), goal.status});
  const CancelSelection selection = select_for_cancel(
      goal_id_of(rq.goal_info.goal_id),
      stamp_nanoseconds(rq.goal_info.stamp.sec, rq.goal_info.stamp.nanosec), known);
  CancelGoalResponse* response;
  Ros2Services::Sample reply = services_.new_reply(to, response);
  response->return_code = static_cast<std::int8_t>(selection.code);
  GoalInfoMessage* canceling = alloc_sequence(response->goals_canceling, selection.goals.size());
  std::vector<RequestId> calls;
  for (std::size_t i = 0; i < selection.goals.size(); ++i) {
    Goal& goal = goals_[selection.goals[i]];
    set_goal_id(canceling[i].goal_id, goal.id);
    canceling[i].stamp.sec = goal.sec;
    canceling[i].stamp.nanosec = goal.nanosec;
    move(goal, GoalEvent::cancel_goal);
    goal.cancel_requested = true;
    if (goal.call != 0) calls.push_back(goal.call);
  }
  services_.send(to, std::move(reply));
  if (selection.goals.empty()) return;
  write_status();  // CANCELING
  // simgate ends each step call early (PREEMPTED with the steps done): the goal is CANCELED
  for (const RequestId call : calls) cancel_(call);
}

void Ros2SimulateSteps::get_result(const void* request, const Ros2Services::ReplyTo& to) {
  const GoalId id = goal_id_of(static_cast<const GetResultRequest*>(request)->goal_id);
  Goal* goal = find(id);
  if (goal && !is_terminal(goal->status)) {
    // answered when the goal ends
    if (goal->waiting.size() < settings_.max_waiting_results) {
      goal->waiting.push_back(to);
    } else if (waiting_dropped_++ % 100 == 0) {
      log::warning("ros2 transport: ", settings_.action, ": goal ", goal_id_text(id),
                   ": more than ", settings_.max_waiting_results,
                   " get_result requests wait for it; later ones are not answered (",
                   waiting_dropped_, " so far)");
    }
    return;
  }
  if (goal) {
    reply_result(*goal, to);
    return;
  }
  // a goal not known (never accepted, or forgotten): STATUS_UNKNOWN, as rclcpp_action answers
  GetResultResponse* response;
  Ros2Services::Sample reply = services_.new_reply(to, response);
  response->status = static_cast<std::int8_t>(GoalStatus::unknown);
  response->result.result.error_message = dds_string_dup("");
  services_.send(to, std::move(reply));
}

void Ros2SimulateSteps::reply_result(const Goal& goal, const Ros2Services::ReplyTo& to) {
  GetResultResponse* response;
  Ros2Services::Sample reply = services_.new_reply(to, response);
  response->status = static_cast<std::int8_t>(goal.status);
  response->result.result.result = goal.result.code;
  response->result.result.error_message = dds_string_dup(goal.result.message.c_str());
  services_.send(to, std::move(reply));
}

void Ros2SimulateSteps::progressed(const GoalId& id, const json& progress) {
  const Goal* goal = find(id);
  if (!goal || is_terminal(goal->status)) return;
  const std::optional<StepsFeedback> feedback = steps_feedback(progress, goal->steps);
  if (!feedback) return;
  FeedbackMessage message{};
  set_goal_id(message.goal_id, id);
  message.feedback.completed_steps = feedback->completed_steps;
  message.feedback.remaining_steps = feedback->remaining_steps;
  if (dds_return_t rc = dds_write(feedback_writer_, &message); rc < 0)
    log::debug("ros2 transport: ", settings_.action,
               ": feedback not written: ", dds::retcode_text(rc));
}

void Ros2SimulateSteps::ended(const GoalId& id, Outcome&& outcome) {
  Goal* goal = find(id);
  if (!goal || is_terminal(goal->status)) return;
  const GoalEnd end = steps_goal_end(outcome, goal->cancel_requested, goal->steps);
  const GoalEvent event = end.status == GoalStatus::succeeded  ? GoalEvent::succeed
                          : end.status == GoalStatus::canceled ? GoalEvent::canceled
                                                               : GoalEvent::abort;
  if (!move(*goal, event)) goal->status = end.status;  // never left without an end
  goal->result = end.result;
  goal->call = 0;
  goal->ended = std::chrono::steady_clock::now();
  if (goal->status != GoalStatus::succeeded)
    log::debug("ros2 transport: ", settings_.action, ": goal ", goal_id_text(id), " ended ",
               static_cast<int>(goal->status), ": ", goal->result.message);
  // the results to whoever asked, then the status (rclcpp_action's order)
  std::vector<Ros2Services::ReplyTo> waiting = std::move(goal->waiting);
  goal->waiting.clear();
  for (const Ros2Services::ReplyTo& to : waiting) reply_result(*goal, to);
  write_status();
}

void Ros2SimulateSteps::write_status() {
  std::vector<GoalStatusMessage> list(goals_.size());
  for (std::size_t i = 0; i < goals_.size(); ++i) {
    set_goal_id(list[i].goal_info.goal_id, goals_[i].id);
    list[i].goal_info.stamp.sec = goals_[i].sec;
    list[i].goal_info.stamp.nanosec = goals_[i].nanosec;
    list[i].status = static_cast<std::int8_t>(goals_[i].status);
  }
  action_msgs_msg_dds__GoalStatusArray_ message{};
  message.status_list._buffer = list.data();
  message.status_list._length = message.status_list._maximum =
      static_cast<std::uint32_t>(list.size());
  if (dds_return_t rc = dds_write(status_writer_, &message); rc < 0)
    log::debug("ros2 transport: ", settings_.action,
               ": status not written: ", dds::retcode_text(rc));
}

void Ros2SimulateSteps::trim() {
  std::size_t ended = 0;
  for (const Goal& goal : goals_) ended += is_terminal(goal.status) ? 1 : 0;
  // the oldest first: goals end in the order they were accepted (one runs at a time)
  while (ended > settings_.max_ended_goals && is_terminal(goals_.front().status)) {
    goals_.pop_front();
    --ended;
  }
}

void Ros2SimulateSteps::expire() {
  if (goals_.empty()) return;
  const auto now = std::chrono::steady_clock::now();
  bool expired = false;
  while (!goals_.empty() && is_terminal(goals_.front().status) &&
         now - goals_.front().ended >= settings_.result_timeout) {
    goals_.pop_front();
    expired = true;
  }
  if (expired) write_status();
}

}  // namespace simgate::ros2
