// RequestManager::unregister_component (core/src/request_manager_services.cc): a component
// removed while the manager runs (a robot deleted at run time).
#include <gtest/gtest.h>

#include <mutex>

#include "test_manager.h"

namespace simgate {
namespace {

using testing::TestManager;

// A component removed at run time (a robot deleted): its running request ends FAILED with
// the reason, exactly once, a later completion of it is ignored, and its services are gone
// while the others stay.
TEST(RequestManagerUnregister, RunningRequestsEndWithTheReasonAndTheServicesGo) {
  TestManager rm;
  Completion saved;
  rm.register_async_service("robot", [&](Completion done) { saved = done; }, "work");
  Completion watching;
  rm.register_async_service(
        "robot", [&](Completion done) { watching = done; }, "watch")
      .concurrent();
  rm.register_service("robot", [] { return 1; }, "ping");
  rm.register_service("other", [] { return 2; }, "ping");
  auto id = rm.call("robot", "work");
  auto watch = rm.call("robot", "watch");
  rm.process();
  ASSERT_FALSE(rm.outcome(id));
  ASSERT_FALSE(rm.outcome(watch));
  {
    std::lock_guard lock(*rm.gate());
    EXPECT_TRUE(rm.unregister_component("robot", "robot 'robot' was deleted"));
    EXPECT_FALSE(rm.unregister_component("ghost", "never there"));
  }
  rm.process();
  ASSERT_TRUE(rm.outcome(id));
  EXPECT_EQ(rm.outcome(id)->status, Status::failed);
  EXPECT_EQ(rm.outcome(id)->message, "robot 'robot' was deleted");
  ASSERT_TRUE(rm.outcome(watch));  // a concurrent call too
  EXPECT_EQ(rm.outcome(watch)->message, "robot 'robot' was deleted");
  EXPECT_TRUE(watching.done());
  saved(Status::success);  // the component finishing it late changes nothing
  rm.process();
  EXPECT_EQ(rm.completion_count(id), 1u);
  EXPECT_EQ(rm.completion_count(watch), 1u);
  EXPECT_FALSE(rm.serves_component("robot"));
  EXPECT_EQ(rm.run("robot", "ping")->failure, Failure::unknown_service);
  EXPECT_EQ(rm.run("other", "ping")->value, json(2));
  for (const auto& d : rm.descriptors()) EXPECT_NE(d.component, "robot");
  EXPECT_EQ(rm.pending_count(), 0u);
}

// The last lookup's service is lent to the request that runs it (no reference count touched
// per request): one that removes its own component while it runs still lives until it
// returns (its captures read after the removal; ASan would see a freed one), and after it
// the component's services are gone and the others are found again.
TEST(RequestManagerUnregister, AServiceThatRemovesItsOwnComponentLivesUntilItReturns) {
  TestManager rm;
  const std::string kept(64, 'k');  // a capture on the heap, in the service's invoker
  rm.register_service("robot",
                      [&rm, kept](bool remove) {
                        if (remove) rm.unregister_component("robot", "removed itself");
                        return kept.size();
                      },
                      "work", {"remove"});
  rm.register_service("other", [] { return 2; }, "ping");
  // the second call of a pipelining client runs the remembered (lent) service
  EXPECT_EQ(rm.run("robot", "work", json::array({false}))->value, json(64));
  EXPECT_EQ(rm.run("robot", "work", json::array({true}))->value, json(64));
  EXPECT_EQ(rm.run("robot", "work", json::array({false}))->failure, Failure::unknown_service);
  EXPECT_EQ(rm.run("other", "ping")->value, json(2));
  EXPECT_EQ(rm.run("other", "ping")->value, json(2));
}

}  // namespace
}  // namespace simgate
