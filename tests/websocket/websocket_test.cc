// The websocket transport (plugins/websocket): JSON-RPC 2.0 over WebSocket, driven by a
// Beast client (ws_test_client.h) against the test services of the JSON-RPC tests
// (tests/jsonrpc/test_services.h) served through libsimgate_transport_websocket.so. The
// protocol is the jsonrpc transport's engine: these tests check that each feature arrives
// through the WebSocket framing, and what is the framing's own (binary and oversized
// messages, plain HTTP without the web app, max_connections, a client that vanishes).
#include <gtest/gtest.h>

#include <sys/socket.h>
#include <sys/time.h>

#include <chrono>
#include <cstdlib>
#include <functional>
#include <thread>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include <boost/asio/read.hpp>
#include <boost/asio/write.hpp>

#include "simgate/core/plugin_loader.h"
#include "test_services.h"
#include "ws_test_client.h"

namespace simgate::websocket_test {
namespace {

using jsonrpc_test::TestHost;
namespace ws = boost::beast::websocket;

json request(const json& id, const std::string& method, json params = nullptr) {
  json r{{"jsonrpc", "2.0"}, {"id", id}, {"method", method}};
  if (!params.is_null()) r["params"] = std::move(params);
  return r;
}

int error_code(const json& response) {
  if (!response.is_object() || !response.contains("error")) return 0;
  return response["error"].value("code", 0);
}

class WebSocketTest : public ::testing::Test {
 protected:
  virtual json options() { return json::object(); }
  void SetUp() override {
    host_ = std::make_unique<TestHost>(options(), plugin_path());
    client_ = std::make_unique<WsClient>(host_->port());
  }
  void TearDown() override {
    client_.reset();
    host_.reset();
  }
  std::unique_ptr<TestHost> host_;
  std::unique_ptr<WsClient> client_;
};

TEST(WebSocketPlugin, LoadsAndReportsItsEndpoint) {
  auto rm = load_transport(plugin_path(), json{{"port", 0}});
  rm->start();
  const auto endpoints = rm->endpoints();
  ASSERT_EQ(endpoints.size(), 1u);
  EXPECT_TRUE(endpoints[0].starts_with("ws://127.0.0.1:")) << endpoints[0];
  EXPECT_TRUE(endpoints[0].ends_with("/")) << endpoints[0];
  rm->stop();
}

TEST(WebSocketPlugin, RefusesAnUnknownOption) {
  EXPECT_ANY_THROW(load_transport(plugin_path(), json{{"port", 0}, {"max_line", 10}}));
}

TEST_F(WebSocketTest, SyncCallWithPositionalParams) {
  json r = client_->call(request(1, "spec.subtract", json::array({42, 23})));
  EXPECT_EQ(r, json({{"jsonrpc", "2.0"}, {"id", 1}, {"result", 19}})) << r.dump();
}

TEST_F(WebSocketTest, NamedParams) {
  json r = client_->call(request("a", "spec.subtract", {{"subtrahend", 23}, {"minuend", 42}}));
  EXPECT_EQ(r["result"], 19) << r.dump();
  EXPECT_EQ(r["id"], "a");
  r = client_->call(request(2, "robot.arm.greet", {{"name", "ws"}}));
  EXPECT_EQ(r["result"], "hello, ws") << r.dump();
}

TEST_F(WebSocketTest, AsyncCallsCompleteOutOfOrder) {
  client_->send(request(1, "robot.arm.hold", json::array({"first"})));
  client_->send(request(2, "robot.cam.hold", json::array({"second"})));
  // both started (a sync call after them answers once they ran)
  ASSERT_EQ(client_->call(request(3, "ctl.iteration"))["id"], 3);
  ASSERT_EQ(client_->call(request(4, "ctl.release", json::array({"second", "b"})))["result"], true);
  json second = client_->receive();
  EXPECT_EQ(second["id"], 2) << second.dump();
  EXPECT_EQ(second["result"], "b");
  ASSERT_EQ(client_->call(request(5, "ctl.release", json::array({"first", "a"})))["result"], true);
  json first = client_->receive();
  EXPECT_EQ(first["id"], 1) << first.dump();
  EXPECT_EQ(first["result"], "a");
}

TEST_F(WebSocketTest, RpcCancelEndsThePendingCall) {
  client_->send(request(7, "robot.arm.hold", json::array({"c"})));
  ASSERT_EQ(client_->call(request(8, "ctl.iteration"))["id"], 8);
  // the cancel's answer, then the cancelled call's -32002
  json cancelled = client_->call(request(9, "rpc.cancel", {{"id", 7}}));
  EXPECT_EQ(cancelled["id"], 9) << cancelled.dump();
  EXPECT_EQ(cancelled["result"], true);
  json call = client_->receive();
  EXPECT_EQ(call["id"], 7) << call.dump();
  EXPECT_EQ(error_code(call), -32002);
  // an id nobody uses
  EXPECT_EQ(client_->call(request(10, "rpc.cancel", {{"id", 12345}}))["result"], false);
}

TEST_F(WebSocketTest, BatchIsOneMessageAnsweredByOneArray) {
  json batch = json::array(
      {request(1, "spec.sum", json::array({1, 2, 4})),
       json{{"jsonrpc", "2.0"}, {"method", "spec.notify_hello"}, {"params", json::array({7})}},
       request(2, "spec.subtract", json::array({42, 23})), json{{"foo", "boo"}},
       request(5, "foo.get"), request(9, "spec.get_data")});
  json r = client_->call(batch);
  ASSERT_TRUE(r.is_array()) << r.dump();
  ASSERT_EQ(r.size(), 5u) << r.dump();  // the notification gets nothing
  EXPECT_EQ(r[0]["result"], 7);
  EXPECT_EQ(r[1]["result"], 19);
  EXPECT_EQ(error_code(r[2]), -32600);
  EXPECT_EQ(error_code(r[3]), -32601);
  EXPECT_EQ(r[4]["result"], json::array({"hello", 5}));
}

TEST_F(WebSocketTest, DiscoverListsTheServedServices) {
  json r = client_->call(request(1, "rpc.discover"));
  ASSERT_TRUE(r.contains("result")) << r.dump();
  EXPECT_EQ(r["result"]["openrpc"].get<std::string>().substr(0, 2), "1.");
  std::set<std::string> methods;
  for (const auto& m : r["result"]["methods"]) methods.insert(m["name"].get<std::string>());
  EXPECT_TRUE(methods.count("spec.subtract")) << r.dump();
  EXPECT_TRUE(methods.count("robot.arm.hold"));
  EXPECT_TRUE(r["result"].contains("x-simgate-streams"));
}

TEST_F(WebSocketTest, UnknownMethodAndMalformedJsonAreAnsweredAndTheConnectionLivesOn) {
  json r = client_->call(request(1, "robot.arm.nothing"));
  EXPECT_EQ(error_code(r), -32601) << r.dump();
  EXPECT_EQ(r["id"], 1);
  client_->send(std::string(R"({"jsonrpc": "2.0", "method": "foobar, "params": "bar", "baz])"));
  r = client_->receive();
  EXPECT_EQ(error_code(r), -32700) << r.dump();
  EXPECT_TRUE(r["id"].is_null());
  EXPECT_EQ(client_->call(request(2, "spec.subtract", json::array({3, 1})))["result"], 2);
}

TEST_F(WebSocketTest, ABinaryMessageIsAnInvalidRequestAndTheConnectionLivesOn) {
  client_->send_binary(R"({"jsonrpc":"2.0","id":1,"method":"spec.get_data"})");
  json r = client_->receive();
  EXPECT_EQ(error_code(r), -32600) << r.dump();
  EXPECT_EQ(r["error"]["data"]["reason"], "binary message");
  EXPECT_EQ(client_->call(request(2, "spec.subtract", json::array({3, 1})))["result"], 2);
}

class WebSocketLimitsTest : public WebSocketTest {
 protected:
  json options() override { return json{{"max_message_bytes", 4096}, {"max_connections", 3}}; }
};

TEST_F(WebSocketLimitsTest, AnOversizedMessageIsRefusedAndTheConnectionLivesOn) {
  // a message of 100 KiB, in one frame, then one of several fragments
  json big = request(1, "robot.arm.echo", json::array({std::string(100 * 1024, 'x')}));
  json r = client_->call(big);
  EXPECT_EQ(error_code(r), -32600) << r.dump().substr(0, 300);
  EXPECT_EQ(r["error"]["data"]["reason"], "message too large");
  EXPECT_EQ(r["error"]["data"]["max_message_bytes"], 4096);
  EXPECT_GE(r["error"]["data"]["bytes"].get<std::size_t>(), 4096u);
  // just under the limit passes
  json fits = client_->call(request(2, "robot.arm.echo", json::array({std::string(3000, 'y')})));
  EXPECT_EQ(fits["result"], std::string(3000, 'y'));
  EXPECT_EQ(client_->call(request(3, "spec.subtract", json::array({3, 1})))["result"], 2);
}

TEST_F(WebSocketLimitsTest, ConnectionsPastMaxConnectionsAreRefusedWithAReason) {
  // the fixture's client and two more reach max_connections 3
  WsClient second(host_->port()), third(host_->port());
  ASSERT_EQ(second.call(request(1, "ctl.iteration"))["id"], 1);
  ASSERT_EQ(third.call(request(1, "ctl.iteration"))["id"], 1);
  try {
    WsClient fourth(host_->port());
    ADD_FAILURE() << "a fourth connection was upgraded";
  } catch (const boost::system::system_error& e) {
    // the upgrade is answered 503 (the JSON-RPC -32006 error in its body)
    SUCCEED() << e.what();
  }
  // the others keep working; one leaving makes room
  EXPECT_EQ(client_->call(request(2, "spec.subtract", json::array({3, 1})))["result"], 2);
  third.vanish();
  for (int attempt = 0; attempt < 200; ++attempt) {
    try {
      WsClient again(host_->port());
      EXPECT_EQ(again.call(request(1, "spec.subtract", json::array({5, 1})))["result"], 4);
      return;
    } catch (const boost::system::system_error&) {
      // the server has not yet seen the third leave
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  ADD_FAILURE() << "no room after a client left";
}

TEST_F(WebSocketTest, AClientVanishingMidCallLeavesTheOthersServedAndItsCallCancelled) {
  auto other = std::make_unique<WsClient>(host_->port());
  other->send(request(1, "robot.arm.hold", json::array({"gone"})));
  ASSERT_EQ(other->call(request(2, "ctl.iteration"))["id"], 2);
  EXPECT_EQ(client_->call(request(1, "ctl.pending", json::array({"gone"})))["result"], true);
  other->vanish();
  other.reset();
  // its call is cancelled once the server sees it leave ("on_disconnect": "cancel")
  bool pending = true;
  for (int attempt = 0; attempt < 500 && pending; ++attempt) {
    json r = client_->call(request(10 + attempt, "ctl.pending", json::array({"gone"})));
    ASSERT_TRUE(r.contains("result")) << r.dump();
    pending = r["result"].get<bool>();
  }
  EXPECT_FALSE(pending);
  EXPECT_EQ(client_->call(request(3, "spec.subtract", json::array({3, 1})))["result"], 2);
}

TEST_F(WebSocketTest, ProgressReportsArriveBeforeTheResult) {
  client_->send(request(1, "robot.arm.hold", {{"key", "p"}, {"_meta", {{"progress", true}}}}));
  ASSERT_EQ(client_->call(request(2, "ctl.iteration"))["id"], 2);
  ASSERT_EQ(client_->call(request(3, "ctl.progress", json::array({"p", 0.5})))["result"], true);
  // the report (sent before the answer to ctl.progress, or after it)
  json a = client_->receive();
  json report = a.value("method", "") == "rpc.progress" ? a : json();
  if (report.is_null()) {
    EXPECT_EQ(a["id"], 3);
  }
  ASSERT_EQ(client_->call(request(4, "ctl.release", json::array({"p", "done"})))["result"], true);
  json r = client_->receive();
  EXPECT_EQ(r["id"], 1) << r.dump();
  EXPECT_EQ(r["result"], "done");
}

TEST_F(WebSocketTest, DeadlineInMetaEndsTheCallWithTimeout) {
  json r =
      client_->call(request(1, "robot.arm.hold", {{"key", "t"}, {"_meta", {{"timeout_ms", 50}}}}));
  EXPECT_EQ(r["id"], 1) << r.dump();
  EXPECT_EQ(error_code(r), -32003) << r.dump();
}

// without the web app (static_files_test.cc tests it), the port says what it is
class WebSocketNoWebTest : public WebSocketTest {
 protected:
  json options() override { return json{{"web", false}}; }
};

TEST_F(WebSocketNoWebTest, APlainHttpGetIsAnsweredNotFound) {
  boost::asio::io_context io;
  boost::asio::ip::tcp::socket socket(io);
  socket.connect({boost::asio::ip::make_address("127.0.0.1"), host_->port()});
  const std::string get = "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n";
  boost::asio::write(socket, boost::asio::buffer(get));
  std::string response;
  boost::system::error_code ec;
  char buffer[4096];
  for (int reads = 0; reads < 100; ++reads) {
    const std::size_t n = socket.read_some(boost::asio::buffer(buffer), ec);
    response.append(buffer, n);
    if (ec) break;  // the server closes after its answer
  }
  EXPECT_TRUE(response.starts_with("HTTP/1.1 404")) << response;
  EXPECT_NE(response.find("JSON-RPC 2.0 over WebSocket"), std::string::npos) << response;
}

class WebSocketSlowReaderTest : public WebSocketTest {
 protected:
  json options() override { return json{{"max_unsent_bytes", 65536}}; }
};

TEST_F(WebSocketSlowReaderTest,
       AClientThatNeverReadsIsDroppedPastMaxUnsentBytesAndOthersAreServed) {
  // three async calls (three components: they run side by side) of a client that then reads
  // nothing (a 16 KiB receive window); another client releases them with 3 MB results each,
  // more than the kernel's buffers and max_unsent_bytes together
  const std::vector<std::string> methods = {"robot.arm.hold", "robot.base.hold", "robot.cam.hold"};
  WsClient slow(host_->port(), std::chrono::milliseconds(10000), 16 * 1024);
  for (std::size_t k = 0; k < methods.size(); ++k)
    slow.send(request(k, methods[k], json::array({"slow" + std::to_string(k)})));
  for (std::size_t k = 0; k < methods.size(); ++k) {
    bool started = false;
    for (int attempt = 0; attempt < 500 && !started; ++attempt)
      started = client_
                    ->call(request(1000 + attempt, "ctl.pending",
                                   json::array({"slow" + std::to_string(k)})))
                    .value("result", false);
    ASSERT_TRUE(started) << methods[k];
  }
  const std::string big(3 << 20, 'x');
  for (std::size_t k = 0; k < methods.size(); ++k) {
    json r =
        client_->call(request(k, "ctl.release", json::array({"slow" + std::to_string(k), big})));
    EXPECT_EQ(r["result"], true) << r.dump().substr(
        0, 300);  // the releasing client is served throughout
  }
  // the slow client finds fewer than its three replies, then the end of the connection
  std::size_t replies = 0;
  for (; replies < methods.size(); ++replies)
    if (!slow.receive_text()) break;
  EXPECT_LT(replies, methods.size());
  EXPECT_NE(slow.error, boost::asio::error::would_block) << "no end of connection, a timeout";
  EXPECT_NE(slow.error, boost::asio::error::try_again);
  EXPECT_EQ(client_->call(request(99, "spec.subtract", json::array({3, 1})))["result"], 2);
}

class WebSocketAuthTest : public WebSocketTest {
 protected:
  json options() override {
    ::setenv("SIMGATE_WEBSOCKET_TEST_TOKEN", k_token, 1);
    return json{{"auth", {{"token_env", "SIMGATE_WEBSOCKET_TEST_TOKEN"}, {"loopback", true}}}};
  }
  static constexpr const char* k_token = "b5f0c6d2a9e84f7a1c3e5d7b9a0f2e4c";
};

TEST_F(WebSocketAuthTest, CallsNeedRpcLoginFirst) {
  EXPECT_EQ(error_code(client_->call(request(1, "spec.subtract", json::array({3, 1})))), -32005);
  EXPECT_EQ(client_->call(request(2, "rpc.login", {{"token", k_token}}))["result"], true);
  EXPECT_EQ(client_->call(request(3, "spec.subtract", json::array({3, 1})))["result"], 2);
}

TEST_F(WebSocketAuthTest, ATokenInTheUpgradeLogsInAndAWrongOneIsRefused) {
  // what a browser's WebSocket can send: the token in the URL, no rpc.login needed
  WsClient in(host_->port(), std::chrono::milliseconds(10000), 0, "",
              std::string("/?token=") + k_token);
  EXPECT_EQ(in.call(request(1, "spec.subtract", json::array({3, 1})))["result"], 2);
  EXPECT_THROW(WsClient(host_->port(), std::chrono::milliseconds(10000), 0, "", "/?token=wrong"),
               boost::system::system_error);
}

TEST_F(WebSocketAuthTest, AWrongTokenIsAnsweredThenClosedWithAReason) {
  json r = client_->call(request(1, "rpc.login", {{"token", "wrong"}}));
  EXPECT_EQ(error_code(r), -32005) << r.dump();
  EXPECT_FALSE(client_->receive_text().has_value());
  EXPECT_EQ(client_->error, ws::error::closed) << client_->error.message();
  EXPECT_EQ(client_->close_reason().code, ws::close_code::policy_error);
  EXPECT_EQ(client_->close_reason().reason, "wrong token");
}

// ---- the framing (RFC 6455), frame by frame, with a raw socket

// A client that writes frames as given (masked or not, fragmented, interleaved) and reads the
// server's frames one by one.
class RawWs {
 public:
  // Connects and upgrades; `first` (frames) is sent in the same write as the request.
  explicit RawWs(std::uint16_t port, const std::string& first = "") : socket_(io_) {
    socket_.connect({boost::asio::ip::make_address("127.0.0.1"), port});
    timeval tv{10, 0};
    ::setsockopt(socket_.native_handle(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    const std::string upgrade =
        "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: Upgrade\r\nUpgrade: websocket\r\n"
        "Sec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\r\n";
    send_raw(upgrade + first);
    while (in_.find("\r\n\r\n") == std::string::npos && fill()) {}
    const auto end = in_.find("\r\n\r\n");
    if (end == std::string::npos || !in_.starts_with("HTTP/1.1 101"))
      throw std::runtime_error("no upgrade: " + in_);
    in_.erase(0, end + 4);
  }
  // One frame as a client writes it (masked unless told otherwise).
  static std::string frame(std::uint8_t opcode, const std::string& payload, bool fin = true,
                           bool masked = true) {
    std::string f;
    f.push_back(static_cast<char>((fin ? 0x80 : 0) | opcode));
    const std::uint8_t mask_bit = masked ? 0x80 : 0;
    if (payload.size() < 126) {
      f.push_back(static_cast<char>(mask_bit | payload.size()));
    } else if (payload.size() <= 0xFFFF) {
      f.push_back(static_cast<char>(mask_bit | 126));
      f.push_back(static_cast<char>(payload.size() >> 8));
      f.push_back(static_cast<char>(payload.size() & 0xFF));
    } else {
      f.push_back(static_cast<char>(mask_bit | 127));
      for (int i = 7; i >= 0; --i)
        f.push_back(
            static_cast<char>((static_cast<std::uint64_t>(payload.size()) >> (8 * i)) & 0xFF));
    }
    const char key[4] = {0x12, 0x34, 0x56, 0x78};
    if (masked) f.append(key, 4);
    for (std::size_t i = 0; i < payload.size(); ++i)
      f.push_back(masked ? static_cast<char>(payload[i] ^ key[i & 3]) : payload[i]);
    return f;
  }
  void send_raw(const std::string& bytes) {
    boost::asio::write(socket_, boost::asio::buffer(bytes));
  }
  struct Frame {
    int opcode = -1;  // -1: the connection ended (or the read timed out)
    bool fin = false;
    std::string payload;
  };
  Frame read_frame() {
    Frame f;
    while (in_.size() < 2)
      if (!fill()) return f;
    std::size_t length = static_cast<unsigned char>(in_[1]) & 0x7F, header = 2;
    if (length >= 126) {
      header += length == 126 ? 2 : 8;
      while (in_.size() < header)
        if (!fill()) return f;
      length = 0;
      for (std::size_t i = 2; i < header; ++i)
        length = (length << 8) | static_cast<unsigned char>(in_[i]);
    }
    while (in_.size() < header + length)
      if (!fill()) return f;
    f.opcode = in_[0] & 0x0F;
    f.fin = in_[0] & 0x80;
    f.payload = in_.substr(header, length);
    in_.erase(0, header + length);
    return f;
  }
  // Whether the server closed the TCP connection (end of input) within the timeout.
  bool ended() {
    for (int reads = 0; reads < 1000; ++reads)
      if (!fill())
        return ec_ == boost::asio::error::eof || ec_ == boost::asio::error::connection_reset;
    return false;
  }

 private:
  bool fill() {
    char buffer[65536];
    const std::size_t n = socket_.read_some(boost::asio::buffer(buffer), ec_);
    in_.append(buffer, n);
    return !ec_;
  }
  boost::asio::io_context io_;
  boost::asio::ip::tcp::socket socket_;
  std::string in_;
  boost::system::error_code ec_;
};

int close_code_of(const RawWs::Frame& f) {
  return f.payload.size() >= 2 ? (static_cast<unsigned char>(f.payload[0]) << 8) |
                                     static_cast<unsigned char>(f.payload[1])
                               : 0;
}

// ---- memory of all sessions together (issue #35, item 6): max_buffered_bytes

class WebSocketMemoryTest : public WebSocketTest {
 protected:
  json options() override { return json{{"max_buffered_bytes", 1 << 20}}; }
};

// before: no total at all (16.5 MB held per client that does not read, times max_connections)
TEST_F(WebSocketMemoryTest, RepliesUnreadByClientsStayUnderMaxBufferedBytes) {
  // a message still arriving holds 700 kB of the 1 MiB; then four clients offering a small
  // window each ask a 6 MB reply (more than the kernel takes at once) and read nothing
  constexpr int k_reply_bytes = 6000000;
  const std::string frame = RawWs::frame(
      k_text, request(1, "robot.arm.echo", json::array({std::string(900000, 'y')})).dump());
  RawWs occupier(host_->port());
  occupier.send_raw(frame.substr(0, 700000));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  std::vector<std::unique_ptr<WsClient>> slow;
  for (int i = 0; i < 4; ++i) {
    slow.push_back(
        std::make_unique<WsClient>(host_->port(), std::chrono::milliseconds(2000), 4096));
    slow.back()->send(request(i, "robot.arm.blob", json::array({k_reply_bytes})));
  }
  EXPECT_EQ(client_->call(request(99, "spec.subtract", json::array({3, 1})))["result"], 2)
      << "a reader is served";
  // each reply took the transport past its budget and was not taken at once: closed
  int closed = 0;
  for (auto& c : slow)
    if (!c->receive_text()) ++closed;
  EXPECT_EQ(closed, 4) << "unread replies held past max_buffered_bytes";
  // the client within the budget finishes its message and is answered
  occupier.send_raw(frame.substr(700000));
  EXPECT_EQ(occupier.read_frame().opcode, k_text);
  EXPECT_EQ(client_->call(request(100, "spec.subtract", json::array({3, 1})))["result"], 2);
}

// before: each session could hold a message of up to max_message_bytes as it arrived, with
// no total
TEST_F(WebSocketMemoryTest, MessagesStillArrivingStayUnderMaxBufferedBytes) {
  // two clients each send 700 kB of a 900 kB message (under max_message_bytes): the second
  // takes the transport past 1 MiB and is closed with 1013; the first finishes and is answered
  const std::string message =
      request(1, "robot.arm.echo", json::array({std::string(900000, 'y')})).dump();
  const std::string frame = RawWs::frame(k_text, message);
  const std::size_t part = 700000;
  RawWs first(host_->port()), second(host_->port());
  first.send_raw(frame.substr(0, part));
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  second.send_raw(frame.substr(0, part));
  const RawWs::Frame closing = second.read_frame();
  EXPECT_EQ(closing.opcode, k_close);
  EXPECT_EQ(close_code_of(closing), 1013) << closing.payload;
  first.send_raw(frame.substr(part));
  const RawWs::Frame answer = first.read_frame();
  EXPECT_EQ(answer.opcode, k_text);
  EXPECT_NE(answer.payload.find(std::string(900000, 'y')), std::string::npos)
      << answer.payload.substr(0, 200);
}

// ---- an unfinished message (issue #37): line_timeout_s bounds it as it bounds a line

class WebSocketTrickleTest : public WebSocketTest {
 protected:
  json options() override { return json{{"line_timeout_s", 0.5}}; }
};

// before: the websocket transport refused line_timeout_s, and a client that announced a
// large message and trickled it kept its connection (and what it sent) forever
TEST_F(WebSocketTrickleTest, AMessageTrickledPastLineTimeoutIsClosedAndOthersAreServed) {
  const std::string frame = RawWs::frame(
      k_text, request(1, "robot.arm.echo", json::array({std::string(100000, 't')})).dump());
  RawWs trickler(host_->port()), half_header(host_->port());
  trickler.send_raw(frame.substr(0, 1000));
  half_header.send_raw(frame.substr(0, 1));  // not even a whole frame head
  const auto began = std::chrono::steady_clock::now();
  // a byte every 100 ms keeps the client heard, not its message finished
  std::size_t sent = 1000;
  for (int i = 0; i < 8; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    trickler.send_raw(frame.substr(sent++, 1));
    EXPECT_EQ(client_->call(request(i, "spec.subtract", json::array({3, 1})))["result"], 2)
        << "others are served";
  }
  for (RawWs* raw : {&trickler, &half_header}) {
    const RawWs::Frame close = raw->read_frame();
    EXPECT_EQ(close.opcode, k_close);
    EXPECT_EQ(close_code_of(close), 1001) << close.payload;
    EXPECT_NE(close.payload.find("line_timeout_s"), std::string::npos) << close.payload;
  }
  const auto waited = std::chrono::steady_clock::now() - began;
  EXPECT_LT(waited, std::chrono::seconds(5)) << "closed at line_timeout_s, not by another rule";
}

TEST_F(WebSocketTrickleTest, WholeMessagesSentSlowlyAreNotUnfinished) {
  // a client that sends a whole message every 300 ms never has one unfinished past 0.5 s
  WsClient slow(host_->port());
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(slow.call(request(i, "spec.subtract", json::array({3, 1})))["result"], 2);
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
  }
  EXPECT_EQ(slow.call(request(9, "spec.subtract", json::array({3, 1})))["result"], 2);
}

TEST_F(WebSocketTest, AFragmentedMessageWithAPingBetweenItsFragmentsIsAnsweredAfterThePong) {
  RawWs raw(host_->port());
  const std::string text = request(1, "spec.subtract", json::array({42, 23})).dump();
  // three fragments (text, continuation, continuation), a ping between the first two
  raw.send_raw(
      RawWs::frame(k_text, text.substr(0, 10), false) + RawWs::frame(k_ping, "are you there") +
      RawWs::frame(0x0, text.substr(10, 10), false) + RawWs::frame(0x0, text.substr(20), true));
  RawWs::Frame pong = raw.read_frame();
  EXPECT_EQ(pong.opcode, k_pong);
  EXPECT_EQ(pong.payload, "are you there");
  RawWs::Frame reply = raw.read_frame();
  ASSERT_EQ(reply.opcode, k_text);
  EXPECT_TRUE(reply.fin);
  EXPECT_EQ(json::parse(reply.payload)["result"], 19) << reply.payload;
}

TEST_F(WebSocketTest, MessagesInOneWriteAndFramesSentWithTheUpgradeAreAllAnsweredInOrder) {
  // the first message travels with the HTTP request itself
  RawWs raw(host_->port(),
            RawWs::frame(k_text, request(0, "spec.subtract", json::array({0, 1})).dump()));
  std::string burst;
  for (int i = 1; i <= 20; ++i)
    burst += RawWs::frame(k_text, request(i, "spec.subtract", json::array({i, 1})).dump());
  raw.send_raw(burst);
  for (int i = 0; i <= 20; ++i) {
    RawWs::Frame reply = raw.read_frame();
    ASSERT_EQ(reply.opcode, k_text) << i;
    json r = json::parse(reply.payload);
    EXPECT_EQ(r["id"], i);
    EXPECT_EQ(r["result"], i - 1);
  }
}

TEST_F(WebSocketTest, LongMessagesUseTheExtendedLengthsBothWays) {
  RawWs raw(host_->port());
  for (std::size_t size : {std::size_t{200}, std::size_t{70000}}) {
    raw.send_raw(RawWs::frame(
        k_text, request(1, "robot.arm.echo", json::array({std::string(size, 'z')})).dump()));
    RawWs::Frame reply = raw.read_frame();
    ASSERT_EQ(reply.opcode, k_text) << size;
    EXPECT_EQ(json::parse(reply.payload)["result"], std::string(size, 'z'));
  }
}

TEST_F(WebSocketTest, TheClientsCloseFrameIsAnsweredWithItsCodeThenTheConnectionEnds) {
  RawWs raw(host_->port());
  raw.send_raw(RawWs::frame(k_close, std::string("\x03\xe8", 2) + "bye"));
  RawWs::Frame close = raw.read_frame();
  EXPECT_EQ(close.opcode, k_close);
  EXPECT_EQ(close_code_of(close), 1000);
  EXPECT_TRUE(raw.ended());
  EXPECT_EQ(client_->call(request(1, "spec.subtract", json::array({3, 1})))["result"], 2);
}

TEST_F(WebSocketTest, ACloseFrameWithACodeNoPeerMaySendIsAnsweredWith1002NotEchoed) {
  // issue #35 item 10: before, 1005, 1006, 999 or 2999 came back as they were sent
  for (int code : {999, 1004, 1005, 1006, 1015, 1016, 2999, 5000}) {
    RawWs raw(host_->port());
    raw.send_raw(RawWs::frame(
        k_close, std::string{static_cast<char>(code >> 8), static_cast<char>(code & 0xFF)}));
    RawWs::Frame close = raw.read_frame();
    EXPECT_EQ(close.opcode, k_close) << code;
    EXPECT_EQ(close_code_of(close), 1002) << code;
  }
  for (int code : {1000, 1001, 1011, 3000, 4999}) {
    RawWs raw(host_->port());
    raw.send_raw(RawWs::frame(
        k_close, std::string{static_cast<char>(code >> 8), static_cast<char>(code & 0xFF)}));
    EXPECT_EQ(close_code_of(raw.read_frame()), code);
  }
}

TEST_F(WebSocketTest, ProtocolErrorsAreClosedWith1002AndOthersServed) {
  const std::string text = request(1, "spec.subtract", json::array({3, 1})).dump();
  for (const std::string& bad :
       {RawWs::frame(k_text, text, true, /*masked=*/false),  // a client frame must be masked
        RawWs::frame(0x0, text),                             // a continuation of nothing
        RawWs::frame(0x3, text),                             // a reserved opcode
        RawWs::frame(k_ping, std::string(126, 'p')),         // a control frame over 125 bytes
        RawWs::frame(k_ping, "p", /*fin=*/false),            // a fragmented control frame
        RawWs::frame(k_text, "{", false) + RawWs::frame(k_text, "}"),  // a message inside another
        std::string(1, '\xC1') +
            RawWs::frame(k_text, text).substr(1)}) {  // RSV1 without an extension
    RawWs raw(host_->port());
    raw.send_raw(bad);
    RawWs::Frame close = raw.read_frame();
    EXPECT_EQ(close.opcode, k_close);
    EXPECT_EQ(close_code_of(close), 1002);
  }
  EXPECT_EQ(client_->call(request(1, "spec.subtract", json::array({3, 1})))["result"], 2);
}

TEST_F(WebSocketTest, ATextMessageThatIsNotUtf8IsAParseErrorAndTheConnectionLivesOn) {
  RawWs raw(host_->port());
  raw.send_raw(RawWs::frame(k_text, "{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"a\xff\xfe\"}"));
  RawWs::Frame reply = raw.read_frame();
  ASSERT_EQ(reply.opcode, k_text);
  EXPECT_EQ(error_code(json::parse(reply.payload)), -32700) << reply.payload;
  raw.send_raw(RawWs::frame(k_text, request(2, "spec.subtract", json::array({3, 1})).dump()));
  reply = raw.read_frame();
  ASSERT_EQ(reply.opcode, k_text);
  EXPECT_EQ(json::parse(reply.payload)["result"], 2);
}

TEST_F(WebSocketTest, ABinaryMessageInFragmentsIsRefusedWhole) {
  RawWs raw(host_->port());
  raw.send_raw(RawWs::frame(k_binary, "abc", false) + RawWs::frame(0x0, "defg", true));
  RawWs::Frame reply = raw.read_frame();
  ASSERT_EQ(reply.opcode, k_text);
  json r = json::parse(reply.payload);
  EXPECT_EQ(r["error"]["data"]["reason"], "binary message");
  EXPECT_EQ(r["error"]["data"]["bytes"], 7);
}

// ---- connections held without use (the TCP transports' options, kit/connection_rules.h)

TEST(WebSocketPlugin, TakesTheTcpTransportsConnectionLimits) {
  auto rm = load_transport(plugin_path(), json{{"port", 0},
                                               {"max_connections_per_peer", 4},
                                               {"idle_timeout_s", 30},
                                               {"idle_evict_s", 0},
                                               {"line_timeout_s", 10},
                                               {"max_buffered_bytes", 1 << 20}});
  rm->start();
  rm->stop();
  for (const char* key : {"max_connections_per_peer", "idle_timeout_s", "idle_evict_s",
                          "line_timeout_s", "max_buffered_bytes"}) {
    try {
      load_transport(plugin_path(), json{{"port", 0}, {key, -1}});
      ADD_FAILURE() << key << " -1 accepted";
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
  }
}

TEST(WebSocketPlugin, LoopbackClientsAreNotCountedPerPeer) {
  // the machine's own programs all come from one address: max_connections_per_peer ignores them
  TestHost host(json{{"max_connections_per_peer", 1}}, plugin_path());
  WsClient a(host.port()), b(host.port()), c(host.port());
  for (WsClient* client : {&a, &b, &c})
    EXPECT_EQ(client->call(request(1, "spec.subtract", json::array({3, 1})))["result"], 2);
}

class WebSocketIdleTest : public WebSocketTest {
 protected:
  json options() override { return json{{"idle_timeout_s", 0.5}}; }
};

TEST_F(WebSocketIdleTest, AnIdleConnectionIsClosedButNotOneWaitingForAnAnswer) {
  // client_ calls then stays silent; `waiting` is owed the answer of a call that holds
  EXPECT_EQ(client_->call(request(1, "spec.subtract", json::array({3, 1})))["result"], 2);
  WsClient waiting(host_->port());
  waiting.send(request(7, "robot.arm.hold", json::array({"w"})));
  ASSERT_EQ(waiting.call(request(8, "ctl.iteration"))["id"], 8);
  // the idle one ends with a close frame that says why (the receive timeout is 10 s)
  EXPECT_FALSE(client_->receive_text().has_value());
  EXPECT_EQ(client_->error, ws::error::closed) << client_->error.message();
  EXPECT_EQ(client_->close_reason().code, ws::close_code::going_away);
  EXPECT_NE(
      std::string(client_->close_reason().reason.data(), client_->close_reason().reason.size())
          .find("idle_timeout_s"),
      std::string::npos);
  // the one owed an answer was kept: it gets it once another client releases the call
  WsClient other(host_->port());
  EXPECT_EQ(other.call(request(1, "ctl.release", json::array({"w", "released"})))["result"], true);
  json r = waiting.receive();
  EXPECT_EQ(r["id"], 7) << r.dump();
  EXPECT_EQ(r["result"], "released");
}

class WebSocketEvictTest : public WebSocketTest {
 protected:
  json options() override { return json{{"max_connections", 2}, {"idle_evict_s", 0.5}}; }

  // Keeps `busy` calling, running `meanwhile` before each call, until a newcomer is let in
  // (30 attempts, 100 ms apart); null when no room was made.
  std::unique_ptr<WsClient> newcomer_once_room_is_made(
      WsClient& busy, const std::function<void()>& meanwhile = {}) {
    for (int attempt = 0; attempt < 30; ++attempt) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      if (meanwhile) meanwhile();
      EXPECT_EQ(busy.call(request(attempt, "spec.subtract", json::array({3, 1})))["result"], 2);
      try {
        return std::make_unique<WsClient>(host_->port());
      } catch (const boost::system::system_error&) {
        // refused (503): nobody idle long enough yet
      }
    }
    return nullptr;
  }
};

TEST_F(WebSocketEvictTest, AtTheLimitTheConnectionIdleLongestMakesRoom) {
  // client_ is the oldest and stays idle; `busy` keeps calling; a newcomer gets client_'s place
  WsClient busy(host_->port());
  EXPECT_EQ(client_->call(request(1, "spec.subtract", json::array({3, 1})))["result"], 2);
  std::unique_ptr<WsClient> newcomer = newcomer_once_room_is_made(busy);
  ASSERT_TRUE(newcomer) << "no room was made";
  EXPECT_EQ(newcomer->call(request(1, "spec.subtract", json::array({5, 1})))["result"], 4);
  EXPECT_FALSE(client_->receive_text().has_value());
  EXPECT_EQ(client_->error, ws::error::closed) << client_->error.message();
  EXPECT_EQ(client_->close_reason().reason, "idle while the server was full");
  EXPECT_EQ(busy.call(request(99, "spec.subtract", json::array({3, 1})))["result"],
            2);  // never chosen
}

TEST_F(WebSocketEvictTest, AtTheLimitAConnectionSendingOnlyPingsIsIdleAndMakesRoom) {
  // issue #35 item 9: before, a ping every so often kept a connection's place for good
  WsClient busy(host_->port());
  EXPECT_EQ(client_->call(request(1, "spec.subtract", json::array({3, 1})))["result"], 2);
  std::unique_ptr<WsClient> newcomer = newcomer_once_room_is_made(busy, [&] {
    try {
      client_->ping();
    } catch (const boost::system::system_error&) {
      // closed: it made room
    }
  });
  ASSERT_TRUE(newcomer) << "no room was made";
  EXPECT_EQ(newcomer->call(request(1, "spec.subtract", json::array({5, 1})))["result"], 4);
  EXPECT_FALSE(client_->receive_text().has_value());
  EXPECT_EQ(client_->close_reason().reason, "idle while the server was full");
}

// ---- allowed_origins (cross-site WebSocket hijacking)

// The raw HTTP response to an upgrade request carrying `origin` (none when empty).
std::string upgrade_response(std::uint16_t port, const std::string& origin) {
  boost::asio::io_context io;
  boost::asio::ip::tcp::socket socket(io);
  socket.connect({boost::asio::ip::make_address("127.0.0.1"), port});
  timeval tv{10, 0};
  ::setsockopt(socket.native_handle(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  std::string upgrade =
      "GET / HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(port) +
      "\r\nConnection: Upgrade\r\nUpgrade: websocket\r\nSec-WebSocket-Version: 13\r\n"
      "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n";
  if (!origin.empty()) upgrade += "Origin: " + origin + "\r\n";
  upgrade += "\r\n";
  boost::asio::write(socket, boost::asio::buffer(upgrade));
  std::string response;
  boost::system::error_code ec;
  char buffer[4096];
  for (int reads = 0; reads < 100; ++reads) {
    const std::size_t n = socket.read_some(boost::asio::buffer(buffer), ec);
    response.append(buffer, n);
    if (ec ||
        (response.starts_with("HTTP/1.1 101") && response.find("\r\n\r\n") != std::string::npos))
      break;
  }
  return response;
}

TEST_F(WebSocketTest, AnUpgradeFromAPageOfAnotherSiteIsRefusedWith403) {
  const std::string response = upgrade_response(host_->port(), "https://evil.example");
  EXPECT_TRUE(response.starts_with("HTTP/1.1 403")) << response;
  EXPECT_NE(response.find("origin 'https://evil.example' are not allowed"), std::string::npos)
      << response;
  EXPECT_NE(response.find("allowed_origins"), std::string::npos) << response;
  EXPECT_THROW(
      WsClient(host_->port(), std::chrono::milliseconds(10000), 0, "http://evil.example:8090"),
      boost::system::system_error);
  // the same host on another port is another origin; "null" (a sandboxed page) is none of ours
  EXPECT_TRUE(upgrade_response(host_->port(), "http://127.0.0.1:1").starts_with("HTTP/1.1 403"));
  EXPECT_TRUE(upgrade_response(host_->port(), "null").starts_with("HTTP/1.1 403"));
  // the others are served on
  EXPECT_EQ(client_->call(request(1, "spec.subtract", json::array({3, 1})))["result"], 2);
}

TEST_F(WebSocketTest, ItsOwnOriginsAndClientsWithoutOriginAreAccepted) {
  const std::string port = std::to_string(host_->port());
  EXPECT_TRUE(upgrade_response(host_->port(), "").starts_with("HTTP/1.1 101"));
  for (const std::string& origin : {"http://127.0.0.1:" + port, "http://localhost:" + port,
                                    "HTTP://LocalHost:" + port, "http://[::1]:" + port}) {
    EXPECT_TRUE(upgrade_response(host_->port(), origin).starts_with("HTTP/1.1 101")) << origin;
    WsClient page(host_->port(), std::chrono::milliseconds(10000), 0, origin);
    EXPECT_EQ(page.call(request(1, "spec.subtract", json::array({3, 1})))["result"], 2) << origin;
  }
}

class WebSocketOriginsTest : public WebSocketTest {
 protected:
  json options() override {
    return json{{"allowed_origins", {"https://app.example", "http://lab.example:8000"}}};
  }
};

TEST_F(WebSocketOriginsTest, AllowedOriginsReplacesTheDefaultList) {
  WsClient app(host_->port(), std::chrono::milliseconds(10000), 0, "https://app.example");
  EXPECT_EQ(app.call(request(1, "spec.subtract", json::array({3, 1})))["result"], 2);
  // the scheme's default port is implied
  EXPECT_TRUE(
      upgrade_response(host_->port(), "https://app.example:443").starts_with("HTTP/1.1 101"));
  EXPECT_TRUE(
      upgrade_response(host_->port(), "http://lab.example:8000").starts_with("HTTP/1.1 101"));
  EXPECT_TRUE(upgrade_response(host_->port(), "http://lab.example").starts_with("HTTP/1.1 403"));
  EXPECT_TRUE(upgrade_response(host_->port(), "http://app.example").starts_with("HTTP/1.1 403"));
  const std::string own = "http://127.0.0.1:" + std::to_string(host_->port());
  EXPECT_TRUE(upgrade_response(host_->port(), own).starts_with("HTTP/1.1 403"));
  EXPECT_TRUE(upgrade_response(host_->port(), "").starts_with("HTTP/1.1 101"));
}

TEST(WebSocketPlugin, AllowedOriginsStarAcceptsAnyPage) {
  TestHost host(json{{"allowed_origins", {"*"}}}, plugin_path());
  WsClient page(host.port(), std::chrono::milliseconds(10000), 0, "https://anywhere.example");
  EXPECT_EQ(page.call(request(1, "spec.subtract", json::array({3, 1})))["result"], 2);
}

TEST(WebSocketPlugin, RefusesMalformedAllowedOrigins) {
  for (const json& bad :
       {json("http://a.example"), json::array({"http://a.example/path"}),
        json::array({"a.example"}), json::array({42}), json::array({"http://a.example:99999"})}) {
    try {
      load_transport(plugin_path(), json{{"port", 0}, {"allowed_origins", bad}});
      ADD_FAILURE() << "accepted " << bad.dump();
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find("allowed_origins"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace simgate::websocket_test
