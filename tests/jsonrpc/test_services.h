// tests/jsonrpc/test_services.h — the services the JSON-RPC tests call, and a host that
// serves them through the jsonrpc plugin with a simulation-thread loop of its own.
//
// Services (free functions, registered by hand as in MORSE's standalone example):
//   spec.*       the JSON-RPC 2.0 specification's examples (subtract, sum, update,
//                notify_hello, notify_sum, get_data)
//   robot.arm.*  sync: add, fail (ServiceError), crash (std::runtime_error), echo, greet
//                (named parameter with a default), blob (a long string)
//   robot.arm.hold, robot.base.hold, robot.cam.hold: async, finished by ctl.release;
//                interruptible, non-interruptible and without local policy respectively
//   ctl.*        release(key, value), release_fail(key, message), pending(key) (true while
//                the held call runs), progress(key, value) (a progress report of the held
//                call: true when passed on), mark(key)/marked(key), iteration() (process()
//                count)
//
// Threads: every service runs under the simulation lock (SimulationGate): on the host's
// simulation thread (the one calling process()) or on the transport's I/O thread when it
// runs its requests itself (run_or_submit). The shared state is touched only under that
// lock; the host's loop takes it to count iterations.
#ifndef SIMGATE_TESTS_JSONRPC_TEST_SERVICES_H_
#define SIMGATE_TESTS_JSONRPC_TEST_SERVICES_H_

#include <atomic>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>

#include "simgate/core/errors.h"
#include "simgate/core/plugin_loader.h"
#include "simgate/core/request_manager.h"

namespace simgate::jsonrpc_test {

// State shared by the services (under the simulation lock only).
struct ServiceState {
  std::map<std::string, Completion> held;  // key -> the async call waiting for release
  std::set<std::string> marks;             // keys set by ctl.mark
  std::uint64_t iteration = 0;             // process() calls so far
};

inline void register_test_services(RequestManager& rm, const std::shared_ptr<ServiceState>& state) {
  // the specification's examples
  rm.register_service("spec", [](int minuend, int subtrahend) { return minuend - subtrahend; },
                      "subtract", {"minuend", "subtrahend"})
      .doc("minuend - subtrahend");
  rm.register_service("spec", [](int a, int b, int c) { return a + b + c; }, "sum",
                      {"a", "b", "c"});
  rm.register_service("spec", [](int, int, int, int, int) {}, "update", {"a", "b", "c", "d", "e"});
  rm.register_service("spec", [](int) {}, "notify_hello", {"value"});
  rm.register_service("spec", [](int, int, int) {}, "notify_sum", {"a", "b", "c"});
  rm.register_service("spec", [] { return json::array({"hello", 5}); }, "get_data");

  // sync services of a component whose name contains a dot
  rm.register_service("robot.arm", [](double a, double b) { return a + b; }, "add", {"a", "b"})
      .doc("a + b");
  rm.register_service("robot.arm", [](std::string message) -> int { throw ServiceError(message); },
                      "fail", {"message"});
  rm.register_service(
      "robot.arm", []() -> int { throw std::runtime_error("unexpected crash"); }, "crash");
  rm.register_service("robot.arm", [](json value) { return value; }, "echo", {"value"});
  rm.register_service("robot.arm",
                      [](std::string name, std::string greeting) { return greeting + ", " + name; },
                      "greet", {"name", {"greeting", std::string("hello")}});
  rm.register_service("robot.arm",
                      [](int n) { return std::string(static_cast<std::size_t>(n), 'x'); }, "blob",
                      {"n"});

  // async services, finished by ctl.release
  auto hold = [state](Completion c, std::string key) { state->held[key] = c; };
  rm.register_async_service("robot.arm", hold, "hold", {"key"})
      .interruptible()
      .doc("waits for ctl.release");
  rm.register_async_service("robot.base", hold, "hold", {"key"}).noninterruptible();
  rm.register_async_service("robot.cam", hold, "hold", {"key"});

  rm.register_service("ctl",
                      [state](std::string key, json value) {
                        auto it = state->held.find(key);
                        if (it == state->held.end()) return false;
                        return it->second(Status::success, value);
                      },
                      "release", {"key", {"value", json(nullptr)}});
  rm.register_service("ctl",
                      [state](std::string key, std::string message) {
                        auto it = state->held.find(key);
                        if (it == state->held.end()) return false;
                        return it->second(Status::failed, message);
                      },
                      "release_fail", {"key", "message"});
  rm.register_service("ctl",
                      [state](std::string key) {
                        auto it = state->held.find(key);
                        return it != state->held.end() && !it->second.done();
                      },
                      "pending", {"key"});
  rm.register_service("ctl",
                      [state](std::string key, json value) {
                        auto it = state->held.find(key);
                        return it != state->held.end() && it->second.progress(value);
                      },
                      "progress", {"key", "value"});
  rm.register_service("ctl", [state](std::string key) { state->marks.insert(key); }, "mark",
                      {"key"});
  rm.register_service("ctl", [state](std::string key) { return state->marks.count(key) > 0; },
                      "marked", {"key"});
  rm.register_service("ctl", [state] { return state->iteration; }, "iteration");
}

// Loads the plugin, registers the services, runs process() on a thread of its own.
class TestHost {
 public:
  explicit TestHost(json options = json::object(),
                    const std::string& plugin_path = default_plugin_path()) {
    if (!options.contains("port")) options["port"] = 0;
    rm_ = load_transport(plugin_path, options);
    register_test_services(*rm_, state_);
    rm_->start();
    const auto endpoint = rm_->endpoints().at(0);
    port_ = static_cast<std::uint16_t>(std::stoi(endpoint.substr(endpoint.rfind(':') + 1)));
    sim_ = std::thread([this] {
      while (!quit_.load()) {
        rm_->process(std::chrono::milliseconds(20));
        // services also run on the transport's I/O thread (run_or_submit), under the lock
        std::lock_guard lock(*rm_->gate());
        ++state_->iteration;
      }
    });
  }
  ~TestHost() { stop(); }
  TestHost(const TestHost&) = delete;
  TestHost& operator=(const TestHost&) = delete;

  void stop() {
    quit_ = true;
    if (sim_.joinable()) sim_.join();
    if (rm_) rm_->stop();
  }

  std::uint16_t port() const { return port_; }
  RequestManager& manager() { return *rm_; }

  static std::string default_plugin_path() {
#ifdef SIMGATE_TEST_PLUGIN_DIR
    return std::string(SIMGATE_TEST_PLUGIN_DIR) + "/libsimgate_transport_jsonrpc.so";
#else
    return "jsonrpc";
#endif
  }

 private:
  std::shared_ptr<ServiceState> state_ = std::make_shared<ServiceState>();  // services' state
  std::shared_ptr<RequestManager> rm_;                                      // the plugin's manager
  std::uint16_t port_ = 0;                                                  // bound port
  std::atomic<bool> quit_{false};  // ends the simulation loop
  std::thread sim_;                // the simulation thread
};

}  // namespace simgate::jsonrpc_test

#endif  // SIMGATE_TESTS_JSONRPC_TEST_SERVICES_H_
