// StreamHub: output streams by frequency, first samples, slow subscribers, input commands
// (applied at once when the simulation lock is free, kept otherwise), removal.
#include "simgate/core/streams.h"

#include <algorithm>
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
  hub.publish_due(0);      // a's first, also due
  hub.publish_due(0.004);  // not due
  auto b = hub.subscribe("robot.counter", "dds", {});
  hub.publish_due(0.004);  // b's first, a gets nothing
  EXPECT_EQ(take(*a).size(), 1u);
  auto b_samples = take(*b);
  ASSERT_EQ(b_samples.size(), 1u);
  EXPECT_DOUBLE_EQ(b_samples[0]->time(), 0.004);
  hub.publish_due(0.01);  // due: both
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
  EXPECT_FALSE(hub.publish("robot.motion", "dds", {{"v", 1}}).ok);
  EXPECT_FALSE(hub.publish("robot.counter", "socket", {{"n", 1}}).ok);
  auto stats = hub.statistics("socket");
  EXPECT_EQ(stats[1].commands, 1u);
  EXPECT_EQ(stats[1].refused, 1u);
  EXPECT_EQ(stats[1].last_refusal, "the command has no 'v'");
}

TEST_F(StreamHubTest, ACommandThatIsNotAnObjectIsRefusedAndCounted) {
  PublishResult r = hub.publish("robot.motion", "socket", json::array({1, 0}));
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.error, "a command of robot.motion is a JSON object, found array");
  // not counted where the stream is not: another transport's, an output stream, nobody's
  EXPECT_FALSE(hub.publish("robot.motion", "dds", "fast").ok);
  EXPECT_FALSE(hub.publish("robot.counter", "socket", 1).ok);
  EXPECT_FALSE(hub.publish("robot.nothing", "socket", 1).ok);
  const auto stats = hub.statistics("socket");
  EXPECT_EQ(stats[1].refused, 1u);
  EXPECT_EQ(stats[1].commands, 0u);
  EXPECT_EQ(stats[1].last_refusal, r.error);
  EXPECT_TRUE(speed.last.is_null());
}

TEST_F(StreamHubTest, ACommandTheTransportCouldNotReadIsCountedAsRefused) {
  EXPECT_TRUE(hub.note_refused("robot.motion", "socket", "not JSON: 'hello'"));
  EXPECT_TRUE(hub.note_refused("robot.motion", "socket", "a line longer than 10 bytes"));
  EXPECT_FALSE(hub.note_refused("robot.motion", "dds", "not JSON"));      // not carried there
  EXPECT_FALSE(hub.note_refused("robot.counter", "socket", "not JSON"));  // an output stream
  EXPECT_FALSE(hub.note_refused("robot.nothing", "socket", "not JSON"));
  auto stats = hub.statistics("socket");
  EXPECT_EQ(stats[0].refused, 0u);
  EXPECT_EQ(stats[1].refused, 2u);
  EXPECT_EQ(stats[1].last_refusal, "a line longer than 10 bytes");
  // the component's own refusals add to them, and the latest reason is kept
  EXPECT_FALSE(hub.publish("robot.motion", "socket", {{"w", 0}}).ok);
  stats = hub.statistics("socket");
  EXPECT_EQ(stats[1].refused, 3u);
  EXPECT_EQ(stats[1].last_refusal, "the command has no 'v'");
}

TEST_F(StreamHubTest, ACommandWithAKeyTheStreamDoesNotTakeIsRefusedAtOnceEvenWhileTheLockIsHeld) {
  // before, it waited for the simulation's turn (the client told it was queued) and was
  // refused there, out of the client's sight (issue #35, item 10)
  gate->lock();
  PublishResult r;
  std::thread transport(
      [&] { r = hub.publish("robot.motion", "socket", {{"v", 1}, {"speed", 2}}); });
  transport.join();
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.error, "the command has an unknown key 'speed' (expected v, w)");
  EXPECT_FALSE(hub.turn_wanted());  // nothing queued
  // a timestamp (a sample written back) is taken
  std::thread again(
      [&] { r = hub.publish("robot.motion", "socket", {{"v", 1}, {"w", 0}, {"timestamp", 3.5}}); });
  again.join();
  EXPECT_TRUE(r.ok);
  EXPECT_TRUE(hub.turn_wanted());
  EXPECT_EQ(hub.apply_commands(), 1u);
  gate->unlock();
  EXPECT_EQ(hub.statistics("socket")[1].refused, 1u);
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

