// A transport plugin with no I/O: the test calls client_call() where a real transport would
// read a socket. Proves the core works through a dlopen'd plugin.
#include <map>
#include <mutex>

#include "mock_transport.h"
#include "simgate/core/config.h"
#include "simgate/core/plugin.h"

namespace simgate::testing {

class MockPlugin : public MockTransport {
 public:
  explicit MockPlugin(const json& options)
      : MockTransport("Mock service manager"), options_(options) {
    ConfigObject config(options, "mock");
    greeting_ = config.get_string("greeting", "hello");
    config.finish();
  }
  RequestId client_call(const std::string& component, const std::string& service,
                        const json& params) override {
    RequestId id = new_request_id();
    submit(id, Call{component, service, params});
    return id;
  }
  std::optional<Outcome> client_outcome(RequestId id) override {
    std::lock_guard lock(mutex_);
    auto it = outcomes_.find(id);
    if (it == outcomes_.end()) return std::nullopt;
    return it->second;
  }
  json options() const override { return options_; }
  bool started() const override { return started_; }
  void start() override { started_ = true; }
  std::vector<std::string> endpoints() const override { return {"mock://" + greeting_}; }

 protected:
  void on_service_completion(RequestId id, Outcome&& outcome) override {
    std::lock_guard lock(mutex_);
    outcomes_[id] = std::move(outcome);
  }

 private:
  json options_;                           // as given
  std::string greeting_;                   // an option, to test option checking
  bool started_ = false;                   // start() was called
  std::mutex mutex_;                       // guards outcomes_
  std::map<RequestId, Outcome> outcomes_;  // delivered outcomes
};

}  // namespace simgate::testing

SIMGATE_TRANSPORT_PLUGIN(mock, simgate::testing::MockPlugin, "1.2.3", "greeting")
