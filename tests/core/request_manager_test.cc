// The request life cycle (core/src/request_manager.cc): sync and async services, arity and
// type errors, named arguments, policies, preemption, cancel, exceptions, shutdown.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <thread>

#include "simgate/core/component.h"
#include "simgate/core/eigen.h"
#include "simgate/core/log.h"
#include "test_manager.h"

namespace simgate {
namespace {

using ::testing::HasSubstr;
using testing::TestManager;

int add(int a, int b) { return a + b; }

// A component like MORSE's waypoint actuator: async goto, sync stop/status.
class Mover : public Component {
 public:
  explicit Mover(std::string name) : Component(std::move(name)) {
    add_async_service("goto", &Mover::go_to, {"x", "y", {"tolerance", 0.5}})
        .interruptible()
        .doc("drive");
    add_async_service("lock", &Mover::lock, {}).noninterruptible();
    add_async_service("wander", &Mover::wander, {});  // no local policy
    add_service("position", &Mover::position);
    add_service("fail", &Mover::fail, {"message"});
    add_service("crash", &Mover::crash);
  }
  void go_to(double x, double y, double tolerance) {
    target_ = {x, y};
    tolerance_ = tolerance;
    moving_ = true;
  }
  void lock() {}
  void wander() {}
  Eigen::Vector2d position() const { return position_; }
  void fail(const std::string& message) { throw ServiceError(message); }
  int crash() { throw std::out_of_range("index 7 out of range"); }

  void default_action() override {
    if (!moving_) return;
    position_ = target_;
    moving_ = false;
    completed(Status::success, "Arrived");
  }
  void interrupt() override {
    moving_ = false;
    ++interrupts;
    Component::interrupt();
  }
  int interrupts = 0;

