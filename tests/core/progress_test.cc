// Progress reports of async calls (Completion::progress, Component::progress,
// RequestManager::on_service_progress): only for calls whose client asked, at most one per
// progress interval, always before the call's outcome, never after it.
#include <gtest/gtest.h>

#include <chrono>
#include <vector>

#include "simgate/core/component.h"
#include "test_manager.h"

namespace simgate {
namespace {

using testing::TestManager;
using Events = std::vector<std::pair<std::string, json>>;

// Counts down: reports the steps left at every step, completes at 0.
class Countdown : public Component {
 public:
  Countdown() : Component("countdown") {
    add_async_service("run", &Countdown::run, {"steps"}).interruptible();
    add_async_service("each", &Countdown::each, {"steps"}).concurrent();
  }
  void run(int steps) { left_ = steps; }
  void each(Completion done, int steps) { calls_.push_back({std::move(done), steps}); }
  void default_action() override {
    if (left_ > 0) {
      --left_;
      reported.push_back(progress(json{{"left", left_}}));
      if (left_ == 0) completed(Status::success, "done");
    }
    for (auto& c : calls_) {
      if (c.left == 0 || c.done.done()) continue;
      --c.left;
      c.done.progress(c.left);
      if (c.left == 0) c.done(Status::success);
    }
  }
  // A report through the first concurrent call's completion, whatever its state.
  bool report_to_first_call(json value) { return calls_.front().done.progress(std::move(value)); }
  std::vector<bool> reported;  // what progress() returned, step by step

 private:
  struct Call {
    Completion done;
    int left;
  };
  int left_ = 0;
  std::vector<Call> calls_;
};

class ProgressTest : public ::testing::Test {
 protected:
  void SetUp() override {
    rm.set_progress_interval(std::chrono::nanoseconds(0));  // every report
    rm.register_component(countdown);
  }
  // default_action, then process(), `n` times: the simulation loop's order
  void steps(int n) {
    for (int i = 0; i < n; ++i) {
      countdown.default_action();
      rm.process();
    }
  }
  TestManager rm;
  Countdown countdown;
};

TEST_F(ProgressTest, ACallThatAskedGetsEveryReportThenItsOutcome) {
  RequestId id = rm.call_with_progress("countdown", "run", {3});
  rm.process();
  steps(3);
  EXPECT_EQ(rm.events(id), (Events{{"progress", {{"left", 2}}},
                                   {"progress", {{"left", 1}}},
                                   {"progress", {{"left", 0}}},
                                   {"outcome", "SUCCESS"}}));
}

TEST_F(ProgressTest, ACallThatDidNotAskGetsItsOutcomeOnlyAndReportsGoNowhere) {
  RequestId id = rm.call("countdown", "run", {2});
  rm.process();
  steps(2);
  EXPECT_EQ(rm.events(id), (Events{{"outcome", "SUCCESS"}}));
  EXPECT_EQ(countdown.reported, (std::vector<bool>{false, false}));
}

TEST_F(ProgressTest, ReportsSoonerThanTheIntervalAfterTheLastAreDropped) {
  rm.set_progress_interval(std::chrono::hours(1));
  RequestId id = rm.call_with_progress("countdown", "run", {3});
  rm.process();
  steps(3);
  // the first passes, the next two come within the hour
  EXPECT_EQ(rm.events(id), (Events{{"progress", {{"left", 2}}}, {"outcome", "SUCCESS"}}));
  EXPECT_EQ(countdown.reported, (std::vector<bool>{true, false, false}));
}

TEST_F(ProgressTest, EachCallOfAConcurrentServiceReportsToItsOwnClient) {
  RequestId asked = rm.call_with_progress("countdown", "each", {2});
  RequestId silent = rm.call("countdown", "each", {2});
  rm.process();
  steps(2);
  EXPECT_EQ(rm.events(asked), (Events{{"progress", 1}, {"progress", 0}, {"outcome", "SUCCESS"}}));
  EXPECT_EQ(rm.events(silent), (Events{{"outcome", "SUCCESS"}}));
}

TEST_F(ProgressTest, NothingIsReportedAfterTheOutcome) {
  RequestId id = rm.call_with_progress("countdown", "run", {5});
  rm.process();
  steps(1);
  rm.cancel(id);
  rm.process();
  // the component's completion is gone: progress() finds no running request
  EXPECT_FALSE(countdown.progress(json(42)));
  steps(2);
  const Events events = rm.events(id);
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0], (std::pair<std::string, json>{"progress", {{"left", 4}}}));
  EXPECT_EQ(events[1], (std::pair<std::string, json>{"outcome", "PREEMPTED"}));
}

TEST_F(ProgressTest, AReportOfAFinishedCallIsRefusedByItsCompletion) {
  RequestId id = rm.call_with_progress("countdown", "each", {1});
  rm.process();
  steps(1);
  EXPECT_FALSE(countdown.report_to_first_call(7));
  rm.process();
  EXPECT_EQ(rm.events(id), (Events{{"progress", 0}, {"outcome", "SUCCESS"}}));
  EXPECT_FALSE(Completion().progress(1));  // an empty handle
}

}  // namespace
}  // namespace simgate
