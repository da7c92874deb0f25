// StreamHub: output streams by frequency, first samples, slow subscribers, input commands
// (applied at once when the simulation lock is free, kept otherwise), removal.
#include "simgate/core/streams.h"

#include <thread>

#include <gtest/gtest.h>

#include "simgate/core/errors.h"

namespace simgate {
namespace {

// A sensor whose sample is a counter, and an actuator that keeps its last command.
class Counter : public Component {
 public:
  Counter() : Component("robot.counter") {
    declare_output_stream("count", [this] { return json{{"n", ++reads}}; });
  }
  int reads = 0;
};

class Speed : public Component {
 public:
  Speed() : Component("robot.motion") {
    declare_input_stream("velocity", {"v", "w"}, [this](const json& c) {
      if (!c.contains("v")) throw ServiceError("the command has no 'v'", Failure::bad_arguments);
      last = c;
    });
  }
  json last;
};

struct StreamHubTest : ::testing::Test {
  std::shared_ptr<SimulationGate> gate = std::make_shared<SimulationGate>();
  StreamHub hub{gate};
  Counter counter;
  Speed speed;
  void SetUp() override {
    hub.add(counter, "counter", {"socket", "dds"}, 100);  // every 0.01 s
    hub.add(speed, "motion_vw", {"socket"});
  }
  static std::vector<SamplePtr> take(StreamSubscription& s) {
    std::vector<SamplePtr> out;
    s.take(out);
    return out;
  }
};

TEST_F(StreamHubTest, ListsTheStreamsOfATransport) {
  auto socket = hub.streams("socket");
  ASSERT_EQ(socket.size(), 2u);
  EXPECT_EQ(socket[0].component, "robot.counter");
  EXPECT_EQ(socket[0].direction, StreamDirection::out);
  EXPECT_EQ(socket[0].kind, "count");
  EXPECT_EQ(socket[0].frequency, 100);
  EXPECT_EQ(socket[1].direction, StreamDirection::in);
  EXPECT_EQ(socket[1].fields, (std::vector<std::string>{"v", "w"}));
  EXPECT_EQ(hub.streams("dds").size(), 1u);
  EXPECT_TRUE(hub.streams("jsonrpc").empty());
  EXPECT_FALSE(hub.find("robot.motion", "dds"));
  EXPECT_STREQ(to_string(StreamDirection::in), "IN");
}

TEST_F(StreamHubTest, AComponentWithoutAStreamOrTwiceIsRefused) {
  Component plain("robot.plain");
  EXPECT_THROW(hub.add(plain, "plain", {"socket"}), std::invalid_argument);
  EXPECT_THROW(hub.add(counter, "counter", {"socket"}), std::invalid_argument);
  Counter other;
  EXPECT_THROW(hub.add(other, "counter", {"socket"}, 0), std::invalid_argument);
}

TEST_F(StreamHubTest, NoSubscriberNoSample) {
  hub.publish_due(0);
  hub.publish_due(1);
  EXPECT_EQ(counter.reads, 0);
  EXPECT_EQ(hub.total_samples(), 0u);
}

TEST_F(StreamHubTest, SamplesFollowTheFrequencyInSimulatedTime) {
  int wakes = 0;
  auto sub = hub.subscribe("robot.counter", "socket", {16, "test", [&] { ++wakes; }});
  ASSERT_TRUE(sub);
  EXPECT_TRUE(hub.turn_wanted());
  // 0.002 s steps for 0.1 s: a sample every 0.01 s, the first at once
  for (int step = 0; step <= 50; ++step) hub.publish_due(step * 0.002);
  auto samples = take(*sub);
  ASSERT_EQ(samples.size(), 11u);
  EXPECT_EQ(samples.front()->seq(), 1u);
  EXPECT_DOUBLE_EQ(samples.front()->time(), 0);
  EXPECT_NEAR(samples.back()->time(), 0.1, 1e-9);
  EXPECT_EQ(samples.back()->text(), "{\"n\":11}");
  EXPECT_EQ(wakes, 1);  // one wake until it took them
  hub.publish_due(0.11);
  EXPECT_EQ(wakes, 2);
}

TEST_F(StreamHubTest, ANewSubscriberGetsAFirstSampleAloneWithoutWaitingForTheNextDue) {
  auto a = hub.subscribe("robot.counter", "socket", {});
  hub.publish_due(0);        // a's first, also due
  hub.publish_due(0.004);    // not due
  auto b = hub.subscribe("robot.counter", "dds", {});
  hub.publish_due(0.004);    // b's first, a gets nothing
  EXPECT_EQ(take(*a).size(), 1u);
  auto b_samples = take(*b);
  ASSERT_EQ(b_samples.size(), 1u);
  EXPECT_DOUBLE_EQ(b_samples[0]->time(), 0.004);
  hub.publish_due(0.01);     // due: both
  EXPECT_EQ(take(*a).size(), 1u);
  EXPECT_EQ(take(*b).size(), 1u);
}

TEST_F(StreamHubTest, ASlowSubscriberKeepsTheLatestAndCountsWhatItLost) {
  auto slow = hub.subscribe("robot.counter", "socket", {4, "slow client", {}});
  auto fast = hub.subscribe("robot.counter", "socket", {4, "fast client", {}});
  for (int i = 0; i < 10; ++i) {
    hub.publish_due(i * 0.01);
    take(*fast);
  }
  auto kept = take(*slow);
  ASSERT_EQ(kept.size(), 4u);
  EXPECT_EQ(kept.front()->seq(), 7u);
  EXPECT_EQ(kept.back()->seq(), 10u);
  EXPECT_EQ(slow->dropped(), 6u);
  EXPECT_EQ(fast->dropped(), 0u);
  slow->note_dropped(2);  // the transport lost two more itself
  EXPECT_EQ(hub.total_dropped(), 8u);
  EXPECT_EQ(hub.statistics("socket")[0].dropped, 8u);
  hub.unsubscribe(slow);  // its drops stay counted
  EXPECT_EQ(hub.total_dropped(), 8u);
  EXPECT_TRUE(slow->closed());
  EXPECT_EQ(hub.statistics()[0].subscribers, 1u);
}

TEST_F(StreamHubTest, TheClockGoingBackStartsTheScheduleAgain) {
  auto sub = hub.subscribe("robot.counter", "socket", {});
  hub.publish_due(5.0);
  hub.publish_due(0.0);  // reset_all: time back to 0
  EXPECT_EQ(take(*sub).size(), 2u);
}

TEST_F(StreamHubTest, OnlyOutputStreamsOfTheTransportCanBeSubscribed) {
  EXPECT_FALSE(hub.subscribe("robot.motion", "socket", {}));
  EXPECT_FALSE(hub.subscribe("robot.counter", "jsonrpc", {}));
  EXPECT_FALSE(hub.subscribe("robot.nothing", "socket", {}));
}

TEST_F(StreamHubTest, ACommandIsAppliedAtOnceWhenTheLockIsFree) {
  PublishResult r = hub.publish("robot.motion", "socket", {{"v", 1}, {"w", 0}});
  EXPECT_TRUE(r.ok);
  EXPECT_TRUE(r.applied);
  EXPECT_EQ(speed.last, (json{{"v", 1}, {"w", 0}}));
  r = hub.publish("robot.motion", "socket", {{"w", 0}});
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.error, "the command has no 'v'");
  r = hub.publish("robot.motion", "socket", json::array({1, 0}));
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("JSON object"), std::string::npos);
  EXPECT_FALSE(hub.publish("robot.motion", "dds", {{"v", 1}}).ok);
  EXPECT_FALSE(hub.publish("robot.counter", "socket", {{"n", 1}}).ok);
  auto stats = hub.statistics("socket");
  EXPECT_EQ(stats[1].commands, 1u);
  EXPECT_EQ(stats[1].refused, 1u);
  EXPECT_EQ(stats[1].last_refusal, "the command has no 'v'");
}