 private:
  Eigen::Vector2d position_{0, 0}, target_{0, 0};
  double tolerance_ = 0;
  bool moving_ = false;
};

class RequestManagerTest : public ::testing::Test {
 protected:
  void SetUp() override { rm.register_component(mover); }
  TestManager rm;
  Mover mover{"robot.mover"};
};

TEST_F(RequestManagerTest, SyncFreeFunctionReturnsItsResult) {
  rm.register_service("test_component", add, "add", {"a", "b"});
  auto o = rm.run("test_component", "add", json{1, 2});
  ASSERT_TRUE(o);
  EXPECT_EQ(o->status, Status::success);
  EXPECT_EQ(o->value, json(3));
}

TEST_F(RequestManagerTest, VoidServiceHasNoValueButFalsyResultsDo) {
  rm.register_service("c", [] {}, "nothing");
  rm.register_service("c", [] { return 0; }, "zero");
  rm.register_service("c", [] { return std::string(); }, "empty");
  rm.register_service("c", [] { return false; }, "no");
  EXPECT_FALSE(rm.run("c", "nothing")->value.has_value());
  EXPECT_EQ(rm.run("c", "zero")->value, json(0));
  EXPECT_EQ(rm.run("c", "empty")->value, json(""));
  EXPECT_EQ(rm.run("c", "no")->value, json(false));
}

TEST_F(RequestManagerTest, UnknownComponentAndServiceHaveNotBeenRegistered) {
  auto o = rm.run("nobody", "move", json::array());
  EXPECT_EQ(o->status, Status::failed);
  EXPECT_EQ(o->failure, Failure::unknown_service);
  EXPECT_THAT(o->message,
              HasSubstr("The request move has not been registered in Test service manager"));
  EXPECT_THAT(o->message, HasSubstr("no component 'nobody'"));
  auto s = rm.run("robot.mover", "fly", json::array());
  EXPECT_THAT(s->message, HasSubstr("has not been registered"));
  EXPECT_THAT(
      s->message,
      HasSubstr("has no service 'fly' (services: crash, fail, goto, lock, position, wander)"));
  EXPECT_EQ(s->value, json(s->message));
}

// robot.mover and robot.eye have services; the robot itself has none of them
class RobotWithParts : public RequestManagerTest {
 protected:
  void SetUp() override {
    RequestManagerTest::SetUp();
    rm.register_service("robot", [] {}, "stop");
    rm.register_service("robot.eye", [] { return 1; }, "position");
    rm.register_service("robot.arm.hand", [] { return 2; }, "position");
  }
};

TEST_F(RobotWithParts, AServiceOfTheRobotsComponentsSuggestsThem) {
  auto o = rm.run("robot", "position");
  EXPECT_THAT(o->message,
              ::testing::StartsWith(
                  "The request position has not been registered in Test service manager: "));
  EXPECT_THAT(o->message, HasSubstr("component 'robot' has no service 'position' (services: stop) "
                                    "(did you mean robot.arm.hand, robot.eye or robot.mover?)"));
  auto one = rm.run("robot", "goto");
  EXPECT_THAT(one->message, HasSubstr("(did you mean robot.mover?)"));
}

TEST_F(RobotWithParts, AComponentNotServedHereButWithPartsThatHaveTheServiceSuggestsThem) {
  auto o = rm.run("robot.arm", "position");
  EXPECT_THAT(o->message, HasSubstr("no component 'robot.arm' (did you mean robot.arm.hand?)"));
}

TEST_F(RobotWithParts, AMisspeltServiceSuggestsTheClosest) {
  auto o = rm.run("robot.mover", "gotoo");
  EXPECT_EQ(o->failure, Failure::unknown_service);
  EXPECT_THAT(
      o->message,
      HasSubstr("has no service 'gotoo' (services: crash, fail, goto, lock, position, wander) "
                "(did you mean 'goto'?)"));
}

TEST_F(RobotWithParts, AMisspeltComponentSuggestsTheClosest) {
  auto o = rm.run("robot.mvoer", "goto");
  EXPECT_THAT(o->message,
              HasSubstr("The request goto has not been registered in Test service manager: "
                        "no component 'robot.mvoer' (did you mean 'robot.mover'?)"));
}

TEST_F(RobotWithParts, NothingCloseSuggestsNothing) {
  EXPECT_THAT(rm.run("robot.mover", "teleport")->message,
              ::testing::Not(HasSubstr("did you mean")));
  EXPECT_THAT(rm.run("satellite", "orbit")->message, ::testing::Not(HasSubstr("did you mean")));
}

TEST_F(RequestManagerTest, WrongArityMentionsWrongNumberOfParameters) {
  rm.register_service("test_component", add, "add", {"a", "b"});
  auto o = rm.run("test_component", "add", json{1});
  EXPECT_EQ(o->failure, Failure::bad_arguments);
  EXPECT_THAT(
      o->message,
      HasSubstr("wrong # of parameters for service test_component.add: expected 2 (a, b), got 1"));
  EXPECT_THAT(rm.run("test_component", "add", json{1, 2, 3})->message,
              HasSubstr("wrong # of parameters"));
  // none at all: MORSE's other phrase (pymorse raises MorseServiceFailed, not TypeError)
  EXPECT_THAT(
      rm.run("test_component", "add")->message,
      HasSubstr("parameters expected for service test_component.add! expected 2 (a, b), got 0"));
  EXPECT_THAT(rm.run("test_component", "add", json::array())->message,
              HasSubstr("parameters expected"));
  EXPECT_EQ(rm.run("test_component", "add", json::array())->failure, Failure::bad_arguments);
}

TEST_F(RequestManagerTest, WrongTypeNamesTheParameterAndWhatCame) {
  rm.register_service("test_component", add, "add", {"a", "b"});
  auto o = rm.run("test_component", "add", json{1, "two"});
  EXPECT_EQ(o->failure, Failure::bad_arguments);
  EXPECT_THAT(o->message, HasSubstr("parameter 'b' expects integer, got string \"two\""));
  EXPECT_EQ(o->data["parameter"], "b");
}

TEST_F(RequestManagerTest, NamedArgumentsAndDefaults) {
  auto id = rm.call("robot.mover", "goto", json{{"y", 2.0}, {"x", 1.0}});
  rm.process();
  EXPECT_TRUE(mover.has_running_request());
  mover.default_action();
  rm.process();
  EXPECT_EQ(rm.outcome(id)->value, json("Arrived"));
  EXPECT_EQ(rm.run("robot.mover", "position")->value, (json{1.0, 2.0}));
}

TEST_F(RequestManagerTest, NamedArgumentsReportMissingAndUnknownNames) {
  auto missing = rm.run("robot.mover", "goto", json{{"x", 1.0}});
  EXPECT_THAT(missing->message, HasSubstr("wrong # of parameters"));
  EXPECT_THAT(missing->message, HasSubstr("missing 'y'"));
  auto unknown = rm.run("robot.mover", "goto", json{{"x", 1.0}, {"y", 1.0}, {"speed", 3}});
  EXPECT_THAT(unknown->message,
              HasSubstr("no parameter named 'speed' (parameters: x, y, tolerance=0.5)"));
  auto scalar = rm.run("robot.mover", "goto", json(5));
  EXPECT_THAT(scalar->message, HasSubstr("must be a list (positional) or an object (named)"));
}

TEST_F(RequestManagerTest, ServiceErrorBecomesFailedWithItsMessage) {
  auto o = rm.run("robot.mover", "fail", json{"Our human cannot walk at negative speed!"});
  EXPECT_EQ(o->status, Status::failed);
  EXPECT_EQ(o->failure, Failure::service_error);
  EXPECT_EQ(o->value, json("Our human cannot walk at negative speed!"));
}

// A message is text of any bytes: a NUL in it (a client's text quoted by the core) used to
// cut it there (issue #17, item 9: ServiceError kept it as what(), a C string).
TEST_F(RequestManagerTest, AServiceErrorMessageKeepsWhatFollowsANul) {
  const std::string message("before\0after", 12);
  auto o = rm.run("robot.mover", "fail", json{message});
  EXPECT_EQ(o->status, Status::failed);
  EXPECT_EQ(o->message, message);
  // the core's own messages quote the client: a parameter name with a NUL in it
  auto named = rm.run("robot.mover", "fail", json{{std::string("mess\0age", 8), "x"}});
  EXPECT_EQ(named->failure, Failure::bad_arguments);
  EXPECT_THAT(named->message, HasSubstr(std::string("mess\0age", 8)));
  EXPECT_THAT(named->message, HasSubstr("message"));  // the parameter list, after the NUL
}

TEST_F(RequestManagerTest, OtherExceptionsFailClearlyAndTheManagerLivesOn) {
  auto o = rm.run("robot.mover", "crash");
  EXPECT_EQ(o->failure, Failure::internal);
  EXPECT_THAT(o->message, HasSubstr("robot.mover.crash"));
  EXPECT_THAT(o->message, HasSubstr("index 7 out of range"));
  EXPECT_EQ(rm.run("robot.mover", "position")->status, Status::success);
}

TEST_F(RequestManagerTest, AsyncCompletesThroughCompleted) {
  auto id = rm.call("robot.mover", "goto", json{3, 4});
  rm.process();
  EXPECT_FALSE(rm.outcome(id));
  EXPECT_EQ(rm.pending_count(), 1u);
  EXPECT_EQ(mover.running_service(), "robot.mover.goto");
  mover.default_action();
  rm.process();
  ASSERT_TRUE(rm.outcome(id));
  EXPECT_EQ(rm.outcome(id)->status, Status::success);
  EXPECT_EQ(rm.pending_count(), 0u);
  EXPECT_FALSE(mover.has_running_request());
}

TEST_F(RequestManagerTest, SecondAsyncPreemptsInterruptible) {
  auto first = rm.call("robot.mover", "goto", json{1, 1});
  auto second = rm.call("robot.mover", "goto", json{2, 2});
  rm.process();
  ASSERT_TRUE(rm.outcome(first));
  EXPECT_EQ(rm.outcome(first)->status, Status::preempted);
  EXPECT_EQ(rm.outcome(first)->failure, Failure::preempted);
  EXPECT_FALSE(rm.outcome(first)->value.has_value());
  EXPECT_EQ(mover.interrupts, 1);
  EXPECT_FALSE(rm.outcome(second));
  mover.default_action();
  rm.process();
  EXPECT_EQ(rm.outcome(second)->status, Status::success);
}

TEST_F(RequestManagerTest, NonInterruptibleRefusesTheNewRequest) {
  auto first = rm.call("robot.mover", "lock");
  auto second = rm.call("robot.mover", "goto", json{2, 2});
  rm.process();
  EXPECT_FALSE(rm.outcome(first));
  EXPECT_EQ(rm.outcome(second)->status, Status::failed);
  EXPECT_EQ(rm.outcome(second)->failure, Failure::busy);
  EXPECT_THAT(rm.outcome(second)->message,
              HasSubstr("A non-interruptible service (robot.mover.lock) is already running"));
  EXPECT_EQ(mover.running_service(), "robot.mover.lock");
}

TEST_F(RequestManagerTest, GlobalPolicyRejectsByDefault) {
  auto first = rm.call("robot.mover", "wander");
  auto second = rm.call("robot.mover", "goto", json{2, 2});
  rm.process();
  EXPECT_FALSE(rm.outcome(first));
  EXPECT_THAT(
      rm.outcome(second)->message,
      HasSubstr("A service (robot.mover.wander) is already running. I do not know what to do."));
  EXPECT_EQ(rm.outcome(second)->data["running"], "robot.mover.wander");
}

TEST_F(RequestManagerTest, GlobalPolicyPreemptInterruptsServicesWithoutLocalPolicy) {
  rm.set_global_policy(GlobalPolicy::preempt);
  auto first = rm.call("robot.mover", "wander");
  auto second = rm.call("robot.mover", "lock");
  auto third = rm.call("robot.mover", "goto", json{1, 1});
  rm.process();
  EXPECT_EQ(rm.outcome(first)->status, Status::preempted);  // no local policy: global preempts
  EXPECT_FALSE(rm.outcome(second));                         // lock keeps running
  EXPECT_EQ(rm.outcome(third)->failure, Failure::busy);     // local policy beats global
}

TEST_F(RequestManagerTest, CancelEndsTheRunningRequestPreempted) {
  auto id = rm.call("robot.mover", "goto", json{1, 1});
  std::optional<bool> found;
  rm.cancel(id, [&](bool f) { found = f; });
  rm.process();
  ASSERT_TRUE(found);
  EXPECT_TRUE(*found);
  EXPECT_EQ(rm.outcome(id)->status, Status::preempted);
  EXPECT_EQ(rm.outcome(id)->failure, Failure::cancelled);
  EXPECT_EQ(mover.interrupts, 1);
  std::optional<bool> again;
  rm.cancel(id, [&](bool f) { again = f; });
  rm.process();
  EXPECT_FALSE(*again);
  EXPECT_EQ(rm.completion_count(id), 1u);
}

TEST_F(RequestManagerTest, CancelOfASyncOrUnknownRequestFindsNothing) {
  auto id = rm.call("robot.mover", "position");
  std::optional<bool> found;
  rm.cancel(id, [&](bool f) { found = f; });
  rm.cancel(987654321, {});
  rm.process();
  EXPECT_FALSE(*found);
}

TEST_F(RequestManagerTest, CancelAfterPreemptionDoesNotTouchTheNewRequest) {
  // MORSE interrupted whatever ran on the component; simgate cancels only its target
  auto first = rm.call("robot.mover", "goto", json{1, 1});
  auto second = rm.call("robot.mover", "goto", json{2, 2});
  rm.cancel(first, {});
  rm.process();
  EXPECT_EQ(rm.outcome(first)->status, Status::preempted);
  EXPECT_FALSE(rm.outcome(second));
  EXPECT_TRUE(mover.has_running_request());
}

class Forgetful : public Component {
 public:
  Forgetful() : Component("forgetful") {
    add_async_service("run", [] {}).interruptible();
  }
  void interrupt() override { ++calls; }  // forgets Component::interrupt()
  int calls = 0;
};

TEST_F(RequestManagerTest, InterruptOverrideThatForgetsTheBaseStillEndsTheRequest) {
  Forgetful f;
  rm.register_component(f);
  auto first = rm.call("forgetful", "run");
  auto second = rm.call("forgetful", "run");
  rm.process();
  EXPECT_EQ(f.calls, 1);
  EXPECT_EQ(rm.outcome(first)->status, Status::preempted);
  EXPECT_TRUE(f.has_running_request());
  (void)second;
}

TEST_F(RequestManagerTest, AsyncFreeFunctionTakesACompletion) {
  Completion saved;
  rm.register_async_service("test_component",
                            [&](Completion done, int start) {
                              saved = done;
                              return start > 0;
                            },
                            "compute", {"start_value"});
  auto id = rm.call("test_component", "compute", json{5});
  rm.process();
  EXPECT_FALSE(rm.outcome(id));
  EXPECT_TRUE(saved(Status::success, "done!"));
  EXPECT_FALSE(saved(Status::success, "twice"));  // exactly once
  rm.process();
  EXPECT_EQ(rm.outcome(id)->value, json("done!"));
  EXPECT_EQ(rm.completion_count(id), 1u);
}

TEST_F(RequestManagerTest, AsyncFreeFunctionsShareTheirComponentSlot) {
  rm.register_async_service("tc", [](Completion) {}, "a");
  rm.register_async_service("tc", [](Completion) {}, "b");
  auto first = rm.call("tc", "a");
  auto second = rm.call("tc", "b");
  rm.process();
  EXPECT_FALSE(rm.outcome(first));
  EXPECT_THAT(rm.outcome(second)->message, HasSubstr("A service (tc.a) is already running"));
}

TEST_F(RequestManagerTest, CompletionFromAnotherThreadWakesProcess) {
  Completion saved;
  rm.register_async_service("tc", [&](Completion done) { saved = done; }, "work");
  auto id = rm.call("tc", "work");
  rm.process();
  std::thread worker([&] { saved(Status::failed, json{{"code", 7}}); });
  auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < 100 && !rm.outcome(id); ++i) rm.process(std::chrono::seconds(10));
  worker.join();
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));
  ASSERT_TRUE(rm.outcome(id));
  EXPECT_EQ(rm.outcome(id)->status, Status::failed);
  EXPECT_EQ(rm.outcome(id)->value, (json{{"code", 7}}));
}

