// simgate/ros2 SimulateSteps — simulation_interfaces 2.1's SimulateSteps action as a ROS 2
// action server, the way rcl_action over rmw_cyclonedds puts an action on DDS, each goal a
// `simulation step {"n": steps}` call of the transport with its progress reports.
//
// Terms:
//  - the action "/simulate_steps" (under the transport's `service_namespace`): three services,
//    served by Ros2Services' machinery (rq/rr topics, request header, serviceid, replies parked
//    until the client's reader matched): "<action>/_action/send_goal", "/cancel_goal",
//    "/get_result"; and two topics written here: "<action>/_action/feedback" (ROS 2's default
//    QoS: reliable, volatile, keep-last 10) and "<action>/_action/status" (rcl_action's status
//    QoS: reliable, transient-local, keep-last 1: a late reader gets the latest).
//  - goal: accepted when no other goal runs and its id is new (else accepted = false: one goal
//    at a time, as simgate's `simulation` runs one step call at a time); its stamp is the
//    simulated time it was accepted at. ACCEPTED -> EXECUTING -> SUCCEEDED, ABORTED, or
//    CANCELING -> CANCELED (rcl_action's state machine, ros2_action_goals.h), the status topic
//    written at each change with every goal kept.
//  - feedback: each progress report of the step call ({steps_done}) as {completed_steps,
//    remaining_steps}, as often as the transport's progress interval lets them through.
//  - cancel: the goals CancelGoal's policy selects go CANCELING and their step call is
//    cancelled (RequestManager::cancel): simgate ends it early, PREEMPTED with the steps done,
//    and the goal is CANCELED.
//  - result: get_result is answered when the goal has ended (at once if it has; status
//    UNKNOWN for a goal not known). An ended goal is kept for `result_timeout`, and at most
//    `max_ended_goals` of them (the oldest go first).
//
// Threads: the DDS thread only (the handlers Ros2Services calls, the Starter's continuations,
// expire()). It never touches simulation state: the goals are calls of the transport.
#ifndef SIMGATE_PLUGINS_ROS2_ROS2_SIMULATE_STEPS_H_
#define SIMGATE_PLUGINS_ROS2_ROS2_SIMULATE_STEPS_H_

#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <dds/dds.h>

#include "ros2_action_goals.h"
#include "ros2_services.h"
#include "simgate/core/request_manager.h"

namespace simgate::ros2 {

class Ros2SimulateSteps {
 public:
  // Runs `call` (Call::progress set) as a request of the transport: its progress reports to
  // `progress`, its outcome to `done` (both on the DDS thread, after the call returns or
  // within it, never from inside the simulation lock); returns its id.
  using Starter = std::function<RequestId(Call call, std::function<void(json&&)> progress,
                                          std::function<void(Outcome&&)> done)>;
  // Cancels the running call `id` (its outcome still comes, to `done`).
  using Canceller = std::function<void(RequestId id)>;

  struct Settings {
    std::string action = "simulate_steps";  // the ROS name, under the services' namespace
    std::chrono::steady_clock::duration result_timeout = std::chrono::minutes(15);
    std::size_t max_ended_goals = 64;
    std::size_t max_waiting_results = 16;  // get_result requests of one running goal
  };

  // Adds the action's services to `services` and makes its topics' writers on `participant`.
  // `sim_time`: the simulated time (goals' stamps). Throws std::runtime_error when DDS refuses.
  Ros2SimulateSteps(Settings settings, Ros2Services& services, dds_entity_t participant,
                    Starter start, Canceller cancel, std::function<double()> sim_time);
  ~Ros2SimulateSteps();
  Ros2SimulateSteps(const Ros2SimulateSteps&) = delete;
  Ros2SimulateSteps& operator=(const Ros2SimulateSteps&) = delete;

  // ---- DDS thread ----
  // Forgets the ended goals past result_timeout (the status topic written again if any).
  void expire();
  // The feedback and status writers, for the ROS graph (the services' endpoints are
  // Ros2Services').
  void endpoints(std::vector<dds_entity_t>& writers, std::vector<dds_entity_t>& readers) const;

 private:
  struct Goal {
    GoalId id{};
    std::int32_t sec = 0;  // when it was accepted (simulated time)
    std::uint32_t nanosec = 0;
    GoalStatus status = GoalStatus::accepted;
    std::uint64_t steps = 0;
    RequestId call = 0;  // its step call, 0 before it starts
    bool cancel_requested = false;
    ServiceResult result;                           // once it has ended
    std::vector<Ros2Services::ReplyTo> waiting;     // get_result requests before it ended
    std::chrono::steady_clock::time_point ended{};  // when it ended
  };

  void send_goal(const void* request, const Ros2Services::ReplyTo& to);
  void cancel_goal(const void* request, const Ros2Services::ReplyTo& to);
  void get_result(const void* request, const Ros2Services::ReplyTo& to);

  Goal* find(const GoalId& id);
  // Moves `goal` through rcl_action's state machine (a refused event is logged, ignored).
  bool move(Goal& goal, GoalEvent event);
  // The step call's progress and outcome.
  void progressed(const GoalId& id, const json& progress);
  void ended(const GoalId& id, Outcome&& outcome);
  void reply_result(const Goal& goal, const Ros2Services::ReplyTo& to);
  void write_status();
  // Drops the oldest ended goals beyond max_ended_goals.
  void trim();

  const Settings settings_;
  Ros2Services& services_;
  const dds_entity_t participant_;
  Starter start_;
  Canceller cancel_;
  std::function<double()> sim_time_;
  std::map<std::string, dds_entity_t> topics_;  // by DDS topic name
  dds_entity_t feedback_writer_ = 0;
  dds_entity_t status_writer_ = 0;
  std::deque<Goal> goals_;             // in the order they were accepted; at most one has not ended
  std::uint64_t waiting_dropped_ = 0;  // get_result requests beyond max_waiting_results
};

}  // namespace simgate::ros2

#endif  // SIMGATE_PLUGINS_ROS2_ROS2_SIMULATE_STEPS_H_
