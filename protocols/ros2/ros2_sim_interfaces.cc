// ROS 2 services in simgate's terms. See ros2_sim_interfaces.h.
#include "ros2_sim_interfaces.h"

#include <regex.h>

#include <cstdio>
#include <memory>
#include <stdexcept>

namespace simgate::ros2 {

std::optional<SimState> sim_state_of(std::string_view run_state) {
  if (run_state == "playing") return SimState::playing;
  // stepping: paused, taking the steps a client asked for
  if (run_state == "paused" || run_state == "stepping") return SimState::paused;
  if (run_state == "quitting") return SimState::quitting;
  return std::nullopt;
}

std::optional<std::string> reset_scope_of(std::uint8_t scope, std::string& why) {
  if (scope == 0 || scope == (k_scope_time | k_scope_state)) return "all";
  if (scope == k_scope_state) return "state";
  if (scope & k_scope_spawned)
    why = "scope " + std::to_string(scope) +
          " includes SCOPE_SPAWNED: a reset keeps the entities spawned since the start (delete "
          "them with DeleteEntity); SCOPE_DEFAULT or SCOPE_TIME | SCOPE_STATE reset everything "
          "else";
  else if (scope == k_scope_time)
    why =
        "scope SCOPE_TIME alone: the simulated time goes back to 0 only with the state "
        "(SCOPE_TIME | SCOPE_STATE)";
  else
    why = "scope " + std::to_string(scope) +
          ": expected SCOPE_DEFAULT (0), SCOPE_STATE (2) or SCOPE_TIME | SCOPE_STATE (3)";
  return std::nullopt;
}

std::vector<std::uint16_t> offered_features(
    const std::function<bool(const std::string& service)>& may_call) {
  struct Feature {
    std::uint16_t id;
    std::vector<const char*> services;  // the `simulation` services its ROS services call
  };
  static const std::vector<Feature> implemented{
      {0, {"spawn_entity", "list_entities"}},
      {1, {"delete_entity"}},
      {5, {"get_object_bbox"}},
      {9, {"spawn_entity", "list_entities"}},
      {10, {"get_entity_state"}},
      {11, {"set_entity_state", "get_entity_state"}},
      {12, {"get_entity_state", "list_robots"}},
      {20, {"reset"}},
      {21, {"reset"}},
      {22, {"reset"}},
      {24, {"get_simulation_state"}},
      {25, {"get_simulation_state", "pause", "play"}},
      {26, {"get_simulation_state", "pause"}},
      {31, {"step"}},
      {32, {"step"}},
      {33, {"step"}},
  };
  std::vector<std::uint16_t> out;
  for (const Feature& feature : implemented) {
    bool all = true;
    for (const char* service : feature.services) all = all && may_call(service);
    if (all) out.push_back(feature.id);
  }
  return out;
}

ServiceResult result_of(const Outcome& outcome, std::string_view entity_parameter) {
  std::string message = outcome.message;
  if (message.empty() && outcome.value && outcome.value->is_string())
    message = outcome.value->get<std::string>();
  if (outcome.status == Status::success) return ServiceResult::ok();
  switch (outcome.failure) {
    case Failure::unknown_service:
      return ServiceResult::fail(ResultCode::feature_unsupported, message);
    case Failure::bad_arguments:
      if (!entity_parameter.empty() && outcome.data.is_object() &&
          outcome.data.value("parameter", "") == entity_parameter)
        return ServiceResult::fail(ResultCode::not_found, message);
      break;
    case Failure::service_error:
    case Failure::busy:
      if (outcome.data.is_object() && outcome.data.contains("state"))
        return ServiceResult::fail(ResultCode::incorrect_state, message);
      break;
    default: break;
  }
  return ServiceResult::fail(ResultCode::operation_failed, message);
}

namespace {
std::string service_topic(std::string_view prefix, std::string_view service,
                          std::string_view suffix) {
  if (!service.empty() && service.front() == '/') service.remove_prefix(1);
  return std::string(prefix) + "/" + std::string(service) + std::string(suffix);
}
}  // namespace

std::string service_request_topic(std::string_view service) {
  return service_topic("rq", service, "Request");
}

std::string service_reply_topic(std::string_view service) {
  return service_topic("rr", service, "Reply");
}

std::string service_user_data(const std::array<std::uint8_t, 16>& participant_guid,
                              std::uint32_t counter) {
  std::array<std::uint8_t, 16> id = participant_guid;
  for (int i = 0; i < 4; ++i) id[12 + i] = static_cast<std::uint8_t>(counter >> (24 - 8 * i));
  std::string out = "serviceid=";
  char hex[4];
  std::snprintf(hex, sizeof hex, "%02x", id[0]);
  out += hex;
  for (std::size_t i = 1; i < id.size(); ++i) {
    std::snprintf(hex, sizeof hex, "%x", id[i]);
    out += '.';
    out += hex;
  }
  return out + ";";
}

std::optional<std::string> user_data_value(std::string_view user_data, std::string_view key) {
  while (!user_data.empty()) {
    const std::size_t end = user_data.find(';');
    const std::string_view entry = user_data.substr(0, end);
    const std::size_t equals = entry.find('=');
    if (equals != std::string_view::npos && entry.substr(0, equals) == key)
      return std::string(entry.substr(equals + 1));
    if (end == std::string_view::npos) break;
    user_data.remove_prefix(end + 1);
  }
  return std::nullopt;
}

struct EntityFilter::Compiled {
  regex_t regex;
};

EntityFilter::EntityFilter(const std::string& pattern) {
  if (pattern.empty()) return;
  auto compiled = std::make_unique<Compiled>();
  if (int rc = regcomp(&compiled->regex, pattern.c_str(), REG_EXTENDED | REG_NOSUB); rc != 0) {
    char text[256];
    regerror(rc, &compiled->regex, text, sizeof text);
    throw std::invalid_argument("filter '" + pattern + "' is not a POSIX extended regular " +
                                "expression: " + text);
  }
  compiled_ = compiled.release();
}

EntityFilter::~EntityFilter() {
  if (compiled_) {
    regfree(&compiled_->regex);
    delete compiled_;
  }
}

bool EntityFilter::matches(const std::string& name) const {
  return !compiled_ || regexec(&compiled_->regex, name.c_str(), 0, nullptr, 0) == 0;
}

json pose_json(const std::array<double, 3>& position, const std::array<double, 4>& orientation) {
  return {{"position", position}, {"orientation", orientation}};
}

json twist_json(const std::array<double, 3>& linear, const std::array<double, 3>& angular) {
  return {{"linear", linear}, {"angular", angular}};
}

namespace {
template <std::size_t N>
bool read_numbers(const json& value, std::array<double, N>& out) {
  if (!value.is_array() || value.size() != N) return false;
  for (std::size_t i = 0; i < N; ++i) {
    if (!value[i].is_number()) return false;
    out[i] = value[i].get<double>();
  }
  return true;
}
}  // namespace

bool entity_motion(const json& state, EntityMotion& out) {
  if (!state.is_object() || !state.contains("pose") || !state.contains("twist")) return false;
  const json& pose = state.at("pose");
  const json& twist = state.at("twist");
  return pose.is_object() && twist.is_object() &&
         read_numbers(pose.value("position", json()), out.position) &&
         read_numbers(pose.value("orientation", json()), out.orientation) &&
         read_numbers(twist.value("linear", json()), out.linear) &&
         read_numbers(twist.value("angular", json()), out.angular);
}

}  // namespace simgate::ros2
