// What the fuzz targets share: a failed-property abort that says which, a strict JSON
// comparison, and ServiceHost, a request manager with no I/O serving services of many
// signatures (free functions, sync and async, a component with policies) so that fuzzed
// parameters go through the core's real argument binding.
#ifndef SIMGATE_TESTS_FUZZ_FUZZ_SUPPORT_H_
#define SIMGATE_TESTS_FUZZ_FUZZ_SUPPORT_H_

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "simgate/core/component.h"
#include "simgate/core/config.h"
#include "simgate/core/errors.h"
#include "simgate/core/log.h"
#include "simgate/core/request_manager.h"

// A property of the code under test does not hold: a finding, like a crash.
#define FUZZ_CHECK(cond, what)                                                                \
  do {                                                                                        \
    if (!(cond)) {                                                                            \
      std::fprintf(stderr, "fuzz property failed at %s:%d: %s\n  (%s)\n", __FILE__, __LINE__, \
                   std::string(what).c_str(), #cond);                                         \
      std::abort();                                                                           \
    }                                                                                         \
  } while (0)

namespace simgate::fuzz {

// The targets print nothing: a log line per input would drown libFuzzer's own.
inline void quiet_logs() { log::set_level(log::Level::off); }

// Serialises as the transports do (invalid UTF-8 replaced: never throws).
inline std::string dump(const json& value) {
  return value.dump(-1, ' ', false, json::error_handler_t::replace);
}

// Same value and, recursively, the same JSON types (json's == equates 1u, 1 and 1.0 and
// never NaN with NaN).
inline bool identical(const json& a, const json& b) {
  if (a.type() != b.type()) return false;
  if (a.is_array()) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i)
      if (!identical(a[i], b[i])) return false;
    return true;
  }
  if (a.is_object()) {
    if (a.size() != b.size()) return false;
    for (auto it = a.begin(), jt = b.begin(); it != a.end(); ++it, ++jt)
      if (it.key() != jt.key() || !identical(it.value(), jt.value())) return false;
    return true;
  }
  if (a.is_number_float()) {
    const double x = a.get<double>(), y = b.get<double>();
    if (std::isnan(x) || std::isnan(y)) return std::isnan(x) && std::isnan(y);
    return x == y && std::signbit(x) == std::signbit(y);
  }
  return a == b;
}

// Bracket depth of a parsed value (a scalar is 0, [] is 1). Recursive: call it only on
// values whose text passed json_nests_deeper_than.
inline std::size_t depth_of(const json& value) {
  std::size_t deepest = 0;
  if (value.is_array() || value.is_object()) {
    for (const auto& element : value) deepest = std::max(deepest, depth_of(element));
    return deepest + 1;
  }
  return 0;
}

// The checks every outcome must pass, then its text as each transport writes it.
inline void check_outcome(const Outcome& o) {
  if (o.status == Status::success) {
    FUZZ_CHECK(o.failure == Failure::none, "a success carries no failure");
  } else {
    FUZZ_CHECK(o.failure != Failure::none, "a failed or preempted outcome says why");
    // a service's own message may be empty: ServiceError's is what() (a C string), cut at
    // a NUL the client's text put there (docs/fuzzing.md, findings)
    FUZZ_CHECK(!o.message.empty() || o.failure == Failure::service_error,
               "a failed or preempted outcome has a message");
  }
  if (o.value) (void)dump(*o.value), (void)json_preview(*o.value), (void)describe_json(*o.value);
  (void)dump(o.data);
  (void)dump(json(o.message));
}

class Mover;

// A request manager with no I/O and a table of services of different signatures (free
// functions of numbers of every width, strings, optionals, arrays, maps, nested vectors,
// Eigen vectors, any JSON, defaults; sync, async, concurrent; a component, Mover, with
// async services under each policy, one completing FAILED with the client's value).
// Requests run under the simulation lock as the transports run them; tick() is one
// simulation step. Checks every outcome (check_outcome) and that every async request ends
// exactly once. Defined in fuzz_support.cc (compiled once: the registrations are heavy).
//
// Building one costs about a millisecond under ASan, more than most inputs: a target keeps
// one for the whole run (ServiceHost::instance()) and calls end_input() after each input,
// which ends what is still running and puts the host back in its initial state.
class ServiceHost : public RequestManager {
 public:
  ServiceHost();
  ~ServiceHost() override;

  // The host a target uses, built on first use, never destroyed.
  static ServiceHost& instance();
  // Cancels every async request still running, finishes the kept jobs, checks that each
  // request ended exactly once, and resets the policy and the component.
  void end_input();

  // Runs one request under the simulation lock, as a transport thread does; the outcome
  // of a sync request, nullopt for an async one (it ends in a later tick or cancel).
  std::optional<Outcome> call(const std::string& component, const std::string& service,
                              const json& params);
  // One simulation step: the components' default_action, the kept jobs finish, and the
  // completions are delivered.
  void tick();
  // Cancels the n-th async request started (modulo their number), then processes.
  void cancel_started(std::size_t n);

 protected:
  void on_service_completion(RequestId id, Outcome&& outcome) override;

 private:
  struct Job {
    Completion done;
    json result;
  };
  std::unique_ptr<Mover> mover_;  // served until abandon_pending() in ~ServiceHost
  std::mutex mutex_;
  std::map<RequestId, int> async_;  // async requests started -> completions received
  std::vector<RequestId> started_;  // in order
  std::vector<Job> jobs_;           // free async functions waiting for tick()
};

}  // namespace simgate::fuzz

#endif  // SIMGATE_TESTS_FUZZ_FUZZ_SUPPORT_H_
