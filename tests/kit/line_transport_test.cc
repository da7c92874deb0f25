// The transport of docs/writing-a-transport.md (docs/examples/line_transport.cc), loaded
// with dlopen like any plugin and driven over real TCP (127.0.0.1, ephemeral port): the kit
// gives it framing, the oversized-line rule, end of input and the hand-off of outcomes
// produced on the simulation thread. The page shows the file as it is built here.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "example_transport.h"
#include "simgate/client/socket_client.h"

namespace simgate {
namespace {

using namespace std::chrono_literals;
using ::testing::HasSubstr;
using ::testing::StartsWith;

class LineTransportTest : public testing::ExampleTransportTest {
 protected:
  LineTransportTest()
      : ExampleTransportTest("line", json{{"port", 0}, {"max_message_bytes", 64}}) {}

  std::string roundtrip(client::SocketClient& c, const std::string& line) {
    c.send_line(line);
    auto reply = c.read_line(10s);
    return reply ? *reply : "(no reply within 10 s)";
  }
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
  EXPECT_THROW(c.read_line(10s), std::runtime_error)
      << "the connection stayed open after its answers";
}

TEST(LineTransportDoc, ThePageShowsTheExampleAsBuilt) {
  EXPECT_TRUE(testing::the_page_shows("line_transport.cc"));
}

}  // namespace
}  // namespace simgate
