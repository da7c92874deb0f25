// The process-wide log's rate limit: a flood of lines cannot fill a disk (issue #17, item 9:
// 20 000 refused connections wrote 2 MB), and what was dropped is said.
#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

#include "simgate/core/log.h"

namespace simgate {
namespace {

class LogRateLimitTest : public ::testing::Test {
 protected:
  void SetUp() override {
    log::set_sink([this](log::Level level, std::string_view message) {
      lines_.emplace_back(level, message);
    });
  }
  void TearDown() override {
    log::set_rate_limit(200, 50);  // the defaults
    log::set_level(log::Level::info);
    log::set_sink({});
  }
  std::vector<std::pair<log::Level, std::string>> lines_;
};

TEST_F(LogRateLimitTest, AFloodIsCutAtTheBurstAndCountedBeforeTheNextLine) {
  log::set_rate_limit(10, 1e-6);  // no refill within the test
  for (int i = 0; i < 20000; ++i) log::warning("refused a connection from 127.0.0.1:", i);
  ASSERT_EQ(lines_.size(), 10u);
  EXPECT_EQ(lines_.back().second, "refused a connection from 127.0.0.1:9");
  log::set_rate_limit(10, 1e-6);  // full again
  log::error("the next line");
  ASSERT_EQ(lines_.size(), 12u);
  EXPECT_EQ(lines_[10].first, log::Level::warning);
  EXPECT_EQ(lines_[10].second, "log: 19990 lines suppressed (more than 1e-06 a second)");
  EXPECT_EQ(lines_[11].second, "the next line");
}

TEST_F(LogRateLimitTest, DebugLinesAskedForAreNeverDropped) {
  log::set_level(log::Level::debug);
  log::set_rate_limit(1, 1e-6);
  for (int i = 0; i < 100; ++i) log::debug("line ", i);
  EXPECT_EQ(lines_.size(), 100u);
}

TEST_F(LogRateLimitTest, ABurstOfZeroMeansNoLimit) {
  log::set_rate_limit(0, 0);
  for (int i = 0; i < 5000; ++i) log::info("line ", i);
  EXPECT_EQ(lines_.size(), 5000u);
}

TEST_F(LogRateLimitTest, ObserversSeeWhatTheSinkGetsUntilTheyAreRemoved) {
  std::vector<std::string> seen;
  const std::uint64_t handle = log::add_observer([&](log::Level level, std::string_view message) {
    seen.push_back(std::string(log::to_string(level)) + " " + std::string(message));
  });
  log::debug("not asked for");  // below the level: neither the sink nor the observer
  log::warning("a wheel slips");
  log::set_rate_limit(1, 1e-6);
  log::info("passes");
  log::info("suppressed");  // cut by the rate limit: neither
  log::set_rate_limit(0, 0);
  log::error("and the note of what was cut before it");
  log::remove_observer(handle);
  log::error("after the removal");
  EXPECT_EQ(seen,
            (std::vector<std::string>{"warning a wheel slips", "info passes",
                                      "warning log: 1 lines suppressed (more than 0 a second)",
                                      "error and the note of what was cut before it"}));
  EXPECT_EQ(lines_.size(), 5u);  // the sink: the same four, and the line after the removal
}

}  // namespace
}  // namespace simgate
