// Test support for the DDS transport: a server (the real plugin, loaded with dlopen) with
// test services, served by a small simulation thread; a raw Cyclone client for wire-level
// cases; unique domains and partitions so parallel test processes never talk to each other.
// Cyclone always runs with config/dds/loopback.xml (loopback only, multicast off).
#ifndef SIMGATE_TESTS_DDS_DDS_TEST_SUPPORT_H_
#define SIMGATE_TESTS_DDS_DDS_TEST_SUPPORT_H_

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "simgate/core/plugin_loader.h"
#include "simgate/core/request_manager.h"

namespace simgate::dds::test {

using namespace std::chrono_literals;

// One domain per test process (tests of one binary run in separate processes under ctest).
inline uint32_t test_domain() { return 20 + static_cast<uint32_t>(getpid() % 200); }

// "simgate-test-<pid>-<test name>[-suffix]".
inline std::string test_partition(const std::string& suffix = "") {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = info ? std::string(info->test_suite_name()) + "." + info->name() : "none";
  return "simgate-test-" + std::to_string(getpid()) + "-" + name +
         (suffix.empty() ? "" : "-" + suffix);
}

inline std::string loopback_uri() { return std::string("file://") + SIMGATE_LOOPBACK_DDS_XML; }

inline json server_options(const std::string& partition, json extra = json::object()) {
  json options = {{"domain", test_domain()}, {"partition", partition}, {"config", loopback_uri()}};
  options.update(extra);
  return options;
}

inline json client_options(const std::string& partition) {
  return {{"domain", test_domain()}, {"partition", partition}, {"config", loopback_uri()}};
}

// Waits up to `timeout` for `condition`, checking every millisecond.
inline bool eventually(const std::function<bool()>& condition,
                       std::chrono::milliseconds timeout = 10s) {
  auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!condition()) {
    if (std::chrono::steady_clock::now() >= deadline) return false;
    std::this_thread::sleep_for(1ms);
  }
  return true;
}

// The simulation thread of a test: process() in a loop until destroyed.
class SimThread {
 public:
  explicit SimThread(std::shared_ptr<RequestManager> manager) : manager_(std::move(manager)) {
    manager_->start();
    thread_ = std::thread([this] {
      while (!stop_) manager_->process(5ms);
    });
  }
  ~SimThread() {
    stop_ = true;
    thread_.join();
  }

 private:
  std::shared_ptr<RequestManager> manager_;  // the transport under test
  std::atomic<bool> stop_{false};            // ends the loop
  std::thread thread_;                       // runs process()
};

// The async service of a test: remembers its Completion so the test can finish it.
struct AsyncProbe {
  std::mutex mutex;            // guards the fields below
  std::condition_variable cv;  // a start
  int started = 0;             // how many calls started
  Completion last;             // the latest call's completion

  void on_start(const Completion& c) {
    std::lock_guard lock(mutex);
    ++started;
    last = c;
    cv.notify_all();
  }
  bool wait_started(int n, std::chrono::milliseconds timeout = 10s) {
    std::unique_lock lock(mutex);
    return cv.wait_for(lock, timeout, [&] { return started >= n; });
  }
  Completion completion() {
    std::lock_guard lock(mutex);
    return last;
  }
};

}  // namespace simgate::dds::test

#endif  // SIMGATE_TESTS_DDS_DDS_TEST_SUPPORT_H_
