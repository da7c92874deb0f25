// Worlds (issue #43): a transport's manager routes "w<k>/<component>" calls to the manager of
// world k (RequestManager::attach_world), which runs them under world k's own lock; outcomes,
// progress, cancels and the service listing all go through the transport's manager.
#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "simgate/core/call_context.h"
#include "simgate/core/request_manager.h"
#include "simgate/core/streams.h"
#include "test_manager.h"

namespace simgate {
namespace {

using testing::TestManager;

// A transport (world 0) with one world attached (w1), each with a component "arm" whose
// services say which manager ran them.
class Worlds : public ::testing::Test {
 protected:
  void SetUp() override {
    transport_.register_service(
        "arm", [] { return CallContext::current()->manager().name(); }, "who");
    world1_ = transport_.attach_world(1);
    world1_->set_gate(gate1_);
    world1_->register_service(
        "arm", [] { return CallContext::current()->manager().name(); }, "who");
    world1_->register_service("arm", [](int a, int b) { return a + b; }, "add", {"a", "b"});
    world1_->register_async_service(
        "arm", [this](Completion done) { held_ = std::move(done); }, "hold");
  }

  // Runs what both worlds have queued, then what came back to the transport.
  void settle() {
    world1_->process();
    transport_.process();
  }

  TestManager transport_;
  std::shared_ptr<SimulationGate> gate1_ = std::make_shared<SimulationGate>();
  std::shared_ptr<RequestManager> world1_;
  Completion held_;
};

TEST(WorldAddress, ReadsWorldAndNameStart) {
  EXPECT_EQ(RequestManager::world_address("w3/robot.motion"), (std::pair{3u, std::size_t{3}}));
  EXPECT_EQ(RequestManager::world_address("w0/time"), (std::pair{0u, std::size_t{3}}));
  EXPECT_EQ(RequestManager::world_address("w12/a"), (std::pair{12u, std::size_t{4}}));
  for (const char* not_one : {"robot.motion", "w/a", "w3/", "w03/a", "wx/a", "w3a/b", "w3", "x3/a",
                              "w99999999999/a", "time"})
    EXPECT_FALSE(RequestManager::world_address(not_one)) << not_one;
}

TEST_F(Worlds, AWorldAttachedAtRunTimeIsPreparedBeforeACallCanReachIt) {
  // its gate and components are given in `prepare`: a call routed meanwhile would find a
  // manager with no gate (create_world attaches worlds while the transports serve)
  auto gate2 = std::make_shared<SimulationGate>();
  bool reachable_while_prepared = true;
  auto world2 = transport_.attach_world(2, [&](const std::shared_ptr<RequestManager>& manager) {
    const auto worlds = transport_.worlds();
    reachable_while_prepared = std::find(worlds.begin(), worlds.end(), 2u) != worlds.end();
    manager->set_gate(gate2);
    manager->register_service(
        "arm", [] { return CallContext::current()->manager().name(); }, "who");
  });
  EXPECT_FALSE(reachable_while_prepared);
  EXPECT_EQ(transport_.attach_world(2), world2);  // attached once
  const RequestId id = transport_.call("w2/arm", "who");
  world2->process();
  transport_.process();
  ASSERT_TRUE(transport_.outcome(id));
  EXPECT_EQ(*transport_.outcome(id)->value, world2->name());
}

TEST_F(Worlds, ACallToAWorldRunsInItsManagerAndItsOutcomeComesToTheTransport) {
  const RequestId id = transport_.call("w1/arm", "who");
  settle();
  auto outcome = transport_.outcome(id);
  ASSERT_TRUE(outcome);
  EXPECT_EQ(outcome->status, Status::success);
  EXPECT_EQ(*outcome->value, world1_->name());
  EXPECT_NE(world1_->name(), transport_.name());

  const RequestId own = transport_.call("arm", "who");
  const RequestId w0 = transport_.call("w0/arm", "who");  // world 0 by its prefix
  settle();
  EXPECT_EQ(*transport_.outcome(own)->value, transport_.name());
  EXPECT_EQ(*transport_.outcome(w0)->value, transport_.name());

  std::vector<std::pair<RequestId, Call>> calls;
  calls.emplace_back(transport_.new_request_id(), Call{"w1/arm", "add", json::array({2, 3})});
  calls.emplace_back(transport_.new_request_id(), Call{"arm", "who", nullptr});
  calls.emplace_back(transport_.new_request_id(), Call{"w1/arm", "add", json::array({4, 5})});
  const std::vector<RequestId> ids = {calls[0].first, calls[1].first, calls[2].first};
  EXPECT_TRUE(transport_.run_or_submit(std::move(calls)));  // both locks free: ran here
  transport_.process();  // the worlds' outcomes reach a transport without a delivery thread here
  EXPECT_EQ(*transport_.outcome(ids[0])->value, 5);
  EXPECT_EQ(*transport_.outcome(ids[1])->value, transport_.name());
  EXPECT_EQ(*transport_.outcome(ids[2])->value, 9);
}

TEST_F(Worlds, AWorldThereIsNotIsFailedNamingTheWorlds) {
  const RequestId id = transport_.call("w7/arm", "who");
  settle();
  auto outcome = transport_.outcome(id);
  ASSERT_TRUE(outcome);
  EXPECT_EQ(outcome->status, Status::failed);
  EXPECT_EQ(outcome->failure, Failure::unknown_service);
  EXPECT_NE(outcome->message.find("no world 'w7' (the worlds here: w0, w1)"), std::string::npos)
      << outcome->message;
  // through run_or_submit too, with other calls around it (issue: it recursed forever)
  std::vector<std::pair<RequestId, Call>> calls;
  calls.emplace_back(transport_.new_request_id(), Call{"w7/arm", "who", nullptr});
  calls.emplace_back(transport_.new_request_id(), Call{"w1/arm", "who", nullptr});
  calls.emplace_back(transport_.new_request_id(), Call{"w8/arm", "who", nullptr});
  const RequestId first = calls[0].first, last = calls[2].first;
  EXPECT_TRUE(transport_.run_or_submit(std::move(calls)));
  settle();
  EXPECT_EQ(transport_.outcome(first)->failure, Failure::unknown_service);
  EXPECT_EQ(transport_.outcome(last)->failure, Failure::unknown_service);
  // and a world's unknown service is that world's answer
  const RequestId in_world = transport_.call("w1/arm", "nope");
  settle();
  EXPECT_EQ(transport_.outcome(in_world)->failure, Failure::unknown_service);
  EXPECT_NE(transport_.outcome(in_world)->message.find("has no service 'nope'"), std::string::npos);
}

TEST_F(Worlds, TheListingsIncludeTheWorldsUnderTheirPrefix) {
  std::vector<std::string> names;
  for (const auto& d : transport_.descriptors()) names.push_back(d.qualified_name());
  EXPECT_EQ(names,
            (std::vector<std::string>{"arm.who", "w1/arm.add", "w1/arm.hold", "w1/arm.who"}));
  EXPECT_EQ(transport_.components(), (std::vector<std::string>{"arm", "w1/arm"}));
  EXPECT_TRUE(transport_.serves_component("w1/arm"));
  EXPECT_TRUE(transport_.serves_component("w0/arm"));
  EXPECT_FALSE(transport_.serves_component("w2/arm"));
  EXPECT_TRUE(transport_.may_call("w1/arm", "add"));
  EXPECT_FALSE(transport_.may_call("w1/arm", "nope"));
  EXPECT_EQ(transport_.worlds(), std::vector<unsigned>{1});

  transport_.detach_world(1);
  EXPECT_EQ(transport_.components(), std::vector<std::string>{"arm"});
  EXPECT_TRUE(transport_.worlds().empty());
}

TEST_F(Worlds, AccessListsApplyInEveryWorld) {
  transport_.set_access(ServiceAccess(std::nullopt, {"arm.add"}));
  EXPECT_FALSE(transport_.may_call("w1/arm", "add"));
  const RequestId id = transport_.call("w1/arm", "add", json::array({1, 2}));
  settle();
  EXPECT_EQ(transport_.outcome(id)->failure, Failure::unknown_service);
}

TEST_F(Worlds, AnAsyncCallInAWorldIsCancelledThroughTheTransport) {
  const RequestId id = transport_.call("w1/arm", "hold");
  settle();
  ASSERT_FALSE(transport_.outcome(id));
  ASSERT_FALSE(held_.done());
  bool found = false;
  transport_.cancel(id, [&](bool f) { found = f; });
  settle();
  EXPECT_TRUE(found);
  auto outcome = transport_.outcome(id);
  ASSERT_TRUE(outcome);
  EXPECT_EQ(outcome->status, Status::preempted);
  EXPECT_EQ(transport_.completion_count(id), 1u);
}

TEST_F(Worlds, ProgressOfAWorldsCallReachesTheTransportBeforeItsOutcome) {
  Call call{"w1/arm", "hold", nullptr};
  call.progress = true;
  const RequestId id = transport_.new_request_id();
  transport_.submit(id, std::move(call));
  settle();
  ASSERT_FALSE(held_.done());
  {
    std::lock_guard lock(*gate1_);
    held_.progress(json{{"left", 2}});
    held_(Status::success, "done");
  }
  settle();
  const auto events = transport_.events(id);
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].first, "progress");
  EXPECT_EQ(events[0].second, (json{{"left", 2}}));
  EXPECT_EQ(events[1].first, "outcome");
  EXPECT_EQ(events[1].second, "SUCCESS");
}

