// Deadlines (issue #20): "_meta": {"timeout_ms": N} in named params bounds a call's wait for
// its response; past it the response is error -32003 (data.failure "timeout") and the async
// service was interrupted, so the component takes the next call instead of refusing it busy.
// Bad values are -32602 naming _meta. No timed assertions: short deadlines, generous waits.
#include <gtest/gtest.h>

#include "test_util.h"

namespace simgate::jsonrpc_test {
namespace {

using JsonRpcDeadline = JsonRpcFixture;

bool contains(const json& text, const std::string& part) {
  return text.is_string() && text.get<std::string>().find(part) != std::string::npos;
}

TEST_F(JsonRpcDeadline, ACallPastItsTimeoutGetsMinus32003AndItsServiceIsInterrupted) {
  // robot.base.hold is non-interruptible: a second hold is refused busy while one runs
  json r = round_trip(
      *client_,
      R"({"jsonrpc":"2.0","method":"robot.base.hold","params":{"key":"t","_meta":{"timeout_ms":50}},"id":"t1"})");
  EXPECT_EQ(r["id"], "t1");
  ASSERT_EQ(error_code(r), -32003) << r.dump();
  EXPECT_EQ(r["error"]["message"],
            "robot.base.hold: no reply within 50 ms (deadline); interrupted");
  EXPECT_EQ(r["error"]["data"]["failure"], "timeout");
  EXPECT_EQ(r["error"]["data"]["status"], "FAILED");
  EXPECT_EQ(r["error"]["data"]["timeout_ms"], 50);
  EXPECT_EQ(r["error"]["data"]["method"], "robot.base.hold");
  // nothing runs for nobody: the held call is over, and the component takes the next one
  EXPECT_EQ(client_->request("ctl.pending", json::array({"t"}), k_timeout)["result"], false);
  client_->send_line(
      R"({"jsonrpc":"2.0","method":"robot.base.hold","params":{"key":"u"},"id":"u2"})");
  barrier(*client_);
  auto control = connect();
  EXPECT_EQ(control->request("ctl.pending", json::array({"u"}), k_timeout)["result"], true);
  EXPECT_EQ(control->request("ctl.release", json::array({"u", "second"}), k_timeout)["result"],
            true);
  r = next(*client_);
  EXPECT_EQ(r["id"], "u2");
  EXPECT_EQ(r["result"], "second");
  // the timed-out call's own completion, had it come, is dropped: it is no longer held
  EXPECT_EQ(control->request("ctl.release", json::array({"t", "late"}), k_timeout)["result"],
            false);
}

TEST_F(JsonRpcDeadline, ACallThatEndsInTimeGetsItsResult) {
  client_->send_line(
      R"({"jsonrpc":"2.0","method":"robot.arm.hold","params":{"key":"k","_meta":{"timeout_ms":60000,"progress":false}},"id":"a"})");
  barrier(*client_);
  auto control = connect();
  EXPECT_EQ(control->request("ctl.release", json::array({"k", 7}), k_timeout)["result"], true);
  json r = next(*client_);
  EXPECT_EQ(r["id"], "a");
  EXPECT_EQ(r["result"], 7);
}

TEST_F(JsonRpcDeadline, SyncCallsWithATimeoutRunAndAZeroTimeoutMeansNone) {
  json r = round_trip(
      *client_,
      R"({"jsonrpc":"2.0","method":"robot.arm.add","params":{"a":1,"b":2,"_meta":{"timeout_ms":1000}},"id":1})");
  EXPECT_EQ(r["result"], 3.0);
  r = round_trip(
      *client_,
      R"({"jsonrpc":"2.0","method":"robot.arm.add","params":{"a":1,"b":2,"_meta":{"timeout_ms":0}},"id":2})");
  EXPECT_EQ(r["result"], 3.0);
  // a client whose numbers are all doubles
  r = round_trip(
      *client_,
      R"({"jsonrpc":"2.0","method":"robot.arm.add","params":{"a":1,"b":2,"_meta":{"timeout_ms":250.0}},"id":3})");
  EXPECT_EQ(r["result"], 3.0);
}

TEST_F(JsonRpcDeadline, BadTimeoutsAreInvalidParamsNamingMeta) {
  int id = 0;
  for (const char* bad : {"-1", "1.5", "\"100\"", "true", "null", "[5]", "{}", "1e12", "2147483648",
                          "18446744073709551615", "-9223372036854775808", "1e400"}) {
    const std::string line =
        std::string(
            R"({"jsonrpc":"2.0","method":"robot.arm.hold","params":{"key":"b","_meta":{"timeout_ms":)") +
        bad + "}},\"id\":" + std::to_string(++id) + "}";
    json r = round_trip(*client_, line);
    if (std::string(bad) == "1e400") {  // not JSON a parser accepts: a parse error, not a crash
      EXPECT_NE(error_code(r), 0) << line;
      continue;
    }
    EXPECT_EQ(error_code(r), -32602) << bad << ": " << r.dump();
    EXPECT_EQ(r["error"]["data"]["parameter"], "_meta") << bad;
    EXPECT_TRUE(contains(r["error"]["message"], "timeout_ms")) << r.dump();
  }
  // nothing was started: the component is free
  EXPECT_EQ(client_->request("ctl.pending", json::array({"b"}), k_timeout)["result"], false);
  json r = round_trip(
      *client_,
      R"({"jsonrpc":"2.0","method":"robot.arm.add","params":{"a":1,"b":2,"_meta":{"timeout":5}},"id":"x"})");
  EXPECT_EQ(error_code(r), -32602);
  EXPECT_TRUE(contains(r["error"]["message"], "known: progress, timeout_ms")) << r.dump();
  // a refused call leaves its id free: the same id works at once
  r = round_trip(*client_,
                 R"({"jsonrpc":"2.0","method":"robot.arm.add","params":{"a":1,"b":2},"id":"x"})");
  EXPECT_EQ(r["result"], 3) << r.dump();
}

TEST_F(JsonRpcDeadline, EachCallOfABatchHasItsOwnDeadline) {
  json r = round_trip(*client_, one_line(R"([
    {"jsonrpc":"2.0","method":"robot.cam.hold","params":{"key":"c1","_meta":{"timeout_ms":50}},"id":1},
    {"jsonrpc":"2.0","method":"robot.arm.add","params":{"a":2,"b":3,"_meta":{"timeout_ms":50}},"id":2}])"));
  ASSERT_TRUE(r.is_array()) << r.dump();
  ASSERT_EQ(r.size(), 2u);
  for (const json& response : r) {
    if (response["id"] == 1) {
      EXPECT_EQ(error_code(response), -32003) << response.dump();
    }
    if (response["id"] == 2) {
      EXPECT_EQ(response["result"], 5.0);
    }
  }
}

}  // namespace
}  // namespace simgate::jsonrpc_test
