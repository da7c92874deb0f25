#include "simgate/core/status.h"

namespace simgate {

std::string_view to_string(Status status) noexcept {
  switch (status) {
    case Status::success: return "SUCCESS";
    case Status::failed: return "FAILED";
    case Status::preempted: return "PREEMPTED";
  }
  return "FAILED";
}

std::string_view to_string(Failure failure) noexcept {
  switch (failure) {
    case Failure::none: return "none";
    case Failure::unknown_service: return "unknown_service";
    case Failure::bad_arguments: return "bad_arguments";
    case Failure::busy: return "busy";
    case Failure::service_error: return "service_error";
    case Failure::internal: return "internal";
    case Failure::preempted: return "preempted";
    case Failure::cancelled: return "cancelled";
    case Failure::shutdown: return "shutdown";
    case Failure::timeout: return "timeout";
  }
  return "internal";
}

Outcome Outcome::success(std::optional<json> value) {
  Outcome o;
  if (value && !value->is_null()) o.value = std::move(value);
  return o;
}

Outcome Outcome::failed(Failure failure, std::string message, json data) {
  Outcome o;
  o.status = failure == Failure::preempted || failure == Failure::cancelled ? Status::preempted
                                                                            : Status::failed;
  o.failure = failure;
  if (o.status == Status::failed) o.value = message;
  o.message = std::move(message);
  o.data = std::move(data);
  return o;
}

}  // namespace simgate