TEST_F(RequestManagerTest, ExceptionInAsyncStartFailsAndFreesTheSlot) {
  rm.register_async_service("tc",
                            [](int x) {
                              if (x < 0) throw ServiceError("negative");
                            },
                            "go", {"x"});
  auto bad = rm.call("tc", "go", json{-1});
  auto good = rm.call("tc", "go", json{1});
  rm.process();
  EXPECT_EQ(rm.outcome(bad)->value, json("negative"));
  EXPECT_FALSE(rm.outcome(good));  // started: the slot was free again
}

TEST_F(RequestManagerTest, BadArgumentsDoNotPreemptTheRunningRequest) {
  auto first = rm.call("robot.mover", "goto", json{1, 1});
  auto bad = rm.call("robot.mover", "goto", json{"x"});
  rm.process();
  EXPECT_FALSE(rm.outcome(first));
  EXPECT_EQ(rm.outcome(bad)->failure, Failure::bad_arguments);
}

TEST_F(RequestManagerTest, ProcessWakesAtOnceForARequestFromAnotherThread) {
  rm.register_service("test_component", add, "add", {"a", "b"});
  RequestId id = 0;
  std::thread io([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    id = rm.call("test_component", "add", json{2, 2});
  });
  auto start = std::chrono::steady_clock::now();
  std::size_t handled = 0;
  while (handled == 0 && std::chrono::steady_clock::now() - start < std::chrono::seconds(30))
    handled = rm.process(std::chrono::seconds(10));
  io.join();
  // generous bound: a missed wake-up would take the full 10 s wait
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));
  EXPECT_EQ(rm.outcome(id)->value, json(4));
}

