// The JSON-RPC 2.0 specification's examples, framing, params, error codes, discovery and
// the C++ client, all over real sockets on 127.0.0.1 against the jsonrpc plugin.
#include <algorithm>
#include <set>
#include <thread>

#include <gtest/gtest.h>

#include "simgate/client/client.h"
#include "test_util.h"

namespace simgate::jsonrpc_test {
namespace {

using JsonRpcConformance = JsonRpcFixture;

// ---- specification examples (methods prefixed "spec.": ours are component.service)

TEST_F(JsonRpcConformance, PositionalParams) {
  auto r = round_trip(
      *client_, R"({"jsonrpc": "2.0", "method": "spec.subtract", "params": [42, 23], "id": 1})");
  EXPECT_EQ(r, json::parse(R"({"jsonrpc": "2.0", "result": 19, "id": 1})"));
  r = round_trip(*client_,
                 R"({"jsonrpc": "2.0", "method": "spec.subtract", "params": [23, 42], "id": 2})");
  EXPECT_EQ(r, json::parse(R"({"jsonrpc": "2.0", "result": -19, "id": 2})"));
}

TEST_F(JsonRpcConformance, NamedParams) {
  auto r = round_trip(
      *client_,
      R"({"jsonrpc": "2.0", "method": "spec.subtract", "params": {"subtrahend": 23, "minuend": 42}, "id": 3})");
  EXPECT_EQ(r, json::parse(R"({"jsonrpc": "2.0", "result": 19, "id": 3})"));
  r = round_trip(
      *client_,
      R"({"jsonrpc": "2.0", "method": "spec.subtract", "params": {"minuend": 42, "subtrahend": 23}, "id": 4})");
  EXPECT_EQ(r, json::parse(R"({"jsonrpc": "2.0", "result": 19, "id": 4})"));
}

TEST_F(JsonRpcConformance, NamedParamsUseDefaults) {
  auto r = client_->request("robot.arm.greet", {{"name", "ada"}}, k_timeout);
  EXPECT_EQ(r["result"], "hello, ada");
  r = client_->request("robot.arm.greet", {{"greeting", "hi"}, {"name", "bob"}}, k_timeout);
  EXPECT_EQ(r["result"], "hi, bob");
  r = client_->request("robot.arm.greet", json::array({"cy"}), k_timeout);
  EXPECT_EQ(r["result"], "hello, cy");
}

TEST_F(JsonRpcConformance, NotificationsGetNoResponse) {
  client_->send_line(R"({"jsonrpc": "2.0", "method": "spec.update", "params": [1,2,3,4,5]})");
  client_->send_line(R"({"jsonrpc": "2.0", "method": "spec.foobar"})");
  client_->send_line(
      R"({"jsonrpc": "2.0", "method": "robot.arm.fail", "params": ["not reported"]})");
  // the first thing that comes back answers the call sent after the notifications
  auto r = round_trip(*client_, R"({"jsonrpc": "2.0", "method": "spec.get_data", "id": "after"})");
  EXPECT_EQ(r, json::parse(R"({"jsonrpc": "2.0", "result": ["hello", 5], "id": "after"})"));
  EXPECT_FALSE(client_->receive(100ms).has_value());
}

TEST_F(JsonRpcConformance, NotificationRuns) {
  client_->send_notification("ctl.mark", json::array({"n1"}));
  EXPECT_EQ(client_->request("ctl.marked", json::array({"n1"}), k_timeout)["result"], true);
}

TEST_F(JsonRpcConformance, MethodNotFound) {
  auto r = round_trip(*client_, R"({"jsonrpc": "2.0", "method": "spec.foobar", "id": "1"})");
  EXPECT_EQ(error_code(r), -32601) << r.dump();
  EXPECT_EQ(r["id"], "1");
  EXPECT_EQ(r["error"]["data"]["method"], "spec.foobar");
  // no dot, unknown component, reserved namespace
  for (const char* method : {"foobar", "nobody.add", "rpc.nope", ".add", "robot."}) {
    r = client_->request(method, nullptr, k_timeout);
    EXPECT_EQ(error_code(r), -32601) << method << ": " << r.dump();
  }
}

TEST_F(JsonRpcConformance, ComponentNameSplitAtLastDot) {
  auto r = client_->request("robot.arm.add", json::array({1.5, 2}), k_timeout);
  EXPECT_EQ(r["result"], 3.5) << r.dump();
}

TEST_F(JsonRpcConformance, InvalidJsonIsParseError) {
  auto r = round_trip(*client_, R"({"jsonrpc": "2.0", "method": "foobar, "params": "bar", "baz])");
  EXPECT_EQ(error_code(r), -32700) << r.dump();
  EXPECT_TRUE(r["id"].is_null());
  // invalid UTF-8 is not JSON either
  r = round_trip(*client_,
                 "{\"jsonrpc\": \"2.0\", \"method\": \"robot.arm.echo\", \"params\": "
                 "[\"\xff\xfe\"], \"id\": 1}");
  EXPECT_EQ(error_code(r), -32700) << r.dump();
}

TEST_F(JsonRpcConformance, ANulByteIsAParseErrorNotTheEndOfTheMessage) {
  // nlohmann's parser stopped at the NUL: the request ran and the rest was ignored (issue
  // #17, item 9, a fuzz finding)
  const std::string line =
      std::string(R"({"jsonrpc":"2.0","method":"robot.arm.add","params":[1,2],"id":1})") +
      std::string(1, '\0') + "garbage";
  auto r = round_trip(*client_, line);
  EXPECT_EQ(error_code(r), -32700) << r.dump();
  EXPECT_TRUE(r["id"].is_null());
  EXPECT_NE(r["error"]["data"]["reason"].get<std::string>().find("a NUL byte at column 65"),
            std::string::npos)
      << r.dump();
  EXPECT_EQ(client_->request("robot.arm.add", json::array({1, 2}), k_timeout)["result"], 3.0);
}

// A number id nlohmann reads as a double (beyond 64 bits, a fraction, an exponent) was
// echoed rounded: 123456789012345678901234567890 came back 1.2345678901234568e+29, and two
// such ids collided as "already pending" (issue #17, item 9). Echoed as sent now.
TEST_F(JsonRpcConformance, ANumberIdIsEchoedExactlyAsSent) {
  auto raw = [&](const std::string& line) {
    client_->send_line(line);
    return client_->read_line(k_timeout).value_or("(no reply)");
  };
  EXPECT_EQ(
      raw(R"({"jsonrpc":"2.0","method":"robot.arm.add","params":[1,2],"id":123456789012345678901234567890})"),
      R"({"jsonrpc":"2.0","id":123456789012345678901234567890,"result":3.0})");
  EXPECT_EQ(raw(R"({"jsonrpc":"2.0","method":"robot.arm.add","params":[1,2],"id":1.50})"),
            R"({"jsonrpc":"2.0","id":1.50,"result":3.0})");
  // errors too, and batch entries
  EXPECT_EQ(raw(R"({"jsonrpc":"2.0","method":"robot.arm.nothing","id":2e3})")
                .rfind(R"({"jsonrpc":"2.0","id":2e3,"error":{"code":-32601,)", 0),
            0u);
  EXPECT_EQ(
      raw(R"([{"jsonrpc":"2.0","method":"robot.arm.add","params":[1,2],"id":18446744073709551616},)"
          R"({"jsonrpc":"2.0","method":"robot.arm.add","params":[2,2],"id":18446744073709551617}])"),
      R"([{"jsonrpc":"2.0","id":18446744073709551616,"result":3.0},)"
      R"({"jsonrpc":"2.0","id":18446744073709551617,"result":4.0}])");
}

TEST_F(JsonRpcConformance, NumberBeyondADoubleIsParseErrorAndTheConnectionLivesOn) {
  // json::parse throws out_of_range (not parse_error) for it: it used to close the connection
  auto r = round_trip(*client_,
                      R"({"jsonrpc":"2.0","method":"robot.arm.echo","params":[1e400],"id":1})");
  EXPECT_EQ(error_code(r), -32700) << r.dump();
  EXPECT_TRUE(r["id"].is_null());
  EXPECT_EQ(client_->request("robot.arm.add", json::array({1, 2}), k_timeout)["result"], 3.0);
}

TEST_F(JsonRpcConformance, InvalidRequestObject) {
  auto r = round_trip(*client_, R"({"jsonrpc": "2.0", "method": 1, "params": "bar"})");
  EXPECT_EQ(error_code(r), -32600) << r.dump();
  EXPECT_TRUE(r["id"].is_null());
  // wrong version, missing method, non-structured params: reported with the request's id
  for (const char* line :
       {R"({"jsonrpc": "1.0", "method": "robot.arm.add", "params": [1, 2], "id": 7})",
        R"({"method": "robot.arm.add", "params": [1, 2], "id": 7})",
        R"({"jsonrpc": "2.0", "id": 7})",
        R"({"jsonrpc": "2.0", "method": "robot.arm.add", "params": 3, "id": 7})"}) {
    r = round_trip(*client_, line);
    EXPECT_EQ(error_code(r), -32600) << line << " -> " << r.dump();
    EXPECT_EQ(r["id"], 7) << line;
  }
  // an id that is neither string, number nor null
  r = round_trip(
      *client_,
      R"({"jsonrpc": "2.0", "method": "robot.arm.add", "params": [1, 2], "id": {"a": 1}})");
  EXPECT_EQ(error_code(r), -32600);
  EXPECT_TRUE(r["id"].is_null());
  r = round_trip(*client_, R"("just a string")");
  EXPECT_EQ(error_code(r), -32600);
}

TEST_F(JsonRpcConformance, BatchWithInvalidJson) {
  auto r = round_trip(
      *client_,
      R"([{"jsonrpc": "2.0", "method": "spec.sum", "params": [1,2,4], "id": "1"}, {"jsonrpc": "2.0", "method"])");
  ASSERT_TRUE(r.is_object()) << r.dump();
  EXPECT_EQ(error_code(r), -32700);
}

TEST_F(JsonRpcConformance, EmptyBatch) {
  auto r = round_trip(*client_, "[]");
  ASSERT_TRUE(r.is_object()) << r.dump();
  EXPECT_EQ(error_code(r), -32600);
  EXPECT_TRUE(r["id"].is_null());
}

TEST_F(JsonRpcConformance, BatchOfInvalidEntries) {
  auto r = round_trip(*client_, "[1]");
  ASSERT_TRUE(r.is_array()) << r.dump();
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(error_code(r[0]), -32600);
  r = round_trip(*client_, "[1,2,3]");
  ASSERT_TRUE(r.is_array()) << r.dump();
  ASSERT_EQ(r.size(), 3u);
  for (const auto& e : r) {
    EXPECT_EQ(error_code(e), -32600);
    EXPECT_TRUE(e["id"].is_null());
  }
}

TEST_F(JsonRpcConformance, MixedBatch) {
  auto r = round_trip(*client_, one_line(R"([
    {"jsonrpc": "2.0", "method": "spec.sum", "params": [1,2,4], "id": "1"},
    {"jsonrpc": "2.0", "method": "spec.notify_hello", "params": [7]},
    {"jsonrpc": "2.0", "method": "spec.subtract", "params": [42,23], "id": "2"},
    {"foo": "boo"},
    {"jsonrpc": "2.0", "method": "spec.foo.get", "params": {"name": "myself"}, "id": "5"},
    {"jsonrpc": "2.0", "method": "spec.get_data", "id": "9"}
  ])"));
  ASSERT_TRUE(r.is_array()) << r.dump();
  ASSERT_EQ(r.size(), 5u) << r.dump();
  std::map<std::string, json> by_id;
  for (const auto& e : r) by_id[e["id"].is_null() ? "null" : e["id"].get<std::string>()] = e;
  EXPECT_EQ(by_id["1"]["result"], 7);
  EXPECT_EQ(by_id["2"]["result"], 19);
  EXPECT_EQ(error_code(by_id["null"]), -32600);
  EXPECT_EQ(error_code(by_id["5"]), -32601);
  EXPECT_EQ(by_id["9"]["result"], json::parse(R"(["hello", 5])"));
}

TEST_F(JsonRpcConformance, BatchOfNotificationsReturnsNothing) {
  client_->send_line(
      one_line(R"([{"jsonrpc": "2.0", "method": "spec.notify_sum", "params": [1,2,4]},
                         {"jsonrpc": "2.0", "method": "spec.notify_hello", "params": [7]}])"));
  auto r = client_->request("robot.arm.add", json::array({1, 1}), k_timeout);
  EXPECT_EQ(r["result"], 2.0);
  EXPECT_FALSE(client_->receive(100ms).has_value());
}

TEST_F(JsonRpcConformance, BatchRunsWithinOneProcessCall) {
  std::string batch = "[";
  for (int i = 0; i < 8; ++i)
    batch += std::string(i ? "," : "") + R"({"jsonrpc":"2.0","method":"ctl.iteration","id":)" +
             std::to_string(i) + "}";
  batch += "]";
  auto r = round_trip(*client_, batch);
  ASSERT_TRUE(r.is_array()) << r.dump();
  ASSERT_EQ(r.size(), 8u);
  for (const auto& e : r) EXPECT_EQ(e["result"], r[0]["result"]) << r.dump();
}

// ---- framing

TEST_F(JsonRpcConformance, CrLfAndSplitFramesAndSeveralPerWrite) {
  client_->send_raw(
      "{\"jsonrpc\":\"2.0\",\"method\":\"robot.arm.add\",\"params\":[1,2],\"id\":1}\r\n");
  EXPECT_EQ(next(*client_)["result"], 3.0);
  // one message in three writes
  client_->send_raw("{\"jsonrpc\":\"2.0\",\"met");
  client_->send_raw("hod\":\"robot.arm.add\",\"params\":[2,");
  EXPECT_FALSE(client_->receive(50ms).has_value());
  client_->send_raw("3],\"id\":2}\n");
  EXPECT_EQ(next(*client_)["result"], 5.0);
  // three messages in one write, with blank keep-alive lines between them
  client_->send_raw(
      "{\"jsonrpc\":\"2.0\",\"method\":\"robot.arm.add\",\"params\":[1,1],\"id\":3}\n\n"
      "{\"jsonrpc\":\"2.0\",\"method\":\"robot.arm.add\",\"params\":[1,2],\"id\":4}\r\n \n"
      "{\"jsonrpc\":\"2.0\",\"method\":\"robot.arm.add\",\"params\":[1,3],\"id\":5}\n");
  std::map<int, double> results;
  for (int i = 0; i < 3; ++i) {
    auto r = next(*client_);
    results[r["id"].get<int>()] = r["result"].get<double>();
  }
  EXPECT_EQ(results, (std::map<int, double>{{3, 2.0}, {4, 3.0}, {5, 4.0}}));
}

// ---- params and service errors

TEST_F(JsonRpcConformance, InvalidParams) {
  // arity
  auto r = client_->request("spec.subtract", json::array({1}), k_timeout);
  EXPECT_EQ(error_code(r), -32602) << r.dump();
  EXPECT_EQ(r["error"]["data"]["component"], "spec");
  EXPECT_EQ(r["error"]["data"]["service"], "subtract");
  // type: the data names the parameter
  r = client_->request("spec.subtract", json::array({1, "two"}), k_timeout);
  EXPECT_EQ(error_code(r), -32602) << r.dump();
  EXPECT_NE(r["error"]["message"].get<std::string>().find("subtrahend"), std::string::npos)
      << r.dump();
  // unknown name
  r = client_->request("spec.subtract", {{"minuend", 1}, {"subtrahen", 2}}, k_timeout);
  EXPECT_EQ(error_code(r), -32602) << r.dump();
  EXPECT_EQ(r["error"]["data"]["parameter"], "subtrahen");
  // rpc.cancel without an id
  r = client_->request("rpc.cancel", json::object(), k_timeout);
  EXPECT_EQ(error_code(r), -32602) << r.dump();
}

TEST_F(JsonRpcConformance, ServiceFailureAndInternalError) {
  auto r = client_->request("robot.arm.fail", json::array({"gripper jammed"}), k_timeout);
  EXPECT_EQ(error_code(r), -32000) << r.dump();
  EXPECT_EQ(r["error"]["data"]["message"], "gripper jammed");
  EXPECT_EQ(r["error"]["data"]["status"], "FAILED");
  r = client_->request("robot.arm.crash", nullptr, k_timeout);
  EXPECT_EQ(error_code(r), -32603) << r.dump();
  // the connection keeps serving
  EXPECT_EQ(client_->request("robot.arm.add", json::array({2, 2}), k_timeout)["result"], 4.0);
}

TEST_F(JsonRpcConformance, StringAndNullIdsEchoed) {
  auto r = round_trip(*client_,
                      R"({"jsonrpc":"2.0","method":"robot.arm.add","params":[1,2],"id":"abc"})");
  EXPECT_EQ(r["id"], "abc");
  r = round_trip(*client_,
                 R"({"jsonrpc":"2.0","method":"robot.arm.add","params":[1,2],"id":null})");
  EXPECT_TRUE(r.contains("id") && r["id"].is_null()) << r.dump();
  EXPECT_EQ(r["result"], 3.0);
  r = round_trip(*client_, R"({"jsonrpc":"2.0","method":"robot.arm.add","params":[1,2],"id":2.5})");
  EXPECT_EQ(r["id"], 2.5);
}

// ---- discovery

using JsonRpcDiscovery = JsonRpcFixture;

TEST_F(JsonRpcDiscovery, OpenRpcDocumentListsExactlyTheServedServices) {
  auto doc = client_->discover(k_timeout);
  EXPECT_EQ(doc["openrpc"], "1.2.6");
  std::set<std::string> names;
  for (const auto& m : doc["methods"]) names.insert(m["name"].get<std::string>());
  std::set<std::string> expected;
  for (const auto& d : host_->manager().descriptors()) expected.insert(d.qualified_name());
  EXPECT_EQ(names, expected);
  EXPECT_EQ(names.count("robot.arm.add"), 1u);
  EXPECT_EQ(names.count("rpc.discover"), 0u);

  auto find = [&](const std::string& name) {
    for (const auto& m : doc["methods"])
      if (m["name"] == name) return m;
    return json();
  };
  auto add = find("robot.arm.add");
  EXPECT_EQ(add["x-component"], "robot.arm");
  EXPECT_EQ(add["x-service"], "add");
  EXPECT_EQ(add["x-async"], false);
  EXPECT_EQ(add["description"], "a + b");
  ASSERT_EQ(add["params"].size(), 2u);
  EXPECT_EQ(add["params"][0]["name"], "a");
  EXPECT_EQ(add["params"][0]["schema"]["type"], "number");
  EXPECT_EQ(add["params"][0]["required"], true);

  auto greet = find("robot.arm.greet");
  EXPECT_EQ(greet["params"][1]["required"], false);
  EXPECT_EQ(greet["params"][1]["schema"]["default"], "hello");
  EXPECT_EQ(greet["params"][1]["schema"]["type"], "string");

  EXPECT_EQ(find("robot.arm.hold")["x-async"], true);
  EXPECT_EQ(find("robot.arm.hold")["x-interruptible"], true);
  EXPECT_EQ(find("robot.base.hold")["x-interruptible"], false);
  EXPECT_EQ(find("robot.base.hold")["x-policy"], "noninterruptible");
  EXPECT_EQ(find("robot.cam.hold")["x-policy"], "unspecified");
}

TEST(JsonRpcDiscoveryScope, ServicesOfOtherManagersAreNeitherListedNorCallable) {
  // a second manager in the same process serves "hidden"; ours must not see it
  auto other = load_transport(TestHost::default_plugin_path(), {{"port", 0}});
  other->register_service("hidden", [] { return 42; }, "secret");
  TestHost host;
  JsonRpcClient c("127.0.0.1", host.port());
  const json doc = c.discover(k_timeout);
  for (const auto& m : doc["methods"]) EXPECT_NE(m["x-component"], "hidden") << m.dump();
  EXPECT_EQ(error_code(c.request("hidden.secret", nullptr, k_timeout)), -32601);
  other->stop();
}

// ---- the C++ client (make_client, Outcome mapping)

using JsonRpcClientTest = JsonRpcFixture;

TEST_F(JsonRpcClientTest, MakeClientCallsAndMapsErrors) {
  auto c = client::make_client("jsonrpc", {{"host", "127.0.0.1"}, {"port", host_->port()}});
  auto ok = c->call("robot.arm", "add", json::array({2, 3}), k_timeout);
  EXPECT_EQ(ok.status, Status::success);
  EXPECT_EQ(ok.value, json(5.0));
  auto failed = c->call("robot.arm", "fail", json::array({"no"}), k_timeout);
  EXPECT_EQ(failed.status, Status::failed);
  EXPECT_EQ(failed.failure, Failure::service_error);
  EXPECT_EQ(c->call("robot.nothing", "add", nullptr, k_timeout).failure, Failure::unknown_service);
  EXPECT_EQ(c->call("robot.arm", "add", json::array({1}), k_timeout).failure,
            Failure::bad_arguments);
}

TEST_F(JsonRpcClientTest, ListServicesMatchesDescriptors) {
  auto listed = client_->list_services(k_timeout);
  auto descriptors = host_->manager().descriptors();
  ASSERT_EQ(listed.size(), descriptors.size());
  for (const auto& d : descriptors) {
    auto expected = d.to_json();
    auto it = std::find_if(listed.begin(), listed.end(), [&](const json& l) {
      return l["component"] == d.component && l["name"] == d.name;
    });
    ASSERT_NE(it, listed.end()) << d.qualified_name();
    EXPECT_EQ((*it)["async"], expected["async"]);
    EXPECT_EQ((*it)["params"], expected["params"]) << d.qualified_name();
    EXPECT_EQ((*it)["doc"], expected["doc"]);
    if (d.is_async) {
      EXPECT_EQ((*it)["policy"], expected["policy"]);
    }
  }
}

TEST_F(JsonRpcClientTest, ConnectFailureIsClientError) {
  const auto port = host_->port();
  host_.reset();  // nobody listens there any more
  EXPECT_THROW(JsonRpcClient("127.0.0.1", port, 2000ms), client::ClientError);
}

}  // namespace
}  // namespace simgate::jsonrpc_test
