// The WebSocket transport of docs/writing-a-transport.md (docs/examples/ws_transport.cc),
// loaded with dlopen like any plugin and driven over a real WebSocket (127.0.0.1, ephemeral
// port): the kit gives it the upgrade, the Origin check, frames, limits and the hand-off of
// outcomes produced on the simulation thread. The page shows the file as it is built here.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <thread>

#include "simgate/core/errors.h"
#include "simgate/core/plugin_loader.h"
#include "simgate/core/request_manager.h"
#include "ws_test_client.h"

namespace simgate {
namespace {

using namespace std::chrono_literals;
using ::testing::HasSubstr;
using websocket_test::WsClient;

std::string read_file(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

class WsTransportTest : public ::testing::Test {
 protected:
  void SetUp() override {
    plugin_ = load_transport_plugin(std::string(SIMGATE_TEST_EXAMPLE_PLUGIN_DIR) + "/libsimgate_transport_wsjson.so");
    manager_ = plugin_->create(json{{"port", 0}, {"max_message_bytes", 256}}, "transports.wsjson");
    manager_->register_service("test", [](int a, int b) { return a + b; }, "add", {"a", "b"});
    manager_->register_service("test", [](std::string m) -> json { throw ServiceError(m); }, "fail", {"message"});
    manager_->start();
    const std::string endpoint = manager_->endpoints().at(0);  // "ws://127.0.0.1:PORT/"
    port_ = static_cast<std::uint16_t>(std::stoi(endpoint.substr(endpoint.rfind(':') + 1)));
    // the simulation thread: runs what the I/O thread could not run at once
    loop_ = std::thread([this] {
      while (!stop_.load()) manager_->process(50ms);
    });
  }
  void TearDown() override {
    stop_ = true;
    manager_->gate()->signal();
    loop_.join();
    manager_->stop();
  }

  std::shared_ptr<TransportPlugin> plugin_;
  std::shared_ptr<RequestManager> manager_;
  std::uint16_t port_ = 0;
  std::atomic<bool> stop_{false};
  std::thread loop_;
};

TEST_F(WsTransportTest, AnswersCallsAndErrorsOnOneConnection) {
  WsClient c(port_);
  EXPECT_EQ(c.call(json{{"id", 1}, {"call", "test.add"}, {"params", {1, 2}}}),
            (json{{"id", 1}, {"status", "SUCCESS"}, {"value", 3}}));
  EXPECT_EQ(c.call(json{{"id", "two"}, {"call", "test.add"}, {"params", {{"a", 40}, {"b", 2}}}}),
            (json{{"id", "two"}, {"status", "SUCCESS"}, {"value", 42}}));
  EXPECT_EQ(c.call(json{{"id", 3}, {"call", "test.fail"}, {"params", {"no"}}}),
            (json{{"id", 3}, {"status", "FAILED"}, {"value", "no"}}));
  const json unknown = c.call(json{{"id", 4}, {"call", "test.nowhere"}});
  EXPECT_EQ(unknown["status"], "FAILED") << unknown.dump();
  c.send(std::string("not JSON"));
  EXPECT_THAT(c.receive()["value"].get<std::string>(), HasSubstr("expected {\"id\""));
}

TEST_F(WsTransportTest, AnOversizedOrBinaryMessageIsRefusedAndTheConnectionKeepsWorking) {
  WsClient c(port_);
  c.send(json{{"id", 5}, {"call", "test.add"}, {"params", {std::string(300, 'x'), 1}}});
  EXPECT_THAT(c.receive()["value"].get<std::string>(), HasSubstr("over max_message_bytes"));
  c.send_binary("\x01\x02");
  EXPECT_THAT(c.receive()["value"].get<std::string>(), HasSubstr("binary"));
  EXPECT_EQ(c.call(json{{"id", 6}, {"call", "test.add"}, {"params", {1, 2}}})["value"], 3);
}

TEST_F(WsTransportTest, APageOfAnotherSiteMayNotOpenIt) {
  EXPECT_THROW(WsClient(port_, 10s, 0, "http://evil.example"), boost::system::system_error);
  WsClient own(port_, 10s, 0, "http://127.0.0.1:" + std::to_string(port_));
  EXPECT_EQ(own.call(json{{"id", 7}, {"call", "test.add"}, {"params", {2, 2}}})["value"], 4);
}

TEST(WsTransportDoc, ThePageShowsTheExampleAsBuilt) {
  const std::string page = read_file(std::string(SIMGATE_SOURCE_DIR) + "/docs/writing-a-transport.md");
  const std::string file = read_file(std::string(SIMGATE_SOURCE_DIR) + "/docs/examples/ws_transport.cc");
  ASSERT_FALSE(file.empty());
  EXPECT_THAT(page, HasSubstr("```cpp\n" + file + "```\n"))
      << "docs/writing-a-transport.md must show docs/examples/ws_transport.cc verbatim";
  std::size_t lines = 0;
  for (char ch : file) lines += ch == '\n';
  EXPECT_LT(lines, 250u) << "a WebSocket transport on the kit fits in under 250 lines";
}

}  // namespace
}  // namespace simgate
