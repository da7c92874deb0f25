// The ros2 transport's services: simulation_interfaces' and simgate/call, each request mapped
// onto `simulation` calls and their outcomes onto the standard's results. Here: the services
// made (add_simulation_services), the simulation's own (features, state, step, reset) and
// simgate/call; the entities' (list, states, info, bounds, spawn, delete):
// ros2_entity_services.cc. The machinery they use (endpoints, requests, replies):
// ros2_services.cc. Design: ros2_services.h, docs/transports/ros2.md.
#include <algorithm>
#include <cstring>
#include <memory>

#include "ros2_mapping.h"
#include "ros2_service_replies.h"
#include "ros2_services.h"
#include "ros2_srvs.h"

namespace simgate::ros2 {

namespace {

using SimFeaturesRequest = simulation_interfaces_srv_dds__GetSimulatorFeatures_Request_;
using SimFeaturesResponse = simulation_interfaces_srv_dds__GetSimulatorFeatures_Response_;
using GetStateRequest = simulation_interfaces_srv_dds__GetSimulationState_Request_;
using GetStateResponse = simulation_interfaces_srv_dds__GetSimulationState_Response_;
using SetStateRequest = simulation_interfaces_srv_dds__SetSimulationState_Request_;
using SetStateResponse = simulation_interfaces_srv_dds__SetSimulationState_Response_;
using StepRequest = simulation_interfaces_srv_dds__StepSimulation_Request_;
using StepResponse = simulation_interfaces_srv_dds__StepSimulation_Response_;
using ResetRequest = simulation_interfaces_srv_dds__ResetSimulation_Request_;
using ResetResponse = simulation_interfaces_srv_dds__ResetSimulation_Response_;
using CallRequest = simgate_interfaces_srv_dds__Call_Request_;
using CallResponse = simgate_interfaces_srv_dds__Call_Response_;

}  // namespace

void Ros2Services::add_simulation_services() {
  add("get_simulator_features", simulation_interfaces_srv_dds__GetSimulatorFeatures_Request__desc,
      simulation_interfaces_srv_dds__GetSimulatorFeatures_Response__desc,
      &Ros2Services::get_simulator_features);
  add("get_simulation_state", simulation_interfaces_srv_dds__GetSimulationState_Request__desc,
      simulation_interfaces_srv_dds__GetSimulationState_Response__desc,
      &Ros2Services::get_simulation_state);
  add("set_simulation_state", simulation_interfaces_srv_dds__SetSimulationState_Request__desc,
      simulation_interfaces_srv_dds__SetSimulationState_Response__desc,
      &Ros2Services::set_simulation_state);
  add("step_simulation", simulation_interfaces_srv_dds__StepSimulation_Request__desc,
      simulation_interfaces_srv_dds__StepSimulation_Response__desc, &Ros2Services::step_simulation);
  add("reset_simulation", simulation_interfaces_srv_dds__ResetSimulation_Request__desc,
      simulation_interfaces_srv_dds__ResetSimulation_Response__desc,
      &Ros2Services::reset_simulation);
  add("get_entities", simulation_interfaces_srv_dds__GetEntities_Request__desc,
      simulation_interfaces_srv_dds__GetEntities_Response__desc, &Ros2Services::get_entities);
  add("get_entities_states", simulation_interfaces_srv_dds__GetEntitiesStates_Request__desc,
      simulation_interfaces_srv_dds__GetEntitiesStates_Response__desc,
      &Ros2Services::get_entities_states);
  add("get_entity_state", simulation_interfaces_srv_dds__GetEntityState_Request__desc,
      simulation_interfaces_srv_dds__GetEntityState_Response__desc,
      &Ros2Services::get_entity_state);
  add("set_entity_state", simulation_interfaces_srv_dds__SetEntityState_Request__desc,
      simulation_interfaces_srv_dds__SetEntityState_Response__desc,
      &Ros2Services::set_entity_state);
  add("get_entity_info", simulation_interfaces_srv_dds__GetEntityInfo_Request__desc,
      simulation_interfaces_srv_dds__GetEntityInfo_Response__desc, &Ros2Services::get_entity_info);
  add("get_entity_bounds", simulation_interfaces_srv_dds__GetEntityBounds_Request__desc,
      simulation_interfaces_srv_dds__GetEntityBounds_Response__desc,
      &Ros2Services::get_entity_bounds);
  add("spawn_entity", simulation_interfaces_srv_dds__SpawnEntity_Request__desc,
      simulation_interfaces_srv_dds__SpawnEntity_Response__desc, &Ros2Services::spawn_entity);
  add("delete_entity", simulation_interfaces_srv_dds__DeleteEntity_Request__desc,
      simulation_interfaces_srv_dds__DeleteEntity_Response__desc, &Ros2Services::delete_entity);
  add("simgate/call", simgate_interfaces_srv_dds__Call_Request__desc,
      simgate_interfaces_srv_dds__Call_Response__desc, &Ros2Services::call);
}

void Ros2Services::get_simulator_features(const void*, const ReplyTo& to) {
  caller_(Call{"simulation", "get_capabilities", json::object()}, [this, to](Outcome&& outcome) {
    SimFeaturesResponse* response;
    Sample reply = new_reply(to, response);
    const std::vector<std::uint16_t> features = offered_features(settings_.may_call);
    std::vector<std::string> formats;
    std::string info = "simgate's ros2 transport (docs/transports/ros2.md)";
    if (outcome.status == Status::success && outcome.value) {
      for (const json& format : outcome.value->value("spawn_formats", json::array()))
        if (format.is_string()) formats.push_back(format.get<std::string>());
    } else {
      info += ": simulation get_capabilities: " + outcome.message;
    }
    std::uint16_t* out = alloc_sequence(response->features.features, features.size());
    std::copy(features.begin(), features.end(), out);
    set_strings(response->features.spawn_formats, formats);
    response->features.custom_info = dup(info);
    send(to, std::move(reply));
  });
}

void Ros2Services::get_simulation_state(const void*, const ReplyTo& to) {
  caller_(Call{"simulation", "get_simulation_state", json::object()},
          [this, to](Outcome&& outcome) {
            GetStateResponse* response;
            Sample reply = new_reply(to, response);
            ServiceResult result = result_of(outcome);
            if (result.is_ok()) {
              const json& value = outcome.value ? *outcome.value : json();
              const auto state = sim_state_of(value.is_object() ? value.value("state", "") : "");
              if (state)
                response->state.state = static_cast<std::uint8_t>(*state);
              else
                result = ServiceResult::fail(ResultCode::operation_failed,
                                             "get_simulation_state said " + value.dump());
            }
            set_result(response->result, result);
            send(to, std::move(reply));
          });
}

void Ros2Services::set_simulation_state(const void* request, const ReplyTo& to) {
  const auto target =
      static_cast<SimState>(static_cast<const SetStateRequest*>(request)->state.state);
  auto reply_with = [this, to](ServiceResult result) {
    SetStateResponse* response;
    Sample reply = new_reply(to, response);
    set_result(response->result, result);
    send(to, std::move(reply));
  };
  switch (target) {
    case SimState::quitting:
      call_for_result<SetStateResponse>(to, Call{"simulation", "quit", json::object()});
      return;
    case SimState::playing:
    case SimState::paused:
    case SimState::stopped: break;
    default:
      reply_with(ServiceResult::fail(
          k_incorrect_transition,
          "state " + std::to_string(static_cast<int>(target)) +
              ": simgate has one world, always loaded: expected STATE_STOPPED (0), "
              "STATE_PLAYING (1), STATE_PAUSED (2) or STATE_QUITTING (3)"));
      return;
  }
  caller_(Call{"simulation", "get_simulation_state", json::object()}, [this, to, target,
                                                                       reply_with](
                                                                          Outcome&& outcome) {
    if (outcome.status != Status::success || !outcome.value) {
      reply_with(result_of(outcome));
      return;
    }
    const auto now = sim_state_of(outcome.value->value("state", ""));
    if (target == SimState::stopped) {
      // stopped = paused and reset (the standard's definition)
      auto reset = [this, to, reply_with] {
        call_for_result<SetStateResponse>(to, Call{"simulation", "reset", json{{"scope", "all"}}});
      };
      if (now == SimState::paused) {
        reset();
        return;
      }
      caller_(Call{"simulation", "pause", json::object()}, [reset, reply_with](Outcome&& paused) {
        if (paused.status != Status::success)
          reply_with(result_of(paused));
        else
          reset();
      });
      return;
    }
    if (now == target) {
      reply_with(
          ServiceResult::fail(k_already_in_target_state, target == SimState::playing
                                                             ? "the simulation is playing already"
                                                             : "the simulation is paused already"));
      return;
    }
    call_for_result<SetStateResponse>(
        to, Call{"simulation", target == SimState::playing ? "play" : "pause", json::object()});
  });
}

void Ros2Services::step_simulation(const void* request, const ReplyTo& to) {
  const std::uint64_t steps = static_cast<const StepRequest*>(request)->steps;
  if (steps == 0) {
    StepResponse* response;
    Sample reply = new_reply(to, response);
    set_result(response->result,
               ServiceResult::fail(ResultCode::operation_failed, "steps = 0: expected at least 1"));
    send(to, std::move(reply));
    return;
  }
  // simgate refuses more than it can take in one call, saying so
  const json n = steps > static_cast<std::uint64_t>(INT64_MAX) ? json(INT64_MAX) : json(steps);
  call_for_result<StepResponse>(to, Call{"simulation", "step", json{{"n", n}}});
}

void Ros2Services::reset_simulation(const void* request, const ReplyTo& to) {
  std::string why;
  const std::optional<std::string> scope =
      reset_scope_of(static_cast<const ResetRequest*>(request)->scope, why);
  if (!scope) {
    ResetResponse* response;
    Sample reply = new_reply(to, response);
    set_result(response->result, ServiceResult::fail(ResultCode::feature_unsupported, why));
    send(to, std::move(reply));
    return;
  }
  call_for_result<ResetResponse>(to, Call{"simulation", "reset", json{{"scope", *scope}}});
}

void Ros2Services::call(const void* request, const ReplyTo& to) {
  const auto& rq = *static_cast<const CallRequest*>(request);
  auto reply_with = [this, to](const Outcome& outcome) {
    CallResponse* response;
    Sample reply = new_reply(to, response);
    response->status = dup(std::string(to_string(outcome.status)));
    std::string message = outcome.message;
    if (outcome.status != Status::success && message.empty() && outcome.value &&
        outcome.value->is_string())
      message = outcome.value->get<std::string>();
    response->message = dup(message);
    response->result = dup(outcome.status == Status::success && outcome.value
                               ? outcome.value->dump(-1, ' ', false, json::error_handler_t::replace)
                               : std::string("null"));
    send(to, std::move(reply));
  };
  const std::string arguments = text(rq.arguments);
  Call call{text(rq.component), text(rq.service), json()};
  if (arguments.size() > settings_.max_argument_bytes) {
    reply_with(Outcome::failed(Failure::bad_arguments,
                               "arguments: " + std::to_string(arguments.size()) +
                                   " bytes, more than the " +
                                   std::to_string(settings_.max_argument_bytes) + " accepted"));
    return;
  }
  if (!arguments.empty()) {
    call.params = json::parse(arguments, nullptr, false);
    if (call.params.is_discarded() ||
        !(call.params.is_array() || call.params.is_object() || call.params.is_null())) {
      reply_with(Outcome::failed(Failure::bad_arguments,
                                 "arguments: expected a JSON object of named arguments or an "
                                 "array of positional ones (or nothing), found '" +
                                     arguments.substr(0, 200) + "'"));
      return;
    }
  }
  call.timeout = std::chrono::milliseconds(rq.timeout_ms);
  caller_(std::move(call), [reply_with](Outcome&& outcome) { reply_with(outcome); });
}

}  // namespace simgate::ros2
