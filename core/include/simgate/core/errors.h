// simgate/core/errors.h — exceptions a service (or the core) throws; each becomes FAILED.
//
// MORSE: MorseRPCInvokationError -> ServiceError, MorseServiceAlreadyRunningError ->
// ServiceAlreadyRunning, MorseMethodNotFoundError -> UnknownService,
// MorseRPCNbArgsError/MorseRPCTypeError -> WrongArguments. These never cross a plugin
// boundary: the request manager turns them into an Outcome.
#ifndef SIMGATE_CORE_ERRORS_H_
#define SIMGATE_CORE_ERRORS_H_

#include <stdexcept>
#include <string>

#include "simgate/core/status.h"

namespace simgate {

// Thrown by a service to fail its request with a message (the FAILED payload).
class ServiceError : public std::runtime_error {
 public:
  explicit ServiceError(const std::string& message, Failure failure = Failure::service_error,
                        json data = json::object())
      : std::runtime_error(message), failure_(failure), data_(std::move(data)) {}
  Failure failure() const noexcept { return failure_; }
  const json& data() const noexcept { return data_; }

 private:
  Failure failure_;  // how transports classify it
  json data_;        // structured detail (component, service, parameter...)
};

// The component or service is not registered with the request manager.
class UnknownService : public ServiceError {
 public:
  UnknownService(const std::string& message, json data)
      : ServiceError(message, Failure::unknown_service, std::move(data)) {}
};

// Wrong number or wrong type of parameters. Arity messages contain "wrong # of
// parameters" (pymorse maps that phrase to TypeError).
class WrongArguments : public ServiceError {
 public:
  WrongArguments(const std::string& message, json data)
      : ServiceError(message, Failure::bad_arguments, std::move(data)) {}
};

// A new async request was refused because another is running on the component.
// running_service is "component.service" of the request that keeps running.
class ServiceAlreadyRunning : public ServiceError {
 public:
  ServiceAlreadyRunning(const std::string& message, std::string running_service)
      : ServiceError(message, Failure::busy, json{{"running", running_service}}),
        running_service(std::move(running_service)) {}
  std::string running_service;  // the service that keeps running
};

// A configuration (deployment file or transport options) is invalid. The message starts
// with the JSON path of the offending value.
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace simgate

#endif  // SIMGATE_CORE_ERRORS_H_