TEST_F(Worlds, EachWorldRunsUnderItsOwnLock) {
  // world 1 busy (its lock held by another thread): the transport's own calls still run at
  // once; world 1's wait for its lock and run when it is free
  std::unique_lock busy(*gate1_);
  std::vector<std::pair<RequestId, Call>> own;
  own.emplace_back(transport_.new_request_id(), Call{"arm", "who", nullptr});
  const RequestId own_id = own[0].first;
  EXPECT_TRUE(transport_.run_or_submit(std::move(own)));
  EXPECT_TRUE(transport_.outcome(own_id));

  std::vector<std::pair<RequestId, Call>> theirs;
  theirs.emplace_back(transport_.new_request_id(), Call{"w1/arm", "add", json::array({1, 1})});
  const RequestId their_id = theirs[0].first;
  EXPECT_FALSE(transport_.run_or_submit(std::move(theirs)));  // queued in world 1
  transport_.process();
  EXPECT_FALSE(transport_.outcome(their_id));
  busy.unlock();
  settle();
  ASSERT_TRUE(transport_.outcome(their_id));
  EXPECT_EQ(*transport_.outcome(their_id)->value, 2);
}

TEST_F(Worlds, AWorldsManagerAnswersWhatIsLeftAtItsShutdown) {
  const RequestId running = transport_.call("w1/arm", "hold");
  settle();
  world1_->abandon_pending("world w1 is deleted");
  transport_.detach_world(1);
  const RequestId later = transport_.call("w1/arm", "who");
  settle();
  EXPECT_EQ(transport_.outcome(running)->failure, Failure::shutdown);
  EXPECT_NE(transport_.outcome(running)->message.find("world w1 is deleted"), std::string::npos);
  EXPECT_EQ(transport_.outcome(later)->failure, Failure::unknown_service);
}

