// simgate/core/status.h — the outcome of a service call.
//
// Every request ends with exactly one Outcome: a Status (MORSE's SUCCESS / FAILED /
// PREEMPTED), an optional JSON value (the result, or the error detail) and, for failures, a
// Failure kind that lets transports with richer error models (JSON-RPC codes, DDS status
// enum) say *why* without parsing messages. The MORSE text transport shows only the
// status and the value.
#ifndef SIMGATE_CORE_STATUS_H_
#define SIMGATE_CORE_STATUS_H_

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

namespace simgate {

using json = nlohmann::json;

struct StreamPayload;  // streams.h: raw bytes with a description (an image's pixels)

// Identifies one request inside one request manager; allocated by
// RequestManager::new_request_id() (a process-wide counter from 1) or by a transport's
// kit::RequestSlots (bit 63 set, request_slots.h); unique within its manager while the request
// lives, never shown to clients.
using RequestId = std::uint64_t;

// MORSE's status values (morse.core.status).
enum class Status : std::uint8_t { success, failed, preempted };

// Wire spelling MORSE uses: "SUCCESS", "FAILED", "PREEMPTED".
std::string_view to_string(Status status) noexcept;

// Why a request did not succeed; Failure::none for successes.
enum class Failure : std::uint8_t {
  none,
  unknown_service,  // component or service not registered with this manager
  bad_arguments,    // arity or type of the parameters (or unparsable parameters)
  busy,             // an async service is running and the policy refused the new one
  service_error,    // the service threw ServiceError or completed with FAILED
  internal,         // the service threw something else; the server lives on
  preempted,        // ended by a newer request on the same component
  cancelled,        // ended by its client's cancel
  shutdown,         // the request manager stopped before the request finished
  timeout,  // no reply within its deadline (Call::timeout or the manager's max wait): FAILED
};

std::string_view to_string(Failure failure) noexcept;

// The single final answer to a request.
struct Outcome {
  Status status = Status::success;
  // SUCCESS: the service's return value, or empty when it returns nothing (void).
  // FAILED: the error message as a JSON string, or what the component passed to completed().
  // PREEMPTED: empty unless the component passed a value.
  std::optional<json> value;
  Failure failure = Failure::none;
  // Human-readable reason for failures and preemptions (empty on success).
  std::string message;
  // Structured detail for richer transports: {"component", "service", "parameter", "by", ...};
  // null when there is none (successes: no allocation per reply).
  json data;
  // SUCCESS: raw bytes of what `value` shows encoded (an image's pixels, whose record holds
  // them as a base64 PNG), one per such record, in the order of the records (a capture's
  // list). Optional and additive: `value` is complete without them, and a transport that
  // knows the content may send them typed beside it (DDS: simgate_ReplyImage); every other
  // transport ignores them. Empty for nearly every call (no allocation). For a caller that
  // takes them raw (Call::raw_attachments) a record may leave its encoded copy out ("format":
  // "raw", no "image"); its payload's to_json then makes the full record, should the
  // transport have to send it encoded after all.
  std::vector<std::shared_ptr<const StreamPayload>> attachments;

  static Outcome success(std::optional<json> value);
  static Outcome failed(Failure failure, std::string message, json data = json::object());
};

}  // namespace simgate

#endif  // SIMGATE_CORE_STATUS_H_
