// The transport of docs/writing-a-transport.md (docs/examples/line_transport.cc), loaded
// with dlopen like any plugin and driven over real TCP (127.0.0.1, ephemeral port): the kit
// gives it framing, the oversized-line rule, end of input and the hand-off of outcomes
// produced on the simulation thread. The page shows the file as it is built here.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>

#include "simgate/client/socket_client.h"
#include "simgate/core/errors.h"
#include "simgate/core/plugin_loader.h"
#include "simgate/core/request_manager.h"

namespace simgate {
namespace {

using namespace std::chrono_literals;
using ::testing::HasSubstr;
using ::testing::StartsWith;

std::string read_file(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

class LineTransportTest : public ::testing::Test {
 protected:
  void SetUp() override {
    plugin_ = load_transport_plugin(std::string(SIMGATE_TEST_EXAMPLE_PLUGIN_DIR) + "/libsimgate_transport_line.so");
    manager_ = plugin_->create(json{{"port", 0}, {"max_message_bytes", 64}}, "transports.line");
    manager_->register_service("test", [](int a, int b) { return a + b; }, "add", {"a", "b"});
    manager_->register_service("test", [](std::string m) -> json { throw ServiceError(m); }, "fail", {"message"});
    manager_->start();
    const std::string endpoint = manager_->endpoints().at(0);
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

  std::string roundtrip(client::SocketClient& c, const std::string& line) {
    c.send_line(line);
    auto reply = c.read_line(10s);
    return reply ? *reply : "(no reply within 10 s)";
  }

  std::shared_ptr<TransportPlugin> plugin_;
  std::shared_ptr<RequestManager> manager_;
  std::uint16_t port_ = 0;
  std::atomic<bool> stop_{false};
  std::thread loop_;
};

TEST_F(LineTransportTest, AnswersCallsAndErrorsOnOneConnection) {
  client::SocketClient c("127.0.0.1", port_);
  EXPECT_EQ(roundtrip(c, "1 test add [1, 2]"), "1 SUCCESS 3");
  EXPECT_EQ(roundtrip(c, "2 test add {\"a\": 40, \"b\": 2}"), "2 SUCCESS 42");
  EXPECT_EQ(roundtrip(c, "3 test fail [\"no\"]"), "3 FAILED \"no\"");
  EXPECT_THAT(roundtrip(c, "4 test nowhere"), StartsWith("4 FAILED \""));
  EXPECT_EQ(roundtrip(c, "5 test add [1,"), "5 FAILED \"the parameters are not JSON\"");
  EXPECT_EQ(roundtrip(c, "6 test"), "6 FAILED \"expected <id> <component> <service> [<JSON>]\"");
}

TEST_F(LineTransportTest, AnOversizedLineIsRefusedAndTheConnectionKeepsWorking) {
  client::SocketClient c("127.0.0.1", port_);
  EXPECT_EQ(roundtrip(c, "7 test add [" + std::string(100, ' ') + "1, 2]"),
            "- FAILED \"line longer than max_message_bytes\"");
  EXPECT_EQ(roundtrip(c, "8 test add [1, 2]"), "8 SUCCESS 3");
}

TEST_F(LineTransportTest, AClientThatEndsItsInputGetsItsAnswersThenTheConnectionCloses) {
  client::SocketClient c("127.0.0.1", port_);
  c.send_raw("9 test add [2, 2]\n10 test add [3, 3]");  // the last line without its '\n'
  c.shutdown_send();
  EXPECT_EQ(c.read_line(10s).value_or(""), "9 SUCCESS 4");
  EXPECT_EQ(c.read_line(10s).value_or(""), "10 SUCCESS 6");
  EXPECT_THROW(c.read_line(10s), std::runtime_error) << "the connection stayed open after its answers";
}

TEST(LineTransportDoc, ThePageShowsTheExampleAsBuilt) {
  const std::string page = read_file(std::string(SIMGATE_SOURCE_DIR) + "/docs/writing-a-transport.md");
  const std::string file = read_file(std::string(SIMGATE_SOURCE_DIR) + "/docs/examples/line_transport.cc");
  ASSERT_FALSE(file.empty());
  EXPECT_THAT(page, HasSubstr("```cpp\n" + file + "```\n"))
      << "docs/writing-a-transport.md must show docs/examples/line_transport.cc verbatim";
}

}  // namespace
}  // namespace simgate
