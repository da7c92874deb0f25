// InProcessGateway: a gateway started from a config in the test's own process, running on a
// thread of its own (Gateway::run), on the ports the config gives (0: ephemeral). The
// fixtures of the gateway tests that talk to it over real sockets share it.
#ifndef SIMGATE_TESTS_GATEWAY_IN_PROCESS_GATEWAY_H_
#define SIMGATE_TESTS_GATEWAY_IN_PROCESS_GATEWAY_H_

#include <memory>
#include <string>
#include <thread>

#include "simgate/gateway/gateway.h"
#include "simgate/sim/registry.h"
#include "test_support.h"

namespace simgate::gateway::testing {

class InProcessGateway {
 public:
  // Parses `config` (relative paths from the source tree's config/), starts the gateway and
  // its loop. Throws what parse_deployment and Gateway::start throw.
  explicit InProcessGateway(const json& config, GatewayOptions options = {}) {
    const Deployment deployment = parse_deployment(config, SIMGATE_SOURCE_DIR "/config");
    gateway_ = std::make_unique<Gateway>(deployment, registry_, std::move(options));
    gateway_->start();
    thread_ = std::thread([this] { gateway_->run(); });
  }
  ~InProcessGateway() {
    gateway_->stop();
    if (thread_.joinable()) thread_.join();
  }
  InProcessGateway(const InProcessGateway&) = delete;
  InProcessGateway& operator=(const InProcessGateway&) = delete;

  // The port of `transport`'s first endpoint.
  int port(const std::string& transport = "socket") const {
    return port_of(gateway_->endpoints().at(transport).at(0));
  }
  Gateway& gateway() { return *gateway_; }
  // Waits for the loop to end by itself (a client's `simulation quit`).
  void join() { thread_.join(); }

 private:
  sim::ComponentRegistry registry_ = sim::builtin_registry();  // outlives the gateway
  std::unique_ptr<Gateway> gateway_;
  std::thread thread_;  // runs Gateway::run()
};

}  // namespace simgate::gateway::testing

#endif  // SIMGATE_TESTS_GATEWAY_IN_PROCESS_GATEWAY_H_