// A direct subscriber (SubscriberOptions::deliver) is handed each sample as it is made, on
// the publishing thread: same schedule and first sample as a queue, nothing queued, no wake.
TEST_F(StreamHubTest, ADirectSubscriberGetsEachSampleAsItIsMadeAndNothingIsQueued) {
  std::vector<std::pair<std::uint64_t, double>> got;
  int wakes = 0;
  SubscriberOptions options{1, "direct", [&] { ++wakes; }, {}};
  options.deliver = [&](const StreamSample& sample) {
    got.emplace_back(sample.seq(), sample.time());
    return true;
  };
  auto direct = hub.subscribe("robot.counter", "dds", std::move(options));
  ASSERT_TRUE(direct);
  for (int step = 0; step <= 10; ++step)
    hub.publish_due(step * 0.002);  // due at 0 (first), 0.01, 0.02
  ASSERT_EQ(got.size(), 3u);
  EXPECT_EQ(got[0], (std::pair<std::uint64_t, double>{1, 0}));
  EXPECT_EQ(got[2].first, 3u);
  EXPECT_NEAR(got[2].second, 0.02, 1e-9);
  EXPECT_EQ(take(*direct).size(), 0u);
  EXPECT_EQ(wakes, 0);
  EXPECT_EQ(direct->delivered(), 3u);
  EXPECT_EQ(direct->dropped(), 0u);
  // a queued subscriber beside it gets the same samples
  auto queued = hub.subscribe("robot.counter", "socket", {});
  hub.publish_due(0.03);
  EXPECT_EQ(got.size(), 4u);
  EXPECT_EQ(take(*queued).size(), 1u);
  // unsubscribed: never called again
  hub.unsubscribe(direct);
  hub.publish_due(0.04);
  EXPECT_EQ(got.size(), 4u);
  EXPECT_EQ(take(*queued).size(), 1u);
}

TEST_F(StreamHubTest, ADirectSubscribersUnsentAndFailedSamplesAreCountedAsDropped) {
  int calls = 0;
  SubscriberOptions options;
  options.deliver = [&](const StreamSample&) -> bool {
    ++calls;
    if (calls == 2) throw std::invalid_argument("not of the topic's shape");
    return calls != 3;  // the third is refused, the others sent
  };
  auto direct = hub.subscribe("robot.counter", "dds", std::move(options));
  for (int i = 0; i < 4; ++i) hub.publish_due(i * 0.01);
  EXPECT_EQ(calls, 4);
  EXPECT_EQ(direct->delivered(), 4u);
  EXPECT_EQ(direct->dropped(), 2u);
  EXPECT_EQ(hub.statistics("dds")[0].dropped, 2u);
  EXPECT_FALSE(direct->closed());
  // the component removed: closed, no more deliveries
  EXPECT_TRUE(hub.remove("robot.counter"));
  EXPECT_TRUE(direct->closed());
  hub.publish_due(1);
  EXPECT_EQ(calls, 4);
}

