// Deadlines (Call::timeout, RequestManager::set_max_wait): a request past its deadline ends
// FAILED with Failure::timeout, its async service interrupted and its later completion
// dropped; a request that waited for the lock past its deadline is not run; a sync service
// that ran is answered with its result. No timed assertions: the deadlines are short, the
// waits for the replies generous, and only statuses, failures and calls are checked.
#include <gtest/gtest.h>
#include <gmock/gmock.h>

#include <chrono>
#include <mutex>
#include <thread>
#include <vector>

#include "simgate/core/component.h"
#include "test_manager.h"

namespace simgate {
namespace {

using namespace std::chrono_literals;
using ::testing::HasSubstr;
using testing::TestManager;

// An async service that runs until interrupted, a concurrent one that never ends by itself,
// and a sync one that counts its runs.
class Forever : public Component {
 public:
  Forever() : Component("forever") {
    add_async_service("wait", &Forever::wait);
    add_async_service("each", &Forever::each).concurrent();
    add_service("count", &Forever::count);
  }
  void wait() { ++started; }
  void each(Completion done) { calls.push_back(std::move(done)); }
  int count() { return ++counted; }
  void interrupt() override {
    ++interrupted;
    if (complete_on_interrupt) {
      completed(Status::success, "finished anyway");  // the reply must still be the timeout
      return;
    }
    Component::interrupt();
  }
  int started = 0;
  int interrupted = 0;
  int counted = 0;
  bool complete_on_interrupt = false;
  std::vector<Completion> calls;
};

class DeadlineTest : public ::testing::Test {
 protected:
  void SetUp() override { rm.register_component(forever); }
  RequestId call(const std::string& service, std::chrono::milliseconds timeout) {
    const RequestId id = rm.new_request_id();
    Call c{"forever", service, nullptr};
    c.timeout = timeout;
    rm.submit(id, std::move(c));
    return id;
  }
  // process() until request `id` is answered (bounded: a broken deadline fails, never hangs)
  std::optional<Outcome> wait_for(RequestId id) {
    for (int i = 0; i < 2000 && !rm.outcome(id); ++i) rm.process(10ms);
    return rm.outcome(id);
  }
  TestManager rm;
  Forever forever;
};

TEST_F(DeadlineTest, AnAsyncRequestPastItsDeadlineFailsWithTimeoutAndIsInterrupted) {
  const RequestId id = call("wait", 50ms);
  auto outcome = wait_for(id);
  ASSERT_TRUE(outcome);
  EXPECT_EQ(outcome->status, Status::failed);
  EXPECT_EQ(outcome->failure, Failure::timeout);
  EXPECT_EQ(outcome->message, "forever.wait: no reply within 50 ms (deadline); interrupted");
  EXPECT_EQ(outcome->data["timeout_ms"], 50);
  EXPECT_EQ(outcome->data["limit"], "deadline");
  EXPECT_EQ(outcome->data["component"], "forever");
  EXPECT_EQ(forever.started, 1);
  EXPECT_EQ(forever.interrupted, 1);
  EXPECT_EQ(rm.pending_count(), 0u);
}

TEST_F(DeadlineTest, TheComponentsOwnCompletionOnInterruptIsDroppedTheReplyIsTheTimeout) {
  forever.complete_on_interrupt = true;
  const RequestId id = call("wait", 50ms);
  auto outcome = wait_for(id);
  ASSERT_TRUE(outcome);
  EXPECT_EQ(outcome->failure, Failure::timeout);
  EXPECT_EQ(outcome->status, Status::failed);
  EXPECT_EQ(forever.interrupted, 1);
  rm.process();
  EXPECT_EQ(rm.completion_count(id), 1u);
}

TEST_F(DeadlineTest, AfterATimeoutTheComponentTakesTheNextRequestInsteadOfRefusingItBusy) {
  const RequestId first = call("wait", 50ms);
  ASSERT_TRUE(wait_for(first));
  const RequestId second = call("wait", 0ms);  // no deadline: runs until interrupted
  rm.process();
  EXPECT_FALSE(rm.outcome(second)) << rm.outcome(second)->message;  // running, not refused busy
  EXPECT_EQ(forever.started, 2);
  EXPECT_EQ(rm.pending_count(), 1u);
}

TEST_F(DeadlineTest, ARequestWithoutADeadlineIsNeverTimedOut) {
  const RequestId id = call("wait", 0ms);
  for (int i = 0; i < 5; ++i) rm.process(10ms);
  EXPECT_FALSE(rm.outcome(id));
  forever.completed(Status::success, "done");
  rm.process();
  ASSERT_TRUE(rm.outcome(id));
  EXPECT_EQ(rm.outcome(id)->status, Status::success);
}

TEST_F(DeadlineTest, ARequestThatCompletesInTimeGetsItsOwnOutcomeOnly) {
  const RequestId id = call("wait", 30ms);
  rm.process();
  forever.completed(Status::success, "done");
  rm.process();
  ASSERT_TRUE(rm.outcome(id));
  EXPECT_EQ(rm.outcome(id)->status, Status::success);
  // past its deadline: nothing more for it, the component is not interrupted
  std::this_thread::sleep_for(60ms);
  rm.process();
  EXPECT_EQ(rm.completion_count(id), 1u);
  EXPECT_EQ(forever.interrupted, 0);
}

TEST_F(DeadlineTest, TheServersMaxWaitBoundsCallsWithoutATimeoutAndLongerOnes) {
  rm.set_max_wait(50ms);
  const RequestId none = call("each", 0ms);
  const RequestId longer = call("each", 60'000ms);
  auto a = wait_for(none);
  auto b = wait_for(longer);
  ASSERT_TRUE(a);
  ASSERT_TRUE(b);
  for (const auto& outcome : {*a, *b}) {
    EXPECT_EQ(outcome.failure, Failure::timeout);
    EXPECT_EQ(outcome.message,
              "forever.each: no reply within 50 ms (the server's max wait); interrupted");
    EXPECT_EQ(outcome.data["limit"], "max_wait");
  }
}

TEST_F(DeadlineTest, ACallsShorterTimeoutWinsOverTheMaxWait) {
  rm.set_max_wait(60'000ms);
  const RequestId id = call("wait", 40ms);
  auto outcome = wait_for(id);
  ASSERT_TRUE(outcome);
  EXPECT_THAT(outcome->message, HasSubstr("no reply within 40 ms (deadline)"));
}

TEST_F(DeadlineTest, AConcurrentCallPastItsDeadlineEndsThroughItsCompletion) {
  const RequestId timed = call("each", 50ms);
  const RequestId other = call("each", 0ms);
  auto outcome = wait_for(timed);
  ASSERT_TRUE(outcome);
  EXPECT_EQ(outcome->failure, Failure::timeout);
  ASSERT_EQ(forever.calls.size(), 2u);
  EXPECT_TRUE(forever.calls[0].done());
  EXPECT_FALSE(forever.calls[1].done());  // the other call runs on
  EXPECT_FALSE(rm.outcome(other));
  forever.calls[0](Status::success);  // too late: dropped
  rm.process();
  EXPECT_EQ(rm.completion_count(timed), 1u);
}

TEST_F(DeadlineTest, AConcurrentCallPastItsDeadlineRunsItsInterruptHook) {
  const RequestId timed = call("each", 50ms);
  rm.process();  // started
  ASSERT_EQ(forever.calls.size(), 1u);
  int told = 0;
  forever.calls[0].on_interrupt([&] { ++told; });
  auto outcome = wait_for(timed);
  ASSERT_TRUE(outcome);
  EXPECT_EQ(outcome->failure, Failure::timeout);
  EXPECT_EQ(told, 1);
}

TEST_F(DeadlineTest, ARequestThatWaitedForTheLockPastItsDeadlineIsNotRun) {
  rm.process();  // started
  RequestId id = 0;
  {
    std::lock_guard hold(*rm.gate());  // the simulation is busy
    id = call("count", 1ms);
    std::this_thread::sleep_for(20ms);
  }
  rm.process();
  auto outcome = rm.outcome(id);
  ASSERT_TRUE(outcome);
  EXPECT_EQ(outcome->failure, Failure::timeout);
  EXPECT_EQ(outcome->status, Status::failed);
  EXPECT_THAT(outcome->message,
              HasSubstr("forever.count: no reply within 1 ms (deadline); not run"));
  EXPECT_EQ(forever.counted, 0);
}

TEST_F(DeadlineTest, ASyncServiceThatRunsIsAnsweredWithItsResult) {
  const RequestId id = call("count", 60'000ms);
  rm.process();
  auto outcome = rm.outcome(id);
  ASSERT_TRUE(outcome);
  EXPECT_EQ(outcome->status, Status::success);
  EXPECT_EQ(outcome->value, json(1));
}

TEST_F(DeadlineTest, AProcessWaitingForWorkWakesWhenADeadlineIsDue) {
  const RequestId id = call("wait", 50ms);
  rm.process();  // started; its deadline is watched
  ASSERT_FALSE(rm.outcome(id));
  rm.gate()->consume();  // the submission's signal, which would end the wait at once
  // one long wait: the gate ends it at the deadline (not after the 60 s), and that process()
  // answers the request
  std::thread waiter([&] { rm.process(60s); });
  waiter.join();
  auto outcome = rm.outcome(id);
  ASSERT_TRUE(outcome);
  EXPECT_EQ(outcome->failure, Failure::timeout);
}

TEST_F(DeadlineTest, ACancelBeforeTheDeadlineWinsAndTheDeadlineThenDoesNothing) {
  const RequestId id = call("wait", 50ms);
  rm.process();
  rm.cancel(id);
  rm.process();
  ASSERT_TRUE(rm.outcome(id));
  EXPECT_EQ(rm.outcome(id)->failure, Failure::cancelled);
  std::this_thread::sleep_for(80ms);
  rm.process();
  EXPECT_EQ(rm.completion_count(id), 1u);
  EXPECT_EQ(forever.interrupted, 1);
}

TEST_F(DeadlineTest, ManyRequestsThatEndInTimeDoNotPileUpOrTimeOutLaterOnes) {
  // ids are the manager's; each request completes at once, its deadline entry is left behind
  for (int i = 0; i < 300; ++i) {
    const RequestId id = call("wait", 60'000ms);
    rm.process();
    forever.completed(Status::success);
    rm.process();
    ASSERT_EQ(rm.outcome(id)->status, Status::success);
  }
  const RequestId last = call("wait", 50ms);
  auto outcome = wait_for(last);
  ASSERT_TRUE(outcome);
  EXPECT_EQ(outcome->failure, Failure::timeout);
  EXPECT_EQ(forever.interrupted, 1);
}

}  // namespace
}  // namespace simgate
