// The foxglove transport in a gateway: it stops whatever its time messages are doing (a bug
// fixed: a tick already due when the transport stopped armed its timer again, and the I/O
// thread never ended, so `simulation quit` hung); with "auth", a client presents the token in
// its upgrade request (Foxglove's protocol has no login), or is refused with 401.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <future>
#include <memory>
#include <string>
#include <thread>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/read_until.hpp>
#include <boost/asio/streambuf.hpp>
#include <boost/asio/write.hpp>

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

// The status line of the answer to a Foxglove upgrade of `target` with `headers`.
std::string upgrade_status(int port, const std::string& target, const std::string& headers = "") {
  namespace asio = boost::asio;
  asio::io_context io;
  asio::ip::tcp::socket socket(io);
  socket.connect({asio::ip::make_address("127.0.0.1"), static_cast<unsigned short>(port)});
  asio::write(socket, asio::buffer("GET " + target +
                                   " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: Upgrade\r\n"
                                   "Upgrade: websocket\r\nSec-WebSocket-Version: 13\r\n"
                                   "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                                   "Sec-WebSocket-Protocol: foxglove.websocket.v1\r\n" +
                                   headers + "\r\n"));
  asio::streambuf in;
  boost::system::error_code ec;
  asio::read_until(socket, in, "\r\n", ec);
  std::string line(asio::buffers_begin(in.data()), asio::buffers_end(in.data()));
  return line.substr(0, line.find("\r\n"));
}

TEST(FoxgloveGatewayTest, WithAuthTheUpgradeCarriesTheToken) {
  constexpr const char* k_token = "0d9c8b7a6f5e4d3c2b1a0f9e8d7c6b5a";
  ::setenv("SIMGATE_FOXGLOVE_TEST_TOKEN", k_token, 1);
  json config = testing::demo_config();
  config["transports"]["foxglove"]["options"]["auth"] = {
      {"token_env", "SIMGATE_FOXGLOVE_TEST_TOKEN"}, {"loopback", true}};
  testing::InProcessGateway g(config);
  const int port = g.port("foxglove");
  EXPECT_EQ(upgrade_status(port, "/"), "HTTP/1.1 401 Unauthorized");
  EXPECT_EQ(upgrade_status(port, "/?token=wrong0123456789abcdef"), "HTTP/1.1 401 Unauthorized");
  EXPECT_EQ(upgrade_status(port, "/", "Authorization: Bearer nope\r\n"),
            "HTTP/1.1 401 Unauthorized");
  EXPECT_EQ(upgrade_status(port, std::string("/?x=1&token=") + k_token),
            "HTTP/1.1 101 Switching Protocols");
  EXPECT_EQ(upgrade_status(port, "/", std::string("Authorization: Bearer ") + k_token + "\r\n"),
            "HTTP/1.1 101 Switching Protocols");
  // percent-encoded, as a URL field may send it
  EXPECT_EQ(upgrade_status(port, "/?token=%30d9c8b7a6f5e4d3c2b1a0f9e8d7c6b5a"),
            "HTTP/1.1 101 Switching Protocols");
}

}  // namespace
}  // namespace simgate::gateway
