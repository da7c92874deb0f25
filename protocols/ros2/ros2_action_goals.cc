// A ROS 2 action's goals in simgate's terms. See ros2_action_goals.h.
#include "ros2_action_goals.h"

#include <algorithm>

namespace simgate::ros2 {

std::string action_part_name(std::string_view action, std::string_view part) {
  return std::string(action) + "/_action/" + std::string(part);
}

bool is_terminal(GoalStatus status) {
  return status == GoalStatus::succeeded || status == GoalStatus::canceled ||
         status == GoalStatus::aborted;
}

bool is_cancelable(GoalStatus status) {
  return status == GoalStatus::accepted || status == GoalStatus::executing;
}

std::optional<GoalStatus> goal_transition(GoalStatus from, GoalEvent event) {
  switch (event) {
    case GoalEvent::execute:
      if (from == GoalStatus::accepted) return GoalStatus::executing;
      break;
    case GoalEvent::cancel_goal:
      if (is_cancelable(from)) return GoalStatus::canceling;
      break;
    case GoalEvent::succeed:
      if (from == GoalStatus::executing || from == GoalStatus::canceling)
        return GoalStatus::succeeded;
      break;
    case GoalEvent::abort:
      if (from == GoalStatus::executing || from == GoalStatus::canceling)
        return GoalStatus::aborted;
      break;
    case GoalEvent::canceled:
      if (from == GoalStatus::canceling) return GoalStatus::canceled;
      break;
  }
  return std::nullopt;
}

CancelSelection select_for_cancel(const GoalId& id, std::int64_t stamp_ns,
                                  std::span<const GoalRef> known) {
  CancelSelection out;
  const bool zero_id = std::all_of(id.begin(), id.end(), [](std::uint8_t b) { return b == 0; });
  if (!zero_id && stamp_ns == 0) {
    // exactly that goal
    out.code = CancelCode::unknown_goal_id;
    for (std::size_t i = 0; i < known.size(); ++i) {
      if (known[i].id != id) continue;
      if (is_cancelable(known[i].status)) {
        out.code = CancelCode::none;
        out.goals.push_back(i);
      } else {
        out.code = CancelCode::goal_terminated;
      }
      break;
    }
    return out;
  }
  // every goal accepted at or before the stamp (all of them: both zero), and that goal
  const std::int64_t until = zero_id && stamp_ns == 0 ? INT64_MAX : stamp_ns;
  for (std::size_t i = 0; i < known.size(); ++i)
    if (is_cancelable(known[i].status) && (known[i].stamp_ns <= until || known[i].id == id))
      out.goals.push_back(i);
  return out;
}

namespace {
// {"steps_done": k, ...}'s k (a count: an integer, not negative), or nullopt.
std::optional<std::uint64_t> steps_done_in(const json& value) {
  if (!value.is_object()) return std::nullopt;
  const auto it = value.find("steps_done");
  if (it == value.end() || !it->is_number_integer() ||
      (!it->is_number_unsigned() && it->get<std::int64_t>() < 0))
    return std::nullopt;
  return it->get<std::uint64_t>();
}
}  // namespace

std::optional<StepsFeedback> steps_feedback(const json& progress, std::uint64_t requested) {
  const std::optional<std::uint64_t> done = steps_done_in(progress);
  if (!done) return std::nullopt;
  const std::uint64_t completed = std::min(*done, requested);
  return StepsFeedback{completed, requested - completed};
}

namespace {
// The steps an ended step call took, or nullopt.
std::optional<std::uint64_t> steps_done(const Outcome& outcome) {
  return outcome.value ? steps_done_in(*outcome.value) : std::nullopt;
}

std::string steps_taken(const Outcome& outcome, std::uint64_t requested) {
  const std::optional<std::uint64_t> done = steps_done(outcome);
  return (done ? std::to_string(*done) : std::string("?")) + " of " + std::to_string(requested) +
         " steps taken";
}
}  // namespace

GoalEnd steps_goal_end(const Outcome& outcome, bool cancel_requested, std::uint64_t requested) {
  if (outcome.status == Status::success) return {GoalStatus::succeeded, ServiceResult::ok()};
  if (outcome.status == Status::preempted) {
    if (cancel_requested)
      return {GoalStatus::canceled, ServiceResult{static_cast<std::uint8_t>(ResultCode::ok),
                                                  "canceled: " + steps_taken(outcome, requested)}};
    const std::string why = outcome.message.empty() ? std::string("preempted") : outcome.message;
    return {GoalStatus::aborted,
            ServiceResult::fail(ResultCode::operation_failed,
                                why + " (" + steps_taken(outcome, requested) + ")")};
  }
  return {GoalStatus::aborted, result_of(outcome)};
}

}  // namespace simgate::ros2
