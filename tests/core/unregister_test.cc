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

}  // namespace
}  // namespace simgate