TEST_F(StreamHubTest, WhileTheLockIsHeldTheLatestCommandWaitsForTheNextTurn) {
  gate->lock();
  std::thread transport([&] {
    EXPECT_TRUE(hub.publish("robot.motion", "socket", {{"v", 1}, {"w", 0}}).ok);
    PublishResult r = hub.publish("robot.motion", "socket", {{"v", 2}, {"w", 0}});
    EXPECT_TRUE(r.ok);
    EXPECT_FALSE(r.applied);
  });
  transport.join();
  EXPECT_TRUE(speed.last.is_null());
  EXPECT_TRUE(hub.turn_wanted());
  EXPECT_TRUE(gate->consume());  // the loop was woken for it
  EXPECT_EQ(hub.apply_commands(), 1u);
  EXPECT_FALSE(hub.turn_wanted());
  gate->unlock();
  EXPECT_EQ(speed.last["v"], 2);
  EXPECT_EQ(hub.statistics("socket")[1].replaced, 1u);
}

TEST_F(StreamHubTest, RemovingAComponentClosesItsSubscriptions) {
  int wakes = 0;
  auto sub = hub.subscribe("robot.counter", "socket", {16, "", [&] { ++wakes; }});
  hub.publish_due(0);
  EXPECT_TRUE(hub.remove("robot.counter"));
  EXPECT_TRUE(sub->closed());
  EXPECT_EQ(wakes, 2);  // the sample, then the close
  EXPECT_FALSE(hub.remove("robot.counter"));
  EXPECT_TRUE(hub.streams("dds").empty());
  hub.publish_due(1);
  EXPECT_EQ(counter.reads, 1);
}