// A sensor whose sample is its world's number, and an actuator that keeps its last command.
class Sensor : public Component {
 public:
  explicit Sensor(int world) : Component("robot.sensor") {
    declare_output_stream("count", [world] { return json{{"world", world}}; });
  }
};
class Motion : public Component {
 public:
  Motion() : Component("robot.motion") {
    declare_input_stream("velocity", {"v"}, [this](const json& c) { last = c; });
  }
  json last;
};

// The streams a transport reaches (RequestManager::streams()): world 0's under their names,
// each attached world's under "w<k>/", as its calls are.
class WorldStreams : public ::testing::Test {
 protected:
  void SetUp() override {
    hub0_->add(sensor0_, "sensor", {"t"});
    hub0_->add(motion0_, "motion", {"t"});
    hub1_->add(sensor1_, "sensor", {"t"});
    hub1_->add(motion1_, "motion", {"t"});
    transport_.set_streams(hub0_, "t");
    transport_.attach_world(1, [&](const std::shared_ptr<RequestManager>& manager) {
      manager->set_gate(gate1_);
      manager->set_streams(hub1_, "t");
    });
  }
  static std::vector<std::string> names(const std::vector<StreamInfo>& infos) {
    std::vector<std::string> out;
    for (const auto& info : infos) out.push_back(info.component);
    return out;
  }

