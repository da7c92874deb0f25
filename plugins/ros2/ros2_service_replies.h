// ros2_service_replies.h — what the handlers of the ros2 transport's services share to fill
// their replies (private to plugins/ros2: ros2_sim_services.cc, ros2_entity_services.cc):
// strings into and out of the messages, a Result, and a reply whose Result is one
// `simulation` call's outcome (Ros2Services::call_for_result).
#ifndef SIMGATE_PLUGINS_ROS2_ROS2_SERVICE_REPLIES_H_
#define SIMGATE_PLUGINS_ROS2_ROS2_SERVICE_REPLIES_H_

#include <string>
#include <utility>
#include <vector>

#include "ros2_services.h"
#include "ros2_srvs.h"

namespace simgate::ros2 {

inline char* dup(const std::string& text) { return dds_string_dup(text.c_str()); }
inline std::string text(const char* s) { return s ? std::string(s) : std::string(); }

inline void set_strings(dds_sequence_string& seq, const std::vector<std::string>& values) {
  char** out = alloc_sequence(seq, values.size());
  for (std::size_t i = 0; i < values.size(); ++i) out[i] = dup(values[i]);
}

inline void set_result(simulation_interfaces_msg_dds__Result_& out, const ServiceResult& result) {
  out.result = result.code;
  out.error_message = dup(result.message);
}

template <class Response>
void Ros2Services::call_for_result(const ReplyTo& to, Call call, std::string entity_parameter) {
  caller_(std::move(call), [this, to, entity_parameter](Outcome&& outcome) {
    Response* response;
    Sample reply = new_reply(to, response);
    set_result(response->result, result_of(outcome, entity_parameter));
    send(to, std::move(reply));
  });
}

}  // namespace simgate::ros2

#endif  // SIMGATE_PLUGINS_ROS2_ROS2_SERVICE_REPLIES_H_