TEST_F(StreamHubTest, ASensorThatThrowsSkipsItsSample) {
  class Broken : public Component {
   public:
    Broken() : Component("robot.broken") {
      declare_output_stream("x", []() -> json { throw std::runtime_error("no data"); });
    }
  } broken;
  hub.add(broken, "broken", {"socket"});
  auto sub = hub.subscribe("robot.broken", "socket", {});
  hub.publish_due(0);
  std::vector<SamplePtr> out;
  EXPECT_EQ(sub->take(out), 0u);
  EXPECT_FALSE(sub->closed());
}

// A record stream (a pose's): its samples carry numbers, read by name without JSON; the JSON
// object, made when a transport asks, is the one the component's get_local_data gives.
TEST_F(StreamHubTest, ARecordSampleIsReadByNameAndIsTheSameJsonOnAsking) {
  class Position : public Component {
   public:
    Position() : Component("robot.position") {
      declare_output_stream("position", {"x", "y", "timestamp"}, [this](std::span<double> v) {
        v[0] = 1.5, v[1] = -2, v[2] = ++reads;
      });
    }
    int reads = 0;
  } position;
  hub.add(position, "position", {"socket"});
  auto sub = hub.subscribe("robot.position", "socket", {});
  hub.publish_due(0);
  const auto samples = take(*sub);
  ASSERT_EQ(samples.size(), 1u);
  const StreamSample& sample = *samples[0];
  EXPECT_TRUE(sample.is_record());
  EXPECT_EQ(sample.seq(), 1u);
  EXPECT_EQ(sample.number("x"), 1.5);
  EXPECT_EQ(sample.number("timestamp"), 1);
  EXPECT_THROW(sample.number("z"), std::out_of_range);
  EXPECT_EQ(sample.data(), (json{{"x", 1.5}, {"y", -2.0}, {"timestamp", 1.0}}));
  EXPECT_EQ(sample.text(), R"({"timestamp":1.0,"x":1.5,"y":-2.0})");
  // produce() (get_local_data's JSON, for a component library that reads it) is the same
  EXPECT_EQ(position.stream()->produce(), (json{{"x", 1.5}, {"y", -2.0}, {"timestamp", 2.0}}));
  // a JSON sample's numbers are read by name too
  auto counted = hub.subscribe("robot.counter", "socket", {});
  hub.publish_due(0.5);
  const auto counts = take(*counted);
  ASSERT_EQ(counts.size(), 1u);
  EXPECT_FALSE(counts[0]->is_record());
  EXPECT_EQ(counts[0]->number("n"), 1);
  EXPECT_THROW(counts[0]->number("m"), std::out_of_range);
}

TEST(RecordStream, HasOneToSixteenNumbers) {
  class Empty : public Component {
   public:
    Empty() : Component("robot.empty") {}
    void declare(std::size_t n) {
      declare_output_stream("x", std::vector<std::string>(n, "f"), [](std::span<double>) {});
    }
  } component;
  EXPECT_THROW(component.declare(0), std::invalid_argument);
  EXPECT_THROW(component.declare(k_max_record_fields + 1), std::invalid_argument);
  EXPECT_NO_THROW(component.declare(k_max_record_fields));
}

}  // namespace
}  // namespace simgate
