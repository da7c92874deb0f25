// socket_test_fixture.h — loads the real socket plugin, registers test services by hand and
// runs a process() loop, so tests talk to it over real TCP (127.0.0.1, ephemeral port).
//
// Services (all free functions registered on the manager, as in MORSE's standalone use):
//   test_component add(a, b)        Python-like a + b (numbers, strings, lists)
//   test echo(x)                    returns x (falsy values included)
//   test nothing()                  returns nothing (void)
//   test none()                     returns null
//   test scale(x: number)           2 * x (typed: a string is a type error)
//   test fail(message)              throws ServiceError(message)
//   test crash()                    throws std::runtime_error
//   test big(n)                     a string of n 'x'
//   worker hold(token)              async, interruptible; ends on `worker release`
//   worker release(value)           completes worker's held request with SUCCESS value
//   strict hold(token)              async, non-interruptible; `strict release` ends it
//   plain hold(token)               async, no local policy; `plain release` ends it
// Threads: the loop thread runs process(); the test thread only does I/O and setup.
#ifndef SIMGATE_TESTS_SOCKET_SOCKET_TEST_FIXTURE_H_
#define SIMGATE_TESTS_SOCKET_SOCKET_TEST_FIXTURE_H_

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "simgate/client/socket_client.h"
#include "simgate/core/errors.h"
#include "simgate/core/plugin_loader.h"
#include "simgate/core/request_manager.h"

namespace simgate::socket::test {

using namespace std::chrono_literals;
using client::SocketClient;

// Python's a + b for the JSON values MORSE's `add` example would see.
inline json python_add(const json& a, const json& b) {
  if (a.is_number_integer() && b.is_number_integer())
    return a.get<std::int64_t>() + b.get<std::int64_t>();
  if (a.is_number() && b.is_number()) return a.get<double>() + b.get<double>();
  if (a.is_string() && b.is_string()) return a.get<std::string>() + b.get<std::string>();
  if (a.is_array() && b.is_array()) {
    json out = a;
    for (const auto& e : b) out.push_back(e);
    return out;
  }
  throw ServiceError("unsupported operand types for +: " + describe_json(a) + " and " +
                     describe_json(b));
}

class SocketFixture : public ::testing::Test {
 protected:
  void TearDown() override { shutdown(); }

  // Loads the plugin and starts the transport with `options` (port 0 unless given).
  void start_server(json options = json::object()) {
    plugin_ = load_transport_plugin(std::string(SIMGATE_TEST_PLUGIN_DIR) +
                                    "/libsimgate_transport_socket.so");
    if (!options.contains("port")) options["port"] = 0;
    manager_ = plugin_->create(options, "transports.socket");
    register_services(*manager_);
    register_more(*manager_);
    manager_->start();
    const std::string endpoint = manager_->endpoints().at(0);
    port_ = static_cast<std::uint16_t>(std::stoi(endpoint.substr(endpoint.rfind(':') + 1)));
    loop_ = std::thread([this] {
      while (!stop_.load()) manager_->process(50ms);
    });
  }

  void shutdown() {
    if (loop_.joinable()) {
      stop_ = true;
      manager_->gate()->signal();
      loop_.join();
    }
    if (manager_) manager_->stop();
    manager_.reset();
  }

  std::unique_ptr<SocketClient> connect() {
    return std::make_unique<SocketClient>("127.0.0.1", port_);
  }

  // The next line, failing the test after a deadline.
  static std::string next_line(SocketClient& c, std::chrono::milliseconds timeout = 10s) {
    auto line = c.read_line(timeout);
    if (!line) throw std::runtime_error("no reply within the deadline");
    return *line;
  }
  // Sends one line, returns the next line received.
  static std::string roundtrip(SocketClient& c, const std::string& line) {
    c.send_line(line);
    return next_line(c);
  }
  // The next n lines, as a set (for replies whose order is not specified).
  static std::multiset<std::string> next_lines(SocketClient& c, std::size_t n) {
    std::multiset<std::string> out;
    for (std::size_t i = 0; i < n; ++i) out.insert(next_line(c));
    return out;
  }

  // A fixture's own services, registered after the common ones.
  virtual void register_more(RequestManager& /*rm*/) {}

  static void register_services(RequestManager& rm) {
    rm.register_service("test_component", [](json a, json b) { return python_add(a, b); }, "add",
                        {"a", "b"});
    rm.register_service("test", [](json x) { return x; }, "echo", {"x"});
    rm.register_service("test", [] {}, "nothing");
    rm.register_service("test", [] { return json(nullptr); }, "none");
    rm.register_service("test", [](double x) { return 2 * x; }, "scale", {"x"});
    rm.register_service("test", [](std::string m) -> json { throw ServiceError(m); }, "fail",
                        {"message"});
    rm.register_service("test", []() -> json { throw std::runtime_error("boom"); }, "crash");
    rm.register_service("test", [](int n) { return std::string(std::size_t(n), 'x'); }, "big",
                        {"n"});
    rm.register_service("test", [] { return std::string("pong"); }, "ping");

    // async components: the held completion is touched only on the process() thread
    for (const char* component : {"worker", "strict", "plain"}) {
      auto held = std::make_shared<Completion>();
      auto builder = rm.register_async_service(component,
                                               [held](Completion c, json /*token*/) {
                                                 *held = c;
                                                 return true;
                                               },
                                               "hold", {"token"});
      if (std::string(component) == "worker") builder.interruptible();
      if (std::string(component) == "strict") builder.noninterruptible();
      rm.register_service(component,
                          [held](json value) {
                            bool done = (*held)(Status::success, value);
                            *held = Completion();
                            return done;
                          },
                          "release", {"value"});
    }
  }

  std::shared_ptr<TransportPlugin> plugin_;  // keeps the library loaded
  std::shared_ptr<RequestManager> manager_;  // the transport under test
  std::uint16_t port_ = 0;                   // its ephemeral port
  std::thread loop_;                         // runs process()
  std::atomic<bool> stop_{false};            // ends loop_
};

}  // namespace simgate::socket::test

#endif  // SIMGATE_TESTS_SOCKET_SOCKET_TEST_FIXTURE_H_