TEST_F(RequestManagerTest, BatchRunsInOneProcess) {
  rm.register_service("test_component", add, "add", {"a", "b"});
  std::vector<std::pair<RequestId, Call>> batch;
  for (int i = 0; i < 3; ++i)
    batch.emplace_back(rm.new_request_id(), Call{"test_component", "add", json{i, i}});
  auto ids = std::vector<RequestId>{batch[0].first, batch[1].first, batch[2].first};
  rm.submit_batch(std::move(batch));
  rm.process();
  for (int i = 0; i < 3; ++i) EXPECT_EQ(rm.outcome(ids[i])->value, json(2 * i));
}

TEST_F(RequestManagerTest, RunOrSubmitRunsOnTheCallingThreadWhenTheLockIsFree) {
  std::thread::id ran_on;
  rm.register_service("test_component",
                      [&](int a, int b) {
                        ran_on = std::this_thread::get_id();
                        return a + b;
                      },
                      "add", {"a", "b"});
  // queued earlier: runs first, in the same process()
  auto earlier = rm.call("robot.mover", "position");
  rm.gate()->consume();  // submit() signalled
  RequestId id = rm.new_request_id();
  EXPECT_TRUE(rm.run_or_submit(id, Call{"test_component", "add", json{2, 3}}));
  EXPECT_EQ(ran_on, std::this_thread::get_id());
  auto done = rm.completions();
  ASSERT_EQ(done.size(), 2u);
  EXPECT_EQ(done[0].first, earlier);
  EXPECT_EQ(done[1].first, id);
  EXPECT_EQ(done[1].second.value, json(5));
  // nothing left to wake the simulation thread for
  EXPECT_FALSE(rm.gate()->consume());
}

// `simulation step 1` on a paused simulation: an async service done in its start method,
// run on the calling thread, is answered there, and the simulation thread is not woken for it
// (it would only compete for the CPU and the lock: a client stepping back to back measured
// p99 4 ms with the wake, 87 us without)
TEST_F(RequestManagerTest, AnAsyncServiceDoneInItsStartOnTheCallingThreadWakesNobody) {
  rm.register_async_service("test_component",
                            [](Completion done, int n) { done(Status::success, n); }, "now", {"n"});
  RequestId id = rm.new_request_id();
  EXPECT_TRUE(rm.run_or_submit(id, Call{"test_component", "now", json{7}}));
  ASSERT_TRUE(rm.outcome(id).has_value());
  EXPECT_EQ(rm.outcome(id)->value, json(7));
  EXPECT_FALSE(rm.gate()->consume());
  // the same from the simulation thread's process(): answered in that process()
  RequestId queued = rm.call("test_component", "now", json{8});
  rm.gate()->consume();  // submit() signalled
  rm.process();
  EXPECT_EQ(rm.outcome(queued)->value, json(8));
  EXPECT_FALSE(rm.gate()->consume());
}

TEST_F(RequestManagerTest, AnAsyncServiceDoneOnAnotherThreadStillWakesTheLoop) {
  Completion kept;
  rm.register_async_service("test_component", [&](Completion done) { kept = done; }, "later");
  RequestId id = rm.new_request_id();
  EXPECT_TRUE(rm.run_or_submit(id, Call{"test_component", "later", nullptr}));
  EXPECT_FALSE(rm.outcome(id).has_value());
  std::thread([&] { kept(Status::success); }).join();
  EXPECT_TRUE(rm.gate()->consume());  // the loop's next process() delivers it
  rm.process();
  EXPECT_TRUE(rm.outcome(id).has_value());
}

TEST_F(RequestManagerTest, RunOrSubmitQueuesWhileTheSimulationLockIsHeld) {
  rm.register_service("test_component", add, "add", {"a", "b"});
  std::vector<std::pair<RequestId, Call>> calls;
  calls.emplace_back(rm.new_request_id(), Call{"test_component", "add", json{1, 1}});
  calls.emplace_back(rm.new_request_id(), Call{"test_component", "add", json{2, 2}});
  auto first = calls[0].first, second = calls[1].first;
  bool ran = true;
  {
    // the simulation thread is stepping
    std::lock_guard stepping(*rm.gate());
    std::thread io([&] { ran = rm.run_or_submit(std::move(calls)); });
    io.join();
  }
  EXPECT_FALSE(ran);
  EXPECT_TRUE(rm.completions().empty());
  // the holder is told to come back: its wait returns at once
  EXPECT_TRUE(rm.gate()->wait_for(std::chrono::seconds(10)));
  rm.process();
  EXPECT_EQ(rm.outcome(first)->value, json(2));
  EXPECT_EQ(rm.outcome(second)->value, json(4));
}

