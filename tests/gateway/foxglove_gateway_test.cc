// The foxglove transport in a gateway: it stops whatever its time messages are doing (a bug
// fixed: a tick already due when the transport stopped armed its timer again, and the I/O
// thread never ended, so `simulation quit` hung).
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <future>
#include <memory>
#include <thread>

#include "in_process_gateway.h"
#include "test_support.h"

namespace simgate::gateway {
namespace {

using namespace std::chrono_literals;

TEST(FoxgloveGatewayTest, ItStopsWhileItsTimeTicks) {
  json config = testing::demo_config();
  config["transports"]["foxglove"]["options"]["time_hz"] = 1000;  // a tick every millisecond
  for (int round = 0; round < 100; ++round) {
    auto g = std::make_unique<testing::InProcessGateway>(config);
    std::this_thread::sleep_for(std::chrono::milliseconds(round % 7));
    auto stopped = std::async(std::launch::async, [&g] { g.reset(); });
    if (stopped.wait_for(30s) != std::future_status::ready) {
      ADD_FAILURE() << "round " << round << ": the gateway did not stop within 30 s";
      std::_Exit(1);  // its threads still wait: nothing more can be checked
    }
  }
}

}  // namespace
}  // namespace simgate::gateway
