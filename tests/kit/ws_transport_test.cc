// The WebSocket transport of docs/writing-a-transport.md (docs/examples/ws_transport.cc),
// loaded with dlopen like any plugin and driven over a real WebSocket (127.0.0.1, ephemeral
// port): the kit gives it the upgrade, the Origin check, frames, limits and the hand-off of
// outcomes produced on the simulation thread. The page shows the file as it is built here.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>

#include "example_transport.h"
#include "ws_test_client.h"

namespace simgate {
namespace {

using namespace std::chrono_literals;
using ::testing::HasSubstr;
using websocket_test::WsClient;

class WsTransportTest : public testing::ExampleTransportTest {
 protected:
  WsTransportTest()
      : ExampleTransportTest("wsjson", json{{"port", 0}, {"max_message_bytes", 256}}) {}
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
  EXPECT_TRUE(testing::the_page_shows("ws_transport.cc"));
  const std::string file =
      testing::read_file(std::string(SIMGATE_SOURCE_DIR) + "/docs/examples/ws_transport.cc");
  std::size_t lines = 0;
  for (char ch : file) lines += ch == '\n';
  EXPECT_LT(lines, 250u) << "a WebSocket transport on the kit fits in under 250 lines";
}

}  // namespace
}  // namespace simgate
