// tests/jsonrpc/test_util.h — small helpers shared by the JSON-RPC tests: a fixture with a
// running TestHost, raw-line round trips with deadlines, and error matchers.
#ifndef SIMGATE_TESTS_JSONRPC_TEST_UTIL_H_
#define SIMGATE_TESTS_JSONRPC_TEST_UTIL_H_

#include <chrono>
#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "simgate/client/jsonrpc_client.h"
#include "test_services.h"

namespace simgate::jsonrpc_test {

using client::JsonRpcClient;
using namespace std::chrono_literals;

// Every wait in these tests is bounded by this (generous for sanitizer builds).
inline constexpr auto k_timeout = std::chrono::milliseconds(10000);

// The next message on `c`, failing the test on timeout.
inline json next(JsonRpcClient& c) {
  auto m = c.receive(k_timeout);
  if (!m) {
    ADD_FAILURE() << "no message within " << k_timeout.count() << " ms";
    return json();
  }
  return *m;
}

// Joins a multi-line literal into one line (one message per line on the wire).
inline std::string one_line(std::string text) {
  for (char& c : text)
    if (c == '\n') c = ' ';
  return text;
}

// Sends one raw line and returns the next message.
inline json round_trip(JsonRpcClient& c, const std::string& line) {
  c.send_line(line);
  return next(c);
}

// The error code of a response (0 when it is a result).
inline int error_code(const json& response) {
  if (!response.is_object() || !response.contains("error")) return 0;
  return response["error"].value("code", 0);
}

// A running host plus one connected client.
class JsonRpcFixture : public ::testing::Test {
 protected:
  virtual json options() { return json::object(); }
  void SetUp() override {
    host_ = std::make_unique<TestHost>(options());
    client_ = connect();
  }
  void TearDown() override {
    client_.reset();
    host_.reset();
  }
  std::unique_ptr<JsonRpcClient> connect() {
    return std::make_unique<JsonRpcClient>("127.0.0.1", host_->port());
  }
  // A sync round trip on `c`: when it returns, every call sent on `c` before it has started
  // (requests of one connection reach the simulation thread in order).
  void barrier(JsonRpcClient& c) {
    auto r = c.request("ctl.iteration", nullptr, k_timeout);
    ASSERT_TRUE(r.contains("result")) << r.dump();
  }

  std::unique_ptr<TestHost> host_;         // the server
  std::unique_ptr<JsonRpcClient> client_;  // a connected client
};

}  // namespace simgate::jsonrpc_test

#endif  // SIMGATE_TESTS_JSONRPC_TEST_UTIL_H_
