// The websocket transport's keep-alive (`keepalive_s`, docs/transports/websocket.md): a client
// silent that long is pinged, one silent twice that long (it answered no ping) is dropped,
// one that answers the pings stays. Raw RFC 6455 on a plain socket, so that the test decides
// whether a ping is answered (Beast's client answers them by itself while it reads). Every
// wait is bounded by the socket's 10 s receive timeout; nothing asserts on durations.
#include <gtest/gtest.h>

#include <sys/socket.h>
#include <sys/time.h>

#include <array>
#include <cstdint>
#include <optional>
#include <string>

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/read.hpp>
#include <boost/asio/write.hpp>

#include "simgate/core/plugin_loader.h"
#include "test_services.h"
#include "ws_test_client.h"

namespace simgate::websocket_test {
namespace {

using boost::asio::ip::tcp;
using jsonrpc_test::TestHost;

// A WebSocket client on a raw socket: the upgrade, then frames read and written one by one.
class RawWsClient {
 public:
  struct Frame {
    std::uint8_t opcode = 0;
    std::string payload;
  };

  explicit RawWsClient(std::uint16_t port) : socket_(io_) {
    socket_.connect({boost::asio::ip::make_address("127.0.0.1"), port});
    timeval tv{10, 0};  // every read below ends within 10 s
    ::setsockopt(socket_.native_handle(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    const std::string upgrade =
        "GET / HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(port) +
        "\r\nConnection: Upgrade\r\nUpgrade: websocket\r\nSec-WebSocket-Version: 13\r\n"
        "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\r\n";
    boost::asio::write(socket_, boost::asio::buffer(upgrade));
    // the 101 response, up to its blank line; what follows it is frames
    while (buffer_.find("\r\n\r\n") == std::string::npos)
      if (!fill()) throw std::runtime_error("no upgrade response: " + buffer_);
    if (!buffer_.starts_with("HTTP/1.1 101"))
      throw std::runtime_error("upgrade refused: " + buffer_);
    buffer_.erase(0, buffer_.find("\r\n\r\n") + 4);
  }

  // The next frame; nullopt when the server closed the connection (or 10 s passed).
  std::optional<Frame> read_frame() {
    while (buffer_.size() < 2)
      if (!fill()) return std::nullopt;
    // the server's frames are unmasked and, here, short (< 126 bytes)
    const std::size_t size = static_cast<std::uint8_t>(buffer_[1]) & 0x7f;
    EXPECT_LT(size, 126u);
    while (buffer_.size() < 2 + size)
      if (!fill()) return std::nullopt;
    Frame frame{static_cast<std::uint8_t>(buffer_[0] & 0x0f), buffer_.substr(2, size)};
    buffer_.erase(0, 2 + size);
    return frame;
  }

  // One masked frame (a client's must be), FIN set.
  void write_frame(std::uint8_t opcode, const std::string& payload) {
    ASSERT_LT(payload.size(), 126u);
    const std::array<std::uint8_t, 4> mask{0x12, 0x34, 0x56, 0x78};
    std::string frame{static_cast<char>(0x80 | opcode), static_cast<char>(0x80 | payload.size())};
    frame.append(mask.begin(), mask.end());
    for (std::size_t i = 0; i < payload.size(); ++i)
      frame += static_cast<char>(payload[i] ^ mask[i % 4]);
    boost::asio::write(socket_, boost::asio::buffer(frame));
  }

 private:
  // Appends what the socket has; false at its end, on an error or after the receive timeout.
  bool fill() {
    char bytes[4096];
    boost::system::error_code ec;
    const std::size_t n = socket_.read_some(boost::asio::buffer(bytes), ec);
    buffer_.append(bytes, n);
    return !ec && n > 0;
  }

  boost::asio::io_context io_;
  tcp::socket socket_;
  std::string buffer_;  // read, not yet taken
};

TEST(WebSocketKeepAlive, ASilentClientIsPingedThenDropped) {
  TestHost host(json{{"keepalive_s", 0.5}}, plugin_path());
  RawWsClient client(host.port());
  // it says nothing: a ping comes, then, unanswered, the end of the connection
  auto ping = client.read_frame();
  ASSERT_TRUE(ping.has_value()) << "no ping within 10 s";
  EXPECT_EQ(ping->opcode, k_ping);
  EXPECT_FALSE(client.read_frame().has_value()) << "the connection outlived an unanswered ping";
}

TEST(WebSocketKeepAlive, AClientThatAnswersThePingsStays) {
  TestHost host(json{{"keepalive_s", 0.5}}, plugin_path());
  RawWsClient client(host.port());
  // three pings answered: silent from messages for longer than twice keepalive_s, yet kept
  for (int pings = 0; pings < 3; ++pings) {
    auto frame = client.read_frame();
    ASSERT_TRUE(frame.has_value())
        << "dropped (or no ping within 10 s) after " << pings << " ping(s)";
    ASSERT_EQ(frame->opcode, k_ping);
    client.write_frame(k_pong, frame->payload);
  }
  client.write_frame(k_text, R"({"jsonrpc":"2.0","id":1,"method":"spec.subtract","params":[3,1]})");
  std::optional<RawWsClient::Frame> reply;
  do reply = client.read_frame();
  while (reply && reply->opcode == k_ping);  // a ping may come first
  ASSERT_TRUE(reply.has_value());
  EXPECT_EQ(json::parse(reply->payload)["result"], 2) << reply->payload;
}

TEST(WebSocketKeepAlive, KeepaliveMustBeANumberOfSecondsFromZeroToADay) {
  for (const json& bad : {json(-1), json("150"), json(86'401), json(true)}) {
    try {
      load_transport(plugin_path(), json{{"port", 0}, {"keepalive_s", bad}});
      ADD_FAILURE() << "accepted keepalive_s " << bad.dump();
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find("keepalive_s"), std::string::npos) << e.what();
    }
  }
  // 0 turns it off; the default is 150 s
  EXPECT_NO_THROW(load_transport(plugin_path(), json{{"port", 0}, {"keepalive_s", 0}}));
}

}  // namespace
}  // namespace simgate::websocket_test
