// Deadlines on the socket transport (issue #20): MORSE's lines carry none, so the transport's
// "timeouts" option gives calls theirs (a default, and per service). Past it the reply is
// `<id> FAILED "<message>"` and the async service was interrupted: the component takes the
// next call instead of refusing it. No timed assertions: short deadlines, generous waits.
#include "socket_test_fixture.h"

namespace simgate::socket::test {
namespace {

using ::testing::HasSubstr;

using SocketDeadline = SocketFixture;

TEST_F(SocketDeadline, APerServiceDeadlineEndsTheCallFailedAndFreesTheComponent) {
  start_server({{"timeouts", {{"services", {{"strict.hold", 50}}}}}});
  auto c = connect();
  // strict.hold is non-interruptible: a second hold is refused while one runs
  EXPECT_EQ(roundtrip(*c, "a strict hold [1]"),
            "a FAILED \"strict.hold: no reply within 50 ms (deadline); interrupted\"");
  // the next one is accepted (a refusal would say "A non-interruptible service (strict.hold)
  // is already running"): it runs, and times out in its turn
  EXPECT_EQ(roundtrip(*c, "b strict hold [2]"),
            "b FAILED \"strict.hold: no reply within 50 ms (deadline); interrupted\"");
  // the timed-out calls are over: their completions finish nothing
  EXPECT_EQ(roundtrip(*c, "c strict release [7]"), "c SUCCESS false");
}

TEST_F(SocketDeadline, TheDefaultAppliesToEveryCallAndSyncCallsRunToTheirResult) {
  start_server({{"timeouts", {{"default_ms", 50}}}});
  auto c = connect();
  EXPECT_EQ(roundtrip(*c, "a plain hold [1]"),
            "a FAILED \"plain.hold: no reply within 50 ms (deadline); interrupted\"");
  EXPECT_EQ(roundtrip(*c, "b test ping"), "b SUCCESS \"pong\"");
  EXPECT_EQ(roundtrip(*c, "c test_component add (1, 2)"), "c SUCCESS 3");
}

TEST_F(SocketDeadline, AServicesZeroOverridesTheDefault) {
  start_server({{"timeouts", {{"default_ms", 50}, {"services", {{"worker.hold", 0}}}}}});
  auto c = connect();
  c->send_line("a worker hold [1]");  // no deadline: runs until released
  EXPECT_EQ(roundtrip(*c, "b plain hold [1]"),
            "b FAILED \"plain.hold: no reply within 50 ms (deadline); interrupted\"");
  c->send_line("c worker release [5]");
  EXPECT_EQ(next_lines(*c, 2), (std::multiset<std::string>{"a SUCCESS 5", "c SUCCESS true"}));
}

TEST_F(SocketDeadline, WithoutTimeoutsNothingTimesOut) {
  start_server();
  auto c = connect();
  c->send_line("a worker hold [1]");
  EXPECT_EQ(roundtrip(*c, "b test ping"), "b SUCCESS \"pong\"");
  std::this_thread::sleep_for(100ms);
  c->send_line("c worker release [5]");
  EXPECT_EQ(next_lines(*c, 2), (std::multiset<std::string>{"a SUCCESS 5", "c SUCCESS true"}));
}

TEST_F(SocketDeadline, BadTimeoutsAreConfigErrorsNamingTheKey) {
  auto plugin = load_transport_plugin(std::string(SIMGATE_TEST_PLUGIN_DIR) +
                                      "/libsimgate_transport_socket.so");
  const std::vector<std::pair<json, std::string>> bad = {
      {5, "timeouts"},
      {{{"default_ms", -1}}, "timeouts.default_ms"},
      {{{"default_ms", 1.5}}, "timeouts.default_ms"},
      {{{"default_ms", "100"}}, "timeouts.default_ms"},
      {{{"default_ms", 1e12}}, "timeouts.default_ms"},
      {{{"default_ms", 10}, {"servcies", json::object()}}, "servcies"},
      {{{"services", {{"nodot", 5}}}}, "timeouts.services.nodot"},
      {{{"services", {{"robot.", 5}}}}, "timeouts.services.robot."},
      {{{"services", {{"robot.goto", -5}}}}, "timeouts.services.robot.goto"},
      {{{"services", {{"robot.goto", "5"}}}}, "timeouts.services.robot.goto"},
      {{{"services", json::array()}}, "timeouts.services"},
  };
  for (const auto& [value, key] : bad) {
    try {
      plugin->create({{"port", 0}, {"timeouts", value}}, "transports.socket");
      ADD_FAILURE() << "timeouts " << value.dump() << " accepted";
    } catch (const ConfigError& e) {
      EXPECT_THAT(e.what(), HasSubstr(key)) << value.dump();
    }
  }
}

}  // namespace
}  // namespace simgate::socket::test
