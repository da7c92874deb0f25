// example_transport.h — what the tests of docs/examples' transports share: one of them
// loaded with dlopen from build/example-plugins, serving test.add and test.fail, with a
// thread standing in for the simulation's (process()), and the page that shows its file.
#ifndef SIMGATE_TESTS_KIT_EXAMPLE_TRANSPORT_H_
#define SIMGATE_TESTS_KIT_EXAMPLE_TRANSPORT_H_

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <thread>

#include "simgate/core/errors.h"
#include "simgate/core/plugin_loader.h"
#include "simgate/core/request_manager.h"

namespace simgate::testing {

inline std::string read_file(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

class ExampleTransportTest : public ::testing::Test {
 protected:
  // `name`: the plugin's ("line" for libsimgate_transport_line.so); `options` its options.
  ExampleTransportTest(std::string name, json options)
      : name_(std::move(name)), options_(std::move(options)) {}

  void SetUp() override {
    plugin_ = load_transport_plugin(std::string(SIMGATE_TEST_EXAMPLE_PLUGIN_DIR) +
                                    "/libsimgate_transport_" + name_ + ".so");
    manager_ = plugin_->create(options_, "transports." + name_);
    manager_->register_service("test", [](int a, int b) { return a + b; }, "add", {"a", "b"});
    manager_->register_service("test", [](std::string m) -> json { throw ServiceError(m); }, "fail",
                               {"message"});
    manager_->start();
    // "tcp://127.0.0.1:PORT", "ws://127.0.0.1:PORT/"
    const std::string endpoint = manager_->endpoints().at(0);
    const std::string address = endpoint.substr(0, endpoint.find_last_not_of('/') + 1);
    port_ = static_cast<std::uint16_t>(std::stoi(address.substr(address.rfind(':') + 1)));
    // the simulation thread: runs what the I/O thread could not run at once
    loop_ = std::thread([this] {
      while (!stop_.load()) manager_->process(std::chrono::milliseconds(50));
    });
  }
  void TearDown() override {
    stop_ = true;
    manager_->gate()->signal();
    loop_.join();
    manager_->stop();
  }

  std::string name_;
  json options_;
  std::shared_ptr<TransportPlugin> plugin_;
  std::shared_ptr<RequestManager> manager_;
  std::uint16_t port_ = 0;
  std::atomic<bool> stop_{false};
  std::thread loop_;
};

// Whether docs/writing-a-transport.md shows `example` (a file of docs/examples) verbatim.
inline ::testing::AssertionResult the_page_shows(const std::string& example) {
  const std::string page =
      read_file(std::string(SIMGATE_SOURCE_DIR) + "/docs/writing-a-transport.md");
  const std::string file = read_file(std::string(SIMGATE_SOURCE_DIR) + "/docs/examples/" + example);
  if (file.empty())
    return ::testing::AssertionFailure() << "docs/examples/" << example << " cannot be read";
  if (page.find("```cpp\n" + file + "```\n") == std::string::npos)
    return ::testing::AssertionFailure()
           << "docs/writing-a-transport.md must show docs/examples/" << example << " verbatim";
  return ::testing::AssertionSuccess();
}

}  // namespace simgate::testing

#endif  // SIMGATE_TESTS_KIT_EXAMPLE_TRANSPORT_H_