  TestManager transport_;
  std::shared_ptr<SimulationGate> gate1_ = std::make_shared<SimulationGate>();
  std::shared_ptr<StreamHub> hub0_ = std::make_shared<StreamHub>(transport_.gate());
  std::shared_ptr<StreamHub> hub1_ = std::make_shared<StreamHub>(gate1_);
  Sensor sensor0_{0}, sensor1_{1};
  Motion motion0_, motion1_;
};

TEST_F(WorldStreams, AreListedFoundAndSubscribedUnderTheirWorldsPrefix) {
  StreamDirectory& streams = *transport_.streams();
  EXPECT_EQ(names(streams.streams("t")),
            (std::vector<std::string>{"robot.sensor", "robot.motion", "w1/robot.sensor",
                                      "w1/robot.motion"}));
  EXPECT_EQ(streams.find("w1/robot.sensor", "t")->component, "w1/robot.sensor");
  EXPECT_EQ(streams.find("w0/robot.sensor", "t")->component, "w0/robot.sensor");
  EXPECT_FALSE(streams.find("w2/robot.sensor", "t"));

  auto sub1 = streams.subscribe("w1/robot.sensor", "t", {});
  auto sub0 = streams.subscribe("robot.sensor", "t", {});
  ASSERT_TRUE(sub1 && sub0);
  EXPECT_EQ(sub1->component(), "w1/robot.sensor");  // what the subscriber asked for
  hub1_->publish_due(0);
  hub0_->publish_due(0);
  std::vector<SamplePtr> samples;
  ASSERT_EQ(sub1->take(samples), 1u);
  EXPECT_EQ(samples[0]->data(), (json{{"world", 1}}));
  samples.clear();
  ASSERT_EQ(sub0->take(samples), 1u);
  EXPECT_EQ(samples[0]->data(), (json{{"world", 0}}));
  EXPECT_EQ(*streams.sample_now("w1/robot.sensor"), (json{{"world", 1}}));

  streams.unsubscribe(sub1);
  EXPECT_TRUE(sub1->closed());
  EXPECT_EQ(hub1_->statistics()[0].subscribers, 0u);
}

TEST_F(WorldStreams, CommandsGoToTheirWorldAndAWorldThereIsNotIsNamed) {
  StreamDirectory& streams = *transport_.streams();
  EXPECT_TRUE(streams.publish("w1/robot.motion", "t", {{"v", 1}}).applied);
  EXPECT_EQ(motion1_.last, (json{{"v", 1}}));
  EXPECT_TRUE(motion0_.last.is_null());
  const PublishResult refused = streams.publish("w4/robot.motion", "t", {{"v", 1}});
  EXPECT_FALSE(refused.ok);
  EXPECT_NE(refused.error.find("the worlds here: w0, w1"), std::string::npos) << refused.error;
  EXPECT_TRUE(streams.note_refused("w1/robot.motion", "t", "not JSON"));
  EXPECT_EQ(hub1_->statistics()[1].refused, 1u);
}

TEST_F(WorldStreams, AWorldDetachedLeavesTheListingAndItsSubscriptionsEndWithItsStreams) {
  StreamDirectory& streams = *transport_.streams();
  auto sub = streams.subscribe("w1/robot.sensor", "t", {});
  hub1_->remove_all();  // what deleting the world does (Gateway::leave)
  transport_.detach_world(1);
  EXPECT_TRUE(sub->closed());
  EXPECT_EQ(names(streams.streams("t")),
            (std::vector<std::string>{"robot.sensor", "robot.motion"}));
  EXPECT_FALSE(streams.subscribe("w1/robot.sensor", "t", {}));
  streams.unsubscribe(sub);  // nothing left to end: no harm
}

}  // namespace
}  // namespace simgate
