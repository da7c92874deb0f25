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
#include <vector>

#include "simgate/core/status.h"

namespace simgate {

// Thrown by a service to fail its request with a message (the FAILED payload).
class ServiceError : public std::runtime_error {
 public:
  explicit ServiceError(const std::string& message, Failure failure = Failure::service_error,
                        json data = json::object())
      : std::runtime_error(message), message_(message), failure_(failure), data_(std::move(data)) {}
  // The whole message: what() is a C string, cut at the first NUL of a client's text quoted in it.
  const std::string& message() const noexcept { return message_; }
  Failure failure() const noexcept { return failure_; }
  const json& data() const noexcept { return data_; }

 private:
  std::string message_;  // as given
  Failure failure_;      // how transports classify it
  json data_;            // structured detail (component, service, parameter...)
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

// A configuration (deployment file or transport options) is invalid. Each message starts
// with the JSON path of the offending value; one ConfigError may carry several (a whole
// file's errors, `simgate check`) and the file they are in. what() reads
// "config 'demo.json': <message>", or "config 'demo.json': 3 errors:" and one per line.
class ConfigError : public std::runtime_error {
 public:
  explicit ConfigError(const std::string& message)
      : ConfigError(std::vector<std::string>{message}) {}
  explicit ConfigError(std::vector<std::string> errors, std::string file = "")
      : std::runtime_error(describe(errors, file)),
        errors_(std::move(errors)),
        file_(std::move(file)) {}
  // Every error, in the order found, without the file.
  const std::vector<std::string>& errors() const noexcept { return errors_; }
  // The file they were found in ("" when unknown).
  const std::string& file() const noexcept { return file_; }

 private:
  static std::string describe(const std::vector<std::string>& errors, const std::string& file) {
    std::string out = file.empty() ? "" : "config '" + file + "': ";
    if (errors.size() == 1) return out + errors.front();
    out += std::to_string(errors.size()) + " errors:";
    for (const auto& e : errors) out += "\n  " + e;
    return out;
  }
  std::vector<std::string> errors_;  // one message each
  std::string file_;                 // where they were found
};

// A configuration text that is not a document simgate reads (not JSON, a number beyond a
// double, nested too deeply, a NUL byte: parse_config_text), at a line and column (from 1,
// the column in bytes). errors() and what() read "<message> (line L, column C)"; a loader
// that knows the file reports located(file) instead, as compilers locate their errors.
class ConfigTextError : public ConfigError {
 public:
  ConfigTextError(std::string message, std::size_t line, std::size_t column)
      : ConfigError(message + " (line " + std::to_string(line) + ", column " +
                    std::to_string(column) + ")"),
        message_(std::move(message)),
        line_(line),
        column_(column) {}
  // The message without its position: "scene: invalid JSON: expected ..., found ...".
  const std::string& message() const noexcept { return message_; }
  std::size_t line() const noexcept { return line_; }
  std::size_t column() const noexcept { return column_; }
  // "FILE:LINE:COLUMN: <message>", where editors jump from.
  std::string located(const std::string& file) const {
    return file + ":" + std::to_string(line_) + ":" + std::to_string(column_) + ": " + message_;
  }

 private:
  std::string message_;  // what is wrong, starting with the JSON path
  std::size_t line_;     // where, from 1
  std::size_t column_;   // from 1, in bytes
};

// Collects the ConfigErrors of independent checks so that all of a file's errors are
// reported at once: errors.check([&] { ...may throw ConfigError... }); errors.throw_if_any().
class ConfigErrors {
 public:
  // Runs `check`; a ConfigError it throws is recorded (every message of it). Returns
  // whether it succeeded.
  template <class F>
  bool check(F&& check) {
    try {
      check();
      return true;
    } catch (const ConfigError& e) {
      errors_.insert(errors_.end(), e.errors().begin(), e.errors().end());
      return false;
    }
  }
  void add(std::string message) { errors_.push_back(std::move(message)); }
  bool empty() const { return errors_.empty(); }
  const std::vector<std::string>& errors() const { return errors_; }
  // Throws one ConfigError carrying every recorded message, if any.
  void throw_if_any() const {
    if (!errors_.empty()) throw ConfigError(errors_);
  }

 private:
  std::vector<std::string> errors_;  // in the order found
};

}  // namespace simgate

#endif  // SIMGATE_CORE_ERRORS_H_