TEST_F(RequestManagerTest, RunOrSubmitOnASpanLeavesRunCallsInPlaceAndMovesQueuedOnes) {
  rm.register_service("test_component", add, "add", {"a", "b"});
  std::vector<std::pair<RequestId, Call>> calls;
  calls.emplace_back(rm.new_request_id(), Call{"test_component", "add", json{1, 1}});
  calls.emplace_back(rm.new_request_id(), Call{"test_component", "add", json{2, 2}});
  const json::array_t* params = &calls[0].second.params.get_ref<const json::array_t&>();

  rm.register_service("test_component", [](const json& x) { return x; }, "echo", {"x"});
  calls.emplace_back(rm.new_request_id(),
                     Call{"test_component", "echo", json{"a long string, on the heap"}});
  calls.emplace_back(rm.new_request_id(), Call{"test_component", "echo", json{json{1, 2}}});
  calls.emplace_back(rm.new_request_id(), Call{"test_component", "add", json{{"a", 3}, {"b", 4}}});

  // run here: the objects stay for the caller to reuse. Numbers are kept, in the same
  // array, for the next parse to overwrite; what holds memory (strings, nested values,
  // named arguments) is released
  EXPECT_TRUE(rm.run_or_submit(std::span(calls)));
  EXPECT_EQ(rm.outcome(calls[0].first)->value, json(2));
  EXPECT_EQ(rm.outcome(calls[1].first)->value, json(4));
  EXPECT_EQ(rm.outcome(calls[2].first)->value, json("a long string, on the heap"));
  EXPECT_EQ(rm.outcome(calls[3].first)->value, json({1, 2}));
  EXPECT_EQ(rm.outcome(calls[4].first)->value, json(7));
  EXPECT_EQ(calls[0].second.component, "test_component");
  ASSERT_TRUE(calls[0].second.params.is_array());
  EXPECT_EQ(&calls[0].second.params.get_ref<const json::array_t&>(), params);
  EXPECT_EQ(calls[0].second.params, json({1, 1}));
  EXPECT_EQ(calls[2].second.params, json::array());
  EXPECT_EQ(calls[3].second.params, json::array());
  EXPECT_TRUE(calls[4].second.params.is_null());

  // a caller that drops its call objects (refilled = false): params emptied, so that
  // destroying them costs no allocation
  std::vector<std::pair<RequestId, Call>> dropped;
  dropped.emplace_back(rm.new_request_id(), Call{"test_component", "add", json{5, 6}});
  EXPECT_TRUE(rm.run_or_submit(std::span(dropped), /*refilled=*/false));
  EXPECT_EQ(rm.outcome(dropped[0].first)->value, json(11));
  EXPECT_EQ(dropped[0].second.params, json::array());
  calls.resize(2);

  // queued while the lock is held: moved into the queue, run by the next process()
  calls[0].first = rm.new_request_id();
  calls[0].second.params = json{3, 3};
  bool ran = true;
  {
    std::lock_guard stepping(*rm.gate());
    std::thread io([&] { ran = rm.run_or_submit(std::span(calls.data(), 1)); });
    io.join();
  }
  EXPECT_FALSE(ran);
  rm.process();
  EXPECT_EQ(rm.outcome(calls[0].first)->value, json(6));
}

// A transport that only reads the outcome it is given (as the socket transport does): the
// core reuses one Outcome object, so nothing of a request may show in the next one.
class ReadingManager : public RequestManager {
 public:
  ReadingManager() : RequestManager("Reading service manager") {}
  std::vector<std::pair<RequestId, Outcome>> seen;  // copies, in delivery order

 protected:
  void on_service_completion(RequestId id, Outcome&& outcome) override {
    seen.emplace_back(id, outcome);
  }
};

TEST(RequestManagerOutcomeTest, NothingOfAnOutcomeShowsInTheNextOneOfTheSameRun) {
  ReadingManager rm;
  rm.register_service("c", [](int a) { return a; }, "echo", {"a"});
  rm.register_service("c", [] {}, "nothing");
  rm.register_service("c", [](const std::string& m) -> int { throw ServiceError(m); }, "fail",
                      {"message"});
  std::vector<std::pair<RequestId, Call>> calls;
  auto add = [&](std::string service, json params) {
    calls.emplace_back(rm.new_request_id(), Call{"c", std::move(service), std::move(params)});
  };
  add("fail", json{"no"});  // FAILED, with a message and data
  add("echo", json{7});     // then a success: no failure, no message, no data
  add("fly", nullptr);      // unknown service
  add("nothing", nullptr);  // a success without a value
  add("echo", json{"x"});   // bad arguments
  add("echo", json{0});     // a falsy value is still a value
  ASSERT_TRUE(rm.run_or_submit(std::span(calls)));
  ASSERT_EQ(rm.seen.size(), calls.size());
  for (std::size_t i = 0; i < calls.size(); ++i) EXPECT_EQ(rm.seen[i].first, calls[i].first);

  const Outcome& failed = rm.seen[0].second;
  EXPECT_EQ(failed.status, Status::failed);
  EXPECT_EQ(failed.failure, Failure::service_error);
  EXPECT_EQ(failed.message, "no");
  EXPECT_EQ(failed.data.value("service", ""), "fail");

  for (std::size_t i : {1u, 3u, 5u}) {
    const Outcome& ok = rm.seen[i].second;
    SCOPED_TRACE(i);
    EXPECT_EQ(ok.status, Status::success);
    EXPECT_EQ(ok.failure, Failure::none);
    EXPECT_EQ(ok.message, "");
    EXPECT_TRUE(ok.data.is_null());
  }
  EXPECT_EQ(rm.seen[1].second.value, json(7));
  EXPECT_FALSE(rm.seen[3].second.value.has_value());
  EXPECT_EQ(rm.seen[5].second.value, json(0));
  EXPECT_EQ(rm.seen[2].second.failure, Failure::unknown_service);
  EXPECT_EQ(rm.seen[4].second.failure, Failure::bad_arguments);
  EXPECT_THAT(rm.seen[4].second.message, HasSubstr("parameter 'a'"));
}

