// A request manager with no I/O, for unit tests: submit() from the test, completions
// collected in order.
#ifndef SIMGATE_TESTS_CORE_TEST_MANAGER_H_
#define SIMGATE_TESTS_CORE_TEST_MANAGER_H_

#include <mutex>
#include <string>
#include <utility>
#include <tuple>
#include <vector>

#include "simgate/core/request_manager.h"

namespace simgate::testing {

class TestManager : public RequestManager {
 public:
  TestManager() : RequestManager("Test service manager") {}

  // Submits and returns the id.
  RequestId call(std::string component, std::string service, json params = nullptr) {
    RequestId id = new_request_id();
    submit(id, Call{std::move(component), std::move(service), std::move(params)});
    return id;
  }
  // Submits a call whose client asked for progress reports (Call::progress).
  RequestId call_with_progress(std::string component, std::string service, json params = nullptr) {
    RequestId id = new_request_id();
    Call c{std::move(component), std::move(service), std::move(params)};
    c.progress = true;
    submit(id, std::move(c));
    return id;
  }
  // Submits, processes once, returns the outcome if it finished.
  std::optional<Outcome> run(std::string component, std::string service, json params = nullptr) {
    RequestId id = call(std::move(component), std::move(service), std::move(params));
    process();
    return outcome(id);
  }
  std::optional<Outcome> outcome(RequestId id) {
    std::lock_guard lock(mutex_);
    for (auto& [i, o] : completions_)
      if (i == id) return o;
    return std::nullopt;
  }
  std::size_t completion_count(RequestId id) {
    std::lock_guard lock(mutex_);
    std::size_t n = 0;
    for (auto& c : completions_) n += c.first == id;
    return n;
  }
  std::vector<std::pair<RequestId, Outcome>> completions() {
    std::lock_guard lock(mutex_);
    return completions_;
  }
  // What reached the transport, in order: progress reports ("progress", value) and final
  // outcomes ("outcome", status) of request `id`.
  std::vector<std::pair<std::string, json>> events(RequestId id) {
    std::lock_guard lock(mutex_);
    std::vector<std::pair<std::string, json>> out;
    for (auto& [i, kind, value] : events_)
      if (i == id) out.emplace_back(kind, value);
    return out;
  }

 protected:
  void on_service_completion(RequestId id, Outcome&& outcome) override {
    std::lock_guard lock(mutex_);
    events_.emplace_back(id, "outcome", std::string(to_string(outcome.status)));
    completions_.emplace_back(id, std::move(outcome));
  }
  void on_service_progress(RequestId id, json&& value) override {
    std::lock_guard lock(mutex_);
    events_.emplace_back(id, "progress", std::move(value));
  }

 private:
  std::mutex mutex_;
  std::vector<std::pair<RequestId, Outcome>> completions_;
  std::vector<std::tuple<RequestId, std::string, json>> events_;  // progress and outcomes, in order
};

}  // namespace simgate::testing

#endif  // SIMGATE_TESTS_CORE_TEST_MANAGER_H_
