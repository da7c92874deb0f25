// The ros2 transport's SimulateSteps action in simgate's terms (protocols/ros2/ros2_action_goals.h):
// rcl_action's names, goal states and cancel policy; `simulation step`'s progress and outcome as
// the action's feedback and result; the action's types on the wire (ros2_actions.idl).
#include <gtest/gtest.h>

#include <cstddef>
#include <string>
#include <vector>

#include "ros2_action_goals.h"
#include "ros2_actions.h"
#include "ros2_mapping.h"
#include "ros2_sim_interfaces.h"

namespace simgate::ros2 {
namespace {

GoalId id_of(std::uint8_t last) {
  GoalId id{};
  id[15] = last;
  return id;
}

std::vector<std::size_t> indices(std::initializer_list<std::size_t> list) { return list; }

Outcome step_preempted(Failure failure, std::string message, std::uint64_t done,
                       std::uint64_t requested) {
  Outcome o;
  o.status = Status::preempted;
  o.failure = failure;
  o.message = std::move(message);
  o.value = json{{"sim_time", 1.5}, {"steps_done", done}, {"steps_requested", requested}};
  return o;
}

TEST(Ros2ActionGoalsTest, PartsAreNamedAsRclActionNamesThem) {
  EXPECT_EQ(action_part_name("/simulate_steps", "send_goal"), "/simulate_steps/_action/send_goal");
  EXPECT_EQ(action_part_name("/sim/simulate_steps", "status"),
            "/sim/simulate_steps/_action/status");
  // as rmw_cyclonedds puts them on DDS
  EXPECT_EQ(service_request_topic(action_part_name("/simulate_steps", "cancel_goal")),
            "rq/simulate_steps/_action/cancel_goalRequest");
  EXPECT_EQ(service_reply_topic(action_part_name("/simulate_steps", "get_result")),
            "rr/simulate_steps/_action/get_resultReply");
  EXPECT_EQ(dds_topic_name(action_part_name("/simulate_steps", "feedback")),
            "rt/simulate_steps/_action/feedback");
}

TEST(Ros2ActionGoalsTest, GoalsMoveAsRclActionsStateMachineLetsThem) {
  using S = GoalStatus;
  using E = GoalEvent;
  EXPECT_EQ(goal_transition(S::accepted, E::execute), S::executing);
  EXPECT_EQ(goal_transition(S::accepted, E::cancel_goal), S::canceling);
  EXPECT_EQ(goal_transition(S::executing, E::cancel_goal), S::canceling);
  EXPECT_EQ(goal_transition(S::executing, E::succeed), S::succeeded);
  EXPECT_EQ(goal_transition(S::executing, E::abort), S::aborted);
  EXPECT_EQ(goal_transition(S::canceling, E::canceled), S::canceled);
  EXPECT_EQ(goal_transition(S::canceling, E::succeed), S::succeeded);  // it ended first
  EXPECT_EQ(goal_transition(S::canceling, E::abort), S::aborted);
  // refused: canceled without a cancel request, anything after the end, executing twice
  EXPECT_FALSE(goal_transition(S::executing, E::canceled));
  EXPECT_FALSE(goal_transition(S::accepted, E::succeed));
  EXPECT_FALSE(goal_transition(S::executing, E::execute));
  for (S end : {S::succeeded, S::canceled, S::aborted}) {
    EXPECT_TRUE(is_terminal(end));
    EXPECT_FALSE(is_cancelable(end));
    for (E event : {E::execute, E::cancel_goal, E::succeed, E::abort, E::canceled})
      EXPECT_FALSE(goal_transition(end, event));
  }
  EXPECT_FALSE(is_terminal(S::canceling));
  EXPECT_FALSE(is_cancelable(S::canceling));  // already asked
}

TEST(Ros2ActionGoalsTest, CancelRequestsSelectGoalsAsRclActionDoes) {
  const std::vector<GoalRef> goals{{id_of(1), 100, GoalStatus::succeeded},
                                   {id_of(2), 200, GoalStatus::aborted},
                                   {id_of(3), 300, GoalStatus::executing}};
  // one goal by id (stamp zero)
  CancelSelection one = select_for_cancel(id_of(3), 0, goals);
  EXPECT_EQ(one.code, CancelCode::none);
  EXPECT_EQ(one.goals, indices({2}));
  CancelSelection ended = select_for_cancel(id_of(1), 0, goals);
  EXPECT_EQ(ended.code, CancelCode::goal_terminated);
  EXPECT_TRUE(ended.goals.empty());
  CancelSelection unknown = select_for_cancel(id_of(9), 0, goals);
  EXPECT_EQ(unknown.code, CancelCode::unknown_goal_id);
  EXPECT_TRUE(unknown.goals.empty());
  // id and stamp zero: every goal that can be
  CancelSelection all = select_for_cancel(GoalId{}, 0, goals);
  EXPECT_EQ(all.code, CancelCode::none);
  EXPECT_EQ(all.goals, indices({2}));
  // a stamp: those accepted at or before it (none here: an empty list, still ERROR_NONE)
  CancelSelection before = select_for_cancel(GoalId{}, 250, goals);
  EXPECT_EQ(before.code, CancelCode::none);
  EXPECT_TRUE(before.goals.empty());
  EXPECT_EQ(select_for_cancel(GoalId{}, 300, goals).goals, indices({2}));
  // both: that goal, and those accepted before the stamp
  EXPECT_EQ(select_for_cancel(id_of(3), 50, goals).goals, indices({2}));
}

TEST(Ros2ActionGoalsTest, StepProgressIsTheFeedback) {
  const auto feedback = steps_feedback(json{{"steps_done", 40u}, {"steps_requested", 200u}}, 200);
  ASSERT_TRUE(feedback);
  EXPECT_EQ(feedback->completed_steps, 40u);
  EXPECT_EQ(feedback->remaining_steps, 160u);
  const auto capped = steps_feedback(json{{"steps_done", 300u}}, 200);
  ASSERT_TRUE(capped);
  EXPECT_EQ(capped->remaining_steps, 0u);
  EXPECT_FALSE(steps_feedback(json{{"distance_left", 2.0}}, 200));
  EXPECT_FALSE(steps_feedback(json{{"steps_done", -1}}, 200));
  EXPECT_FALSE(steps_feedback(json(), 200));
}

TEST(Ros2ActionGoalsTest, StepOutcomesEndTheGoal) {
  const GoalEnd done =
      steps_goal_end(Outcome::success(json{{"sim_time", 0.4}, {"steps_done", 200u}}), false, 200);
  EXPECT_EQ(done.status, GoalStatus::succeeded);
  EXPECT_TRUE(done.result.is_ok());
  EXPECT_EQ(done.result.message, "");

  // cancelled by its client: CANCELED, the steps taken said
  const GoalEnd canceled = steps_goal_end(
      step_preempted(Failure::cancelled, "cancelled by its client", 1234, 1000000), true, 1000000);
  EXPECT_EQ(canceled.status, GoalStatus::canceled);
  EXPECT_TRUE(canceled.result.is_ok());
  EXPECT_NE(canceled.result.message.find("1234 of 1000000 steps"), std::string::npos)
      << canceled.result.message;

  // stopped by someone else (a pause): ABORTED, OPERATION_FAILED, why and how far
  const GoalEnd paused = steps_goal_end(
      step_preempted(Failure::preempted, "simulation pause stopped the steps", 7, 50), false, 50);
  EXPECT_EQ(paused.status, GoalStatus::aborted);
  EXPECT_EQ(paused.result.code, static_cast<std::uint8_t>(ResultCode::operation_failed));
  EXPECT_NE(paused.result.message.find("simulation pause"), std::string::npos);
  EXPECT_NE(paused.result.message.find("7 of 50 steps"), std::string::npos);

  // refused for a playing simulation: ABORTED, INCORRECT_STATE, simgate's message
  const GoalEnd playing = steps_goal_end(
      Outcome::failed(Failure::service_error, "the simulation is playing; pause it first",
                      json{{"state", "playing"}}),
      false, 10);
  EXPECT_EQ(playing.status, GoalStatus::aborted);
  EXPECT_EQ(playing.result.code, static_cast<std::uint8_t>(ResultCode::incorrect_state));
  EXPECT_NE(playing.result.message.find("pause it first"), std::string::npos);

  // a count simgate refuses: ABORTED, OPERATION_FAILED
  const GoalEnd too_many =
      steps_goal_end(Outcome::failed(Failure::bad_arguments, "n = 10000000 is out of range",
                                     json{{"parameter", "n"}}),
                     false, 10000000);
  EXPECT_EQ(too_many.status, GoalStatus::aborted);
  EXPECT_EQ(too_many.result.code, static_cast<std::uint8_t>(ResultCode::operation_failed));

  // a cancel asked, but the steps were all taken first: SUCCEEDED
  EXPECT_EQ(steps_goal_end(Outcome::success(json{{"steps_done", 5u}}), true, 5).status,
            GoalStatus::succeeded);
}

TEST(Ros2ActionGoalsTest, ActionTypesHaveRosNamesAndTheRequestHeader) {
#define SIMGATE_EXPECT_HEADER(T)                     \
  EXPECT_EQ(offsetof(T, rmw_client_guid), 0u) << #T; \
  EXPECT_EQ(offsetof(T, rmw_sequence), 8u) << #T
  SIMGATE_EXPECT_HEADER(simulation_interfaces_action_dds__SimulateSteps_SendGoal_Request_);
  SIMGATE_EXPECT_HEADER(simulation_interfaces_action_dds__SimulateSteps_SendGoal_Response_);
  SIMGATE_EXPECT_HEADER(simulation_interfaces_action_dds__SimulateSteps_GetResult_Request_);
  SIMGATE_EXPECT_HEADER(simulation_interfaces_action_dds__SimulateSteps_GetResult_Response_);
  SIMGATE_EXPECT_HEADER(action_msgs_srv_dds__CancelGoal_Request_);
  SIMGATE_EXPECT_HEADER(action_msgs_srv_dds__CancelGoal_Response_);
#undef SIMGATE_EXPECT_HEADER
  EXPECT_STREQ(simulation_interfaces_action_dds__SimulateSteps_SendGoal_Request__desc.m_typename,
               "simulation_interfaces::action::dds_::SimulateSteps_SendGoal_Request_");
  EXPECT_STREQ(simulation_interfaces_action_dds__SimulateSteps_FeedbackMessage__desc.m_typename,
               "simulation_interfaces::action::dds_::SimulateSteps_FeedbackMessage_");
  EXPECT_STREQ(action_msgs_srv_dds__CancelGoal_Response__desc.m_typename,
               "action_msgs::srv::dds_::CancelGoal_Response_");
  EXPECT_STREQ(action_msgs_msg_dds__GoalStatusArray__desc.m_typename,
               "action_msgs::msg::dds_::GoalStatusArray_");
  // a goal id is 16 bytes, as unique_identifier_msgs/UUID
  EXPECT_EQ(sizeof(unique_identifier_msgs_msg_dds__UUID_), 16u);
}

}  // namespace
}  // namespace simgate::ros2
