// Progress notifications (issue #20): a call whose named params carry
// "_meta": {"progress": true} gets rpc.progress {id, status: "RUNNING", data} for each report
// of its service before its response; other calls get none; a bad _meta is -32602.
#include <gtest/gtest.h>

#include "test_util.h"

namespace simgate::jsonrpc_test {
namespace {

class JsonRpcProgress : public JsonRpcFixture {
 protected:
  json options() override { return {{"progress_interval_ms", 0}}; }  // every report
};

json progress_note(const json& id, const json& data) {
  return {{"jsonrpc", "2.0"},
          {"method", "rpc.progress"},
          {"params", {{"id", id}, {"status", "RUNNING"}, {"data", data}}}};
}

TEST_F(JsonRpcProgress, ACallThatAskedGetsEachReportThenItsResponse) {
  client_->send_line(
      R"({"jsonrpc":"2.0","method":"robot.arm.hold","params":{"key":"p","_meta":{"progress":true}},"id":7})");
  barrier(*client_);  // the hold has started (the service saw no _meta: it takes only key)
  auto control = connect();
  EXPECT_EQ(control->request("ctl.progress", json::array({"p", 1}), k_timeout)["result"], true);
  EXPECT_EQ(
      control->request("ctl.progress", json::array({"p", {{"left", 2.5}}}), k_timeout)["result"],
      true);
  EXPECT_EQ(control->request("ctl.release", json::array({"p", "done"}), k_timeout)["result"], true);
  EXPECT_EQ(next(*client_), progress_note(7, 1));
  EXPECT_EQ(next(*client_), progress_note(7, {{"left", 2.5}}));
  json response = next(*client_);
  EXPECT_EQ(response["id"], 7);
  EXPECT_EQ(response["result"], "done");
}

TEST_F(JsonRpcProgress, ACallThatDidNotAskGetsNoReports) {
  client_->send_line(
      R"({"jsonrpc":"2.0","method":"robot.arm.hold","params":{"key":"q"},"id":"q1"})");
  barrier(*client_);
  auto control = connect();
  EXPECT_EQ(control->request("ctl.progress", json::array({"q", 1}), k_timeout)["result"], false);
  EXPECT_EQ(control->request("ctl.release", json::array({"q", 3}), k_timeout)["result"], true);
  json response = next(*client_);
  EXPECT_EQ(response["id"], "q1");
  EXPECT_EQ(response["result"], 3);
}

TEST_F(JsonRpcProgress, AStringIdIsEchoedAsSentInTheNotification) {
  client_->send_line(
      R"({"jsonrpc":"2.0","method":"robot.arm.hold","params":{"key":"s","_meta":{"progress":true}},"id":"job-1"})");
  barrier(*client_);
  auto control = connect();
  EXPECT_EQ(control->request("ctl.progress", json::array({"s", "half"}), k_timeout)["result"],
            true);
  EXPECT_EQ(control->request("ctl.release", json::array({"s", nullptr}), k_timeout)["result"],
            true);
  EXPECT_EQ(next(*client_), progress_note("job-1", "half"));
  EXPECT_EQ(next(*client_)["id"], "job-1");
}

TEST_F(JsonRpcProgress, ABadMetaIsInvalidParamsNamingIt) {
  json r = round_trip(
      *client_,
      R"({"jsonrpc":"2.0","method":"robot.arm.add","params":{"a":1,"b":2,"_meta":5},"id":1})");
  EXPECT_EQ(error_code(r), -32602);
  EXPECT_EQ(r["error"]["data"]["parameter"], "_meta");
  r = round_trip(
      *client_,
      R"({"jsonrpc":"2.0","method":"robot.arm.add","params":{"a":1,"b":2,"_meta":{"progres":true}},"id":2})");
  EXPECT_EQ(error_code(r), -32602);
  EXPECT_NE(r["error"]["message"].get<std::string>().find("unknown call option 'progres'"),
            std::string::npos);
  r = round_trip(
      *client_,
      R"({"jsonrpc":"2.0","method":"robot.arm.add","params":{"a":1,"b":2,"_meta":{"progress":1}},"id":3})");
  EXPECT_EQ(error_code(r), -32602);
  // a sync call may ask: it simply has nothing to report
  r = round_trip(
      *client_,
      R"({"jsonrpc":"2.0","method":"robot.arm.add","params":{"a":1,"b":2,"_meta":{"progress":true}},"id":4})");
  EXPECT_EQ(r["result"], 3.0);
}

}  // namespace
}  // namespace simgate::jsonrpc_test
