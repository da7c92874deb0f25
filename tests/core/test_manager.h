// A request manager with no I/O, for unit tests: submit() from the test, completions
// collected in order.
#ifndef SIMGATE_TESTS_CORE_TEST_MANAGER_H_
#define SIMGATE_TESTS_CORE_TEST_MANAGER_H_

#include <mutex>
#include <utility>
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

 protected:
  void on_service_completion(RequestId id, Outcome&& outcome) override {
    std::lock_guard lock(mutex_);
    completions_.emplace_back(id, std::move(outcome));
  }

 private:
  std::mutex mutex_;
  std::vector<std::pair<RequestId, Outcome>> completions_;
};

}  // namespace simgate::testing

#endif  // SIMGATE_TESTS_CORE_TEST_MANAGER_H_
