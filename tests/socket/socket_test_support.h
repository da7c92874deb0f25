// socket_test_support.h — helpers shared by the socket transport's test files
// (socket_connections_test.cc, tcp_transport_test.cc).
#ifndef SIMGATE_TESTS_SOCKET_SOCKET_TEST_SUPPORT_H_
#define SIMGATE_TESTS_SOCKET_SOCKET_TEST_SUPPORT_H_

#include <algorithm>
#include <cstddef>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "simgate/core/log.h"

namespace simgate::socket::test {

// The warnings logged while it lives, from any thread.
class WarningLog {
 public:
  WarningLog() {
    log::set_sink([this](log::Level level, std::string_view message) {
      if (level < log::Level::warning) return;
      std::lock_guard lock(mutex_);
      lines_.emplace_back(message);
    });
  }
  ~WarningLog() { log::set_sink({}); }
  // How many warnings contain `text`.
  std::size_t count(const std::string& text) const {
    std::lock_guard lock(mutex_);
    return std::size_t(std::count_if(lines_.begin(), lines_.end(), [&](const std::string& l) {
      return l.find(text) != std::string::npos;
    }));
  }
  std::vector<std::string> lines() const {
    std::lock_guard lock(mutex_);
    return lines_;
  }

 private:
  mutable std::mutex mutex_;        // guards lines_ (the sink runs on the logging thread)
  std::vector<std::string> lines_;  // warnings and errors, in order
};

}  // namespace simgate::socket::test

#endif  // SIMGATE_TESTS_SOCKET_SOCKET_TEST_SUPPORT_H_