// A record stream (a pose's): its samples carry numbers, read by name without JSON; the JSON
// object, made when a transport asks, is the one the component's get_local_data gives.
TEST_F(StreamHubTest, ARecordSampleIsReadByNameAndIsTheSameJsonOnAsking) {
  class Position : public Component {
   public:
    Position() : Component("robot.position") {
      declare_output_stream("position", {"x", "y", "timestamp"},
                            [this](std::span<double> v) { v[0] = 1.5, v[1] = -2, v[2] = ++reads; });
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

// The hub reuses a record sample nobody holds for the stream's next one (no allocation per
// sample): a direct subscriber sees each sample's own numbers, JSON and text, and a sample a
// queue still holds is never overwritten.
TEST_F(StreamHubTest, ARecordSampleIsReusedOnlyWhenNobodyHoldsIt) {
  class Position : public Component {
   public:
    Position() : Component("robot.position") {
      declare_output_stream("position", {"x", "timestamp"},
                            [this](std::span<double> v) { v[0] = ++reads, v[1] = 0; });
    }
    int reads = 0;
  } position;
  hub.add(position, "position", {"dds", "socket"}, 100);
  std::vector<std::string> texts;
  std::vector<const StreamSample*> addresses;
  SubscriberOptions options;
  options.deliver = [&](const StreamSample& sample) {
    texts.push_back(sample.text());  // its JSON made (and kept by the sample) each time
    addresses.push_back(&sample);
    return true;
  };
  auto direct = hub.subscribe("robot.position", "dds", std::move(options));
  for (int i = 0; i < 3; ++i) hub.publish_due(i * 0.01);
  ASSERT_EQ(texts.size(), 3u);
  EXPECT_EQ(texts[0], R"({"timestamp":0.0,"x":1.0})");
  EXPECT_EQ(texts[1], R"({"timestamp":0.0,"x":2.0})");
  EXPECT_EQ(texts[2], R"({"timestamp":0.0,"x":3.0})");
  EXPECT_EQ(addresses[1], addresses[0]);  // nobody kept the first: the second is the same object
  EXPECT_EQ(addresses[2], addresses[0]);
  // a queue keeps its samples: each one stays as it was made
  auto queued = hub.subscribe("robot.position", "socket", {4, "queue", {}, {}});
  for (int i = 3; i < 6; ++i) hub.publish_due(i * 0.01);
  const auto kept = take(*queued);
  ASSERT_EQ(kept.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(kept[i]->seq(), static_cast<std::uint64_t>(i + 4));
    EXPECT_EQ(kept[i]->number("x"), i + 4);
    EXPECT_EQ(kept[i]->data().at("x"), i + 4);
    EXPECT_NEAR(kept[i]->time(), (i + 3) * 0.01, 1e-12);
  }
  EXPECT_NE(kept[0].get(), kept[1].get());
  EXPECT_EQ(texts.back(), R"({"timestamp":0.0,"x":6.0})");
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

// A component that pushes its samples (a camera's images, made on another thread): bytes
// whose JSON is made by to_json, counted.
class Pusher : public Component {
 public:
  Pusher() : Component("robot.camera") { declare_pushed_stream("image", 10); }
  using Component::note_skipped_sample;
  using Component::push_sample;
  // A payload of `n` bytes valued `value`; its JSON counts how often it is made.
  std::shared_ptr<const StreamPayload> payload(std::size_t n, std::uint8_t value) {
    auto p = std::make_shared<StreamPayload>();
    p->content = "image";
    p->description = {{"width", n}, {"height", 1}, {"encoding", "mono8"}};
    p->bytes.assign(n, value);
    p->to_json = [this](const StreamPayload& q) {
      ++jsons_made;
      return json{{"first", q.bytes.at(0)}, {"n", q.bytes.size()}};
    };
    return p;
  }
  std::atomic<int> jsons_made{0};
};

struct PushedStreamTest : ::testing::Test {
  std::shared_ptr<SimulationGate> gate = std::make_shared<SimulationGate>();
  StreamHub hub{gate};
  Counter counter;
  Pusher pusher;
  void SetUp() override {
    hub.add(counter, "counter", {"socket"}, 100);
    hub.add(pusher, "video_camera", {"socket", "dds"}, 60);  // the component's own rate is listed
  }
  static std::vector<SamplePtr> take(StreamSubscription& s) {
    std::vector<SamplePtr> out;
    s.take(out);
    return out;
  }
};

TEST_F(PushedStreamTest, ADirectSubscriberIsHandedEachPushedSample) {
  std::vector<double> times;
  SubscriberOptions options;
  options.deliver = [&](const StreamSample& sample) {
    times.push_back(sample.time());
    return true;
  };
  auto direct = hub.subscribe("robot.camera", "dds", std::move(options));
  ASSERT_TRUE(direct);
  EXPECT_TRUE(pusher.stream_wanted());
  EXPECT_TRUE(pusher.push_sample(0.5, json{{"frame", 1}}));
  EXPECT_TRUE(pusher.push_sample(0.6, json{{"frame", 2}}));
  EXPECT_EQ(times, (std::vector<double>{0.5, 0.6}));
  EXPECT_EQ(take(*direct).size(), 0u);
}

TEST_F(PushedStreamTest, IsListedPushedAtTheComponentsFrequency) {
  auto info = hub.find("robot.camera", "dds");
  ASSERT_TRUE(info);
  EXPECT_TRUE(info->pushed);
  EXPECT_EQ(info->frequency, 10);
  EXPECT_EQ(info->kind, "image");
  EXPECT_FALSE(hub.find("robot.counter", "socket")->pushed);
}

TEST_F(PushedStreamTest, WantedFollowsSubscribersAndNothingIsTakenWithoutThem) {
  EXPECT_FALSE(pusher.stream_wanted());
  EXPECT_FALSE(pusher.push_sample(0.0, json{{"a", 1}}));
  auto a = hub.subscribe("robot.camera", "socket", {});
  EXPECT_TRUE(pusher.stream_wanted());
  auto b = hub.subscribe("robot.camera", "dds", {});
  hub.unsubscribe(a);
  EXPECT_TRUE(pusher.stream_wanted());  // b still subscribes
  hub.unsubscribe(b);
  EXPECT_FALSE(pusher.stream_wanted());
  EXPECT_FALSE(pusher.push_sample(1.0, pusher.payload(4, 7)));
  EXPECT_EQ(hub.total_samples(), 0u);
}

TEST_F(PushedStreamTest, APushedSampleGoesToEverySubscriberAndTheHubNeverProducesOne) {
  int wakes = 0;
  auto a = hub.subscribe("robot.camera", "socket", {4, "a", [&] { ++wakes; }});
  auto b = hub.subscribe("robot.camera", "dds", {4, "b", {}});
  // steps: the hub has nothing to produce for it (no first sample made by the hub)
  hub.publish_due(0.0);
  hub.publish_due(0.5);
  EXPECT_TRUE(take(*a).empty());
  EXPECT_EQ(wakes, 0);
  ASSERT_TRUE(pusher.push_sample(0.1, pusher.payload(6, 42)));
  ASSERT_TRUE(pusher.push_sample(0.2, json{{"n", 2}}));
  EXPECT_EQ(wakes, 1);  // once, empty to not empty
  auto from_a = take(*a), from_b = take(*b);
  ASSERT_EQ(from_a.size(), 2u);
  ASSERT_EQ(from_b.size(), 2u);
  EXPECT_EQ(from_a[0], from_b[0]);  // shared, not copied
  EXPECT_EQ(from_a[0]->seq(), 1u);
  EXPECT_EQ(from_a[1]->seq(), 2u);
  EXPECT_DOUBLE_EQ(from_a[0]->time(), 0.1);
  ASSERT_NE(from_a[0]->payload(), nullptr);
  EXPECT_EQ(from_a[0]->payload()->bytes, std::vector<std::uint8_t>(6, 42));
  EXPECT_EQ(from_a[0]->payload()->description["encoding"], "mono8");
  EXPECT_EQ(from_a[1]->payload(), nullptr);
  EXPECT_EQ(from_a[1]->number("n"), 2);
  EXPECT_EQ(hub.total_samples(), 2u);
  auto stats = hub.statistics("dds");
  ASSERT_EQ(stats.size(), 1u);
  EXPECT_EQ(stats[0].samples, 2u);
  EXPECT_EQ(stats[0].subscribers, 2u);
}

TEST_F(PushedStreamTest, ThePayloadsJsonIsMadeOnceOnFirstAskAndNotBefore) {
  auto a = hub.subscribe("robot.camera", "socket", {});
  auto b = hub.subscribe("robot.camera", "dds", {});
  ASSERT_TRUE(pusher.push_sample(0.1, pusher.payload(3, 9)));
  const SamplePtr sample = take(*a).at(0);
  EXPECT_EQ(pusher.jsons_made, 0);  // a typed transport reads the bytes: no JSON
  EXPECT_EQ(sample->payload()->bytes.size(), 3u);
  // two transport threads ask at once: made once, the same for both
  std::string t1, t2;
  std::thread one([&] { t1 = sample->text(); });
  std::thread two([&] { t2 = take(*b).at(0)->data().dump(); });
  one.join();
  two.join();
  EXPECT_EQ(pusher.jsons_made, 1);
  EXPECT_EQ(t1, R"({"first":9,"n":3})");
  EXPECT_EQ(t2, t1);
  EXPECT_EQ(sample->number("n"), 3);
  EXPECT_EQ(pusher.jsons_made, 1);
}

TEST_F(PushedStreamTest, ASlowSubscriberLosesItsOldestPushedSamplesCounted) {
  auto slow = hub.subscribe("robot.camera", "socket", {2, "slow", {}});
  for (int i = 1; i <= 5; ++i) ASSERT_TRUE(pusher.push_sample(0.1 * i, json{{"n", i}}));
  auto got = take(*slow);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[0]->number("n"), 4);
  EXPECT_EQ(got[1]->number("n"), 5);
  EXPECT_EQ(slow->dropped(), 3u);
  EXPECT_EQ(hub.total_dropped(), 3u);
}

TEST_F(PushedStreamTest, ASkippedSampleIsCountedAsSkippedAndDropped) {
  auto sub = hub.subscribe("robot.camera", "socket", {16, "client", {}});
  ASSERT_TRUE(pusher.push_sample(0.1, json{{"n", 1}}));
  // the next one due never comes (the render thread was behind)
  pusher.note_skipped_sample();
  ASSERT_TRUE(pusher.push_sample(0.3, json{{"n", 3}}));
  pusher.note_skipped_sample();
  EXPECT_EQ(take(*sub).size(), 2u);
  EXPECT_EQ(sub->dropped(), 0u);  // the subscriber's own queue lost nothing
  const auto stats = hub.statistics("socket");
  auto camera = std::find_if(stats.begin(), stats.end(),
                             [](const auto& s) { return s.info.component == "robot.camera"; });
  ASSERT_NE(camera, stats.end());
  EXPECT_EQ(camera->samples, 2u);
  EXPECT_EQ(camera->skipped, 2u);
  EXPECT_EQ(camera->dropped, 2u);
  EXPECT_EQ(hub.total_dropped(), 2u);
  // and still after the component leaves
  hub.remove("robot.camera");
  EXPECT_EQ(hub.total_dropped(), 2u);
}

TEST_F(PushedStreamTest, ANewSubscribersFirstSampleIsTheNextPushed) {
  auto early = hub.subscribe("robot.camera", "socket", {});
  ASSERT_TRUE(pusher.push_sample(0.1, json{{"n", 1}}));
  auto late = hub.subscribe("robot.camera", "dds", {});
  hub.publish_due(0.15);  // the hub's turn gives it nothing (it has nothing to give)
  EXPECT_TRUE(take(*late).empty());
  ASSERT_TRUE(pusher.push_sample(0.2, json{{"n", 2}}));
  auto first = take(*late);
  ASSERT_EQ(first.size(), 1u);
  EXPECT_EQ(first[0]->number("n"), 2);
  EXPECT_EQ(take(*early).size(), 2u);
}

TEST_F(PushedStreamTest, RemovedTheComponentIsNoLongerWantedAndPushesNothing) {
  auto sub = hub.subscribe("robot.camera", "socket", {});
  ASSERT_TRUE(pusher.stream_wanted());
  ASSERT_TRUE(hub.remove("robot.camera"));
  EXPECT_TRUE(sub->closed());
  EXPECT_FALSE(pusher.stream_wanted());
  EXPECT_FALSE(pusher.push_sample(1.0, json{{"n", 1}}));
  // added again, it works again
  hub.add(pusher, "video_camera", {"socket"});
  auto again = hub.subscribe("robot.camera", "socket", {});
  EXPECT_TRUE(pusher.push_sample(1.0, json{{"n", 1}}));
  EXPECT_EQ(take(*again).size(), 1u);
}

TEST(PushedStream, TheHubsEndDisconnectsItsComponents) {
  Pusher pusher;
  {
    StreamHub hub(std::make_shared<SimulationGate>());
    hub.add(pusher, "video_camera", {"socket"});
    auto sub = hub.subscribe("robot.camera", "socket", {});
    ASSERT_TRUE(pusher.stream_wanted());
  }
  EXPECT_FALSE(pusher.stream_wanted());
  EXPECT_FALSE(pusher.push_sample(0.0, json{{"n", 1}}));
}

TEST(PushedStream, NeedsAPositiveFrequency) {
  class Bad : public Component {
   public:
    Bad() : Component("robot.bad") {}
    void declare(double f) { declare_pushed_stream("image", f); }
  } component;
  EXPECT_THROW(component.declare(0), std::invalid_argument);
  EXPECT_NO_THROW(component.declare(5));
  EXPECT_FALSE(component.stream()->produce);
}

}  // namespace
}  // namespace simgate
