// simgate/ros2 action goals — a ROS 2 action's goals in simgate's terms, for the ros2 transport's
// SimulateSteps action (plugins/ros2/ros2_simulate_steps.h, docs/transports/ros2.md): the names
// rcl_action gives an action's services and topics, the goal states of action_msgs/GoalStatus
// and rcl_action's state machine over them, the cancel policy of action_msgs/CancelGoal as
// rcl_action applies it, and how `simulation step`'s progress and outcome become SimulateSteps'
// feedback and result. The types are ros2_actions.idl's.
//
// Threads: any (pure functions).
#ifndef SIMGATE_PROTOCOLS_ROS2_ROS2_ACTION_GOALS_H_
#define SIMGATE_PROTOCOLS_ROS2_ROS2_ACTION_GOALS_H_

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "ros2_sim_interfaces.h"
#include "simgate/core/status.h"

namespace simgate::ros2 {

// The ROS names of an action's parts (rcl_action's names): "<action>/_action/send_goal",
// "/cancel_goal", "/get_result" (services) and "/feedback", "/status" (topics), for the fully
// qualified `action` ("/simulate_steps").
std::string action_part_name(std::string_view action, std::string_view part);

// action_msgs/msg/GoalStatus.
enum class GoalStatus : std::int8_t {
  unknown = 0,
  accepted = 1,
  executing = 2,
  canceling = 3,
  succeeded = 4,
  canceled = 5,
  aborted = 6,
};
// SUCCEEDED, CANCELED, ABORTED: the goal has its result.
bool is_terminal(GoalStatus status);
// ACCEPTED, EXECUTING: a cancel request may move it to CANCELING.
bool is_cancelable(GoalStatus status);

// rcl_action's goal events, and its state machine: the state `event` leads to from `from`,
// nullopt when rcl_action refuses that transition (ACCEPTED -execute-> EXECUTING; ACCEPTED or
// EXECUTING -cancel_goal-> CANCELING; EXECUTING or CANCELING -succeed-> SUCCEEDED, -abort->
// ABORTED; CANCELING -canceled-> CANCELED).
enum class GoalEvent : std::uint8_t { execute, cancel_goal, succeed, abort, canceled };
std::optional<GoalStatus> goal_transition(GoalStatus from, GoalEvent event);

// action_msgs/srv/CancelGoal's return codes.
enum class CancelCode : std::int8_t {
  none = 0,             // ERROR_NONE: goals_canceling lists the goals now CANCELING
  rejected = 1,         // ERROR_REJECTED
  unknown_goal_id = 2,  // ERROR_UNKNOWN_GOAL_ID
  goal_terminated = 3,  // ERROR_GOAL_TERMINATED
};

// unique_identifier_msgs/UUID: a goal's id.
using GoalId = std::array<std::uint8_t, 16>;
// What a cancel request is matched against: a goal, its acceptance stamp (ROS time, ns) and
// its state.
struct GoalRef {
  GoalId id{};
  std::int64_t stamp_ns = 0;
  GoalStatus status = GoalStatus::unknown;
};
// Which goals a CancelGoal request {goal_id, stamp} cancels, as rcl_action decides: id and
// stamp zero: every cancelable goal; id zero, stamp not: those accepted at or before the
// stamp; id not zero, stamp zero: that goal (UNKNOWN_GOAL_ID when there is none,
// GOAL_TERMINATED when it has ended); both: that goal and those accepted at or before the
// stamp. `goals`: indices into `known`, cancelable ones only; `code` NONE otherwise (also when
// none matched, as rcl_action answers).
struct CancelSelection {
  CancelCode code = CancelCode::none;
  std::vector<std::size_t> goals;
};
CancelSelection select_for_cancel(const GoalId& id, std::int64_t stamp_ns,
                                  std::span<const GoalRef> known);

// ---- SimulateSteps (simulation_interfaces 2.1) ----

// `simulation step {"n": requested}`'s progress report ({"steps_done": k, ...}) as
// SimulateSteps' feedback; nullopt when it is not that shape.
struct StepsFeedback {
  std::uint64_t completed_steps = 0;
  std::uint64_t remaining_steps = 0;
};
std::optional<StepsFeedback> steps_feedback(const json& progress, std::uint64_t requested);

// How a SimulateSteps goal ends, from its `simulation step` call's outcome: SUCCESS:
// SUCCEEDED, RESULT_OK; PREEMPTED after the client's cancel (`cancel_requested`): CANCELED,
// RESULT_OK, the message saying how many steps were taken; PREEMPTED otherwise (a pause, a
// play or another client's step stopped it): ABORTED, RESULT_OPERATION_FAILED with simgate's
// reason and the steps taken; FAILED: ABORTED with result_of's code (RESULT_INCORRECT_STATE
// for a playing simulation, RESULT_OPERATION_FAILED for a step count simgate refuses, ...).
struct GoalEnd {
  GoalStatus status = GoalStatus::aborted;
  ServiceResult result;
};
GoalEnd steps_goal_end(const Outcome& outcome, bool cancel_requested, std::uint64_t requested);

}  // namespace simgate::ros2

#endif  // SIMGATE_PROTOCOLS_ROS2_ROS2_ACTION_GOALS_H_
