// A minimal out-of-tree transport: at start() it submits the one call named in its options
// and writes the outcome, as JSON, to the file named in its options.
#include <fstream>

#include <simgate/core/config.h>
#include <simgate/core/plugin.h>

class HelloTransport : public simgate::RequestManager {
 public:
  explicit HelloTransport(const simgate::json& options) : RequestManager("Hello service manager") {
    simgate::ConfigObject config(options, "hello");
    call_ = config.get_json("call").value_or(simgate::json::array());
    output_ = config.required_string("output");
    config.finish();
  }
  void start() override {
    submit(new_request_id(), simgate::Call{call_.at(0), call_.at(1), call_.at(2)});
  }

 protected:
  void on_service_completion(simgate::RequestId, simgate::Outcome&& outcome) override {
    std::ofstream(output_) << simgate::json{
        {"status", to_string(outcome.status)},
        {"value", outcome.value.value_or(
                      nullptr)}}.dump();
  }

 private:
  simgate::json call_;  // [component, service, params]
  std::string output_;  // where the outcome goes
};

SIMGATE_TRANSPORT_PLUGIN(hello, HelloTransport, "1.0.0", "call", "output")