TEST_F(RequestManagerTest, AServiceRegisteredAgainReplacesTheOneCalledBefore) {
  // the manager remembers the previous lookup; a registration must end that
  rm.register_service("c", [] { return 1; }, "version");
  EXPECT_EQ(rm.run("c", "version")->value, json(1));
  EXPECT_EQ(rm.run("c", "version")->value, json(1));
  rm.register_service("c", [] { return 2; }, "version");
  EXPECT_EQ(rm.run("c", "version")->value, json(2));
  // a name that only shares a prefix, or another component, is not the remembered one
  rm.register_service("c", [] { return 3; }, "versions");
  rm.register_service("c2", [] { return 4; }, "version");
  EXPECT_EQ(rm.run("c", "versions")->value, json(3));
  EXPECT_EQ(rm.run("c2", "version")->value, json(4));
  EXPECT_EQ(rm.run("c", "version")->value, json(2));
  EXPECT_EQ(rm.run("c", "missing")->failure, Failure::unknown_service);
}

TEST_F(RequestManagerTest, RunOrSubmitAfterAbandonPendingIsRefused) {
  rm.register_service("test_component", add, "add", {"a", "b"});
  rm.abandon_pending();
  RequestId id = rm.new_request_id();
  rm.run_or_submit(id, Call{"test_component", "add", json{1, 2}});
  ASSERT_TRUE(rm.outcome(id));
  EXPECT_EQ(rm.outcome(id)->failure, Failure::shutdown);
}

