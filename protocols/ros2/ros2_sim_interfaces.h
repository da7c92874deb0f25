// simgate/ros2 sim interfaces — ROS 2 services in simgate's terms, for the ros2 transport's services
// (plugins/ros2/ros2_services.h, docs/transports/ros2.md): the names rmw_cyclonedds gives a
// service's topics and its endpoints' ids, the codes of ros-simulation/simulation_interfaces
// 2.1 (Result, SimulationState, ResetSimulation's scopes, SimulatorFeatures), and how a
// simgate outcome becomes one of those results. The types are ros2_srvs.idl's.
//
// Threads: any (pure functions).
#ifndef SIMGATE_PROTOCOLS_ROS2_ROS2_SIM_INTERFACES_H_
#define SIMGATE_PROTOCOLS_ROS2_ROS2_SIM_INTERFACES_H_

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "simgate/core/status.h"

namespace simgate::ros2 {

// simulation_interfaces/msg/Result: result codes common to every service; a service's own
// codes are above 100.
enum class ResultCode : std::uint8_t {
  feature_unsupported = 0,
  ok = 1,
  not_found = 2,
  incorrect_state = 3,
  operation_failed = 4,
};
// A result: the code (common or a service's own) and its error_message.
struct ServiceResult {
  std::uint8_t code = static_cast<std::uint8_t>(ResultCode::ok);
  std::string message;
  static ServiceResult ok() { return {}; }
  static ServiceResult fail(ResultCode code, std::string message) {
    return {static_cast<std::uint8_t>(code), std::move(message)};
  }
  static ServiceResult fail(std::uint8_t code, std::string message) {
    return {code, std::move(message)};
  }
  bool is_ok() const { return code == static_cast<std::uint8_t>(ResultCode::ok); }
};

// The services' own result codes (their .srv's constants).
inline constexpr std::uint8_t k_already_in_target_state = 101;  // SetSimulationState
inline constexpr std::uint8_t k_incorrect_transition = 103;     // SetSimulationState
inline constexpr std::uint8_t k_invalid_pose = 101;             // SetEntityState
inline constexpr std::uint8_t k_name_not_unique = 101;          // SpawnEntity
inline constexpr std::uint8_t k_name_invalid = 102;             // SpawnEntity
inline constexpr std::uint8_t k_no_resource = 104;              // SpawnEntity
inline constexpr std::uint8_t k_resource_parse_error = 106;     // SpawnEntity
inline constexpr std::uint8_t k_spawn_invalid_pose = 109;       // SpawnEntity

// simulation_interfaces/msg/SimulationState.
enum class SimState : std::uint8_t {
  stopped = 0,
  playing = 1,
  paused = 2,
  quitting = 3,
  no_world = 4,
  loading_world = 5,
};
// simgate's run state word (`simulation get_simulation_state`'s "state": playing, paused,
// stepping, quitting) as a SimulationState; nullopt for a word it does not know.
std::optional<SimState> sim_state_of(std::string_view run_state);

// ResetSimulation's scope bits (SCOPE_DEFAULT = 0, SCOPE_ALL = 255).
inline constexpr std::uint8_t k_scope_time = 1, k_scope_state = 2, k_scope_spawned = 4;
// `simulation reset`'s scope for ResetSimulation's `scope`: "all" (DEFAULT, TIME | STATE),
// "state" (STATE); nullopt for what simgate cannot reset (TIME alone, SPAWNED, ALL), `why`
// then says so.
std::optional<std::string> reset_scope_of(std::uint8_t scope, std::string& why);

// The SimulatorFeatures the ros2 transport implements, offered when the transport may call
// every `simulation` service its ROS services use for it (`may_call(service)`), in ascending
// order: SPAWNING (0: spawn_entity, list_entities), DELETING (1), ENTITY_BOUNDS (5:
// get_object_bbox), SPAWNING_RESOURCE_STRING (9), ENTITY_STATE_GETTING (10), _SETTING (11),
// ENTITY_INFO_GETTING (12: get_entity_state, list_robots), SIMULATION_RESET and its TIME and
// STATE scopes (20-22: reset), SIMULATION_STATE_GETTING (24), _SETTING (25:
// get_simulation_state, pause, play), SIMULATION_STATE_PAUSE (26), STEP_SIMULATION_SINGLE and
// _MULTIPLE (31, 32: step), STEP_SIMULATION_ACTION (33: step, the SimulateSteps action).
std::vector<std::uint16_t> offered_features(
    const std::function<bool(const std::string& service)>& may_call);

// A failed simgate outcome as a result: unknown_service (not served to this transport):
// FEATURE_UNSUPPORTED; bad_arguments naming `entity_parameter`: NOT_FOUND; refused for the
// simulation's state ("state" in its data): INCORRECT_STATE; anything else:
// OPERATION_FAILED. The message is simgate's.
ServiceResult result_of(const Outcome& outcome, std::string_view entity_parameter = {});

// The topic of a service's half (rmw_cyclonedds' naming): "rq/<name>Request" or
// "rr/<name>Reply" for the fully qualified `service` ("/step_simulation").
std::string service_request_topic(std::string_view service);
std::string service_reply_topic(std::string_view service);

// The USER_DATA rmw_cyclonedds puts on a service's request reader and reply writer
// ("serviceid=<id>;"): the id is the participant's GUID prefix (12 bytes) and `counter` (big
// endian), written as rmw_cyclonedds writes it (the first byte as two hex digits, then each
// byte in hex after a '.').
std::string service_user_data(const std::array<std::uint8_t, 16>& participant_guid,
                              std::uint32_t counter);
// The value of `key` in USER_DATA written as "key=value;key2=value2;" (rmw's format), or
// nullopt.
std::optional<std::string> user_data_value(std::string_view user_data, std::string_view key);

// POSIX extended regular expression matching, as simulation_interfaces' EntityFilters asks
// (glibc's regcomp/regexec: no backtracking blow-up on a client's pattern). An empty
// pattern matches everything. Throws std::invalid_argument naming the pattern's error.
class EntityFilter {
 public:
  explicit EntityFilter(const std::string& pattern);
  ~EntityFilter();
  EntityFilter(const EntityFilter&) = delete;
  EntityFilter& operator=(const EntityFilter&) = delete;
  bool matches(const std::string& name) const;

 private:
  struct Compiled;
  Compiled* compiled_ = nullptr;  // null: matches everything
};

// A ROS pose (position, orientation x y z w) in simgate's words: {"position": [x, y, z],
// "orientation": [qx, qy, qz, qw]}; and a twist {"linear": [...], "angular": [...]}.
json pose_json(const std::array<double, 3>& position, const std::array<double, 4>& orientation);
json twist_json(const std::array<double, 3>& linear, const std::array<double, 3>& angular);
// `simulation get_entity_state`'s answer read back: false when it is not that shape.
struct EntityMotion {
  std::array<double, 3> position{};
  std::array<double, 4> orientation{0, 0, 0, 1};  // x, y, z, w
  std::array<double, 3> linear{};
  std::array<double, 3> angular{};
};
bool entity_motion(const json& state, EntityMotion& out);

}  // namespace simgate::ros2

#endif  // SIMGATE_PROTOCOLS_ROS2_ROS2_SIM_INTERFACES_H_
