// simgate/ros2 — the ros2 transport (issue #41): simgate's data as ROS 2 topics, with ROS 2's
// names, types, CDR and QoS, over plain Cyclone DDS, with no ROS 2 installed. A ROS 2 node
// on any DDS RMW sees /clock, /tf, /tf_static, /<robot>/odom, /<robot>/joint_states and
// writes /<robot>/cmd_vel; `ros2 node list` shows the node /simgate (ros_discovery_info).
// docs/transports/ros2.md is the user's page.
//
// Terms:
//  - participant: one per transport, on the domain protocols/dds makes from the Cyclone
//    settings (by default loopback only, multicast off), USER_DATA "enclave=/;" as
//    rmw_cyclonedds writes it.
//  - the node: one ROS node, `node_name` in namespace "/", owning every endpoint of the
//    transport; its GIDs (the endpoints' DDS GUIDs) are published on ros_discovery_info
//    (rmw_dds_common/ParticipantEntitiesInfo, reliable, transient-local, keep-last 1) each
//    time they change.
//  - /clock: rosgraph_msgs/Clock, the simulated time (StreamHub::time()), written by the DDS
//    thread `clock_hz` times a wall-clock second while it advances, once a second while it
//    stands still (a paused simulation: nodes with use_sim_time that join learn the time).
//  - topics: Ros2Topics (ros2_topics.h).
//  - services: Ros2Services (ros2_services.h): simulation_interfaces' services and
//    simgate/call, each request one or more calls through this transport (call()), their
//    outcomes turned into replies on the DDS thread.
//  - the SimulateSteps action: Ros2SimulateSteps (ros2_simulate_steps.h), its services served
//    by Ros2Services, each goal a `simulation step` call with progress reports (its
//    feedback) that a cancel ends early.
//
// Threads: one DDS thread waits on a waitset (guard condition: samples queued, outcomes
// handed over, the services changed; the cmd_vel readers) with the clock period as its
// timeout, and does all DDS I/O. Its requests (each world's `simulation get_scene_geometry` for its /tf's
// frames, and the services' calls) go through run_or_submit: run at once on this thread when
// the simulation lock is free, else by the simulation thread, their outcomes handed back
// (deliver_on_this_thread). A service's continuation runs after run_or_submit returns, outside
// the lock (it may make the next call). It never touches simulation state.
#ifndef SIMGATE_PLUGINS_ROS2_ROS2_TRANSPORT_H_
#define SIMGATE_PLUGINS_ROS2_ROS2_TRANSPORT_H_

#include <atomic>
#include <chrono>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <thread>
#include <variant>
#include <vector>

#include <dds/dds.h>

#include "dds_support.h"
#include "ros2_services.h"
#include "ros2_simulate_steps.h"
#include "ros2_topics.h"
#include "simgate/core/request_manager.h"

namespace simgate::ros2 {

// The transport's options (plugins/ros2/README.md, Config keys).
struct Ros2Options {
  uint32_t domain = 0;  // DDS domain id = ROS_DOMAIN_ID (0 .. 230)
  std::string config;   // Cyclone settings, as the dds transport's "config"
  std::string node_name = "simgate";
  std::string world_frame = "world";  // the frame of the world body
  double clock_hz = 100;              // /clock writes per wall-clock second; 0: no /clock
  bool tf = true;                     // /tf and /tf_static from simulation's body_poses
  bool humble_graph = false;          // ros_distro "humble": the graph's Gid is 24 bytes
  bool all_robots = true;             // no "robots" option: every robot
  std::set<std::string> robots;       // the robots whose topics are carried
  bool services = true;               // the simulation_interfaces services and simgate/call
  std::string service_namespace;      // "" or "/ns": the services' names under it
  std::chrono::milliseconds park_timeout{10000};  // a reply waits for its client's reader
  // the shortest time between two SimulateSteps feedback messages of a goal (0: every step)
  std::chrono::milliseconds feedback_interval = RequestManager::k_default_progress_interval;
  // Throws ConfigError naming the key and what was expected.
  static Ros2Options parse(const json& options);
};

class Ros2Transport : public RequestManager {
 public:
  // Creates the participant and the graph and clock writers (no thread yet). Throws
  // ConfigError for bad options, std::runtime_error when DDS refuses.
  explicit Ros2Transport(const json& options);
  ~Ros2Transport() override;
  // The options and the Cyclone settings checked, nothing created (simgate check).
  static void validate_options(const json& options);

  // Host thread: the topics (the hub is set by now) and the DDS thread.
  void start() override;
  // Stops and joins the DDS thread, leaves the domain. Idempotent.
  void stop() override;
  std::vector<std::string> endpoints() const override;

 protected:
  // The DDS thread (deliver_on_this_thread): the answer of get_scene_geometry, the
  // services' calls' outcomes.
  void on_service_completion(RequestId id, Outcome&& outcome) override;
  // The DDS thread: a progress report of a call made with progress (SimulateSteps' goals).
  void on_service_progress(RequestId id, json&& value) override;
  // Under the simulation lock, any thread: the streams may have changed (a robot spawned or
  // deleted); the DDS thread syncs its topics.
  void on_services_changed() override;

 private:
  void run();
  // Syncs the topics with the hub's streams; the graph written anew when they changed.
  void sync_topics();
  // Asks the world of body_poses stream `component` for its frame tree (`component`
  // get_scene_geometry) unless a request is under way.
  void ask_geometry(const std::string& component);
  void write_clock(bool force);
  void write_graph();
  // The services' Caller: `call` as a request of this transport, `done` with its outcome
  // (and `progress` with its progress reports, for a call with Call::progress); its id.
  RequestId call(Call call, std::function<void(Outcome&&)> done,
                 std::function<void(json&&)> progress = {});
  // Runs the continuations of the outcomes and progress reports that came (not nested: the
  // outermost runs them).
  void run_continuations();

  const Ros2Options options_;
  std::unique_ptr<dds::Participant> participant_;
  dds_entity_t clock_writer_ = 0;       // rt/clock (none when clock_hz is 0)
  dds_entity_t graph_writer_ = 0;       // ros_discovery_info
  dds_entity_t waitset_ = 0;            // the DDS thread's
  dds_entity_t guard_ = 0;              // wakes it (samples, outcomes, services changed, stop)
  std::unique_ptr<Ros2Topics> topics_;  // made in start()
  std::unique_ptr<Ros2Services> services_;
  std::unique_ptr<Ros2SimulateSteps> simulate_steps_;  // with the services
  // the services' calls in flight, and what came of them (progress reports, then the
  // outcome) that waits for their continuations
  struct Continuation {
    std::function<void(Outcome&&)> done;
    std::function<void(json&&)> progress;  // empty: no progress asked
  };
  std::map<RequestId, Continuation> continuations_;
  using Event = std::variant<Outcome, json>;  // an outcome, or a progress report
  std::deque<std::pair<RequestId, Event>> completed_;
  bool running_continuations_ = false;
  std::thread thread_;  // the DDS thread
  std::atomic<bool> started_{false};
  std::atomic<bool> stopping_{false};
  std::atomic<bool> streams_changed_{true};  // on_services_changed, or not synced yet
  // the pending get_scene_geometry calls: the body_poses stream each asks for
  std::map<RequestId, std::string> geometry_calls_;
  bool geometry_failure_logged_ = false;
  double clock_written_ = -1;                                 // the simulated time /clock said last
  std::chrono::steady_clock::time_point clock_written_at_{};  // when
};

}  // namespace simgate::ros2

#endif  // SIMGATE_PLUGINS_ROS2_ROS2_TRANSPORT_H_