TEST_F(RequestManagerTest, ServicesNeverRunConcurrentlyFromTwoThreads) {
  // the simulation thread processing and a transport thread running inline share one lock
  int inside = 0, overlaps = 0, calls = 0;
  rm.register_service(
      "test_component",
      [&] {
        if (++inside > 1) ++overlaps;
        ++calls;
        std::this_thread::yield();
        --inside;
      },
      "touch");
  std::atomic<bool> stop{false};
  std::thread sim([&] {
    while (!stop) rm.process(std::chrono::milliseconds(5));
  });
  std::thread queuer([&] {
    for (int i = 0; i < 300; ++i) rm.call("test_component", "touch");
  });
  for (int i = 0; i < 300; ++i)
    rm.run_or_submit(rm.new_request_id(), Call{"test_component", "touch", nullptr});
  queuer.join();
  for (int i = 0; i < 1000 && rm.completions().size() < 600; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  stop = true;
  rm.gate()->signal();
  sim.join();
  EXPECT_EQ(rm.completions().size(), 600u);
  std::lock_guard holder(*rm.gate());  // the counters were written under the lock
  EXPECT_EQ(calls, 600);
  EXPECT_EQ(overlaps, 0);
}

TEST_F(RequestManagerTest, AbandonPendingAnswersEveryPendingRequest) {
  auto running = rm.call("robot.mover", "goto", json{1, 1});
  rm.process();
  auto queued = rm.call("robot.mover", "position");
  rm.abandon_pending();
  EXPECT_EQ(rm.outcome(running)->failure, Failure::shutdown);
  EXPECT_EQ(rm.outcome(queued)->failure, Failure::shutdown);
  EXPECT_FALSE(mover.has_running_request());
  auto late = rm.call("robot.mover", "position");
  rm.process();
  EXPECT_EQ(rm.outcome(late)->failure, Failure::shutdown);
  mover.completed(Status::success);  // ignored: nothing running any more
  EXPECT_EQ(rm.completion_count(running), 1u);
}

TEST_F(RequestManagerTest, ComponentsAreSharedBetweenManagers) {
  TestManager other;
  other.register_component(mover);
  auto a = rm.call("robot.mover", "lock");
  rm.process();
  auto b = other.call("robot.mover", "goto", json{1, 1});
  other.process();
  EXPECT_EQ(other.outcome(b)->failure, Failure::busy);  // one async request per component
  (void)a;
}

// ---- concurrent services

// A clock whose `wait` is concurrent: each call keeps its own completion until its tick.
class Waiter : public Component {
 public:
  Waiter() : Component("clock") {
    add_async_service("wait", &Waiter::wait, {"ticks"})
        .concurrent()
        .doc("completes after `ticks` ticks");
    add_async_service("exclusive", [](Completion) {}, {});  // the slot's own, no policy
  }
  void wait(Completion done, int ticks) {
    if (ticks < 0) throw ServiceError("ticks must not be negative");
    waits.push_back({std::move(done), now + ticks});
  }
  // each tick: the calls that are due finish; those done otherwise (cancel, shutdown) go
  void default_action() override {
    ++now;
    std::erase_if(waits, [&](Wait& w) {
      if (w.done.done()) return true;
      if (now < w.until) return false;
      w.done(Status::success, now);
      return true;
    });
  }
  struct Wait {
    Completion done;  // its call
    int until;        // tick at which it completes
  };
  std::vector<Wait> waits;  // calls running
  int now = 0;              // ticks so far
};

class ConcurrentServiceTest : public RequestManagerTest {
 protected:
  void SetUp() override {
    RequestManagerTest::SetUp();
    rm.register_component(clock);
  }
  void tick() {
    clock.default_action();
    rm.process();
  }
  Waiter clock;
};

TEST_F(ConcurrentServiceTest, TwoCallsRunTogetherAndBothSucceed) {
  auto first = rm.call("clock", "wait", json{2});
  auto second = rm.call("clock", "wait", json{1});
  rm.process();
  EXPECT_FALSE(rm.outcome(first));
  EXPECT_FALSE(rm.outcome(second));  // not refused: no slot, no policy
  EXPECT_EQ(rm.pending_count(), 2u);
  tick();
  ASSERT_TRUE(rm.outcome(second));
  EXPECT_EQ(rm.outcome(second)->status, Status::success);
  EXPECT_EQ(rm.outcome(second)->value, json(1));
  EXPECT_FALSE(rm.outcome(first));
  tick();
  EXPECT_EQ(rm.outcome(first)->value, json(2));
  EXPECT_EQ(rm.pending_count(), 0u);
  EXPECT_TRUE(clock.waits.empty());
}

TEST_F(ConcurrentServiceTest, CallsDoNotTouchTheComponentsSlot) {
  auto exclusive = rm.call("clock", "exclusive");
  auto wait = rm.call("clock", "wait", json{1});
  auto another = rm.call("clock", "exclusive");
  rm.process();
  EXPECT_FALSE(rm.outcome(exclusive));
  EXPECT_FALSE(rm.outcome(wait));
  EXPECT_EQ(rm.outcome(another)->failure,
            Failure::busy);  // the slot's rule still holds for the others
  EXPECT_EQ(clock.running_service(), "clock.exclusive");
  tick();
  EXPECT_EQ(rm.outcome(wait)->status, Status::success);
  EXPECT_TRUE(clock.has_running_request());
}

TEST_F(ConcurrentServiceTest, CancelEndsThatCallOnlyAndTheComponentSeesItDone) {
  auto first = rm.call("clock", "wait", json{3});
  auto second = rm.call("clock", "wait", json{3});
  rm.process();
  std::optional<bool> found;
  rm.cancel(first, [&](bool f) { found = f; });
  rm.process();
  EXPECT_TRUE(found.value_or(false));
  ASSERT_TRUE(rm.outcome(first));
  EXPECT_EQ(rm.outcome(first)->status, Status::preempted);
  EXPECT_EQ(rm.outcome(first)->failure, Failure::cancelled);
  EXPECT_EQ(rm.outcome(first)->message, "cancelled by its client");
  EXPECT_FALSE(rm.outcome(second));
  ASSERT_EQ(clock.waits.size(), 2u);
  EXPECT_TRUE(clock.waits[0].done.done());
  EXPECT_FALSE(clock.waits[1].done.done());
  tick();
  EXPECT_EQ(clock.waits.size(), 1u);  // dropped once done
  tick();
  tick();
  EXPECT_EQ(rm.outcome(second)->status, Status::success);
  EXPECT_EQ(rm.completion_count(first), 1u);
  std::optional<bool> again;
  rm.cancel(first, [&](bool f) { again = f; });
  rm.process();
  EXPECT_FALSE(again.value_or(true));
}

TEST_F(ConcurrentServiceTest, CancelRunsThatCallsInterruptHookAtOnce) {
  auto first = rm.call("clock", "wait", json{3});
  auto second = rm.call("clock", "wait", json{3});
  rm.process();
  ASSERT_EQ(clock.waits.size(), 2u);
  int first_told = 0, second_told = 0;
  clock.waits[0].done.on_interrupt([&] {
    ++first_told;
    EXPECT_TRUE(clock.waits[0].done.done());  // told after its outcome was given
  });
  clock.waits[1].done.on_interrupt([&] { ++second_told; });
  rm.cancel(first);
  rm.process();
  // no tick: the component learns of it without looking
  EXPECT_EQ(first_told, 1);
  EXPECT_EQ(second_told, 0);
  rm.cancel(first);  // a second cancel finds nothing: not told twice
  rm.process();
  EXPECT_EQ(first_told, 1);
  // a call the component finishes itself runs no hook
  tick();
  tick();
  tick();
  EXPECT_EQ(rm.outcome(second)->status, Status::success);
  EXPECT_EQ(second_told, 0);
}

TEST_F(ConcurrentServiceTest, AbandonPendingEndsEveryCallWithShutdown) {
  auto first = rm.call("clock", "wait", json{5});
  auto second = rm.call("clock", "wait", json{5});
  rm.process();
  rm.abandon_pending();
  EXPECT_EQ(rm.outcome(first)->failure, Failure::shutdown);
  EXPECT_EQ(rm.outcome(first)->status, Status::failed);
  EXPECT_EQ(rm.outcome(second)->failure, Failure::shutdown);
  EXPECT_TRUE(clock.waits[0].done.done());
  EXPECT_TRUE(clock.waits[1].done.done());
  EXPECT_TRUE(clock.async_slot()->running_concurrent().empty());
}

TEST_F(ConcurrentServiceTest, TheSlotListsTheCallsStillRunning) {
  auto first = rm.call("clock", "wait", json{1});
  auto second = rm.call("clock", "wait", json{5});
  rm.process();
  EXPECT_EQ(clock.async_slot()->running_concurrent().size(), 2u);
  tick();
  ASSERT_EQ(clock.async_slot()->running_concurrent().size(), 1u);
  EXPECT_EQ(clock.async_slot()->running_concurrent()[0].state()->id, second);
  (void)first;
}

TEST_F(ConcurrentServiceTest, AStartThatThrowsFailsThatCallOnly) {
  auto bad = rm.call("clock", "wait", json{-1});
  auto good = rm.call("clock", "wait", json{1});
  rm.process();
  EXPECT_EQ(rm.outcome(bad)->value, json("ticks must not be negative"));
  EXPECT_FALSE(rm.outcome(good));
  EXPECT_EQ(rm.pending_count(), 1u);
  EXPECT_EQ(clock.async_slot()->running_concurrent().size(), 1u);
}

TEST_F(ConcurrentServiceTest, FreeFunctionsCanBeConcurrent) {
  std::vector<Completion> held;
  rm.register_async_service("tc", [&](Completion c) { held.push_back(c); }, "each").concurrent();
  auto a = rm.call("tc", "each");
  auto b = rm.call("tc", "each");
  rm.process();
  ASSERT_EQ(held.size(), 2u);
  held[1](Status::success, "b");
  held[0](Status::success, "a");
  rm.process();
  EXPECT_EQ(rm.outcome(a)->value, json("a"));
  EXPECT_EQ(rm.outcome(b)->value, json("b"));
}

TEST_F(ConcurrentServiceTest, TheDescriptorSaysConcurrent) {
  auto ds = rm.descriptors();
  auto wait = std::find_if(ds.begin(), ds.end(),
                           [](auto& d) { return d.qualified_name() == "clock.wait"; });
  auto goto_ = std::find_if(ds.begin(), ds.end(),
                            [](auto& d) { return d.qualified_name() == "robot.mover.goto"; });
  ASSERT_NE(wait, ds.end());
  EXPECT_TRUE(wait->concurrent);
  EXPECT_EQ(wait->to_json()["concurrent"], true);
  EXPECT_EQ(wait->to_json()["async"], true);
  EXPECT_EQ(goto_->to_json()["concurrent"], false);
  auto position = std::find_if(
      ds.begin(), ds.end(), [](auto& d) { return d.qualified_name() == "robot.mover.position"; });
  EXPECT_FALSE(position->to_json().contains("concurrent"));  // sync services: not a question
}

TEST(ConcurrentServiceRegistrationTest, MistakesAreCaughtAtRegistration) {
  TestManager rm;
  // sync, no Completion parameter, or with a policy
  EXPECT_THROW(rm.register_service("c", [] {}, "sync").concurrent(), std::logic_error);
  EXPECT_THROW(rm.register_async_service("c", [](int) {}, "no_completion", {"x"}).concurrent(),
               std::logic_error);
  EXPECT_THROW(rm.register_async_service(
                     "c", [](Completion) {}, "a")
                   .interruptible()
                   .concurrent(),
               std::logic_error);
  EXPECT_THROW(rm.register_async_service(
                     "c", [](Completion) {}, "b")
                   .concurrent()
                   .noninterruptible(),
               std::logic_error);
}

// ---- debug log of every request

class RequestLogTest : public RequestManagerTest {
 protected:
  void SetUp() override {
    RequestManagerTest::SetUp();
    saved_level_ = log::level();
    log::set_sink([this](log::Level level, std::string_view line) {
      std::lock_guard lock(mutex_);
      if (level == log::Level::debug) lines_.emplace_back(line);
    });
  }
  void TearDown() override {
    log::set_sink({});
    log::set_level(saved_level_);
  }
  std::vector<std::string> lines() {
    std::lock_guard lock(mutex_);
    return lines_;
  }

  log::Level saved_level_ = log::Level::info;
  std::mutex mutex_;                // guards lines_
  std::vector<std::string> lines_;  // debug lines logged
};

TEST_F(RequestLogTest, DebugLogsEverySyncRequestWithItsStatusAndTime) {
  log::set_level(log::Level::debug);
  rm.run("robot.mover", "position");
  rm.run("robot.mover", "fail", json{"no way"});
  auto l = lines();
  ASSERT_EQ(l.size(), 2u);
  EXPECT_THAT(l[0], ::testing::MatchesRegex(
                        "Test service manager: robot\\.mover position -> SUCCESS in [0-9]+ us"));
  EXPECT_THAT(
      l[1],
      ::testing::MatchesRegex(
          "Test service manager: robot\\.mover fail -> FAILED \\(no way\\) in [0-9.]+ (us|ms)"));
}

TEST_F(RequestLogTest, DebugLogsAnAsyncRequestWhenItEnds) {
  log::set_level(log::Level::debug);
  auto id = rm.call("robot.mover", "goto", json{1, 1});
  rm.process();
  EXPECT_TRUE(lines().empty());  // started: nothing yet
  rm.cancel(id);
  rm.process();
  auto l = lines();
  ASSERT_EQ(l.size(), 1u);
  EXPECT_THAT(l[0],
              ::testing::MatchesRegex("Test service manager: robot\\.mover goto -> PREEMPTED "
                                      "\\(cancelled by its client\\) after [0-9.]+ (us|ms|s)"));
}

TEST_F(RequestLogTest, NothingIsLoggedWithoutDebug) {
  log::set_level(log::Level::info);
  auto id = rm.call("robot.mover", "goto", json{1, 1});
  rm.run("robot.mover", "position");
  log::set_level(log::Level::debug);  // switched on while the goto runs: it was not timed
  mover.default_action();
  rm.process();
  EXPECT_EQ(rm.outcome(id)->status, Status::success);
  EXPECT_TRUE(lines().empty());
}

TEST_F(RequestManagerTest, DescriptorsCarryTypesDefaultsAndPolicy) {
  auto ds = rm.descriptors();
  auto it = std::find_if(ds.begin(), ds.end(), [](auto& d) { return d.name == "goto"; });
  ASSERT_NE(it, ds.end());
  EXPECT_TRUE(it->is_async);
  EXPECT_EQ(it->policy, Policy::interruptible);
  EXPECT_EQ(it->doc, "drive");
  ASSERT_EQ(it->params.size(), 3u);
  EXPECT_EQ(it->params[0].schema, (json{{"type", "number"}}));
  EXPECT_EQ(it->params[2].default_value, json(0.5));
  EXPECT_EQ(it->signature(), "x, y, tolerance=0.5");
  EXPECT_EQ(it->to_json()["policy"], "interruptible");
  EXPECT_EQ(rm.services().at("robot.mover").size(), 6u);
}

TEST(ServiceRegistrationTest, MistakesAreCaughtAtRegistration) {
  TestManager rm;
  EXPECT_THROW(rm.register_service("c", add, "add", {"a"}), std::logic_error);
  EXPECT_THROW(rm.register_service("c", add, "add", {"a", "a"}), std::logic_error);
  EXPECT_THROW(rm.register_service("c", add, "add", {{"a", 1}, "b"}), std::logic_error);
  EXPECT_THROW(rm.register_service("c", add, "add", {"a", {"b", "two"}}), std::logic_error);
  EXPECT_THROW(
      rm.register_service("c", [](Completion) {}, "sync_with_completion"), std::logic_error);
  EXPECT_THROW(rm.register_service("c", add, "add").interruptible(), std::logic_error);
}

TEST(ServiceRegistrationTest, ParametersWithoutNamesAreNumbered) {
  TestManager rm;
  rm.register_service("c", add, "add");
  EXPECT_EQ(rm.descriptors()[0].signature(), "arg0, arg1");
}

}  // namespace
}  // namespace simgate
